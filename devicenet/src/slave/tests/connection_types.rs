//! Bit-strobe, change of state, cyclic, heartbeat and the offline connection set
//! (docs/src/reference/io-connections.md).

use super::*;

/// An input image whose bytes tell where they come from.
const INPUT: [u8; 18] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17];

/// The 18-byte input as I/O fragments on `id` (protocol §4.2).
fn fragments(id: u16) -> Tx {
    std::vec![
        (id, std::vec![0x00, 0, 1, 2, 3, 4, 5, 6]),
        (id, std::vec![0x41, 7, 8, 9, 10, 11, 12, 13]),
        (id, std::vec![0x82, 14, 15, 16, 17]),
    ]
}

/// On-line, `choice` allocated through the Group 2 Only port by master 0, and the EPR of
/// `instance` set to `epr` ms.
fn allocated(choice: u8, instance: u8, epr: u16) -> Rig {
    let mut rig = Rig::online();
    rig.node.set_input(&INPUT).unwrap();
    assert_eq!(rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, choice, 0x00]), tx(0x42B, &[0x00, 0xCB, 0x00]));
    let [lo, hi] = epr.to_le_bytes();
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x10, 0x05, instance, 0x09, lo, hi]),
        tx(0x42B, &[0x00, 0x90, lo, hi])
    );
    rig.events();
    rig
}

fn get(rig: &mut Rig, class: u8, instance: u8, attr: u8) -> Vec<u8> {
    let frames = rig.send(0x42C, &[0x00, 0x0E, class, instance, attr]);
    assert_eq!(frames.len(), 1, "{frames:02X?}");
    frames[0].1[2..].to_vec()
}

#[test]
fn strobe_answers_every_strobe_with_the_first_eight_input_bytes() {
    let mut rig = allocated(0x05, 3, 100);
    assert!(rig.node.strobe_connection().is_established());
    // Our bit (MAC 5 = byte 0 bit 5) set, then clear: answered both times (NI, §II.1.3).
    let response = tx(0x385, &[0, 1, 2, 3, 4, 5, 6, 7]);
    assert_eq!(rig.send(0x400, &[0x20, 0, 0, 0, 0, 0, 0, 0]), response);
    assert!(rig.node.strobe_bit());
    assert_eq!(rig.send(0x400, &[0xDF, 0xFF, 0, 0, 0, 0, 0, 0]), response);
    assert!(!rig.node.strobe_bit());
    // The output image is not touched by a strobe.
    assert_eq!(rig.node.output(), &[0; 8]);
}

#[rstest]
#[case::short(0x400, &[0x20, 0, 0, 0, 0, 0, 0])]
#[case::empty(0x400, &[])]
#[case::another_master(0x408, &[0x20, 0, 0, 0, 0, 0, 0, 0])]
fn strobe_ignores_what_is_not_the_owners_whole_command(#[case] id: u16, #[case] data: &[u8]) {
    let mut rig = allocated(0x05, 3, 100);
    assert_eq!(rig.send(id, data), Tx::new());
    assert!(!rig.node.strobe_bit());
}

#[test]
fn strobe_is_not_answered_until_established() {
    let mut rig = Rig::explicit();
    assert_eq!(rig.send(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x04, 0x00]), tx(0x42B, &[0x00, 0xCB, 0x00]));
    assert_eq!(rig.node.strobe_connection().state, ConnectionState::Configuring);
    assert_eq!(rig.send(0x400, &[0x20, 0, 0, 0, 0, 0, 0, 0]), Tx::new());
}

#[test]
fn strobe_watchdog_times_out_after_four_expected_packet_rates() {
    let mut rig = allocated(0x05, 3, 100);
    rig.send(0x400, &[0; 8]);
    rig.advance(Duration::from_millis(399));
    assert!(rig.events().is_empty());
    rig.advance(Duration::from_millis(1));
    assert_eq!(rig.events(), std::vec![Event::ConnectionTimedOut(ConnectionKind::Strobe)]);
    assert_eq!(rig.node.identity_status() >> 4 & 0xF, 0b0010);
    assert_eq!(rig.node.network_indication(), led::Indication::FlashingRed);
    // A timed-out strobe connection answers nothing.
    assert_eq!(rig.send(0x400, &[0; 8]), Tx::new());
}

