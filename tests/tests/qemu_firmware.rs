//! End to end on the emulated board: the real firmware (feature `emulated`; on an empty settings
//! flash the converter runs its factory default, the breaker) runs in QEMU; the bench master
//! brings it up over SLCAN on USART1 and checks the 28 frames of protocol §2 byte for byte, then closes and opens the simulated breaker
//! that answers on USART2, and sees each change in the breaker and in the poll data (byte 9); the
//! scanner keeps it in I/O; then change of state (`connect --io cos`) and the recovery of the board
//! made Communication Faulted (`recover --mac 5 --to 9`, issue 14).
//!
//! ```sh
//! scripts/qemu-firmware --build-only
//! DNET_QEMU=1 cargo test -p system-tests --test qemu_firmware -- --ignored
//! ```
//!
//! `scripts/check` runs it in its "emulated firmware run" stage. The firmware is built by the
//! script beforehand: a nested `cargo build` would wait for the build-directory lock that the
//! running `cargo test` holds.
//!
//! ## The board is powered on when the master is on-line
//!
//! The reference sequence is the capture of a slave powered on after the master went on-line: the
//! master's two duplicate MAC ID checks (frames 0–1), then the slave's (2–3). A board running
//! before the master connects would send its checks first. So QEMU starts paused, the board
//! unpowered (`scripts/qemu-firmware --paused`), and [`PowerOnAtMasterOnline`] powers it on
//! (`cont` on QEMU's monitor) when the master goes on-line (1 s after its second duplicate MAC ID
//! check request, seen by [`MasterOnlineWatch`]), as the simulated bus does by default
//! (`--slave-power-on master-online`). Until then the master
//! is alone on its bus and its frames go nowhere. The firmware is not changed for the test: it
//! starts its duplicate MAC ID check at power-on, and its SLCAN adapter holds frames until the
//! host opens the channel, as a bxCAN mailbox holds a frame nobody acknowledges.
//!
//! ## Time
//!
//! Everything runs in real time. The master uses its bus's clock; the breaker thread converts
//! `std::time::Instant` to [`devicenet::Instant`] microseconds since it started. The whole run is
//! bounded by [`RUN_LIMIT`] (also QEMU's time limit); on failure the test prints the frame table,
//! the breaker's serial transcript and QEMU's log (guest errors).

use can_io::bus::slcan::SlcanBus;
use can_io::bus::{Bitrate, Bus, BusError, BusEvent, Origin};
use can_io::sim::MasterOnlineWatch;
use converter_sim::device::{COMMAND_CLOSE, COMMAND_OPEN, LOAD, SWITCH_BYTE, SWITCH_CLOSED, SWITCH_OPEN};
use converter_sim::SimulatedBreaker;
use devicenet::messages::DuplicateMacCheck;
use devicenet::reference::{Direction, BRING_UP, INPUT_IMAGE};
use devicenet::{CanFrame, Duration, Instant};
use dnet_scanner::model::{ConsoleCommand, NodeStatus, ScanEntry, ScanList};
use dnet_scanner::monitor::InputLayout;
use dnet_scanner::{Scanner, ScannerOptions};
use harness_common::table::print_table;
use master_core::error::MasterError;
use master_core::master::io::{IoKind, IoOptions};
use master_core::master::recovery::RecoverOptions;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::{Session, Verdict};
use serialport::SerialPort;
use slave_fw::description::DeviceDescription;
use slave_fw::serial::breaker::{BreakerCommand, SwitchState};
use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::UnixStream;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex};
use std::time::Duration as StdDuration;
use system_tests::mac;

/// The whole run's bound, also QEMU's time limit.
const RUN_LIMIT: StdDuration = StdDuration::from_secs(120);
/// From `cont` to the firmware answering on USART1 (it boots in well under a second).
const BOOT_LIMIT: StdDuration = StdDuration::from_secs(5);
/// How long the poll data may take to show a breaker command: the command goes out at once, the
/// breaker reports its new state in its next status frame (every second).
const STATE_CHANGE_LIMIT: Duration = Duration::from_secs(5);
/// The expected packet rate the bring-up sets (protocol §2 frame 22).
const EPR: Duration = Duration::from_millis(100);
/// The poll response timeout after the bring-up. The firmware answers within milliseconds, but
/// QEMU's virtual CPU may wait for the host's scheduler (the bring-up's one poll keeps the
/// harness's EPR timeout, as the reference sequence fixes the EPR).
const POLL_TIMEOUT: Duration = Duration::from_secs(1);

