//! The scanner's ADR events on MQTT, read by an independent client (`mosquitto_sub`) from a
//! mosquitto broker of the test's own: a replacement on the simulated bus (`--sim-replace`'s
//! device at 63) gives `moved` and `replaced` on `devicenet/events`, not retained.
//!
//! Needs Debian's mosquitto and mosquitto-clients: ignored in the plain host-test run, run by
//! scripts/check's scanner-adr stage (it fails, not skips, when they are missing).

use can_io::bus::{Bitrate, BusSpec};
use converter_sim::{open_bus, SimSetup};
use devicenet::{Instant, MacId};
use dnet_scanner::model::AdrMode;
use dnet_scanner::mqtt::Publisher;
use dnet_scanner::{build_scan_list, Scanner, ScannerOptions};
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use pty_rig::console::free_port;
use pty_rig::mqtt::Mosquitto;
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
#[ignore = "needs mosquitto: run by scripts/check's scanner-adr stage"]
fn adr_events_reach_an_mqtt_subscriber() {
    let port = free_port();
    let _broker = Mosquitto::start(&pty_rig::scratch("scanner-adr-mqtt"), port, None);
    let sub = Command::new("mosquitto_sub")
        .args(["-h", "127.0.0.1", "-p", &port.to_string(), "-t", "devicenet/events", "-v"])
        .args(["-W", "60", "-F", "%r %t %p"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot run mosquitto_sub ({e}): apt-get install -y mosquitto-clients"));
    let publisher = Publisher::start(&format!("mqtt://127.0.0.1:{port}"), "dnet-scanner-adr-test").unwrap();
    let end = std::time::Instant::now() + Duration::from_secs(10);
    while !publisher.is_connected() {
        assert!(std::time::Instant::now() < end, "not connected: {}", publisher.status());
        std::thread::sleep(Duration::from_millis(50));
    }
    // The subscriber is in place before the first event.
    std::thread::sleep(Duration::from_millis(500));

    let mut setup = SimSetup::reference();
    setup.macs = vec![MacId::new(5).unwrap(), MacId::new(6).unwrap()];
    setup.replace = vec![(MacId::new(5).unwrap(), Instant::from_millis(10_000))];
    let mut bus = open_bus(&BusSpec::Sim, Bitrate::K250, &setup).unwrap();
    let mut session = Session::new(bus.as_mut());
    let mut master = Master::new(&mut session, MasterConfig::default());
    let mut list = build_scan_list(&mut master, 0, 63).unwrap();
    for n in &mut list.nodes {
        n.adr = AdrMode::ConfigAddress;
    }
    let mut scanner = Scanner::new(list, 0, ScannerOptions::default());
    scanner.start(&mut master).unwrap();
    let mut seen = 0;
    while master.session.now() < Instant::from_secs(18) {
        scanner.cycle(&mut master).unwrap();
        let events = scanner.events().since(seen);
        seen = events.last().map_or(seen, |e| e.seq);
        publisher.publish_events(&events);
    }
    scanner.stop(&mut master).unwrap();
    let published = scanner.events().all();
    assert!(published.len() >= 6, "{published:#?}");
    // Everything queued has gone out once the publisher is dropped (it disconnects after).
    drop(publisher);
    std::thread::sleep(Duration::from_millis(500));
    let mut sub = sub;
    let _ = sub.kill();
    let out = sub.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let kinds: Vec<String> = text
        .lines()
        .map(|line| {
            let mut parts = line.splitn(3, ' ');
            assert_eq!(parts.next(), Some("0"), "not retained: {line}");
            assert_eq!(parts.next(), Some("devicenet/events"), "{line}");
            let v: serde_json::Value = serde_json::from_str(parts.next().unwrap()).unwrap();
            v["kind"].as_str().unwrap().to_string()
        })
        .collect();
    let want: Vec<String> = published.iter().map(|e| e.kind.name().to_string()).collect();
    assert_eq!(kinds, want, "every event, in order");
    assert!(kinds.iter().any(|k| k == "moved") && kinds.iter().any(|k| k == "replaced"), "{kinds:?}");
}
