//! Error counting, error passive, bus-off and its recovery, ESR and the SCE line, and a bus at
//! another bit rate.

use super::*;
use rstest::rstest;

fn firmware() -> Driver {
    let mut d = Driver::new(PCLK1);
    d.firmware_setup();
    let _ = d.enable_non_blocking();
    d
}

/// ESR's flags: EWGF, EPVF, BOFF.
fn flags(d: &mut Driver) -> u32 {
    d.read(offset::ESR) & 0b111
}

#[test]
fn lone_node_stops_at_error_passive() {
    let mut d = firmware();
    assert_eq!(d.transmit(&data(0x42F, &[0, 1])), Nb::Ok((0, None)));
    for attempt in 1..=16 {
        d.send(TxOutcome::NoAcknowledge).unwrap();
        assert_eq!(d.counters(), (8 * attempt, 0));
    }
    assert_eq!(flags(&mut d), 0b011, "EWGF and EPVF at TEC 128");
    assert_eq!(d.read(offset::ESR) >> 4 & 7, 3, "LEC: acknowledgement error");
    assert_eq!(d.read(offset::TSR) & 0xFF, tsr::TERR, "still pending, TERR0");
    assert!(d.m.irqs[usize::from(irq::SCE)], "EPVIE: ERRI");
    // ISO 11898-1 rule 3a: error passive without ACK, no error flag seen: TEC stays.
    for _ in 0..100 {
        d.send(TxOutcome::NoAcknowledge).unwrap();
    }
    assert_eq!(d.counters(), (128, 0));
    assert!(!d.can.is_bus_off());
    // A node joins and acknowledges: TEC − 1, LEC 0.
    d.send(TxOutcome::Acknowledged).unwrap();
    assert_eq!(d.counters(), (127, 0));
    assert_eq!(d.read(offset::ESR) >> 4 & 7, 0);
    assert_eq!(flags(&mut d), 0b001, "error active again, still warning");
}

#[test]
fn error_flags_drive_the_transmitter_bus_off_and_abom_recovers() {
    let mut d = firmware();
    d.transmit(&data(0x42F, &[]));
    for _ in 0..31 {
        d.send(TxOutcome::ErrorFlagged).unwrap();
    }
    assert_eq!(d.counters(), (248, 0));
    let bus_state = d.can_bus_state();
    assert_eq!(bus_state & 0b111, 0b011);
    assert!(!d.m.irqs[usize::from(irq::SCE)], "ERRI cleared by can_bus_state");
    d.send(TxOutcome::ErrorFlagged).unwrap();
    assert!(d.can.is_bus_off());
    let esr = d.read(offset::ESR);
    assert_eq!(esr & 0b111, 0b111, "BOFF");
    assert_eq!(esr >> 4 & 7, 4, "LEC: bit recessive error");
    assert_eq!(esr >> 16 & 0xFF, 255, "TEC shown saturated");
    assert!(d.m.irqs[usize::from(irq::SCE)], "BOFIE: ERRI");
    assert_eq!(d.can.poll_transmit(d.m.now, &mut d.m), None, "bus-off sends nothing");
    assert_eq!(d.hear(&data(0x42C, &[]), 125_000), Response::Quiet);
    // ABOM (set by enable_non_blocking): recovery after 128 × 11 bits = 11.264 ms at 125k.
    assert_eq!(d.can.next_deadline(), Some(11_264_000));
    assert_eq!(d.can.next_event(), Some(11_264_000));
    d.wait(11_263_999);
    assert!(d.can.is_bus_off());
    d.wait(1);
    assert!(!d.can.is_bus_off());
    assert_eq!(d.counters(), (0, 0));
    assert_eq!(flags(&mut d), 0);
    assert!(d.send(TxOutcome::Acknowledged).is_some(), "the pending frame goes out again");
}

/// Bus-off with ABOM cleared, through 32 error-flagged attempts.
fn bus_off_without_abom() -> Driver {
    let mut d = firmware();
    d.modify(offset::MCR, |r| r & !mcr::ABOM);
    d.transmit(&data(0x42F, &[]));
    for _ in 0..32 {
        d.send(TxOutcome::ErrorFlagged).unwrap();
    }
    assert!(d.can.is_bus_off());
    d
}

#[test]
fn without_abom_recovery_waits_for_software() {
    let mut d = bus_off_without_abom();
    assert_eq!(d.can.next_deadline(), None);
    d.wait(1_000_000_000);
    assert!(d.can.is_bus_off(), "no recovery without ABOM until init is entered and left");
    // The firmware's restart(): modify_config (init), leave_disabled, enable_non_blocking.
    d.builder();
    d.leave_disabled();
    let _ = d.enable_non_blocking();
    assert_eq!(d.can.mode(), Mode::Normal);
    let deadline = d.can.next_deadline().unwrap();
    assert_eq!(deadline, d.m.now + 11_264_000);
    d.wait(11_264_000);
    assert!(!d.can.is_bus_off());
    assert_eq!(d.counters(), (0, 0));
}

