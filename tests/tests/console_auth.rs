//! `dnet-master ui --users FILE` as a process, driven over real TCP with hand-made requests:
//! logins, sessions, roles and the audit log (issue 29 item 1), and every hostile request the
//! console must refuse (no session, a forged CSRF token, a wrong role, an oversized body, a foreign
//! `Origin` or `Host`). The users file is made by `dnet-master user add`, the password on stdin.
//! Once on the simulated bus, once on the real SLCAN path (the simulated breaker and the soft
//! slave on socat pty pairs, pty-rig); the refusals before the bus (a non-loopback address without
//! `--users`, a bad users file, bad TLS files) with exit 2; and the console over TLS with a
//! certificate made at test time (rcgen), read by Python's `ssl` trusting the test CA only.
//!
//! Needs the built `dnet-master` (and `dnet-soft-slave`, `dnet-sim-breaker`, socat for the pty
//! test, `python3` for the TLS test): ignored in the plain host-test run, run by `scripts/check`
//! with `-- --ignored`.

use pty_rig::console::{add_user, console_addr, stop_ui};
use pty_rig::{bin, require_socat, scratch, Proc, PtyRig};
use serde_json::Value;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A users file with a viewer, an operator and an engineer (password: the name twice).
fn users_file(dir: &Path) -> PathBuf {
    let file = dir.join("users.toml");
    let _ = std::fs::remove_file(&file);
    for (name, role) in [("vera", "viewer"), ("otto", "operator"), ("erin", "engineer")] {
        add_user(&file, name, role, &format!("{name}{name}"));
    }
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(!text.contains("ottootto"), "a password is stored in the users file:\n{text}");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        assert_eq!(std::fs::metadata(&file).unwrap().permissions().mode() & 0o777, 0o600);
    }
    file
}

/// Starts `dnet-master BUS ui --listen 127.0.0.1:0 --no-history EXTRA`; the console's host:port.
fn start_ui(bus: &str, extra: &[&str]) -> (Proc, String) {
    let mut args = vec!["--bus", bus, "ui", "--listen", "127.0.0.1:0", "--no-history"];
    args.extend_from_slice(extra);
    let p = Proc::spawn(bin("dnet-master"), &args);
    let addr = console_addr(&p, Duration::from_secs(30));
    (p, addr)
}

/// An answer: status, head, body.
struct Answer {
    status: u16,
    head: String,
    body: String,
}

impl Answer {
    fn json(&self) -> Value {
        serde_json::from_str(&self.body).unwrap_or_else(|e| panic!("not JSON ({e}): {}", self.body))
    }

    fn error(&self) -> String {
        self.json()["error"].as_str().unwrap_or_default().to_string()
    }
}

/// A request as a browser (or an attacker) would send it.
#[derive(Clone)]
struct Req {
    method: &'static str,
    path: String,
    headers: Vec<(String, String)>,
    body: String,
}

impl Req {
    /// A GET with `Host` naming the console.
    fn get(addr: &str, path: &str) -> Req {
        Req {
            method: "GET",
            path: path.into(),
            headers: vec![("Host".into(), addr.into())],
            body: String::new(),
        }
    }

    /// A POST as the console's page sends it: own `Origin`, JSON, `body`.
    fn post(addr: &str, path: &str, body: &str) -> Req {
        let mut r = Req::get(addr, path);
        r.method = "POST";
        r.headers.push(("Origin".into(), format!("http://{addr}")));
        r.headers.push(("Content-Type".into(), "application/json".into()));
        r.body = body.into();
        r
    }

    fn with(mut self, name: &str, value: &str) -> Req {
        self.headers.retain(|(k, _)| k != name);
        self.headers.push((name.into(), value.into()));
        self
    }

    fn session(self, s: &Session) -> Req {
        self.with("Cookie", &format!("dnet_session={}", s.id)).with("X-CSRF-Token", &s.token)
    }