#[rstest]
// Strobe (§II.1.1): transport, produced 0x385, consumed the master's G2 msg 0, 0x02, sizes.
#[case::strobe_transport(0x05, 3, 3, &[0x82])]
#[case::strobe_produced_id(0x05, 3, 4, &[0x85, 0x03])]
#[case::strobe_consumed_id(0x05, 3, 5, &[0x00, 0x04])]
#[case::strobe_comm(0x05, 3, 6, &[0x02])]
#[case::strobe_produced_size(0x05, 3, 7, &[0x08, 0x00])]
#[case::strobe_consumed_size(0x05, 3, 8, &[0x08, 0x00])]
#[case::strobe_produced_path(0x05, 3, 14, &[0x20, 0x04, 0x24, 0x64, 0x30, 0x03])]
#[case::strobe_no_consumed_path(0x05, 3, 15, &[0x00, 0x00])]
#[case::strobe_consumed_path_empty(0x05, 3, 16, &[])]
// COS acknowledged (§II.2.2, RA tables).
#[case::cos_transport(0x11, 4, 3, &[0x13])]
#[case::cos_produced_id(0x11, 4, 4, &[0x45, 0x03])]
#[case::cos_consumed_id(0x11, 4, 5, &[0x2A, 0x04])]
#[case::cos_comm(0x11, 4, 6, &[0x01])]
#[case::cos_produced_size(0x11, 4, 7, &[0x12, 0x00])]
#[case::cos_consumed_size(0x11, 4, 8, &[0x00, 0x00])]
#[case::cos_ack_handler_path(0x11, 4, 16, &[0x20, 0x2B, 0x24, 0x01, 0x30, 0x01])]
#[case::cos_produced_path(0x11, 4, 14, &[0x20, 0x04, 0x24, 0x64, 0x30, 0x03])]
#[case::cos_inhibit(0x11, 4, 17, &[0x00, 0x00])]
// Cyclic and acknowledge suppression.
#[case::cyclic_transport(0x21, 4, 3, &[0x03])]
#[case::cos_suppressed_transport(0x51, 4, 3, &[0x10])]
#[case::cyclic_suppressed_transport(0x61, 4, 3, &[0x00])]
#[case::suppressed_consumed_id(0x51, 4, 5, &[0xFF, 0xFF])]
#[case::suppressed_comm(0x51, 4, 6, &[0x0F])]
#[case::suppressed_no_consumed_path(0x51, 4, 15, &[0x00, 0x00])]
#[case::suppressed_consumed_path_empty(0x51, 4, 16, &[])]
// Connection 2 created to consume the master's COS data (§II.2.5, EAT).
#[case::consumer_transport(0x11, 2, 3, &[0x82])]
#[case::consumer_produced_size(0x11, 2, 7, &[0x00, 0x00])]
#[case::consumer_consumed_size(0x11, 2, 8, &[0x08, 0x00])]
#[case::consumer_produced_path_empty(0x11, 2, 14, &[])]
#[case::consumer_consumed_path(0x11, 2, 16, &[0x20, 0x04, 0x24, 0x96, 0x30, 0x03])]
#[case::consumer_suppressed_transport(0x51, 2, 3, &[0x80])]
#[case::consumer_suppressed_comm(0x51, 2, 6, &[0xF1])]
#[case::consumer_state(0x11, 2, 1, &[0x03])]
// With poll, Connection 2 is an ordinary poll connection.
#[case::poll_with_cos(0x13, 2, 7, &[0x12, 0x00])]
fn io_connection_attributes(
    #[case] choice: u8,
    #[case] instance: u8,
    #[case] attr: u8,
    #[case] value: &[u8],
) {
    let epr_instance = if instance == 2 {
        if choice & 0x02 != 0 {
            2
        } else {
            4
        }
    } else {
        instance
    };
    let mut rig = allocated(choice, epr_instance, 1000);
    rig.advance(Duration::from_millis(1));
    assert_eq!(get(&mut rig, 0x05, instance, attr), value);
}

#[test]
fn acknowledged_cos_produces_at_once_then_on_change_and_every_epr() {
    let mut rig = allocated(0x11, 4, 1000);
    // The first production right after Established, then one acknowledgement.
    assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
    assert_eq!(rig.send(0x42A, &[]), Tx::new());
    // A change is produced at once.
    rig.advance(Duration::from_millis(100));
    rig.node.input_changed(rig.now);
    assert_eq!(rig.drain(), fragments(0x345));
    rig.send(0x42A, &[]);
    // Nothing changes: the next production one EPR after the last (the COS heartbeat).
    assert_eq!(rig.advance(Duration::from_millis(999)), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345));
    rig.send(0x42A, &[]);
    assert!(rig.events().is_empty());
    assert!(rig.node.cos_connection().is_established());
}

