//! Register facts of the RCC, driven as stm32f4xx-hal 0.23 drives it for `board::hw::clocks`
//! (`Rcc::freeze`) and for the peripherals' `enable` / `reset`.

use super::*;
use crate::gpio::tests::TestMachine;
use rstest::rstest;

fn rmw(rcc: &mut Rcc, m: &mut TestMachine, offset: u32, f: impl Fn(u32) -> u32) {
    let v = rcc.read(offset, Width::Word, m);
    rcc.write(offset, Width::Word, f(v), m);
}

/// Polls `flag` of `offset` as the HAL's `while … bit_is_clear() {}` does, 1 µs a poll;
/// the number of polls, `None` after 10 ms.
fn poll(rcc: &mut Rcc, m: &mut TestMachine, offset: u32, flag: u32) -> Option<u32> {
    for polls in 0..10_000 {
        if rcc.read(offset, Width::Word, m) & flag != 0 {
            return Some(polls);
        }
        m.now += 1_000;
    }
    None
}

/// What stm32f4xx-hal 0.23's `rcc.freeze(Config::hse(8.MHz()).sysclk(168.MHz())
/// .pclk1(42.MHz()).pclk2(84.MHz()))` writes and polls (rcc/f4/mod.rs `freeze_internal`,
/// rcc/f4/pll.rs `fast_setup`), as `board::hw::clocks` asks; returns whether every poll ended.
fn hal_freeze(rcc: &mut Rcc, m: &mut TestMachine) -> bool {
    // PLLCFGR.write from the reset value: M = 4, N = 168, P = 2 (0), Q = 7, PLLSRC = HSE.
    let pllcfgr = 0x2000_0000 | 7 << 24 | 1 << 22 | 168 << 6 | 4;
    rcc.write(reg::PLLCFGR, Width::Word, pllcfgr, m);
    rmw(rcc, m, reg::CR, |v| v | cr::HSEON);
    if poll(rcc, m, reg::CR, cr::HSERDY).is_none() {
        return false;
    }
    rmw(rcc, m, reg::CR, |v| v | cr::PLLON);
    if poll(rcc, m, reg::CR, cr::PLLRDY).is_none() {
        return false;
    }
    // PPRE2 = /2 (100), PPRE1 = /4 (101), HPRE = /1.
    rmw(rcc, m, reg::CFGR, |v| v & !0xFCF0 | 0b100 << 13 | 0b101 << 10);
    rmw(rcc, m, reg::CFGR, |v| v & !3 | 2);
    true
}

#[test]
fn reset_values() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    assert_eq!(rcc.read(reg::CR, Width::Word, &mut m) & 0xFFFF_00FF, 0x83);
    assert_eq!(rcc.read(reg::PLLCFGR, Width::Word, &mut m), 0x2400_3010);
    assert_eq!(rcc.read(reg::CFGR, Width::Word, &mut m), 0);
    assert_eq!(rcc.read(reg::AHB1ENR, Width::Word, &mut m), 0x0010_0000);
    assert_eq!(rcc.read(reg::CSR, Width::Word, &mut m), 0x0E00_0000);
    assert_eq!(rcc.current_clocks(), Clocks::RESET);
}

#[test]
fn hal_freeze_gives_the_board_clocks() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    assert!(hal_freeze(&mut rcc, &mut m));
    assert_eq!(rcc.read(reg::CFGR, Width::Word, &mut m) & 0xF, 0b1010, "SWS = SW = PLL");
    assert_eq!(
        rcc.clocks(),
        Some(Clocks { sysclk: 168_000_000, hclk: 168_000_000, pclk1: 42_000_000, pclk2: 84_000_000 })
    );
    assert!(rcc.notes().is_empty(), "{:?}", rcc.notes());
}

#[test]
fn ready_flags_rise_after_the_start_up_time() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    rmw(&mut rcc, &mut m, reg::CR, |v| v | cr::HSEON);
    assert_eq!(rcc.read(reg::CR, Width::Word, &mut m) & cr::HSERDY, 0);
    assert_eq!(rcc.next_event(), Some(RccTiming::FAST.hse));
    m.now = RccTiming::FAST.hse;
    assert_ne!(rcc.read(reg::CR, Width::Word, &mut m) & cr::HSERDY, 0);
}

#[rstest]
#[case::no_crystal(Hse::None, false)]
#[case::crystal_bypassed(Hse::Crystal(8_000_000), true)]
#[case::external_clock_not_bypassed(Hse::External(8_000_000), false)]
fn hse_that_cannot_start_never_gets_ready(#[case] hse: Hse, #[case] bypass: bool) {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(hse);
    let byp = if bypass { cr::HSEBYP } else { 0 };
    rmw(&mut rcc, &mut m, reg::CR, |v| v | byp | cr::HSEON);
    assert_eq!(poll(&mut rcc, &mut m, reg::CR, cr::HSERDY), None);
    assert!(!hal_freeze(&mut rcc, &mut m), "the HAL would spin forever");
    assert_eq!(rcc.current_clocks(), Clocks::RESET);
}

