//! Reset values, the initialisation and sleep handshakes, BTR protection, bus access rules.

use super::*;
use rstest::rstest;

#[rstest]
// RM0090 §32.9.2, §32.9.4: the reset values.
#[case::mcr(offset::MCR, 0x0001_0002)]
#[case::msr(offset::MSR, 0x0000_0C02)]
#[case::tsr(offset::TSR, 0x1C00_0000)]
#[case::rf0r(offset::RF0R, 0)]
#[case::rf1r(offset::RF1R, 0)]
#[case::ier(offset::IER, 0)]
#[case::esr(offset::ESR, 0)]
#[case::btr(offset::BTR, 0x0123_0000)]
#[case::fmr(offset::FMR, 0x2A1C_0E01)]
#[case::fa1r(filter::offset::FA1R, 0)]
fn reset_values(#[case] reg: u32, #[case] value: u32) {
    assert_eq!(Driver::new(PCLK1).read(reg), value);
}

#[test]
fn builder_enters_initialisation_from_sleep() {
    let mut d = Driver::new(PCLK1);
    assert_eq!(d.can.mode(), Mode::Sleep);
    d.builder();
    assert_eq!(d.can.mode(), Mode::Init);
    assert_eq!(d.read(offset::MSR) & 0b11, msr::INAK);
    assert_eq!(d.read(offset::MCR) & 0b11, mcr::INRQ);
}

#[test]
fn enable_goes_through_sleep_to_normal() {
    let mut d = Driver::new(PCLK1);
    d.builder();
    d.set_bit_timing(BTR_125K_AT_42MHZ);
    d.leave_disabled();
    assert_eq!(d.can.mode(), Mode::Sleep);
    assert_eq!(d.enable_non_blocking(), Nb::WouldBlock, "the first call asks to leave sleep");
    assert_eq!(d.enable_non_blocking(), Nb::Ok(()), "then the controller is synchronised");
    assert_eq!(d.can.mode(), Mode::Normal);
    assert_eq!(d.read(offset::MSR) & 0b11, 0);
    assert_ne!(d.read(offset::MCR) & mcr::ABOM, 0, "enable_non_blocking sets ABOM");
}

#[test]
fn firmware_setup() {
    let mut d = Driver::new(PCLK1);
    d.firmware_setup();
    assert_eq!(d.can.mode(), Mode::Normal);
    assert_eq!(d.read(offset::BTR), BTR_125K_AT_42MHZ);
    assert_eq!(d.can.bit_timing().bit_rate(PCLK1), 125_000);
    assert_eq!(d.read(offset::MCR), mcr::DBF | mcr::ABOM);
    assert_eq!(d.read(offset::IER), 0x0000_8613);
    assert_eq!(d.read(filter::offset::FA1R), 0b11);
    assert_eq!(d.read(filter::offset::FM1R) | d.read(filter::offset::FS1R), 0, "16-bit mask mode");
    assert_eq!(d.read(offset::FMR) & 1, 0, "FINIT left");
    // Bank 0: FR1 = own mask << 16 | own id, FR2 = strobe.
    assert_eq!(d.read(filter::offset::F0R1), (0x7F8 << 5 | 8) << 16 | 0x428 << 5);
    assert_eq!(d.read(filter::offset::F0R1 + 4), (0x607 << 5 | 8) << 16 | 0x400 << 5);
}

#[rstest]
#[case::in_sleep_after_reset(false, false)]
#[case::in_normal_mode(true, true)]
fn btr_refused_outside_initialisation(#[case] init_first: bool, #[case] enable: bool) {
    let mut d = Driver::new(PCLK1);
    if init_first {
        d.builder();
    }
    if enable {
        d.enable();
    }
    d.write(offset::BTR, BTR_125K_AT_42MHZ | LBKM);
    assert_eq!(d.read(offset::BTR), BTR_RESET_VALUE);
}

#[test]
fn btr_reserved_bits_read_zero() {
    let mut d = Driver::new(PCLK1);
    d.builder();
    d.write(offset::BTR, 0xFFFF_FFFF);
    assert_eq!(d.read(offset::BTR), 0xC37F_03FF);
}

