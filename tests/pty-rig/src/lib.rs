//! # pty-rig
//!
//! Test equipment for system tests on the real serial paths, shared by the soft slave's tests and
//! the bench master's field tests: socat pseudo-terminal pairs ([`PtyPair`]), child processes that
//! are stopped by signal and whose output is collected ([`Proc`]), and the whole bench
//! ([`PtyRig`]): an instrument process on one pty pair (`dnet-sim-breaker`, or a pymodbus RTU
//! slave), `dnet-soft-slave` between that pair and a second pair that carries SLCAN, and the
//! master at the far end of the second pair. Two SLCAN endpoints joined back to back are a two-node
//! CAN link: each side's transmit lines arrive as the other's receive lines; set-up commands are
//! ignored.
//!
//! The system tests of the web console and the plant interfaces share their helpers here too:
//! [`console`] (raw HTTP/1.1 to `dnet-master ui`, a free loopback address, waiting until it
//! listens, the page's CSRF token, starting and stopping the console), [`browser`] (a script of
//! `tests/browser/` driving chromium), [`mqtt`] (a mosquitto of the test's own) and
//! [`sparkplug`] (the independent Sparkplug B host on pysparkplug); the Modbus tests share
//! [`pymodbus`] (a pymodbus server as the instrument, the gateway description, the monitor run),
//! the multi-network tests [`plant`] (a plant file, two breaker benches).
//!
//! The programs are found with [`bin`]: next to the test executable (`target/<profile>/`), or in
//! `DNET_BIN_DIR`.
//!
//! A missing tool (socat, the Python virtual environment) skips a test with a message, except in CI
//! (`CI=true`), where it fails.

pub mod browser;
pub mod console;
pub mod mqtt;
pub mod plant;
pub mod pymodbus;
pub mod qemu;
pub mod sparkplug;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::sync::{Arc, Mutex};

/// The workspace root.
pub fn workspace_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..").canonicalize().expect("the workspace folder")
}

/// A fresh scratch folder for one test.
pub fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("rig-{}-{test}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `true` in CI (`CI=true`): a missing tool is a failure there, not a skip.
pub fn in_ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v == "true" || v == "1")
}

/// Returns `false` (after saying why) when `what` is missing and the test may skip; panics in CI.
fn available(ok: bool, what: &str, how: &str) -> bool {
    if ok {
        return true;
    }
    if in_ci() {
        panic!("{what} is missing, and CI=true: {how}");
    }
    eprintln!("SKIPPED: {what} is missing ({how})");
    false
}

/// Whether `socat` can be run.
pub fn require_socat() -> bool {
    let ok = Command::new("socat").arg("-V").stdout(Stdio::null()).stderr(Stdio::null()).status().is_ok();
    available(ok, "socat", "apt-get install socat, or run ./scripts/check")
}

/// The Python of the test virtual environment with pymodbus and pyserial: `DNET_PYTHON`, else
/// `.venv/bin/python` in the workspace.
pub fn require_pymodbus() -> Option<PathBuf> {
    let python = std::env::var_os("DNET_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_dir().join(".venv/bin/python"));
    let ok = Command::new(&python)
        .args(["-c", "import pymodbus, serial"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    let how = format!(
        "{} cannot import pymodbus and serial; run ./scripts/check, or python3 -m venv .venv && .venv/bin/pip install pymodbus==3.16.1 pyserial==3.5",
        python.display()
    );
    available(ok, "the pymodbus virtual environment", &how).then_some(python)
}

/// Lines a child wrote, collected by a thread.
#[derive(Clone, Default)]
pub struct Output(Arc<Mutex<Vec<String>>>);

impl Output {
    fn collect(stream: impl Read + Send + 'static) -> (Output, Receiver<String>) {
        let out = Output::default();
        let lines = Arc::clone(&out.0);
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stream).lines().map_while(Result::ok) {
                lines.lock().unwrap().push(line.clone());
                let _ = tx.send(line);
            }
        });
        (out, rx)
    }

    /// Every line read so far, joined with newlines.
    pub fn text(&self) -> String {
        self.0.lock().unwrap().join("\n")
    }

    /// Every line read so far.
    pub fn lines(&self) -> Vec<String> {
        self.0.lock().unwrap().clone()
    }
}

