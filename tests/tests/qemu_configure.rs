//! A configuration downloaded over DeviceNet to the real firmware in QEMU: the emulated board
//! (feature `emulated`, a new settings flash file) starts as the factory default, the breaker;
//! `dnet-master configure` downloads `slave-fw/descriptions/modbus-meter.toml` to it; after its
//! Identity Reset the board is the Modbus gateway and reads a real Modbus RTU slave (pymodbus,
//! `slave-fw/soft-slave/tests/modbus/server.py`) on USART2 into its poll response. Then:
//!
//! - a description the converter accepts but the board cannot run (a baud rate beyond the USART's
//!   divider) is refused at Commit_Download with the key and reason, and the gateway keeps polling
//!   the meter;
//! - a second download is cut off: QEMU is stopped after Begin_Download and the Write_Chunk
//!   requests (all but the last chunk of the breaker's image), before Commit_Download, as if the
//!   board lost power; QEMU started again on the same
//!   flash file runs the meter configuration (`configure --read` gives it back, Identity product
//!   code 2) and polls the meter again.
//!
//! ```sh
//! scripts/qemu-firmware --build-only
//! DNET_QEMU=1 DNET_PYTHON=.venv/bin/python cargo test -p system-tests --test qemu_configure -- --ignored
//! ```
//!
//! `scripts/check` runs it in its "emulated firmware run" stage (after installing the pymodbus
//! virtual environment). The firmware is built by the script beforehand: a nested `cargo build`
//! would wait for the build-directory lock that the running `cargo test` holds.
//!
//! ## The serial line
//!
//! The meter description is 19200 8E1, and the board runs it unchanged. Only the host end of
//! USART2 refuses parity: QEMU's STM32 USART model carries the data bytes only (the firmware sets
//! 9-bit words with parity and masks the parity bit off, `board::uart`; the model never sets a
//! parity error), so the line between the board and the server is a byte stream whatever the
//! firmware configures. The server's end is QEMU's chardev pseudo-terminal, whose termios refuses
//! parity (`tcsetattr` fails with EINVAL), so the server runs 19200 8N1 there: the same bytes
//! reach it as over a real 8E1 line.
//!
//! ## Time
//!
//! Everything runs in real time, each step bounded; the test prints how long the download, the
//! reset (from the Identity Reset to the board on-line again, the master's bus time) and the whole
//! run took.

use can_io::bus::slcan::SlcanBus;
use can_io::bus::{Bitrate, Bus};
use devicenet::explicit::{Request, ServiceCode};
use devicenet::objects::class;
use devicenet::Duration;
use harness_common::table::print_table;
use master_core::client::Port;
use master_core::decode::short_string;
use master_core::error::MasterError;
use master_core::master::{ConnectOptions, DeviceSummary, Master, MasterConfig};
use master_core::session::Session;
use master_harness::configure::{BEGIN_DOWNLOAD, CHUNK, CONFIGURATION_CLASS, WRITE_CHUNK};
use pty_rig::{require_pymodbus, scratch, workspace_dir, Proc};
use slave_fw::description::DeviceDescription;
use std::path::{Path, PathBuf};
use std::time::Duration as StdDuration;
use std::time::Instant as StdInstant;
use system_tests::mac;

/// QEMU's time limit for one run of the board (the script's `--timeout`).
const QEMU_LIMIT: StdDuration = StdDuration::from_secs(180);
/// The whole test's bound.
const RUN_LIMIT: StdDuration = StdDuration::from_secs(240);
/// How long the gateway may take to show the meter's registers in its poll response.
const READ_LIMIT: Duration = Duration::from_secs(5);
/// The poll response timeout: the firmware answers within milliseconds, but QEMU's virtual CPU
/// may wait for the host's scheduler.
const POLL_TIMEOUT: Duration = Duration::from_secs(1);
/// The expected packet rate the bring-up sets.
const EPR_MS: u16 = 100;
/// Input registers 0..3 of the server (0x0102, 0x0304, 0x0506, 0x0708), little-endian: input
/// bytes 0..7 of the meter description.
const INPUT_REGISTERS: [u8; 8] = [0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07];
/// Holding registers 100..101 (0xABCD, 0x1234): input bytes 8..11.
const HOLDING_100: [u8; 4] = [0xCD, 0xAB, 0x34, 0x12];
/// The poll command: written to holding registers 16..17 by the gateway.
const OUTPUT: [u8; 4] = [0x11, 0x22, 0x33, 0x44];
/// The emulated board's MAC ID (the script's default build).
const BOARD: u8 = 5;

