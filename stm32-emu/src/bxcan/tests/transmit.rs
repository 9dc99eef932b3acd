//! Transmit mailboxes: bxcan's `transmit`, TSR, priority, abort, NART, test modes.

use super::*;
use rstest::rstest;

fn on_bus() -> Driver {
    let mut d = Driver::new(PCLK1);
    d.firmware_setup();
    let _ = d.enable_non_blocking();
    d
}

/// Writes a frame straight into mailbox `m` (as any software may).
fn request(d: &mut Driver, m: u32, frame: &Frame) {
    let base = offset::TI0R + 0x10 * m;
    d.write(base + 4, u32::from(frame.dlc()));
    let [low, high] = frame.data_registers();
    d.write(base + 8, low);
    d.write(base + 12, high);
    d.write(base, frame.id_register() | 1);
}

#[test]
fn transmit_and_acknowledge() {
    let mut d = on_bus();
    let frame = data(0x42B, &[0x80, 0x4E, 1, 2, 3, 4, 5, 6]);
    assert!(d.is_transmitter_idle());
    assert_eq!(d.transmit(&frame), Nb::Ok((0, None)));
    let tsr = d.read(offset::TSR);
    assert_eq!(tsr >> 26 & 0b111, 0b110, "TME0 clear");
    assert_eq!(tsr >> 24 & 0b11, 1, "CODE: the next empty mailbox");
    assert_eq!(d.read(offset::TI0R) & 1, 1, "TXRQ reads 1 while pending");
    let tx = d.send(TxOutcome::Acknowledged).unwrap();
    assert_eq!(tx, Transmission { frame, bit_rate: 125_000 });
    let tsr = d.read(offset::TSR);
    assert_eq!(tsr & 0xFF, tsr::RQCP | tsr::TXOK);
    assert_eq!(tsr >> 26 & 0b111, 0b111);
    assert_eq!(d.read(offset::TI0R) & 1, 0, "TXRQ cleared");
    assert!(d.m.irqs[usize::from(irq::TX)], "TMEIE and RQCP0");
    d.clear_tx_interrupt();
    assert_eq!(d.read(offset::TSR), 0x1C00_0000, "RQCP0 written 1 clears TXOK0 too");
    assert!(!d.m.irqs[usize::from(irq::TX)]);
    assert_eq!(d.send(TxOutcome::Acknowledged), None, "nothing left");
}

#[test]
fn priority_by_identifier() {
    let mut d = on_bus();
    for (m, id) in [(0, 0x300), (1, 0x100), (2, 0x200)] {
        request(&mut d, m, &data(id, &[]));
    }
    let tsr = d.read(offset::TSR);
    assert_eq!(tsr >> 24 & 0b11, 0, "CODE: all pending, mailbox 0 has the lowest priority");
    assert_eq!(tsr >> 29, 0b001, "LOW0");
    let order: Vec<u16> = (0..3)
        .map(|_| match d.send(TxOutcome::Acknowledged).unwrap().frame.id() {
            FrameId::Standard(id) => id,
            FrameId::Extended(_) => unreachable!(),
        })
        .collect();
    assert_eq!(order, [0x100, 0x200, 0x300]);
}

#[test]
fn equal_identifiers_go_by_mailbox_number() {
    let mut d = on_bus();
    request(&mut d, 2, &data(0x100, &[2]));
    request(&mut d, 1, &data(0x100, &[1]));
    assert_eq!(d.send(TxOutcome::Acknowledged).unwrap().frame.data(), [1]);
}

#[test]
fn priority_by_request_order() {
    let mut d = on_bus();
    d.modify(offset::MCR, |r| r | mcr::TXFP);
    for (m, id) in [(2, 0x300), (0, 0x100), (1, 0x200)] {
        request(&mut d, m, &data(id, &[]));
    }
    assert_eq!(d.read(offset::TSR) >> 29, 0b010, "LOW1: the latest request");
    let first = d.send(TxOutcome::Acknowledged).unwrap();
    assert_eq!(first.frame.id(), FrameId::Standard(0x300));
}

#[test]
fn bxcan_refuses_a_frame_of_lower_priority_than_a_pending_one() {
    let mut d = on_bus();
    assert_eq!(d.transmit(&data(0x200, &[])), Nb::Ok((0, None)));
    assert_eq!(d.transmit(&data(0x300, &[])), Nb::WouldBlock);
    assert_eq!(d.transmit(&data(0x200, &[])), Nb::WouldBlock, "equal priority: FIFO order kept");
    assert_eq!(d.transmit(&data(0x100, &[])), Nb::Ok((1, None)));
}

