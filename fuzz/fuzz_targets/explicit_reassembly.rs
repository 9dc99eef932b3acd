//! Explicit (acknowledged) fragmentation: the reassembler fed arbitrary frames, the transmitter
//! fed arbitrary acknowledgements, and a message through both.
#![no_main]

use devicenet::fragment::{ExplicitReassembler, ExplicitReceive, ExplicitTransmitter, TransmitEvent};
use devicenet::{Duration, Instant};
use dnet_fuzz::steps::chunks;
use libfuzzer_sys::fuzz_target;

const N: usize = 64;

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    match mode % 3 {
        0 => {
            let mut rx = ExplicitReassembler::<N>::new();
            for frame in chunks(rest, 8) {
                match rx.receive(frame) {
                    ExplicitReceive::Complete(ack) => {
                        assert_eq!(ack.len(), 3);
                        let m = rx.message();
                        assert!(!m.is_empty() && m.len() <= N);
                        assert_eq!(m[0] & 0x80, 0, "the reassembled header has no fragment bit");
                    }
                    ExplicitReceive::Ack(ack)
                    | ExplicitReceive::Duplicate(ack)
                    | ExplicitReceive::Rejected(ack) => {
                        assert_eq!(ack.len(), 3);
                    }
                    ExplicitReceive::Ignored(_) => {}
                }
                assert!(rx.message().len() <= N);
            }
        }
        1 => {
            // The transmitter with arbitrary acks at arbitrary times.
            let mut tx = ExplicitTransmitter::<N>::new();
            let len = rest.first().map_or(0, |&l| usize::from(l) % (N + 1));
            let message = rest.get(1..1 + len).unwrap_or(&[]);
            let mut now = Instant::ZERO;
            if tx.start(message, now).is_err() {
                return;
            }
            for ack in chunks(rest.get(1 + len..).unwrap_or(&[]), 8) {
                while let Some(p) = tx.poll_transmit(now) {
                    assert!(p.len() <= 8);
                }
                tx.handle_ack(ack, now);
                now += Duration::from_millis(u64::from(ack.first().copied().unwrap_or(0)) * 10);
                while tx.poll_event(now).is_some() {}
                assert!(tx.poll_at().is_none_or(|t| t >= now || tx.is_active()));
            }
        }
        _ => {
            // Round trip: every message the transmitter accepts arrives whole.
            let len = rest.len().min(N);
            let mut message = rest[..len].to_vec();
            if message.len() < 2 {
                return;
            }
            message[0] &= 0x7F;
            let mut tx = ExplicitTransmitter::<N>::new();
            let mut rx = ExplicitReassembler::<N>::new();
            let now = Instant::ZERO;
            if tx.start(&message, now).is_err() {
                return;
            }
            let mut done = false;
            for _ in 0..64 {
                let Some(p) = tx.poll_transmit(now) else { break };
                match rx.receive(&p) {
                    ExplicitReceive::Ack(ack) => {
                        tx.handle_ack(&ack, now);
                    }
                    ExplicitReceive::Complete(ack) => {
                        assert_eq!(rx.message(), &message[..]);
                        tx.handle_ack(&ack, now);
                        done = true;
                    }
                    other => panic!("{other:?} for {p:02X?}"),
                }
            }
            assert!(done, "{} bytes never arrived", message.len());
            assert!(matches!(tx.poll_event(now), Some(TransmitEvent::Completed)));
        }
    }
});