#[test]
fn production_inhibit_time_delays_a_change() {
    let mut rig = Rig::online();
    rig.node.set_input(&INPUT).unwrap();
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x51, 0x00]);
    // Inhibit time 50 ms, set while configuring (§II.2.3).
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x05, 0x04, 0x11, 0x32, 0x00]), tx(0x42B, &[0x00, 0x90]));
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x04, 0x09, 0xE8, 0x03]);
    assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
    rig.advance(Duration::from_millis(10));
    rig.node.input_changed(rig.now);
    assert_eq!(rig.drain(), Tx::new(), "inside the inhibit time");
    assert_eq!(rig.advance(Duration::from_millis(39)), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345), "when it ends");
}

#[test]
fn unacknowledged_production_is_sent_again_then_the_retry_limit_is_reported() {
    let mut rig = allocated(0x11, 4, 1000);
    assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
    // The acknowledge timer (16 ms by default, §II.2.4), then the whole series again.
    assert_eq!(rig.advance(Duration::from_millis(15)), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345));
    // Retry limit 1: the next timeout is reported and nothing more is sent until the next trigger.
    assert_eq!(rig.advance(Duration::from_millis(16)), Tx::new());
    assert_eq!(rig.events(), std::vec![Event::RetryLimitReached]);
    assert!(rig.node.cos_connection().is_established(), "the connection stays");
}

#[test]
fn acknowledge_handler_attributes_are_read_and_set() {
    let mut rig = allocated(0x11, 4, 1000);
    assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
    rig.send(0x42A, &[]);
    assert_eq!(get(&mut rig, 0x2B, 1, 1), &[0x10, 0x00]);
    assert_eq!(get(&mut rig, 0x2B, 1, 2), &[0x01]);
    assert_eq!(get(&mut rig, 0x2B, 1, 3), &[0x04, 0x00]);
    assert_eq!(get(&mut rig, 0x2B, 0, 1), &[0x01, 0x00]);
    assert_eq!(get(&mut rig, 0x2B, 0, 2), &[0x01, 0x00]);
    // The class instance has no attribute 3, and no Set.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x2B, 0x00, 0x03]), tx(0x42B, &[0x00, 0x94, 0x14, 0xFF]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x00, 0x01, 0x01]), tx(0x42B, &[0x00, 0x94, 0x08, 0xFF]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x01, 0x01, 0x28, 0x00]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x01, 0x02, 0x03]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(rig.node.ack_handler(), AckHandler { acknowledge_timer_ms: 40, retry_limit: 3 });
    // Timer 0 is invalid (U3K); attribute 3 is not settable; no attribute 8.
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x01, 0x01, 0x00, 0x00]),
        tx(0x42B, &[0x00, 0x94, 0x09, 0xFF])
    );
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x01, 0x03, 0x04, 0x00]),
        tx(0x42B, &[0x00, 0x94, 0x0E, 0xFF])
    );
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x2B, 0x01, 0x08]), tx(0x42B, &[0x00, 0x94, 0x14, 0xFF]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x2B, 0x02, 0x01]), tx(0x42B, &[0x00, 0x94, 0x16, 0xFF]));
    // The new timer is used: 40 ms, then the retry.
    rig.node.input_changed(rig.now);
    assert_eq!(rig.drain(), fragments(0x345));
    assert_eq!(rig.advance(Duration::from_millis(39)), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345));
}

#[test]
fn cyclic_with_acknowledge_suppression_produces_every_epr_and_never_times_out() {
    let mut rig = allocated(0x61, 4, 100);
    assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
    assert_eq!(rig.advance(Duration::from_millis(99)), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345));
    // A change does not trigger a cyclic connection.
    rig.node.input_changed(rig.now);
    assert_eq!(rig.drain(), Tx::new());
    // No acknowledgement ever: no retry, no timeout.
    let sent = rig.advance(Duration::from_millis(1000));
    assert_eq!(sent.len(), 30, "ten productions of three fragments");
    assert!(rig.events().is_empty());
    assert!(rig.node.cos_connection().is_established());
    assert_eq!(rig.node.cos_connection().deadline, Instant::MAX);
}

