//! Bus and node health (issue 28 item 3, guide: docs/src/plant/health.md): the scanner's
//! `bus` report, each node's response times, drop-outs and the node that dropped first, on the
//! simulated bus under fault injection (the master's TEC/REC by the ISO 11898-1 rules, its
//! bus-off) and on the real SLCAN path (socat pty pairs: the soft slave and the simulated breaker,
//! and an adapter that answers `F` with status flags).
//!
//! The pty tests need socat: ignored in the plain host-test run, run by `scripts/check`'s health
//! stage (`cargo build -p soft-slave -p master-harness && cargo test -p system-tests --test
//! health -- --ignored`).

use can_io::bus::health::ErrorState;
use can_io::bus::{Bitrate, Bus};
use can_io::sim::fault::{Fault, FaultRule, PatternFaults, Station};
use can_io::sim::{PowerOn, SimBus};
use converter_sim::SoftSlave;
use devicenet::{Instant, MacId};
use dnet_scanner::engine::{build_scan_list, Scanner, ScannerOptions};
use dnet_scanner::health::HealthReport;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use pty_rig::console::{csrf_token, get, http, spawn_ui};
use std::collections::HashMap;
use std::io::Write;

fn mac(m: u8) -> MacId {
    MacId::new(m).unwrap()
}

/// Reference breakers at `macs` on a simulated bus at 500 kbit/s with the fault `rules`.
fn sim_bus(macs: &[u8], rules: Vec<FaultRule>) -> SimBus {
    let mut bus = SimBus::new(Bitrate::K500);
    for &m in macs {
        bus.attach(Box::new(SoftSlave::reference(mac(m))), PowerOn::WhenMasterOnline);
    }
    let mut faults = PatternFaults::new();
    for r in rules {
        faults = faults.rule(r);
    }
    bus.set_faults(Some(Box::new(faults)));
    bus
}

