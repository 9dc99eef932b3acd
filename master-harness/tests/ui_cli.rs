//! `dnet-master ui`'s bad input and unavailable parts, through the program: an address in use, a
//! history that cannot be opened and a malformed broker URL are refused before the bus is touched
//! (exit 2, the thing named); a broker that is down is not an error: the scanner scans to the end.

use pty_rig::{console, scratch};
use std::process::{Command, Output};

fn dnet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dnet-master")).args(args).output().expect("run dnet-master")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

#[test]
fn an_address_in_use_is_refused_and_named() {
    let taken = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let dir = scratch("in-use");
    let history = dir.join("h.sqlite");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        &addr,
        "--history",
        history.to_str().unwrap(),
        "--cycles",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains(&format!("cannot listen on {addr}")), "{}", text(&o));
}

#[test]
fn a_history_that_cannot_be_opened_is_refused_and_named() {
    let o =
        dnet(&["--bus", "sim", "ui", "--listen", "127.0.0.1:0", "--history", "/nonexistent/dir/h.sqlite"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("/nonexistent/dir/h.sqlite"), "{}", text(&o));
    let dir = scratch("not-a-db");
    let bogus = dir.join("notes.sqlite");
    std::fs::write(&bogus, "these are not a database, just text long enough to be read as a header").unwrap();
    let o = dnet(&["--bus", "sim", "ui", "--listen", "127.0.0.1:0", "--history", bogus.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("is not an SQLite database"), "{}", text(&o));
}

#[test]
fn a_malformed_broker_url_is_refused() {
    let dir = scratch("bad-url");
    let history = dir.join("h.sqlite");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        history.to_str().unwrap(),
        "--mqtt",
        "http://x",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--mqtt http://x"), "{}", text(&o));
}

#[test]
fn a_broker_that_is_down_does_not_stop_the_scanner() {
    // Nothing listens on a port just released.
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let dir = scratch("broker-down");
    let history = dir.join("h.sqlite");
    let url = format!("mqtt://127.0.0.1:{port}");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        history.to_str().unwrap(),
        "--mqtt",
        &url,
        "--cycles",
        "30",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.starts_with("console at http://127.0.0.1:"), "{out}");
    assert!(out.contains("  5  ok"), "node 5 kept in I/O: {out}");
    assert!(out.contains("30 cycle(s)"), "{out}");
}

#[test]
fn a_run_that_exchanged_nothing_is_not_a_success() {
    // --cycles 0: the node is allocated but no poll was answered yet: exit 1, as scanner.
    let dir = scratch("no-cycles");
    let history = dir.join("h.sqlite");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        history.to_str().unwrap(),
        "--cycles",
        "0",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("initializing"), "{}", text(&o));
}

/// `dnet-master --bus sim --slave-mac 5 ui` running, its console's address read from its first
/// line; SIGINT and a wait when dropped.
struct Running {
    child: std::process::Child,
    addr: String,
}

impl Running {
    fn start(name: &str) -> Running {
        use std::io::BufRead;
        let dir = scratch(name);
        let history = dir.join("h.sqlite");
        let mut child = Command::new(env!("CARGO_BIN_EXE_dnet-master"))
            .args(["--bus", "sim", "--slave-mac", "5", "ui", "--listen", "127.0.0.1:0", "--history"])
            .arg(&history)
            .arg("--record-dir")
            .arg(&dir)
            .stdin(std::process::Stdio::null())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("run dnet-master ui");
        let mut line = String::new();
        std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        let addr = line
            .trim()
            .strip_prefix("console at http://")
            .and_then(|a| a.strip_suffix('/'))
            .unwrap_or_else(|| panic!("no console address: {line:?}"))
            .to_string();
        let running = Running { child, addr };
        running.until("node 5 ok", |r| {
            r.get("/api/state").1.contains(r#""mac":5"#) && r.node5().contains(r#""status":"ok""#)
        });
        running
    }

    /// One request with exactly `headers` (besides Host, Content-Length and Connection).
    fn request(&self, method: &str, path: &str, headers: &[(&str, &str)], body: &str) -> (u16, String) {
        let extra: String = headers.iter().map(|(k, v)| format!("{k}: {v}\r\n")).collect();
        let reply = console::request(&self.addr, method, path, &extra, body);
        (reply.status, reply.body)
    }

    fn get(&self, path: &str) -> (u16, String) {
        self.request("GET", path, &[], "")
    }

    fn node5(&self) -> String {
        self.get("/api/node/5").1
    }

    fn token(&self) -> String {
        console::csrf_token(&self.addr)
    }

    fn threads(&self) -> usize {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).unwrap();
        status
            .lines()
            .find_map(|l| l.strip_prefix("Threads:"))
            .and_then(|n| n.trim().parse().ok())
            .expect("Threads: in /proc/PID/status")
    }

