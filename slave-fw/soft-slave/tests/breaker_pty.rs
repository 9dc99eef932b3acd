//! The breaker profile over real serial ports: `dnet-sim-breaker` on one end of a socat pty pair,
//! `dnet-soft-slave` on the other (the `serialport` crate, the profile's settings), its CAN side
//! SLCAN on a second pty pair with the master harness at the far end.
//!
//! These need socat, so they are ignored in the plain host-test run and run by the
//! `scripts/check` stage "serial bridge on ptys (socat, pymodbus)":
//! `cargo test -p soft-slave --test breaker_pty -- --ignored`. Without socat they skip with a
//! message, except in CI (`CI=true`), where they fail.

mod common;

use can_io::log::read_log;
use common::{bring_up, link_attribute, poll_until, require_socat, PtyRig};
use devicenet::Duration;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use slave_fw::serial::breaker::{SWITCH_CLOSED, SWITCH_OPEN};
use slave_fw::serial::StatusByte;

fn count(log: &str, event: &str) -> usize {
    log.lines().filter(|l| l.split_once(' ').is_some_and(|(_, e)| e == event)).count()
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn data_reaches_the_poll_response_and_commands_run_exactly_once() {
    if !require_socat() {
        return;
    }
    let mut rig = PtyRig::breaker("exactly-once", &["--closed", "--period", "0.2"], None);
    let mut bus = common::master_bus(&rig);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let summary = bring_up(&mut master);

    // The breaker's status frame, read from the pty, is the poll response.
    let (input, _) =
        poll_until(&mut master, &summary, &[0; 8], Duration::from_secs(3), |i| i[9] == SWITCH_CLOSED);
    assert_eq!(&input[..4], &[120, 118, 121, 3], "{}", rig.dump());

    // Open (command 1, sequence 1) in a hundred polls: the breaker hears it once.
    let open = [1, 1, 0, 0, 0, 0, 0, 0];
    for _ in 0..100 {
        master.poll(common::mac(), &open, 18, 8, Duration::from_millis(500)).unwrap();
    }
    let (input, _) =
        poll_until(&mut master, &summary, &open, Duration::from_secs(3), |i| i[9] == SWITCH_OPEN);
    assert_eq!(&input[..4], &[0; 4]);
    // Close (command 2, sequence 2), twenty times: once more.
    let close = [2, 2, 0, 0, 0, 0, 0, 0];
    for _ in 0..20 {
        master.poll(common::mac(), &close, 18, 8, Duration::from_millis(500)).unwrap();
    }
    poll_until(&mut master, &summary, &close, Duration::from_secs(3), |i| i[9] == SWITCH_CLOSED);
    assert_eq!(link_attribute(&mut master, 5), 2, "commands sent (0x64/1/5)");
    assert_eq!(link_attribute(&mut master, 6), 0, "commands retried (0x64/1/6)");
    assert_eq!(master.session.failures(), 0);
    drop(master);
    drop(session);

    let log = rig.breaker_log();
    assert_eq!(count(&log, "command open"), 1, "{log}");
    assert_eq!(count(&log, "command close"), 1, "{log}");
    let report = rig.stop_slave();
    assert!(report.contains("commands 2 sent, 0 retried, 0 failed"), "{report}");
    let frames = read_log(&rig.dir.join("can.log")).unwrap();
    assert!(frames.iter().filter(|e| e.frame.id().as_raw() == 0x42D).count() >= 120, "every poll is logged");
    assert!(frames.iter().all(|e| &*e.iface == "slcan0"));
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn a_silent_breaker_is_reported_stale_within_the_configured_timeout() {
    if !require_socat() {
        return;
    }
    // Stale timeout 1500 ms, assembly 101, clear policy (tests/descriptions/breaker-with-status.toml).
    let config = common::description("breaker-with-status.toml");
    let rig =
        PtyRig::breaker("stale", &["--closed", "--period", "0.2", "--silent-after", "6"], Some(&config));
    let mut bus = common::master_bus(&rig);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let summary = bring_up(&mut master);
    assert_eq!(summary.produced_size, Some(20));

    let (input, _) =
        poll_until(&mut master, &summary, &[0; 8], Duration::from_secs(3), |i| i[18] & 0x01 != 0);
    assert_eq!(&input[..4], &[120, 118, 121, 3]);
    // Poll every 20 ms; note when the freshness counter last moved and when the status says stale.
    let mut counter = input[19];
    let mut fresh_at = master.session.now();
    let end = fresh_at + Duration::from_secs(10);
    let (stale, stale_at) = loop {
        let i = master.poll(common::mac(), &[0; 8], 20, 8, Duration::from_millis(500)).unwrap();
        let now = master.session.now();
        if i[19] != counter {
            counter = i[19];
            fresh_at = now;
        }
        if i[18] & StatusByte::LINK_TIMEOUT != 0 {
            break (i, now);
        }
        assert!(now < end, "never reported stale; last input {i:02X?}\n{}", rig.dump());
        master.idle_until(now + Duration::from_millis(20)).unwrap();
    };
    let took = stale_at - fresh_at;
    eprintln!("reported stale {} ms after the last fresh frame", took.total_micros() / 1000);
    assert!(
        (1_400_000..=2_000_000).contains(&took.total_micros()),
        "reported stale {took:?} after the last fresh frame; configured 1500 ms"
    );
    assert_eq!(stale[18] & 0x03, StatusByte::LINK_TIMEOUT, "timeout, not ok");
    assert_eq!(&stale[..18], &[0; 18], "clear policy");
    // The scanner's other views: Identity status (minor recoverable fault), the link object.
    let (status, _) = master.get(common::mac(), 1, 1, 5).unwrap();
    assert_eq!(u16::from_le_bytes([status[0], status[1]]) & 0x0100, 0x0100, "minor recoverable fault");
    assert_eq!(link_attribute(&mut master, 15), 2, "link state timeout (0x64/1/15)");
    assert_eq!(link_attribute(&mut master, 12), 1, "one link timeout (0x64/1/12)");
    assert_eq!(master.session.failures(), 0);
    assert!(rig.breaker_log().lines().last().is_some_and(|l| l.ends_with(" silent")), "{}", rig.dump());
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn garbage_and_bad_checksums_are_counted_and_survived() {
    if !require_socat() {
        return;
    }
    let config = common::description("breaker-with-status.toml");
    let rig =
        PtyRig::breaker("garbage", &["--closed", "--period", "0.2", "--garbage-every", "0.5"], Some(&config));
    let mut bus = common::master_bus(&rig);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let summary = bring_up(&mut master);

    // Two seconds of polling: the data keeps coming and the link stays up.
    let mut freshness = Vec::new();
    let (last, _) = poll_until(&mut master, &summary, &[0; 8], Duration::from_secs(5), |i| {
        if freshness.last() != Some(&i[19]) {
            freshness.push(i[19]);
        }
        freshness.len() >= 8
    });
    assert_eq!(&last[..4], &[120, 118, 121, 3]);
    assert_eq!(last[9], SWITCH_CLOSED);
    assert_ne!(last[18] & StatusByte::LINK_OK, 0, "link ok despite the garbage");
    let checksum_errors = link_attribute(&mut master, 2);
    let framing_errors = link_attribute(&mut master, 3);
    let discarded = link_attribute(&mut master, 11);
    let received = link_attribute(&mut master, 1);
    let log = rig.breaker_log();
    let garbage = log.lines().filter(|l| l.ends_with(" garbage 6 bytes")).count() as u32;
    let spoiled = log.lines().filter(|l| l.ends_with(" frame with a bad checksum")).count() as u32;
    assert!(garbage >= 5 && spoiled >= 5, "{log}");
    assert!(
        checksum_errors >= 5 && checksum_errors <= spoiled,
        "checksum errors {checksum_errors}, spoiled {spoiled}"
    );
    assert!(framing_errors >= 5, "framing errors {framing_errors}");
    assert!(discarded >= 5 * 4, "discarded bytes {discarded}");
    assert!(received >= 8, "good frames {received}");
    assert_eq!(master.session.failures(), 0);
}
