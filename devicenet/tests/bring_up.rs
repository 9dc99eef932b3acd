//! The slave node through the exact 28-frame sequence of protocol §2, on a
//! virtual clock: every byte the slave emits, the two duplicate MAC requests 1 s apart, and
//! silence towards the two UCMM frames.

mod common;

use common::{play_bring_up, reference_node};
use devicenet::reference::{Direction, BRING_UP};
use devicenet::slave::{ConnectionState, NetworkState, WatchdogAction};
use devicenet::{Event, Instant};

#[test]
fn reference_sequence_byte_for_byte() {
    let mut node = reference_node();
    let seen = play_bring_up(&mut node);
    for (i, (got, want)) in seen.iter().zip(BRING_UP.iter()).enumerate() {
        assert_eq!(
            (got.direction, got.id, got.data.as_slice()),
            (want.direction, want.id, want.data),
            "frame {i} ({})",
            want.meaning
        );
    }
    assert_eq!(seen.len(), 28, "exactly 28 frames: {seen:#X?}");
}

#[test]
fn duplicate_mac_requests_one_second_apart_and_online_after_another() {
    let mut node = reference_node();
    let seen = play_bring_up(&mut node);
    let slave_dup: Vec<_> = seen.iter().filter(|s| s.id == 0x42F).collect();
    assert_eq!(slave_dup.len(), 2);
    assert_eq!(slave_dup[0].at, Instant::from_secs(2));
    assert_eq!(slave_dup[1].at, Instant::from_secs(3));
    assert_eq!(node.network_state(), NetworkState::Online);
}

#[test]
fn silent_towards_ucmm() {
    let mut node = reference_node();
    let seen = play_bring_up(&mut node);
    let ucmm = seen.iter().position(|s| s.id == 0x780).unwrap();
    assert_eq!(seen[ucmm + 1].id, 0x780, "no answer between the two UCMM frames");
    assert_eq!(seen[ucmm + 2].id, 0x42E, "no answer after the retry: straight to the Group 2 Only port");
    assert!(seen.iter().all(|s| !(0x600..0x7C0).contains(&s.id) || s.direction == Direction::MasterToSlave));
}

#[test]
fn state_effects_of_the_sequence() {
    let mut node = reference_node();
    play_bring_up(&mut node);
    assert_eq!(node.explicit_connection().state, ConnectionState::Established);
    assert_eq!(node.explicit_connection().watchdog_action, WatchdogAction::DeferredDelete);
    assert_eq!(node.poll_connection().state, ConnectionState::Established);
    assert_eq!(node.poll_connection().expected_packet_rate, 100);
    assert_eq!(node.output(), &[0u8; 8]);
    let events: Vec<Event> = std::iter::from_fn(|| node.poll_event()).collect();
    assert!(events.contains(&Event::Online));
    assert!(events.contains(&Event::OutputReceived));
    assert_eq!(node.identity_status() & 1, 1, "owned");
}