/// A scanner over the network scan's list, run for `cycles` cycles; its health report.
/// With `clear_after` (cycle, error frames): the errors counted by then are checked, then the
/// statistics cleared.
fn run(bus: &mut SimBus, cycles: u32, clear_after: Option<(u32, u64)>) -> HealthReport {
    let mut session = Session::new(bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let list = build_scan_list(&mut master, 0, 63).unwrap();
    let options = ScannerOptions { cycles: None, bitrate: Bitrate::K500, layouts: HashMap::new() };
    let mut scanner = Scanner::new(list, 0, options);
    scanner.start(&mut master).unwrap();
    for c in 0..cycles {
        scanner.cycle(&mut master).unwrap();
        if let Some((_, errors)) = clear_after.filter(|a| a.0 == c) {
            let (tx, rx) = std::sync::mpsc::channel();
            scanner.command(
                &mut master,
                dnet_scanner::model::ConsoleCommand::Health { clear: false, reply: tx },
            );
            let before = rx.recv().unwrap();
            assert_eq!(before.bus.error_frames, Some(errors), "{:?}", before.bus);
            assert!(before.bus.frames > 0);
            let (tx, rx) = std::sync::mpsc::channel();
            scanner
                .command(&mut master, dnet_scanner::model::ConsoleCommand::Health { clear: true, reply: tx });
            let cleared = rx.recv().unwrap();
            assert_eq!(cleared.bus.frames, 0, "{cleared:?}");
            assert!(cleared
                .nodes
                .iter()
                .all(|n| n.frames == 0 && n.dropouts == 0 && n.response_ms.is_none()));
            assert!(cleared.incidents.is_empty());
            assert_eq!(cleared.bus.error_frames, Some(0));
        }
    }
    let now = master.session.now();
    scanner.health().report(now)
}

#[test]
fn a_healthy_bus_scores_100_with_response_times_and_traffic() {
    let mut bus = sim_bus(&[5, 6], vec![]);
    let r = run(&mut bus, 50, None);
    assert_eq!(
        (r.bus.state, r.bus.tec, r.bus.rec, r.bus.error_frames),
        ("active", Some(0), Some(0), Some(0))
    );
    assert_eq!((r.bus.bus_off, r.bus.bus_offs), (Some(false), Some(0)));
    assert!(r.bus.load > 0.0 && r.bus.load < 1.0, "{:?}", r.bus);
    for n in &r.nodes {
        let t = n.response_ms.unwrap_or_else(|| panic!("MAC {}: no response time", n.mac));
        assert!(t.count >= 50 && t.min > 0.0 && t.min <= t.avg && t.avg <= t.max, "{n:?}");
        assert!(n.traffic_pct > 30.0 && n.traffic_pct < 70.0, "two alike nodes share the traffic: {n:?}");
        assert_eq!(n.dropouts, 0);
    }
    assert_eq!((r.score, r.findings.len()), (100, 0), "{:?}", r.findings);
}

#[test]
fn destroyed_frames_drive_the_master_bus_off_by_the_iso_counts() {
    // 32 of the master's Group 2 frames destroyed in a row after the start: TEC 32 × 8 = 256.
    let rule = FaultRule::new(Fault::Destroy, 0x400..=0x5FF).from(Station::Master).skip(150).times(32);
    let mut bus = sim_bus(&[5, 6], vec![rule]);
    let r = run(&mut bus, 80, None);
    assert_eq!(r.bus.error_frames, Some(32), "{:?}", r.bus);
    assert_eq!(r.bus.bus_offs, Some(1), "{:?}", r.bus);
    // Back after 128 × 11 bits with zero counters; error-free frames keep TEC at 0.
    assert_eq!((r.bus.state, r.bus.tec, r.bus.rec, r.bus.bus_off), ("active", Some(0), Some(0), Some(false)));
    assert_eq!(r.incidents.len(), 1, "{:?}", r.incidents);
    assert_eq!(r.incidents[0].cause, dnet_scanner::health::Cause::BusOff);
    assert!(r.findings.iter().any(|f| f.contains("bus-off 1 time")), "{:?}", r.findings);
    assert!(r.findings.iter().any(|f| f.contains("32 error frame(s)")), "{:?}", r.findings);
    assert!(r.score <= 80, "{}", r.score);
}

#[test]
fn fewer_errors_leave_the_master_error_passive_then_recovering() {
    // 17 errors: TEC 136, error passive; each later frame sent without error takes 1 off.
    let rule = FaultRule::new(Fault::Destroy, 0x400..=0x5FF).from(Station::Master).skip(150).times(17);
    let mut bus = sim_bus(&[5], vec![rule]);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let list = build_scan_list(&mut master, 0, 63).unwrap();
    let mut scanner =
        Scanner::new(list, 0, ScannerOptions { bitrate: Bitrate::K500, ..ScannerOptions::default() });
    scanner.start(&mut master).unwrap();
    let mut seen = Vec::new();
    for _ in 0..60 {
        scanner.cycle(&mut master).unwrap();
        let now = master.session.now();
        let r = scanner.health().report(now);
        seen.push((r.bus.state, r.bus.tec.unwrap()));
    }
    let peak = seen.iter().map(|s| s.1).max().unwrap();
    assert!((128..=136).contains(&peak), "{seen:?}");
    assert!(
        seen.iter().all(|s| (s.1 >= 128) == (s.0 == "passive")),
        "passive exactly at 128 and above: {seen:?}"
    );
    assert!(seen.last().unwrap().1 < peak, "{seen:?}");
    assert!(!seen.iter().any(|s| s.0 == "bus_off"));
}

#[test]
fn two_nodes_silenced_one_after_the_other_are_one_incident_with_the_first_named() {
    // MAC 6 is not heard from its 120th frame on, MAC 7 from its 160th: 6 went silent first.
    let silence = |m: u8, skip: u32| {
        FaultRule::new(Fault::Drop, 0..=0x7FF).from(Station::Device(mac(m))).to(Station::Master).skip(skip)
    };
    let mut bus = sim_bus(&[5, 6, 7], vec![silence(7, 160), silence(6, 120)]);
    let r = run(&mut bus, 400, None);
    let node = |m: u8| r.nodes.iter().find(|n| n.mac == m).unwrap();
    assert_eq!((node(5).dropouts, node(6).dropouts, node(7).dropouts), (0, 1, 1), "{:?}", r.nodes);
    assert!(node(6).last_dropout_s.is_some() && node(5).last_dropout_s.is_none());
    let multi: Vec<_> =
        r.incidents.iter().filter(|i| i.cause == dnet_scanner::health::Cause::DropOuts).collect();
    assert_eq!(multi.len(), 1, "{:?}", r.incidents);
    assert_eq!(multi[0].first, Some(6));
    assert_eq!(multi[0].nodes.iter().map(|d| d.mac).collect::<Vec<_>>(), vec![6, 7]);
    assert!(multi[0].nodes[0].last_heard_us < multi[0].nodes[1].last_heard_us);
    assert!(
        r.findings.iter().any(|f| f.contains("2 nodes dropped out together, in this order: MAC 6, MAC 7")),
        "{:?}",
        r.findings
    );
    assert!(r.findings.iter().any(|f| f.starts_with("MAC 6 dropped out once")), "{:?}", r.findings);
    assert_eq!(r.score, 90, "two drop-outs, 5 each: {:?}", r.findings);
}

#[test]
fn clearing_starts_the_statistics_again() {
    let rule = FaultRule::new(Fault::Destroy, 0x400..=0x5FF).from(Station::Master).skip(150).times(3);
    let mut bus = sim_bus(&[5], vec![rule]);
    // The errors come before the clear (after cycle 100); the report counts from the clear.
    let r = run(&mut bus, 110, Some((100, 3)));
    assert_eq!(r.bus.error_frames, Some(0), "{:?}", r.bus);
    assert!(r.bus.frames > 0 && r.nodes[0].response_ms.is_some_and(|t| t.count <= 10), "{r:?}");
}

#[test]
fn the_report_exports_as_csv_with_a_row_per_node() {
    let mut bus = sim_bus(&[5, 6], vec![]);
    let r = run(&mut bus, 5, None);
    let csv = r.csv();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0],
        "mac,frames,traffic_pct,response_min_ms,response_avg_ms,response_max_ms,responses,dropouts,last_dropout_s,dropout_interval_s"
    );
    assert_eq!(lines.len(), 3, "{csv}");
    for (line, n) in lines[1..].iter().zip(&r.nodes) {
        let cells: Vec<&str> = line.split(',').collect();
        assert_eq!(cells.len(), 10, "{line}");
        assert_eq!(cells[0], n.mac.to_string());
        assert_eq!(cells[4].parse::<f64>().ok(), n.response_ms.map(|t| t.avg), "{line}");
        assert_eq!((cells[7], cells[8]), ("0", ""), "{line}");
    }
}