/// `scripts/qemu-firmware` with its settings flash in a kept folder, and the QEMU it runs;
/// stopped by SIGTERM (the script then stops QEMU: the board loses power) on drop.
struct Emulator {
    script: Proc,
    usart1: String,
    usart2: String,
}

impl Emulator {
    fn start(flash_dir: &Path, scratch: &Path) -> Emulator {
        let script = workspace_dir().join("scripts/qemu-firmware");
        let pty_file = scratch.join("qemu.ptys");
        let script = Proc::spawn(
            script,
            &[
                "--no-build",
                "--timeout",
                &QEMU_LIMIT.as_secs().to_string(),
                "--flash-dir",
                flash_dir.to_str().expect("a UTF-8 scratch path"),
                "--pty-file",
                pty_file.to_str().expect("a UTF-8 scratch path"),
            ],
        );
        if script.wait_stdout("FLASH=", StdDuration::from_secs(20)).is_none() {
            panic!("scripts/qemu-firmware did not start QEMU:\n{}", script.dump());
        }
        let lines = script.stdout.lines();
        let value = |key: &str| {
            lines
                .iter()
                .find_map(|l| l.strip_prefix(key).map(str::to_string))
                .unwrap_or_else(|| panic!("no {key} line:\n{}", script.dump()))
        };
        let (usart1, usart2) = (value("USART1="), value("USART2="));
        Emulator { script, usart1, usart2 }
    }

    /// Stops QEMU at once (SIGTERM to the script, which ends QEMU): to the board, a power cut.
    fn power_off(mut self) {
        self.script.terminate();
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        self.script.terminate();
    }
}

/// The Modbus RTU slave on the board's USART2 at the meter description's 19200 baud, 8N1 on the
/// pty (module docs, "The serial line").
fn start_meter(python: &Path, usart2: &str) -> Proc {
    let server = workspace_dir().join("slave-fw/soft-slave/tests/modbus/server.py");
    let meter =
        Proc::spawn(python, &[server.to_str().expect("a UTF-8 path"), "--port", usart2, "--baud", "19200"]);
    if meter.wait_stdout("ready", StdDuration::from_secs(20)).is_none() {
        panic!("the Modbus server did not start:\n{}", meter.dump());
    }
    meter
}