#[test]
fn bxcan_replaces_the_lowest_of_three_pending() {
    let mut d = on_bus();
    for id in [0x300, 0x200, 0x100] {
        assert!(matches!(d.transmit(&data(id, &[id as u8])), Nb::Ok(_)));
    }
    // All pending: CODE names mailbox 0 (0x300); bxcan aborts it and returns its frame.
    let result = d.transmit(&data(0x050, &[]));
    assert_eq!(result, Nb::Ok((0, Some(data(0x300, &[0x00])))));
    assert_eq!(d.send(TxOutcome::Acknowledged).unwrap().frame.id(), FrameId::Standard(0x050));
}

#[test]
fn mailbox_written_only_while_empty() {
    let mut d = on_bus();
    request(&mut d, 0, &data(0x123, &[1, 2]));
    d.write(offset::TI0R + 8, 0xDEAD_BEEF);
    d.write(offset::TI0R, 0x7FF << 21 | 1);
    assert_eq!(d.read(offset::TI0R), 0x123 << 21 | 1);
    assert_eq!(d.read(offset::TI0R + 8), 0x0201);
}

#[rstest]
#[case::pending(false, None, tsr::RQCP)]
#[case::on_the_wire_then_sent(true, Some(TxOutcome::Acknowledged), tsr::RQCP | tsr::TXOK)]
#[case::on_the_wire_then_failed(true, Some(TxOutcome::NoAcknowledge), tsr::RQCP | tsr::TERR)]
fn abort(#[case] in_flight: bool, #[case] outcome: Option<TxOutcome>, #[case] status: u32) {
    let mut d = on_bus();
    request(&mut d, 0, &data(0x123, &[]));
    if in_flight {
        assert!(d.can.poll_transmit(0, &mut d.m).is_some());
    }
    d.write(offset::TSR, tsr::ABRQ);
    if in_flight {
        assert_ne!(d.read(offset::TSR) & tsr::ABRQ, 0, "ABRQ stays set while the frame is sent");
        d.can.transmit_outcome(outcome.unwrap(), 0, &mut d.m);
    }
    let tsr = d.read(offset::TSR);
    assert_eq!(tsr & 0xFF, status);
    assert_eq!(tsr >> 26 & 1, 1, "TME0: empty");
    assert_eq!(d.send(TxOutcome::Acknowledged), None);
}

#[test]
fn abort_of_an_empty_mailbox_has_no_effect() {
    let mut d = on_bus();
    d.write(offset::TSR, tsr::ABRQ << 8);
    assert_eq!(d.read(offset::TSR), 0x1C00_0000);
}

#[rstest]
#[case::no_ack(TxOutcome::NoAcknowledge, tsr::TERR)]
#[case::arbitration_lost(TxOutcome::ArbitrationLost, tsr::ALST)]
#[case::error_flag(TxOutcome::ErrorFlagged, tsr::TERR)]
fn one_shot_mode(#[case] outcome: TxOutcome, #[case] flag: u32) {
    let mut d = on_bus();
    d.modify(offset::MCR, |r| r | mcr::NART);
    request(&mut d, 0, &data(0x123, &[]));
    d.send(outcome).unwrap();
    assert_eq!(d.read(offset::TSR) & 0xFF, tsr::RQCP | flag, "done, TXOK clear");
    assert_eq!(d.send(TxOutcome::Acknowledged), None, "no retransmission");
}

#[rstest]
#[case::no_ack(TxOutcome::NoAcknowledge, tsr::TERR)]
#[case::arbitration_lost(TxOutcome::ArbitrationLost, tsr::ALST)]
fn automatic_retransmission(#[case] outcome: TxOutcome, #[case] flag: u32) {
    let mut d = on_bus();
    request(&mut d, 0, &data(0x123, &[]));
    d.send(outcome).unwrap();
    assert_eq!(d.read(offset::TSR) & 0xFF, flag, "pending again, RQCP clear");
    assert!(d.send(TxOutcome::Acknowledged).is_some(), "offered again");
    assert_eq!(d.read(offset::TSR) & 0xFF, tsr::RQCP | tsr::TXOK);
}

#[test]
fn nothing_sent_in_initialisation_or_sleep() {
    let mut d = Driver::new(PCLK1);
    d.builder();
    request(&mut d, 0, &data(0x123, &[]));
    assert_eq!(d.send(TxOutcome::Acknowledged), None);
    d.leave_disabled();
    assert_eq!(d.send(TxOutcome::Acknowledged), None);
    let _ = d.enable_non_blocking();
    assert!(d.send(TxOutcome::Acknowledged).is_some(), "sent once on the bus");
}

