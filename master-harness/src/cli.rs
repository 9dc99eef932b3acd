//! The `dnet-master` command line: options, bus opening, and the human and JSON reports.
//!
//! Exit status: 0 when every check holds, 1 when a check failed, the device diverged, timed out
//! or answered with an error, or a replay compared nothing; 2 for a usage or configuration error
//! (bad option, unknown bus, bad or unwritable file); 130 / 143 when SIGINT / SIGTERM stopped the
//! command ([`harness_common::console`]).
//!
//! Every command ends the same way, however it ended: the connections it allocated are released
//! through the Group 2 Only port (not with `--keep`; not when the bus itself failed), then the CSV
//! and the log are flushed and the result printed (with `"interrupted"` in the JSON when a signal
//! stopped it). Output files are created before the bus is touched.

use crate::configure;
use crate::replay::{self, ReplayOptions};
use can_io::bus::{Bitrate, Bus, BusSpec};
use can_io::log::{LogEntry, LogWriter};
use can_io::pcap::{PcapBus, PcapWriter};
use can_io::sim::PowerOn;
use can_io::trace::write::log_format;
use can_io::trace::{read_trace, ReadOptions, Trace, TraceFormat};
use clap::{Args, Parser, Subcommand};
use converter_sim::{OpenError, SimSetup};
use devicenet::explicit::ServiceCode;
use devicenet::{Duration, Instant, MacId};
use dnet_conformance::command::ConformanceCommand;
use dnet_scanner::monitor::{self, InputLayout, MonitorOptions};
use dnet_scanner::params;
use dnet_scanner::scan::{self, ScanReport};
use harness_common::console::{Console, Progress};
use harness_common::error::HarnessError;
use harness_common::table::{print_table, record_json, RecordJson};
use master_core::client::ReplyBody;
use master_core::decode::{self, Decoder};
use master_core::error::MasterError;
use master_core::io::{IoKind, IoOptions, IoSummary};
use master_core::master::{ConnectOptions, DeviceSummary, Master, MasterConfig};
use master_core::recovery::{RecoverOptions, RecoveryReport};
use master_core::session::Session;
use serde_json::json;
use slave_fw::converter::ConverterConfig;
use slave_fw::description::DeviceDescription;
use std::ffi::OsString;
use std::io::Write;
use std::path::PathBuf;

/// Parses a MAC ID: `0..=63`, decimal or `0x` hex.
pub fn parse_mac(s: &str) -> Result<MacId, String> {
    let v = parse_number(s)?;
    u8::try_from(v).ok().and_then(MacId::new).ok_or_else(|| format!("MAC ID {s} is out of range 0..=63"))
}

/// Parses a decimal or `0x` hexadecimal number.
pub fn parse_number(s: &str) -> Result<u32, String> {
    let t = s.trim();
    let r = match t.strip_prefix("0x").or_else(|| t.strip_prefix("0X")) {
        Some(h) => u32::from_str_radix(h, 16),
        None => t.parse::<u32>(),
    };
    r.map_err(|_| format!("'{s}' is not a number (decimal, or hex with 0x)"))
}

fn parse_u16(s: &str) -> Result<u16, String> {
    u16::try_from(parse_number(s)?).map_err(|_| format!("{s} does not fit in 16 bits"))
}

fn parse_u8(s: &str) -> Result<u8, String> {
    u8::try_from(parse_number(s)?).map_err(|_| format!("{s} does not fit in 8 bits"))
}

/// Parses hex bytes: `0201`, `02 01`, `02:01`, `02-01`.
pub fn parse_hex(s: &str) -> Result<Vec<u8>, String> {
    let digits: String = s.chars().filter(|c| !matches!(c, ' ' | ':' | '-' | '_')).collect();
    let digits = digits.strip_prefix("0x").unwrap_or(&digits);
    if digits.len() % 2 != 0 {
        return Err(format!("'{s}': odd number of hex digits"));
    }
    (0..digits.len())
        .step_by(2)
        .map(|i| {
            digits
                .get(i..i + 2)
                .and_then(|d| u8::from_str_radix(d, 16).ok())
                .ok_or_else(|| format!("'{s}': invalid hex digit at position {}", i + 1))
        })
        .collect()
}

/// Hex bytes given on the command line (`0201`, `02 01`, `02:01`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HexBytes(pub Vec<u8>);

impl std::str::FromStr for HexBytes {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        parse_hex(s).map(HexBytes)
    }
}

/// When the simulated slaves power on (`--slave-power-on`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PowerOnArg(pub PowerOn);

impl std::str::FromStr for PowerOnArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "master-online" => Ok(PowerOnArg(PowerOn::WhenMasterOnline)),
            "start" => Ok(PowerOnArg(PowerOn::AtStart)),
            ms => parse_number(ms)
                .map(|ms| PowerOnArg(PowerOn::At(Instant::from_millis(u64::from(ms)))))
                .map_err(|_| format!("'{s}': expected master-online, start, or a time in ms")),
        }
    }
}

/// The I/O connection `connect` and `monitor` bring up (`docs/io-connections.md`).
#[derive(Args, Debug, Clone, Default)]
pub struct IoArgs {
    /// The I/O connection: poll (Connection 2, the reference bring-up), strobe (bit-strobe,
    /// Connection 3), cos (change of state) or cyclic (Connection 4, the master's data on
    /// Connection 2).
    #[arg(long, default_value = "poll", value_name = "KIND")]
    pub io: IoKind,
    /// cos / cyclic: allocate with acknowledge suppression (0x40): no acknowledgements either way.
    #[arg(long)]
    pub ack_suppression: bool,
    /// cos / cyclic: production inhibit time to set, ms (Connection 4 attribute 17) [default: the
    /// device's].
    #[arg(long, value_name = "MS", value_parser = parse_u16)]
    pub inhibit: Option<u16>,
    /// cos / cyclic: acknowledge timer to set, ms (Acknowledge Handler attribute 1) [default: the
    /// device's, read back].
    #[arg(long, value_name = "MS", value_parser = parse_u16)]
    pub ack_timer: Option<u16>,
    /// cos / cyclic: retry limit to set (Acknowledge Handler attribute 2) [default: the device's,
    /// read back].
    #[arg(long, value_name = "N", value_parser = parse_u8)]
    pub retry_limit: Option<u8>,
}

impl IoArgs {
    /// The options, timing judged unless the bus buffers frames (SLCAN).
    pub fn options(&self, bus: &BusSpec) -> IoOptions {
        IoOptions {
            kind: self.io,
            ack_suppression: self.ack_suppression,
            inhibit_ms: self.inhibit,
            ack_timer_ms: self.ack_timer,
            retry_limit: self.retry_limit,
            judge_timing: judges_timing(bus),
        }
    }
}

/// `false` on SLCAN, whose frames arrive in bursts from a serial line: intervals are noted, not
/// judged (as the conformance suite does, [`dnet_conformance::BUFFERED_TIMING`]).
fn judges_timing(bus: &BusSpec) -> bool {
    !matches!(bus, BusSpec::Slcan { .. })
}