#[test]
fn initialisation_interrupts_the_recovery() {
    let mut d = firmware();
    d.transmit(&data(0x42F, &[]));
    for _ in 0..32 {
        d.send(TxOutcome::ErrorFlagged).unwrap();
    }
    d.wait(10_000_000);
    d.builder();
    d.wait(10_000_000);
    assert_eq!(d.can.next_deadline(), None, "CANRX not monitored in initialisation");
    d.enable();
    d.wait(11_263_999);
    assert!(d.can.is_bus_off(), "the count started over");
    d.wait(1);
    assert!(!d.can.is_bus_off());
}

#[test]
fn receive_counter() {
    let mut d = firmware();
    // The 42 MHz timing on a 250 kbit/s bus: every frame is a receive error.
    for n in 1..=127 {
        assert_eq!(d.hear(&data(0x42C, &[]), 250_000), Response::ErrorFlag);
        assert_eq!(d.counters(), (0, n));
    }
    assert_eq!(d.read(offset::ESR) >> 4 & 7, 1, "LEC: stuff error");
    assert_eq!(d.hear(&data(0x42C, &[]), 250_000), Response::ErrorFlag, "last active flag");
    assert_eq!(d.counters(), (0, 128));
    assert_eq!(flags(&mut d), 0b011, "error passive");
    assert_eq!(d.hear(&data(0x42C, &[]), 250_000), Response::Quiet, "passive error flag");
    assert_eq!(d.read(offset::RF0R), 0, "nothing received");
    // A frame at the right rate: REC from above 127 to 120 (RM0090 §32.9.2), then − 1.
    assert_eq!(d.hear(&data(0x42C, &[]), 125_000), Response::Acknowledge);
    assert_eq!(d.counters(), (0, 120));
    d.hear(&data(0x42C, &[]), 125_000);
    assert_eq!(d.counters(), (0, 119));
    assert_eq!(d.read(offset::RF0R) & 0b11, 2);
}

#[test]
fn disturbed_frame_is_a_receive_error() {
    let mut d = firmware();
    d.can.on_wire(&data(0x42C, &[]), 125_000, true, 0, &mut d.m);
    assert_eq!(d.counters(), (0, 1));
    assert_eq!(d.read(offset::RF0R), 0);
}

#[rstest]
// The emulated board's reset clock with the real board's timing: 16 MHz / 336 = 47.6 kbit/s.
#[case::hsi_with_the_42_mhz_timing(16_000_000, 125_000)]
// The right clock, a bus at 500 kbit/s.
#[case::another_rate(42_000_000, 500_000)]
fn at_the_wrong_rate_nothing_gets_through(#[case] pclk1: u32, #[case] bus: u32) {
    let mut d = Driver::new(pclk1);
    d.firmware_setup();
    let _ = d.enable_non_blocking();
    // What it hears: nothing but errors.
    for _ in 0..10 {
        assert_eq!(d.hear(&data(0x42C, &[1]), bus), Response::ErrorFlag);
    }
    assert_eq!(d.read(offset::RF0R), 0);
    assert_eq!(d.counters(), (0, 10));
    // What it sends: at its own rate, which the world's nodes cannot decode; error active
    // nodes flag it, so TEC rises past error passive to bus-off.
    d.transmit(&data(0x42F, &[]));
    let tx = d.can.poll_transmit(0, &mut d.m).unwrap();
    assert_eq!(tx.bit_rate, d.can.bit_timing().bit_rate(pclk1));
    assert!(!d.can.bit_timing().follows(pclk1, bus));
    d.can.transmit_outcome(TxOutcome::ErrorFlagged, 0, &mut d.m);
    for _ in 0..31 {
        d.send(TxOutcome::ErrorFlagged).unwrap();
    }
    assert!(d.can.is_bus_off());
}

#[test]
fn software_sets_lec_to_seven() {
    let mut d = firmware();
    d.write(offset::ESR, 7 << 4 | 0xFFFF_0007);
    assert_eq!(d.read(offset::ESR), 7 << 4, "only LEC is writable");
}

#[test]
fn lec_interrupt() {
    let mut d = firmware();
    d.enable_interrupts(ier::LECIE);
    d.transmit(&data(0x42F, &[]));
    d.send(TxOutcome::NoAcknowledge).unwrap();
    assert_ne!(d.read(offset::MSR) & msr::ERRI, 0);
    assert!(d.m.irqs[usize::from(irq::SCE)]);
}
