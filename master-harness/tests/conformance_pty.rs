//! `dnet-master conformance` on the real SLCAN path: `dnet-soft-slave` as a process on a socat pty
//! pair (with `dnet-sim-breaker` on its serial line), the master at the far end. The whole suite
//! passes with its timing checks advisory (the pty buffers frames, so their arrival times say
//! nothing about the device); an absent device stops the run at once; SIGINT stops the real
//! `dnet-master` process with exit status 130, its log and report kept and the device released.
//! Against `dnet-soft-slave --mutant ID` (one deliberate fault, the self-test's mutants on a real
//! bus) the check that tests the fault fails over SLCAN too, and no other.
//!
//! Needs socat and the built programs (`cargo build -p soft-slave -p master-harness`): ignored in
//! the plain host-test run, run by `scripts/check`; skips with a message without socat, fails in
//! CI.

use pty_rig::{require_socat, Proc, PtyRig};
use std::time::{Duration, Instant};

fn master(rig: &PtyRig, args: &[&str]) -> (u8, String, String) {
    let bus = rig.master_bus_arg();
    let mut all = vec!["dnet-master", "--bus", bus.as_str()];
    all.extend_from_slice(args);
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = master_harness::cli::run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn the_suite_passes_over_slcan_with_timing_advisory() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("conformance-suite", &["--period", "0.3"], None);
    let html = rig.dir.join("report.html");
    let started = Instant::now();
    let (code, out, err) =
        master(&rig, &["--json", "conformance", "--mac", "5", "--html", html.to_str().unwrap()]);
    let took = started.elapsed();
    eprintln!("the suite over SLCAN on a pty took {took:?}");
    let v: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}\n{out}\n{err}\n{}", rig.dump()));
    let failed: Vec<String> = v["checks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["grade"] == "fail")
        .map(|c| format!("{}: {}", c["id"], c["expectations"]))
        .collect();
    assert_eq!(code, 0, "failed checks: {failed:#?}\n{err}");
    assert_eq!(v["summary"]["fail"], 0);
    assert_eq!(v["summary"]["checks"], 52);
    assert!(v["transport"].as_str().unwrap().starts_with("slcan:"), "{}", v["transport"]);
    assert_eq!(v["timestamps"]["source"], "host_buffered");
    assert_eq!(v["timestamps"]["timing_judged"], false);
    // The timing checks are advisory, with the reason.
    for id in ["poll-latency", "explicit-latency", "watchdog-poll-timed-out"] {
        let c = v["checks"].as_array().unwrap().iter().find(|c| c["id"] == id).unwrap();
        assert_eq!(c["grade"], "advisory", "{c}");
        assert!(c["expectations"].to_string().contains("frames arrive in bursts"), "{c}");
    }
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("host receive time of buffered serial lines"));
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn an_absent_device_stops_the_run_at_once() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("conformance-absent", &["--period", "0.3"], None);
    let started = Instant::now();
    let (code, out, err) = master(&rig, &["conformance", "--mac", "7"]);
    let took = started.elapsed();
    eprintln!("conformance against an absent MAC 7 over SLCAN stopped after {took:?}");
    assert_eq!(code, 1, "{out}\n{err}");
    assert!(err.contains("error: no device answers at MAC 7"), "{err}");
    assert!(out.contains("1 of 52 checks run"), "{out}");
    assert!(took < Duration::from_secs(20), "{took:?}");
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn sigint_stops_the_run_keeps_the_log_and_releases_the_device() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("conformance-sigint", &["--period", "0.3"], None);
    let bus = rig.master_bus_arg();
    let log = rig.dir.join("master.log");
    let args = ["--bus", bus.as_str(), "--log", log.to_str().unwrap(), "--json", "conformance", "--mac", "5"];
    let mut proc = Proc::spawn(env!("CARGO_BIN_EXE_dnet-master"), &args);
    // Into the connection set checks (the bring-up takes about 3 s).
    std::thread::sleep(Duration::from_secs(8));
    assert!(proc.running(), "{}", proc.dump());
    let asked = Instant::now();
    proc.signal("INT");
    let status =
        proc.wait(Duration::from_secs(20)).unwrap_or_else(|| panic!("still running\n{}", proc.dump()));
    eprintln!("stopped {:?} after SIGINT", asked.elapsed());
    assert_eq!(status.code(), Some(130), "{}", proc.dump());
    let v: serde_json::Value = serde_json::from_str(&proc.stdout.text()).unwrap();
    assert_eq!(v["interrupted"], "SIGINT");
    assert_eq!(v["ok"], false);
    let checks = v["summary"]["checks"].as_u64().unwrap();
    assert!((1..52).contains(&checks), "{checks} checks completed");
    let logged = std::fs::read_to_string(&log).unwrap();
    assert!(logged.lines().count() > 28, "the log holds the frames:\n{logged}");
    // Released: another master run connects at once.
    let (code, out, err) = {
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let code = master_harness::cli::run(
            ["dnet-master", "--bus", bus.as_str(), "connect", "--mac", "5"],
            &mut out,
            &mut err,
            false,
        );
        (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
    };
    assert_eq!(code, 0, "connect after the interrupted run\n{out}\n{err}\n{}", rig.dump());
    assert!(!err.contains("released and allocated again"), "nothing was left allocated: {err}");
}

/// The failed expectations of a JSON report, one per line.
fn findings(v: &serde_json::Value) -> String {
    let mut lines = Vec::new();
    for c in v["checks"].as_array().into_iter().flatten() {
        for e in c["expectations"].as_array().into_iter().flatten().filter(|e| e["grade"] == "fail") {
            lines.push(format!("{}: {}", c["id"], e["text"]));
        }
    }
    lines.join("\n")
}

/// The suite against `dnet-soft-slave --mutant ID` on the pty pair: the checks that fail.
fn failed_against_mutant(id: &str) -> (Vec<String>, serde_json::Value, PtyRig) {
    let rig = PtyRig::breaker_with(
        &format!("conformance-mutant-{id}"),
        &["--period", "0.3"],
        None,
        &["--mutant", id],
    );
    let (code, out, err) = master(&rig, &["--json", "conformance", "--mac", "5"]);
    assert_eq!(code, 1, "{err}\n{}", rig.dump());
    let v: serde_json::Value =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}\n{out}\n{err}\n{}", rig.dump()));
    let failed = v["checks"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["grade"] == "fail")
        .map(|c| c["id"].as_str().unwrap().to_string())
        .collect();
    (failed, v, rig)
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn a_mutant_soft_slave_fails_its_target_check_over_slcan() {
    if !require_socat() {
        return;
    }
    // Frames added by the fault: an answer to UCMM.
    let (failed, v, rig) = failed_against_mutant("answers-ucmm");
    assert_eq!(failed, ["ucmm-silent"], "{}", findings(&v));
    assert!(rig.slave.as_ref().unwrap().stderr.text().contains("MUTANT answers-ucmm"));
    let check = v["checks"].as_array().unwrap().iter().find(|c| c["id"] == "ucmm-silent").unwrap();
    assert!(check["expectations"].to_string().contains("answered a UCMM open"), "{check}");
    // A frame fed to the node: the acknowledgement it should have waited for.
    let (failed, v, _rig) = failed_against_mutant("does-not-wait-for-ack");
    assert_eq!(failed, ["missing-ack"], "{}", findings(&v));
}