/// `dnet-master`: a bench DeviceNet master.
#[derive(Debug, Parser)]
#[command(name = "dnet-master", version = harness_common::version(), about = "A bench DeviceNet master: brings a device up like a scanner and verifies every frame, replays transcripts, scans, reads and writes attributes, monitors polled data, decodes traces of every common format.", long_about = None)]
pub struct Cli {
    /// The bus: `sim`, `socketcan:IFACE` or `slcan:PATH[@SERIALBAUD]`.
    #[arg(long, global = true, default_value = "sim")]
    pub bus: BusSpec,
    /// The master's MAC ID [default: 0; replay: the transcript's master].
    #[arg(long, global = true, value_parser = parse_mac)]
    pub master_mac: Option<MacId>,
    /// CAN bit rate: 125k, 250k or 500k (sim and slcan).
    #[arg(long, global = true, default_value = "250k")]
    pub bitrate: Bitrate,
    /// Write every frame seen to FILE, in the format --format names, else the one FILE's
    /// extension names (.asc, .trc, .csv), else candump -L.
    #[arg(long, global = true, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// The --log file's format: candump, trc (PCAN-View 2.1), asc (Vector) or csv (python-can's
    /// layout) [default: from the file's extension, else candump]; each is read back by `decode`,
    /// `replay` and python-can.
    #[arg(long, global = true, value_name = "FORMAT", value_parser = parse_trace_format)]
    pub format: Option<TraceFormat>,
    /// Write every frame seen to FILE as a pcap capture (link type SocketCAN, for Wireshark).
    #[arg(long, global = true, value_name = "FILE")]
    pub pcap: Option<PathBuf>,
    /// Print a machine-readable JSON result instead of text.
    #[arg(long, global = true)]
    pub json: bool,
    /// Also print the frame-by-frame table (connect and replay always do).
    #[arg(long, global = true)]
    pub frames: bool,
    /// Explicit response timeout in ms.
    #[arg(long, global = true, default_value_t = 1000, value_name = "MS")]
    pub timeout: u64,
    /// Leave the connections this command allocated in place when it ends (by default every
    /// command releases what it allocated).
    #[arg(long, global = true)]
    pub keep: bool,
    /// sim: pace the simulation in real time.
    #[arg(long, global = true)]
    pub realtime: bool,
    /// sim: MAC IDs of the simulated slaves (comma-separated) [default: one device at the
    /// command's --mac].
    #[arg(long, global = true, value_delimiter = ',', value_parser = parse_mac)]
    pub slave_mac: Vec<MacId>,
    /// sim: a device description file (TOML) for the soft slaves instead of the reference device.
    #[arg(long, global = true, value_name = "FILE")]
    pub slave_config: Option<PathBuf>,
    /// sim: when the slaves power on: master-online (as in the capture), start, or a time in ms.
    #[arg(long, global = true, default_value = "master-online", value_name = "WHEN")]
    pub slave_power_on: PowerOnArg,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// The full bring-up of devicenet-notes §2, every frame checked.
    Connect {
        /// The device's MAC ID [default: the --slave-config description's, else 5].
        #[arg(long, value_parser = parse_mac)]
        mac: Option<MacId>,
        /// Expected packet rate of the poll connection, ms.
        #[arg(long, default_value_t = 100)]
        epr: u16,
        /// Poll cycles after the connection is established.
        #[arg(long, default_value_t = 1)]
        polls: u32,
        /// Poll output data in hex (default: zeros of the consumed size).
        #[arg(long)]
        output: Option<HexBytes>,
        /// Read the connection states back and check the 4 x EPR watchdog (adds frames).
        #[arg(long)]
        verify_state: bool,
        /// The I/O connection.
        #[command(flatten)]
        io: IoArgs,
    },
    /// Find a node that is Communication Faulted after a duplicate MAC ID (Offline Connection
    /// Set: Who, then the answers listed); with --to give it a new MAC ID (long Identify, offline
    /// ownership, Change MAC ID) and watch it come on-line there.
    Recover {
        /// The MAC ID at which the node faulted.
        #[arg(long, value_parser = parse_mac)]
        mac: MacId,
        /// The MAC ID to give it [default: only list the faulted nodes].
        #[arg(long, value_parser = parse_mac)]
        to: Option<MacId>,
        /// The serial number of the node to recover, when several answer (decimal or 0x hex).
        #[arg(long, value_parser = parse_number)]
        serial: Option<u32>,
        /// How long the answers to Who are collected, ms.
        #[arg(long, default_value_t = 500, value_name = "MS")]
        window: u64,
        /// Who's time-delay byte offset (0-6): each node answers after byte N of its answer in ms.
        #[arg(long, default_value_t = master_core::recovery::TIME_DELAY_OFFSET, value_parser = clap::value_parser!(u8).range(0..=6))]
        delay_byte: u8,
        /// How many times Who is sent, 1 s apart, while no node answers.
        #[arg(long, default_value_t = master_core::recovery::WHO_ATTEMPTS, value_parser = clap::value_parser!(u8).range(1..))]
        attempts: u8,
    },
    /// Replay a candump -L transcript against the device at MAC N.
    Replay {
        /// The transcript (candump -L, pcap, pcapng, trc, asc, blf or csv, detected from the
        /// content; `-`: standard input).
        transcript: PathBuf,
        /// How the trace is read.
        #[command(flatten)]
        input: TraceInput,
        /// The device under test [default: the transcript's device, when it has just one].
        #[arg(long, value_parser = parse_mac)]
        mac: Option<MacId>,
        /// How late an expected frame may be, ms.
        #[arg(long, default_value_t = 1000)]
        tolerance: u64,
        /// How long to watch for extra frames after the transcript, ms.
        #[arg(long, default_value_t = 500)]
        settle: u64,
        /// Begin where the device is on-line, for a device that is not powered on in step with
        /// the transcript (without it, a transcript that begins with the device's power-up needs
        /// the device powered on then; on a real bus replay prints the window): `--from-online`
        /// skips the transcript's start-up (the device is on-line already); `--from-online=wait`
        /// first waits for the device's own duplicate MAC ID check (power it on after starting the
        /// replay).
        #[arg(long, value_name = "WAIT", num_args = 0..=1, require_equals = true, default_missing_value = "now")]
        from_online: Option<replay::FromOnline>,
        /// Data not compared: `io`, the data of the device's I/O messages (poll, bit-strobe,
        /// change-of-state/cyclic responses), which differs from a recording of live values;
        /// their identifier and length are still compared, and they are reported as not compared.
        #[arg(long, value_name = "WHAT", value_parser = ["io"])]
        ignore_data: Option<String>,
    },
    /// Find every device: identity and I/O sizes.
    Scan {
        /// First MAC ID.
        #[arg(long, default_value_t = 0, value_parser = parse_u8)]
        from: u8,
        /// Last MAC ID.
        #[arg(long, default_value_t = 63, value_parser = parse_u8)]
        to: u8,
    },
    /// Keep every node of a scan list in I/O, as a DeviceNet scanner does (without --scanlist:
    /// a scan list from a network scan); a table of the nodes' status at the end.
    Scanner {
        /// The scan list (TOML).
        #[arg(long, value_name = "FILE.toml")]
        scanlist: Option<PathBuf>,
        /// Write the scan list in force (built by the network scan) to FILE.
        #[arg(long, value_name = "FILE")]
        write_scanlist: Option<PathBuf>,
        /// Stop after N full scan cycles (default: until SIGINT / SIGTERM).
        #[arg(long, value_name = "N")]
        cycles: Option<u64>,
    },
    /// The scanner with its web console: `--listen ADDR` serves the network, device and trace
    /// views (and their JSON API) while every node of the scan list is kept in I/O; samples go to
    /// an SQLite history, and with --mqtt to a broker.
    Ui {
        /// The address to serve the console on (port 0: any free port; the URL is printed).
        #[arg(long, default_value = "127.0.0.1:8080", value_name = "ADDR")]
        listen: String,
        /// The scan list (TOML) [default: built from a network scan].
        #[arg(long, value_name = "FILE.toml")]
        scanlist: Option<PathBuf>,
        /// The sample history (SQLite; created when missing).
        #[arg(long, value_name = "FILE", default_value = "dnet-history.sqlite")]
        history: PathBuf,
        /// Keep no history (the device view's plot and the CSV export then have nothing).
        #[arg(long)]
        no_history: bool,
        /// Publish node status and decoded values to an MQTT broker: `mqtt://HOST[:PORT][/PREFIX]`.
        #[arg(long, value_name = "URL")]
        mqtt: Option<String>,
        /// Where the console's recordings go.
        #[arg(long, value_name = "DIR", default_value = ".")]
        record_dir: PathBuf,
        /// Stop after N full scan cycles (default: until SIGINT / SIGTERM).
        #[arg(long, value_name = "N")]
        cycles: Option<u64>,
    },
    /// Get_Attribute_Single.
    Get {
        /// Device MAC ID.
        #[arg(value_parser = parse_mac)]
        mac: MacId,
        /// Class ID.
        #[arg(value_parser = parse_u16)]
        class: u16,
        /// Instance ID.
        #[arg(value_parser = parse_u16)]
        instance: u16,
        /// Attribute ID.
        #[arg(value_parser = parse_u8)]
        attribute: u8,
    },
    /// Set_Attribute_Single.
    Set {
        /// Device MAC ID.
        #[arg(value_parser = parse_mac)]
        mac: MacId,
        /// Class ID.
        #[arg(value_parser = parse_u16)]
        class: u16,
        /// Instance ID.
        #[arg(value_parser = parse_u16)]
        instance: u16,
        /// Attribute ID.
        #[arg(value_parser = parse_u8)]
        attribute: u8,
        /// The value in hex.
        value: HexBytes,
    },
    /// Connect, then show the polled data decoded by the device profile.
    Monitor {
        /// The device's MAC ID [default: the --description or --slave-config description's, else 5].
        #[arg(long, value_parser = parse_mac)]
        mac: Option<MacId>,
        /// Poll period (expected packet rate), ms.
        #[arg(long, default_value_t = 100)]
        epr: u16,
        /// Poll output data in hex (e.g. 0201 closes the breaker).
        #[arg(long)]
        output: Option<HexBytes>,
        /// Record every sample in FILE (CSV).
        #[arg(long, value_name = "FILE")]
        csv: Option<PathBuf>,
        /// Stop after K samples.
        #[arg(long)]
        count: Option<u64>,
        /// Stop after this many seconds of monitoring (bus time; sim default 10 s unless --realtime).
        #[arg(long)]
        duration: Option<f64>,
        /// Report a lost connection (bus error, poll unanswered) and reconnect instead of stopping.
        #[arg(long)]
        reconnect: bool,
        /// Decode the polled data with this device description (TOML) [default on sim: the
        /// --slave-config description, else the reference breaker; on a real bus: raw bytes].
        #[arg(long, value_name = "FILE")]
        description: Option<PathBuf>,
        /// The I/O connection.
        #[command(flatten)]
        io: IoArgs,
    },
    /// Download a device description to the device: checked, downloaded, read back, reset, and
    /// the device checked against it; with --read, upload the configuration in force as a
    /// description file.
    Configure {
        /// The device's MAC ID.
        #[arg(long, value_parser = parse_mac)]
        mac: MacId,
        /// The device description (TOML) to download.
        #[arg(required_unless_present = "read", conflicts_with = "read")]
        description: Option<PathBuf>,
        /// Upload: write the configuration in force to FILE as a description (`-`: standard
        /// output).
        #[arg(long, value_name = "FILE")]
        read: Option<PathBuf>,
    },
    /// Read (and with --set write) every parameter of the device: its Parameter object, or the
    /// `[Params]` of an EDS through their link paths.
    Params {
        /// The device's MAC ID.
        #[arg(long, value_parser = parse_mac)]
        mac: MacId,
        /// Take the parameter list from this EDS.
        #[arg(long, value_name = "FILE")]
        eds: Option<PathBuf>,
        /// Write a parameter first: NAME=VALUE (repeatable).
        #[arg(long = "set", value_name = "NAME=VALUE")]
        set: Vec<String>,
    },
    /// Pretty-print a trace as DeviceNet messages (candump -L, pcap, pcapng, PCAN trc, Vector
    /// asc and blf, csv).
    Decode {
        /// The trace (its format is detected from the content; `-`: standard input).
        logfile: PathBuf,
        /// How the trace is read.
        #[command(flatten)]
        input: TraceInput,
    },
    /// The conformance suite against a group-2-only slave: network access, connection set,
    /// explicit messaging, connections, timing (exit 0 only when no check fails).
    Conformance {
        /// The device's MAC ID [default: the --slave-config description's, else 5].
        #[arg(long, value_parser = parse_mac)]
        mac: Option<MacId>,
        /// Also write a self-contained HTML report with a sequence diagram per check (with
        /// --self-test: the matrix and every mutant's finding).
        #[arg(long, value_name = "FILE")]
        html: Option<PathBuf>,
        /// Prove that every check can fail: run the suite on the simulated bus against the
        /// reference device and against mutant devices, each with one deliberate fault, and print
        /// the matrix check x mutant (exit 0 only when every check fails against at least one
        /// mutant, every mutant fails its target check and the reference device passes).
        #[arg(long, conflicts_with = "mac")]
        self_test: bool,
        /// With --self-test: print the matrix as Markdown tables (as in the README).
        #[arg(long, requires = "self_test")]
        markdown: bool,
    },
}

