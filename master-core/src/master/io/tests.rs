//! The I/O connections against hand-built frames ([`super::super::scripted`]).

use super::*;
use crate::master::scripted::Scripted;
use crate::master::{ConnectOptions, MasterConfig};
use crate::session::Session;
use can_io::bus::Bitrate;
use can_io::sim::{PowerOn, SimBus};
use rstest::rstest;

const INPUT: [u8; 18] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17];

/// The device at MAC 5 as far as the Identity reads of the bring-up.
fn prologue() -> Scripted {
    Scripted::new(5)
        .on(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00], &[(0, 0x42B, &[0x00, 0xCB, 0x00])])
        .explicit(&[0x00, 0x10, 0x05, 0x01, 0x0C, 0x03], &[0x00, 0x90])
        .explicit(&[0x00, 0x0E, 0x01, 0x01, 0x01], &[0x00, 0x8E, 0x34, 0x12])
        .explicit(&[0x00, 0x0E, 0x01, 0x01, 0x02], &[0x00, 0x8E, 0x0C, 0x00])
        .explicit(&[0x00, 0x0E, 0x01, 0x01, 0x03], &[0x00, 0x8E, 0x01, 0x00])
}

fn strobe_device(response: &[u8]) -> Scripted {
    prologue()
        .explicit(&[0x00, 0x4B, 0x03, 0x01, 0x04, 0x00], &[0x00, 0xCB, 0x00])
        .explicit(&[0x00, 0x0E, 0x05, 0x03, 0x04], &[0x00, 0x8E, 0x85, 0x03])
        .explicit(&[0x00, 0x0E, 0x05, 0x03, 0x05], &[0x00, 0x8E, 0x00, 0x04])
        .explicit(&[0x00, 0x0E, 0x05, 0x03, 0x07], &[0x00, 0x8E, 0x08, 0x00])
        .explicit(&[0x00, 0x0E, 0x05, 0x03, 0x08], &[0x00, 0x8E, 0x08, 0x00])
        .explicit(&[0x00, 0x10, 0x05, 0x03, 0x09, 0x64, 0x00], &[0x00, 0x90, 0x64, 0x00])
        .on(0x400, &[0x20, 0, 0, 0, 0, 0, 0, 0], &[(0, 0x385, response)])
}

/// A COS/cyclic device: `choice` allocated, `consumed_id` its attribute 5, productions of the
/// 18-byte input every `period_ms` (each again `resend_ms` later), the master's 8 bytes
/// acknowledged with `output_ack` (none when `None`).
fn cos_device(
    choice: u8,
    consumed_id: u16,
    period_ms: u64,
    resend_ms: Option<u64>,
    output_ack: Option<&[u8]>,
) -> Scripted {
    let d = cos_attributes(choice, consumed_id).explicit(&SET_EPR_100, &[0x00, 0x90, 0x64, 0x00]).produce(
        (0x42C, &SET_EPR_100),
        2,
        period_ms,
        productions(),
        resend_ms,
    );
    match output_ack {
        Some(ack) => d.on(0x42D, &[0; 8], &[(0, 0x3C5, ack)]),
        None => d,
    }
}

/// The Set EPR request of 100 ms for Connection 4 (explicit header and body).
const SET_EPR_100: [u8; 7] = [0x00, 0x10, 0x05, 0x04, 0x09, 0x64, 0x00];

/// The fragments of one production of [`INPUT`] on 0x345.
fn productions() -> Vec<(u16, Vec<u8>)> {
    io_fragments(&INPUT).map(|p| (0x345u16, p.to_vec())).collect()
}