#[test]
fn external_clock_with_bypass_starts() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::External(8_000_000));
    rmw(&mut rcc, &mut m, reg::CR, |v| v | cr::HSEBYP | cr::HSEON);
    assert!(poll(&mut rcc, &mut m, reg::CR, cr::HSERDY).is_some());
}

#[rstest]
#[case::vco_input_too_low(16, 336, 0)] // 0.5 MHz in
#[case::vco_output_too_high(4, 240, 0)] // 480 MHz out
#[case::vco_output_too_low(8, 50, 0)] // 50 MHz out
#[case::pllm_one(1, 100, 3)] // M = 1 is a wrong configuration
fn pll_outside_its_range_never_locks(#[case] m_div: u32, #[case] n: u32, #[case] p: u32) {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    rcc.write(reg::PLLCFGR, Width::Word, 7 << 24 | 1 << 22 | p << 16 | n << 6 | m_div, &mut m);
    rmw(&mut rcc, &mut m, reg::CR, |v| v | cr::HSEON | cr::PLLON);
    assert_eq!(poll(&mut rcc, &mut m, reg::CR, cr::PLLRDY), None);
    assert!(matches!(rcc.notes(), [RccNote::PllOutOfRange { .. }]));
    rmw(&mut rcc, &mut m, reg::CFGR, |v| v | 2);
    m.now += 1_000_000;
    assert_eq!(rcc.read(reg::CFGR, Width::Word, &mut m) & 0xC, 0, "SWS stays HSI");
}

#[test]
fn switch_waits_for_its_clock() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    rmw(&mut rcc, &mut m, reg::CFGR, |v| v | 1);
    assert_eq!(rcc.read(reg::CFGR, Width::Word, &mut m), 1, "SW = HSE, SWS = HSI");
    rmw(&mut rcc, &mut m, reg::CR, |v| v | cr::HSEON);
    m.now += RccTiming::FAST.hse;
    assert_eq!(rcc.read(reg::CFGR, Width::Word, &mut m), 0b0101, "switched once ready");
    assert_eq!(rcc.current_clocks().sysclk, 8_000_000);
}

#[rstest]
#[case::hsi_in_use(cr::HSION)]
#[case::hse_through_pll(cr::HSEON)]
#[case::pll_in_use(cr::PLLON)]
fn oscillator_in_use_cannot_be_stopped(#[case] bit: u32) {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    if bit != cr::HSION {
        assert!(hal_freeze(&mut rcc, &mut m));
    }
    rmw(&mut rcc, &mut m, reg::CR, |v| v & !bit);
    assert_ne!(rcc.read(reg::CR, Width::Word, &mut m) & bit, 0);
    assert!(rcc.notes().contains(&RccNote::StopRefused));
}

#[test]
fn pll_configuration_frozen_while_running() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    assert!(hal_freeze(&mut rcc, &mut m));
    let before = rcc.read(reg::PLLCFGR, Width::Word, &mut m);
    rcc.write(reg::PLLCFGR, Width::Word, 0x2400_3010, &mut m);
    assert_eq!(rcc.read(reg::PLLCFGR, Width::Word, &mut m), before);
    assert_eq!(rcc.notes(), [RccNote::PllConfigWhileOn]);
}

#[rstest]
#[case::hpre_div2(0b1000 << 4, 8_000_000, 8_000_000, 8_000_000)]
#[case::hpre_div64(0b1100 << 4, 250_000, 250_000, 250_000)]
#[case::ppre1_div4_ppre2_div16(0b101 << 10 | 0b111 << 13, 16_000_000, 4_000_000, 1_000_000)]
fn prescalers(#[case] cfgr: u32, #[case] hclk: u32, #[case] pclk1: u32, #[case] pclk2: u32) {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::None);
    rcc.write(reg::CFGR, Width::Word, cfgr, &mut m);
    assert_eq!(rcc.current_clocks(), Clocks { sysclk: 16_000_000, hclk, pclk1, pclk2 });
}

#[test]
fn bus_clock_above_maximum_is_noted() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    assert!(hal_freeze(&mut rcc, &mut m));
    rmw(&mut rcc, &mut m, reg::CFGR, |v| v & !(7 << 10));
    assert!(matches!(rcc.notes(), [RccNote::AboveMaximum { clocks }] if clocks.pclk1 == 168_000_000));
}

