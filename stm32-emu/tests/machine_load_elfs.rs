//! Loading a bootloader and an application before the power-on reset (`Stm32::load_elfs`), and
//! the jump a bootloader makes (MSR MSP, VTOR, the application's reset vector): on
//! hand-assembled Thumb code wrapped in minimal ELF files.

mod elf32;
mod thumb;

use rstest::rstest;
use stm32_emu::cpu::core::CoreFault;
use stm32_emu::machine::{Chip, ElfSegment, Fault, Stm32};
use thumb::{word, Asm, COUNTER, FLASH, SYSTICK};
use unicorn_engine::RegisterARM;

/// Where the application is linked (ACTIVE, sector 5, docs/src/development/firmware-update.md).
const APP: u32 = 0x0802_0000;
const BOOT_STACK: u32 = 0x2000_1000;
const APP_STACK: u32 = 0x2000_2000;

/// A vector table of 16 words: the stack pointer, the reset handler and `handlers`.
fn vector_table(stack: u32, reset: u32, handlers: &[(u16, u32)]) -> Vec<u8> {
    let mut table = [0u32; 16];
    table[0] = stack;
    table[1] = reset | 1;
    for &(number, address) in handlers {
        table[usize::from(number)] = address | 1;
    }
    table.iter().flat_map(|w| w.to_le_bytes()).collect()
}

/// The bootloader at 0x0800_0000: its own vector table (no SysTick handler), then MSP from the
/// application's table, VTOR = the table if `set_vtor` (PM0214 §4.4.3), and BX to its reset
/// handler.
fn bootloader(set_vtor: bool) -> Vec<u8> {
    let code_at = FLASH + 0x200;
    let mut code = Asm::new(code_at);
    code.ldr_const(0, APP).ldr(1, 0, 0);
    code.op(0xF381).op(0x8808); // MSR MSP, R1 (T1: Rn in the first halfword, SYSm 8)
    if set_vtor {
        code.ldr_const(2, 0xE000_ED08).str(0, 2, 0);
    }
    code.ldr(1, 0, 1).op(0x4708); // LDR R1, [R0, #4]; BX R1
    let table = vector_table(BOOT_STACK, code_at, &[]);
    elf32::executable(code_at | 1, &[(FLASH, &table), (code_at, &code.finish())])
}

/// The application at APP: SysTick every 1000 cycles, then an idle loop; the SysTick handler
/// counts at COUNTER.
fn application() -> Vec<u8> {
    let main_at = APP + 0x200;
    let handler_at = APP + 0x300;
    let mut main = Asm::new(main_at);
    main.ldr_const(0, 0xE000_E010).ldr_const(1, 999).str(1, 0, 1).movs(1, 7).str(1, 0, 0);
    let here = main.here();
    main.b(here);
    let mut handler = Asm::new(handler_at);
    handler.ldr_const(0, COUNTER).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).bx_lr();
    let table = vector_table(APP_STACK, main_at, &[(SYSTICK, handler_at)]);
    elf32::executable(
        main_at | 1,
        &[(APP, &table), (main_at, &main.finish()), (handler_at, &handler.finish())],
    )
}

fn machine() -> Stm32 {
    Stm32::new(Chip::Stm32F405, [0; 12]).expect("machine")
}

#[test]
fn the_bootloader_starts_the_application_whose_vector_table_vtor_names() {
    let mut mcu = machine();
    mcu.load_elfs(&[&bootloader(true), &application()]).expect("load");
    assert_eq!(mcu.resets(), 1, "one power-on reset for both files");
    assert_eq!(mcu.register(RegisterARM::SP), BOOT_STACK, "reset through the bootloader's table");
    // 16 MHz HSI: SysTick every 62.5 µs, 16 in 1 ms.
    mcu.run_for(1_000_000).expect("runs");
    assert_eq!(mcu.scs().vtor(), APP);
    let count = word(&mcu, COUNTER);
    assert!((14..=16).contains(&count), "{count} SysTick interrupts through the application's table");
    assert_eq!(mcu.register(RegisterARM::SP), APP_STACK, "MSP from the application's table");
    assert!((APP..APP + 0x400).contains(&mcu.pc()), "pc {:#010x} in the application", mcu.pc());
}

