//! Several networks in one process (issue 29 item 5): `dnet-master ui --plant FILE.toml`.
//!
//! On the real SLCAN path: two benches on socat ptys (`dnet-sim-breaker` + `dnet-soft-slave`
//! each, both at MAC 5), one `ui --plant` process scanning both; the console's API shows both
//! networks in I/O, a Close sent to network `b`'s node reaches `b`'s breaker only, and the audit
//! log names the network. On the simulated bus: two networks run `--cycles` and both tables are
//! printed; a plant that cannot start (a bad scan list, a bus that cannot be opened, `--bus` or
//! `--scanlist` with `--plant`) is exit 2 naming what, before any bus is touched.
//!
//! Needs socat and the built programs: ignored in the plain host-test run, run by scripts/check's
//! plant-networks stage.

use pty_rig::console::{csrf_token, get, http, spawn_ui, stop_ui};
use pty_rig::plant::{plant_file, two_breaker_benches, BREAKER_SCANLIST};
use pty_rig::{bin, scratch};
use serde_json::Value;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

fn json(text: &str) -> Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("{e}: {text}"))
}

/// Node 5's status in each network of `GET /api/state`'s `networks`, by name.
fn statuses(state: &Value) -> Vec<(String, String)> {
    state["networks"]
        .as_array()
        .map(|ns| {
            ns.iter()
                .map(|n| {
                    let node = n["nodes"].as_array().and_then(|v| v.iter().find(|x| x["mac"] == 5));
                    (
                        n["name"].as_str().unwrap_or("?").to_string(),
                        node.and_then(|x| x["status"].as_str()).unwrap_or("none").to_string(),
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check's plant-networks stage"]
fn two_slcan_networks_in_one_console() {
    if !pty_rig::require_socat() {
        return;
    }
    let (a, b) = two_breaker_benches("plant-slcan");
    let dir = scratch("plant-slcan");
    let file = plant_file(&dir, &[("a", &a.master_bus_arg()), ("b", &b.master_bus_arg())]);
    let history = dir.join("history.sqlite");
    let dump = || format!("--- network a:\n{}\n--- network b:\n{}", a.dump(), b.dump());
    let (mut ui, addr) = spawn_ui(
        &["--bitrate", "250k"],
        &["--plant", file.to_str().unwrap(), "--history", history.to_str().unwrap()],
        Duration::from_secs(20),
        dump,
    );
    // Both networks in I/O, seen through one console.
    let end = Instant::now() + Duration::from_secs(60);
    let mut state = Value::Null;
    while Instant::now() < end {
        state = json(&get(&addr, "/api/state").1);
        if statuses(&state) == [("a".into(), "ok".into()), ("b".into(), "ok".into())] {
            break;
        }
        std::thread::sleep(Duration::from_millis(300));
    }
    assert_eq!(
        statuses(&state),
        [("a".to_string(), "ok".to_string()), ("b".to_string(), "ok".to_string())],
        "{state}\n{}\n{}",
        ui.dump(),
        dump()
    );
    assert_eq!(state["networks"][1]["bus"], b.master_bus_arg(), "{state}");
    let (status, net_b) = get(&addr, "/api/net/b/state");
    assert_eq!(status, 200, "{net_b}");
    let net_b = json(&net_b);
    assert_eq!(net_b["nodes"][0]["status"], "ok", "{net_b}");
    assert!(net_b.get("networks").is_none(), "a network's own state holds no networks: {net_b}");
    let (status, list) = get(&addr, "/api/networks");
    assert_eq!((status, json(&list)["networks"].as_array().map(Vec::len)), (200, Some(2)), "{list}");
    let (status, missing) = get(&addr, "/api/net/c/state");
    assert!(status == 404 && missing.contains("a, b"), "{status} {missing}");

    // A Close to network b's node: b's breaker receives it, a's does not.
    let token = csrf_token(&addr);
    let (status, body) = http(&addr, "POST", "/api/net/b/node/5/breaker/close", Some(&token), "{}");
    assert_eq!(status, 200, "{body}\n{}", ui.dump());
    assert!(
        b.wait_breaker_log("command close", Duration::from_secs(15)),
        "network b's breaker:\n{}",
        b.breaker_log()
    );
    assert!(!a.breaker_log().contains("command"), "network a's breaker got a command:\n{}", a.breaker_log());
    // The node's detail through b's own API, and the audit log names the network.
    let (status, node) = get(&addr, "/api/net/b/node/5");
    assert_eq!(status, 200, "{node}");
    let (_, audit) = get(&addr, "/api/audit");
    let audit = json(&audit);
    let entry = &audit["entries"][0];
    assert_eq!((entry["mac"].as_u64(), entry["result"].as_str()), (Some(5), Some("ok")), "{audit}");
    assert!(entry["what"].as_str().is_some_and(|w| w.starts_with("net b: breaker close")), "{audit}");

    stop_ui(&mut ui, Duration::from_secs(20), &dump());
    let out = ui.stdout.text();
    assert!(out.contains("network a:") && out.contains("network b:"), "{out}");
    // Each network's samples in its own history file.
    for name in ["a", "b"] {
        let h = dir.join(format!("history-{name}.sqlite"));
        assert!(h.metadata().is_ok_and(|m| m.len() > 0), "{} missing", h.display());
    }
}

fn dnet(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(bin("dnet-master")).args(args).output().expect("dnet-master runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
#[ignore = "needs the built dnet-master: run by scripts/check's plant-networks stage"]
fn two_simulated_networks_run_their_cycles() {
    let dir = scratch("plant-sim");
    let file = plant_file(&dir, &[("line-a", "sim"), ("line-b", "sim")]);
    let (code, out, err) = dnet(&[
        "--slave-mac",
        "5",
        "ui",
        "--plant",
        file.to_str().unwrap(),
        "--listen",
        "127.0.0.1:0",
        "--no-history",
        "--cycles",
        "20",
    ]);
    assert_eq!(code, 0, "{out}\n{err}");
    for name in ["line-a", "line-b"] {
        let table =
            out.split(&format!("network {name}:\n")).nth(1).unwrap_or_else(|| panic!("{name}: {out}"));
        let row = table.lines().find(|l| l.trim_start().starts_with("5 ")).unwrap_or("");
        assert!(row.contains(" ok "), "{name}'s node 5: {out}");
    }
}

#[test]
#[ignore = "needs the built dnet-master: run by scripts/check's plant-networks stage"]
fn a_plant_that_cannot_start_is_refused_before_any_bus() {
    let dir = scratch("plant-refused");
    let run = |file: &Path, extra: &[&str]| {
        let f = file.to_str().unwrap();
        let args: Vec<&str> =
            [extra, &["ui", "--plant", f, "--listen", "127.0.0.1:0", "--no-history", "--cycles", "1"]]
                .concat();
        dnet(&args)
    };
    // A scan list refused: the network and the scan list's file and line named.
    let file = plant_file(&dir, &[("good", "sim"), ("bad", "sim")]);
    std::fs::write(dir.join("bad.toml"), "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\nspeed = 1\n")
        .unwrap();
    let (code, out, err) = run(&file, &[]);
    assert_eq!(code, 2, "{out}\n{err}");
    assert!(err.contains("network bad: ") && err.contains("bad.toml:5"), "{err}");
    assert!(!out.contains("console at"), "nothing started: {out}");
    // A bus that cannot be opened: named with its network; the other network never scanned.
    let file = plant_file(&dir, &[("good", "sim"), ("gone", "slcan:/nonexistent/tty")]);
    let (code, out, err) = run(&file, &["--slave-mac", "5"]);
    assert_eq!(code, 2, "{out}\n{err}");
    assert!(err.contains("network gone: "), "{err}");
    assert!(!out.contains("network good:"), "the good network did not scan: {out}");
    // The plant file's own errors: file, line and key.
    std::fs::write(
        dir.join("plant.toml"),
        "[[network]]\nname = \"a\"\nbus = \"sim\"\nscanlist = \"good.toml\"\nspeed = 1\n",
    )
    .unwrap();
    let (code, _, err) = run(&dir.join("plant.toml"), &[]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("plant.toml:5:1 plant file (key `speed`)"), "{err}");
    // --bus and --scanlist belong to one network.
    let (code, _, err) = run(&file, &["--bus", "slcan:/dev/null"]);
    assert!(code == 2 && err.contains("not --bus"), "{code} {err}");
    let (code, _, err) = dnet(&["ui", "--plant", "p.toml", "--scanlist", "s.toml"]);
    assert!(code == 2 && err.contains("cannot be used with"), "{code} {err}");
}

#[test]
#[ignore = "needs mosquitto and the built dnet-master: run by scripts/check's plant-networks stage"]
fn each_network_publishes_under_its_name() {
    let dir = scratch("plant-mqtt");
    let port = pty_rig::console::free_port();
    let _broker = pty_rig::mqtt::Mosquitto::start(&dir, port, None);
    // Network a scans MAC 5, network b MAC 6 (both simulated buses hold both).
    let file = plant_file(&dir, &[("a", "sim"), ("b", "sim")]);
    std::fs::write(dir.join("b.toml"), BREAKER_SCANLIST.replace("mac = 5", "mac = 6")).unwrap();
    let sub = Command::new("mosquitto_sub")
        .args(["-h", "127.0.0.1", "-p", &port.to_string(), "-t", "plant/#", "-v", "-W", "20", "-C", "60"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run mosquitto_sub ({e}): apt-get install -y mosquitto-clients"));
    std::thread::sleep(Duration::from_millis(500));
    let url = format!("mqtt://127.0.0.1:{port}/plant");
    let (mut ui, _addr) = spawn_ui(
        &["--slave-mac", "5,6"],
        &["--plant", file.to_str().unwrap(), "--no-history", "--mqtt", &url],
        Duration::from_secs(20),
        String::new,
    );
    let out = sub.wait_with_output().unwrap();
    stop_ui(&mut ui, Duration::from_secs(20), "");
    let text = String::from_utf8_lossy(&out.stdout);
    let topics: std::collections::BTreeSet<&str> = text.lines().filter_map(|l| l.split(' ').next()).collect();
    for want in ["plant/a/node/5/status", "plant/b/node/6/status", "plant/a/scanner", "plant/b/scanner"] {
        assert!(topics.contains(want), "{want} missing: {topics:?}\n{}", ui.dump());
    }
    assert!(
        !topics.iter().any(|t| t.starts_with("plant/node")
            || *t == "plant/a/node/6/status"
            || *t == "plant/b/node/5/status"),
        "a node under another network or no network: {topics:?}"
    );
    let ok = |topic: &str| text.lines().any(|l| l.starts_with(&format!("{topic} ")) && l.contains("\"ok\""));
    assert!(ok("plant/a/node/5/status") && ok("plant/b/node/6/status"), "{text}");
}
