//! The machine's memory: CPU stores into flash go through the FLASH model (a stand-in here),
//! flash survives resets and power cycles, SRAM survives a system reset only; WFI sleeps to
//! the next SysTick interrupt.

mod stand_ins;
mod thumb;

use rstest::rstest;
use stand_ins::{Flash, Record};
use std::cell::RefCell;
use std::rc::Rc;
use stm32_emu::cpu::core::CoreFault;
use stm32_emu::machine::{Chip, Stm32};
use thumb::*;
use unicorn_engine::RegisterARM;

/// Sector 10's first word (the settings journal's, board/memory.x).
const SETTINGS: u32 = 0x080C_0000;

/// Main: unlocks FLASH if `unlock` (RM0090 §3.5.1 KEYR sequence), sets PG with PSIZE x32
/// (RM0090 §3.9.7), stores 0x1234_5678 at SETTINGS and loads it back into R4.
fn program_word(unlock: bool) -> Asm {
    let mut main = Asm::new(RESET);
    if unlock {
        main.ldr_const(0, 0x4002_3C04).ldr_const(1, 0x4567_0123).str(1, 0, 0);
        main.ldr_const(1, 0xCDEF_89AB).str(1, 0, 0);
    }
    main.ldr_const(0, 0x4002_3C10).ldr_const(1, 0x201).str(1, 0, 0);
    main.ldr_const(2, SETTINGS).ldr_const(3, 0x1234_5678).str(3, 2, 0).ldr(4, 2, 0);
    let here = main.here();
    main.b(here);
    main
}

#[rstest]
#[case::unlocked(true, 0x1234_5678)]
#[case::locked_store_is_ignored(false, 0xFFFF_FFFF)]
fn a_cpu_store_into_flash_goes_through_the_flash_model(#[case] unlock: bool, #[case] stored: u32) {
    let mut mcu = machine(&mut [(RESET, program_word(unlock))], &[]);
    let record = Rc::new(RefCell::new(Record::default()));
    mcu.add_peripheral(0x4002_3C00, 0x400, Box::new(Flash::new(&record))).expect("FLASH");
    mcu.run_for(10_000).expect("runs");
    let at = (SETTINGS - FLASH) as usize;
    assert_eq!(u32::from_le_bytes(mcu.flash()[at..at + 4].try_into().expect("4 bytes")), stored);
    assert_eq!(mcu.register(RegisterARM::R4), stored, "the CPU reads what the array holds");
    assert_eq!(word(&mcu, SETTINGS), stored);
}

/// The same with the FLASH model of [`stm32_emu::flash`] (which keeps the array itself).
#[rstest]
#[case::unlocked(true, 0x1234_5678)]
#[case::locked_store_is_refused(false, 0xFFFF_FFFF)]
fn a_cpu_store_into_flash_goes_through_the_real_flash_model(#[case] unlock: bool, #[case] stored: u32) {
    let mut mcu = Stm32::new(Chip::Stm32F405, [0; 12]).expect("machine");
    mcu.add_flash(stm32_emu::flash::Flash::new()).expect("FLASH");
    flash(&mut mcu, &image(&mut [(RESET, program_word(unlock))], &[]));
    mcu.run_for(100_000).expect("runs");
    let at = (SETTINGS - FLASH) as usize;
    assert_eq!(u32::from_le_bytes(mcu.flash()[at..at + 4].try_into().expect("4 bytes")), stored);
    assert_eq!(mcu.register(RegisterARM::R4), stored, "the CPU reads what the array holds");
}

#[test]
fn flash_survives_power_cycles_and_sram_only_system_resets() {
    let mut main = Asm::new(RESET);
    let here = main.here();
    main.b(here);
    let mut mcu = machine(&mut [(RESET, main)], &[]);
    mcu.program_flash(SETTINGS - FLASH, &[1, 2, 3, 4]).expect("flash");
    assert!(mcu.write_memory(COUNTER, &[9, 9, 9, 9]));
    mcu.system_reset().expect("system reset");
    assert_eq!(word(&mcu, COUNTER), 0x0909_0909, "SRAM kept by a system reset");
    mcu.power_on_reset().expect("power cycle");
    assert_eq!(word(&mcu, COUNTER), 0, "SRAM not kept by a power cycle");
    assert_eq!(word(&mcu, SETTINGS), 0x0403_0201, "flash kept");
    assert_eq!(word(&mcu, SETTINGS - FLASH), 0x0403_0201, "and seen through the alias at 0");
}

#[rstest]
#[case::wfi(0xBF30)]
#[case::wfe(0xBF20)]
fn wfi_and_wfe_sleep_until_the_next_systick_interrupt(#[case] sleep: u16) {
    let mut main = Asm::new(RESET);
    // SysTick every 16,000 cycles (1 ms at the 16 MHz HSI), then WFI in a loop counting R4.
    main.ldr_const(0, 0xE000_E010).ldr_const(1, 15_999).str(1, 0, 1).movs(1, 7).str(1, 0, 0);
    let top = main.here();
    main.op(sleep).adds(4, 1).b(top);
    let mut handler = Asm::new(FLASH + 0x400);
    handler.ldr_const(0, COUNTER).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).bx_lr();
    let mut mcu = machine(&mut [(RESET, main), (FLASH + 0x400, handler)], &[(SYSTICK, FLASH + 0x400)]);
    // The set-up's few cycles put the tenth tick just after 10 ms.
    mcu.run_for(10_100_000).expect("runs");
    assert_eq!(word(&mcu, COUNTER), 10, "ten ticks in 10.1 ms");
    assert_eq!(mcu.register(RegisterARM::R4), 10, "one wake-up a tick");
    assert!(mcu.sleeping());
}