#[test]
fn master_cos_data_without_poll_is_consumed_and_acknowledged() {
    let mut rig = allocated(0x11, 4, 1000);
    rig.advance(Duration::ZERO);
    assert_eq!(rig.send(0x42D, &[1, 2, 3, 4, 5, 6, 7, 8]), tx(0x3C5, &[]));
    assert_eq!(rig.node.output(), &[1, 2, 3, 4, 5, 6, 7, 8]);
    assert_eq!(rig.events(), std::vec![Event::OutputReceived]);
    // Under acknowledge suppression it is consumed without an acknowledgement.
    let mut rig = allocated(0x51, 4, 1000);
    rig.advance(Duration::ZERO);
    assert_eq!(rig.send(0x42D, &[8, 7, 6, 5, 4, 3, 2, 1]), Tx::new());
    assert_eq!(rig.node.output(), &[8, 7, 6, 5, 4, 3, 2, 1]);
}

#[test]
fn poll_and_cos_together_keep_poll_responses() {
    let mut rig = allocated(0x13, 4, 1000);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    rig.advance(Duration::ZERO);
    assert_eq!(rig.send(0x42D, &[0; 8]), fragments(0x3C5));
}

#[test]
fn cos_watchdog_is_kept_alive_by_acknowledgements() {
    let mut rig = allocated(0x11, 4, 100);
    rig.advance(Duration::ZERO);
    rig.send(0x42A, &[]);
    for _ in 0..10 {
        rig.advance(Duration::from_millis(100));
        rig.send(0x42A, &[]);
    }
    assert!(rig.events().is_empty());
    // Without acknowledgements: 4 x EPR after the last one, timed out; production stops.
    rig.advance(Duration::from_millis(400));
    assert!(rig.events().contains(&Event::ConnectionTimedOut(ConnectionKind::ChangeOfState)));
    assert_eq!(rig.advance(Duration::from_millis(1000)), Tx::new());
}

#[test]
fn cos_epr_zero_is_refused() {
    let mut rig = Rig::online();
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x11, 0x00]);
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x10, 0x05, 0x04, 0x09, 0x00, 0x00]),
        tx(0x42B, &[0x00, 0x94, 0x09, 0xFF])
    );
}

#[test]
fn releasing_cos_deletes_the_connection_it_created() {
    let mut rig = allocated(0x11, 4, 1000);
    rig.advance(Duration::ZERO);
    rig.send(0x42A, &[]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x4C, 0x03, 0x01, 0x10]), tx(0x42B, &[0x00, 0xCC]));
    assert!(!rig.node.cos_connection().exists());
    assert!(!rig.node.poll_connection().exists());
    assert_eq!(rig.node.allocation().0, AllocationChoice::EXPLICIT);
    assert_eq!(rig.advance(Duration::from_millis(2000)), Tx::new());
}

#[test]
fn heartbeat_every_interval_while_on_line() {
    let mut rig = Rig::explicit();
    assert_eq!(get(&mut rig, 0x01, 1, 10), &[0x00]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x0A, 0x02]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(get(&mut rig, 0x01, 1, 10), &[0x02]);
    let heartbeat = tx(0x42B, &[0x05, 0xCD, 0x01, 0x00, 0x03, 0x00, 0x00, 0x00]);
    assert_eq!(rig.advance(Duration::from_millis(1999)), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(1)), heartbeat);
    assert_eq!(rig.advance(Duration::from_secs(2)), heartbeat);
    // Off again.
    rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x0A, 0x00]);
    assert_eq!(rig.advance(Duration::from_secs(10)), Tx::new());
}

#[test]
fn heartbeat_carries_the_configuration_consistency_value() {
    // Its last two bytes are Identity attribute 9, little-endian (AN, LIM; protocol §II.5.1).
    let mut rig = Rig::explicit();
    rig.node.set_configuration_consistency(0xA1B2);
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x0A, 0x01]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(
        rig.advance(Duration::from_secs(1)),
        tx(0x42B, &[0x05, 0xCD, 0x01, 0x00, 0x03, 0x00, 0xB2, 0xA1])
    );
}

#[test]
fn heartbeat_flags_a_timed_out_connection() {
    let mut rig = allocated(0x03, 2, 100);
    rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x0A, 0x01]);
    let sent = rig.advance(Duration::from_secs(1));
    // SF (bit 2): the poll connection timed out (LIM, §II.5.1).
    assert_eq!(sent, tx(0x42B, &[0x05, 0xCD, 0x01, 0x00, 0x03, 0x04, 0x00, 0x00]));
}

/// A node that found MAC 5 taken during its check: Communication Faulted.
fn faulted() -> Rig {
    let mut rig = Rig::new(DeviceConfig::reference());
    rig.node.power_on(rig.now);
    rig.drain();
    rig.send(0x42F, &[0x80, 0x99, 0x00, 0x01, 0x00, 0x00, 0x00]);
    assert_eq!(rig.node.network_state(), NetworkState::CommunicationFaulted(FaultReason::DuplicateMacId));
    rig.events();
    rig
}