/// `GPIOx::enable` / `reset` of the HAL (rcc/f4/enable.rs): bit-band set of the ENR bit, then
/// set and clear of the RSTR bit (the machine turns the bit-band writes into these).
#[rstest]
#[case::gpioa(reg::AHB1ENR, reg::AHB1RSTR, ClockGate::Ahb1(0))]
#[case::usart2(reg::APB1ENR, reg::APB1RSTR, ClockGate::Apb1(17))]
#[case::can1(reg::APB1ENR, reg::APB1RSTR, ClockGate::Apb1(25))]
#[case::usart1(reg::APB2ENR, reg::APB2RSTR, ClockGate::Apb2(4))]
fn clock_gate_and_peripheral_reset(#[case] enr: u32, #[case] rstr: u32, #[case] gate: ClockGate) {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::None);
    let (_, bit) = bus_index(gate);
    assert_eq!(rcc.clock_gate(gate), Some(false));
    rmw(&mut rcc, &mut m, enr, |v| v | 1 << bit);
    assert_eq!(rcc.clock_gate(gate), Some(true));
    rmw(&mut rcc, &mut m, rstr, |v| v | 1 << bit);
    assert!(rcc.in_reset(gate));
    rmw(&mut rcc, &mut m, rstr, |v| v & !(1 << bit));
    assert!(!rcc.in_reset(gate));
    assert_eq!(rcc.take_peripheral_resets(), [gate]);
    assert!(rcc.take_peripheral_resets().is_empty());
}

#[rstest]
#[case::software(ResetCause::Software, csr::SFTRSTF | csr::PINRSTF)]
#[case::watchdog(ResetCause::IndependentWatchdog, csr::IWDGRSTF | csr::PINRSTF)]
#[case::pin(ResetCause::Pin, csr::PINRSTF)]
fn reset_flags(#[case] cause: ResetCause, #[case] flags: u32) {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    rcc.write(reg::CSR, Width::Word, csr::RMVF, &mut m);
    assert_eq!(rcc.read(reg::CSR, Width::Word, &mut m), 0, "RMVF clears the flags");
    assert!(hal_freeze(&mut rcc, &mut m));
    rcc.reset(ResetKind::System);
    rcc.record_reset_cause(cause);
    assert_eq!(rcc.read(reg::CSR, Width::Word, &mut m), flags);
    assert_eq!(rcc.current_clocks(), Clocks::RESET, "back on HSI");
    rcc.reset(ResetKind::PowerOn);
    assert_eq!(rcc.read(reg::CSR, Width::Word, &mut m), 0x0E00_0000);
}

#[test]
fn ready_interrupt_flag() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    rcc.write(reg::CIR, Width::Word, 1 << 11, &mut m); // HSERDYIE
    rmw(&mut rcc, &mut m, reg::CR, |v| v | cr::HSEON);
    rcc.advance(RccTiming::FAST.hse, &mut m);
    assert_eq!(rcc.read(reg::CIR, Width::Word, &mut m) & 0xFF, 1 << 3, "HSERDYF");
    assert_eq!(m.irqs.get(&IRQ), Some(&true));
    rcc.write(reg::CIR, Width::Word, 1 << 11 | 1 << 19, &mut m); // HSERDYC
    assert_eq!(rcc.read(reg::CIR, Width::Word, &mut m) & 0xFF, 0);
    assert_eq!(m.irqs.get(&IRQ), Some(&false));
}

#[test]
fn hsebyp_is_written_only_while_the_hse_is_off() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::Crystal(8_000_000));
    rmw(&mut rcc, &mut m, reg::CR, |v| v | cr::HSEON);
    rmw(&mut rcc, &mut m, reg::CR, |v| v | cr::HSEBYP);
    assert_eq!(rcc.read(reg::CR, Width::Word, &mut m) & cr::HSEBYP, 0);
    m.now += RccTiming::FAST.hse;
    assert_ne!(rcc.read(reg::CR, Width::Word, &mut m) & cr::HSERDY, 0, "the crystal still runs");
    rmw(&mut rcc, &mut m, reg::CR, |v| v & !cr::HSEON);
    rmw(&mut rcc, &mut m, reg::CR, |v| v | cr::HSEBYP);
    assert_ne!(rcc.read(reg::CR, Width::Word, &mut m) & cr::HSEBYP, 0);
}

#[test]
fn lsi_ready_after_its_start_up() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::new(Hse::None);
    rcc.write(reg::CSR, Width::Word, csr::LSION, &mut m);
    assert_eq!(rcc.read(reg::CSR, Width::Word, &mut m) & csr::LSIRDY, 0);
    m.now += RccTiming::FAST.hsi;
    assert_ne!(rcc.read(reg::CSR, Width::Word, &mut m) & csr::LSIRDY, 0);
}

#[test]
fn datasheet_timing_makes_the_hal_wait_longer() {
    let mut m = TestMachine::default();
    let mut rcc = Rcc::with_timing(Hse::Crystal(8_000_000), RccTiming::DATASHEET);
    assert!(hal_freeze(&mut rcc, &mut m));
    assert!(m.now >= RccTiming::DATASHEET.hse + RccTiming::DATASHEET.pll);
}
