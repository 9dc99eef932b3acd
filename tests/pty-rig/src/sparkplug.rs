//! The independent Sparkplug B host of the Sparkplug system tests (the broker is
//! [`crate::mqtt::Mosquitto`]): `tests/python/sparkplug_host.py` on PyPI's pysparkplug
//! ([`Host`]), which prints each message it decodes as one JSON line and takes commands
//! (Rebirth, DCMD) as JSON lines on its standard input.
//!
//! A missing pysparkplug is a failure, not a skip: these tests are run on purpose
//! (`-- --ignored`).

use crate::workspace_dir;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

/// The Python with pysparkplug: `DNET_PYTHON`, else the workspace's `.venv/bin/python`. Panics
/// when it cannot import pysparkplug.
pub fn python() -> PathBuf {
    let python = std::env::var_os("DNET_PYTHON")
        .map_or_else(|| workspace_dir().join(".venv/bin/python"), PathBuf::from);
    let ok = Command::new(&python).args(["-c", "import pysparkplug"]).status().is_ok_and(|s| s.success());
    assert!(ok, "{} cannot import pysparkplug: .venv/bin/pip install pysparkplug==0.6.1", python.display());
    python
}

/// The host application, subscribed to one Sparkplug group: its decoded messages as JSON values,
/// and its standard input for commands. Killed when dropped.
#[derive(Debug)]
pub struct Host {
    child: Child,
    stdin: ChildStdin,
    /// The messages not taken yet, in the order the host printed them. A line that is not JSON
    /// arrives as `{"error": ...}`.
    pub rx: Receiver<Value>,
    /// Every message taken so far, in order.
    pub seen: Vec<Value>,
}

impl Host {
    /// Starts the host for `group` on the broker at `127.0.0.1:port` (over TLS with the CA
    /// `ca`) and waits (20 s at most) until it says it is connected.
    pub fn start(port: u16, group: &str, ca: Option<&Path>) -> Host {
        let script = workspace_dir().join("tests/python/sparkplug_host.py");
        let mut cmd = Command::new(python());
        cmd.arg(script).arg("127.0.0.1").arg(port.to_string()).arg(group);
        if let Some(ca) = ca {
            cmd.arg("--ca").arg(ca);
        }
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("the Sparkplug host starts");
        let stdin = child.stdin.take().expect("the host's stdin");
        let stdout = child.stdout.take().expect("the host's stdout");
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let v = serde_json::from_str::<Value>(&line)
                    .unwrap_or_else(|e| json!({"error": format!("not JSON ({e}): {line}")}));
                let _ = tx.send(v);
            }
        });
        let mut host = Host { child, stdin, rx, seen: Vec::new() };
        host.next(Duration::from_secs(20), "the host connected", |v| v["ready"] == true);
        host
    }

    /// The next message (after those already taken) that `want` accepts, within `limit`; panics
    /// naming `what` with every message seen when none does, or when the host could not decode
    /// one.
    pub fn next(&mut self, limit: Duration, what: &str, want: impl Fn(&Value) -> bool) -> Value {
        let until = Instant::now() + limit;
        loop {
            match self.rx.recv_timeout(until.saturating_duration_since(Instant::now())) {
                Ok(v) => {
                    self.seen.push(v.clone());
                    assert!(v.get("error").is_none(), "the host could not decode: {v}");
                    if want(&v) {
                        return v;
                    }
                }
                Err(_) => panic!("{what}: not within {limit:?}; the host saw:\n{}", self.dump()),
            }
        }
    }

    /// A message already taken that `want` accepts, else [`Host::next`].
    pub fn seen_or_next(&mut self, limit: Duration, what: &str, want: impl Fn(&Value) -> bool) -> Value {
        match self.seen.iter().find(|v| want(v)) {
            Some(v) => v.clone(),
            None => self.next(limit, what, want),
        }
    }

    /// Sends one command line (JSON) to the host.
    pub fn send(&mut self, command: &Value) {
        writeln!(self.stdin, "{command}").expect("the host takes a command");
        self.stdin.flush().expect("the host takes a command");
    }

    /// Every message taken so far, one JSON line each.
    pub fn dump(&self) -> String {
        self.seen.iter().map(Value::to_string).collect::<Vec<_>>().join("\n")
    }
}

impl Drop for Host {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A plain mosquitto of its own (configuration in `dir`) on a free loopback port and the host
/// for `group` connected to it: the broker, the host and the broker's URL (`mqtt://…`). Bind
/// them in this order so that the host is dropped (killed) before the broker.
pub fn broker_and_host(dir: &Path, group: &str) -> (crate::mqtt::Mosquitto, Host, String) {
    let port = crate::console::free_port();
    let broker = crate::mqtt::Mosquitto::start(dir, port, None);
    let host = Host::start(port, group, None);
    (broker, host, format!("mqtt://127.0.0.1:{port}"))
}
