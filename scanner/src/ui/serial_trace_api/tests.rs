//! The Serial line API over HTTP against a scanner loop stand-in that answers each request the
//! way the converter does: class 0x68 by the analyzer object itself
//! (`slave_fw::converter::analyzer_object::handle` over a real `Trace`), the settings object's
//! profile attributes, and an error response from a node without the analyzer.

use super::*;
use crate::model::{NodeState, NodeStatus, ScannerState, ScannerStatus};
use devicenet::explicit::{GeneralStatus, Request, ServiceCode};
use devicenet::slave::Reply;
use devicenet::Instant;
use slave_fw::serial::breaker;
use slave_fw::serial::trace::{Trace, TraceKind};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

/// MAC 5 is a breaker converter, MAC 6 a node without the analyzer.
const CONVERTER: u8 = 5;
const OTHER: u8 = 6;

fn node(mac: u8) -> NodeState {
    NodeState {
        mac,
        name: None,
        connection: "poll".into(),
        ack_suppression: false,
        status: NodeStatus::Ok,
        code: 0,
        detail: None,
        identity: Default::default(),
        input_size: Some(8),
        output_size: Some(8),
        input: Vec::new(),
        output: Vec::new(),
        exchanges: 0,
        last_exchange_us: None,
    }
}

/// The converter's side: its trace, and how many Read_Trace requests it answered.
struct Device {
    trace: Mutex<Trace>,
    reads: AtomicUsize,
}

/// A breaker status frame on the wire.
fn status_frame(currents: [u8; 4]) -> Vec<u8> {
    let mut wire = [0u8; 32];
    let data = breaker::StatusData::new(currents, breaker::SwitchState::Closed);
    let n = breaker::FRAMING.encode(data.as_bytes(), &mut wire).unwrap();
    wire[..n].to_vec()
}

/// Answers `cmd` as the scanner's loop would, the devices being `device` (MAC 5) and a node
/// without the analyzer (MAC 6).
fn answer(device: &Device, cmd: ConsoleCommand) {
    let ConsoleCommand::Request { mac, service, class, instance, data, reply } = cmd else {
        panic!("only Request is sent: {cmd:?}");
    };
    let body = match (mac, class) {
        (CONVERTER, ANALYZER_CLASS) => {
            if service == READ_TRACE {
                device.reads.fetch_add(1, Ordering::SeqCst);
            }
            let req = Request { service: ServiceCode::from(service), class, instance, data: &data };
            let mut buf = [0u8; 62];
            let mut r = Reply::new(&mut buf);
            let mut trace = device.trace.lock().unwrap();
            match slave_fw::converter::analyzer_object::handle(&mut trace, &req, &mut r) {
                Ok(()) => {
                    let n = r.len();
                    ReplyBody::Success(buf[..n].to_vec())
                }
                Err(e) => ReplyBody::Error { general: e.general, additional: e.additional },
            }
        }
        // Attribute 11: framed serial; attribute 12 is not asked for a framed instrument.
        (CONVERTER, SETTINGS_CLASS) if data == [11] => ReplyBody::Success(vec![0]),
        // Object does not exist.
        _ => ReplyBody::Error { general: GeneralStatus::ObjectDoesNotExist, additional: 0xFF },
    };
    let _ = reply.send(Ok(body));
}

/// A console on a free port with MAC 5 and 6 in the scan list, its scanner loop answering from
/// `device`.
fn console(device: Arc<Device>) -> super::super::UiServer {
    let (tx, rx) = mpsc::channel::<ConsoleCommand>();
    std::thread::spawn(move || {
        while let Ok(cmd) = rx.recv() {
            answer(&device, cmd);
        }
    });
    let state = ScannerState {
        mac: 0,
        status: ScannerStatus::Running,
        cycles: 1,
        cycle_ms: 1.0,
        bus_load: 0.0,
        interscan_delay_ms: 10,
        expected_packet_rate_ms: 100,
        nodes: vec![node(CONVERTER), node(OTHER)],
    };
    let shared = Arc::new(Shared {
        state: Mutex::new(state),
        frames: Mutex::new(VecDeque::new()),
        commands: Mutex::new(tx),
        history: None,
        record_dir: std::env::temp_dir(),
        mqtt: Mutex::new(None),
        audit: Arc::new(crate::audit::MemoryAudit::default()),
    });
    super::super::serve("127.0.0.1:0", shared).unwrap()
}

/// `GET path`: the status and the JSON body.
fn get(server: &super::super::UiServer, path: &str) -> (u16, serde_json::Value) {
    let addr = server.addr();
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n").unwrap();
    let mut text = String::new();
    s.read_to_string(&mut text).unwrap();
    let (head, body) = text.split_once("\r\n\r\n").unwrap();
    let status = head.split_whitespace().nth(1).unwrap().parse().unwrap();
    (status, serde_json::from_str(body).unwrap_or_else(|e| panic!("{e}: {body}")))
}

fn device() -> Arc<Device> {
    Arc::new(Device { trace: Mutex::new(Trace::new()), reads: AtomicUsize::new(0) })
}

