//! Scan-list changes and the event log through the web console's API (issue 28 item 5), over
//! HTTP against `dnet-master ui` on the simulated bus: a node disabled and enabled again, an
//! entry with compatible keying added, a bad entry refused naming its key, the events listed.
//!
//! Needs the dnet-master program: ignored in the plain host-test run, run by scripts/check's
//! scanner-adr stage.

use pty_rig::console::{csrf_token, http, spawn_ui};
use std::time::{Duration, Instant};

fn node_status(addr: &str, mac: u64) -> Option<String> {
    let (status, body) = http(addr, "GET", "/api/state", None, "");
    if status != 200 {
        return None;
    }
    let v: serde_json::Value = serde_json::from_str(&body).ok()?;
    let n = v["nodes"].as_array()?.iter().find(|n| n["mac"] == mac)?.clone();
    n["status"].as_str().map(str::to_string)
}

fn wait_status(addr: &str, mac: u64, want: &str, ui: &pty_rig::Proc) {
    let end = Instant::now() + Duration::from_secs(30);
    while node_status(addr, mac).as_deref() != Some(want) {
        assert!(Instant::now() < end, "MAC {mac} never {want}: {:?}\n{}", node_status(addr, mac), ui.dump());
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// Disables MAC 5 through the console (`POST /api/scanlist/enable` with the page's token), waits
/// until the console shows it `disabled`, enables it again and waits until it is `ok`.
fn disable_and_enable_mac_5(addr: &str, token: &str, ui: &pty_rig::Proc) {
    for (enabled, status) in [(false, "disabled"), (true, "ok")] {
        let body = format!(r#"{{"mac": 5, "enabled": {enabled}}}"#);
        let (code, answer) = http(addr, "POST", "/api/scanlist/enable", Some(token), &body);
        assert_eq!(code, 200, "{answer}");
        wait_status(addr, 5, status, ui);
    }
}

#[test]
#[ignore = "needs dnet-master built: run by scripts/check's scanner-adr stage"]
fn the_console_edits_the_scan_list_and_lists_the_events() {
    let dir = pty_rig::scratch("scanner-adr-console");
    let list = dir.join("list.toml");
    // MAC 7 is on the bus but not in the list: added through the API.
    std::fs::write(
        &list,
        "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n\n[[node]]\nmac = 6\ninput_size = 18\noutput_size = 8\n",
    )
    .unwrap();
    let (mut ui, addr) = spawn_ui(
        &["--bus", "sim", "--slave-mac", "5,6,7"],
        &["--no-history", "--scanlist", list.to_str().unwrap()],
        Duration::from_secs(30),
        String::new,
    );
    wait_status(&addr, 5, "ok", &ui);
    let token = csrf_token(&addr);
    let post = |path: &str, body: &str| http(&addr, "POST", path, Some(&*token), body);

    assert_eq!(http(&addr, "GET", "/api/scanlist/enable", None, "").0, 405);
    disable_and_enable_mac_5(&addr, &token, &ui);

    let (status, body) = post(
        "/api/scanlist/add",
        r#"{"mac": 7, "input_size": 18, "output_size": 8, "keying": "compatible", "major_revision": 1}"#,
    );
    assert_eq!(status, 200, "{body}");
    wait_status(&addr, 7, "ok", &ui);
    let (status, body) = post("/api/scanlist/add", r#"{"mac": 9, "input_size": 500, "output_size": 8}"#);
    assert_eq!(status, 400, "{body}");
    assert!(body.contains("input_size") && body.contains("448"), "{body}");
    let (status, body) = post("/api/scanlist/remove", r#"{"mac": 7}"#);
    assert_eq!(status, 200, "{body}");

    let (status, body) = http(&addr, "GET", "/api/events", None, "");
    assert_eq!(status, 200, "{body}");
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    let events = v["events"].as_array().unwrap();
    let details: Vec<&str> = events.iter().map(|e| e["detail"].as_str().unwrap()).collect();
    assert_eq!(
        details,
        ["MAC 5 disabled (maintenance)", "MAC 5 enabled", "MAC 7 added (poll connection)", "MAC 7 removed"],
        "{body}"
    );
    assert!(events.iter().all(|e| e["kind"] == "list_changed"), "{body}");
    let last = events[1]["seq"].as_u64().unwrap();
    let (_, body) = http(&addr, "GET", &format!("/api/events?since={last}"), None, "");
    let after: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(after["events"].as_array().unwrap().len(), 2, "{body}");
    ui.terminate();
}

/// The same edits on the real SLCAN path: `dnet-master ui` over an SLCAN pty against
/// `dnet-soft-slave` with `dnet-sim-breaker` (pty-rig): the node disabled (released, status
/// `disabled`), enabled (back in I/O), removed, added again.
#[test]
#[ignore = "needs dnet-master, dnet-soft-slave and socat: run by scripts/check's scanner-adr stage"]
fn the_console_edits_the_scan_list_over_slcan() {
    if !pty_rig::require_socat() {
        return;
    }
    let rig = pty_rig::PtyRig::breaker("scanner-edit-slcan", &[], None);
    let bus = rig.master_bus_arg();
    let dir = pty_rig::scratch("scanner-edit-slcan-list");
    let list = dir.join("list.toml");
    std::fs::write(&list, "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n").unwrap();
    let (mut ui, addr) = spawn_ui(
        &["--bus", &bus, "--bitrate", "500k"],
        &["--no-history", "--scanlist", list.to_str().unwrap()],
        Duration::from_secs(30),
        || rig.dump(),
    );
    wait_status(&addr, 5, "ok", &ui);
    let token = csrf_token(&addr);
    let post = |path: &str, body: &str| http(&addr, "POST", path, Some(&*token), body);

    disable_and_enable_mac_5(&addr, &token, &ui);
    let (status, body) = post("/api/scanlist/remove", r#"{"mac": 5}"#);
    assert_eq!(status, 200, "{body}");
    let end = Instant::now() + Duration::from_secs(30);
    while node_status(&addr, 5).is_some() {
        assert!(Instant::now() < end, "MAC 5 still listed after remove\n{}", ui.dump());
        std::thread::sleep(Duration::from_millis(200));
    }
    let (status, body) = post("/api/scanlist/add", r#"{"mac": 5, "input_size": 18, "output_size": 8}"#);
    assert_eq!(status, 200, "{body}");
    wait_status(&addr, 5, "ok", &ui);
    let (_, body) = http(&addr, "GET", "/api/events", None, "");
    for want in ["MAC 5 disabled (maintenance)", "MAC 5 enabled", "MAC 5 removed", "MAC 5 added"] {
        assert!(body.contains(want), "no event {want:?}: {body}");
    }
    ui.terminate();
}
