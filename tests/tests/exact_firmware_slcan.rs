//! The exact firmware ELF of a board on the real SLCAN path: `exact-firmware-serve` runs it on the
//! stm32-emu register models in wall time, as the other node behind an SLCAN adapter on a socat
//! pty pair, with its instrument USART on a second pair; the real programs drive it unchanged
//! (issue 26):
//!
//! - `dnet-master connect` brings the node up, every frame checked, and the 28 frames of its log
//!   are protocol §2 byte for byte (the board powered when the master is on-line);
//! - `dnet-master monitor` closes and then opens `dnet-sim-breaker` on the instrument pty through
//!   the poll output, and the breaker hears each command once;
//! - `dnet-master configure` downloads the Modbus meter description; the pymodbus meter
//!   (slave-fw/soft-slave/tests/modbus/server.py) on the instrument pty answers the gateway at
//!   19200 8E1 and its registers come back in the poll data, and its write of the poll output is
//!   seen by the meter; then a power cycle (the serve process stopped by SIGINT, as Ctrl-C, started
//!   again on the same flash file): `configure --read` gives the meter description back and the meter's
//!   data still flows;
//! - the same download with the instrument side at another baud rate carries no meter data (the
//!   characters are counted garbled);
//! - bad arguments are refused with the reason.
//!
//! ```sh
//! scripts/firmware-size            # the ELFs: target/thumbv7em-none-eabihf/firmware/slave-fw-firmware-BOARD
//! cargo build -p exact-firmware -p soft-slave -p master-harness
//! DNET_PYTHON=.venv/bin/python cargo test -p system-tests --test exact_firmware_slcan -- --ignored
//! ```
//!
//! The boards are `DNET_EXACT_BOARDS` (comma-separated, or `all`); by default the bring-up runs
//! on every board and the rest on the reference board (about 1 min in all; every board for
//! everything takes about 3). A missing ELF,
//! program, socat or pymodbus fails the test, saying which command provides it: nothing here is
//! skipped. scripts/check runs it in the stage after the exact-firmware stage.

use can_io::log::read_log;
use devicenet::reference::BRING_UP;
use pty_rig::{bin, require_pymodbus, scratch, workspace_dir, Proc, PtyPair};
use slave_fw::description::DeviceDescription;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The node's MAC ID and rate in every run (the master's default bit rate, 250k).
const MAC: &str = "5";
const RATE: &str = "250k";

/// How long a board powered at the start takes to be on-line: its duplicate MAC ID check (2 s
/// by its clock) and the emulator's start-up, with a margin.
const BOARD_ONLINE: Duration = Duration::from_millis(3000);

/// The explicit response timeout of `configure`, ms. The firmware programs the 640-byte settings
/// record after Commit_Download; in a debug build the emulator takes about 1.5 s of wall time for
/// that (every flash operation goes through the FLASH model and refreshes the CPU's copy of the
/// array), a release build about 0.4 s, and the read-back's first Read_Chunk waits for it: the
/// master's 1000 ms default would time the emulator, not the firmware (exact-firmware-serve's
/// summary reports how far the machine fell behind the wall clock). Not longer: after the
/// Identity Reset `configure` repeats its allocation until 6 s after the reset (master-harness
/// `BACK_ONLINE`), and with the board's start-up checks seen before in the same session the
/// master reckons it on-line a second early, so the second attempt must fit in those 6 s.
const CONFIGURE_TIMEOUT: &str = "2500";

/// The ELF scripts/firmware-size leaves for `board`; fails the test when it is not there.
fn elf(board: &str) -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_dir().join("target"));
    let path = target.join(format!("thumbv7em-none-eabihf/firmware/slave-fw-firmware-{board}"));
    assert!(
        path.is_file(),
        "{} is missing: build every board's ELF with scripts/firmware-size (or scripts/exact-firmware)",
        path.display()
    );
    path
}

/// Every board build (board crate, `board::boards::ALL`; a board added there and not here is
/// not served, one renamed fails on its missing ELF).
const ALL_BOARDS: [&str; 4] = ["reference", "olimex-p405", "olimex-p405-rs485", "nucleo-f446re"];

/// The boards to run: `DNET_EXACT_BOARDS` (comma-separated, or `all`), else every board when
/// `every` (the bring-up, a few seconds each), else the reference board.
fn boards(every: bool) -> Vec<String> {
    let chosen =
        std::env::var("DNET_EXACT_BOARDS").unwrap_or_else(|_| if every { "all" } else { "reference" }.into());
    if chosen == "all" {
        return ALL_BOARDS.iter().map(|b| b.to_string()).collect();
    }
    let boards: Vec<String> =
        chosen.split(',').map(|b| b.trim().to_string()).filter(|b| !b.is_empty()).collect();
    assert!(!boards.is_empty(), "DNET_EXACT_BOARDS names no board");
    boards
}

