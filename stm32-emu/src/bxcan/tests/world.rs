//! Two controllers on one wire, driven as bus.rs's module docs tell a CAN world to.

use super::*;
use rstest::rstest;

/// On the bus at 125 kbit/s with the 42 MHz timing, one bank accepting everything.
fn node(pclk1: u32) -> Driver {
    let mut d = Driver::new(pclk1);
    d.builder();
    d.set_bit_timing(BTR_125K_AT_42MHZ);
    d.modify_filters();
    d.enable_bank_mask16(0, false, [Mask16 { id: 0, mask: 0 }; 2]);
    d.drop_filters();
    d.enable();
    d
}

/// One frame on the wire: arbitration, responses, delivery, outcomes. Returns the winner's
/// index and the outcome, or `None` when nobody sends.
fn exchange(nodes: &mut [&mut Driver]) -> Option<(usize, TxOutcome)> {
    let offers: Vec<Option<Transmission>> =
        nodes.iter_mut().map(|d| d.can.poll_transmit(d.m.now, &mut d.m)).collect();
    let (winner, tx) = offers
        .iter()
        .enumerate()
        .filter_map(|(i, o)| o.map(|t| (i, t)))
        .min_by_key(|(_, t)| t.frame.arbitration_key())?;
    let responses: Vec<Response> = nodes
        .iter()
        .enumerate()
        .filter(|&(i, _)| i != winner)
        .map(|(_, d)| d.can.response(tx.bit_rate, &d.m))
        .collect();
    let (outcome, disturbed) = TxOutcome::from_responses(responses);
    for (i, d) in nodes.iter_mut().enumerate() {
        let now = d.m.now;
        if i == winner {
            d.can.transmit_outcome(outcome, now, &mut d.m);
        } else {
            if offers[i].is_some() {
                d.can.transmit_outcome(TxOutcome::ArbitrationLost, now, &mut d.m);
            }
            d.can.on_wire(&tx.frame, tx.bit_rate, disturbed, now, &mut d.m);
        }
    }
    Some((winner, outcome))
}

#[test]
fn a_frame_from_one_to_the_other() {
    let (mut a, mut b) = (node(PCLK1), node(PCLK1));
    a.transmit(&data(0x42F, &[0, 0x34, 0x12]));
    assert_eq!(exchange(&mut [&mut a, &mut b]), Some((0, TxOutcome::Acknowledged)));
    assert_eq!(b.receive(), Nb::Ok(data(0x42F, &[0, 0x34, 0x12])));
    assert_eq!(a.read(offset::TSR) & 0xFF, tsr::RQCP | tsr::TXOK);
    assert_eq!(exchange(&mut [&mut a, &mut b]), None);
}

#[test]
fn arbitration_between_the_two() {
    let (mut a, mut b) = (node(PCLK1), node(PCLK1));
    a.transmit(&data(0x300, &[]));
    b.transmit(&data(0x100, &[]));
    assert_eq!(exchange(&mut [&mut a, &mut b]), Some((1, TxOutcome::Acknowledged)));
    assert_eq!(a.read(offset::TSR) & 0xFF, tsr::ALST, "lost, still pending");
    assert_eq!(a.receive(), Nb::Ok(data(0x100, &[])), "the loser receives the winner");
    assert_eq!(exchange(&mut [&mut a, &mut b]), Some((0, TxOutcome::Acknowledged)));
    assert_eq!(b.receive(), Nb::Ok(data(0x300, &[])));
}

#[rstest]
// The same BTR at the reset clock (the emulated board without RCC set-up): 47.6 kbit/s.
#[case::receiver_at_hsi(PCLK1, 16_000_000)]
#[case::sender_at_hsi(16_000_000, PCLK1)]
fn different_rates_nothing_gets_through(#[case] pclk_a: u32, #[case] pclk_b: u32) {
    let (mut a, mut b) = (node(pclk_a), node(pclk_b));
    a.transmit(&data(0x42F, &[]));
    // Each attempt: B flags an error (TEC + 8 for A, REC + 1 for B), until A is bus-off.
    for n in 1..=32 {
        assert_eq!(exchange(&mut [&mut a, &mut b]), Some((0, TxOutcome::ErrorFlagged)));
        assert_eq!(b.counters(), (0, n));
    }
    assert!(a.can.is_bus_off());
    assert_eq!(b.receive(), Nb::WouldBlock);
    assert_eq!(exchange(&mut [&mut a, &mut b]), None, "bus-off: silence");
}

#[test]
fn an_error_passive_receiver_at_another_rate_leaves_the_sender_unacknowledged() {
    let (mut a, mut b) = (node(PCLK1), node(16_000_000));
    for _ in 0..128 {
        b.hear(&data(0x100, &[]), 125_000);
    }
    assert_eq!(b.counters(), (0, 128));
    a.transmit(&data(0x42F, &[]));
    for _ in 0..40 {
        assert_eq!(exchange(&mut [&mut a, &mut b]), Some((0, TxOutcome::NoAcknowledge)));
    }
    assert_eq!(a.counters(), (128, 0), "rule 3a: error passive without ACK stops at 128");
    assert!(!a.can.is_bus_off());
}