/// The description files a run reads, each read once, before the bus is touched.
struct Descriptions {
    /// `--slave-config`: the simulated devices' configuration.
    slave: Option<DeviceDescription>,
    /// The command's own description: `monitor --description`, `configure FILE`.
    command: Option<DeviceDescription>,
}

impl Descriptions {
    fn load(cli: &Cli) -> Result<Descriptions, HarnessError> {
        let own = match &cli.command {
            Command::Monitor { description: Some(path), .. }
            | Command::Configure { description: Some(path), .. } => Some(path),
            _ => None,
        };
        Ok(Descriptions {
            slave: cli.slave_config.as_deref().map(DeviceDescription::load).transpose()?,
            command: own.map(|p| DeviceDescription::load(p)).transpose()?,
        })
    }
}

/// Opens the bus the options name: on `sim`, the simulated converters of `slave` (the
/// `--slave-config` description, else the reference device) / `--slave-mac` / `--slave-power-on`
/// ([`converter_sim::open_bus`], the one way every program opens a bus); with no `--slave-mac`,
/// one device at `device` (the command's `--mac`). `replay_power_on` is how a replayed
/// transcript meets its device ([`replay::sim_start`]): a simulated device with the default
/// power-on policy is powered on, or brought on-line before the first frame, as it says.
pub fn open_bus(
    cli: &Cli,
    slave: Option<&ConverterConfig>,
    device: Option<MacId>,
    replay_power_on: Option<replay::SimStart>,
) -> Result<Box<dyn Bus>, HarnessError> {
    let mut setup = match slave {
        Some(config) => SimSetup::described(config.clone()),
        None => SimSetup::reference(),
    };
    setup.macs = match (cli.slave_mac.is_empty(), device) {
        (true, Some(mac)) => vec![mac],
        _ => cli.slave_mac.clone(),
    };
    setup.power_on = match (cli.slave_power_on.0, replay_power_on) {
        (PowerOn::WhenMasterOnline, Some(replay::SimStart::PowerOnAt(after))) => {
            PowerOn::At(Instant::ZERO + after)
        }
        (PowerOn::WhenMasterOnline, Some(replay::SimStart::PowerOnAtStart)) => PowerOn::AtStart,
        (PowerOn::WhenMasterOnline, Some(replay::SimStart::OnlineBeforeStart)) => {
            setup.online_before_start = true;
            PowerOn::WhenMasterOnline
        }
        (policy, _) => policy,
    };
    // The console is watched by people: its simulation runs in real time.
    setup.realtime = cli.realtime || matches!(cli.command, Command::Ui { .. });
    converter_sim::open_bus(&cli.bus, cli.bitrate, &setup).map_err(|e| match e {
        OpenError::Setup(msg) => HarnessError::Usage(msg),
        OpenError::Bus(e) => HarnessError::from(e),
    })
}

/// What a command produced, for printing.
struct Outcome {
    /// The command's own result, as JSON and as text lines.
    json: serde_json::Value,
    text: String,
    /// Exit status.
    code: u8,
}

/// The signal that interrupted a command, if one did.
fn interruption(e: &HarnessError) -> Option<i32> {
    match e {
        HarnessError::Master(MasterError::Interrupted { signal }) => Some(*signal),
        _ => None,
    }
}

/// Runs `dnet-master` with `args` (the program name first), writing to `out` and `err`; returns
/// the exit status. `terminal` says whether `out` is a terminal (monitor refreshes in place). No
/// progress lines, and only [`Stop::request`](master_core::stop::Stop::request) stops it: see
/// [`run_with`].
pub fn run<I, T>(args: I, out: &mut dyn Write, err: &mut dyn Write, terminal: bool) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    run_with(args, out, err, &Console { stdout_terminal: terminal, ..Console::plain() })
}

/// Runs `dnet-master` in `console` (the binary: terminals as they are, SIGINT / SIGTERM setting
/// its stop).
pub fn run_with<I, T>(args: I, out: &mut dyn Write, err: &mut dyn Write, console: &Console) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let mut cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let text = e.render().to_string();
            let code = u8::try_from(e.exit_code()).unwrap_or(2);
            let _ = if code == 0 { write!(out, "{text}") } else { write!(err, "{text}") };
            return code;
        }
    };
    // The --log file's format, for every command that writes it: --format, else the file's
    // extension, else candump (the rule of every program with --log).
    let result = match cli.log.as_deref().map(|path| log_format(path, cli.format)).transpose() {
        Ok(format) => {
            cli.format = format.or(cli.format);
            execute(&cli, out, err, console)
        }
        Err(e) => Err(HarnessError::Usage(e.to_string())),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            if cli.json {
                let _ = writeln!(out, "{}", json!({ "ok": false, "error": e.to_string() }));
            }
            let _ = writeln!(err, "error: {e}");
            e.exit_code()
        }
    }
}

