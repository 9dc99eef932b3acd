//! Several instances into one broker (issue 29 item 5, beyond one machine): two `dnet-master ui`
//! processes, each with its own network, publish into one mosquitto as Sparkplug B edge nodes of
//! one group under their own edge-node IDs (`plant1/line-a`, `plant1/line-b`). The independent
//! host (pysparkplug, `tests/python/sparkplug_host.py`) sees each edge node's NBIRTH and its node's
//! DBIRTH under its own ID; stopping one leaves the other's data flowing.
//!
//! Needs mosquitto, pysparkplug and the built dnet-master: ignored in the plain host-test run, run
//! by scripts/check's plant-networks stage.

use pty_rig::console::console_addr;
use pty_rig::sparkplug::broker_and_host;
use pty_rig::{bin, scratch, Proc};
use serde_json::Value;
use std::time::Duration;

/// `dnet-master --bus sim --slave-mac MAC ui ... --sparkplug plant1/EDGE`.
fn instance(dir: &std::path::Path, url: &str, edge: &str, mac: &str) -> Proc {
    let store = dir.join(format!("spb-{edge}.sqlite"));
    let history = dir.join(format!("history-{edge}.sqlite"));
    let id = format!("plant1/{edge}");
    let p = Proc::spawn(
        bin("dnet-master"),
        &[
            "--bus",
            "sim",
            "--slave-mac",
            mac,
            "ui",
            "--listen",
            "127.0.0.1:0",
            "--history",
            history.to_str().unwrap(),
            "--mqtt",
            url,
            "--sparkplug",
            &id,
            "--sparkplug-store",
            store.to_str().unwrap(),
        ],
    );
    console_addr(&p, Duration::from_secs(30));
    p
}

/// A message of `kind` from edge node `edge` (its topic `spBv1.0/plant1/KIND/EDGE[/DEVICE]`).
fn from<'a>(kind: &'a str, edge: &'a str, device: Option<&'a str>) -> impl Fn(&Value) -> bool + 'a {
    move |v| {
        let topic = v["topic"].as_str().unwrap_or("");
        let parts: Vec<&str> = topic.split('/').collect();
        v["type"] == kind && parts.get(3) == Some(&edge) && device.is_none_or(|d| v["device"] == d)
    }
}

#[test]
#[ignore = "needs mosquitto and pysparkplug: run by scripts/check's plant-networks stage"]
fn two_instances_publish_under_their_own_edge_node_ids() {
    let dir = scratch("plant-sparkplug");
    let (_broker, mut host, url) = broker_and_host(&dir, "plant1");
    let mut a = instance(&dir, &url, "line-a", "5");
    let mut b = instance(&dir, &url, "line-b", "6");
    for (edge, device) in [("line-a", "mac05"), ("line-b", "mac06")] {
        host.seen_or_next(Duration::from_secs(30), &format!("{edge}'s NBIRTH"), from("NBIRTH", edge, None));
        let birth = host.seen_or_next(
            Duration::from_secs(30),
            &format!("{edge}'s DBIRTH of {device}"),
            from("DBIRTH", edge, Some(device)),
        );
        assert!(birth["metrics"].as_array().is_some_and(|m| !m.is_empty()), "{birth}");
    }
    // Each edge node births its own network's node only.
    assert!(!host.seen.iter().any(|v| from("DBIRTH", "line-a", Some("mac06"))(v)), "{}", host.dump());
    assert!(!host.seen.iter().any(|v| from("DBIRTH", "line-b", Some("mac05"))(v)), "{}", host.dump());
    // line-a stops: its NDEATH; line-b goes on.
    a.signal("INT");
    assert_eq!(a.wait(Duration::from_secs(20)).and_then(|s| s.code()), Some(130), "{}", a.dump());
    host.next(Duration::from_secs(30), "line-a's NDEATH", from("NDEATH", "line-a", None));
    assert!(b.running(), "line-b stopped with line-a: {}", b.dump());
    b.signal("INT");
    assert_eq!(b.wait(Duration::from_secs(20)).and_then(|s| s.code()), Some(130), "{}", b.dump());
}