/// `dnet-master --bus slcan:USART1 ARGS...`, in process: the exit status, stdout and stderr.
fn dnet_master(usart1: &str, args: &[&str]) -> (u8, String, String) {
    let bus = format!("slcan:{usart1}");
    let mut all = vec!["dnet-master", "--bus", &bus];
    all.extend_from_slice(args);
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = master_harness::cli::run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

/// Runs `steps` with a master on the SLCAN link on USART1; an error comes back with the frames
/// of the session.
fn with_master<T>(
    usart1: &str,
    steps: impl FnOnce(&mut Master<'_, '_>) -> Result<T, String>,
) -> Result<T, String> {
    let port = serialport::new(usart1, 115_200)
        .timeout(StdDuration::from_millis(10))
        .open()
        .map_err(|e| format!("open {usart1}: {e}"))?;
    let mut bus = SlcanBus::new(port, Bitrate::K250).map_err(|e| e.to_string())?;
    let bus: &mut dyn Bus = &mut bus;
    let mut session = Session::new(bus);
    let outcome = {
        let mut master = Master::new(&mut session, MasterConfig::default());
        settle(&mut master).and_then(|()| steps(&mut master))
    };
    outcome.map_err(|e| {
        let mut table = Vec::new();
        let _ = print_table(&mut table, session.records(), Some(mac(BOARD)));
        format!("{e}\nframes:\n{}", String::from_utf8_lossy(&table))
    })
}

/// Waits until the board is on-line, with a margin: after a power-on its duplicate MAC ID
/// check shows when the link opens, and the board goes on-line 1 s after its second request by
/// its own clock, which the master's request must not beat.
fn settle(master: &mut Master<'_, '_>) -> Result<(), String> {
    master.network_access().map_err(text)?;
    master.await_online(&[mac(BOARD)]).map_err(text)?;
    let until = master.session.now() + Duration::from_millis(500);
    master.idle_until(until).map_err(text)
}

fn text(e: MasterError) -> String {
    e.to_string()
}

/// A Get_Attribute_Single of the Identity object's product name (attribute 7).
fn product_name(master: &mut Master<'_, '_>) -> Result<String, String> {
    let (name, _) = master.get(mac(BOARD), class::IDENTITY, 1, 7).map_err(text)?;
    Ok(short_string(&name).unwrap_or_default())
}

/// The configuration object's state (attribute 3): 0 factory default, 1 stored image in force.
fn config_state(master: &mut Master<'_, '_>) -> Result<Vec<u8>, String> {
    master.get(mac(BOARD), CONFIGURATION_CLASS, 1, 3).map(|(d, _)| d).map_err(text)
}

/// Brings the gateway up (explicit and poll, EPR 100 ms) with [`OUTPUT`] as the poll command,
/// then polls every EPR until the input shows the meter's registers; returns the input.
fn poll_meter(master: &mut Master<'_, '_>) -> Result<Vec<u8>, String> {
    let target = mac(BOARD);
    let opts = ConnectOptions {
        target,
        epr_ms: EPR_MS,
        polls: 1,
        output: Some(OUTPUT.to_vec()),
        verify_state: false,
    };
    let summary: DeviceSummary = master.connect(&opts).map_err(text)?;
    let (produced, consumed) = (summary.produced_size.unwrap_or(0), summary.consumed_size.unwrap_or(0));
    if (produced, consumed) != (14, 4) {
        return Err(format!("poll sizes {produced}/{consumed}, the meter description's 14/4"));
    }
    let epr = Duration::from_millis(u64::from(EPR_MS));
    let start = master.session.now();
    let mut input = summary.last_input.unwrap_or_default();
    let mut next = start;
    while input.get(..8) != Some(&INPUT_REGISTERS[..]) || input.get(8..12) != Some(&HOLDING_100[..]) {
        if master.session.now() - start > READ_LIMIT {
            return Err(format!("poll data still {input:02X?} after {READ_LIMIT}"));
        }
        next += epr;
        master.idle_until(next).map_err(text)?;
        input = master.poll(target, &OUTPUT, produced, consumed, POLL_TIMEOUT).map_err(text)?;
    }
    Ok(input)
}

/// The meter description with the baud rate replaced: valid for the converter (300..=4_000_000),
/// beyond the emulated USART's divider (16 MHz / 8 = 2 Mbit/s).
fn unrunnable_meter(dir: &Path, meter: &Path) -> PathBuf {
    let text = std::fs::read_to_string(meter).expect("the meter description");
    assert!(text.contains("baud = 19200"), "the meter description changed");
    let path = dir.join("modbus-meter-4M.toml");
    std::fs::write(&path, text.replace("baud = 19200", "baud = 4000000"))
        .expect("write the scratch description");
    path
}

#[test]
#[ignore = "runs QEMU and pymodbus: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p system-tests --test qemu_configure -- --ignored"]
fn a_downloaded_modbus_configuration_runs_and_survives_a_cut_download() {
    if std::env::var("DNET_QEMU").as_deref() != Ok("1") {
        eprintln!("DNET_QEMU=1 not set: not running QEMU");
        return;
    }
    assert!(std::env::var("DNET_MAC").map_or(true, |m| m == "5"), "this test expects DNET_MAC=5");
    let Some(python) = require_pymodbus() else {
        return;
    };
    let started = StdInstant::now();
    let dir = scratch("qemu-configure");
    let flash_dir = dir.join("flash");
    std::fs::create_dir_all(&flash_dir).unwrap();
    let meter_file = workspace_dir().join("slave-fw/descriptions/modbus-meter.toml");
    let meter = DeviceDescription::load(&meter_file).expect("the meter description");
    let board = BOARD.to_string();

    // A new board: the factory default, the breaker.
    let emulator = Emulator::start(&flash_dir, &dir);
    let server = start_meter(&python, &emulator.usart2);
    let (name, state) = with_master(&emulator.usart1, |m| {
        m.open_explicit(mac(BOARD)).map_err(text)?;
        Ok((product_name(m)?, config_state(m)?))
    })
    .unwrap();
    assert_eq!((name.as_str(), state.as_slice()), ("Serial-DeviceNet Bridge", &[0][..]), "a new board");

    // The download, verified, reset and checked by dnet-master.
    let download_started = StdInstant::now();
    let log = dir.join("configure.log");
    let (code, out, err) = dnet_master(
        &emulator.usart1,
        &["--log", log.to_str().unwrap(), "configure", "--mac", &board, meter_file.to_str().unwrap()],
    );
    let download_time = download_started.elapsed();
    assert_eq!(
        code,
        0,
        "configure:\n{out}\n{err}\nframes:\n{}",
        std::fs::read_to_string(&log).unwrap_or_default()
    );
    let back_online_ms = out
        .split("after ")
        .nth(1)
        .and_then(|s| s.split(" ms").next())
        .and_then(|ms| ms.trim().parse::<u64>().ok())
        .unwrap_or_else(|| panic!("no reset time in:\n{out}"));

    // The gateway reads the meter and writes the poll command to it.
    let input =
        with_master(&emulator.usart1, poll_meter).unwrap_or_else(|e| panic!("{e}\n{}", server.dump()));
    let write = "write unit=1 function=16 address=16 values=0x2211,0x4433";
    assert!(
        server.wait_stdout(write, StdDuration::from_secs(3)).is_some(),
        "the meter saw no {write}\n{}",
        server.dump()
    );

    // A description the board cannot run is refused with the reason; the gateway keeps working.
    let unrunnable = unrunnable_meter(&dir, &meter_file);
    let (code, out, err) =
        dnet_master(&emulator.usart1, &["configure", "--mac", &board, unrunnable.to_str().unwrap()]);
    assert_eq!(code, 1, "configure of 4 Mbit/s:\n{out}\n{err}");
    assert!(
        err.contains("refused the configuration (Commit_Download)")
            && err.contains("profile.modbus.serial.baud: 4000000"),
        "the refusal and its reason:\n{err}"
    );

    // Poll again, then cut a download short: Begin_Download and every Write_Chunk request of the
    // breaker's image but the last, then the board loses power before Commit_Download.
    let breaker =
        DeviceDescription::load(&workspace_dir().join("slave-fw/descriptions/breaker.toml")).unwrap();
    let image = slave_fw::image::encode_to_vec(&breaker.converter).unwrap();
    let len = image.len();
    let sent = len.div_ceil(CHUNK) - 1;
    assert!(sent > 0, "the breaker's image takes more than one chunk");
    let (state, input_after_refusal) = with_master(&emulator.usart1, |m| {
        let input = poll_meter(m)?;
        let state = config_state(m)?;
        // A download is refused while I/O is established.
        m.release(mac(BOARD), devicenet::messages::AllocationChoice::POLL).map_err(text)?;
        let size = u16::try_from(len).unwrap().to_le_bytes();
        let begin = Request {
            service: ServiceCode::from(BEGIN_DOWNLOAD),
            class: CONFIGURATION_CLASS,
            instance: 1,
            data: &size,
        };
        m.request_ok(mac(BOARD), Port::Explicit, &begin).map_err(text)?;
        for (k, part) in image.chunks(CHUNK).take(sent).enumerate() {
            let mut data = u16::try_from(k * CHUNK).unwrap().to_le_bytes().to_vec();
            data.extend_from_slice(part);
            let write = Request {
                service: ServiceCode::from(WRITE_CHUNK),
                class: CONFIGURATION_CLASS,
                instance: 1,
                data: &data,
            };
            m.request_ok(mac(BOARD), Port::Explicit, &write).map_err(text)?;
        }
        Ok((state, input))
    })
    .unwrap();
    assert_eq!(state, [1], "the meter's stored image is in force after the refusal");
    assert_eq!(input_after_refusal[..12], input[..12]);
    emulator.power_off();
    drop(server);

    // Power on again, on the same flash file: the meter configuration is in force.
    let restart_started = StdInstant::now();
    let emulator = Emulator::start(&flash_dir, &dir);
    let server = start_meter(&python, &emulator.usart2);
    // First the master that waits out the board's power-on (`settle`), then dnet-master.
    let (input, name, code) = with_master(&emulator.usart1, |m| {
        let input = poll_meter(m)?;
        let code = m.get_u16(mac(BOARD), class::IDENTITY, 1, 3).map_err(text)?;
        Ok((input, product_name(m)?, code))
    })
    .unwrap_or_else(|e| panic!("{e}\n{}", server.dump()));
    assert_eq!((name.as_str(), code), ("Modbus-DeviceNet Gateway", Some(2)));
    let read_back = dir.join("read-back.toml");
    let (code, out, err) =
        dnet_master(&emulator.usart1, &["configure", "--mac", &board, "--read", read_back.to_str().unwrap()]);
    assert_eq!(code, 0, "configure --read:\n{out}\n{err}");
    let in_force = DeviceDescription::load(&read_back).expect("the description read back");
    assert_eq!(in_force.converter, meter.converter, "the meter description, as downloaded");
    let restart_time = restart_started.elapsed();
    drop(server);
    drop(emulator);

    let total = started.elapsed();
    assert!(total < RUN_LIMIT, "took {total:?}");
    eprintln!(
        "configure (network access, {len_meter}-byte download, read-back, reset, checks) {:.1} s, of which the reset {back_online_ms} ms; \
         restart after the cut download to the meter polled {:.1} s; last poll {input:02X?}; whole test {:.1} s",
        download_time.as_secs_f64(),
        restart_time.as_secs_f64(),
        total.as_secs_f64(),
        len_meter = slave_fw::image::encode_to_vec(&meter.converter).unwrap().len(),
    );
    let _ = std::fs::remove_dir_all(&dir);
}