/// The path of `exact-firmware-serve` ([`bin`] finds it), or a failure saying how to build it.
fn serve_bin() -> PathBuf {
    let dir = std::env::var_os("DNET_BIN_DIR").map(PathBuf::from).unwrap_or_else(|| {
        let exe = std::env::current_exe().expect("the test executable's path");
        let deps = exe.parent().expect("the test executable's folder").to_path_buf();
        deps.parent().map(Path::to_path_buf).unwrap_or(deps)
    });
    assert!(
        dir.join("exact-firmware-serve").is_file(),
        "{}/exact-firmware-serve is not built: cargo build -p exact-firmware (scripts/check does), or set DNET_BIN_DIR",
        dir.display()
    );
    bin("exact-firmware-serve")
}

/// socat, or a failure saying how to get it.
fn socat() {
    let ok = std::process::Command::new("socat")
        .arg("-V")
        .stdout(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "socat is missing: apt-get install socat (scripts/check installs it)");
}

/// One board served: the SLCAN pair (serve on `a`, the master on `b`), the instrument pair (serve
/// on `b`, the instrument on `a`), the serve process.
struct Served {
    board: String,
    dir: PathBuf,
    can: PtyPair,
    serial: PtyPair,
    flash: PathBuf,
    serve: Option<Proc>,
}

impl Served {
    fn new(board: &str, test: &str) -> Served {
        let dir = scratch(&format!("{test}-{board}"));
        let flash = dir.join("settings.flash");
        Served {
            board: board.to_string(),
            dir,
            can: PtyPair::new(),
            serial: PtyPair::new(),
            flash,
            serve: None,
        }
    }