    fn until(&self, what: &str, f: impl Fn(&Running) -> bool) {
        let start = std::time::Instant::now();
        while !f(self) {
            assert!(start.elapsed() < std::time::Duration::from_secs(30), "{what}: not within 30 s");
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        let _ = Command::new("kill").args(["-INT", &self.child.id().to_string()]).status();
        let _ = self.child.wait();
    }
}

#[test]
fn another_site_cannot_drive_the_console() {
    let ui = Running::start("csrf");
    let token = ui.token();
    let own = format!("http://{}", ui.addr);
    let json_type = ("Content-Type", "application/json");
    let hostile: Vec<(&str, Vec<(&str, &str)>)> = vec![
        // What a page of another site sends with fetch(..., {method: "POST", mode: "no-cors"}).
        ("a form of another site", vec![("Origin", "http://evil.example"), ("Content-Type", "text/plain")]),
        ("no token", vec![("Origin", own.as_str()), json_type]),
        (
            "a wrong token",
            vec![("Origin", own.as_str()), json_type, ("X-CSRF-Token", "00000000000000000000000000000000")],
        ),
        (
            "another origin",
            vec![("Origin", "http://evil.example"), json_type, ("X-CSRF-Token", token.as_str())],
        ),
        ("no origin", vec![json_type, ("X-CSRF-Token", token.as_str())]),
        (
            "a form's type",
            vec![
                ("Origin", own.as_str()),
                ("Content-Type", "multipart/form-data; boundary=x"),
                ("X-CSRF-Token", token.as_str()),
            ],
        ),
    ];
    for (what, headers) in &hostile {
        let (status, body) = ui.request("POST", "/api/node/5/breaker/close", headers, "");
        assert_eq!(status, 403, "{what}: {body}");
        assert!(body.contains(r#""ok":false"#), "{what}: {body}");
    }
    // The breaker stayed open: nothing was put in its output image.
    std::thread::sleep(std::time::Duration::from_millis(500));
    assert!(ui.node5().contains(r#""output_hex":"0000000000000000""#), "{}", ui.node5());
    // The console's own page closes it.
    let own_headers = [("Origin", own.as_str()), json_type, ("X-CSRF-Token", token.as_str())];
    let (status, body) = ui.request("POST", "/api/node/5/breaker/close", &own_headers, "");
    assert_eq!(status, 200, "{body}");
    ui.until("the switch closed", |r| r.node5().contains(r#""text":"closed""#));
}

#[test]
fn idle_connections_take_no_thread_each_and_beyond_the_bound_get_503() {
    let ui = Running::start("bound");
    let before = ui.threads();
    let idle: Vec<std::net::TcpStream> =
        (0..300).map(|_| std::net::TcpStream::connect(&ui.addr).unwrap()).collect();
    // Every connection accepted (the last one answered below), then the threads counted.
    let mut last = idle.last().unwrap().try_clone().unwrap();
    last.set_read_timeout(Some(std::time::Duration::from_secs(20))).unwrap();
    let mut answer = String::new();
    let _ = std::io::Read::read_to_string(&mut last, &mut answer);
    assert!(answer.starts_with("HTTP/1.1 503"), "beyond the bound: {answer:?}");
    assert!(answer.contains("the console is busy"), "{answer}");
    let during = ui.threads();
    assert!(during <= before + 2, "{before} threads before 300 idle connections, {during} with them");
    drop(idle);
    // Once they are gone the console answers again.
    ui.until("the console answers again", |r| r.get("/api/state").0 == 200);
}

#[test]
fn a_record_directory_that_does_not_exist_is_refused_not_created() {
    let dir = scratch("record-dir");
    let missing = dir.join("no-such-dir");
    let _ = std::fs::remove_dir_all(&missing);
    let history = dir.join("h.sqlite");
    let o = dnet(&[
        "--bus",
        "sim",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        history.to_str().unwrap(),
        "--record-dir",
        missing.to_str().unwrap(),
        "--cycles",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains(&format!("--record-dir {}: no such directory", missing.display())),
        "{}",
        text(&o)
    );
    assert!(!missing.exists(), "{} was created", missing.display());
}

#[test]
fn the_console_s_history_drops_old_samples_and_thins_the_older_than_six_hours() {
    use dnet_scanner::history::History;
    use dnet_scanner::model::{unix_ms_now, HistoryStore, Sample};
    let dir = scratch("retention");
    let path = dir.join("h.sqlite");
    let _ = std::fs::remove_file(&path);
    let now = unix_ms_now();
    let at = |unix_ms: i64| Sample { mac: 5, unix_ms, bus_us: 0, input: vec![1, 2, 3], values: vec![] };
    {
        // A history that ran before: ten minutes at one sample a second seven hours ago, and a
        // few samples 31 days ago.
        let h = History::open(&path).unwrap();
        let seven_hours_ago = now - 7 * 3_600_000;
        h.record(&(0..600).map(|s| at(seven_hours_ago + s * 1000)).collect::<Vec<_>>()).unwrap();
        h.record(&(0..5).map(|s| at(now - 31 * 24 * 3_600_000 + s * 1000)).collect::<Vec<_>>()).unwrap();
    }
    let o = dnet(&[
        "--bus",
        "sim",
        "--slave-mac",
        "5",
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--history",
        path.to_str().unwrap(),
        "--record-dir",
        dir.to_str().unwrap(),
        "--cycles",
        "20",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let h = History::open(&path).unwrap();
    let old = h.samples(5, 0, now - 30 * 24 * 3_600_000, 100).unwrap();
    assert!(old.is_empty(), "samples older than 30 days kept: {}", old.len());
    let thinned = h.samples(5, now - 8 * 3_600_000, now - 6 * 3_600_000, 10_000).unwrap();
    assert!(
        (10..=11).contains(&thinned.len()),
        "ten minutes seven hours ago: one sample a minute, {} kept",
        thinned.len()
    );
    assert!(!h.samples(5, now - 60_000, i64::MAX, 10).unwrap().is_empty(), "this run's samples kept");
}