#[test]
fn malformed_mac_is_400_and_unknown_node_404() {
    let server = console(device());
    for mac in ["64", "x", "-1", "300"] {
        let (status, v) = get(&server, &format!("/api/node/{mac}/serial-trace"));
        assert_eq!(status, 400, "{mac}: {v}");
        assert!(v["error"].as_str().unwrap().contains("bad MAC"), "{v}");
    }
    let (status, v) = get(&server, "/api/node/7/serial-trace");
    assert_eq!((status, v["error"].as_str()), (404, Some("MAC 7 is not in the scan list")), "{v}");
    let (status, v) = get(&server, "/api/node/5/serial-trace?since=x");
    assert_eq!(status, 400, "{v}");
}

#[test]
fn a_node_without_the_analyzer_gets_a_note_not_an_error() {
    let server = console(device());
    let (status, v) = get(&server, "/api/node/6/serial-trace");
    assert_eq!(status, 200, "{v}");
    assert_eq!((v["ok"].as_bool(), v["converter"].as_bool()), (Some(true), Some(false)), "{v}");
    let note = v["note"].as_str().unwrap();
    assert!(note.starts_with("MAC 6 has no serial-line analyzer (class 0x68)"), "{note}");
}

#[test]
fn lines_are_decoded_and_polled_since_a_number() {
    let device = device();
    let server = console(Arc::clone(&device));
    let record = |kind, bytes: &[u8], ms| {
        device.trace.lock().unwrap().record_bytes(kind, bytes, Instant::from_millis(ms))
    };
    record(TraceKind::Receive, &status_frame([1, 2, 3, 4]), 100);
    record(TraceKind::DriverOn, &[], 200);
    record(TraceKind::Transmit, &[0x68, 0x01, 0x02, 0x02, 0x16], 201);
    let (status, v) = get(&server, "/api/node/5/serial-trace");
    assert_eq!(status, 200, "{v}");
    assert_eq!(
        (v["converter"].as_bool(), v["profile"].as_str()),
        (Some(true), Some("breaker (framed serial)"))
    );
    let decoded: Vec<(&str, &str)> = v["lines"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| (l["kind"].as_str().unwrap(), l["decoded"].as_str().unwrap()))
        .collect();
    assert_eq!(
        decoded,
        [("rx", "status: currents 1 2 3 4, switch Closed"), ("driver on", ""), ("tx", "command Close")]
    );
    assert_eq!(v["next"], 3, "{v}");
    assert_eq!(v["lines"][0]["n"], 1, "{v}");

    // Nothing new: one Read_Trace, no lines.
    let reads = device.reads.load(Ordering::SeqCst);
    let (_, v) = get(&server, "/api/node/5/serial-trace?since=3");
    assert_eq!(v["lines"].as_array().unwrap().len(), 0, "{v}");
    assert_eq!(device.reads.load(Ordering::SeqCst), reads + 1);

    // A frame split across two polls is decoded whole when its end comes.
    let frame = status_frame([7, 8, 9, 10]);
    record(TraceKind::Receive, &frame[..10], 1000);
    let (_, v) = get(&server, "/api/node/5/serial-trace?since=3");
    assert_eq!(v["lines"].as_array().unwrap().len(), 0, "{v}");
    record(TraceKind::Receive, &frame[10..], 1100);
    let (_, v) = get(&server, "/api/node/5/serial-trace?since=3");
    assert_eq!(v["lines"][0]["decoded"], "status: currents 7 8 9 10, switch Closed", "{v}");
    assert_eq!(v["next"], 4, "{v}");
}

#[test]
fn an_overrun_ring_is_a_missed_line_and_memory_is_bounded() {
    let device = device();
    let server = console(Arc::clone(&device));
    // 40 events in a 32-entry ring before the first read: 8 overwritten.
    for k in 0..40 {
        device.trace.lock().unwrap().record_event(TraceKind::DriverOn, Instant::from_millis(k * 10));
    }
    let (_, v) = get(&server, "/api/node/5/serial-trace");
    assert_eq!(v["lines"][0]["kind"], "missed", "{v}");
    assert_eq!(v["lines"][0]["decoded"], "8 entries missed", "{v}");
    assert_eq!((v["missed"].as_u64(), v["entries"].as_u64()), (Some(8), Some(32)), "{v}");
    // More lines than the server keeps: the oldest go, and a reader far behind is told how many.
    for round in 0..(LINES_KEPT / 20 + 2) {
        for k in 0..20 {
            let ms = 1000 + (round * 20 + k) as u64;
            device.trace.lock().unwrap().record_event(TraceKind::DriverOff, Instant::from_millis(ms));
        }
        get(&server, "/api/node/5/serial-trace?since=100000");
    }
    let (_, v) = get(&server, "/api/node/5/serial-trace?since=1");
    let lines = v["lines"].as_array().unwrap();
    assert_eq!(lines.len(), LINES_KEPT, "{}", lines.len());
    let next = v["next"].as_u64().unwrap();
    assert_eq!(lines[0]["n"].as_u64(), Some(next - LINES_KEPT as u64 + 1));
    assert_eq!(v["dropped"].as_u64(), Some(next - LINES_KEPT as u64 - 1), "{v}");
}

#[test]
fn a_viewer_may_read_the_trace() {
    // Reading is a GET: the least privileged role's action (no CSRF token, no audit entry).
    let action = super::super::auth::required("GET", "/api/node/5/serial-trace");
    assert_eq!(action, crate::accounts::Action::View);
    assert!(crate::accounts::Role::Viewer.may(action));
}