/// A child process, stopped by its own id when dropped.
pub struct Proc {
    name: String,
    child: Option<Child>,
    /// What the process wrote to its standard output.
    pub stdout: Output,
    /// What the process wrote to its standard error.
    pub stderr: Output,
    stdout_lines: Receiver<String>,
}

impl Proc {
    /// Starts `program` with `args`, its standard input empty and its outputs collected; panics
    /// (test code) when it cannot be started.
    pub fn spawn(program: impl AsRef<Path>, args: &[&str]) -> Proc {
        let program = program.as_ref();
        let mut child = Command::new(program)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot run {}: {e}", program.display()));
        let (stdout, stdout_lines) = Output::collect(child.stdout.take().unwrap());
        let (stderr, _) = Output::collect(child.stderr.take().unwrap());
        let name = program.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        Proc { name, child: Some(child), stdout, stderr, stdout_lines }
    }

    /// Waits up to `timeout` for a stdout line containing `needle`.
    pub fn wait_stdout(&self, needle: &str, timeout: std::time::Duration) -> Option<String> {
        let end = std::time::Instant::now() + timeout;
        loop {
            let left = end.saturating_duration_since(std::time::Instant::now());
            match self.stdout_lines.recv_timeout(left) {
                Ok(line) if line.contains(needle) => return Some(line),
                Ok(_) => {}
                Err(_) => return None,
            }
        }
    }

    /// Still running?
    pub fn running(&mut self) -> bool {
        self.child.as_mut().is_some_and(|c| c.try_wait().ok().flatten().is_none())
    }

    /// Sends `signal` (`"INT"`, `"TERM"`, ...) and leaves the process running.
    pub fn signal(&self, signal: &str) {
        if let Some(child) = &self.child {
            let _ = Command::new("kill").args([&format!("-{signal}"), &child.id().to_string()]).status();
        }
    }

