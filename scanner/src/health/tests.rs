//! Unit tests of [`Health`](super::Health): frames in, figures out.

use super::{Cause, Health};
use can_io::bus::health::{ErrorReport, ErrorState};
use can_io::bus::{Bitrate, Origin};
use devicenet::{CanFrame, Instant};

fn frame(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::from_raw(id, data).unwrap()
}

fn ms(t: u64) -> Instant {
    Instant::from_millis(t)
}

/// MAC 5 polled, MAC 9 strobed, scanner at MAC 0, EPR 100 ms (window 1 s).
fn health() -> Health {
    Health::new(&[(5, false), (9, true)], 0, Bitrate::K500, 100)
}

#[test]
fn poll_and_strobe_responses_are_timed_from_the_request() {
    let mut h = health();
    h.observe(&frame(0x405 | 5 << 3, &[0; 8]), Origin::Local, ms(10)); // poll command to 5
    h.observe(&frame(0x400, &[0; 8]), Origin::Local, ms(11)); // bit-strobe
    h.observe(&frame(0x3C0 | 5, &[1]), Origin::Remote, ms(12)); // 5's poll response: 2 ms
    h.observe(&frame(0x380 | 9, &[1]), Origin::Remote, ms(14)); // 9's strobe response: 3 ms
    h.observe(&frame(0x3C0 | 5, &[1]), Origin::Remote, ms(15)); // unasked: not timed
    let r = h.report(ms(20));
    let t5 = r.node(5).unwrap().response_ms.unwrap();
    let t9 = r.node(9).unwrap().response_ms.unwrap();
    assert_eq!((t5.min, t5.avg, t5.max, t5.count), (2.0, 2.0, 2.0, 1));
    assert_eq!((t9.min, t9.count), (3.0, 1));
    // The strobe command is the scanner's own (MAC 0): nobody's traffic.
    assert_eq!((r.node(5).unwrap().frames, r.node(9).unwrap().frames), (3, 1));
    assert_eq!(r.bus.frames, 5);
    let share: f64 = r.nodes.iter().map(|n| n.traffic_pct).sum();
    assert!(share < 100.0, "the strobe command counts for no node: {share}");
}

#[test]
fn drop_outs_within_the_window_are_one_incident_ordered_by_last_heard() {
    let mut h = health();
    h.observe(&frame(0x380 | 9, &[1]), Origin::Remote, ms(100));
    h.observe(&frame(0x3C0 | 5, &[1]), Origin::Remote, ms(300));
    // 5 is detected first, but 9 went silent first.
    h.dropped_out(5, ms(700));
    h.dropped_out(9, ms(900));
    let r = h.report(ms(1000));
    assert_eq!(r.incidents.len(), 1);
    assert_eq!((r.incidents[0].cause, r.incidents[0].first), (Cause::DropOuts, Some(9)));
    assert_eq!(r.incidents[0].nodes.iter().map(|d| d.mac).collect::<Vec<_>>(), vec![9, 5]);
}

#[test]
fn a_lone_drop_out_is_no_incident_and_drop_outs_apart_are_two_lone_ones() {
    let mut h = health();
    h.dropped_out(5, ms(1_000));
    h.dropped_out(9, ms(5_000));
    h.dropped_out(5, ms(41_000));
    let r = h.report(ms(42_000));
    assert!(r.incidents.is_empty(), "{:?}", r.incidents);
    let n5 = r.node(5).unwrap();
    assert_eq!((n5.dropouts, n5.last_dropout_s, n5.dropout_interval_s), (2, Some(41.0), Some(40.0)));
    assert!(r.findings.iter().any(|f| f == "MAC 5 drops out every 40 s (2 times)"), "{:?}", r.findings);
    assert_eq!(r.score, 85, "three drop-outs, 5 each: {:?}", r.findings);
}