/// The firmware's set-up with the test-mode bits of `set_loopback` / `set_silent` before it
/// leaves initialisation.
fn in_test_mode(loopback: bool, silent: bool) -> Driver {
    let mut d = Driver::new(PCLK1);
    d.builder();
    d.set_bit_timing(BTR_125K_AT_42MHZ);
    d.set_btr_mode(LBKM, loopback);
    d.set_btr_mode(SILM, silent);
    d.modify_filters();
    d.enable_bank_mask16(0, true, [Mask16 { id: 0, mask: 0 }; 2]);
    d.drop_filters();
    d.enable();
    d
}

#[test]
fn silent_mode_receives_without_acknowledging_and_never_sends() {
    let mut d = in_test_mode(false, true);
    request(&mut d, 0, &data(0x123, &[]));
    assert_eq!(d.send(TxOutcome::Acknowledged), None);
    assert_eq!(d.hear(&data(0x321, &[9]), 125_000), Response::Quiet);
    assert_eq!(d.receive(), Nb::Ok(data(0x321, &[9])));
}

#[test]
fn silent_loopback_sends_to_itself_only() {
    let mut d = in_test_mode(true, true);
    assert_eq!(d.transmit(&data(0x123, &[7])), Nb::Ok((0, None)));
    assert_eq!(d.read(offset::TSR) & 0xFF, tsr::RQCP | tsr::TXOK, "done at once");
    assert_eq!(d.can.poll_transmit(0, &mut d.m), None, "nothing on the wire");
    assert_eq!(d.read(offset::RF1R) & 0b11, 1, "received back into FIFO 1");
    assert_eq!(d.read(offset::RI0R + 0x10 + 4), 1, "DLC 1, FMI 0");
    assert_eq!(d.receive(), Nb::Ok(data(0x123, &[7])));
    assert_eq!(d.hear(&data(0x321, &[]), 125_000), Response::Quiet, "CANRX disregarded");
    assert_eq!(d.receive(), Nb::WouldBlock);
}

#[test]
fn loopback_sends_to_the_wire_and_ignores_the_missing_ack() {
    let mut d = in_test_mode(true, false);
    assert_eq!(d.transmit(&data(0x123, &[7])), Nb::Ok((0, None)));
    let tx = d.send(TxOutcome::NoAcknowledge).unwrap();
    assert_eq!(tx.frame, data(0x123, &[7]));
    assert_eq!(d.read(offset::TSR) & 0xFF, tsr::RQCP | tsr::TXOK);
    assert_eq!(d.counters(), (0, 0));
    assert_eq!(d.receive(), Nb::Ok(data(0x123, &[7])));
}

#[rstest]
#[case::silent_loopback(true)]
#[case::loopback(false)]
fn a_broken_loopback_path_completes_the_frame_but_never_receives_it(#[case] silent: bool) {
    let mut d = in_test_mode(true, silent);
    d.can.set_loopback_broken(true);
    assert_eq!(d.transmit(&data(0x7FF, &[0x55, 0xAA])), Nb::Ok((0, None)));
    if !silent {
        assert!(d.send(TxOutcome::NoAcknowledge).is_some(), "still on the wire");
    }
    assert_eq!(d.read(offset::TSR) & 0xFF, tsr::RQCP | tsr::TXOK, "the mailbox still completes");
    assert_eq!(d.receive(), Nb::WouldBlock, "nothing came back");
    assert_eq!(d.read(offset::RF1R) & 0b11, 0);
}

#[test]
fn a_broken_loopback_path_survives_resets_and_leaves_normal_mode_alone() {
    let mut d = on_bus();
    d.can.set_loopback_broken(true);
    d.write(offset::MCR, mcr::RESET);
    Bxcan::reset(&mut d.can);
    assert!(d.can.loopback_broken(), "the chip's defect, not a register");
    d.firmware_setup();
    let _ = d.enable_non_blocking();
    let frame = data(0x42B, &[1]);
    assert_eq!(d.hear(&frame, 125_000), Response::Acknowledge);
    assert_eq!(d.receive(), Nb::Ok(frame), "reception from the bus works");
    assert_eq!(d.transmit(&data(0x42C, &[2])), Nb::Ok((0, None)));
    assert_eq!(d.send(TxOutcome::Acknowledged).map(|t| t.frame), Some(data(0x42C, &[2])));
    d.can.set_loopback_broken(false);
    assert!(!d.can.loopback_broken());
}