/// A COS/cyclic device up to its Set EPR: `choice` allocated, `consumed_id` its attribute 5.
fn cos_attributes(choice: u8, consumed_id: u16) -> Scripted {
    let [c0, c1] = consumed_id.to_le_bytes();
    prologue()
        .explicit(&[0x00, 0x4B, 0x03, 0x01, choice, 0x00], &[0x00, 0xCB, 0x00])
        .explicit(&[0x00, 0x0E, 0x05, 0x04, 0x04], &[0x00, 0x8E, 0x45, 0x03])
        .explicit(&[0x00, 0x0E, 0x05, 0x04, 0x05], &[0x00, 0x8E, c0, c1])
        .explicit(&[0x00, 0x0E, 0x05, 0x04, 0x07], &[0x00, 0x8E, 0x12, 0x00])
        .explicit(&[0x00, 0x0E, 0x05, 0x04, 0x08], &[0x00, 0x8E, 0x00, 0x00])
        .explicit(&[0x00, 0x0E, 0x05, 0x02, 0x07], &[0x00, 0x8E, 0x00, 0x00])
        .explicit(&[0x00, 0x0E, 0x05, 0x02, 0x08], &[0x00, 0x8E, 0x08, 0x00])
        .explicit(&[0x00, 0x0E, 0x05, 0x04, 0x11], &[0x00, 0x8E, 0x00, 0x00])
        .explicit(&[0x00, 0x0E, 0x2B, 0x01, 0x01], &[0x00, 0x8E, 0x10, 0x00])
        .explicit(&[0x00, 0x0E, 0x2B, 0x01, 0x02], &[0x00, 0x8E, 0x01])
}

/// Runs `connect --io` against `device` for `cycles`; the summary (or the error) and the
/// failures with their reasons.
fn run(
    device: Scripted,
    io: IoOptions,
    cycles: u32,
) -> (Result<crate::master::DeviceSummary, MasterError>, Vec<String>) {
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(device), PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    let opts = ConnectOptions { polls: cycles, ..ConnectOptions::default() };
    let r = Master::new(&mut session, MasterConfig::default()).connect_io(&opts, &io);
    let failures = crate::master::scripted::failed_frames(&session);
    (r, failures)
}

#[test]
fn strobe_sets_the_device_bit_and_checks_the_response() {
    let response = [1, 2, 3, 4, 5, 6, 7, 8];
    let (r, failures) = run(strobe_device(&response), IoOptions::of(IoKind::Strobe), 3);
    let s = r.unwrap();
    assert!(failures.is_empty(), "{failures:#?}");
    let io = s.io.unwrap();
    assert_eq!((io.strobe_responses, io.produced_id, io.consumed_id), (3, Some(0x385), Some(0x400)));
    assert_eq!(s.last_input.as_deref(), Some(&response[..]));
    assert_eq!((s.produced_size, s.consumed_size), (Some(8), Some(8)));
}

#[test]
fn a_strobe_response_of_another_size_than_attribute_7_fails() {
    let (r, failures) = run(strobe_device(&[1, 2, 3, 4, 5, 6, 7]), IoOptions::of(IoKind::Strobe), 1);
    assert!(r.is_ok());
    assert_eq!(failures.len(), 1, "{failures:#?}");
    assert!(failures[0].contains("DLC 7, expected the produced size 8"), "{failures:#?}");
}

#[test]
fn cos_productions_are_reassembled_acknowledged_and_the_master_data_acknowledged() {
    let (r, failures) =
        run(cos_device(0x10, 0x42A, 100, None, Some(&[])), IoOptions::of(IoKind::ChangeOfState), 4);
    let s = r.unwrap();
    assert!(failures.is_empty(), "{failures:#?}");
    let io = s.io.unwrap();
    assert_eq!((io.productions, io.acks_sent, io.re_sent), (4, 4, 0));
    assert_eq!((io.outputs_sent, io.outputs_acknowledged), (4, 4));
    assert_eq!((io.ack_timer_ms, io.retry_limit), (Some(16), Some(1)));
    assert_eq!(s.last_input.as_deref(), Some(&INPUT[..]));
    assert_eq!(io.interval_min_ms, Some(100.0));
}

#[test]
fn a_first_production_before_the_set_epr_response_belongs_to_the_connection() {
    // The device establishes the connection on the Set EPR and produces at once; its response
    // comes 5 ms later, after the whole production (protocol §II.2.3).
    let device = cos_attributes(0x10, 0x42A)
        .on(0x42C, &SET_EPR_100, &[(5, 0x42B, &[0x00, 0x90, 0x64, 0x00])])
        .produce((0x42C, &SET_EPR_100), 0, 100, productions(), None)
        .on(0x42D, &[0; 8], &[(0, 0x3C5, &[])]);
    let (r, failures) = run(device, IoOptions::of(IoKind::ChangeOfState), 3);
    let s = r.unwrap();
    assert!(failures.is_empty(), "{failures:#?}");
    let io = s.io.unwrap();
    assert_eq!((io.productions, io.acks_sent, io.re_sent), (3, 3, 0));
    assert_eq!(s.last_input.as_deref(), Some(&INPUT[..]));
}

