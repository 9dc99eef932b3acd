//! The console's HTTP server and JSON API (`dnet_scanner::ui`) against a stand-in scanner
//! (`ui_support`): every route, commands and their answers, recording, and bad input: a port in
//! use, malformed requests, clients that vanish mid-request or mid-response.

mod ui_support;

use dnet_scanner::ui::{self, UiServer};
use serde_json::Value;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};
use ui_support::FakeScanner;

/// The token the served page carries (`<meta name="csrf-token" content="...">`).
fn page_token(addr: SocketAddr) -> String {
    let (status, _, page) = raw(addr, "GET", "/", &[], b"");
    assert_eq!(status, 200);
    let page = String::from_utf8(page).unwrap();
    let at = page.find(r#"<meta name="csrf-token" content=""#).expect("the page carries its token") + 33;
    page[at..].split('"').next().unwrap().to_string()
}

/// One HTTP/1.1 exchange as the console's page makes it: a state-changing request carries the
/// page's token, the console's own origin and the JSON content type.
fn http(addr: SocketAddr, method: &str, path: &str, body: &[u8]) -> (u16, Vec<(String, String)>, Vec<u8>) {
    if method == "GET" || method == "HEAD" {
        return raw(addr, method, path, &[], body);
    }
    let token = page_token(addr);
    let origin = format!("http://{addr}");
    let headers =
        [("Origin", origin.as_str()), ("Content-Type", "application/json"), ("X-CSRF-Token", token.as_str())];
    raw(addr, method, path, &headers, body)
}

/// One HTTP/1.1 exchange on a fresh connection with exactly `headers` besides `Host`,
/// `Connection` and `Content-Length`: the status, the headers (lower-case names) and the body.
fn raw(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: &[u8],
) -> (u16, Vec<(String, String)>, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(15))).unwrap();
    let extra: String = headers.iter().map(|(k, v)| format!("{k}: {v}\r\n")).collect();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n{extra}Content-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(body).unwrap();
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).unwrap();
    let split = raw.windows(4).position(|w| w == b"\r\n\r\n").expect("a complete response head");
    let head = String::from_utf8_lossy(&raw[..split]).to_string();
    let mut lines = head.lines();
    let status = lines.next().unwrap().split(' ').nth(1).unwrap().parse().unwrap();
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect::<Vec<_>>();
    let mut body = raw[split + 4..].to_vec();
    if headers.iter().any(|(k, v)| k == "transfer-encoding" && v.contains("chunked")) {
        body = dechunk(&body);
    }
    (status, headers, body)
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let Some(eol) = b.windows(2).position(|w| w == b"\r\n") else { return out };
        let n = usize::from_str_radix(std::str::from_utf8(&b[..eol]).unwrap().trim(), 16).unwrap();
        if n == 0 {
            return out;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + n]);
        b = &b[eol + 4 + n..];
    }
}

fn json(addr: SocketAddr, method: &str, path: &str, body: &str) -> (u16, Value) {
    let (status, headers, body) = http(addr, method, path, body.as_bytes());
    assert!(
        headers.iter().any(|(k, v)| k == "content-type" && v.starts_with("application/json")),
        "{path}: {headers:?}"
    );
    (status, serde_json::from_slice(&body).unwrap_or_else(|e| panic!("{path}: {e}: {body:?}")))
}

/// The stand-in scanner and the console over it, on a free port.
struct Rig {
    scanner: FakeScanner,
    server: UiServer,
    dir: std::path::PathBuf,
}

