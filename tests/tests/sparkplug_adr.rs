//! The scanner's events (automatic device replacement) on Sparkplug B, read by an independent host
//! application: `tests/python/sparkplug_host.py` on PyPI's pysparkplug, against Debian's
//! mosquitto. `dnet-master --bus sim --slave-mac 5,6 --sim-replace 5@10000 --realtime ui --adr
//! --mqtt URL --sparkplug plant/line1`: MAC 5 is replaced by a factory-fresh device at MAC 63 at
//! 10 s; each step reaches the host as an NDATA with the node-level metric `ADR/Last Event`
//! (String, the event as JSON, with its own timestamp), declared in NBIRTH; a Rebirth after the
//! replacement carries the newest event. On the real SLCAN path (the soft slave on socat ptys), a
//! scan-list change made in the console reaches the host the same way.
//!
//! Needs mosquitto, socat and the venv's pysparkplug (`DNET_PYTHON`, else `.venv/bin/python`): ignored in
//! the plain run; it fails, not skips, when a tool is missing.

use pty_rig::console::{csrf_token, http, spawn_ui};
use pty_rig::sparkplug::broker_and_host;
use pty_rig::{bin, scratch, Proc};
use serde_json::{json, Value};
use std::time::Duration;

const LAST_EVENT: &str = "ADR/Last Event";

fn of_type(kind: &'static str) -> impl Fn(&Value) -> bool {
    move |v| v["type"] == kind
}

fn last_event(message: &Value) -> Option<&Value> {
    message["metrics"].as_array()?.iter().find(|m| m["name"] == LAST_EVENT)
}

/// The event an `ADR/Last Event` metric carries (its value is JSON text).
fn event_of(metric: &Value) -> Value {
    let text = metric["value"].as_str().unwrap_or_else(|| panic!("not a string: {metric}"));
    serde_json::from_str(text).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
}

#[test]
#[ignore = "needs mosquitto and pysparkplug: run by scripts/check"]
fn adr_steps_reach_a_sparkplug_host_as_node_data() {
    let dir = scratch("spb-adr");
    let (_broker, mut host, url) = broker_and_host(&dir, "plant");
    let store = dir.join("sparkplug.sqlite");
    let p = Proc::spawn(
        bin("dnet-master"),
        &[
            "--bus",
            "sim",
            "--slave-mac",
            "5,6",
            "--sim-replace",
            "5@10000",
            "--realtime",
            "ui",
            "--no-history",
            "--listen",
            "127.0.0.1:0",
            "--adr",
            "--mqtt",
            &url,
            "--sparkplug",
            "plant/line1",
            "--sparkplug-store",
            store.to_str().unwrap(),
        ],
    );

    // Declared in NBIRTH, a String (null until the first event).
    let nbirth = host.next(Duration::from_secs(30), "NBIRTH", of_type("NBIRTH"));
    let declared = last_event(&nbirth).unwrap_or_else(|| panic!("NBIRTH without {LAST_EVENT}: {nbirth}"));
    assert_eq!(declared["datatype"], "STRING", "{declared}");

    // Each step an NDATA, in order, ending with the replacement in I/O at MAC 5.
    let mut kinds: Vec<String> = Vec::new();
    let mut seqs: Vec<u64> = Vec::new();
    let mut last_seq: Option<u64> = None;
    while kinds.last().is_none_or(|k| k != "replaced") {
        let ndata = host.next(Duration::from_secs(40), "NDATA with the replacement", of_type("NDATA"));
        assert_eq!(ndata["topic"], "spBv1.0/plant/NDATA/line1");
        let m = last_event(&ndata).unwrap_or_else(|| panic!("NDATA without {LAST_EVENT}: {ndata}"));
        assert_eq!((m["datatype"].as_str(), m["null"].as_bool()), (Some("STRING"), Some(false)), "{m}");
        let now_ms = u64::try_from(std::time::SystemTime::UNIX_EPOCH.elapsed().unwrap().as_millis()).unwrap();
        let stamp = m["timestamp"].as_u64().unwrap_or_else(|| panic!("no timestamp: {m}"));
        assert!(stamp <= now_ms && now_ms - stamp < 60_000, "timestamp {stamp}, now {now_ms}");
        let e = event_of(m);
        let seq = e["seq"].as_u64().unwrap_or_else(|| panic!("{e}"));
        assert!(last_seq.is_none_or(|l| seq == l + 1), "event {seq} after {last_seq:?}: none lost");
        last_seq = Some(seq);
        seqs.push(seq);
        kinds.push(e["kind"].as_str().unwrap_or_default().to_string());
        if e["kind"] == "replaced" {
            assert_eq!(e["mac"], 5, "{e}");
        }
    }
    println!("events as NDATA (seq {seqs:?}): {kinds:?}");
    for step in ["node_lost", "appeared_at_63", "moved", "replaced"] {
        assert!(kinds.iter().any(|k| k == step), "no {step}: {kinds:?}\n{}", host.dump());
    }

    // A Rebirth now carries the newest event in NBIRTH, with its own time.
    host.send(&json!({"rebirth": "line1"}));
    let again = host.next(Duration::from_secs(20), "NBIRTH after the Rebirth", of_type("NBIRTH"));
    let m = last_event(&again).unwrap_or_else(|| panic!("{again}"));
    let newest = event_of(m);
    assert!(newest["seq"].as_u64() >= seqs.last().copied(), "{newest} older than {seqs:?}");

    // NDATA counts in the edge node's seq like DBIRTH and DDATA: one more than the message before.
    let mut last: Option<u64> = None;
    let mut ndata_checked = 0;
    for v in host.seen.iter().filter(|v| v["type"].is_string()) {
        let Some(seq) = v["seq"].as_u64() else { continue };
        match v["type"].as_str() {
            Some("NBIRTH") => last = Some(seq),
            Some(kind @ ("DBIRTH" | "DDATA" | "NDATA")) => {
                let before = last.unwrap_or_else(|| panic!("{v} before any NBIRTH"));
                assert_eq!(seq, (before + 1) % 256, "seq after {before}: {v}");
                ndata_checked += usize::from(kind == "NDATA");
                last = Some(seq);
            }
            _ => {}
        }
    }
    assert!(ndata_checked >= 4, "{ndata_checked} NDATA seq checked");
    drop(p);
}