/// The device a command addresses when `--mac` is left out: the MAC of the description the
/// command was given (`monitor --description`), else of `--slave-config`'s, else 5 (the reference
/// converter's).
fn default_device(descriptions: &Descriptions) -> MacId {
    descriptions
        .command
        .as_ref()
        .or(descriptions.slave.as_ref())
        .map_or(MacId::from_low_bits(5), |d| d.converter.device.mac_id)
}

/// The device the command addresses, with the defaults resolved.
fn command_device(
    cli: &Cli,
    descriptions: &Descriptions,
    transcript: Option<&[LogEntry]>,
) -> Result<Option<MacId>, HarnessError> {
    Ok(match &cli.command {
        Command::Connect { mac, .. } | Command::Monitor { mac, .. } | Command::Conformance { mac, .. } => {
            Some(mac.unwrap_or_else(|| default_device(descriptions)))
        }
        Command::Get { mac, .. }
        | Command::Set { mac, .. }
        | Command::Configure { mac, .. }
        | Command::Params { mac, .. }
        | Command::Recover { mac, .. } => Some(*mac),
        Command::Replay { mac: Some(m), .. } => Some(*m),
        Command::Replay { mac: None, transcript: path, .. } => {
            let devices = replay::transcript_devices(transcript.unwrap_or_default());
            match devices.as_slice() {
                [one] => Some(*one),
                [] => {
                    return Err(HarnessError::Usage(format!(
                        "{}: the transcript has no device frames; give the device with --mac",
                        path.display()
                    )))
                }
                many => {
                    return Err(HarnessError::Usage(format!(
                        "{}: the transcript has several devices (MAC {}); choose one with --mac",
                        path.display(),
                        many.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
                    )))
                }
            }
        }
        Command::Scan { .. } | Command::Decode { .. } | Command::Scanner { .. } | Command::Ui { .. } => None,
    })
}

/// The master's MAC: `--master-mac`, else (replay) the transcript's master, else 0. A replay sends
/// the transcript's frames as recorded, so a `--master-mac` that differs from the transcript's
/// master is refused.
fn master_mac(cli: &Cli, transcript: Option<&[LogEntry]>) -> Result<MacId, HarnessError> {
    let recorded = transcript.and_then(replay::transcript_master);
    match (cli.master_mac, recorded) {
        (Some(given), Some(rec)) if given != rec => Err(HarnessError::Usage(format!(
            "--master-mac {given}: the transcript's master is MAC {rec}, and a replay sends its frames as recorded; leave --master-mac out or give {rec}"
        ))),
        (Some(given), _) => Ok(given),
        (None, Some(rec)) => Ok(rec),
        (None, None) => Ok(MacId::from_low_bits(0)),
    }
}

/// How `decode` and `replay` read their trace.
#[derive(Args, Debug, Clone, Default)]
pub struct TraceInput {
    /// Stop at the first line or record that is not DeviceNet traffic (an error frame, an
    /// extended, remote or FD frame, a line of no known kind), instead of skipping and counting it.
    #[arg(long)]
    pub strict: bool,
    /// The trace's format, when detection from the content is not wanted: candump, pcap, pcapng,
    /// trc, asc, blf, csv.
    #[arg(long, value_name = "FORMAT", value_parser = parse_trace_format)]
    pub input_format: Option<TraceFormat>,
}

impl TraceInput {
    fn options(&self) -> ReadOptions {
        ReadOptions { strict: self.strict, format: self.input_format }
    }
}

fn parse_trace_format(text: &str) -> Result<TraceFormat, String> {
    TraceFormat::from_name(text).ok_or_else(|| {
        let names: Vec<&str> = TraceFormat::ALL.iter().map(|f| f.name()).collect();
        format!("unknown trace format '{text}' (one of: {})", names.join(", "))
    })
}

/// Reads a trace for `decode` or `replay` and says on `err` what was skipped (the first
/// [`can_io::trace::NAMED_SKIPS`] by line, then the count).
fn read_input(
    path: &std::path::Path,
    input: &TraceInput,
    err: &mut dyn Write,
) -> Result<Trace, HarnessError> {
    let trace = read_trace(path, input.options())?;
    let name =
        if path.as_os_str() == "-" { "standard input".to_string() } else { path.display().to_string() };
    if trace.skipped_count > 0 {
        let unit = if matches!(trace.format, TraceFormat::Pcap | TraceFormat::Pcapng | TraceFormat::Blf) {
            "record"
        } else {
            "line"
        };
        let _ = writeln!(
            err,
            "dnet-master: {name}: {} {unit}{} skipped, not DeviceNet traffic (--strict stops at the first):",
            trace.skipped_count,
            if trace.skipped_count == 1 { "" } else { "s" }
        );
        for s in &trace.skipped {
            let _ = writeln!(err, "  {name}:{}: {}", s.line, s.reason);
        }
        if trace.skipped_count > trace.skipped.len() {
            let _ = writeln!(err, "  ... and {} more", trace.skipped_count - trace.skipped.len());
        }
    }
    if trace.entries.is_empty() {
        return Err(HarnessError::NothingCompared(format!(
            "{name}: no DeviceNet frames in this {} trace ({} skipped)",
            trace.format, trace.skipped_count
        )));
    }
    Ok(trace)
}

/// How `monitor` decodes the polled data: `--description`, else on the simulated bus the
/// `--slave-config` description or the reference device (which the simulated device then is), else
/// (a real bus, nothing known of the device) raw bytes. `--slave-config` describes only the
/// simulated devices, so on a real bus it does not choose the decoding.
fn monitor_layout(cli: &Cli, descriptions: &Descriptions) -> InputLayout {
    match (&descriptions.command, &descriptions.slave, &cli.bus) {
        (Some(d), _, _) | (None, Some(d), BusSpec::Sim) => InputLayout::from_converter(&d.converter),
        (None, None, BusSpec::Sim) => InputLayout::from_converter(&DeviceDescription::reference().converter),
        (None, _, _) => InputLayout::raw(),
    }
}

/// `conformance --self-test`: the suite against the reference device and every mutant, each on a
/// simulated bus of its own (`--bus sim` only: the mutants are simulated devices).
fn self_test_command(
    cli: &Cli,
    markdown: bool,
    html: Option<&std::path::Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
    stderr_terminal: bool,
) -> Result<u8, HarnessError> {
    use dnet_conformance::self_test;
    if cli.bus != BusSpec::Sim {
        return Err(HarnessError::Usage(format!(
            "--self-test runs the suite against simulated mutant devices: it needs --bus sim, not {}",
            cli.bus
        )));
    }
    let unused = [
        (cli.log.is_some(), "--log"),
        (cli.pcap.is_some(), "--pcap"),
        (cli.keep, "--keep"),
        (cli.realtime, "--realtime"),
        (!cli.slave_mac.is_empty(), "--slave-mac"),
        (cli.slave_config.is_some(), "--slave-config"),
        (cli.frames, "--frames"),
    ];
    if let Some((_, flag)) = unused.iter().find(|(given, _)| *given) {
        return Err(HarnessError::Usage(format!(
            "{flag} has no meaning with --self-test, which builds its own devices and buses"
        )));
    }
    if markdown && cli.json {
        return Err(HarnessError::Usage("--markdown and --json: choose one".into()));
    }
    // The page's file is created before the run, so a path that cannot be written fails at once.
    let mut page = html.map(|p| create_output(p).map(|f| (f, p))).transpose()?;
    let config = MasterConfig {
        mac: cli.master_mac.unwrap_or(MacId::from_low_bits(0)),
        response_timeout: Duration::from_millis(cli.timeout.max(1)),
        ..MasterConfig::default()
    };
    struct Shown<'e>(&'e mut dyn Write, bool);
    impl self_test::SelfTestObserver for Shown<'_> {
        fn start(&mut self, n: usize, total: usize, mutant: Option<&dnet_conformance::mutants::Mutant>) {
            if self.1 {
                let what = mutant.map_or("the reference device".to_string(), |m| format!("mutant {}", m.id));
                let _ = write!(self.0, "\r\x1b[K[{n}/{total}] {what}");
                let _ = self.0.flush();
            }
        }
    }
    let progress = stderr_terminal && !cli.json && !markdown;
    let mut shown = Shown(err, progress);
    let report = self_test::run(config, cli.bitrate, &mut shown)?;
    if progress {
        let _ = write!(shown.0, "\r\x1b[K");
    }
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    if cli.json {
        writeln!(out, "{}", self_test::report_json(&report)).map_err(werr)?;
    } else if markdown {
        write!(out, "{}", self_test::markdown(&report)).map_err(werr)?;
    } else {
        self_test::write_text(out, &report).map_err(werr)?;
    }
    if let Some((file, path)) = &mut page {
        file.write_all(self_test::render_html(&report).as_bytes())
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
    }
    Ok(if report.passed() { 0 } else { 1 })
}