    /// Starts exact-firmware-serve (power-on `now` or `master-online`) with the instrument at
    /// `line`; waits for its start line.
    fn start(&mut self, line: &str, power_on: &str) {
        let elf = elf(&self.board);
        let args = [
            "--board",
            &self.board,
            "--elf",
            elf.to_str().expect("a UTF-8 path"),
            "--slcan",
            &self.can.a,
            "--instrument",
            &self.serial.b,
            "--instrument-line",
            line,
            "--flash",
            self.flash.to_str().expect("a UTF-8 path"),
            "--mac",
            MAC,
            "--rate",
            RATE,
            "--power-on",
            power_on,
        ];
        let serve = Proc::spawn(serve_bin(), &args);
        let end = std::time::Instant::now() + Duration::from_secs(20);
        while !serve.stderr.text().contains(" started: ") && std::time::Instant::now() < end {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert!(
            serve.stderr.text().contains(" started: "),
            "exact-firmware-serve did not start:\n{}",
            serve.dump()
        );
        self.serve = Some(serve);
        if power_on == "now" {
            // As on a bench where the board was powered first: its duplicate MAC ID check (two
            // requests 1 s apart, then 1 s) is over before a master connects. A master that comes
            // in the middle of it may allocate before the board is on-line by its own clock, and
            // `configure --read` does not repeat the allocation (reported to the lead).
            std::thread::sleep(BOARD_ONLINE);
        }
    }

    /// SIGTERM: it must save the flash file, print its summary and exit 0; the summary.
    fn stop(&mut self) -> String {
        self.stop_with("TERM")
    }

    /// [`Served::stop`] by `signal` (`TERM`, or `INT` as Ctrl-C sends): the flash file is saved,
    /// newer than before the stop.
    fn stop_with(&mut self, signal: &str) -> String {
        let mut serve = self.serve.take().expect("a running exact-firmware-serve");
        let before = std::fs::metadata(&self.flash).and_then(|m| m.modified()).ok();
        serve.signal(signal);
        let status = serve.wait(Duration::from_secs(10));
        let stderr = serve.stderr.text();
        assert_eq!(status.and_then(|s| s.code()), Some(0), "a clean stop on SIG{signal}:\n{}", serve.dump());
        assert!(stderr.contains("stopped after") && stderr.contains("flash saved to"), "{stderr}");
        let after = std::fs::metadata(&self.flash).and_then(|m| m.modified()).ok();
        assert!(
            after.is_some() && after != before,
            "{}: SIG{signal} did not save the flash file",
            self.board
        );
        eprintln!("{}: {}", self.board, stderr.lines().last().unwrap_or_default());
        stderr
    }

    /// `dnet-master --bus slcan:PTY ARGS`: stdout; fails the test on a non-zero exit.
    fn master(&self, args: &[&str]) -> String {
        let bus = format!("slcan:{}", self.can.b);
        // Every run's frames, for the failure message (a --log in `args` takes precedence).
        let log = self.dir.join("master-frames.log");
        let mut all = vec!["--bus", bus.as_str()];
        if !args.contains(&"--log") {
            all.extend_from_slice(&["--log", path(&log)]);
        }
        all.extend_from_slice(args);
        let mut master = Proc::spawn(bin("dnet-master"), &all);
        let status = master.wait(Duration::from_secs(60));
        let serve = self.serve.as_ref().map(Proc::dump).unwrap_or_default();
        let frames = std::fs::read_to_string(&log).unwrap_or_default();
        assert_eq!(
            status.and_then(|s| s.code()),
            Some(0),
            "{}: dnet-master {}\n{}\n{serve}\n--- frames:\n{frames}",
            self.board,
            args.join(" "),
            master.dump()
        );
        master.stdout.text()
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        if let Some(mut serve) = self.serve.take() {
            serve.terminate();
        }
    }
}

fn description(name: &str) -> PathBuf {
    workspace_dir().join("slave-fw/descriptions").join(name)
}

fn path(p: &Path) -> &str {
    p.to_str().expect("a UTF-8 path")
}

#[test]
#[ignore = "needs the board ELFs, socat and the programs: run by scripts/check"]
fn dnet_master_brings_the_exact_firmware_up_over_slcan_frame_for_frame() {
    socat();
    for board in boards(true) {
        let mut served = Served::new(&board, "bring-up");
        // The breaker on the instrument line: its status is byte 9 of the poll data (0x0F).
        let _breaker = Proc::spawn(bin("dnet-sim-breaker"), &["--serial", &served.serial.a]);
        served.start("9600,8N1", "master-online");
        let log = served.dir.join("connect.log");
        let out = served.master(&["--log", path(&log), "connect", "--mac", MAC]);
        assert!(out.contains("every check holds"), "{board}:\n{out}");
        let frames = read_log(&log).expect("the master's log");
        assert!(frames.len() >= BRING_UP.len(), "{board}: {} frames in the log\n{out}", frames.len());
        for (i, (got, want)) in frames.iter().zip(BRING_UP.iter()).enumerate() {
            assert_eq!(
                (got.frame.id().as_raw(), got.frame.data()),
                (want.id, want.data),
                "{board}: frame {i} ({})\n{out}",
                want.meaning
            );
        }
        served.stop();
    }
}

/// `dnet-master monitor --output HEX --epr 300 --count 10` with the breaker's description; the
/// CSV rows.
fn monitor(served: &Served, output: &str, name: &str) -> Vec<String> {
    let csv = served.dir.join(format!("{name}.csv"));
    let breaker = description("breaker.toml");
    let out = served.master(&[
        "monitor",
        "--mac",
        MAC,
        "--output",
        output,
        "--epr",
        "300",
        "--count",
        "10",
        "--description",
        path(&breaker),
        "--csv",
        path(&csv),
    ]);
    assert!(out.contains("10 samples"), "{out}");
    std::fs::read_to_string(&csv).expect("the CSV").lines().skip(1).map(str::to_string).collect()
}

#[test]
#[ignore = "needs the board ELFs, socat and the programs: run by scripts/check"]
fn the_breaker_on_the_instrument_pty_closes_and_opens() {
    socat();
    for board in boards(false) {
        let mut served = Served::new(&board, "breaker");
        let log = served.dir.join("breaker.log");
        let breaker = Proc::spawn(
            bin("dnet-sim-breaker"),
            &["--serial", &served.serial.a, "--period", "0.3", "--log", path(&log)],
        );
        served.start("9600,8N1", "now");
        let rows = monitor(&served, "0201", "close");
        assert!(rows[0].contains(",open,"), "{board}: {rows:#?}\n{}", breaker.dump());
        assert!(rows[9].contains(",closed,"), "{board}: {rows:#?}\n{}", breaker.dump());
        let rows = monitor(&served, "0102", "open");
        assert!(rows[9].contains(",open,"), "{board}: {rows:#?}\n{}", breaker.dump());
        let summary = served.stop();
        let text = std::fs::read_to_string(&log).unwrap_or_default();
        let commands: Vec<&str> =
            text.lines().filter_map(|l| l.split_once(" command ").map(|(_, c)| c)).collect();
        assert_eq!(commands, ["close", "open"], "{board}: the breaker's log\n{text}\n{summary}");
    }
}

/// The pymodbus meter on the instrument pty (19200 bit/s; the pty carries bytes, the 8E1 framing
/// is checked by exact-firmware-serve's `--instrument-line`).
fn meter(python: &Path, served: &Served) -> Proc {
    let server = workspace_dir().join("slave-fw/soft-slave/tests/modbus/server.py");
    let meter = Proc::spawn(python, &[path(&server), "--port", &served.serial.a, "--baud", "19200"]);
    assert!(
        meter.wait_stdout("ready", Duration::from_secs(20)).is_some(),
        "the meter did not start:\n{}",
        meter.dump()
    );
    meter
}

/// The meter's input registers 0..3 (0x0102, 0x0304, 0x0506, 0x0708) and holding registers
/// 100..101 (0xABCD, 0x1234) as the gateway puts them in the poll data, little-endian (the
/// `raw` column of the monitor's CSV starts with them).
const METER_DATA: &str = "0201040306050807CDAB3412";

/// `dnet-master monitor --output 11223344` with the meter's description, 10 samples; the last
/// CSV row's columns after the time (`u1:30001..`, status, freshness, stale, raw).
fn meter_monitor(served: &Served, name: &str) -> Vec<String> {
    let csv = served.dir.join(format!("{name}.csv"));
    served.master(&[
        "monitor",
        "--mac",
        MAC,
        "--output",
        "11223344",
        "--epr",
        "300",
        "--count",
        "10",
        "--description",
        path(&description("modbus-meter.toml")),
        "--csv",
        path(&csv),
    ]);
    let text = std::fs::read_to_string(&csv).expect("the CSV");
    let header = text.lines().next().unwrap_or_default();
    assert!(header.starts_with("time_s,") && header.ends_with(",raw"), "{}: {header}", served.board);
    text.lines().last().unwrap_or_default().split(',').skip(1).map(str::to_string).collect()
}

/// [`meter_monitor`], and the data must be the meter's: its registers in the poll data, its
/// write of the poll output (holding registers 16..17) seen by the meter.
fn meter_polled(served: &Served, meter: &Proc, name: &str) -> Vec<String> {
    let write = "write unit=1 function=16 address=16 values=0x2211,0x4433";
    let writes = || meter.stdout.lines().iter().filter(|l| l.contains(write)).count();
    let before = writes();
    let row = meter_monitor(served, name);
    let raw = row.last().cloned().unwrap_or_default();
    assert!(
        raw.starts_with(METER_DATA),
        "{}: poll data {row:?}, not the meter's\n{}",
        served.board,
        meter.dump()
    );
    assert_eq!(row.first().map(String::as_str), Some("258"), "{}: u1:30001 is 0x0102: {row:?}", served.board);
    let end = std::time::Instant::now() + Duration::from_secs(3);
    while writes() == before && std::time::Instant::now() < end {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(writes() > before, "{}: the meter saw no new {write}\n{}", served.board, meter.dump());
    row
}

#[test]
#[ignore = "needs the board ELFs, socat, pymodbus and the programs: run by scripts/check"]
fn configure_to_the_modbus_meter_survives_a_power_cycle() {
    socat();
    let python = require_pymodbus().expect("the pymodbus virtual environment (scripts/check makes .venv)");
    for board in boards(false) {
        let mut served = Served::new(&board, "configure");
        let meter_proc = meter(&python, &served);
        served.start("19200,8E1", "now");
        let meter_file = description("modbus-meter.toml");
        let out =
            served.master(&["--timeout", CONFIGURE_TIMEOUT, "configure", "--mac", MAC, path(&meter_file)]);
        eprintln!("{board}: configure: {}", out.lines().last().unwrap_or_default());
        let before = meter_polled(&served, &meter_proc, "before");
        // Ctrl-C, as at a terminal.
        served.stop_with("INT");

        served.start("19200,8E1", "now");
        let read_back = served.dir.join("read-back.toml");
        served.master(&[
            "--timeout",
            CONFIGURE_TIMEOUT,
            "configure",
            "--mac",
            MAC,
            "--read",
            path(&read_back),
        ]);
        let meter = DeviceDescription::load(&meter_file).expect("the meter description");
        let in_force = DeviceDescription::load(&read_back).expect("the description read back");
        assert_eq!(
            in_force.converter, meter.converter,
            "{board}: the meter's description after the power cycle"
        );
        let after = meter_polled(&served, &meter_proc, "after");
        // Everything but the freshness counter (column 8) and the status byte's sequence bits.
        assert_eq!(after[..6], before[..6], "{board}: the meter's registers after the power cycle");
        served.stop();
    }
}

/// The line has teeth: the same download with the instrument side at 9600 8E1 while the
/// firmware runs the description's 19200 8E1; the meter hears garbled characters only (counted by
/// exact-firmware-serve) and its data never reaches the poll data.
#[test]
#[ignore = "needs the board ELFs, socat, pymodbus and the programs: run by scripts/check"]
fn an_instrument_line_at_another_baud_rate_carries_no_meter_data() {
    socat();
    let python = require_pymodbus().expect("the pymodbus virtual environment (scripts/check makes .venv)");
    let board = boards(false).into_iter().next().expect("a board");
    let mut served = Served::new(&board, "wrong-line");
    let meter_proc = meter(&python, &served);
    served.start("9600,8E1", "now");
    served.master(&[
        "--timeout",
        CONFIGURE_TIMEOUT,
        "configure",
        "--mac",
        MAC,
        path(&description("modbus-meter.toml")),
    ]);
    let row = meter_monitor(&served, "wrong-line");
    let summary = served.stop();
    let raw = row.last().cloned().unwrap_or_default();
    assert!(!raw.starts_with(METER_DATA), "{board}: the meter's data came through a wrong line: {row:?}");
    assert!(!meter_proc.stdout.text().contains("write unit=1"), "{}", meter_proc.dump());
    let garbled = summary
        .split(" garbled")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.parse::<u64>().ok())
        .unwrap_or(0);
    assert!(garbled > 0, "{board}: no garbled character counted: {summary}");
}

/// `exact-firmware-serve` with its flags as given; its exit code and stderr.
fn serve_refused(args: &[&str]) -> (Option<i32>, String) {
    let mut serve = Proc::spawn(serve_bin(), args);
    let status = serve.wait(Duration::from_secs(20));
    (status.and_then(|s| s.code()), serve.stderr.text())
}

/// Bad arguments are refused before anything runs, each with the reason.
#[test]
#[ignore = "needs the board ELFs and the programs: run by scripts/check"]
fn bad_arguments_are_refused_with_the_reason() {
    let dir = scratch("serve-args");
    let nucleo = elf("nucleo-f446re");
    let flash = dir.join("short.flash");
    std::fs::write(&flash, [0u8; 100]).unwrap();
    let common = |elf: &Path, flash: &Path| {
        vec![
            "--elf".to_string(),
            path(elf).to_string(),
            "--slcan".into(),
            "/dev/null".into(),
            "--instrument".into(),
            "/dev/null".into(),
            "--flash".into(),
            path(flash).to_string(),
        ]
    };
    let new_flash = dir.join("new.flash");
    let cases: [(Vec<String>, i32, &str); 5] = [
        (vec!["--board".into(), "nope".into()], 2, "no board called 'nope'"),
        (
            vec!["--board".into(), "reference".into(), "--instrument-line".into(), "9600,8X1".into()],
            2,
            "parity is not N, E or O",
        ),
        (
            vec!["--board".into(), "reference".into(), "--elf".into(), "/nonexistent".into()],
            1,
            "scripts/firmware-size builds",
        ),
        (
            vec!["--board".into(), "nucleo-f446re".into(), "--mac".into(), "4".into()],
            1,
            "give --mac and --rate together",
        ),
        (
            vec!["--board".into(), "nucleo-f446re".into(), "--flash".into(), path(&flash).to_string()],
            1,
            "100 bytes, but the nucleo-f446re board's two settings sectors are 32768 bytes",
        ),
    ];
    for (extra, code, why) in cases {
        let mut args = common(&nucleo, &new_flash);
        // The case's own flags replace the common ones (clap refuses a repeated flag).
        for pair in extra.chunks(2) {
            if let Some(i) = args.iter().position(|a| *a == pair[0]) {
                args[i + 1] = pair[1].clone();
            } else {
                args.extend_from_slice(pair);
            }
        }
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (got, stderr) = serve_refused(&args);
        assert_eq!(got, Some(code), "{args:?}: {stderr}");
        assert!(stderr.contains(why), "{args:?}: {stderr}");
    }
    assert!(!new_flash.exists(), "a refused start wrote the flash file");
}