/// An SLCAN adapter on `port` (one end of a socat pty pair) that answers the set-up commands
/// `\r` and each `F` with the next of `flags` (BEL when `flags` is empty), until `stop`.
fn fake_adapter(
    port: String,
    flags: Vec<&'static str>,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut link =
            serialport::new(&port, 115_200).timeout(std::time::Duration::from_millis(20)).open().unwrap();
        let mut flags = flags.into_iter();
        let mut seen = Vec::new();
        let mut line = Vec::new();
        let mut buf = [0u8; 64];
        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
            let n = link.read(&mut buf).unwrap_or(0);
            for &b in &buf[..n] {
                seen.push(b);
                if b != b'\r' {
                    line.push(b);
                    continue;
                }
                let answer = match line.as_slice() {
                    b"F" => match flags.next() {
                        Some(f) => format!("{f}\r"),
                        None => "\x07".into(),
                    },
                    _ => "\r".into(),
                };
                link.write_all(answer.as_bytes()).unwrap();
                line.clear();
            }
        }
        seen
    })
}

/// Receives until `ms` ms after the bus's start.
fn listen(bus: &mut dyn Bus, ms: u64) {
    while bus.recv(Instant::from_millis(ms)).unwrap().is_some() {}
}

#[test]
#[ignore = "needs socat; run by scripts/check's health stage"]
fn status_flags_from_an_slcan_adapter_on_a_pty() {
    if !pty_rig::require_socat() {
        return;
    }
    let pair = pty_rig::PtyPair::new();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let adapter = fake_adapter(pair.a.clone(), vec!["F24", "F00"], stop.clone());
    let mut bus = can_io::bus::slcan::open(&pair.b, 115_200, Bitrate::K500).unwrap();
    assert_eq!(bus.error_state(), None, "asked, not yet answered");
    listen(&mut bus, 200);
    let passive = bus.error_state().expect("the answer F24");
    assert_eq!((passive.state, passive.tec, passive.rec), (ErrorState::Passive, None, None));
    listen(&mut bus, 1_100);
    assert_eq!(bus.error_state().map(|r| r.state), Some(ErrorState::Passive), "asks again, answer pending");
    listen(&mut bus, 1_300);
    assert_eq!(bus.error_state().map(|r| r.state), Some(ErrorState::Active), "the answer F00");
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let seen = adapter.join().unwrap();
    assert!(String::from_utf8_lossy(&seen).ends_with("O\rF\rF\r"), "{:?}", String::from_utf8_lossy(&seen));
}

#[test]
#[ignore = "needs socat; run by scripts/check's health stage"]
fn an_slcan_adapter_that_refuses_f_is_no_bus_error() {
    if !pty_rig::require_socat() {
        return;
    }
    let pair = pty_rig::PtyPair::new();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let adapter = fake_adapter(pair.a.clone(), vec![], stop.clone());
    let mut bus = can_io::bus::slcan::open(&pair.b, 115_200, Bitrate::K500).unwrap();
    assert_eq!(bus.error_state(), None);
    listen(&mut bus, 1_200);
    assert_eq!(bus.error_state(), None, "refused: not asked again, no state");
    listen(&mut bus, 1_400);
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let seen = adapter.join().unwrap();
    assert_eq!(seen.iter().filter(|&&b| b == b'F').count(), 1);
}

