//! The options every command shares (bus, master MAC, bit rate, log, pcap, output format,
//! timeouts, the simulated devices), the value parsers of the command line, and what is done with
//! them before a command runs: the bus opened, the log format checked, output files created.

use crate::replay;
use can_io::bus::{Bitrate, Bus, BusSpec};
use can_io::pcap::{PcapBus, PcapWriter};
use can_io::sim::PowerOn;
use can_io::trace::{read_trace, ReadOptions, Skipped, Trace, TraceFormat};
use clap::Args;
use converter_sim::{OpenError, SimSetup};
use devicenet::{Duration, Instant, MacId};
use harness_common::error::HarnessError;
use master_core::io::{IoKind, IoOptions};
use master_core::master::MasterConfig;
use slave_fw::converter::ConverterConfig;
use slave_fw::description::DeviceDescription;
use std::io::Write;
use std::path::PathBuf;

/// Parses a MAC ID: `0..=63`, decimal or `0x` hex.
pub fn parse_mac(s: &str) -> Result<MacId, String> {
    let v = parse_number(s)?;
    u8::try_from(v).ok().and_then(MacId::new).ok_or_else(|| format!("MAC ID {s} is out of range 0..=63"))
}

/// Parses `--sim-replace MAC@MS`: the device at MAC fails at MS ms of simulated time.
pub fn parse_sim_replace(s: &str) -> Result<(MacId, Instant), String> {
    let (mac, ms) = s.split_once('@').ok_or_else(|| format!("'{s}': expected MAC@MS, e.g. 5@3000"))?;
    let ms = parse_number(ms).map_err(|e| format!("'{s}': the time in ms: {e}"))?;
    Ok((parse_mac(mac)?, Instant::ZERO + Duration::from_millis(u64::from(ms))))
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

/// `--duration SECONDS` (`monitor`, `serial-trace`): a finite number of seconds, 0 or more.
pub fn duration_secs(value: Option<f64>) -> Result<Option<Duration>, HarnessError> {
    match value {
        Some(d) if !(d.is_finite() && d >= 0.0) => Err(HarnessError::InvalidValue {
            option: "--duration",
            value: d.to_string(),
            expected: "seconds >= 0",
        }),
        d => Ok(d.map(|d| Duration::from_micros((d * 1e6) as u64))),
    }
}

/// Parses a 16-bit number (decimal or `0x` hex).
pub fn parse_u16(s: &str) -> Result<u16, String> {
    u16::try_from(parse_number(s)?).map_err(|_| format!("{s} does not fit in 16 bits"))
}

/// Parses an 8-bit number (decimal or `0x` hex).
pub fn parse_u8(s: &str) -> Result<u8, String> {
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

/// The I/O connection `connect` and `monitor` bring up (`docs/src/reference/io-connections.md`).
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
    #[must_use]
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
#[must_use]
pub fn judges_timing(bus: &BusSpec) -> bool {
    !matches!(bus, BusSpec::Slcan { .. })
}

/// The options of every command (`global`: given before or after the command's name).
#[derive(Args, Clone, Debug)]
pub struct GlobalOptions {
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
    /// sim: MAC@MS: the device at MAC goes silent at MS ms of simulated time and a factory-fresh
    /// device of the same kind appears at MAC 63 (automatic device replacement); repeatable.
    #[arg(long, global = true, value_name = "MAC@MS", value_parser = parse_sim_replace)]
    pub sim_replace: Vec<(MacId, Instant)>,
}

impl GlobalOptions {
    /// The master's configuration at `mac`, with `--timeout`.
    #[must_use]
    pub fn master_config(&self, mac: MacId) -> MasterConfig {
        MasterConfig {
            mac,
            response_timeout: Duration::from_millis(self.timeout.max(1)),
            ..MasterConfig::default()
        }
    }

    /// `--master-mac`, else 0.
    #[must_use]
    pub fn master_mac_or_default(&self) -> MacId {
        self.master_mac.unwrap_or(MacId::from_low_bits(0))
    }

    /// `--slave-config`'s description, read.
    pub fn slave_description(&self) -> Result<Option<DeviceDescription>, HarnessError> {
        Ok(self.slave_config.as_deref().map(DeviceDescription::load).transpose()?)
    }

    /// Refuses `--format` without `--log`, or a format `--log` cannot write.
    pub fn check_log_format(&self) -> Result<(), HarnessError> {
        match (self.format, &self.log) {
            (Some(_), None) => Err(HarnessError::FormatWithoutLog),
            (Some(format), Some(_)) if !format.writable() => Err(HarnessError::FormatNotWritable { format }),
            _ => Ok(()),
        }
    }
}

/// Opens the bus the options name: on `sim`, the simulated converters of `slave` (the
/// `--slave-config` description, else the reference device) / `--slave-mac` / `--slave-power-on`
/// ([`converter_sim::open_bus`], the one way every program opens a bus); with no `--slave-mac`,
/// one device at `device` (the command's `--mac`). `replay_power_on` is how a replayed
/// transcript meets its device ([`replay::sim_start`]): a simulated device with the default
/// power-on policy is powered on, or brought on-line before the first frame, as it says.
pub fn open_bus(
    opts: &GlobalOptions,
    slave: Option<&ConverterConfig>,
    device: Option<MacId>,
    replay_power_on: Option<replay::SimStart>,
) -> Result<Box<dyn Bus>, HarnessError> {
    let mut setup = match slave {
        Some(config) => SimSetup::described(config.clone()),
        None => SimSetup::reference(),
    };
    setup.macs = match (opts.slave_mac.is_empty(), device) {
        (true, Some(mac)) => vec![mac],
        _ => opts.slave_mac.clone(),
    };
    setup.power_on = match (opts.slave_power_on.0, replay_power_on) {
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
    setup.realtime = opts.realtime;
    setup.replace = opts.sim_replace.clone();
    converter_sim::open_bus(&opts.bus, opts.bitrate, &setup).map_err(|e| match e {
        OpenError::Setup(detail) => HarnessError::BusSetup { detail },
        OpenError::Bus(e) => HarnessError::from(e),
    })
}

/// [`open_bus`], wrapped in a pcap writer with `--pcap FILE`.
pub fn open_bus_with_pcap(
    opts: &GlobalOptions,
    slave: Option<&ConverterConfig>,
    device: Option<MacId>,
    replay_power_on: Option<replay::SimStart>,
) -> Result<Box<dyn Bus>, HarnessError> {
    let bus = open_bus(opts, slave, device, replay_power_on)?;
    match &opts.pcap {
        Some(path) => {
            let pcap = PcapWriter::create(path)
                .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
            Ok(Box::new(PcapBus::new(bus, pcap)))
        }
        None => Ok(bus),
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
    /// The reader's options.
    #[must_use]
    pub fn options(&self) -> ReadOptions {
        ReadOptions { strict: self.strict, format: self.input_format }
    }
}

/// Parses a trace format's name (`candump`, `trc`, …).
pub fn parse_trace_format(text: &str) -> Result<TraceFormat, String> {
    TraceFormat::from_name(text).ok_or_else(|| {
        let names: Vec<&str> = TraceFormat::ALL.iter().map(|f| f.name()).collect();
        format!("unknown trace format '{text}' (one of: {})", names.join(", "))
    })
}

/// Reads a trace for `decode` or `replay` and says on `err` what was skipped (the first
/// [`can_io::trace::NAMED_SKIPS`] by line, then the count).
pub fn read_input(
    path: &std::path::Path,
    input: &TraceInput,
    err: &mut dyn Write,
) -> Result<Trace, HarnessError> {
    let trace = read_trace(path, input.options())?;
    let name =
        if path.as_os_str() == "-" { "standard input".to_string() } else { path.display().to_string() };
    report_skipped(err, &name, trace.format, trace.skipped_count, &trace.skipped);
    if trace.entries.is_empty() {
        return Err(HarnessError::NothingCompared(format!(
            "{name}: no DeviceNet frames in this {} trace ({} skipped)",
            trace.format, trace.skipped_count
        )));
    }
    Ok(trace)
}

/// Creates an output file before the command touches the bus, so a path that cannot be written is
/// an error at once, not after the run.
pub fn create_output(path: &std::path::Path) -> Result<std::fs::File, HarnessError> {
    std::fs::File::create(path)
        .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })
}

/// Says which lines (records, in a binary format) of the trace `name` were skipped as not
/// DeviceNet traffic: `count` in all, `named` the first of them with their reasons. Nothing when
/// `count` is 0. Every command that reads a trace words it so, standard input read line by line
/// included.
pub(crate) fn report_skipped(
    err: &mut dyn Write,
    name: &str,
    format: TraceFormat,
    count: usize,
    named: &[Skipped],
) {
    if count == 0 {
        return;
    }
    let unit = if matches!(format, TraceFormat::Pcap | TraceFormat::Pcapng | TraceFormat::Blf) {
        "record"
    } else {
        "line"
    };
    let _ = writeln!(
        err,
        "dnet-master: {name}: {count} {unit}{} skipped, not DeviceNet traffic (--strict stops at the first):",
        if count == 1 { "" } else { "s" }
    );
    for s in named {
        let _ = writeln!(err, "  {name}:{}: {}", s.line, s.reason);
    }
    if count > named.len() {
        let _ = writeln!(err, "  ... and {} more", count - named.len());
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
}