/// `scripts/qemu-firmware --paused` and the QEMU it runs; stopped (SIGTERM, so the script stops
/// QEMU) on drop, also on panic.
struct Emulator {
    child: Child,
    usart1: String,
    usart2: String,
    monitor: String,
    log: String,
}

impl Emulator {
    fn start() -> Emulator {
        let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/qemu-firmware");
        let mut child = Command::new(script)
            .args(["--no-build", "--paused", "--timeout", &RUN_LIMIT.as_secs().to_string()])
            .stdout(Stdio::piped())
            .spawn()
            .expect("start scripts/qemu-firmware");
        let stdout = child.stdout.take().expect("piped stdout");
        let mut emulator = Emulator {
            child,
            usart1: String::new(),
            usart2: String::new(),
            monitor: String::new(),
            log: String::new(),
        };
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        while emulator.usart1.is_empty()
            || emulator.usart2.is_empty()
            || emulator.monitor.is_empty()
            || emulator.log.is_empty()
        {
            let line = rx
                .recv_timeout(StdDuration::from_secs(20))
                .expect("scripts/qemu-firmware printed no USART1/USART2/MONITOR/LOG lines");
            let field = match line.split_once('=') {
                Some(("USART1", v)) => (&mut emulator.usart1, v),
                Some(("USART2", v)) => (&mut emulator.usart2, v),
                Some(("MONITOR", v)) => (&mut emulator.monitor, v),
                Some(("LOG", v)) => (&mut emulator.log, v),
                _ => continue,
            };
            *field.0 = field.1.to_string();
        }
        emulator
    }

    /// QEMU's log (its messages and the guest errors it reported).
    fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_else(|e| format!("({}: {e})", self.log))
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        let _ = Command::new("kill").arg("-TERM").arg(self.child.id().to_string()).status();
        let _ = self.child.wait();
    }
}

/// Opens a pseudo-terminal raw (the serial port crate sets raw mode), with a short read timeout.
fn open_pty(path: &str, baud: u32) -> Box<dyn SerialPort> {
    serialport::new(path, baud)
        .timeout(StdDuration::from_millis(10))
        .open()
        .unwrap_or_else(|e| panic!("open {path}: {e}"))
}

