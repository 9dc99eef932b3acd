//! The harness and the soft slave over real SocketCAN, with the standard Linux CAN tools.
//!
//! These tests need a `vcan0` interface and root (to take it down and up), can-utils, tshark and
//! socat, so they are `#[ignore]`d in ordinary runs. `scripts/vcan-tests` builds everything on the
//! host and runs them through `scripts/canvm-run`: inside a small Linux guest with vcan when the
//! host kernel has no CAN support, natively when it has. Each test is a real bench session:
//!
//! - the simulated breaker (`dnet-sim-breaker`) serves one end of a socat pty pair, the soft slave
//!   (`dnet-soft-slave --bus socketcan:vcan0 --serial PTY`) the other;
//! - `dnet-master --bus socketcan:vcan0` plays the master, `candump -L vcan0` and `dumpcap -i vcan0`
//!   record the bus, tshark decodes the captures.
//!
//! The tests share `vcan0`, so they take turns ([`RIG_LOCK`]). What each run leaves (logs,
//! captures, the processes' output) is kept in `$DNET_VCAN_OUT/<test>` when that is set (the
//! runner shares it with the host), else in a temporary directory.

use can_io::bus::socketcan::SocketCanBus;
use can_io::bus::Bus;
use can_io::log::{read_log, LogEntry};
use can_io::pcap::PcapWriter;
use devicenet::reference::BRING_UP;
use devicenet::{CanFrame, Identifier, MacId};
use master_core::session::is_from_device;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant as WallClock};

/// The interface every test uses.
const IFACE: &str = "vcan0";
/// The device under test.
const DEVICE: u8 = 5;
/// Tests take turns on the one interface.
static RIG_LOCK: Mutex<()> = Mutex::new(());

/// The reference device's description: on a real bus monitor decodes only what a description
/// tells it.
const BREAKER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../slave-fw/descriptions/breaker.toml");

/// The directory of the workspace's binaries: `DNET_BIN_DIR`, else next to this test's `deps/`.
fn bin_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("DNET_BIN_DIR") {
        return PathBuf::from(d);
    }
    let exe = std::env::current_exe().expect("the test's own path");
    exe.parent().and_then(Path::parent).expect("target/<profile>/deps/<test>").to_path_buf()
}

fn bin(name: &str) -> PathBuf {
    let p = bin_dir().join(name);
    assert!(p.exists(), "{} is missing: build it first (scripts/vcan-tests does)", p.display());
    p
}

/// Lines a process printed, collected by a reader thread.
#[derive(Clone, Default)]
struct Lines(Arc<Mutex<Vec<String>>>);

impl Lines {
    /// Follows `stream` to its end; the thread's handle says when that came.
    fn follow(stream: impl Read + Send + 'static, copy_to: Option<PathBuf>) -> (Lines, JoinHandle<()>) {
        let lines = Lines::default();
        let sink = lines.clone();
        let reader = std::thread::spawn(move || {
            let mut file = copy_to.and_then(|p| std::fs::File::create(p).ok());
            for line in BufReader::new(stream).lines().map_while(Result::ok) {
                if let Some(f) = &mut file {
                    use std::io::Write;
                    let _ = writeln!(f, "{line}");
                }
                sink.0.lock().unwrap_or_else(|e| e.into_inner()).push(line);
            }
        });
        (lines, reader)
    }

    fn snapshot(&self) -> Vec<String> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    fn text(&self) -> String {
        self.snapshot().join("\n")
    }