#[test]
fn a_bus_off_starts_an_incident_that_the_drop_outs_after_it_join() {
    let mut h = health();
    let report =
        |state, bus_offs| Some(ErrorReport { state, tec: Some(0), rec: Some(0), error_frames: 40, bus_offs });
    h.bus_state(report(ErrorState::Active, 0), ms(100));
    h.bus_state(report(ErrorState::Active, 1), ms(200)); // a bus-off and its recovery between two looks
    h.dropped_out(5, ms(600));
    let r = h.report(ms(700));
    assert_eq!(r.incidents.len(), 1);
    assert_eq!((r.incidents[0].cause, r.incidents[0].first), (Cause::BusOff, Some(5)));
    assert_eq!((r.bus.bus_offs, r.bus.error_frames), (Some(1), Some(40)));
    // Cleared: counted from the clear on; TEC, REC and state stay the controller's.
    h.clear(ms(800));
    h.bus_state(report(ErrorState::Warning, 1), ms(900));
    let r = h.report(ms(1_000));
    assert_eq!((r.bus.bus_offs, r.bus.error_frames, r.bus.state), (Some(0), Some(0), "warning"));
    assert!(r.incidents.is_empty() && r.nodes.iter().all(|n| n.dropouts == 0));
}

#[test]
fn a_bus_that_reports_nothing_says_unknown() {
    let mut h = health();
    h.bus_state(None, ms(10));
    let r = h.report(ms(10));
    assert_eq!((r.bus.state, r.bus.tec, r.bus.error_frames, r.bus.bus_off), ("unknown", None, None, None));
    assert_eq!(r.score, 100);
}

#[test]
fn a_node_added_while_running_is_measured_from_then_on() {
    let mut h = health();
    h.observe(&frame(0x405 | 7 << 3, &[0; 8]), Origin::Local, ms(10)); // poll to 7: not listed yet
    h.observe(&frame(0x3C0 | 7, &[1]), Origin::Remote, ms(11));
    assert!(h.report(ms(12)).node(7).is_none());
    h.track(7, false, true);
    h.observe(&frame(0x405 | 7 << 3, &[0; 8]), Origin::Local, ms(20));
    h.observe(&frame(0x3C0 | 7, &[1]), Origin::Remote, ms(24));
    h.dropped_out(7, ms(900));
    let r = h.report(ms(1_000));
    let n7 = r.node(7).unwrap();
    assert_eq!((n7.frames, n7.response_ms.unwrap().avg, n7.dropouts), (2, 4.0, 1));
    assert!(n7.traffic_pct > 0.0);
}

#[test]
fn a_removed_node_leaves_the_statistics() {
    let mut h = health();
    h.observe(&frame(0x3C0 | 5, &[1]), Origin::Remote, ms(10));
    h.dropped_out(5, ms(500));
    h.untrack(5);
    h.dropped_out(5, ms(600));
    h.observe(&frame(0x3C0 | 5, &[1]), Origin::Remote, ms(700));
    let r = h.report(ms(1_000));
    assert!(r.node(5).is_none());
    assert_eq!(r.nodes.iter().map(|n| n.mac).collect::<Vec<_>>(), vec![9]);
    assert_eq!(r.score, 100, "its drop-out left with it: {:?}", r.findings);
}

#[test]
fn a_disabled_node_has_no_drop_outs_counted_until_enabled_again() {
    let mut h = health();
    h.set_enabled(9, false);
    h.observe(&frame(0x400, &[0; 8]), Origin::Local, ms(10)); // bit-strobe: 9 is not awaited
    h.observe(&frame(0x380 | 9, &[1]), Origin::Remote, ms(12));
    h.dropped_out(9, ms(500));
    h.dropped_out(5, ms(600));
    let r = h.report(ms(700));
    let n9 = r.node(9).unwrap();
    assert_eq!((n9.dropouts, n9.disabled, n9.response_ms), (0, true, None));
    assert!(r.incidents.is_empty(), "one counted drop-out is no incident: {:?}", r.incidents);
    h.set_enabled(9, true);
    h.dropped_out(9, ms(5_000));
    let n9 = h.report(ms(5_100)).node(9).cloned().unwrap();
    assert_eq!((n9.dropouts, n9.disabled), (1, false));
}
