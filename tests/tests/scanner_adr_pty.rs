//! The scanner's automatic device replacement on the real SLCAN path (issue 28 item 2):
//! `dnet-master scanner` keeps `dnet-soft-slave` (MAC 5, stored in its state file, program
//! position) in I/O over socat ptys; the soft slave is stopped and a fresh one with the same
//! identity and no stored MAC starts (at MAC 63, as a replacement out of the box); the scanner
//! moves it to MAC 5 and brings it into I/O. The wall time from its appearance at 63 to I/O is
//! printed (the figure the guide gives).
//!
//! Needs socat and the programs (`dnet-master`, `dnet-soft-slave`, `dnet-sim-breaker`): ignored in
//! the plain host-test run, run by scripts/check's scanner-adr stage.

use pty_rig::plant::BREAKER_SCANLIST;
use pty_rig::{Proc, PtyRig};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// The reference breaker's description in the program position (MAC settable over the network).
fn programmable(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(pty_rig::workspace_dir().join("slave-fw/descriptions/breaker.toml"))
        .unwrap()
        .replace("programmable = false", "programmable = true");
    assert!(text.contains("programmable = true"), "the reference description changed");
    let path = dir.join("breaker-programmable.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
#[ignore = "needs socat: run by scripts/check's scanner-adr stage"]
fn a_stopped_soft_slave_is_replaced_by_a_fresh_one_at_63() {
    if !pty_rig::require_socat() {
        return;
    }
    let dir = pty_rig::scratch("scanner-adr-pty-files");
    let description = programmable(&dir);
    let old_state = dir.join("old-state.json");
    std::fs::write(&old_state, "{ \"mac_id\": 5 }\n").unwrap();
    let new_state = dir.join("new-state.json");
    let _ = std::fs::remove_file(&new_state);
    let list = dir.join("list.toml");
    // The breaker, replaced automatically with its configuration and address.
    std::fs::write(&list, format!("{BREAKER_SCANLIST}adr = \"config+address\"\n")).unwrap();
    let old_arg = old_state.to_str().unwrap().to_string();
    let mut rig = PtyRig::breaker_with(
        "scanner-adr-pty",
        &["--period", "0.3"],
        Some(&description),
        &["--state", &old_arg],
    );
    let started = rig.slave.as_ref().unwrap().stderr.text();
    assert!(started.contains("dnet-soft-slave: MAC 5 "), "{started}");

    let bus = rig.master_bus_arg();
    let mut scanner = Proc::spawn(
        pty_rig::bin("dnet-master"),
        &["--bus", &bus, "--bitrate", "250k", "--json", "scanner", "--scanlist", list.to_str().unwrap()],
    );
    // In I/O, and its configuration stored (uploaded over the link), well within this.
    std::thread::sleep(Duration::from_secs(8));
    rig.stop_slave();
    let replaced_at = Instant::now();
    rig.start_slave_with(Some(&description), &["--state", new_state.to_str().unwrap()]);
    let fresh = rig.slave.as_ref().unwrap().stderr.text();
    assert!(fresh.contains("dnet-soft-slave: MAC 63 "), "out of the box at 63: {fresh}");
    // The move, the fresh device's duplicate MAC ID checks (2 s at 63, 2 s at 5) and the bring-up.
    while replaced_at.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(200));
        if std::fs::read_to_string(&new_state).is_ok_and(|s| s.contains("\"mac_id\": 5")) {
            std::thread::sleep(Duration::from_secs(5));
            break;
        }
    }
    let status = scanner.terminate();
    let out = scanner.stdout.text();
    let v: serde_json::Value = serde_json::from_str(out.trim())
        .unwrap_or_else(|e| panic!("{e}: {out}\n{}\n{}", scanner.dump(), rig.dump()));
    assert_eq!(status.and_then(|s| s.code()), Some(143), "{}", scanner.dump());
    let events = v["events"].as_array().unwrap();
    let kinds: Vec<&str> = events.iter().map(|e| e["kind"].as_str().unwrap()).collect();
    for want in ["config_stored", "node_lost", "appeared_at_63", "moved", "duplicate_check", "replaced"] {
        assert!(kinds.contains(&want), "{want} missing: {kinds:?}\n{}\n{}", scanner.dump(), rig.dump());
    }
    let time = |kind: &str| events.iter().find(|e| e["kind"] == kind).unwrap()["time_us"].as_u64().unwrap();
    let n5 = v["nodes"].as_array().unwrap().iter().find(|n| n["mac"] == 5).unwrap();
    assert_eq!(n5["status"], "ok", "{n5}");
    let kept = std::fs::read_to_string(&new_state).unwrap();
    assert!(kept.contains("\"mac_id\": 5"), "the fresh device stored its new MAC: {kept}");
    println!(
        "wall time from the replacement at 63 to I/O on the SLCAN pty path: {} ms",
        (time("replaced") - time("appeared_at_63")) / 1000
    );
}
