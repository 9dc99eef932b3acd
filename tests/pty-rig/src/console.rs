//! The web console (`dnet-master ui`) as the system tests talk to it: raw HTTP/1.1 requests over
//! one TCP connection each (`Connection: close`, so the answer ends when the console closes), a
//! free loopback address to listen on, waiting until the console listens, and the page's CSRF
//! token.
//!
//! The requests are written by hand, not by an HTTP client crate, so that a test sends exactly
//! the bytes it means to (the headers of the console's page, or hostile ones) and sees the
//! status line as the console wrote it.

use crate::Proc;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::time::{Duration, Instant};

/// How long a request waits for the console's answer before the read fails.
const READ_TIMEOUT: Duration = Duration::from_secs(60);

/// The console's answer to [`request`]: the status code (0 when the status line has none), the
/// head (status line and header lines) and the body.
#[derive(Debug, Clone)]
pub struct Reply {
    /// The status code of the status line; 0 when it has none.
    pub status: u16,
    /// The status line and the header lines, without the blank line.
    pub head: String,
    /// Everything after the blank line.
    pub body: String,
}

/// Sends `text` (a whole request) to `addr` on a new connection and reads until the console
/// closes it. Panics when the console cannot be reached or does not answer within a minute.
fn exchange(addr: &str, text: &str) -> Reply {
    let mut s = TcpStream::connect(addr).unwrap_or_else(|e| panic!("connect to the console at {addr}: {e}"));
    s.set_read_timeout(Some(READ_TIMEOUT)).unwrap();
    s.write_all(text.as_bytes()).unwrap_or_else(|e| panic!("send to the console at {addr}: {e}"));
    let mut answer = String::new();
    s.read_to_string(&mut answer).unwrap_or_else(|e| panic!("the console's answer at {addr}: {e}"));
    let (head, body) = answer.split_once("\r\n\r\n").unwrap_or((&answer, ""));
    let status = head.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    Reply { status, head: head.to_string(), body: body.to_string() }
}

/// One request with the header lines `headers` (each ending in `\r\n`, may be empty) and `body`:
/// `METHOD PATH HTTP/1.1`, `Host`, `Connection: close`, `headers`, `Content-Length`.
pub fn request(addr: &str, method: &str, path: &str, headers: &str, body: &str) -> Reply {
    exchange(
        addr,
        &format!(
            "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n{headers}Content-Length: {}\r\n\r\n{body}",
            body.len()
        ),
    )
}

/// One request as the console's page sends it: with `token`, the page's own `Origin`, JSON,
/// `X-CSRF-Token` and `body`; without, a bare request (no body, no `Content-Length`). Status and
/// body.
pub fn http(addr: &str, method: &str, path: &str, token: Option<&str>, body: &str) -> (u16, String) {
    let mut text = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    if let Some(t) = token {
        text.push_str(&format!(
            "Origin: http://{addr}\r\nContent-Type: application/json\r\nX-CSRF-Token: {t}\r\nContent-Length: {}\r\n\r\n{body}",
            body.len()
        ));
    } else {
        text.push_str("\r\n");
    }
    let r = exchange(addr, &text);
    (r.status, r.body)
}

/// `GET path` without a session or token: status and body.
pub fn get(addr: &str, path: &str) -> (u16, String) {
    http(addr, "GET", path, None, "")
}

/// The CSRF token of the console's page (`GET /`, its `csrf-token` meta tag). Panics, showing
/// the page, when it has none.
pub fn csrf_token(addr: &str) -> String {
    let (status, page) = get(addr, "/");
    page.split("name=\"csrf-token\" content=\"")
        .nth(1)
        .and_then(|t| t.split('"').next())
        .unwrap_or_else(|| panic!("no csrf-token in the page (status {status}):\n{page}"))
        .to_string()
}

/// A loopback address with a port that was free a moment ago (the system's choice), as
/// `127.0.0.1:PORT`.
pub fn free_addr() -> String {
    format!("127.0.0.1:{}", free_port())
}

/// A loopback port that was free a moment ago (the system's choice).
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// Waits until something accepts connections at `addr`, trying every 100 ms; after `limit`,
/// panics with `dump()` (the programs' output).
pub fn wait_listening(addr: &str, limit: Duration, dump: impl Fn() -> String) {
    let end = Instant::now() + limit;
    while TcpStream::connect(addr).is_err() {
        assert!(Instant::now() < end, "nothing listens at {addr} within {limit:?}\n{}", dump());
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Stops `dnet-master ui` with SIGINT and checks that it ended as `ui` does on an interrupt
/// (exit status 130) within `limit` and that it did not panic; `extra` (other programs' output)
/// is shown with its own when either fails.
pub fn stop_ui(p: &mut Proc, limit: Duration, extra: &str) {
    p.signal("INT");
    assert_eq!(p.wait(limit).and_then(|s| s.code()), Some(130), "{}\n{extra}", p.dump());
    assert!(!p.stderr.text().contains("panicked"), "a panic:\n{}", p.dump());
}

/// Starts `dnet-master GLOBAL ui --listen ADDR EXTRA` on a free loopback address and waits
/// until it listens (at most `limit`; else panics with its output and `also()`, the other
/// programs' output): the process and ADDR.
pub fn spawn_ui(
    global: &[&str],
    extra: &[&str],
    limit: Duration,
    also: impl Fn() -> String,
) -> (Proc, String) {
    let addr = free_addr();
    let args: Vec<&str> = [global, &["ui", "--listen", &addr], extra].concat();
    let ui = Proc::spawn(crate::bin("dnet-master"), &args);
    wait_listening(&addr, limit, || format!("{}\n{}", ui.dump(), also()));
    (ui, addr)
}

/// Adds `name` with `role` and `password` to the users file `file` with `dnet-master user add`
/// (the password on its standard input, as an operator types it); panics with its standard
/// error when it fails.
pub fn add_user(file: &std::path::Path, name: &str, role: &str, password: &str) {
    use std::process::{Command, Stdio};
    let mut child = Command::new(crate::bin("dnet-master"))
        .args(["user", "add", &file.to_string_lossy(), name, "--role", role])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("dnet-master runs");
    child
        .stdin
        .take()
        .expect("user add's stdin")
        .write_all(format!("{password}\n").as_bytes())
        .expect("user add reads the password");
    let out = child.wait_with_output().expect("user add ends");
    assert!(out.status.success(), "user add {name}: {}", String::from_utf8_lossy(&out.stderr));
}

/// The console's URL (`http://HOST:PORT/`, or `https://…` with TLS) from `dnet-master ui`'s
/// `console at URL` line, waiting for that line at most `limit` (then panics with the output).
pub fn console_url(p: &Proc, limit: Duration) -> String {
    let end = Instant::now() + limit;
    loop {
        let url =
            p.stdout.lines().iter().find_map(|l| l.strip_prefix("console at ").map(|u| u.trim().to_string()));
        if let Some(url) = url {
            return url;
        }
        assert!(Instant::now() < end, "no console address within {limit:?}\n{}", p.dump());
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The `HOST:PORT` of [`console_url`].
pub fn console_addr(p: &Proc, limit: Duration) -> String {
    let url = console_url(p, limit);
    let rest = url.split_once("://").map_or(url.as_str(), |(_, rest)| rest);
    rest.trim_end_matches('/').to_string()
}