impl Rig {
    fn start(name: &str, answer: bool) -> Rig {
        let dir = std::env::temp_dir().join(format!("dnet-ui-http-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let scanner = FakeScanner::start(&dir, answer);
        let server = ui::serve("127.0.0.1:0", scanner.shared.clone()).unwrap();
        let rig = Rig { scanner, server, dir };
        rig.wait_until(|r| {
            json(r.addr(), "GET", "/api/state", "").1["nodes"].as_array().is_some_and(|n| n.len() == 2)
        });
        rig
    }

    fn addr(&self) -> SocketAddr {
        self.server.addr()
    }

    fn wait_until(&self, mut f: impl FnMut(&Rig) -> bool) {
        let start = Instant::now();
        while !f(self) {
            assert!(start.elapsed() < Duration::from_secs(5), "condition not met within 5 s");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

#[test]
fn page_and_assets_are_served_from_the_binary() {
    let rig = Rig::start("assets", true);
    for (path, kind, needle) in [
        ("/", "text/html", "Network"),
        ("/app.js", "text/javascript", "/api/state"),
        ("/style.css", "text/css", ".grid"),
    ] {
        let (status, headers, body) = http(rig.addr(), "GET", path, b"");
        assert_eq!(status, 200, "{path}");
        assert!(
            headers.iter().any(|(k, v)| k == "content-type" && v.starts_with(kind)),
            "{path}: {headers:?}"
        );
        assert!(String::from_utf8_lossy(&body).contains(needle), "{path}");
        // No asset from the internet: the page must work offline.
        assert!(!String::from_utf8_lossy(&body).contains("://"), "{path} refers to another site");
    }
}

#[test]
fn state_has_the_nodes_scanner_status_and_mqtt() {
    let rig = Rig::start("state", true);
    let (status, s) = json(rig.addr(), "GET", "/api/state", "");
    assert_eq!(status, 200);
    assert_eq!(s["status"], "running");
    assert_eq!(s["nodes"][0]["mac"], 5);
    assert_eq!(s["nodes"][0]["identity"]["product_name"], "Serial-DeviceNet Bridge");
    assert_eq!(s["nodes"][1]["input_size"], 20);
    assert!(s["mqtt"].as_str().unwrap().contains("unreachable"));
    assert_eq!(s["history"], true);
    assert_eq!(s["recording"], false);
}

#[test]
fn frames_come_after_a_sequence_number_filtered_by_mac_and_kind() {
    let rig = Rig::start("frames", true);
    rig.wait_until(|r| r.scanner.shared.frames.lock().unwrap().len() > 40);
    let (_, all) = json(rig.addr(), "GET", "/api/frames", "");
    let frames = all["frames"].as_array().unwrap();
    assert!(!frames.is_empty());
    let next = all["next"].as_u64().unwrap();
    assert_eq!(frames.last().unwrap()["seq"].as_u64().unwrap(), next);
    let (_, later) = json(rig.addr(), "GET", &format!("/api/frames?after={next}"), "");
    assert!(later["frames"].as_array().unwrap().iter().all(|f| f["seq"].as_u64().unwrap() > next));
    let (_, six) = json(rig.addr(), "GET", "/api/frames?mac=6&kind=io&limit=10", "");
    let six = six["frames"].as_array().unwrap();
    assert_eq!(six.len(), 10);
    assert!(six.iter().all(|f| f["mac"] == 6 && f["kind"] == "io"));
    assert!(six.iter().any(|f| f["meaning"].as_str().unwrap().contains("oll")), "{six:?}");
    let (_, none) = json(rig.addr(), "GET", "/api/frames?kind=ucmm", "");
    assert_eq!(none["frames"].as_array().unwrap().len(), 0);
}

fn field<'a>(node: &'a Value, name: &str) -> &'a Value {
    node["fields"]
        .as_array()
        .unwrap()
        .iter()
        .find(|f| f["name"] == name)
        .unwrap_or_else(|| panic!("{name}: {node}"))
}

#[test]
fn a_node_is_decoded_by_its_profile() {
    let rig = Rig::start("node", true);
    let (status, n5) = json(rig.addr(), "GET", "/api/node/5", "");
    assert_eq!(status, 200);
    assert_eq!(n5["profile"], "breaker");
    assert_eq!(field(&n5, "switch")["text"], "open");
    assert_eq!(field(&n5, "phase_a")["text"], "0 A");
    assert_eq!(field(&n5, "param_1")["text"], "200");
    assert_eq!(n5["link"], Value::Null);
    let (_, n6) = json(rig.addr(), "GET", "/api/node/6", "");
    assert_eq!(n6["with_status"], true);
    assert_eq!(n6["link"]["link"], "ok");
    assert!(n6["link"]["text"].as_str().unwrap().contains("freshness"));
}

#[test]
fn breaker_close_and_open_go_through_the_output_image() {
    let rig = Rig::start("breaker", true);
    let (status, r) = json(rig.addr(), "POST", "/api/node/5/breaker/close", "");
    assert_eq!((status, &r["ok"]), (200, &Value::Bool(true)), "{r}");
    assert_eq!(r["data"], "0201000000000000");
    rig.wait_until(|r| field(&json(r.addr(), "GET", "/api/node/5", "").1, "switch")["text"] == "closed");
    let (_, n5) = json(rig.addr(), "GET", "/api/node/5", "");
    assert!(field(&n5, "phase_a")["values"][0].as_u64().unwrap() > 100);
    assert_eq!(n5["output_hex"], "0201000000000000");
    // The sequence number is bumped for each command.
    let (_, r) = json(rig.addr(), "POST", "/api/node/5/breaker/open", "");
    assert_eq!(r["data"], "0102000000000000");
    rig.wait_until(|r| field(&json(r.addr(), "GET", "/api/node/5", "").1, "switch")["text"] == "open");
    // Set parameter: its outcome in the status byte of MAC 6.
    let (_, r) = json(rig.addr(), "POST", "/api/node/6/breaker/param", r#"{"id": 2, "value": 777}"#);
    assert_eq!(r["data"], "0301020903000000", "{r}");
    rig.wait_until(|r| field(&json(r.addr(), "GET", "/api/node/6", "").1, "param_2")["text"] == "777");
    let (_, n6) = json(rig.addr(), "GET", "/api/node/6", "");
    assert_eq!(n6["link"]["command"], "ok");
}

#[test]
fn explicit_get_set_output_and_parameters() {
    let rig = Rig::start("explicit", true);
    let (status, r) =
        json(rig.addr(), "POST", "/api/node/5/get", r#"{"class": 1, "instance": 1, "attribute": 7}"#);
    assert_eq!(status, 200, "{r}");
    assert!(r["text"].as_str().unwrap().contains("Serial-DeviceNet Bridge"), "{r}");
    let (_, r) =
        json(rig.addr(), "POST", "/api/node/5/get", r#"{"class": "0x01", "instance": "1", "attribute": 1}"#);
    assert_eq!(r["data"], "3412");
    let (status, r) = json(
        rig.addr(),
        "POST",
        "/api/node/5/set",
        r#"{"class": 1, "instance": 1, "attribute": 7, "value": "00"}"#,
    );
    assert_eq!((status, r["ok"].clone()), (409, Value::Bool(false)));
    assert!(r["error"].as_str().unwrap().contains("not settable"));
    let (status, r) = json(rig.addr(), "POST", "/api/node/6/output", r#"{"data": "0000000000000000"}"#);
    assert_eq!((status, r["ok"].clone()), (200, Value::Bool(true)), "{r}");
    let (status, r) = json(rig.addr(), "POST", "/api/node/6/output", r#""00""#);
    assert_eq!(status, 409);
    assert!(r["error"].as_str().unwrap().contains("8 bytes"), "{r}");
    let (_, p) = json(rig.addr(), "GET", "/api/node/5/params", "");
    let params = p["params"].as_array().unwrap();
    assert_eq!(params.len(), 4, "{p}");
    assert_eq!(params[1]["name"], "Trip delay");
    assert_eq!(params[1]["value"], 200);
    assert_eq!(params[1]["units"], "ms");
}

#[test]
fn history_and_csv_export() {
    let rig = Rig::start("history", true);
    rig.wait_until(|r| r.scanner.history.0.lock().unwrap().len() >= 6);
    let (status, h) = json(rig.addr(), "GET", "/api/history?mac=5", "");
    assert_eq!(status, 200);
    let samples = h["samples"].as_array().unwrap();
    assert!(!samples.is_empty());
    assert_eq!(samples[0]["values"][0][0], "phase_a");
    let (status, headers, body) = http(rig.addr(), "GET", "/api/export.csv?mac=5&from=0", b"");
    assert_eq!(status, 200);
    assert!(
        headers.iter().any(|(k, v)| k == "content-disposition" && v.contains("history-mac5-0-")),
        "{headers:?}"
    );
    let text = String::from_utf8(body).unwrap();
    assert!(text.starts_with("unix_ms,time,mac,input_hex,phase_a"), "{text}");
    assert!(text.lines().skip(1).all(|l| l.split(',').nth(2) == Some("5")));
    assert!(text.lines().count() > 1);
}

#[test]
fn recording_writes_candump_and_pcap() {
    let rig = Rig::start("record", true);
    let (status, r) = json(rig.addr(), "POST", "/api/record/start", "");
    assert_eq!(status, 200, "{r}");
    let (log, pcap) = (r["log"].as_str().unwrap().to_string(), r["pcap"].as_str().unwrap().to_string());
    assert!(log.ends_with(".log") && pcap.ends_with(".pcap") && log.contains("record-"));
    let (status, again) = json(rig.addr(), "POST", "/api/record/start", "");
    assert_eq!(status, 409, "{again}");
    std::thread::sleep(Duration::from_millis(400));
    let (_, s) = json(rig.addr(), "GET", "/api/state", "");
    assert_eq!(s["recording"], true);
    let (status, done) = json(rig.addr(), "POST", "/api/record/stop", "");
    assert_eq!(status, 200, "{done}");
    let frames = done["frames"].as_u64().unwrap();
    assert!(frames > 10, "{done}");
    let lines = std::fs::read_to_string(&log).unwrap();
    assert_eq!(lines.lines().count() as u64, frames);
    let first = lines.lines().next().unwrap();
    assert!(first.starts_with('(') && first.contains(") can0 "), "{first}");
    let cap = std::fs::read(&pcap).unwrap();
    assert_eq!(cap.len() as u64, 24 + 32 * frames);
    assert_eq!(&cap[..4], &0xA1B2_C3D4u32.to_le_bytes());
    assert!(std::path::Path::new(&log).starts_with(&rig.dir));
    let (status, _) = json(rig.addr(), "POST", "/api/record/stop", "");
    assert_eq!(status, 409);
}

#[test]
fn a_port_in_use_is_an_error_naming_the_address() {
    let rig = Rig::start("port", true);
    let listen = rig.addr().to_string();
    let e = ui::serve(&listen, rig.scanner.shared.clone()).err().expect("the port is taken");
    let text = e.to_string();
    assert!(text.contains(&listen), "{text}");
    assert!(text.contains("cannot listen"), "{text}");
    assert!(matches!(e, harness_common::error::HarnessError::Listen { .. }), "exit 2: {e:?}");
    assert_eq!(e.exit_code(), 2);
    let e = ui::serve("not an address", rig.scanner.shared.clone()).err().unwrap();
    assert!(e.to_string().contains("not an address"));
}

#[test]
fn bad_input_is_answered_with_precise_json_errors() {
    let rig = Rig::start("bad", true);
    let a = rig.addr();
    let cases: &[(&str, &str, &str, u16, &str)] = &[
        ("GET", "/api/node/64", "", 400, "bad MAC \"64\""),
        ("GET", "/api/node/x", "", 400, "bad MAC \"x\""),
        ("GET", "/api/node/7", "", 404, "MAC 7 is not in the scan list"),
        ("POST", "/api/node/5/output", r#"{"data": "02g1"}"#, 400, "bad hex"),
        ("POST", "/api/node/5/output", r#""021""#, 400, "bad hex"),
        ("POST", "/api/node/5/output", "0201", 400, "bad JSON body"),
        ("POST", "/api/node/5/output", "{}", 400, "missing \"data\""),
        ("POST", "/api/node/5/get", "{", 400, "bad JSON body"),
        ("POST", "/api/node/5/get", r#"{"class": 1}"#, 400, "missing \"instance\""),
        (
            "POST",
            "/api/node/5/get",
            r#"{"class": 1, "instance": 1, "attribute": 300}"#,
            400,
            "bad attribute 300",
        ),
        (
            "POST",
            "/api/node/5/set",
            r#"{"class": 1, "instance": 1, "attribute": 1}"#,
            400,
            "missing \"value\"",
        ),
        ("POST", "/api/node/5/breaker/explode", "", 404, "no breaker command"),
        ("POST", "/api/node/5/breaker/param", r#"{"id": 1, "value": 70000}"#, 400, "bad value 70000"),
        ("GET", "/api/frames?after=x", "", 400, "bad after \"x\""),
        ("GET", "/api/frames?mac=99", "", 400, "bad MAC \"99\""),
        ("GET", "/api/history", "", 400, "missing mac"),
        ("GET", "/api/history?mac=5&from=10&to=5", "", 400, "from 10 is after to 5"),
        ("GET", "/api/nothing", "", 404, "no such API: /api/nothing"),
        ("GET", "/nothing", "", 404, "not found: /nothing"),
        ("DELETE", "/api/state", "", 405, "DELETE is not allowed on /api/state"),
        ("GET", "/api/record/start", "", 405, "GET is not allowed"),
    ];
    for (method, path, body, status, needle) in cases {
        let (got, v) = json(a, method, path, body);
        assert_eq!(got, *status, "{method} {path}: {v}");
        assert_eq!(v["ok"], false, "{method} {path}");
        let e = v["error"].as_str().unwrap();
        assert!(e.contains(needle), "{method} {path}: {e:?} lacks {needle:?}");
    }
    // A body over the limit is refused without being read.
    let big = vec![b'0'; 4096];
    let (status, _, body) = http(a, "POST", "/api/node/5/output", &big);
    assert_eq!(status, 413);
    assert!(String::from_utf8_lossy(&body).contains("at most 1024"));
    // The breaker helpers need a breaker.
    assert_eq!(json(a, "GET", "/api/state", "").0, 200);
}

#[test]
fn clients_that_vanish_mid_request_or_mid_response_do_not_disturb_the_server() {
    let rig = Rig::start("vanish", true);
    let a = rig.addr();
    // Half a request line, then gone.
    {
        let mut s = TcpStream::connect(a).unwrap();
        s.write_all(b"GET /api/sta").unwrap();
    }
    // A body announced and not sent, then gone; and one that stays silent.
    {
        let mut s = TcpStream::connect(a).unwrap();
        s.write_all(b"POST /api/node/5/output HTTP/1.1\r\nHost: x\r\nContent-Length: 900\r\n\r\n0201")
            .unwrap();
    }
    let silent = {
        let mut s = TcpStream::connect(a).unwrap();
        s.write_all(b"POST /api/node/5/output HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n02")
            .unwrap();
        s
    };
    // Mid-response: ask for the whole frame ring and the CSV, read a few bytes, close.
    for path in ["/api/frames?limit=5000", "/api/export.csv?from=0", "/api/frames?limit=5000"] {
        let mut s = TcpStream::connect(a).unwrap();
        s.write_all(format!("GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").as_bytes()).unwrap();
        let mut buf = [0u8; 64];
        let _ = s.read(&mut buf);
        drop(s);
    }
    // Many polls at once, some abandoned before the answer.
    let threads: Vec<_> = (0..20)
        .map(|i| {
            std::thread::spawn(move || {
                if i % 2 == 0 {
                    let mut s = TcpStream::connect(a).unwrap();
                    let _ = s.write_all(b"GET /api/state HTTP/1.1\r\nHost: x\r\n\r\n");
                } else {
                    assert_eq!(json(a, "GET", "/api/frames?limit=100", "").0, 200);
                }
            })
        })
        .collect();
    for t in threads {
        t.join().unwrap();
    }
    // The server goes on answering, quickly.
    let start = Instant::now();
    for _ in 0..10 {
        let (status, s) = json(a, "GET", "/api/state", "");
        assert_eq!((status, s["ok"].clone()), (200, Value::Bool(true)));
    }
    assert!(start.elapsed() < Duration::from_secs(2), "{:?}", start.elapsed());
    let (_, r) = json(a, "POST", "/api/node/5/breaker/close", "");
    assert_eq!(r["ok"], true);
    drop(silent);
}

#[test]
fn a_scanner_that_does_not_answer_is_a_timeout_not_a_hang() {
    let rig = Rig::start("timeout", false);
    let start = Instant::now();
    let (status, r) = json(rig.addr(), "POST", "/api/node/5/breaker/close", "");
    assert_eq!(status, 504, "{r}");
    assert!(r["error"].as_str().unwrap().contains("no answer from the scanner within 5 s"));
    assert!(start.elapsed() < Duration::from_secs(8));
    // The rest of the API still answers meanwhile.
    assert_eq!(json(rig.addr(), "GET", "/api/node/5", "").0, 200);
}

#[test]
fn a_stopped_server_releases_its_port() {
    let rig = Rig::start("stop", true);
    let addr = rig.addr();
    let Rig { scanner, server, .. } = rig;
    server.stop();
    std::thread::sleep(Duration::from_millis(100));
    let again = ui::serve(&addr.to_string(), scanner.shared.clone()).expect("the port is free again");
    assert_eq!(json(again.addr(), "GET", "/api/state", "").0, 200);
}

#[test]
fn state_changes_without_the_page_s_token_origin_and_content_type_are_refused() {
    let rig = Rig::start("csrf", true);
    let a = rig.addr();
    let token = page_token(a);
    assert_eq!(token.len(), 32, "{token}");
    assert_eq!(json(a, "GET", "/api/token", "").1["token"], token.as_str());
    let own = format!("http://{a}");
    let json_type = ("Content-Type", "application/json");
    type Headers<'a> = Vec<(&'a str, &'a str)>;
    let cases: Vec<(&str, Headers, &str)> = vec![
        ("no token", vec![("Origin", own.as_str()), json_type], "no X-CSRF-Token"),
        (
            "wrong token",
            vec![("Origin", own.as_str()), json_type, ("X-CSRF-Token", "0123456789abcdef0123456789abcdef")],
            "wrong X-CSRF-Token",
        ),
        (
            "foreign origin",
            vec![("Origin", "http://evil.example"), json_type, ("X-CSRF-Token", token.as_str())],
            "is not the console's own",
        ),
        ("no origin", vec![json_type, ("X-CSRF-Token", token.as_str())], "no Origin"),
        (
            "form content type",
            vec![
                ("Origin", own.as_str()),
                ("Content-Type", "application/x-www-form-urlencoded"),
                ("X-CSRF-Token", token.as_str()),
            ],
            "application/x-www-form-urlencoded",
        ),
        (
            "text content type",
            vec![("Origin", own.as_str()), ("Content-Type", "text/plain"), ("X-CSRF-Token", token.as_str())],
            "text/plain",
        ),
    ];
    for path in ["/api/node/5/breaker/close", "/api/record/start", "/api/node/5/output"] {
        for (what, headers, needle) in &cases {
            let (status, _, body) = raw(a, "POST", path, headers, b"{}");
            let body = String::from_utf8_lossy(&body);
            assert_eq!(status, 403, "{what} on {path}: {body}");
            assert!(body.contains(needle), "{what} on {path}: {body} lacks {needle:?}");
        }
    }
    // A page served under another name (DNS rebinding) cannot even read.
    let mut s = TcpStream::connect(a).unwrap();
    s.write_all(b"GET /api/state HTTP/1.1\r\nHost: evil.example:80\r\nConnection: close\r\n\r\n").unwrap();
    let mut answer = String::new();
    s.read_to_string(&mut answer).unwrap();
    assert!(answer.starts_with("HTTP/1.1 403"), "{answer}");
    assert!(answer.contains("is not this console's address"), "{answer}");
    // Nothing changed: the breaker is open, nothing records, no output was put.
    let (_, n5) = json(a, "GET", "/api/node/5", "");
    assert_eq!(field(&n5, "switch")["text"], "open");
    assert_eq!(n5["output_hex"], "0000000000000000");
    assert_eq!(json(a, "GET", "/api/state", "").1["recording"], false);
    // The page's own request goes through.
    let (status, r) = json(a, "POST", "/api/node/5/breaker/close", "");
    assert_eq!(status, 200, "{r}");
}

#[test]
fn the_scan_list_s_name_is_in_the_state_and_the_node() {
    let rig = Rig::start("names", true);
    let (_, s) = json(rig.addr(), "GET", "/api/state", "");
    assert_eq!(s["nodes"][0]["name"], "feeder 1", "{s}");
    assert_eq!(s["nodes"][1]["name"], Value::Null, "{s}");
    let (_, n5) = json(rig.addr(), "GET", "/api/node/5", "");
    assert_eq!(n5["node"]["name"], "feeder 1", "{n5}");
}
