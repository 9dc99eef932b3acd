//! Untrusted input never panics: random transcripts replayed on the simulated bus, random answers
//! thrown at an explicit transaction, random log text.

use can_io::bus::Bitrate;
use can_io::log::{format_line, parse_log};
use devicenet::explicit::{BodyFormat, Request, ServiceCode};
use devicenet::{CanFrame, Duration, Instant};
use master_core::client::{Port, Transaction};
use master_core::session::Session;
use master_harness::replay::{replay, ReplayOptions};
use proptest::prelude::*;
use system_tests::{mac, sim_bus};

fn frame_strategy() -> impl Strategy<Value = (u16, Vec<u8>)> {
    (
        prop_oneof![0x3C0u16..0x3D0, 0x428u16..0x430, 0x400u16..0x408, 0u16..=0x7FF],
        proptest::collection::vec(any::<u8>(), 0..=8),
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn random_transcripts_replay_without_panic(frames in proptest::collection::vec((0u64..3_000_000, frame_strategy()), 1..24)) {
        let mut at = 0u64;
        let mut text = String::new();
        for (gap, (id, data)) in frames {
            at += gap;
            let f = CanFrame::from_raw(id, &data).unwrap();
            text.push_str(&format_line(Instant::from_micros(at), "sim", &f));
            text.push('\n');
        }
        let entries = parse_log(&text, "p").unwrap();
        let mut bus = sim_bus(&[5], Bitrate::K250);
        let mut session = Session::new(&mut bus);
        let opts = ReplayOptions { tolerance: Duration::from_millis(200), settle: Duration::from_millis(100), ..ReplayOptions::new(mac(5)) };
        let _ = replay(&mut session, &entries, &opts);
    }

    #[test]
    fn random_answers_to_a_transaction(answers in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..=8), 0..32)) {
        let req = Request { service: ServiceCode::SetAttributeSingle, class: 4, instance: 150, data: &[3, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10] };
        let mut tx = Transaction::new(mac(5), mac(0), Port::Explicit, false, &req, BodyFormat::Class8Instance8, Duration::from_secs(1)).unwrap();
        let mut now = Instant::ZERO;
        tx.start(now);
        for a in answers {
            now += Duration::from_millis(10);
            while tx.poll_transmit().is_some() {}
            let f = CanFrame::from_raw(0x42B, &a).unwrap();
            let _ = tx.handle_frame(&f, now);
            tx.handle_timeout(now);
        }
        now += Duration::from_secs(5);
        tx.handle_timeout(now);
        tx.handle_timeout(now + Duration::from_secs(5));
    }
}