    /// Waits up to `timeout` for the process to end; its exit status, or `None` while it still
    /// runs (it is left running).
    pub fn wait(&mut self, timeout: std::time::Duration) -> Option<ExitStatus> {
        let end = std::time::Instant::now() + timeout;
        let child = self.child.as_mut()?;
        loop {
            if let Ok(Some(status)) = child.try_wait() {
                // Let the collector threads take the last lines.
                std::thread::sleep(std::time::Duration::from_millis(50));
                self.child = None;
                return Some(status);
            }
            if std::time::Instant::now() >= end {
                return None;
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
    }

    /// SIGTERM, then the exit status (SIGKILL after 5 s).
    pub fn terminate(&mut self) -> Option<ExitStatus> {
        let mut child = self.child.take()?;
        let _ = Command::new("kill").args(["-TERM", &child.id().to_string()]).status();
        let end = std::time::Instant::now() + std::time::Duration::from_secs(5);
        while std::time::Instant::now() < end {
            if let Ok(Some(status)) = child.try_wait() {
                // Let the collector threads take the last lines.
                std::thread::sleep(std::time::Duration::from_millis(50));
                return Some(status);
            }
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        let _ = child.kill();
        let status = child.wait().ok();
        eprintln!("{} did not stop on SIGTERM within 5 s", self.name);
        status
    }

    /// What it printed, for failure messages.
    pub fn dump(&self) -> String {
        format!(
            "--- {} stdout:\n{}\n--- {} stderr:\n{}",
            self.name,
            self.stdout.text(),
            self.name,
            self.stderr.text()
        )
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// A pseudo-terminal pair joined by socat (`pty,raw,echo=0` on both sides).
pub struct PtyPair {
    socat: Proc,
    /// One end.
    pub a: String,
    /// The other end.
    pub b: String,
}

impl Default for PtyPair {
    fn default() -> Self {
        PtyPair::new()
    }
}

impl PtyPair {
    /// Starts socat and waits until it reports both ends.
    pub fn new() -> PtyPair {
        let mut child = Command::new("socat")
            .args(["-d", "-d", "pty,raw,echo=0", "pty,raw,echo=0"])
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run socat");
        let (stderr, lines) = Output::collect(child.stderr.take().unwrap());
        let socat = Proc {
            name: "socat".into(),
            child: Some(child),
            stdout: Output::default(),
            stderr,
            stdout_lines: mpsc::channel().1,
        };
        let mut ptys = Vec::new();
        let end = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while ptys.len() < 2 || !socat.stderr.text().contains("starting data transfer loop") {
            let left = end.saturating_duration_since(std::time::Instant::now());
            match lines.recv_timeout(left) {
                Ok(line) => {
                    if let Some((_, path)) = line.split_once("PTY is ") {
                        ptys.push(path.trim().to_string());
                    }
                }
                Err(_) => panic!("socat did not report two ptys:\n{}", socat.stderr.text()),
            }
        }
        PtyPair { b: ptys.pop().unwrap(), a: ptys.pop().unwrap(), socat }
    }
}

impl Drop for PtyPair {
    fn drop(&mut self) {
        self.socat.terminate();
    }
}

/// The path of one of the workspace's programs (`dnet-soft-slave`, `dnet-sim-breaker`,
/// `dnet-master`): in `DNET_BIN_DIR` when set, else next to the test executable
/// (`target/<profile>/deps/test-HASH` → `target/<profile>/NAME`). Panics, saying how to build it,
/// when it is not there.
pub fn bin(name: &str) -> PathBuf {
    let dir = match std::env::var_os("DNET_BIN_DIR") {
        Some(d) => PathBuf::from(d),
        None => {
            let exe = std::env::current_exe().expect("the test executable's path");
            let deps = exe.parent().expect("the test executable's folder");
            deps.parent().unwrap_or(deps).to_path_buf()
        }
    };
    let path = dir.join(name);
    assert!(
        path.is_file(),
        "{} is not built: cargo build -p soft-slave -p master-harness (scripts/check does), or set DNET_BIN_DIR",
        path.display()
    );
    path
}

/// `dnet-soft-slave` on SLCAN at `can.a`, its instrument at `serial` (a pty end or
/// `tcp:HOST:PORT`), described by `config`.
pub fn soft_slave(can: &PtyPair, serial: &str, config: &Path) -> Proc {
    let bus = format!("slcan:{}", can.a);
    Proc::spawn(
        bin("dnet-soft-slave"),
        &["--bus", &bus, "--serial", serial, "--config", config.to_str().unwrap()],
    )
}

/// The bench on pseudo-terminals: an instrument process on the `serial` pair, `dnet-soft-slave`
/// between it and the `can` pair (SLCAN on its end `can.a`); the master uses `can.b`.
pub struct PtyRig {
    /// The test's scratch folder (logs of every process).
    pub dir: PathBuf,
    /// The instrument's serial line.
    pub serial: PtyPair,
    /// The CAN link: SLCAN at both ends.
    pub can: PtyPair,
    /// The instrument process.
    pub instrument: Proc,
    /// The soft slave, while it runs.
    pub slave: Option<Proc>,
}

impl PtyRig {
    /// The simulated breaker with `args`, then the soft slave with `config` (None: built-in).
    pub fn breaker(test: &str, args: &[&str], config: Option<&Path>) -> PtyRig {
        PtyRig::breaker_with(test, args, config, &[])
    }

    /// [`PtyRig::breaker`], the soft slave started with `extra` arguments from the first (a
    /// restarted soft slave may leave frames of its first run in the pty).
    pub fn breaker_with(test: &str, args: &[&str], config: Option<&Path>, extra: &[&str]) -> PtyRig {
        let dir = scratch(test);
        let serial = PtyPair::new();
        let log = dir.join("breaker.log");
        let mut all = vec!["--serial", serial.a.as_str(), "--log", log.to_str().unwrap()];
        all.extend_from_slice(args);
        let instrument = Proc::spawn(bin("dnet-sim-breaker"), &all);
        let can = PtyPair::new();
        let mut rig = PtyRig { dir, serial, can, instrument, slave: None };
        rig.start_slave_with(config, extra);
        rig
    }

    /// tests/modbus/server.py on the serial pty, then the soft slave with `config`.
    pub fn modbus(test: &str, python: &Path, config: &Path) -> PtyRig {
        let dir = scratch(test);
        let serial = PtyPair::new();
        let script = workspace_dir().join("slave-fw/soft-slave/tests/modbus/server.py");
        let instrument =
            Proc::spawn(python, &[script.to_str().unwrap(), "--port", &serial.a, "--baud", "19200"]);
        if instrument.wait_stdout("ready", std::time::Duration::from_secs(20)).is_none() {
            panic!("the Modbus server did not start:\n{}", instrument.dump());
        }
        PtyRig::with_instrument(dir, serial, instrument, Some(config))
    }

    fn with_instrument(dir: PathBuf, serial: PtyPair, instrument: Proc, config: Option<&Path>) -> PtyRig {
        let can = PtyPair::new();
        let mut rig = PtyRig { dir, serial, can, instrument, slave: None };
        rig.start_slave(config);
        rig
    }

    /// Starts dnet-soft-slave (again), logging to `can.log` in the scratch folder.
    pub fn start_slave(&mut self, config: Option<&Path>) {
        self.start_slave_with(config, &[]);
    }

    /// Starts dnet-soft-slave (again) with `extra` arguments (`--state FILE`, `--mac N`).
    pub fn start_slave_with(&mut self, config: Option<&Path>, extra: &[&str]) {
        let bus = format!("slcan:{}", self.can.a);
        let log = self.dir.join("can.log");
        let mut args =
            vec!["--bus", bus.as_str(), "--serial", self.serial.b.as_str(), "--log", log.to_str().unwrap()];
        if let Some(c) = config {
            args.extend_from_slice(&["--config", c.to_str().unwrap()]);
        }
        args.extend_from_slice(extra);
        let slave = Proc::spawn(bin("dnet-soft-slave"), &args);
        // Ready (its signal handler installed, the bus open) once it reports the start: a stop or
        // a master before that would race its start-up.
        let end = std::time::Instant::now() + std::time::Duration::from_secs(10);
        while !slave.stderr.text().contains("started on") && std::time::Instant::now() < end {
            std::thread::sleep(std::time::Duration::from_millis(10));
        }
        self.slave = Some(slave);
    }

    /// The master's end of the CAN link, as a `--bus` argument.
    pub fn master_bus_arg(&self) -> String {
        format!("slcan:{}", self.can.b)
    }

    /// The breaker's event log.
    pub fn breaker_log(&self) -> String {
        std::fs::read_to_string(self.dir.join("breaker.log")).unwrap_or_default()
    }

    /// Waits up to `timeout` for the breaker's event log to contain `needle`; whether it does.
    pub fn wait_breaker_log(&self, needle: &str, timeout: std::time::Duration) -> bool {
        let end = std::time::Instant::now() + timeout;
        while !self.breaker_log().contains(needle) {
            if std::time::Instant::now() >= end {
                return false;
            }
            std::thread::sleep(std::time::Duration::from_millis(200));
        }
        true
    }

    /// Stops the soft slave with SIGTERM: it must exit 0 and report its run.
    pub fn stop_slave(&mut self) -> String {
        let mut slave = self.slave.take().expect("a running soft slave");
        let status = slave.terminate();
        assert_eq!(status.and_then(|s| s.code()), Some(0), "clean stop on SIGTERM\n{}", slave.dump());
        let stderr = slave.stderr.text();
        assert!(stderr.contains("dnet-soft-slave: stopped after"), "{stderr}");
        stderr
    }

    /// Everything the processes printed (for failure messages).
    pub fn dump(&self) -> String {
        let slave = self.slave.as_ref().map(Proc::dump).unwrap_or_default();
        format!("{slave}\n{}\n--- breaker log:\n{}", self.instrument.dump(), self.breaker_log())
    }
}