#[test]
fn a_connection_given_back_mid_production_is_followed_again_from_its_next_production() {
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(cos_device(0x20, 0x42A, 100, None, Some(&[]))), PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    let mut m = Master::new(&mut session, MasterConfig::default());
    let opts = ConnectOptions { polls: 1, ..ConnectOptions::default() };
    m.connect_io(&opts, &IoOptions::of(IoKind::Cyclic)).unwrap();
    // A check takes the connection and watches the frames itself: a whole production, then the
    // first fragment of the next; the rest of that one comes after the master has it back.
    let conn = m.end_io().unwrap();
    let deadline = m.session.now() + Duration::from_millis(300);
    let mut watched = 0;
    while let Some(i) = m.session.next(deadline).unwrap() {
        let rec = m.session.record(i).clone();
        if rec.origin == Origin::Remote {
            m.session.set_verdict(i, Verdict::Ok("watched by the test".into()));
            watched += 1;
            if rec.frame.data().first() == Some(&0x00) && watched > 1 {
                break;
            }
        }
    }
    m.resume_io(conn);
    assert_eq!(m.await_production().unwrap(), INPUT);
    assert_eq!(m.await_production().unwrap(), INPUT);
    let failures = crate::master::scripted::failed_frames(m.session);
    assert!(failures.is_empty(), "{failures:#?}");
    let rest = m
        .session
        .records()
        .iter()
        .filter(|r| matches!(&r.verdict, Verdict::Info(n) if n.contains("before the master took")))
        .count();
    assert_eq!(rest, 2, "the middle and last fragments of the production begun before");
    let io = m.io_connection().unwrap();
    assert_eq!(io.summary.productions, 1 + 2, "the one of connect and the two after");
}

