//! `scanner` on the simulated bus: 63 nodes in I/O, a node that disappears and returns, a node
//! with the wrong product code, one with the wrong size, one that is not there, two devices at one
//! MAC, and malformed scan lists (file, line, key; exit 2).

use can_io::bus::Bitrate;
use can_io::sim::fault::SharedDevice;
use can_io::sim::{PowerOn, SimBus, SimDevice};
use converter_sim::SoftSlave;
use devicenet::{CanFrame, Instant, MacId};
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use master_harness::monitor::InputLayout;
use master_harness::scanner::model::{NodeStatus, ScanEntry, ScanList};
use master_harness::scanner::{Scanner, ScannerOptions};
use slave_fw::converter::ConverterConfig;
use slave_fw::description::DeviceDescription;
use std::collections::HashMap;
use std::path::PathBuf;

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-scanner-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// `dnet-master ARGS` in-process: exit status, stdout, stderr.
fn dnet(args: &[&str]) -> (u8, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let mut all = vec!["dnet-master"];
    all.extend_from_slice(args);
    let code = master_harness::cli::run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

fn json(out: &str) -> serde_json::Value {
    serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"))
}

fn node(v: &serde_json::Value, mac: u64) -> &serde_json::Value {
    v["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["mac"] == mac)
        .unwrap_or_else(|| panic!("no MAC {mac}: {v}"))
}

fn breaker_entry(mac: u8) -> ScanEntry {
    ScanEntry {
        mac,
        connection: "poll".into(),
        ack_suppression: false,
        inhibit_ms: None,
        vendor_id: Some(0x1234),
        device_type: Some(0x000C),
        product_code: Some(1),
        major_revision: Some(1),
        input_size: 18,
        output_size: 8,
        name: None,
    }
}

#[test]
fn sixty_three_nodes_at_500k_every_one_ok() {
    let macs: Vec<String> = (1..=63).map(|m| m.to_string()).collect();
    let macs = macs.join(",");
    let (code, out, err) = dnet(&[
        "--bus",
        "sim",
        "--bitrate",
        "500k",
        "--slave-mac",
        &macs,
        "--json",
        "scanner",
        "--cycles",
        "20",
    ]);
    assert_eq!(code, 0, "{out}\n{err}");
    let v = json(&out);
    let nodes = v["nodes"].as_array().unwrap();
    assert_eq!(nodes.len(), 63);
    for n in nodes {
        assert_eq!(n["status"], "ok", "{n}");
        assert_eq!(n["code"], 0);
        assert_eq!(n["product_name"], "Serial-DeviceNet Bridge");
        assert_eq!(n["input_size"], 18);
        assert_eq!(n["output_size"], 8);
        assert!(n["exchanges"].as_u64().unwrap() >= 20, "{n}");
    }
    let cycle = v["cycle_ms"].as_f64().unwrap();
    // The frames alone take about 55 ms at 500 kbit/s; the goal is 70 ms.
    assert!(cycle > 40.0 && cycle <= 70.0, "median cycle {cycle} ms");
    let load = v["bus_load"].as_f64().unwrap();
    assert!(load > 0.7 && load <= 1.0, "bus load {load}");
}

#[test]
fn scan_list_built_written_and_read_back() {
    let path = temp("built.toml");
    let p = path.to_str().unwrap();
    let (code, out, err) = dnet(&["--slave-mac", "5,6", "scanner", "--cycles", "3", "--write-scanlist", p]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("Serial-DeviceNet Bridge"), "{out}");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.contains("mac = 6") && text.contains("input_size = 18"), "{text}");
    let (code, out, err) =
        dnet(&["--slave-mac", "5,6", "--json", "scanner", "--cycles", "3", "--scanlist", p]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert_eq!(json(&out)["nodes"].as_array().unwrap().len(), 2);
}

#[test]
fn wrong_product_code_wrong_size_and_absent_node() {
    let mut list = ScanList::default();
    let mut wrong_code = breaker_entry(5);
    wrong_code.product_code = Some(99);
    let mut wrong_size = breaker_entry(6);
    wrong_size.input_size = 10;
    list.nodes = vec![wrong_code, wrong_size, breaker_entry(7), breaker_entry(9)];
    let path = temp("faults.toml");
    std::fs::write(&path, master_harness::scanner::write_scan_list(&list)).unwrap();
    let (code, out, err) = dnet(&[
        "--slave-mac",
        "5,6,7",
        "--json",
        "scanner",
        "--cycles",
        "5",
        "--scanlist",
        path.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "not every node ok: {out}\n{err}");
    let v = json(&out);
    let n5 = node(&v, 5);
    assert_eq!((n5["status"].as_str(), n5["code"].as_u64()), (Some("keying_mismatch"), Some(73)), "{n5}");
    assert!(n5["detail"].as_str().unwrap().contains("expected product code 99, read 1"), "{n5}");
    let n6 = node(&v, 6);
    assert_eq!((n6["status"].as_str(), n6["code"].as_u64()), (Some("size_mismatch"), Some(77)), "{n6}");
    assert!(n6["detail"].as_str().unwrap().contains("input (produced) size 18 bytes, scan list 10"), "{n6}");
    let n7 = node(&v, 7);
    assert_eq!((n7["status"].as_str(), n7["code"].as_u64()), (Some("ok"), Some(0)), "{n7}");
    let n9 = node(&v, 9);
    assert_eq!((n9["status"].as_str(), n9["code"].as_u64()), (Some("not_present"), Some(78)), "{n9}");
    // Text: the table names each.
    let (code, out, _) =
        dnet(&["--slave-mac", "5,6,7", "scanner", "--cycles", "2", "--scanlist", path.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(out.contains("keying_mismatch") && out.contains("  73  "), "{out}");
}

#[test]
fn malformed_scan_lists_name_file_line_and_key() {
    for (name, text, want) in [
        ("range.toml", "[[node]]\nmac = 64\ninput_size = 1\noutput_size = 1\n", ":2:7: scan list (key `mac`): MAC 64"),
        (
            "twice.toml",
            "[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n\n[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n",
            ":7:7: scan list (key `mac`): MAC 5 is given twice",
        ),
        ("big.toml", "[[node]]\nmac = 5\ninput_size = 1\noutput_size = 500\n", ":4:15: scan list (key `output_size`)"),
        ("type.toml", "[[node]]\nmac = 5\ninput_size = \"18\"\noutput_size = 1\n", ":3:14: scan list (key `input_size`)"),
        ("unknown.toml", "[[node]]\nmac = 5\nsize = 3\ninput_size = 1\noutput_size = 1\n", "unknown field `size`"),
    ] {
        let path = temp(name);
        std::fs::write(&path, text).unwrap();
        let p = path.to_str().unwrap();
        let (code, out, err) = dnet(&["scanner", "--scanlist", p]);
        assert_eq!(code, 2, "{name}: {out}\n{err}");
        assert!(err.contains(&format!("{p}:")) && err.contains(want), "{name}: {err}");
        let (code, out, _) = dnet(&["--json", "scanner", "--scanlist", p]);
        assert_eq!(code, 2);
        assert!(json(&out)["error"].as_str().unwrap().contains(want), "{out}");
    }
    let (code, _, err) = dnet(&["scanner", "--scanlist", "/nonexistent/list.toml"]);
    assert_eq!(code, 2);
    assert!(err.contains("/nonexistent/list.toml: cannot read the scan list"), "{err}");
}

/// A soft slave that can be switched off (silent, deaf) and powered on again.
struct Removable {
    inner: SoftSlave,
    present: bool,
}

impl SimDevice for Removable {
    fn mac(&self) -> MacId {
        self.inner.mac()
    }
    fn power_on(&mut self, now: Instant) {
        SimDevice::power_on(&mut self.inner, now)
    }
    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        if self.present {
            SimDevice::handle_frame(&mut self.inner, frame, now)
        }
    }
    fn handle_timeout(&mut self, now: Instant) {
        SimDevice::handle_timeout(&mut self.inner, now)
    }
    fn poll_transmit(&mut self) -> Option<CanFrame> {
        let f = SimDevice::poll_transmit(&mut self.inner);
        if self.present {
            f
        } else {
            None
        }
    }
    fn poll_at(&self) -> Option<Instant> {
        SimDevice::poll_at(&self.inner)
    }
}

fn library_scanner(list: ScanList) -> Scanner {
    let layout = InputLayout::from_converter(&DeviceDescription::reference().converter);
    let layouts: HashMap<u8, InputLayout> = list.nodes.iter().map(|n| (n.mac, layout.clone())).collect();
    Scanner::new(list, 0, ScannerOptions { cycles: None, bitrate: Bitrate::K500, layouts })
}

fn status(s: &Scanner, mac: u8) -> NodeStatus {
    s.state().nodes.iter().find(|n| n.mac == mac).map(|n| n.status).unwrap()
}

#[test]
fn a_node_that_disappears_is_timed_out_then_not_present_and_reconnected_when_it_returns() {
    let mut bus = SimBus::new(Bitrate::K500);
    bus.attach(Box::new(SoftSlave::reference(MacId::new(5).unwrap())), PowerOn::WhenMasterOnline);
    let removable =
        SharedDevice::new(Removable { inner: SoftSlave::reference(MacId::new(6).unwrap()), present: true });
    let handle = removable.handle();
    bus.attach(Box::new(removable), PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let mut scanner =
        library_scanner(ScanList { nodes: vec![breaker_entry(5), breaker_entry(6)], ..ScanList::default() });
    scanner.start(&mut master).unwrap();
    for _ in 0..5 {
        scanner.cycle(&mut master).unwrap();
    }
    assert_eq!(status(&scanner, 6), NodeStatus::Ok);
    let samples = scanner.take_samples();
    assert!(
        samples.iter().any(|s| s.mac == 6 && s.values.iter().any(|(n, _)| n == "phase_a")),
        "{samples:?}"
    );
    let epr = u64::from(scanner.state().expected_packet_rate_ms);
    // Gone: timed out after 4 x EPR without a response, then not present at the next attempt.
    handle.borrow_mut().present = false;
    let mut seen = Vec::new();
    let give_up = master.session.now() + devicenet::Duration::from_secs(10);
    while master.session.now() < give_up {
        scanner.cycle(&mut master).unwrap();
        let s = status(&scanner, 6);
        if seen.last() != Some(&s) {
            seen.push(s);
        }
        if s == NodeStatus::NotPresent {
            break;
        }
    }
    assert_eq!(seen, vec![NodeStatus::Ok, NodeStatus::TimedOut, NodeStatus::NotPresent], "EPR {epr} ms");
    assert_eq!(status(&scanner, 5), NodeStatus::Ok, "the other node goes on");
    let exchanges_5 = scanner.state().nodes[0].exchanges;
    // Back (powered on again): reconnected, exchanging again.
    {
        let mut d = handle.borrow_mut();
        d.present = true;
        let now = master.session.now();
        SimDevice::power_on(&mut d.inner, now);
    }
    let give_up = master.session.now() + devicenet::Duration::from_secs(10);
    while master.session.now() < give_up {
        scanner.cycle(&mut master).unwrap();
        if status(&scanner, 6) == NodeStatus::Ok {
            break;
        }
    }
    assert_eq!(status(&scanner, 6), NodeStatus::Ok, "{:?}", scanner.state().nodes[1]);
    assert!(scanner.state().nodes[0].exchanges > exchanges_5);
    // Outputs go to an ok node, and are refused for a node that is not.
    let (tx, rx) = std::sync::mpsc::channel();
    scanner.command(
        &mut master,
        master_harness::scanner::model::ConsoleCommand::SetOutput {
            mac: 6,
            data: vec![2, 1, 0, 0, 0, 0, 0, 0],
            reply: tx,
        },
    );
    assert_eq!(rx.recv().unwrap(), Ok(vec![]));
    let (tx, rx) = std::sync::mpsc::channel();
    scanner.command(
        &mut master,
        master_harness::scanner::model::ConsoleCommand::SetOutput { mac: 6, data: vec![1], reply: tx },
    );
    assert!(rx.recv().unwrap().unwrap_err().contains("consumes 8 bytes"));
    let (tx, rx) = std::sync::mpsc::channel();
    scanner.command(
        &mut master,
        master_harness::scanner::model::ConsoleCommand::Get {
            mac: 6,
            class: 1,
            instance: 1,
            attribute: 7,
            reply: tx,
        },
    );
    assert!(String::from_utf8_lossy(&rx.recv().unwrap().unwrap()).contains("Serial-DeviceNet Bridge"));
    // Frames drain, and the session's records stay bounded.
    let frames = scanner.take_frames(&mut master);
    assert!(frames.iter().any(|f| f.kind == "io" && f.mac == Some(6)));
    assert!(scanner.take_frames(&mut master).len() < frames.len());
    assert!(master.session.records().len() <= master_harness::scanner::RECORDS_KEPT);
    scanner.stop(&mut master).unwrap();
    assert!(master.held(MacId::new(6).unwrap()).is_empty());
}

#[test]
fn two_devices_at_one_mac_are_communication_faulted() {
    let mut bus = SimBus::new(Bitrate::K500);
    for serial in [0x1111_1111, 0x2222_2222] {
        let mut config = ConverterConfig::breaker_reference();
        config.device.identity.serial_number = serial;
        bus.attach(Box::new(SoftSlave::new(config).unwrap()), PowerOn::WhenMasterOnline);
    }
    bus.attach(Box::new(SoftSlave::reference(MacId::new(6).unwrap())), PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let mut scanner =
        library_scanner(ScanList { nodes: vec![breaker_entry(5), breaker_entry(6)], ..ScanList::default() });
    scanner.start(&mut master).unwrap();
    for _ in 0..5 {
        scanner.cycle(&mut master).unwrap();
    }
    let n5 = scanner.state().nodes[0].clone();
    assert_eq!((n5.status, n5.code), (NodeStatus::CommunicationFaulted, 78), "{n5:?}");
    assert!(n5.detail.as_deref().unwrap_or("").contains("two devices"), "{n5:?}");
    assert_eq!(status(&scanner, 6), NodeStatus::Ok);
}