/// The simulated breaker on USART2, run by a thread in real time.
struct BreakerRig {
    breaker: Arc<Mutex<SimulatedBreaker>>,
    transcript: Arc<Mutex<Vec<String>>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl BreakerRig {
    fn start(path: &str) -> BreakerRig {
        let mut port = open_pty(path, 9600);
        let origin = std::time::Instant::now();
        let now =
            move || Instant::from_micros(u64::try_from(origin.elapsed().as_micros()).unwrap_or(u64::MAX));
        let mut sim = SimulatedBreaker::new(now());
        sim.set_load(LOAD);
        let breaker = Arc::new(Mutex::new(sim));
        let transcript = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (b, t, s) = (breaker.clone(), transcript.clone(), stop.clone());
        let thread = std::thread::spawn(move || {
            let mut buf = [0u8; 64];
            while !s.load(Ordering::Relaxed) {
                let wait = {
                    let mut breaker = b.lock().unwrap();
                    let at = now();
                    while let Some(bytes) = breaker.poll_transmit(at) {
                        t.lock().unwrap().push(format!("{at} breaker -> {}", hex(&bytes)));
                        if let Err(e) = port.write_all(&bytes) {
                            t.lock().unwrap().push(format!("{at} write failed: {e}"));
                        }
                    }
                    breaker.poll_at().map_or(StdDuration::from_millis(50), |next| {
                        StdDuration::from_micros(next.total_micros().saturating_sub(now().total_micros()))
                    })
                };
                let _ =
                    port.set_timeout(wait.clamp(StdDuration::from_millis(1), StdDuration::from_millis(50)));
                match port.read(&mut buf) {
                    Ok(n) if n > 0 => {
                        let at = now();
                        t.lock().unwrap().push(format!("{at} breaker <- {}", hex(&buf[..n])));
                        b.lock().unwrap().on_bytes(&buf[..n], at);
                    }
                    _ => {}
                }
            }
        });
        BreakerRig { breaker, transcript, stop, thread: Some(thread) }
    }

    fn switch_state(&self) -> SwitchState {
        self.breaker.lock().unwrap().switch_state()
    }

    fn commands(&self) -> Vec<BreakerCommand> {
        self.breaker.lock().unwrap().commands().to_vec()
    }

    fn transcript(&self) -> String {
        self.transcript.lock().unwrap().join("\n")
    }
}

impl Drop for BreakerRig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The master's bus: nothing but the master until it is on-line; then the board is powered on
/// (`cont` on QEMU's monitor) and the bus is the SLCAN link on USART1. One clock throughout (the
/// SLCAN bus's own clock starts when it opens, and is shifted onto this one).
struct PowerOnAtMasterOnline {
    origin: std::time::Instant,
    /// USART1, opened at once so QEMU sees its client connected before the board boots.
    port: Option<Box<dyn SerialPort>>,
    monitor: String,
    slcan: Option<(SlcanBus<Box<dyn SerialPort>>, Duration)>,
    /// The master's own frames while it is alone.
    echoes: std::collections::VecDeque<BusEvent>,
    power_error: Option<String>,
    /// When the board was powered on, on this bus's clock.
    powered_at: Option<Instant>,
    /// Sees the master go on-line from its own frames.
    watch: MasterOnlineWatch,
    /// When the master goes on-line: the board is powered on then.
    power_at: Option<Instant>,
}

impl PowerOnAtMasterOnline {
    fn new(usart1: &str, monitor: &str) -> Self {
        PowerOnAtMasterOnline {
            origin: std::time::Instant::now(),
            port: Some(open_pty(usart1, 115_200)),
            monitor: monitor.to_string(),
            slcan: None,
            echoes: Default::default(),
            watch: MasterOnlineWatch::default(),
            power_at: None,
            power_error: None,
            powered_at: None,
        }
    }

    fn clock(&self) -> Instant {
        Instant::from_micros(u64::try_from(self.origin.elapsed().as_micros()).unwrap_or(u64::MAX))
    }

    /// `cont` on the monitor, then `V` on USART1 until the firmware answers, then the SLCAN
    /// set-up (close, 250k, open) by the harness's SLCAN bus.
    fn power_on(&mut self) -> Result<(), String> {
        let mut monitor =
            UnixStream::connect(&self.monitor).map_err(|e| format!("QEMU monitor {}: {e}", self.monitor))?;
        monitor.write_all(b"cont\n").map_err(|e| format!("QEMU monitor: {e}"))?;
        self.powered_at = Some(self.clock());
        let mut port = self.port.take().ok_or("powered on twice")?;
        let started = std::time::Instant::now();
        let mut answer = Vec::new();
        let mut buf = [0u8; 64];
        while !String::from_utf8_lossy(&answer).contains("V1013\r") {
            if started.elapsed() > BOOT_LIMIT {
                return Err(format!("the firmware did not answer `V` within {BOOT_LIMIT:?} of power-on"));
            }
            port.write_all(b"V\r").map_err(|e| format!("USART1: {e}"))?;
            let _ = port.set_timeout(StdDuration::from_millis(50));
            if let Ok(n) = port.read(&mut buf) {
                answer.extend_from_slice(&buf[..n]);
            }
        }
        let bus = SlcanBus::new(port, Bitrate::K250).map_err(|e| e.to_string())?;
        let offset = Duration::from_micros(self.clock().total_micros());
        self.slcan = Some((bus, offset));
        drop(monitor);
        Ok(())
    }
}

impl Bus for PowerOnAtMasterOnline {
    fn name(&self) -> &str {
        "slcan0"
    }

    fn now(&mut self) -> Instant {
        self.clock()
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        if let Some(e) = &self.power_error {
            return Err(BusError::Adapter(e.clone()));
        }
        let now = self.clock();
        if let Some(online) = self.watch.sent(frame, now) {
            self.power_at = Some(online);
        }
        match &mut self.slcan {
            Some((bus, _)) => bus.send(frame),
            None => {
                let at = self.clock();
                self.echoes.push_back(BusEvent { at, frame: *frame, origin: Origin::Local });
                Ok(())
            }
        }
    }