/// Creates an output file before the command touches the bus, so a path that cannot be written is
/// an error at once, not after the run.
fn create_output(path: &std::path::Path) -> Result<std::fs::File, HarnessError> {
    std::fs::File::create(path)
        .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })
}

fn execute(
    cli: &Cli,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    match (cli.format, &cli.log) {
        (Some(_), None) => {
            return Err(HarnessError::Usage(
                "--format names the format of the --log file: give --log FILE too".into(),
            ))
        }
        (Some(f), Some(_)) if !f.writable() => {
            return Err(HarnessError::Usage(format!(
                "--format {f}: --log writes candump, trc, asc or csv (a pcap capture: --pcap FILE)"
            )))
        }
        _ => {}
    }
    if let Command::Decode { logfile, input } = &cli.command {
        let trace = read_input(logfile, input, err)?;
        return decode_command(cli, &trace, out).map_err(|e| match e {
            HarnessError::Write { source, .. } => werr(source),
            other => other,
        });
    }
    if let Command::Ui { listen, scanlist, history, no_history, mqtt, record_dir, cycles } = &cli.command {
        let args = crate::commands::ui::UiArgs {
            listen: listen.clone(),
            scanlist: scanlist.clone(),
            history: (!no_history).then(|| history.clone()),
            mqtt: mqtt.clone(),
            record_dir: record_dir.clone(),
            cycles: *cycles,
        };
        return crate::commands::ui::execute(cli, &args, out, err, console);
    }
    if let Command::Scanner { scanlist, write_scanlist, cycles } = &cli.command {
        let args = crate::commands::scanner::ScannerArgs {
            scanlist: scanlist.clone(),
            write_scanlist: write_scanlist.clone(),
            cycles: *cycles,
        };
        return crate::commands::scanner::execute(cli, &args, out, err, console);
    }
    if let Command::Conformance { self_test: true, markdown, html, .. } = &cli.command {
        return self_test_command(cli, *markdown, html.as_deref(), out, err, console.stderr_terminal);
    }
    // Read input files and resolve the defaults before touching the bus.
    let transcript = match &cli.command {
        Command::Replay { transcript, input, .. } => Some(read_input(transcript, input, err)?.entries),
        _ => None,
    };
    let descriptions = Descriptions::load(cli)?;
    let device = command_device(cli, &descriptions, transcript.as_deref())?;
    let master_mac = master_mac(cli, transcript.as_deref())?;
    if device == Some(master_mac) {
        return Err(HarnessError::Usage(format!(
            "the device's MAC {master_mac} is the master's own MAC (--master-mac)"
        )));
    }
    let replay_power_on = match (device, &transcript, &cli.command) {
        (Some(mac), Some(entries), Command::Replay { from_online, .. }) => {
            Some(replay::sim_start(entries, mac, *from_online))
        }
        _ => None,
    };
    // A real device must be powered on in step with a transcript of its power-up: say when.
    if let (Some(mac), Some(entries), Command::Replay { from_online: None, tolerance, .. }) =
        (device, &transcript, &cli.command)
    {
        let note = replay::power_on_note(entries, mac, Duration::from_millis(*tolerance));
        if let Some(note) = note.filter(|_| cli.bus != BusSpec::Sim && !cli.json) {
            let _ = writeln!(err, "{note}");
        }
    }
    // --from-online=wait may wait long: say for what, also where no progress line is shown.
    if let (Some(mac), Command::Replay { from_online: Some(replay::FromOnline::Wait), .. }) =
        (device, &cli.command)
    {
        if cli.bus != BusSpec::Sim && !cli.json && !console.stderr_terminal {
            let _ = writeln!(
                err,
                "note: waiting for MAC {mac}'s duplicate MAC ID check: power it on (Ctrl-C stops)"
            );
        }
    }
    let slave = descriptions.slave.as_ref().map(|d| &d.converter);
    let mut bus = open_bus(cli, slave, device, replay_power_on)?;
    if let Some(path) = &cli.pcap {
        let pcap = PcapWriter::create(path)
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
        bus = Box::new(PcapBus::new(bus, pcap));
    }
    let progress =
        if console.stderr_terminal && !cli.json { Progress::on(&mut *err) } else { Progress::off() };
    if let Command::Conformance { html, .. } = &cli.command {
        let run = ConformanceCommand {
            log: cli.log.as_deref(),
            log_format: cli.format.unwrap_or(TraceFormat::Candump),
            master_mac,
            response_timeout: Duration::from_millis(cli.timeout.max(1)),
            json: cli.json,
            frames: cli.frames,
            html: html.as_deref(),
            keep: cli.keep,
            transport: cli.bus.to_string(),
            stop: console.stop.clone(),
        };
        let mac = device.unwrap_or(MacId::from_low_bits(5));
        return dnet_conformance::command::execute(&run, bus.as_mut(), mac, out, progress);
    }
    let mut session = Session::new(bus.as_mut());
    session.set_stop(console.stop.clone());
    if let Some(path) = &cli.log {
        let log = LogWriter::create_as(path, cli.format.unwrap_or(TraceFormat::Candump))
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
        session.set_log(log);
    }
    let mut csv_file = match &cli.command {
        Command::Monitor { csv: Some(p), .. } => Some(std::io::BufWriter::new(create_output(p)?)),
        _ => None,
    };
    let config = MasterConfig {
        mac: master_mac,
        response_timeout: Duration::from_millis(cli.timeout.max(1)),
        ..MasterConfig::default()
    };
    let mut master = Master::new(&mut session, config);
    let mut progress = progress;
    let target = device.unwrap_or(MacId::from_low_bits(5));
    // What a command produced before it failed or was interrupted (monitor's samples).
    let mut partial: Option<Outcome> = None;
    let result: Result<Outcome, HarnessError> = match &cli.command {
        Command::Connect { epr, polls, output, verify_state, io, .. } => {
            let opts = ConnectOptions {
                target,
                epr_ms: *epr,
                polls: *polls,
                output: output.clone().map(|h| h.0),
                verify_state: *verify_state,
            };
            progress.show(&format!("connect: bringing up MAC {target} ({}) ...", io.io));
            let r = master
                .connect_io(&opts, &io.options(&cli.bus))
                .map(|s| connect_outcome(&s))
                .map_err(HarnessError::from);
            progress.clear();
            r
        }
        Command::Recover { mac, to, serial, window, delay_byte, attempts } => {
            let opts = RecoverOptions {
                mac: *mac,
                to: *to,
                serial: *serial,
                window: Duration::from_millis(*window),
                time_delay_offset: *delay_byte,
                attempts: *attempts,
                judge_timing: judges_timing(&cli.bus),
            };
            progress.show(&format!("recover: asking who is Communication Faulted at MAC {mac} ..."));
            let r = master.recover(&opts).map(|r| recover_outcome(&r)).map_err(HarnessError::from);
            progress.clear();
            r
        }
        Command::Replay { tolerance, settle, from_online, ignore_data, .. } => {
            let opts = ReplayOptions {
                device: target,
                tolerance: Duration::from_millis(*tolerance),
                settle: Duration::from_millis(*settle),
                from_online: *from_online,
                ignore_io_data: ignore_data.is_some(),
            };
            let entries = transcript.unwrap_or_default();
            let what = match from_online {
                Some(replay::FromOnline::Wait) => format!(
                    "replay: waiting for MAC {target}'s duplicate MAC ID check: power it on (Ctrl-C stops) ..."
                ),
                _ => format!("replay: {} frames against MAC {target} ...", entries.len()),
            };
            progress.show(&what);
            let r = replay::replay(master.session, &entries, &opts).map(|s| Outcome {
                text: s.text(),
                json: json!({ "summary": s }),
                code: 0,
            });
            progress.clear();
            // What the transcript allocated stays with the device: released below like any
            // command's. A device that sent nothing (never powered on during a
            // --from-online=wait) holds nothing.
            let heard = master.session.records().iter().any(|r| {
                r.origin == can_io::bus::Origin::Remote
                    && master_core::session::is_from_device(&r.frame, target)
            });
            if heard && !matches!(r, Err(HarnessError::NothingCompared(_))) {
                master.note_held(target, replay::held_after(&entries, target));
            }
            r
        }
        Command::Scan { from, to } => {
            scan::scan(&mut master, *from, *to, &mut progress).map(|r| scan_outcome(&r))
        }
        Command::Get { mac, class, instance, attribute } => {
            explicit_command(&mut master, *mac, *class, *instance, *attribute, None)
        }
        Command::Set { mac, class, instance, attribute, value } => {
            explicit_command(&mut master, *mac, *class, *instance, *attribute, Some(&value.0))
        }
        Command::Monitor { epr, output, count, duration, reconnect, io, .. } => {
            let duration = match duration {
                Some(d) if !(d.is_finite() && *d >= 0.0) => {
                    return Err(HarnessError::Usage(format!("--duration {d}: expected seconds >= 0")))
                }
                Some(d) => Some(Duration::from_micros((d * 1e6) as u64)),
                None if cli.bus == BusSpec::Sim && !cli.realtime && count.is_none() => {
                    Some(Duration::from_secs(10))
                }
                None => None,
            };
            let opts = MonitorOptions {
                connect: ConnectOptions {
                    target,
                    epr_ms: *epr,
                    polls: 0,
                    output: output.clone().map(|h| h.0),
                    verify_state: false,
                },
                count: *count,
                duration,
                in_place: console.stdout_terminal && !cli.json,
                reconnect: *reconnect,
                // A strobe response carries the first 8 input bytes only: shown raw.
                layout: if io.io == IoKind::Strobe {
                    InputLayout::raw()
                } else {
                    monitor_layout(cli, &descriptions)
                },
                io: io.options(&cli.bus),
            };
            let mut sink = std::io::sink();
            let screen: &mut dyn Write = if cli.json { &mut sink } else { &mut *out };
            progress.show(&format!("monitor: bringing up MAC {target} ..."));
            let run = monitor::monitor(
                &mut master,
                &opts,
                screen,
                csv_file.as_mut().map(|f| f as &mut dyn Write),
                &mut progress,
            );
            progress.clear();
            let outcome = Outcome {
                text: format!(
                    "{} sample{}",
                    run.samples.len(),
                    if run.samples.len() == 1 { "" } else { "s" }
                ),
                json: json!({ "samples": run.samples }),
                code: 0,
            };
            match run.ended {
                // A run that took no sample showed nothing of the device: not a success.
                None if run.samples.is_empty() => {
                    partial = Some(outcome);
                    Err(HarnessError::NothingCompared(format!(
                        "monitor: no sample of MAC {target} was taken before --count or --duration ended the run"
                    )))
                }
                None => Ok(outcome),
                Some(e) => {
                    // Interrupted or failed: the samples taken are still reported.
                    partial = Some(outcome);
                    Err(e)
                }
            }
        }
        Command::Configure { mac, description: Some(path), .. } => {
            progress.show(&format!("configure: downloading {} to MAC {mac} ...", path.display()));
            let r = match &descriptions.command {
                Some(description) => configure::download(&mut master, *mac, description, &mut |note| {
                    progress.show(&format!("configure: {note}"));
                }),
                None => unreachable!("Descriptions::load reads configure's file"),
            };
            progress.clear();
            r.map(|report| configure_outcome(&report, path))
        }
        Command::Configure { mac, read: Some(path), .. } => {
            progress.show(&format!("configure: reading the configuration of MAC {mac} ..."));
            let r = configure::upload(&mut master, *mac);
            progress.clear();
            r.and_then(|configure::Uploaded { description, serial_number }| {
                let text = description.to_toml().map_err(HarnessError::Usage)?;
                let header = format!(
                    "# The configuration in force at MAC {mac}, read by dnet-master {} configure --read.\n\
                     # identity.vendor_name and identity.catalog are EDS-only: the device does not keep them.\n\
                     # identity.serial_number is the image's: the device keeps its own, {serial_number}.\n\n",
                    harness_common::version()
                );
                let whole = header + &text;
                if path.as_os_str() == "-" {
                    Ok(Outcome { text: whole.trim_end().to_string(), json: json!({ "description": whole }), code: 0 })
                } else {
                    std::fs::write(path, &whole)
                        .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
                    Ok(Outcome {
                        text: format!("MAC {mac}: the configuration in force written to {}", path.display()),
                        json: json!({ "description": whole, "file": path }),
                        code: 0,
                    })
                }
            })
        }
        Command::Configure { .. } => {
            Err(HarnessError::Usage("configure needs a description file or --read FILE".into()))
        }
        Command::Params { mac, eds: eds_file, set } => {
            params_command(&mut master, *mac, eds_file.as_deref(), set)
        }
        Command::Decode { .. }
        | Command::Conformance { .. }
        | Command::Scanner { .. }
        | Command::Ui { .. } => {
            unreachable!("handled above")
        }
    };
    drop(progress);
    // Whatever happened, what was recorded is kept: the device gets back what this command
    // allocated (unless --keep, or the bus itself failed), then the CSV and the log are flushed.
    let interrupted = result.as_ref().err().and_then(interruption);
    master.session.take_stop();
    let mut finish_errors: Vec<HarnessError> = Vec::new();
    let bus_failed = matches!(result, Err(HarnessError::Master(MasterError::Bus(_))));
    let mut released_text = String::new();
    if cli.keep {
        if let Some(d) = device.filter(|d| !master.held(*d).is_empty()) {
            released_text =
                format!("MAC {d}: {} kept allocated to master MAC {master_mac} (--keep)", master.held(d));
        }
    } else if !bus_failed {
        match master.release_held() {
            Ok(released) if !released.is_empty() && interrupted.is_some() => {
                let macs: Vec<String> = released.iter().map(ToString::to_string).collect();
                released_text = format!("released MAC {}", macs.join(", "));
            }
            Ok(_) => {}
            Err(e) => finish_errors.push(HarnessError::Release(Box::new(e))),
        }
    }
    let notices: Vec<String> = master.notices().to_vec();
    if let Some(f) = &mut csv_file {
        if let Err(source) = f.flush() {
            finish_errors.push(HarnessError::Write { path: "the CSV file".into(), source });
        }
    }
    if let Err(e) = session.flush() {
        finish_errors.push(e.into());
    }
    let failures = session.failures();
    let show_table = cli.frames
        || matches!(cli.command, Command::Connect { .. } | Command::Replay { .. } | Command::Recover { .. });
    let records = session.records();
    let (mut code, error_text, payload) = match result {
        Ok(o) => (o.code, None, Some(o)),
        Err(e) => (e.exit_code(), Some(e), partial.take()),
    };
    if failures > 0 && code == 0 {
        code = 1;
    }
    if code == 0 {
        if let Some(e) = finish_errors.first() {
            code = e.exit_code();
        }
    }
    for n in &notices {
        writeln!(err, "note: {n}").map_err(werr)?;
    }
    if cli.json {
        let frames: Vec<RecordJson<'_>> = records.iter().map(|r| record_json(r, device)).collect();
        let mut v = json!({
            "ok": code == 0,
            "failures": failures,
            "frames": frames,
            "version": harness_common::version(),
            "notices": notices,
        });
        if let Some(p) = &payload {
            if let (Some(obj), Some(extra)) = (v.as_object_mut(), p.json.as_object()) {
                for (k, val) in extra {
                    obj.insert(k.clone(), val.clone());
                }
            }
        }
        if let Some(signal) = interrupted {
            v["interrupted"] = json!(master_core::stop::signal_name(signal));
        }
        if let Some(e) = &error_text {
            v["error"] = json!(e.to_string());
            if let HarnessError::Divergence(d) = e {
                v["divergence"] = json!(d);
            }
        }
        if !finish_errors.is_empty() {
            v["cleanup_errors"] = json!(finish_errors.iter().map(ToString::to_string).collect::<Vec<_>>());
        }
        writeln!(out, "{v}").map_err(werr)?;
    } else {
        if show_table {
            print_table(out, records, device).map_err(werr)?;
            writeln!(out).map_err(werr)?;
        }
        if let Some(p) = &payload {
            if !p.text.is_empty() {
                writeln!(out, "{}", p.text).map_err(werr)?;
            }
        }
        if failures > 0 {
            writeln!(out, "{failures} frame check(s) failed:").map_err(werr)?;
            for r in records.iter().filter(|r| r.verdict.is_failure()) {
                writeln!(out, "  #{} {}: {}", r.index, r.frame, r.verdict.label()).map_err(werr)?;
            }
        } else if error_text.is_none() && show_table {
            writeln!(out, "{} frames, every check holds", records.len()).map_err(werr)?;
        }
        if !released_text.is_empty() {
            writeln!(err, "{released_text}").map_err(werr)?;
        }
        for e in &finish_errors {
            writeln!(err, "error: {e}").map_err(werr)?;
        }
        if let Some(signal) = interrupted {
            writeln!(
                err,
                "interrupted by {}: {} frames recorded{}",
                master_core::stop::signal_name(signal),
                records.len(),
                if cli.log.is_some() { ", log flushed" } else { "" }
            )
            .map_err(werr)?;
        }
    }
    match error_text {
        Some(e) if !cli.json && interrupted.is_none() => Err(e),
        _ => Ok(code),
    }
}