    /// Waits until some line satisfies `pred`; returns it.
    fn wait_for(&self, what: &str, timeout: Duration, pred: impl Fn(&str) -> bool) -> String {
        let end = WallClock::now() + timeout;
        loop {
            if let Some(l) = self.snapshot().into_iter().find(|l| pred(l)) {
                return l;
            }
            assert!(WallClock::now() < end, "no {what} within {timeout:?}; output so far:\n{}", self.text());
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// A child process stopped with SIGINT (then SIGKILL) when dropped.
struct Proc {
    name: String,
    child: Child,
    stdout: Lines,
    stderr: Lines,
    readers: Vec<JoinHandle<()>>,
}

impl Proc {
    fn spawn(name: &str, cmd: &mut Command, out: &Path) -> Proc {
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {name}: {e}"));
        let (stdout, r1) =
            Lines::follow(child.stdout.take().expect("piped"), Some(out.join(format!("{name}.out"))));
        let (stderr, r2) =
            Lines::follow(child.stderr.take().expect("piped"), Some(out.join(format!("{name}.err"))));
        Proc { name: name.to_string(), child, stdout, stderr, readers: vec![r1, r2] }
    }

    /// After the process ended: waits until its last output was read.
    fn drain(&mut self) {
        for r in self.readers.drain(..) {
            let _ = r.join();
        }
    }

    /// Waits for the process to end by itself.
    fn wait(&mut self, timeout: Duration) -> ExitStatus {
        let end = WallClock::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().expect("try_wait") {
                self.drain();
                return status;
            }
            if WallClock::now() >= end {
                let _ = self.child.kill();
                panic!(
                    "{} did not finish within {timeout:?}\nstdout:\n{}\nstderr:\n{}",
                    self.name,
                    self.stdout.text(),
                    self.stderr.text()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// SIGINT, as a user's Ctrl-C, then the exit status.
    fn interrupt(&mut self) -> Option<ExitStatus> {
        if self.running() {
            let _ = Command::new("kill").arg("-INT").arg(self.child.id().to_string()).status();
        }
        let end = WallClock::now() + Duration::from_secs(5);
        while WallClock::now() < end {
            if let Ok(Some(status)) = self.child.try_wait() {
                self.drain();
                return Some(status);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        None
    }

    fn assert_no_panic(&self) {
        for text in [self.stdout.text(), self.stderr.text()] {
            assert!(!text.contains("panicked"), "{} panicked:\n{text}", self.name);
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.interrupt();
    }
}

/// Runs a command to completion; panics with its output unless it succeeds.
fn run(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap_or_else(|e| panic!("cannot run {cmd:?}: {e}"));
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{cmd:?}: {}\n{text}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// One test's bench: the interface, its output directory, the breaker on a pty pair, and the
/// processes it started (stopped in reverse order when it is dropped).
struct Rig {
    out: PathBuf,
    /// The pty end the soft slave opens.
    slave_tty: PathBuf,
    breaker: Proc,
    _socat: Proc,
    _lock: MutexGuard<'static, ()>,
}

impl Rig {
    /// A fresh bench: `vcan0` up and quiet, the simulated breaker on a pty (`breaker_args` added).
    fn new(test: &str, breaker_args: &[&str]) -> Rig {
        let lock = RIG_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        let out = match std::env::var_os("DNET_VCAN_OUT") {
            Some(d) => PathBuf::from(d).join(test),
            None => std::env::temp_dir().join(format!("dnet-vcan-{}-{test}", std::process::id())),
        };
        let _ = std::fs::remove_dir_all(&out);
        std::fs::create_dir_all(&out).expect("output directory");
        assert!(
            Path::new("/sys/class/net").join(IFACE).exists(),
            "{IFACE} does not exist: run these tests through scripts/vcan-tests"
        );
        run(Command::new("ip").args(["link", "set", IFACE, "up"]));
        let (a, b) = (out.join("tty-breaker"), out.join("tty-slave"));
        let socat = Proc::spawn(
            "socat",
            Command::new("socat").args([
                "-d",
                "-d",
                &format!("pty,raw,echo=0,link={}", a.display()),
                &format!("pty,raw,echo=0,link={}", b.display()),
            ]),
            &out,
        );
        socat
            .stderr
            .wait_for("socat's pty pair", Duration::from_secs(20), |l| l.contains("starting data transfer"));
        let mut args = vec!["--serial".to_string(), a.display().to_string()];
        args.extend(breaker_args.iter().map(|s| s.to_string()));
        let breaker = Proc::spawn("breaker", Command::new(bin("dnet-sim-breaker")).args(&args), &out);
        breaker
            .stdout
            .wait_for("the breaker's first status frame", Duration::from_secs(20), |l| l.contains("status"));
        Rig { out, slave_tty: b, breaker, _socat: socat, _lock: lock }
    }

    /// Starts the soft slave on the interface.
    fn soft_slave(&self, name: &str) -> Proc {
        Proc::spawn(
            name,
            Command::new(bin("dnet-soft-slave")).args([
                "--bus",
                &format!("socketcan:{IFACE}"),
                "--serial",
                &self.slave_tty.display().to_string(),
                "--log",
                &self.out.join(format!("{name}.log")).display().to_string(),
            ]),
            &self.out,
        )
    }

    /// `dnet-master --bus socketcan:vcan0 ARGS`.
    fn master(&self, name: &str, args: &[&str]) -> Proc {
        Proc::spawn(
            name,
            Command::new(bin("dnet-master")).args(["--bus", &format!("socketcan:{IFACE}")]).args(args),
            &self.out,
        )
    }

    fn path(&self, file: &str) -> String {
        self.out.join(file).display().to_string()
    }
}

/// Listens on the interface until the master's second duplicate MAC ID request has been on the
/// bus: the master is then 1 s from on-line, and a device powered now starts its own check after
/// the master's, as in protocol §2.
fn await_master_second_check(listener: &mut SocketCanBus, timeout: Duration) {
    let master_check =
        Identifier::group2(MacId::from_low_bits(0), devicenet::Group2Message::DuplicateMacCheck);
    let end = WallClock::now() + timeout;
    let mut seen = 0;
    while seen < 2 {
        assert!(
            WallClock::now() < end,
            "the master's duplicate MAC ID checks did not show within {timeout:?}"
        );
        let deadline = listener.now() + devicenet::Duration::from_millis(100);
        if let Some(ev) = listener.recv(deadline).expect("listening on vcan0") {
            if ev.frame.id() == master_check {
                seen += 1;
            }
        }
    }
}

/// The (direction, id, data) of a log's frames, direction from who may send each identifier.
fn frames(entries: &[LogEntry]) -> Vec<(bool, u16, Vec<u8>)> {
    let dev = MacId::from_low_bits(DEVICE);
    entries
        .iter()
        .map(|e| (is_from_device(&e.frame, dev), e.frame.id().as_raw(), e.frame.data().to_vec()))
        .collect()
}

fn reference_frames() -> Vec<(bool, u16, Vec<u8>)> {
    BRING_UP
        .iter()
        .map(|f| (f.direction == devicenet::reference::Direction::SlaveToMaster, f.id, f.data.to_vec()))
        .collect()
}

/// The log at `path` holds protocol §2 from frame `from` on (a device started after the master's
/// checks never saw frames 0 and 1), byte for byte and in order, the checks 1 s apart.
fn assert_bring_up(what: &str, path: &str, from: usize) {
    let entries = read_log(Path::new(path)).unwrap_or_else(|e| panic!("{what}: {e}"));
    let got = frames(&entries);
    let want = &reference_frames()[from..];
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(g, w, "{what}: frame {} ({}) differs", from + i, BRING_UP[from + i].meaning);
    }
    assert_eq!(
        got.len(),
        want.len(),
        "{what}: {} frames, protocol §2 has {} from frame {from}",
        got.len(),
        want.len()
    );
    let t = |i: usize| entries[i - from].at.total_millis() as i64;
    // The duplicate MAC ID checks are 1 s apart on the real clock too (protocol §7.1).
    for (a, b) in [(0, 1), (2, 3)].into_iter().filter(|&(a, _)| a >= from) {
        assert!((t(b) - t(a) - 1000).abs() < 150, "{what}: frames {a} and {b} are {} ms apart", t(b) - t(a));
    }
}

/// One frame as tshark decodes it with `-d can.subdissector=devicenet`.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Decoded {
    protocol: String,
    info: String,
    malformed: bool,
}

/// Decodes `captures` with tshark, in one run: tshark's start-up is the slow part under
/// emulation, so `mergecap -a` puts the files one after the other and each frame's interface ID
/// says which file it came from.
fn tshark_devicenet(out: &Path, captures: &[&str]) -> Vec<Vec<Decoded>> {
    let merged = out.join("merged.pcapng").display().to_string();
    run(Command::new("mergecap").args(["-a", "-w", &merged]).args(captures));
    let text = run(Command::new("tshark").args([
        "-n",
        "-r",
        &merged,
        "-d",
        "can.subdissector=devicenet",
        "-T",
        "fields",
        "-E",
        "separator=|",
        "-e",
        "frame.interface_id",
        "-e",
        "_ws.col.Protocol",
        "-e",
        "_ws.col.Info",
        "-e",
        "_ws.malformed",
    ]));
    let mut decoded = vec![Vec::new(); captures.len()];
    for line in text.lines() {
        let f: Vec<&str> = line.split('|').collect();
        let file: usize = f[0].parse().unwrap_or_else(|_| panic!("tshark line {line}"));
        decoded[file].push(Decoded {
            protocol: f[1].to_string(),
            info: f[2].to_string(),
            malformed: !f.get(3).unwrap_or(&"").is_empty(),
        });
    }
    decoded
}

/// A capture tool on the interface, ready once it says so.
fn capture(rig: &Rig, name: &str, cmd: &mut Command, ready: &str) -> Proc {
    let p = Proc::spawn(name, cmd, &rig.out);
    if !ready.is_empty() {
        p.stderr.wait_for(&format!("{name} ready"), Duration::from_secs(60), |l| l.contains(ready));
    }
    p
}

#[test]
#[ignore = "needs vcan0 and root: run scripts/vcan-tests"]
fn bring_up_over_vcan_is_notes_section_2_byte_for_byte_recorded_by_candump_and_dumpcap() {
    let rig = Rig::new("bring_up", &[]);
    let mut candump = capture(&rig, "candump", Command::new("candump").args(["-L", IFACE]), "");
    let mut dumpcap = capture(
        &rig,
        "dumpcap",
        Command::new("dumpcap").args(["-q", "-i", IFACE, "-w", &rig.path("guest.pcapng")]),
        "Capturing on",
    );
    let mut listener = SocketCanBus::open(IFACE).expect("a listening socket on vcan0");
    let mut master = rig.master(
        "master",
        &[
            "--keep",
            "--log",
            &rig.path("master.log"),
            "--pcap",
            &rig.path("master.pcap"),
            "connect",
            "--mac",
            "5",
        ],
    );
    await_master_second_check(&mut listener, Duration::from_secs(30));
    let mut slave = rig.soft_slave("slave");
    let status = master.wait(Duration::from_secs(60));
    assert!(
        status.success(),
        "dnet-master connect: {status}\n{}\n{}",
        master.stdout.text(),
        master.stderr.text()
    );
    assert!(master.stdout.text().contains("28 frames, every check holds"), "{}", master.stdout.text());
    // Let the tail of the exchange reach the recorders, then stop them as a user would.
    std::thread::sleep(Duration::from_millis(500));
    candump.interrupt();
    dumpcap.interrupt();
    std::fs::write(rig.out.join("candump.log"), candump.stdout.text() + "\n").expect("candump.log");

    assert_bring_up("the master's --log", &rig.path("master.log"), 0);
    assert_bring_up("candump -L vcan0", &rig.path("candump.log"), 0);
    assert_bring_up("the soft slave's --log", &rig.path("slave.log"), 2);

    // The same exchange in both captures, every frame DeviceNet, none malformed. A control
    // capture with a truncated duplicate MAC ID check proves tshark's verdict is read.
    let control = rig.path("control.pcap");
    let mut w = PcapWriter::create(Path::new(&control)).expect("control.pcap");
    w.write(devicenet::Instant::ZERO, &CanFrame::from_raw(0x42F, &[0x00, 0x34, 0x12]).expect("frame"))
        .expect("control frame");
    drop(w);
    let decoded =
        tshark_devicenet(&rig.out, &[&rig.path("master.pcap"), &rig.path("guest.pcapng"), &control]);
    let (harness, guest) = (&decoded[0], &decoded[1]);
    assert_eq!(harness.len(), 28, "{harness:#?}");
    assert!(harness.iter().all(|d| d.protocol == "DeviceNet" && !d.malformed), "{harness:#?}");
    assert_eq!(guest, harness, "the guest's capture and the harness's pcap decode alike");
    assert_eq!(harness[6].info, "Group 2 Only Unconnected Explicit Request Messages", "{harness:#?}");
    assert!(decoded[2].len() == 1 && decoded[2][0].malformed, "the control frame: {:?}", decoded[2]);

    // The slave kept running; nobody panicked.
    assert!(slave.running(), "the soft slave stopped:\n{}", slave.stderr.text());
    slave.assert_no_panic();
    master.assert_no_panic();
}

#[test]
#[ignore = "needs vcan0 and root: run scripts/vcan-tests"]
fn candump_recording_replays_against_a_fresh_soft_slave_and_decodes() {
    let rig = Rig::new("replay", &[]);
    // Record a bring-up with candump, as a user would on the bench.
    let mut candump = capture(&rig, "candump", Command::new("candump").args(["-L", IFACE]), "");
    let mut listener = SocketCanBus::open(IFACE).expect("a listening socket on vcan0");
    let mut master = rig.master("master", &["--keep", "connect", "--mac", "5"]);
    await_master_second_check(&mut listener, Duration::from_secs(30));
    let mut slave = rig.soft_slave("slave");
    assert!(master.wait(Duration::from_secs(60)).success(), "{}", master.stdout.text());
    std::thread::sleep(Duration::from_millis(500));
    candump.interrupt();
    slave.interrupt();
    let recording = rig.path("candump.log");
    std::fs::write(&recording, candump.stdout.text() + "\n").expect("candump.log");
    assert_bring_up("candump -L vcan0", &recording, 0);

    // Replay it against a fresh device, powered when the replayed master check #2 is on the bus.
    let mut listener = SocketCanBus::open(IFACE).expect("a fresh listening socket on vcan0");
    let mut replay = rig.master("replay", &["replay", &recording, "--mac", "5", "--tolerance", "1500"]);
    await_master_second_check(&mut listener, Duration::from_secs(30));
    let fresh = rig.soft_slave("fresh-slave");
    let status = replay.wait(Duration::from_secs(60));
    assert!(status.success(), "replay: {status}\n{}\n{}", replay.stdout.text(), replay.stderr.text());
    assert!(
        replay.stdout.text().contains("replay held: 28 frames, 14 from the device compared byte for byte"),
        "{}",
        replay.stdout.text()
    );
    fresh.assert_no_panic();
    drop(fresh);

    // decode reads candump's own file.
    let decoded = run(Command::new(bin("dnet-master")).args(["decode", &recording]));
    assert_eq!(decoded.lines().filter(|l| l.starts_with('(')).count(), 28, "{decoded}");
    for needle in ["Allocate", "Get_Attribute_Single", "poll"] {
        assert!(decoded.to_lowercase().contains(&needle.to_lowercase()), "no {needle} in:\n{decoded}");
    }
}

#[test]
#[ignore = "needs vcan0 and root: run scripts/vcan-tests"]
fn monitor_open_command_reaches_the_breaker() {
    // The breaker starts closed, so the open command shows in its state as well as in its log.
    let rig = Rig::new("monitor", &["--closed"]);
    let mut listener = SocketCanBus::open(IFACE).expect("a listening socket on vcan0");
    let mut master = rig.master(
        "monitor",
        &["monitor", "--mac", "5", "--output", "0101", "--count", "40", "--description", BREAKER],
    );
    await_master_second_check(&mut listener, Duration::from_secs(30));
    let mut slave = rig.soft_slave("slave");
    let status = master.wait(Duration::from_secs(90));
    let shown = master.stdout.text();
    assert!(status.success(), "monitor: {status}\n{shown}\n{}", master.stderr.text());
    let samples: Vec<&str> = shown.lines().filter(|l| l.contains("switch")).collect();
    assert_eq!(samples.len(), 40, "{shown}");
    let first_open = samples.iter().position(|l| l.ends_with("switch open"));
    assert!(samples[0].ends_with("switch closed") && samples[0].contains("A 120 A"), "{shown}");
    assert!(first_open.is_some(), "the switch never showed open:\n{shown}");
    assert!(samples[first_open.unwrap_or(0)..].iter().all(|l| l.ends_with("switch open")), "{shown}");
    rig.breaker
        .stdout
        .wait_for("the open command at the breaker", Duration::from_secs(5), |l| l.contains("command open"));
    assert!(slave.running(), "{}", slave.stderr.text());
    slave.assert_no_panic();
    master.assert_no_panic();
    rig.breaker.assert_no_panic();
}

#[test]
#[ignore = "needs vcan0 and root: run scripts/vcan-tests"]
fn interface_down_and_up_during_polling_is_reported_and_reconnected() {
    let rig = Rig::new("bus_off", &[]);
    let mut listener = SocketCanBus::open(IFACE).expect("a listening socket on vcan0");
    let mut master = rig.master(
        "monitor",
        &[
            "monitor",
            "--mac",
            "5",
            "--epr",
            "100",
            "--reconnect",
            "--duration",
            "16",
            "--description",
            BREAKER,
        ],
    );
    await_master_second_check(&mut listener, Duration::from_secs(30));
    let mut slave = rig.soft_slave("slave");
    master.stdout.wait_for("polled samples", Duration::from_secs(30), |l| l.contains("switch open"));
    std::thread::sleep(Duration::from_millis(500));
    run(Command::new("ip").args(["link", "set", IFACE, "down"]));
    std::thread::sleep(Duration::from_secs(2));
    run(Command::new("ip").args(["link", "set", IFACE, "up"]));
    let lost = master
        .stdout
        .wait_for("the lost connection", Duration::from_secs(10), |l| l.contains("connection lost"));
    assert!(lost.contains("Network is down") || lost.contains("timeout"), "{lost}");
    // The device either rode the outage out, or stopped with the bus error named (exit status 1,
    // no panic) and is started again, as a service manager would.
    let mut slave = if slave.running() {
        slave
    } else {
        let status = slave.wait(Duration::from_secs(5));
        let said = slave.stderr.text();
        slave.assert_no_panic();
        assert!(status.code() == Some(1) && said.contains("Network is down"), "soft slave: {status}\n{said}");
        eprintln!("note: the soft slave stopped when {IFACE} went down ({status}); started again");
        rig.soft_slave("slave-restarted")
    };
    master.stdout.wait_for("the reconnection", Duration::from_secs(30), |l| l.starts_with("reconnected at"));
    let status = master.wait(Duration::from_secs(60));
    let shown = master.stdout.text();
    let after: Vec<&str> = shown
        .lines()
        .skip_while(|l| !l.starts_with("reconnected"))
        .filter(|l| l.contains("switch open"))
        .collect();
    assert!(after.len() >= 10, "polling goes on after the reconnection:\n{shown}");
    assert!(status.success(), "monitor --reconnect: {status}\n{shown}\n{}", master.stderr.text());
    master.assert_no_panic();
    assert!(slave.running(), "the soft slave stopped:\n{}", slave.stderr.text());
    slave.assert_no_panic();
}
