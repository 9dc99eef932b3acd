//! The independent watchdog on the machine: a program that starts it and never feeds it is reset
//! after the timeout RM0090 table 107 gives, with RCC_CSR.IWDGRSTF set; one that feeds it runs
//! on. Hand-assembled Thumb code, the IWDG and RCC models.

mod thumb;

use rstest::rstest;
use stm32_emu::iwdg::Iwdg;
use stm32_emu::machine::{Chip, Stm32};
use stm32_emu::rcc::{csr, Hse, Rcc};
use thumb::*;

const IWDG: u32 = stm32_emu::iwdg::BASE;
const RCC_CSR: u32 = stm32_emu::rcc::BASE + 0x74;
/// PR 0 (/4), RLR 99: 100 × 4 / 32 kHz = 12.5 ms.
const TIMEOUT: u64 = 12_500_000;
/// The flags a power-on reset leaves in RCC_CSR (RM0090 §7.3.21).
const POWER_ON: u32 = csr::PORRSTF | csr::PINRSTF | csr::BORRSTF;

/// Counts its starts at COUNTER (SRAM survives a system reset), starts the IWDG as
/// stm32f4xx-hal does (0x5555, PR, RLR, 0xAAAA, 0xCCCC), then feeds it in a loop (`feed`) or
/// idles in `b .`.
fn program(feed: bool) -> Asm {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, COUNTER).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0);
    main.ldr_const(0, IWDG).ldr_const(1, 0x5555).str(1, 0, 0);
    main.movs(1, 0).str(1, 0, 1).movs(1, 99).str(1, 0, 2);
    main.ldr_const(1, 0xAAAA).str(1, 0, 0).ldr_const(1, 0xCCCC).str(1, 0, 0);
    let top = main.here();
    if feed {
        main.ldr_const(1, 0xAAAA).str(1, 0, 0).b(top);
    } else {
        main.b(top);
    }
    main
}

fn machine(feed: bool) -> Stm32 {
    let mut mcu = Stm32::new(Chip::Stm32F405, [0; 12]).expect("machine");
    mcu.add_peripheral(stm32_emu::rcc::BASE, 0x400, Box::new(Rcc::new(Hse::Crystal(8_000_000))))
        .expect("RCC");
    mcu.add_peripheral(IWDG, 0x400, Box::new(Iwdg::new())).expect("IWDG");
    flash(&mut mcu, &image(&mut [(RESET, program(feed))], &[]));
    mcu
}

#[test]
fn a_program_that_never_feeds_is_reset_at_the_timeout_with_iwdgrstf() {
    let mut mcu = machine(false);
    assert!(mcu.run_until(2 * TIMEOUT, |m| m.resets() == 2).expect("runs"), "a watchdog reset");
    // The start-up code takes a few microseconds at 16 MHz before 0xAAAA.
    let at = mcu.now();
    assert!((TIMEOUT..TIMEOUT + 5_000).contains(&at), "reset at {at} ns, not 12.5 ms after the start");
    assert_eq!(mcu.read_peripheral(RCC_CSR).map(|v| v & csr::FLAGS), Some(POWER_ON | csr::IWDGRSTF));
    // Stopped by the reset, started again by the program: one reset per timeout.
    mcu.run_for(100_000_000 - at).expect("runs");
    assert_eq!(mcu.resets(), 1 + 7, "7 timeouts of 12.5 ms in 100 ms");
    assert_eq!(word(&mcu, COUNTER), 8, "the program started 8 times");
}

#[test]
fn a_program_that_feeds_it_is_not_reset() {
    let mut mcu = machine(true);
    mcu.run_for(100_000_000).expect("runs");
    assert_eq!(mcu.resets(), 1, "only the power-on reset");
    assert_eq!(word(&mcu, COUNTER), 1);
    assert_eq!(mcu.read_peripheral(RCC_CSR).map(|v| v & csr::FLAGS), Some(POWER_ON));
}

/// A program that writes `aircr` to AIRCR on its first start only (PM0214 §4.4.4: SYSRESETREQ
/// with VECTKEY 0x05FA resets; without the key the write is ignored).
#[rstest]
#[case::sysresetreq(0x05FA_0004, csr::SFTRSTF)]
#[case::no_key(0x0000_0004, 0)]
fn a_sysresetreq_reset_sets_sftrstf(#[case] aircr: u32, #[case] flag: u32) {
    let mut main = Asm::new(RESET);
    main.ldr_const(0, COUNTER).ldr(1, 0, 0).adds(1, 1).str(1, 0, 0).cmp(1, 1);
    let idle = main.here() + 8; // past BNE, the two LDRs and the STR
    main.bne(idle);
    main.ldr_const(2, 0xE000_ED0C).ldr_const(3, aircr).str(3, 2, 0);
    assert_eq!(main.here(), idle);
    main.b(idle);
    let mut mcu = Stm32::new(Chip::Stm32F405, [0; 12]).expect("machine");
    mcu.add_peripheral(stm32_emu::rcc::BASE, 0x400, Box::new(Rcc::new(Hse::Crystal(8_000_000))))
        .expect("RCC");
    flash(&mut mcu, &image(&mut [(RESET, main)], &[]));
    mcu.run_for(1_000_000).expect("runs");
    assert_eq!(mcu.resets(), 1 + u32::from(flag != 0));
    assert_eq!(mcu.read_peripheral(RCC_CSR).map(|v| v & csr::FLAGS), Some(POWER_ON | flag));
}