fn configure_outcome(r: &configure::DownloadReport, path: &std::path::Path) -> Outcome {
    // What the master said before the reset comes first.
    let mut text: String = r.notes.iter().map(|n| format!("note: {n}\n")).collect();
    text += &format!(
        "MAC {}: {} downloaded ({} bytes in {} chunks), read back and verified; reset; on-line again at MAC {} after {} ms",
        r.mac,
        path.display(),
        r.bytes,
        r.chunks,
        r.back_at.map_or_else(|| "?".into(), |m| m.to_string()),
        r.back_online_ms.map_or_else(|| "?".into(), |m| m.to_string()),
    );
    for c in &r.checks {
        let mark = if c.holds() { "ok  " } else { "FAIL" };
        text.push_str(&format!(
            "\n  {mark} {:<24} {}",
            c.what,
            if c.holds() {
                c.actual.clone()
            } else {
                format!("expected {}, device has {}", c.expected, c.actual)
            }
        ));
    }
    let failed = r.failures().len();
    text.push_str(&if failed == 0 {
        "\nthe device runs the description".to_string()
    } else {
        format!("\n{failed} check(s) failed: the device does not run the description")
    });
    Outcome { json: json!({ "configure": r }), text, code: u8::from(failed > 0) }
}

fn params_command(
    master: &mut Master<'_, '_>,
    mac: MacId,
    eds_file: Option<&std::path::Path>,
    set: &[String],
) -> Result<Outcome, HarnessError> {
    let assignments: Vec<(String, i64)> = set
        .iter()
        .map(|a| params::parse_assignment(a))
        .collect::<Result<_, _>>()
        .map_err(HarnessError::Usage)?;
    let listed: Option<Vec<(u32, eds::model::Param)>> = match eds_file {
        Some(path) => {
            let model =
                eds::read_file(path).map_err(|e| HarnessError::Usage(format!("{}: {e}", path.display())))?;
            Some(model.params().map(|(n, p)| (n, p.clone())).collect())
        }
        None => None,
    };
    master.open_explicit(mac)?;
    let read = |master: &mut Master<'_, '_>| match &listed {
        Some(list) => params::read_eds(master, mac, list),
        None => params::read_device(master, mac),
    };
    let mut rows = read(master)?;
    if !assignments.is_empty() {
        for (name, value) in &assignments {
            params::set(master, mac, &rows, name, *value)?;
        }
        rows = read(master)?;
    }
    if rows.is_empty() {
        return Err(HarnessError::NothingCompared(format!("MAC {mac} has no parameters to read")));
    }
    Ok(Outcome { text: params::table(&rows), json: json!({ "params": rows }), code: 0 })
}