/// On the real SLCAN path (`dnet-soft-slave` with the simulated breaker on socat pty pairs): a
/// scan-list change made in the console (MAC 5 disabled, enabled) reaches the host as NDATA.
#[test]
#[ignore = "needs socat, mosquitto and pysparkplug: run by scripts/check"]
fn scan_list_changes_over_slcan_reach_a_sparkplug_host() {
    assert!(pty_rig::require_socat(), "socat is missing: apt-get install socat");
    let rig = pty_rig::PtyRig::breaker("spb-adr-slcan", &[], None);
    let bus = rig.master_bus_arg();
    let dir = scratch("spb-adr-slcan");
    let (_broker, mut host, url) = broker_and_host(&dir, "plant");
    let store = dir.join("sparkplug.sqlite");
    let (p, addr) = spawn_ui(
        &["--bus", &bus, "--bitrate", "500k"],
        &[
            "--no-history",
            "--mqtt",
            &url,
            "--sparkplug",
            "plant/line1",
            "--sparkplug-store",
            store.to_str().unwrap(),
        ],
        Duration::from_secs(30),
        || rig.dump(),
    );
    host.next(Duration::from_secs(30), "NBIRTH", of_type("NBIRTH"));
    host.next(Duration::from_secs(30), "DBIRTH mac05", |v| v["type"] == "DBIRTH" && v["device"] == "mac05");
    for (body, want) in [
        (r#"{"mac": 5, "enabled": false}"#, "MAC 5 disabled (maintenance)"),
        (r#"{"mac": 5, "enabled": true}"#, "MAC 5 enabled"),
    ] {
        let (status, answer) = http(&addr, "POST", "/api/scanlist/enable", Some(&csrf_token(&addr)), body);
        assert_eq!(status, 200, "{answer}\n{}\n{}", p.dump(), rig.dump());
        let ndata = host.next(Duration::from_secs(20), want, of_type("NDATA"));
        let e = event_of(last_event(&ndata).unwrap_or_else(|| panic!("{ndata}")));
        assert_eq!(
            (e["kind"].as_str(), e["mac"].as_u64(), e["detail"].as_str()),
            (Some("list_changed"), Some(5), Some(want))
        );
    }
    drop(p);
}