#[test]
fn a_cyclic_connection_producing_off_its_epr_fails_and_is_only_noted_where_timing_is_not_judged() {
    let (r, failures) = run(cos_device(0x20, 0x42A, 150, None, Some(&[])), IoOptions::of(IoKind::Cyclic), 3);
    r.unwrap();
    assert!(
        !failures.is_empty() && failures.iter().all(|f| f.contains("produces every EPR")),
        "{failures:#?}"
    );
    let io = IoOptions { judge_timing: false, ..IoOptions::of(IoKind::Cyclic) };
    let (r, failures) = run(cos_device(0x20, 0x42A, 150, None, Some(&[])), io, 3);
    r.unwrap();
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn a_cos_connection_silent_past_its_epr_fails() {
    let (r, failures) =
        run(cos_device(0x10, 0x42A, 180, None, Some(&[])), IoOptions::of(IoKind::ChangeOfState), 2);
    r.unwrap();
    assert!(failures.iter().any(|f| f.contains("at the latest every EPR")), "{failures:#?}");
}

#[test]
fn a_cyclic_series_sent_again_although_acknowledged_in_time_fails_the_epr() {
    let (r, failures) =
        run(cos_device(0x20, 0x42A, 100, Some(20), Some(&[])), IoOptions::of(IoKind::Cyclic), 3);
    let io = r.unwrap().io.unwrap();
    assert_eq!(io.re_sent, 0, "acknowledged in time: not a re-send");
    assert!(
        failures
            .iter()
            .any(|f| f.contains("20.0 ms after the previous production") && f.contains("every EPR")),
        "{failures:#?}"
    );
}

#[test]
fn acknowledge_suppression_sends_no_acknowledgement_and_refuses_one() {
    let io = IoOptions { ack_suppression: true, ..IoOptions::of(IoKind::ChangeOfState) };
    let (r, failures) = run(cos_device(0x50, 0xFFFF, 100, None, Some(&[])), io.clone(), 2);
    let s = r.unwrap().io.unwrap();
    assert_eq!(s.acks_sent, 0);
    assert!(
        failures.iter().all(|f| f.contains("under acknowledge suppression")) && !failures.is_empty(),
        "{failures:#?}"
    );
    let (r, failures) = run(cos_device(0x50, 0xFFFF, 100, None, None), io, 2);
    assert!(r.is_ok() && failures.is_empty(), "{failures:#?}");
}

#[test]
fn attributes_that_contradict_the_wire_fail() {
    // Consumed connection ID 0x42D (the RA tables' slip, §II.2.2) instead of the acknowledgement's.
    let (r, failures) =
        run(cos_device(0x10, 0x42D, 100, None, Some(&[])), IoOptions::of(IoKind::ChangeOfState), 1);
    r.unwrap();
    assert_eq!(failures.len(), 1, "{failures:#?}");
    assert!(failures[0].contains("consumed connection ID 0x042D (1069), expected 0x042A"), "{failures:#?}");
}

#[test]
fn an_unacknowledged_master_output_is_a_timeout() {
    let (r, _) = run(cos_device(0x10, 0x42A, 100, None, None), IoOptions::of(IoKind::ChangeOfState), 1);
    let e = r.unwrap_err().to_string();
    assert!(e.contains("acknowledgement of the master's COS/cyclic data"), "{e}");
}

#[rstest]
#[case::mac_0(0, [0x01, 0, 0, 0, 0, 0, 0, 0])]
#[case::mac_5(5, [0x20, 0, 0, 0, 0, 0, 0, 0])]
#[case::mac_13(13, [0, 0x20, 0, 0, 0, 0, 0, 0])]
#[case::mac_63(63, [0, 0, 0, 0, 0, 0, 0, 0x80])]
fn the_strobe_bit_of_a_mac(#[case] mac: u8, #[case] data: [u8; 8]) {
    assert_eq!(strobe_data(MacId::from_low_bits(mac)), data);
}

#[rstest]
#[case::suppression_on_strobe(IoOptions { ack_suppression: true, ..IoOptions::of(IoKind::Strobe) }, "--ack-suppression")]
#[case::inhibit_on_poll(IoOptions { inhibit_ms: Some(5), ..IoOptions::default() }, "--inhibit")]
#[case::timer_with_suppression(IoOptions { ack_suppression: true, ack_timer_ms: Some(20), ..IoOptions::of(IoKind::Cyclic) }, "turns off")]
#[case::timer_zero(IoOptions { ack_timer_ms: Some(0), ..IoOptions::of(IoKind::Cyclic) }, "1..=65535")]
fn contradicting_options_are_refused(#[case] io: IoOptions, #[case] says: &str) {
    let e = io.validate().unwrap_err().to_string();
    assert!(e.contains(says), "{e}");
}

#[rstest]
#[case::poll("poll", IoKind::Poll, 0x02)]
#[case::strobe("strobe", IoKind::Strobe, 0x04)]
#[case::cos("cos", IoKind::ChangeOfState, 0x10)]
#[case::cyclic("cyclic", IoKind::Cyclic, 0x20)]
fn kinds_by_name(#[case] name: &str, #[case] kind: IoKind, #[case] bit: u8) {
    assert_eq!(name.parse::<IoKind>(), Ok(kind));
    assert_eq!(kind.to_string(), name);
    assert_eq!(kind.choice().bits(), bit);
    assert!("multicast".parse::<IoKind>().unwrap_err().contains("poll, strobe, cos or cyclic"));
}

#[test]
fn series_of_fragments_are_checked_for_their_lengths() {
    let mut s = IoSeries::new(18);
    assert!(matches!(s.take(&[0x00, 0, 1, 2, 3, 4, 5, 6], "x"), SeriesStep::Fragment(Verdict::Ok(_))));
    // A middle fragment one byte short.
    assert!(matches!(s.take(&[0x41, 7, 8, 9, 10, 11, 12], "x"), SeriesStep::Fragment(Verdict::Fail(_))));
    let mut s = IoSeries::new(18);
    assert!(matches!(s.take(&[0x41, 7, 8, 9, 10, 11, 12, 13], "x"), SeriesStep::Rejected(_)));
    let mut s = IoSeries::new(2);
    assert!(matches!(s.take(&[1, 2], "x"), SeriesStep::Complete(d, Verdict::Ok(_)) if d == [1, 2]));
    assert!(matches!(s.take(&[1], "x"), SeriesStep::Complete(_, Verdict::Fail(_))));
    assert_eq!(timing_tolerance(Duration::from_millis(50)), Duration::from_millis(20));
    assert_eq!(timing_tolerance(Duration::from_millis(1000)), Duration::from_millis(200));
}