fn connect_outcome(s: &DeviceSummary) -> Outcome {
    let hex16 = |v: Option<u16>| v.map_or_else(|| "?".into(), |v| format!("0x{v:04X}"));
    let num = |v: Option<u16>| v.map_or_else(|| "?".into(), |v| v.to_string());
    let kind = match &s.io {
        None => "poll".to_string(),
        Some(io) if io.ack_suppression => format!("{} (acknowledge suppression)", io.kind),
        Some(io) => io.kind.to_string(),
    };
    let mut text = format!(
        "device MAC {}: {}vendor {}, device type {}, product code {}; {kind} produced {} / consumed {} bytes, EPR {} ms{}",
        s.mac,
        if s.ucmm_capable { "UCMM-capable, " } else { "group-2-only, " },
        hex16(s.vendor_id),
        hex16(s.device_type),
        num(s.product_code),
        num(s.produced_size),
        num(s.consumed_size),
        num(s.expected_packet_rate_ms),
        s.last_input.as_ref().map_or_else(String::new, |i| format!("; last input {}", decode::hex(i)))
    );
    if let Some(io) = &s.io {
        text.push_str(&io_text(io));
    }
    Outcome { json: json!({ "device": s }), text, code: 0 }
}

/// The second line of `connect --io strobe|cos|cyclic`: identifiers, settings, what was exchanged.
pub(crate) fn io_text(io: &IoSummary) -> String {
    let id = |v: Option<u16>| v.map_or_else(|| "?".into(), |v| format!("0x{v:03X}"));
    let mut parts = vec![format!(
        "Connection {}: produced ID {}, consumed ID {}",
        io.instance,
        id(io.produced_id),
        id(io.consumed_id)
    )];
    if let Some(p) = io.inhibit_time_ms {
        parts.push(format!("inhibit time {p} ms"));
    }
    if let (Some(t), Some(n)) = (io.ack_timer_ms, io.retry_limit) {
        parts.push(format!("acknowledge timer {t} ms, retry limit {n}"));
    }
    if io.kind == IoKind::Strobe {
        parts.push(format!("{} strobe response(s)", io.strobe_responses));
    } else {
        let mut p = format!("{} production(s), {} acknowledged by the master", io.productions, io.acks_sent);
        if io.re_sent > 0 {
            p.push_str(&format!(", {} re-sent by the device", io.re_sent));
        }
        parts.push(p);
        if let (Some(lo), Some(hi)) = (io.interval_min_ms, io.interval_max_ms) {
            parts.push(format!("interval {lo:.1}-{hi:.1} ms"));
        }
        if io.outputs_sent > 0 {
            parts.push(format!(
                "master data sent {} time(s), {} acknowledged",
                io.outputs_sent, io.outputs_acknowledged
            ));
        }
    }
    format!("\n{}", parts.join("; "))
}

fn recover_outcome(r: &RecoveryReport) -> Outcome {
    let mut lines = vec![format!(
        "Who {} for MAC {}: {} Communication Faulted node(s) answered",
        r.who,
        r.mac,
        r.found.len()
    )];
    for n in &r.found {
        lines.push(format!("  {} (answered after {:.1} ms)", n.text(), n.answered_after_ms));
    }
    match (r.chosen, r.new_mac) {
        (Some(node), Some(to)) => {
            let yes = |b: Option<bool>| if b == Some(true) { "answered" } else { "NOT answered" };
            lines.push(format!("recovered {}:", node.text()));
            lines.push(format!(
                "  long Identify {}; offline ownership {}",
                yes(r.identified),
                yes(r.ownership)
            ));
            lines.push(format!(
                "  Change MAC ID to {to}: duplicate MAC ID requests at MAC {to} after {} ms",
                r.dup_mac_requests_ms.iter().map(|t| format!("{t:.0}")).collect::<Vec<_>>().join(" and ")
            ));
            lines.push(format!(
                "  on-line at MAC {to}: explicit connection allocated, serial number {}",
                r.serial_at_new_mac.map_or_else(|| "?".into(), |s| format!("0x{s:08X}"))
            ));
        }
        _ => lines.push("nothing changed (give --to MAC to recover a node)".into()),
    }
    for f in &r.findings {
        lines.push(format!("finding: {f}"));
    }
    Outcome { json: json!({ "recover": r }), text: lines.join("\n"), code: u8::from(!r.findings.is_empty()) }
}

