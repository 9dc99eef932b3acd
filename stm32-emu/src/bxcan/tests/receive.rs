//! Receive FIFOs: FMP, FULL, FOVR with the RFLM rule, RFOM, the RX interrupt lines.

use super::*;
use rstest::rstest;

/// On the bus at 125 kbit/s, one bank accepting everything into FIFO 0.
fn accepting_all() -> Driver {
    let mut d = Driver::new(PCLK1);
    d.builder();
    d.set_bit_timing(BTR_125K_AT_42MHZ);
    d.modify_filters();
    d.enable_bank_mask16(0, false, [Mask16 { id: 0, mask: 0 }; 2]);
    d.drop_filters();
    d.enable_interrupts(ier::FMPIE0 | ier::FFIE0 | ier::FOVIE0);
    d.enable();
    d
}

#[test]
fn message_pending_and_release() {
    let mut d = accepting_all();
    d.hear(&data(0x100, &[1, 2, 3, 4, 5]), 125_000);
    assert_eq!(d.read(offset::RF0R), 1);
    assert!(d.m.irqs[usize::from(irq::RX0)]);
    assert_eq!(d.read(offset::RI0R), 0x100 << 21);
    assert_eq!(d.read(offset::RI0R + 4), 5, "DLC 5, FMI 0");
    assert_eq!(d.read(offset::RI0R + 8), 0x0403_0201);
    assert_eq!(d.read(offset::RI0R + 12), 0x05);
    d.write(offset::RF0R, rfr::RFOM);
    assert_eq!(d.read(offset::RF0R), 0);
    assert!(!d.m.irqs[usize::from(irq::RX0)]);
    d.write(offset::RF0R, rfr::RFOM);
    assert_eq!(d.read(offset::RF0R), 0, "RFOM on an empty FIFO has no effect");
}

#[test]
fn fifo_order() {
    let mut d = accepting_all();
    for id in [0x300, 0x100, 0x200] {
        d.hear(&data(id, &[]), 125_000);
    }
    for id in [0x300, 0x100, 0x200] {
        assert_eq!(d.receive(), Nb::Ok(data(id, &[])));
    }
    assert_eq!(d.receive(), Nb::WouldBlock);
}

#[rstest]
// RFLM = 0: the newest message replaces the last one stored; RFLM = 1: it is discarded.
#[case::not_locked(false, 0x400)]
#[case::locked(true, 0x300)]
fn overrun(#[case] locked: bool, #[case] third: u16) {
    let mut d = accepting_all();
    if locked {
        d.modify(offset::MCR, |r| r | mcr::RFLM);
    }
    for id in [0x100, 0x200, 0x300] {
        d.hear(&data(id, &[]), 125_000);
    }
    assert_eq!(d.read(offset::RF0R), 3 | rfr::FULL);
    d.hear(&data(0x400, &[]), 125_000);
    assert_eq!(d.read(offset::RF0R), 3 | rfr::FULL | rfr::FOVR);
    // bxcan's receive reports the overrun once (clearing FOVR), then the three messages.
    assert_eq!(d.receive(), Nb::Other(Overrun));
    assert_eq!(d.read(offset::RF0R) & rfr::FOVR, 0);
    assert_eq!(d.receive(), Nb::Ok(data(0x100, &[])));
    assert_eq!(d.receive(), Nb::Ok(data(0x200, &[])));
    assert_eq!(d.receive(), Nb::Ok(data(third, &[])));
    assert_eq!(d.receive(), Nb::WouldBlock);
}

#[test]
fn full_cleared_by_writing_one() {
    let mut d = accepting_all();
    for id in [0x100, 0x200, 0x300] {
        d.hear(&data(id, &[]), 125_000);
    }
    d.write(offset::RF0R, rfr::RFOM);
    assert_ne!(d.read(offset::RF0R) & rfr::FULL, 0, "FULL stays until software clears it");
    d.write(offset::RF0R, rfr::FULL);
    assert_eq!(d.read(offset::RF0R), 2);
}

#[test]
fn rx_line_follows_each_enable_bit() {
    let mut d = accepting_all();
    d.write(offset::IER, ier::FFIE0);
    d.hear(&data(0x100, &[]), 125_000);
    assert!(!d.m.irqs[usize::from(irq::RX0)], "FMP alone with only FFIE0");
    d.hear(&data(0x100, &[]), 125_000);
    d.hear(&data(0x100, &[]), 125_000);
    assert!(d.m.irqs[usize::from(irq::RX0)], "FULL with FFIE0");
    assert!(!d.m.irqs[usize::from(irq::RX1)]);
}

#[test]
fn nothing_received_in_initialisation() {
    let mut d = accepting_all();
    d.builder();
    assert_eq!(d.hear(&data(0x100, &[]), 125_000), Response::Quiet);
    assert_eq!(d.read(offset::RF0R), 0);
}