#[test]
fn without_the_vtor_write_systick_goes_through_the_bootloaders_table() {
    let mut mcu = machine();
    mcu.load_elfs(&[&bootloader(false), &application()]).expect("load");
    let fault = mcu.run_for(1_000_000).expect_err("the bootloader's table has no SysTick handler");
    assert_eq!(fault, Fault::Core(CoreFault::InvalidVector { exception: SYSTICK, vector: 0 }));
}

#[test]
fn one_elf_still_loads_and_resets() {
    let mut mcu = machine();
    let mut main = Asm::new(FLASH + 0x200);
    main.movs(4, 42);
    let here = main.here();
    main.b(here);
    let table = vector_table(BOOT_STACK, FLASH + 0x200, &[]);
    mcu.load_elf(&elf32::executable(FLASH + 0x201, &[(FLASH, &table), (FLASH + 0x200, &main.finish())]))
        .expect("load");
    mcu.run_for(10_000).expect("runs");
    assert_eq!(mcu.register(RegisterARM::R4), 42);
}

#[rstest]
// The application's vector table over the bootloader's code.
#[case::second_starts_inside_the_first(FLASH + 0x100, ElfSegment { elf: 0, start: FLASH + 0x100, end: FLASH + 0x140 }, ElfSegment { elf: 1, start: FLASH + 0x100, end: FLASH + 0x110 })]
// The application's first bytes inside the bootloader's last segment.
#[case::second_ends_inside_the_first(FLASH + 0xF8, ElfSegment { elf: 0, start: FLASH + 0x100, end: FLASH + 0x140 }, ElfSegment { elf: 1, start: FLASH + 0xF8, end: FLASH + 0x108 })]
fn overlapping_segments_are_refused_naming_both(
    #[case] at: u32,
    #[case] first: ElfSegment,
    #[case] second: ElfSegment,
) {
    let mut mcu = machine();
    let boot = elf32::executable(FLASH | 1, &[(FLASH, &[0x11; 0x40]), (FLASH + 0x100, &[0x22; 0x40])]);
    let app = elf32::executable(at | 1, &[(at, &[0x33; 0x10])]);
    let fault = mcu.load_elfs(&[&boot, &app]).expect_err("overlap");
    assert_eq!(fault, Fault::ElfOverlap { first, second });
    assert!(fault.to_string().contains("ELF 0's segment") && fault.to_string().contains("ELF 1's segment"));
    assert!(mcu.flash()[..0x200].iter().all(|&b| b == 0xFF), "nothing programmed");
}

#[test]
fn adjacent_segments_are_no_overlap() {
    let mut mcu = machine();
    let boot = elf32::executable(0, &[(FLASH, &vector_table(BOOT_STACK, FLASH + 0x40, &[]))]);
    let app = elf32::executable(0, &[(FLASH + 0x40, &[0xFE, 0xE7])]); // b .
    mcu.load_elfs(&[&boot, &app]).expect("adjacent files load");
    assert_eq!(mcu.pc(), FLASH + 0x40);
}

#[test]
fn a_segment_outside_flash_is_refused_naming_its_file() {
    let mut mcu = machine();
    let boot = elf32::executable(0, &[(FLASH, &vector_table(BOOT_STACK, FLASH + 0x40, &[]))]);
    let app = elf32::executable(0, &[(0x080F_FFF0, &[0; 0x20])]);
    let fault = mcu.load_elfs(&[&boot, &app]).expect_err("past the end of flash");
    assert_eq!(fault, Fault::Elf("ELF 1: segment at 0x080ffff0 is not in flash".into()));
}
