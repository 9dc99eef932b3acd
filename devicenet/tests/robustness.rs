//! Fuzz-style robustness: random and mutated frames never panic the node, and it keeps answering
//! a valid request afterwards (style.md practice 6: no panic reachable from bus input).

mod common;

use common::{play_bring_up, reference_node};
use devicenet::reference::BRING_UP;
use devicenet::{CanFrame, Duration, Instant, SlaveNode};
use proptest::prelude::*;

fn established() -> (SlaveNode, Instant) {
    let mut node = reference_node();
    let seen = play_bring_up(&mut node);
    while node.poll_event().is_some() {}
    (node, seen.last().unwrap().at)
}

/// After any abuse, the node must still answer (or, if the abuse legitimately faulted it or
/// dropped the connection, recover through the normal sequence).
fn still_answers(node: &mut SlaveNode, now: Instant) {
    while node.poll_transmit().is_some() {}
    let get_vendor = CanFrame::from_raw(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]).unwrap();
    node.handle_frame(&get_vendor, now);
    let answered = std::iter::from_fn(|| node.poll_transmit()).any(|f| f.data() == [0x00, 0x8E, 0x34, 0x12]);
    if answered {
        return;
    }
    // Connection lost (released, timed out) or faulted: power-cycle and bring it up again.
    let mut fresh = reference_node();
    let seen = play_bring_up(&mut fresh);
    assert_eq!(seen.len(), BRING_UP.len());
}

/// Frames aimed at the node's own identifiers (the interesting part of the space) mixed with
/// arbitrary identifiers.
fn frame_strategy() -> impl Strategy<Value = (u16, Vec<u8>, u64)> {
    let id = prop_oneof![
        4 => prop::sample::select(vec![0x42Cu16, 0x42D, 0x42E, 0x42F]),
        1 => 0u16..0x800,
    ];
    (id, prop::collection::vec(any::<u8>(), 0..=8), 0u64..3_000_000)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn random_frames_never_panic(frames in prop::collection::vec(frame_strategy(), 1..64)) {
        let (mut node, mut now) = established();
        for (id, data, step) in frames {
            now += Duration::from_micros(step);
            let frame = CanFrame::from_raw(id, &data).unwrap();
            node.handle_frame(&frame, now);
            while node.poll_transmit().is_some() {}
            while node.poll_event().is_some() {}
            if let Some(at) = node.poll_at() {
                if at <= now { node.handle_timeout(now); }
            }
        }
        still_answers(&mut node, now);
    }
}

/// A seeded generator that mutates the valid master frames of the reference sequence (bit flips,
/// truncation, extension, retargeting) and replays them in bulk: 200 000 frames.
#[test]
fn mutated_reference_frames_never_panic() {
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let masters: Vec<_> =
        BRING_UP.iter().filter(|f| f.direction == devicenet::reference::Direction::MasterToSlave).collect();
    let (mut node, mut now) = established();
    for i in 0..200_000u32 {
        let base = masters[(next() % masters.len() as u64) as usize];
        let mut data = base.data.to_vec();
        let mut id = base.id;
        match next() % 6 {
            0 if !data.is_empty() => {
                let k = (next() % data.len() as u64) as usize;
                data[k] ^= 1 << (next() % 8);
            }
            1 => data.truncate((next() % (data.len() as u64 + 1)) as usize),
            2 if data.len() < 8 => data.push(next() as u8),
            3 => id = (id & !7) | (next() % 8) as u16,
            4 if !data.is_empty() => data[0] |= 0x80, // fragment bit on anything
            _ => {}
        }
        now += Duration::from_micros(next() % 50_000);
        node.handle_frame(&CanFrame::from_raw(id, &data).unwrap(), now);
        while node.poll_transmit().is_some() {}
        while node.poll_event().is_some() {}
        if i % 10_000 == 0 {
            node.handle_timeout(now);
        }
    }
    assert!(node.stats().frames_received >= 200_000);
    still_answers(&mut node, now);
}