#[test]
#[ignore = "needs socat; run by scripts/check's health stage"]
fn the_scanner_reports_health_on_the_slcan_pty_path() {
    if !pty_rig::require_socat() {
        return;
    }
    let rig = pty_rig::PtyRig::breaker("health-slcan", &[], None);
    let bus = rig.master_bus_arg();
    let mut master = pty_rig::Proc::spawn(
        pty_rig::bin("dnet-master"),
        &["--bus", &bus, "--bitrate", "500k", "--json", "scanner", "--cycles", "150"],
    );
    let status = master.wait(std::time::Duration::from_secs(60)).expect("the scanner ends");
    assert_eq!(status.code(), Some(0), "{}\n{}", master.dump(), rig.dump());
    let out = master.stdout.text();
    let v: serde_json::Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}\n{out}"));
    // The soft slave's end answers `F` as an adapter with no CAN controller would: F00.
    assert_eq!(v["bus"]["state"], "active", "{v}");
    assert_eq!(v["bus"]["tec"], serde_json::Value::Null, "the flags carry no counters: {v}");
    assert_eq!(v["bus"]["error_frames"], 0, "{v}");
    let load = v["bus"]["load"].as_f64().unwrap();
    assert!(load > 0.0 && load < 1.0, "{v}");
    let node = &v["nodes"][0];
    assert_eq!(node["mac"], 5);
    let t = &node["response_ms"];
    assert!(t["count"].as_u64().unwrap() >= 150, "{v}");
    assert!(t["min"].as_f64().unwrap() <= t["avg"].as_f64().unwrap(), "{v}");
    assert_eq!(node["dropouts"], 0, "{v}");
    assert_eq!(v["health"]["score"], 100, "{v}");
}

#[test]
#[ignore = "needs dnet-master built: run by scripts/check's health stage"]
fn the_console_serves_clears_and_exports_the_health() {
    let dir = pty_rig::scratch("health-console");
    let history = dir.join("h.sqlite");
    let (mut ui, addr) = spawn_ui(
        &["--bus", "sim", "--slave-mac", "5,6", "--realtime"],
        &["--history", history.to_str().unwrap()],
        std::time::Duration::from_secs(30),
        String::new,
    );
    let end = std::time::Instant::now() + std::time::Duration::from_secs(30);
    let report = loop {
        assert!(std::time::Instant::now() < end, "no health report with responses\n{}", ui.dump());
        let (status, body) = get(&addr, "/api/health");
        if status == 200 {
            let v: serde_json::Value = serde_json::from_str(&body).unwrap();
            if v["nodes"].as_array().is_some_and(|n| {
                n.len() == 2 && n.iter().all(|n| n["response_ms"]["count"].as_u64() >= Some(5))
            }) {
                break v;
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(200));
    };
    assert_eq!(
        (report["ok"].as_bool(), report["bus"]["state"].as_str()),
        (Some(true), Some("active")),
        "{report}"
    );
    // The simulated bus at 250 kbit/s with two polled nodes runs near 70 % load: the only finding.
    let load = report["bus"]["load"].as_f64().unwrap();
    let long = report["duration_s"].as_f64().unwrap() >= 1.0;
    let expected = if !long {
        100
    } else if load > 0.8 {
        80
    } else if load > 0.6 {
        90
    } else {
        100
    };
    assert_eq!(report["score"], expected, "{report}");
    let findings = report["findings"].as_array().unwrap();
    assert!(findings.iter().all(|f| f.as_str().unwrap().starts_with("bus load ")), "{report}");
    assert_eq!(findings.len(), usize::from(expected < 100), "{report}");
    let (status, csv) = get(&addr, "/api/health.csv");
    assert_eq!(status, 200, "{csv}");
    let rows: Vec<&str> = csv.lines().collect();
    assert!(rows[0].starts_with("mac,frames,traffic_pct,response_min_ms"), "{csv}");
    assert_eq!(rows.len(), 3, "{csv}");
    assert!(rows[1].starts_with("5,") && rows[2].starts_with("6,"), "{csv}");
    // A GET cannot clear; a POST with the page's token does.
    assert_eq!(get(&addr, "/api/health/clear").0, 405);
    let token = csrf_token(&addr);
    let (status, body) = http(&addr, "POST", "/api/health/clear", Some(&token), "{}");
    assert_eq!(status, 200, "{body}");
    let cleared: serde_json::Value = serde_json::from_str(&body).unwrap();
    let before: u64 = report["bus"]["frames"].as_u64().unwrap();
    let after = cleared["bus"]["frames"].as_u64().unwrap();
    assert!(before > 0 && after < before, "cleared: {after} frames after {before}");
    assert!(
        cleared["nodes"]
            .as_array()
            .unwrap()
            .iter()
            .all(|n| n["response_ms"]["count"].as_u64().unwrap_or(0) <= 2),
        "{cleared}"
    );
    ui.terminate();
}