    fn recv(&mut self, deadline: Instant) -> Result<Option<BusEvent>, BusError> {
        if self.slcan.is_none()
            && self.power_error.is_none()
            && self.power_at.is_some_and(|at| self.clock() >= at)
        {
            if let Err(e) = self.power_on() {
                self.power_error = Some(e);
            }
        }
        if let Some(e) = &self.power_error {
            return Err(BusError::Adapter(e.clone()));
        }
        if let Some(ev) = self.echoes.pop_front() {
            return Ok(Some(ev));
        }
        match &mut self.slcan {
            Some((bus, offset)) => {
                let offset = *offset;
                let inner =
                    Instant::from_micros(deadline.total_micros().saturating_sub(offset.total_micros()));
                Ok(bus.recv(inner)?.map(|ev| BusEvent { at: ev.at + offset, ..ev }))
            }
            None => {
                let now = self.clock();
                if deadline > now {
                    std::thread::sleep(StdDuration::from_micros((deadline - now).total_micros()));
                }
                Ok(None)
            }
        }
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect::<Vec<_>>().join(" ")
}

fn direction(origin: Origin) -> Direction {
    match origin {
        Origin::Local => Direction::MasterToSlave,
        Origin::Remote => Direction::SlaveToMaster,
    }
}

/// Polls with `output` every EPR until the poll data shows `switch` (and the currents that go
/// with it), or [`STATE_CHANGE_LIMIT`] passes; returns the last poll data.
fn poll_until(master: &mut Master<'_, '_>, output: [u8; 8], switch: u8) -> Result<Vec<u8>, String> {
    let target = mac(5);
    let currents = if switch == SWITCH_CLOSED { LOAD } else { [0; 4] };
    let start = master.session.now();
    let mut next = start;
    loop {
        master.idle_until(next).map_err(|e| e.to_string())?;
        next += EPR;
        let input = master.poll(target, &output, 18, 8, POLL_TIMEOUT).map_err(|e| e.to_string())?;
        if input.get(SWITCH_BYTE) == Some(&switch) && input.get(..4) == Some(&currents[..]) {
            return Ok(input);
        }
        if master.session.now() - start > STATE_CHANGE_LIMIT {
            return Err(format!(
                "poll data still {} after {STATE_CHANGE_LIMIT} of command {:02X?}",
                hex(&input),
                output
            ));
        }
    }
}

#[test]
#[ignore = "runs QEMU: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p system-tests --test qemu_firmware -- --ignored"]
fn emulated_converter_brought_up_and_breaker_operated() {
    if std::env::var("DNET_QEMU").as_deref() != Ok("1") {
        eprintln!("DNET_QEMU=1 not set: not running QEMU");
        return;
    }
    // The reference device is MAC 5 with the breaker; the script's default build is.
    assert!(std::env::var("DNET_MAC").map_or(true, |m| m == "5"), "this test expects DNET_MAC=5");
    let started = std::time::Instant::now();

    let emulator = Emulator::start();
    let breaker = BreakerRig::start(&emulator.usart2);
    let mut bus = PowerOnAtMasterOnline::new(&emulator.usart1, &emulator.monitor);
    let mut session = Session::new(&mut bus);

    let outcome = run(&mut session, &breaker);
    let records = session.records().to_vec();
    let failures = session.failures();
    drop(session);
    let outcome = outcome.and_then(|()| match failures {
        0 => Ok(()),
        n => Err(format!("{n} frames failed their checks")),
    });

    let mut table = Vec::new();
    let _ = print_table(&mut table, &records, Some(mac(5)));
    let report = format!(
        "frames (board powered on at {}):\n{}\nbreaker on USART2:\n{}\nQEMU log ({}):\n{}",
        bus.powered_at.map_or("never".to_string(), |t| t.to_string()),
        String::from_utf8_lossy(&table),
        breaker.transcript(),
        emulator.log,
        emulator.log_text()
    );
    if let Err(e) = outcome {
        panic!("{e}\n\n{report}");
    }
    assert!(started.elapsed() < RUN_LIMIT, "took {:?}\n\n{report}", started.elapsed());
    eprintln!("{report}\nend to end in {:.1} s", started.elapsed().as_secs_f64());
}

/// The bring-up, then close and open. Errors carry what went wrong; the caller prints the rest.
fn run(session: &mut Session<'_>, breaker: &BreakerRig) -> Result<(), String> {
    let mut master = Master::new(session, MasterConfig::default());
    let summary = master.connect(&ConnectOptions::default()).map_err(|e: MasterError| e.to_string())?;

    // The 28 frames of protocol §2, byte for byte and in order, every check holding.
    let records = master.session.records();
    if records.len() != BRING_UP.len() {
        return Err(format!("bring-up took {} frames, the reference {}", records.len(), BRING_UP.len()));
    }
    for (i, (got, want)) in records.iter().zip(BRING_UP.iter()).enumerate() {
        let got_frame = (direction(got.origin), got.frame.id().as_raw(), got.frame.data());
        if got_frame != (want.direction, want.id, want.data) {
            return Err(format!(
                "frame {i} ({}): {got_frame:02X?}, expected {:02X?}",
                want.meaning,
                (want.direction, want.id, want.data)
            ));
        }
        if !matches!(got.verdict, Verdict::Sent | Verdict::Ok(_)) {
            return Err(format!("frame {i}: {}", got.verdict.label()));
        }
    }
    if summary.last_input.as_deref() != Some(&INPUT_IMAGE[..]) {
        return Err(format!("poll data {:02X?}, expected the breaker open with no load", summary.last_input));
    }

    // Close (command 2, sequence 1), then open (command 1, sequence 2): each executed once by the
    // breaker and reported back in the poll data.
    poll_until(&mut master, [COMMAND_CLOSE, 1, 0, 0, 0, 0, 0, 0], SWITCH_CLOSED)?;
    if breaker.switch_state() != SwitchState::Closed {
        return Err(format!("the breaker is {:?} after the close command", breaker.switch_state()));
    }
    poll_until(&mut master, [COMMAND_OPEN, 2, 0, 0, 0, 0, 0, 0], SWITCH_OPEN)?;
    if breaker.switch_state() != SwitchState::Open {
        return Err(format!("the breaker is {:?} after the open command", breaker.switch_state()));
    }
    let commands = breaker.commands();
    if commands != [BreakerCommand::Close, BreakerCommand::Open] {
        return Err(format!("the breaker received {commands:?}, expected one close and one open"));
    }
    scanner(&mut master, breaker)?;
    change_of_state_and_recovery(&mut master)
}

/// Issue 14 on the board: `connect --io cos` (the breaker's image produced on change and
/// acknowledged), then the board made Communication Faulted by a duplicate MAC ID response for its
/// MAC (protocol §7.1) and recovered to MAC 9 through the Offline Connection Set (`recover`, §II.6):
/// the firmware's filters take the Group 4 requests and, after the change, its new MAC.
fn change_of_state_and_recovery(master: &mut Master<'_, '_>) -> Result<(), String> {
    master.release_held().map_err(|e| e.to_string())?;
    // The breaker reports once a second: with a 2 s heartbeat every production is a change.
    let opts = ConnectOptions { target: mac(5), epr_ms: 2000, polls: 4, ..ConnectOptions::default() };
    let io = IoOptions { judge_timing: false, ..IoOptions::of(IoKind::ChangeOfState) };
    let failures = master.session.failures();
    let summary = master.connect_io(&opts, &io).map_err(|e| format!("connect --io cos: {e}"))?;
    let cos = summary.io.ok_or("connect --io cos gave no I/O summary")?;
    if cos.productions < 4 || master.session.failures() != failures {
        return Err(format!(
            "connect --io cos: {cos:?}, {} failed frames",
            master.session.failures() - failures
        ));
    }
    if summary.last_input.as_ref().map(Vec::len) != Some(18) {
        return Err(format!("COS data {:02X?}, expected the 18-byte image", summary.last_input));
    }
    master.release_held().map_err(|e| e.to_string())?;

    // Another node claims MAC 5: the on-line board must fault (protocol §7.1).
    let claim = DuplicateMacCheck::response(0, 0x0FFF, 0xA5A5_0002);
    master
        .session
        .send(&CanFrame::from_raw(0x42F, &claim.emit()).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())?;
    let settle = master.session.now() + Duration::from_millis(300);
    master.idle_until(settle).map_err(|e| e.to_string())?;
    let opts = RecoverOptions { to: Some(mac(9)), judge_timing: false, ..RecoverOptions::new(mac(5)) };
    let report = master.recover(&opts).map_err(|e| format!("recover --mac 5 --to 9: {e}"))?;
    if !report.online || report.serial_at_new_mac != Some(0x1234_5678) || !report.findings.is_empty() {
        return Err(format!("recover --mac 5 --to 9: {report:?}"));
    }
    // A device at MAC 9 now (recover left its explicit connection allocated): change of state
    // there too.
    master.release_held().map_err(|e| e.to_string())?;
    let opts = ConnectOptions { target: mac(9), epr_ms: 2000, polls: 2, ..ConnectOptions::default() };
    let summary = master.connect_io(&opts, &io).map_err(|e| format!("connect --mac 9 --io cos: {e}"))?;
    match summary.io {
        Some(cos) if cos.productions >= 2 => Ok(()),
        other => Err(format!("connect --mac 9 --io cos: {other:?}")),
    }
}

/// The scanner of `dnet-master scanner` and `ui` keeps the board in I/O (issue 15): its electronic
/// key and sizes as the scan list says, the input decoded by the breaker's profile, and a close put
/// in the output image through a console command reaching the breaker once.
fn scanner(master: &mut Master<'_, '_>, breaker: &BreakerRig) -> Result<(), String> {
    master.release_held().map_err(|e| e.to_string())?;
    let node = ScanEntry {
        mac: 5,
        connection: "poll".into(),
        ack_suppression: false,
        inhibit_ms: None,
        vendor_id: Some(0x1234),
        device_type: Some(12),
        product_code: Some(1),
        major_revision: None,
        minor_revision: None,
        input_size: 18,
        output_size: 8,
        name: None,
        adr: Default::default(),
        keying: Default::default(),
        enabled: true,
    };
    let list = ScanList { nodes: vec![node], ..ScanList::default() };
    let layout = InputLayout::from_converter(&DeviceDescription::reference().converter);
    let options = ScannerOptions { cycles: None, bitrate: Bitrate::K250, layouts: [(5, layout)].into() };
    let mut scanner = Scanner::new(list, 0, options);
    scanner.start(master).map_err(|e| format!("scanner start: {e}"))?;
    for _ in 0..20 {
        scanner.cycle(master).map_err(|e| format!("scanner cycle: {e}"))?;
    }
    let node = scanner.state().nodes[0].clone();
    if node.status != NodeStatus::Ok
        || node.identity.product_name.as_deref() != Some("Serial-DeviceNet Bridge")
    {
        return Err(format!("the scanner's node 5: {node:?}"));
    }
    let samples = scanner.take_samples();
    if !samples.iter().any(|s| s.mac == 5 && s.values.iter().any(|(name, _)| name == "phase_a")) {
        return Err(format!("no decoded sample of node 5 in {} samples", samples.len()));
    }
    let (reply, answer) = mpsc::channel();
    let data = vec![COMMAND_CLOSE, 3, 0, 0, 0, 0, 0, 0];
    scanner.command(master, ConsoleCommand::SetOutput { mac: 5, data, reply });
    answer.recv().map_err(|e| e.to_string())?.map_err(|e| format!("SetOutput refused: {e}"))?;
    // The breaker reports once a second: the close shows within STATE_CHANGE_LIMIT of bus time.
    let deadline = master.session.now() + STATE_CHANGE_LIMIT;
    let mut closed = false;
    while master.session.now() < deadline {
        scanner.cycle(master).map_err(|e| format!("scanner cycle: {e}"))?;
        if scanner.state().nodes[0].input.get(SWITCH_BYTE) == Some(&SWITCH_CLOSED) {
            closed = true;
            break;
        }
    }
    scanner.stop(master).map_err(|e| format!("scanner stop: {e}"))?;
    if !closed || breaker.switch_state() != SwitchState::Closed {
        return Err(format!(
            "the scanner's close: input {:02X?}, breaker {:?}",
            scanner.state().nodes[0].input,
            breaker.switch_state()
        ));
    }
    let commands = breaker.commands();
    if commands != [BreakerCommand::Close, BreakerCommand::Open, BreakerCommand::Close] {
        return Err(format!("the breaker received {commands:?}, expected close, open, close"));
    }
    Ok(())
}