#[rstest]
// INRQ and SLEEP both set: no transition from any mode (RM0090 §32.4 diagram).
#[case::from_sleep(Mode::Sleep)]
#[case::from_init(Mode::Init)]
#[case::from_normal(Mode::Normal)]
fn both_requests_keep_the_mode(#[case] mode: Mode) {
    let mut d = Driver::new(PCLK1);
    match mode {
        Mode::Sleep => {}
        Mode::Init => d.builder(),
        Mode::Normal => {
            d.builder();
            d.enable();
        }
    }
    d.modify(offset::MCR, |r| r | mcr::INRQ | mcr::SLEEP);
    assert_eq!(d.can.mode(), mode);
}

#[test]
fn sleep_acknowledge_interrupt() {
    let mut d = Driver::new(PCLK1);
    d.builder();
    d.enable_interrupts(ier::SLKIE);
    d.leave_disabled();
    assert_ne!(d.read(offset::MSR) & msr::SLAKI, 0);
    assert!(d.m.irqs[usize::from(irq::SCE)]);
    // Cleared by hardware when SLAK clears.
    let _ = d.enable_non_blocking();
    assert_eq!(d.read(offset::MSR) & msr::SLAKI, 0);
    assert!(!d.m.irqs[usize::from(irq::SCE)]);
}

#[rstest]
#[case::automatic_wakeup(true, Mode::Normal)]
#[case::no_automatic_wakeup(false, Mode::Sleep)]
fn wakeup_on_bus_activity(#[case] awum: bool, #[case] after: Mode) {
    let mut d = Driver::new(PCLK1);
    d.builder();
    d.set_bit_timing(BTR_125K_AT_42MHZ);
    if awum {
        d.modify(offset::MCR, |r| r | mcr::AWUM);
    }
    d.enable_interrupts(ier::WKUIE);
    d.leave_disabled();
    assert_eq!(d.hear(&data(0x100, &[]), 125_000), Response::Quiet);
    assert_ne!(d.read(offset::MSR) & msr::WKUI, 0);
    assert!(d.m.irqs[usize::from(irq::SCE)]);
    assert_eq!(d.can.mode(), after);
    assert_eq!(d.read(offset::MCR) & mcr::SLEEP == 0, awum, "AWUM clears SLEEP");
    d.write(offset::MSR, msr::WKUI);
    assert!(!d.m.irqs[usize::from(irq::SCE)]);
}

#[test]
fn clock_gate_closed() {
    let mut d = Driver::new(PCLK1);
    d.m.gate_open = false;
    assert_eq!(d.read(offset::MCR), 0);
    d.write(offset::MCR, mcr::INRQ);
    d.m.gate_open = true;
    assert_eq!(d.can.mode(), Mode::Sleep);
}

#[test]
fn narrow_accesses() {
    let mut d = Driver::new(PCLK1);
    assert_eq!(d.can.read(offset::MSR + 1, Width::Byte, &mut d.m), 0x0C);
    assert_eq!(d.can.read(offset::FMR + 2, Width::Half, &mut d.m), 0x2A1C);
    d.can.write(offset::MCR, Width::Half, mcr::INRQ, &mut d.m);
    assert_eq!(d.can.mode(), Mode::Sleep, "a half-word write is ignored");
}

#[test]
fn master_reset_keeps_the_filters() {
    let mut d = Driver::new(PCLK1);
    d.firmware_setup();
    d.write(offset::MCR, mcr::RESET);
    assert_eq!(d.read(offset::MCR), mcr::RESET_VALUE, "RESET reads 0 again");
    assert_eq!(d.read(offset::BTR), BTR_RESET_VALUE);
    assert_eq!(d.can.mode(), Mode::Sleep);
    assert_eq!(d.read(filter::offset::FA1R), 0b11);
    // A power-on or system reset clears them too.
    d.can.reset();
    assert_eq!(d.read(filter::offset::FA1R), 0);
    assert_eq!(d.read(offset::FMR), 0x2A1C_0E01);
}

#[rstest]
#[case::power_on(ResetKind::PowerOn)]
#[case::system(ResetKind::System)]
fn machine_reset(#[case] kind: ResetKind) {
    let mut d = Driver::new(PCLK1);
    d.firmware_setup();
    Peripheral::reset(&mut d.can, kind);
    assert_eq!(d.can.mode(), Mode::Sleep);
    assert_eq!(d.read(offset::IER), 0);
    assert_eq!(d.read(filter::offset::FA1R), 0);
    assert_eq!(d.read(offset::FMR), 0x2A1C_0E01);
}
