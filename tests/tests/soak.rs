//! The soak: hours of virtual time of the master polling the soft slave (converter + simulated
//! breaker) while the bus drops, duplicates, delays and destroys frames, the device goes bus-off,
//! and the breaker goes silent or sends garbage; every invariant of `master_harness::soak` holds.
//! Run with `--nocapture` to see the figures.

use master_harness::soak::{self, SoakConfig};

/// Virtual hours of the soak in the test suite (override with `SOAK_HOURS`).
fn hours() -> f64 {
    std::env::var("SOAK_HOURS").ok().and_then(|h| h.parse().ok()).unwrap_or(4.0)
}

#[test]
fn hours_of_faults_break_no_invariant() {
    let cfg = SoakConfig::hours(hours(), 0x5EED);
    let r = soak::run(&cfg).unwrap();
    println!("{}", r.summary());
    for v in &r.violations {
        println!("violation: {v}");
    }
    assert_eq!(r.violation_count, 0, "{:#?}", r.violations);
    // The faults really happened, and the system really worked through them.
    let f = r.bus_faults;
    assert!(f.destroyed > 0 && f.duplicated > 0 && f.dropped > 0 && f.delayed > 0 && f.bus_offs > 0, "{f:?}");
    assert!(r.instrument_silences > 0 && r.instrument_garbage_bursts > 0);
    assert!(r.connections_lost > 0 && r.connections_established > r.connections_lost);
    assert!(r.recoveries > 0 && r.max_recovery_ms <= cfg.recovery_bound.total_millis() as f64);
    assert!(r.commands_exactly_once > 0 && r.commands_reported_failed > 0);
    assert_eq!(
        r.commands,
        r.commands_exactly_once + r.commands_reported_failed + r.commands_repeated_after_lost_ack
    );
    assert!(r.max_queued_frames < 64, "{}", r.max_queued_frames);
}

#[test]
fn the_same_seed_gives_the_same_run() {
    let cfg = SoakConfig::hours(0.3, 7);
    let (a, b) = (soak::run(&cfg).unwrap(), soak::run(&cfg).unwrap());
    assert_eq!((a.frames, a.bus_faults, a.commands, a.polls), (b.frames, b.bus_faults, b.commands, b.polls));
}