fn scan_outcome(r: &ScanReport) -> Outcome {
    let mut text = format!(
        "{:>3}  {:<6}  {:<6}  {:>7}  {:<5}  {:<10}  {:<26}  {:<9}  status\n",
        "MAC", "vendor", "type", "product", "rev", "serial", "name", "poll i/o"
    );
    let opt16 = |v: Option<u16>| v.map_or_else(|| "-".into(), |v| format!("0x{v:04X}"));
    for d in &r.devices {
        let io = match (d.produced_size, d.consumed_size) {
            (Some(p), Some(c)) => format!("{p}/{c}"),
            _ => "-".into(),
        };
        text.push_str(&format!(
            "{:>3}  {:<6}  {:<6}  {:>7}  {:<5}  {:<10}  {:<26}  {:<9}  {}\n",
            d.mac,
            opt16(d.identity.vendor_id),
            opt16(d.identity.device_type),
            d.identity.product_code.map_or_else(|| "-".into(), |v| v.to_string()),
            d.identity.revision.clone().unwrap_or_else(|| "-".into()),
            d.identity.serial_number.map_or_else(|| "-".into(), |v| format!("0x{v:08X}")),
            d.identity.product_name.clone().unwrap_or_else(|| "-".into()),
            io,
            d.note.as_ref().map_or_else(|| d.status.clone(), |n| format!("{} ({n})", d.status))
        ));
    }
    text.push_str(&format!(
        "{} device(s) found among {} MAC IDs; scan {:.1} ms of bus time, {:.1} ms with network access",
        r.devices.len(),
        r.asked,
        r.scan_micros as f64 / 1e3,
        r.total_micros as f64 / 1e3
    ));
    Outcome { json: json!({ "scan": r }), text, code: 0 }
}

fn explicit_command(
    master: &mut Master<'_, '_>,
    mac: MacId,
    class_id: u16,
    instance: u16,
    attribute: u8,
    value: Option<&Vec<u8>>,
) -> Result<Outcome, HarnessError> {
    master.open_explicit(mac)?;
    let mut data = vec![attribute];
    let service = match value {
        Some(v) => {
            data.extend_from_slice(v);
            ServiceCode::SetAttributeSingle
        }
        None => ServiceCode::GetAttributeSingle,
    };
    let req = devicenet::explicit::Request { service, class: class_id, instance, data: &data };
    let what = decode::request_text(&req);
    let answer = master.request(mac, master_core::client::Port::Explicit, &req)?;
    let target = format!(
        "{} inst {instance} {}",
        decode::class_text(class_id),
        decode::attribute_text(class_id, instance, attribute)
    );
    let outcome = match answer.reply.body {
        ReplyBody::Success(bytes) => {
            let shown = if value.is_some() && bytes.is_empty() {
                "success".to_string()
            } else {
                decode::value_text(class_id, instance, attribute, &bytes)
            };
            let frag = if answer.reply.fragmented { " (fragmented response)" } else { "" };
            Outcome {
                text: if bytes.is_empty() {
                    format!("MAC {mac} {target}: {shown}{frag}")
                } else {
                    format!("MAC {mac} {target}: {shown}{frag}\nhex: {}", decode::hex(&bytes))
                },
                json: json!({ "request": what, "value": shown, "hex": decode::hex(&bytes).replace(' ', ""), "fragmented": answer.reply.fragmented }),
                code: 0,
            }
        }
        ReplyBody::Error { general, additional } => {
            let text = decode::error_text(general, additional);
            if let Some(i) = answer.record {
                let v = master.session.record(i).verdict.clone();
                master.session.set_verdict(i, v.with_failures(vec![format!("error response: {text}")]));
            }
            return Err(
                MasterError::ErrorResponse { what, mac: mac.as_raw(), general, additional, text }.into()
            );
        }
    };
    Ok(outcome)
}

fn decode_command(cli: &Cli, trace: &Trace, out: &mut dyn Write) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let mut decoder = Decoder::new();
    if cli.json {
        let mut items = Vec::with_capacity(trace.entries.len());
        for e in &trace.entries {
            let d = decoder.decode(&e.frame);
            items.push(json!({
                "line": e.line,
                "time_us": e.at.total_micros(),
                "iface": &*e.iface,
                "direction": e.direction.map(|d| d.name()),
                "frame": e.frame.to_string(),
                "meaning": d.summary,
                "message": d.message,
            }));
        }
        let skipped: Vec<_> =
            trace.skipped.iter().map(|s| json!({ "line": s.line, "reason": s.reason })).collect();
        let summary = json!({
            "ok": true,
            "format": trace.format.name(),
            "frames": items,
            "skipped": trace.skipped_count,
            "skipped_first": skipped,
        });
        writeln!(out, "{summary}").map_err(werr)?;
        return Ok(0);
    }
    // A million frames a second and more: one buffer per line, written in 64 KiB blocks (the
    // standard output is line-buffered), nothing allocated per frame but completed messages.
    let mut out = std::io::BufWriter::with_capacity(1 << 16, out);
    let mut line = String::with_capacity(256);
    let mut decoded = decode::Decoded::default();
    for e in &trace.entries {
        decoder.decode_into(&e.frame, &mut decoded);
        line.clear();
        push_trace_line(&mut line, e);
        while line.len() < 40 {
            line.push(' ');
        }
        line.push(' ');
        line.push_str(&decoded.summary);
        line.push('\n');
        if let Some(m) = &decoded.message {
            line.push_str(concat!("                                        ", "   => "));
            line.push_str(m);
            line.push('\n');
        }
        out.write_all(line.as_bytes()).map_err(werr)?;
    }
    out.flush().map_err(werr)?;
    Ok(0)
}

/// `(seconds.micros) iface [Rx|Tx] ID#DATA`: a `candump -L` line, with the direction where the
/// trace recorded one.
fn push_trace_line(line: &mut String, e: &LogEntry) {
    let us = e.at.total_micros();
    let mut digits = [0u8; 26];
    let mut at = digits.len();
    let mut rest = us;
    // Digits from the right: six of microseconds, the point, then the seconds (at least one).
    for i in 0.. {
        if i == 6 {
            at -= 1;
            digits[at] = b'.';
        }
        at -= 1;
        digits[at] = b'0' + (rest % 10) as u8;
        rest /= 10;
        if rest == 0 && i >= 6 {
            break;
        }
    }
    line.push('(');
    line.push_str(std::str::from_utf8(&digits[at..]).unwrap_or("?"));
    line.push_str(") ");
    line.push_str(&e.iface);
    if let Some(d) = e.direction {
        line.push(' ');
        line.push_str(d.name());
    }
    line.push(' ');
    let raw = e.frame.id().as_raw();
    for shift in [8, 4, 0] {
        line.push(char::from(b"0123456789ABCDEF"[usize::from(raw >> shift & 0xF)]));
    }
    line.push('#');
    for b in e.frame.data() {
        line.push(char::from(b"0123456789ABCDEF"[usize::from(b >> 4)]));
        line.push(char::from(b"0123456789ABCDEF"[usize::from(b & 0xF)]));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::plain("0201", vec![2, 1])]
    #[case::spaced("02 01", vec![2, 1])]
    #[case::colons("de:ad:BE:ef", vec![0xDE, 0xAD, 0xBE, 0xEF])]
    #[case::empty("", vec![])]
    fn hex_values(#[case] text: &str, #[case] bytes: Vec<u8>) {
        assert_eq!(parse_hex(text), Ok(bytes));
    }

    #[rstest]
    #[case::odd("021")]
    #[case::bad("0G")]
    fn bad_hex(#[case] text: &str) {
        assert!(parse_hex(text).is_err());
    }

    #[rstest]
    #[case::dec("5", 5)]
    #[case::hex("0x3F", 63)]
    fn macs(#[case] text: &str, #[case] mac: u8) {
        assert_eq!(parse_mac(text).map(|m| m.as_raw()), Ok(mac));
    }

    #[test]
    fn mac_out_of_range() {
        assert!(parse_mac("64").unwrap_err().contains("0..=63"));
        assert!(parse_mac("five").is_err());
    }

    #[test]
    fn cli_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}