#[test]
fn faulted_node_answers_who_after_its_time_delay() {
    let mut rig = faulted();
    // `3F 4B 02` (ICP): every faulted node; the delay is byte 2 of the answer, 0x12 = 18 ms.
    assert_eq!(rig.send(0x7ED, &[0x3F, 0x4B, 0x02]), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(17)), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(1)), tx(0x7EC, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]));
    // Exact MAC match: 5 answers, 6 does not; mask 0x38 does not select MAC 5.
    rig.send(0x7ED, &[0x45, 0x4B, 0x00]);
    assert_eq!(rig.advance(Duration::ZERO), tx(0x7EC, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]));
    rig.send(0x7ED, &[0x46, 0x4B, 0x00]);
    rig.send(0x7ED, &[0x38, 0x4B, 0x00]);
    assert_eq!(rig.advance(Duration::from_millis(100)), Tx::new());
}

#[test]
fn faulted_node_identifies_itself_and_takes_ownership() {
    let mut rig = faulted();
    assert_eq!(rig.node.network_indication(), led::Indication::Red);
    let key = [0x34, 0x12, 0x78, 0x56, 0x34, 0x12];
    let mut identify = std::vec![0x3F, 0x4C];
    identify.extend_from_slice(&key);
    assert_eq!(rig.send(0x7ED, &identify), tx(0x7EC, &[0x3F, 0xCC]));
    assert_eq!(rig.node.network_indication(), led::Indication::FlashingRedGreen);
    // Another device's key: no answer.
    assert_eq!(rig.send(0x7ED, &[0x3F, 0x4C, 0x34, 0x12, 0x79, 0x56, 0x34, 0x12]), Tx::new());
    // Ownership by tool 0x3E (its own key): echoed; a second tool is not answered.
    let ownership = [0x3E, 0x4B, 0x99, 0x00, 0x01, 0x00, 0x00, 0x00];
    assert_eq!(rig.send(0x7EF, &ownership), tx(0x7EE, &[0x3E, 0xCB, 0x99, 0x00, 0x01, 0x00, 0x00, 0x00]));
    assert_eq!(rig.send(0x7EF, &[0x3D, 0x4B, 0x98, 0x00, 0x01, 0x00, 0x00, 0x00]), Tx::new());
}

#[test]
fn change_mac_id_restarts_the_duplicate_mac_check_at_the_new_mac() {
    let mut rig = faulted();
    // Not ours: ignored.
    assert_eq!(rig.send(0x7ED, &[0x09, 0x4D, 0x34, 0x12, 0x00, 0x00, 0x00, 0x00]), Tx::new());
    assert_eq!(rig.node.mac_id(), MacId::new(5).unwrap());
    let request = [0x09, 0x4D, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12];
    // The duplicate MAC ID request at MAC 9: 0x400 | 9 << 3 | 7.
    let check = tx(0x44F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]);
    assert_eq!(rig.send(0x7ED, &request), check);
    assert_eq!(rig.events(), std::vec![Event::MacIdChanged(MacId::new(9).unwrap())]);
    assert_eq!(rig.advance(Duration::from_secs(1)), check);
    rig.advance(Duration::from_secs(1));
    assert_eq!(rig.node.network_state(), NetworkState::Online);
    assert_eq!(rig.events(), std::vec![Event::Online]);
    // On-line at 9: answers an allocation there; DeviceNet attribute 1 reads 9.
    assert_eq!(rig.send(0x44E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]), tx(0x44B, &[0x00, 0xCB, 0x00]));
    assert_eq!(rig.send(0x44C, &[0x00, 0x0E, 0x03, 0x01, 0x01]), tx(0x44B, &[0x00, 0x8E, 0x09]));
    // An on-line node ignores Group 4.
    assert_eq!(rig.send(0x7ED, &[0x3F, 0x4B, 0x00]), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(100)), Tx::new());
}

#[test]
fn bus_off_faulted_node_ignores_group_4() {
    let mut rig = Rig::online();
    rig.node.handle_bus_off(rig.now);
    assert_eq!(rig.node.network_state(), NetworkState::CommunicationFaulted(FaultReason::BusOff));
    rig.send(0x7ED, &[0x3F, 0x4B, 0x00]);
    assert_eq!(rig.advance(Duration::from_millis(100)), Tx::new());
}