/// A store to the SRAM bit-band alias sets one bit; a load reads one (PM0214 §2.2.5: bit 3 of
/// 0x2000_0001 is the word 0x2200_0000 + 1 × 32 + 3 × 4).
#[test]
fn sram_bit_band() {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, 0x2200_0000 + 32 + 12).movs(1, 1).str(1, 0, 0).ldr(4, 0, 0);
    main.ldr_const(0, 0x2200_0000 + 32 + 16).ldr(5, 0, 0);
    let here = main.here();
    main.b(here);
    let mut mcu = machine(&mut [(RESET, main)], &[]);
    mcu.run_for(10_000).expect("runs");
    assert_eq!(word(&mcu, COUNTER), 1 << 11);
    assert_eq!(mcu.register(RegisterARM::R4), 1);
    assert_eq!(mcu.register(RegisterARM::R5), 0);
}

/// A wrong unlock key is a bus error (RM0090 §3.6.1), reported with the access.
#[test]
fn a_wrong_flash_key_is_a_bus_fault() {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, 0x4002_3C04).ldr_const(1, 0x1111_1111).str(1, 0, 0);
    let here = main.here();
    main.b(here);
    let mut mcu = Stm32::new(Chip::Stm32F405, [0; 12]).expect("machine");
    mcu.add_flash(stm32_emu::flash::Flash::new()).expect("FLASH");
    flash(&mut mcu, &image(&mut [(RESET, main)], &[]));
    let fault = mcu.run_for(10_000).expect_err("bus fault");
    let expected = CoreFault::Bus { address: 0x4002_3C04, pc: RESET + 4, write: true };
    assert_eq!(fault, stm32_emu::machine::Fault::Core(expected));
}

/// SCR.SLEEPONEXIT: after the first SysTick handler the core sleeps instead of returning to
/// the thread, and wakes only into the handler (PM0214 §4.4.6).
#[test]
fn sleep_on_exit() {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, 0xE000_ED10).movs(1, 2).str(1, 0, 0); // SCR.SLEEPONEXIT
    main.ldr_const(0, 0xE000_E010).ldr_const(1, 15_999).str(1, 0, 1).movs(1, 7).str(1, 0, 0);
    let top = main.here();
    main.adds(4, 1).b(top);
    let mut handler = Asm::new(FLASH + 0x400);
    handler.ldr_const(0, COUNTER).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).bx_lr();
    let mut mcu = machine(&mut [(RESET, main), (FLASH + 0x400, handler)], &[(SYSTICK, FLASH + 0x400)]);
    mcu.run_for(1_500_000).expect("runs");
    let thread_count = mcu.register(RegisterARM::R4);
    mcu.run_for(3_000_000).expect("runs");
    assert_eq!(word(&mcu, COUNTER), 4, "a tick a millisecond");
    assert_eq!(mcu.register(RegisterARM::R4), thread_count, "the thread no longer runs");
    assert!(mcu.sleeping());
}

/// The STM32F446RE's flash ends at 0x0807_FFFF (RM0390 §3.3, 512 KiB): a load or store past it
/// is a bus fault, the last byte is there, and a programmer's download past it is refused.
#[rstest]
#[case::f446_load_past_the_end(Chip::Stm32F446, 0x0808_0000, false, Some(0x0808_0000))]
#[case::f446_store_past_the_end(Chip::Stm32F446, 0x0808_0000, true, Some(0x0808_0000))]
#[case::f446_alias_past_the_end(Chip::Stm32F446, 0x0008_0000, false, Some(0x0008_0000))]
#[case::f446_last_word(Chip::Stm32F446, 0x0807_FFFC, false, None)]
#[case::f405_has_1_mib(Chip::Stm32F405, 0x0808_0000, true, None)]
fn flash_ends_where_the_chip_s_does(
    #[case] chip: Chip,
    #[case] address: u32,
    #[case] store: bool,
    #[case] fault: Option<u32>,
) {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, address).movs(1, 0);
    if store {
        main.str(1, 0, 0);
    } else {
        main.ldr(1, 0, 0);
    }
    main.movs(4, 42);
    let here = main.here();
    main.b(here);
    let mut mcu = Stm32::new(chip, [0; 12]).expect("machine");
    mcu.add_flash(stm32_emu::flash::Flash::new()).expect("FLASH");
    flash(&mut mcu, &image(&mut [(RESET, main)], &[]));
    let result = mcu.run_for(10_000);
    match fault {
        Some(at) => {
            let Err(stm32_emu::machine::Fault::Core(CoreFault::Bus { address, write, .. })) = result else {
                panic!("no bus fault: {result:?}");
            };
            assert_eq!((address, write), (at, store));
        }
        None => {
            result.expect("runs");
            assert_eq!(mcu.register(RegisterARM::R4), 42);
        }
    }
    let past_the_end = mcu.program_flash(0x8_0000, &[0]);
    assert_eq!(past_the_end.is_err(), chip == Chip::Stm32F446, "{past_the_end:?}");
}