    fn send(&self, addr: &str) -> Answer {
        let mut head = format!("{} {} HTTP/1.1\r\n", self.method, self.path);
        for (k, v) in &self.headers {
            head.push_str(&format!("{k}: {v}\r\n"));
        }
        if !self.headers.iter().any(|(k, _)| k == "Content-Length") {
            head.push_str(&format!("Content-Length: {}\r\n", self.body.len()));
        }
        head.push_str("\r\n");
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        s.write_all(head.as_bytes()).unwrap();
        let _ = s.write_all(self.body.as_bytes());
        let mut raw = Vec::new();
        let _ = s.read_to_end(&mut raw);
        let text = String::from_utf8_lossy(&raw).into_owned();
        let (head, body) = text.split_once("\r\n\r\n").unwrap_or_else(|| panic!("no answer: {text:?}"));
        let status = head.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or(0);
        Answer { status, head: head.to_string(), body: body.to_string() }
    }
}

/// A logged-in session: the cookie's value and the CSRF token.
struct Session {
    id: String,
    token: String,
}

fn login(addr: &str, user: &str, password: &str) -> Session {
    let a =
        Req::post(addr, "/api/login", &format!(r#"{{"user":"{user}","password":"{password}"}}"#)).send(addr);
    assert_eq!(a.status, 200, "login {user}: {}", a.body);
    let cookie = a.head.lines().find_map(|l| l.strip_prefix("Set-Cookie: ")).expect("a session cookie");
    assert!(cookie.ends_with("; HttpOnly; SameSite=Strict; Path=/"), "cookie: {cookie}");
    let id = cookie.split(';').next().unwrap().trim_start_matches("dnet_session=").to_string();
    let token = a.json()["token"].as_str().unwrap().to_string();
    assert_eq!((id.len(), token.len()), (32, 32));
    Session { id, token }
}

/// The first node of the console's state, once it is ok (at most `limit`).
fn node_ok(addr: &str, s: &Session, limit: Duration) -> u8 {
    let end = Instant::now() + limit;
    while Instant::now() < end {
        let st = Req::get(addr, "/api/state").session(s).send(addr).json();
        if let Some(n) = st["nodes"].as_array().and_then(|n| n.iter().find(|n| n["status"] == "ok")) {
            return n["mac"].as_u64().unwrap() as u8;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    panic!("no node ok within {limit:?}");
}

/// The breaker's switch state as the console decodes it.
fn switch(addr: &str, s: &Session, mac: u8) -> String {
    let n = Req::get(addr, &format!("/api/node/{mac}")).session(s).send(addr).json();
    let fields = n["fields"].as_array().cloned().unwrap_or_default();
    let f = fields.iter().find(|f| f["name"] == "switch").cloned().unwrap_or_default();
    f["text"].as_str().unwrap_or_default().to_string()
}

/// Every refusal and every right of the three roles, then the audit log; returns the entries.
fn roles_and_hostile_requests(addr: &str, p: &Proc) -> Vec<Value> {
    // No session: 401 for data and commands alike; the page itself is served.
    let a = Req::get(addr, "/api/state").send(addr);
    assert_eq!(a.status, 401, "{}", a.body);
    assert!(a.error().contains("not logged in"), "{}", a.body);
    assert_eq!(Req::get(addr, "/").send(addr).status, 200);
    let a = Req::post(addr, "/api/node/5/breaker/close", "{}").with("X-CSRF-Token", "00").send(addr);
    assert_eq!(a.status, 401, "{}", a.body);
    // A forged cookie is no session.
    let a = Req::get(addr, "/api/state")
        .with("Cookie", "dnet_session=00112233445566778899aabbccddeeff")
        .send(addr);
    assert_eq!(a.status, 401, "{}", a.body);
    // A wrong password, and a user that does not exist: the same answer.
    for body in [r#"{"user":"otto","password":"wrong"}"#, r#"{"user":"nobody","password":"x"}"#] {
        let a = Req::post(addr, "/api/login", body).send(addr);
        assert_eq!((a.status, a.error().as_str()), (401, "wrong user name or password"), "{body}");
    }

    let viewer = login(addr, "vera", "veravera");
    let operator = login(addr, "otto", "ottootto");
    let engineer = login(addr, "erin", "erinerin");
    let mac = node_ok(addr, &operator, Duration::from_secs(90));
    let close = format!("/api/node/{mac}/breaker/close");
    let open = format!("/api/node/{mac}/breaker/open");
    let set = format!("/api/node/{mac}/set");
    let set_body = r#"{"class":1,"instance":1,"attribute":7,"value":"00"}"#;
    // The breaker open to begin with (the engineer opens it when it is closed).
    if switch(addr, &operator, mac) != "open" {
        assert_eq!(Req::post(addr, &open, "{}").session(&engineer).send(addr).status, 200);
        let end = Instant::now() + Duration::from_secs(10);
        while switch(addr, &operator, mac) != "open" {
            assert!(Instant::now() < end, "the breaker did not open\n{}", p.dump());
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    // The viewer sees, and is refused commands by role (403 with the reason).
    assert_eq!(Req::get(addr, "/api/state").session(&viewer).send(addr).status, 200);
    let a = Req::post(addr, &close, "{}").session(&viewer).send(addr);
    assert_eq!(a.status, 403, "{}", a.body);
    assert!(a.error().contains("role viewer, which may not operate"), "{}", a.body);
    // The operator may not Set an attribute.
    let a = Req::post(addr, &set, set_body).session(&operator).send(addr);
    assert_eq!(a.status, 403, "{}", a.body);
    assert!(a.error().contains("may not engineer"), "{}", a.body);

    // Hostile requests with the operator's session: each refused, nothing sent to the device.
    let good = Req::post(addr, &close, "{}").session(&operator);
    let forged = good.clone().with("X-CSRF-Token", "00112233445566778899aabbccddeeff").send(addr);
    assert_eq!(
        (forged.status, forged.error().as_str()),
        (403, "wrong X-CSRF-Token: reload the console's page")
    );
    let other_sessions = good.clone().with("X-CSRF-Token", &viewer.token).send(addr);
    assert_eq!(other_sessions.status, 403, "another session's token: {}", other_sessions.body);
    let mut no_token = good.clone();
    no_token.headers.retain(|(k, _)| k != "X-CSRF-Token");
    assert_eq!(no_token.send(addr).status, 403);
    let a = good.clone().with("Origin", "http://evil.example").send(addr);
    assert!(a.status == 403 && a.error().contains("Origin"), "{}", a.body);
    let a = good.clone().with("Host", "evil.example:80").send(addr);
    assert!(a.status == 403 && a.error().contains("Host"), "{}", a.body);
    let a = good.clone().with("Content-Type", "text/plain").send(addr);
    assert!(a.status == 403 && a.error().contains("Content-Type"), "{}", a.body);
    let mut huge = good.clone();
    huge.body = format!(r#"{{"pad":"{}"}}"#, "x".repeat(1 << 20));
    let a = huge.send(addr);
    assert_eq!(a.status, 413, "{}", a.body);
    let a = Req::post(addr, "/api/login", &"x".repeat(4096)).send(addr);
    assert_eq!(a.status, 413, "an oversized login: {}", a.body);
    assert_eq!(switch(addr, &operator, mac), "open", "a refused request reached the device");

    // The operator's Close is carried out; the engineer may Set (the device may refuse the
    // value, but not the console) and open.
    let a = good.send(addr);
    assert_eq!(a.status, 200, "{}", a.body);
    let end = Instant::now() + Duration::from_secs(10);
    while switch(addr, &operator, mac) != "closed" {
        assert!(Instant::now() < end, "the breaker did not close\n{}", p.dump());
        std::thread::sleep(Duration::from_millis(100));
    }
    let a = Req::post(addr, &set, set_body).session(&engineer).send(addr);
    assert_ne!(a.status, 403, "{}", a.body);
    assert_eq!(Req::post(addr, &open, "{}").session(&engineer).send(addr).status, 200);

    // Logout ends the session: its cookie is cleared and no longer admitted.
    let a = Req::post(addr, "/api/logout", "{}").session(&viewer).send(addr);
    assert_eq!(a.status, 200, "{}", a.body);
    assert!(
        a.head.contains("Set-Cookie: dnet_session=; HttpOnly; SameSite=Strict; Path=/; Max-Age=0"),
        "{}",
        a.head
    );
    assert_eq!(Req::get(addr, "/api/state").session(&viewer).send(addr).status, 401);

    // The audit log: who, which node, what, how it ended; refusals included.
    let a = Req::get(addr, "/api/audit?limit=100").session(&operator).send(addr);
    assert_eq!(a.status, 200, "{}", a.body);
    let entries = a.json()["entries"].as_array().cloned().unwrap();
    let has = |user: &str, what: &str, result: &str| {
        entries.iter().any(|e| {
            e["user"] == user
                && e["via"] == "console"
                && e["what"].as_str().is_some_and(|w| w.starts_with(what))
                && e["result"].as_str().is_some_and(|r| r.starts_with(result))
                && e["unix_ms"].as_i64().is_some_and(|t| t > 1_600_000_000_000)
        })
    };
    assert!(has("otto", "breaker close", "ok"), "{entries:#?}");
    assert!(has("vera", "breaker close", "refused: user vera has the role viewer"), "{entries:#?}");
    assert!(has("otto", "set", "refused:"), "{entries:#?}");
    assert!(has("erin", "breaker open", "ok"), "{entries:#?}");
    assert!(has("otto", "login", "refused: wrong user name or password"), "{entries:#?}");
    assert!(has("vera", "logout", "ok"), "{entries:#?}");
    assert!(entries.iter().filter(|e| e["what"] == "breaker close").all(|e| e["mac"] == mac), "{entries:#?}");
    // No password in the log.
    assert!(!a.body.contains("ottootto") && !a.body.contains("wrong\""), "{}", a.body);
    entries
}

#[test]
#[ignore = "needs the built dnet-master: run by scripts/check"]
fn roles_sessions_and_hostile_requests_on_the_simulated_bus() {
    let dir = scratch("console-auth-sim");
    let users = users_file(&dir);
    let list = dir.join("list.toml");
    std::fs::write(&list, "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n").unwrap();
    let (mut p, addr) =
        start_ui("sim", &["--users", users.to_str().unwrap(), "--scanlist", list.to_str().unwrap()]);
    let entries = roles_and_hostile_requests(&addr, &p);
    eprintln!("audit entries: {}", entries.len());
    assert!(p.running(), "dnet-master still runs\n{}", p.dump());
    stop_ui(&mut p, Duration::from_secs(20), "");
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn roles_sessions_and_hostile_requests_over_slcan() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("console-auth-slcan", &["--period", "0.3"], None);
    let users = users_file(&rig.dir);
    let history = rig.dir.join("history.sqlite");
    let bus = rig.master_bus_arg();
    let mut args = vec!["--bus", bus.as_str(), "ui", "--listen", "127.0.0.1:0"];
    args.extend(["--users", users.to_str().unwrap(), "--history", history.to_str().unwrap()]);
    let mut p = Proc::spawn(bin("dnet-master"), &args);
    let addr = console_addr(&p, Duration::from_secs(30));
    let entries = roles_and_hostile_requests(&addr, &p);
    p.signal("INT");
    assert_eq!(
        p.wait(Duration::from_secs(30)).and_then(|s| s.code()),
        Some(130),
        "{}\n{}",
        p.dump(),
        rig.dump()
    );
    // The audit log is in the history file, as another program reads it.
    let rows = audit_rows(&history);
    assert!(rows >= entries.len(), "{rows} rows in the history's audit table, {} shown", entries.len());
}

/// Rows of the history's `audit` table, counted by Python's sqlite3 (another program).
fn audit_rows(history: &Path) -> usize {
    assert!(history.is_file(), "no history file {}", history.display());
    let out = Command::new("python3")
        .args(["-c", "import sqlite3,sys;print(sqlite3.connect(sys.argv[1]).execute('select count(*) from audit').fetchone()[0])"])
        .arg(history)
        .output()
        .expect("python3 runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).trim().parse().unwrap()
}

/// `dnet-master ARGS`, which must end with exit 2 before the console or the bus: its stderr.
fn refused(args: &[&str]) -> String {
    let out = Command::new(bin("dnet-master")).args(args).output().expect("dnet-master runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stdout}\n{stderr}");
    assert!(!stdout.contains("console at"), "{args:?}: the console started: {stdout}");
    stderr
}

#[test]
#[ignore = "needs the built dnet-master: run by scripts/check"]
fn refusals_before_the_bus() {
    let dir = scratch("console-auth-refusals");
    // An SLCAN port that does not exist: had the bus been touched, the error would name it.
    let bus = ["--bus", "slcan:/nonexistent/tty-console-auth", "ui", "--no-history", "--cycles", "1"];
    for listen in ["0.0.0.0:0", "[::]:0", "192.0.2.1:8080"] {
        let e = refused(&[&bus[..], &["--listen", listen]].concat());
        assert!(e.contains(&format!("--listen {listen}: expected a loopback address")), "{e}");
        assert!(e.contains("--users"), "{e}");
        assert!(!e.contains("tty-console-auth"), "the bus was touched: {e}");
    }
    let bad = dir.join("users.toml");
    std::fs::write(&bad, "[[user]]\nname = \"a\"\nrole = \"root\"\nhash = \"x\"\n").unwrap();
    let e = refused(&[&bus[..], &["--listen", "127.0.0.1:0", "--users", bad.to_str().unwrap()]].concat());
    assert!(e.contains(&format!("users file {}, line 3: unknown role `root`", bad.display())), "{e}");
    let pem = dir.join("not-a-cert.pem");
    std::fs::write(&pem, "hello\n").unwrap();
    let p = pem.to_str().unwrap();
    let e = refused(&[&bus[..], &["--listen", "127.0.0.1:0", "--tls-cert", p, "--tls-key", p]].concat());
    assert!(e.contains(&format!("TLS certificate {p}")), "{e}");
    let e = refused(&[&bus[..], &["--listen", "127.0.0.1:0", "--tls-cert", p]].concat());
    assert!(e.contains("--tls-key"), "{e}");
    // user add: an empty password and an unknown role are refused, nothing written.
    let file = dir.join("new-users.toml");
    let mut child = Command::new(bin("dnet-master"))
        .args(["user", "add", file.to_str().unwrap(), "ann", "--role", "viewer"])
        .stdin(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(b"\n").unwrap();
    let out = child.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no password"), "{out:?}");
    assert!(!file.exists());
    let e = refused(&["user", "add", file.to_str().unwrap(), "ann", "--role", "admin"]);
    assert!(e.contains("unknown role `admin`"), "{e}");
    // With --users every address is allowed; beyond loopback without TLS, with a warning.
    add_user(&file, "ann", "viewer", "annann");
    let list = dir.join("list.toml");
    std::fs::write(&list, "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n").unwrap();
    let out = Command::new(bin("dnet-master"))
        .args(["--bus", "sim", "ui", "--listen", "0.0.0.0:0", "--no-history", "--cycles", "3"])
        .args(["--users", file.to_str().unwrap(), "--scanlist", list.to_str().unwrap()])
        .output()
        .expect("dnet-master runs");
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(stdout.contains("console at http://0.0.0.0:"), "{stdout}\n{stderr}");
    assert!(stderr.contains("warning: the console listens beyond loopback without TLS"), "{stderr}");
    assert_eq!(out.status.code(), Some(0), "{stdout}\n{stderr}");
}

#[test]
#[ignore = "needs the built dnet-master and python3: run by scripts/check"]
fn the_console_over_tls_with_a_test_ca() {
    let dir = scratch("console-auth-tls");
    // A CA and a server certificate for 127.0.0.1 and localhost, made now (no key committed).
    let ca_key = rcgen::KeyPair::generate().unwrap();
    let mut ca_params = rcgen::CertificateParams::new(Vec::<String>::new()).unwrap();
    ca_params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
    ca_params.distinguished_name.push(rcgen::DnType::CommonName, "dnet-master test CA");
    let ca_cert = ca_params.self_signed(&ca_key).unwrap();
    let issuer = rcgen::Issuer::new(ca_params, ca_key);
    let key = rcgen::KeyPair::generate().unwrap();
    let params =
        rcgen::CertificateParams::new(vec!["127.0.0.1".to_string(), "localhost".to_string()]).unwrap();
    let cert = params.signed_by(&key, &issuer).unwrap();
    let (ca_pem, cert_pem, key_pem) = (dir.join("ca.pem"), dir.join("cert.pem"), dir.join("key.pem"));
    std::fs::write(&ca_pem, ca_cert.pem()).unwrap();
    std::fs::write(&cert_pem, cert.pem()).unwrap();
    std::fs::write(&key_pem, key.serialize_pem()).unwrap();
    let users = users_file(&dir);

    let (mut p, addr) = start_ui(
        "sim",
        &[
            "--users",
            users.to_str().unwrap(),
            "--tls-cert",
            cert_pem.to_str().unwrap(),
            "--tls-key",
            key_pem.to_str().unwrap(),
        ],
    );
    assert!(p.stdout.text().contains(&format!("console at https://{addr}/")), "{}", p.dump());
    // Python's ssl, trusting the test CA only: the page, a login (the cookie Secure), a state
    // read with the session, and a client that does not trust the CA refused.
    let script = r#"
import json, ssl, sys, urllib.request, urllib.error
base, ca = sys.argv[1], sys.argv[2]
ctx = ssl.create_default_context(cafile=ca)
page = urllib.request.urlopen(base, context=ctx).read().decode()
assert "dnet-master console" in page, page[:200]
req = urllib.request.Request(base + "api/login", data=json.dumps({"user": "otto", "password": "ottootto"}).encode(),
    headers={"Content-Type": "application/json", "Origin": base.rstrip("/")}, method="POST")
r = urllib.request.urlopen(req, context=ctx)
cookie = r.headers["Set-Cookie"]
assert cookie.endswith("; HttpOnly; SameSite=Strict; Path=/; Secure"), cookie
s = json.load(r)
assert s["role"] == "operator", s
state = json.load(urllib.request.urlopen(urllib.request.Request(base + "api/state",
    headers={"Cookie": cookie.split(";")[0]}), context=ctx))
assert state["ok"] is True, state
try:
    urllib.request.urlopen(base, context=ssl.create_default_context())
    sys.exit("a client without the test CA was served")
except urllib.error.URLError as e:
    assert "CERTIFICATE_VERIFY_FAILED" in str(e), e
print("tls ok", ssl.OPENSSL_VERSION)
"#;
    let out = Command::new("python3")
        .args(["-c", script, &format!("https://{addr}/"), ca_pem.to_str().unwrap()])
        .output()
        .expect("python3 runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("tls ok"),
        "{stdout}\n{}\n{}",
        String::from_utf8_lossy(&out.stderr),
        p.dump()
    );
    // Plain HTTP to the TLS port gets no HTTP answer.
    let mut s = TcpStream::connect(&addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.write_all(format!("GET /api/session HTTP/1.1\r\nHost: {addr}\r\n\r\n").as_bytes()).unwrap();
    let mut raw = Vec::new();
    let _ = s.read_to_end(&mut raw);
    assert!(!raw.starts_with(b"HTTP/1.1 200"), "plain HTTP was answered over the TLS port");
    assert!(p.running(), "{}", p.dump());
    stop_ui(&mut p, Duration::from_secs(20), "");
}
