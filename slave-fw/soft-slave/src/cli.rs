//! The command lines of `dnet-soft-slave` and `dnet-sim-breaker` (clap), and the functions the
//! binaries call. Exit status: 0 after a clean stop (SIGINT, SIGTERM or `--duration`), 1 when the
//! bus or the serial port failed, 2 for a usage or configuration error.

use crate::breaker::{BreakerOptions, BreakerRunner};
use crate::bridge::{Bridge, RunSummary};
use crate::clock::{from_secs_f64, Clock};
use crate::error::SoftSlaveError;
use crate::firmware::FirmwareDir;
use crate::serial::{settings_text, SerialLine};
use crate::state::{StateFile, StoredState};
use crate::tcp::{TcpLine, TcpTarget, BACKOFF_FIRST, BACKOFF_MAX};
use can_io::bus::{Bitrate, BusSpec};
use can_io::log::LogWriter;
use can_io::trace::write::log_format;
use can_io::trace::TraceFormat;
use clap::Parser;
use devicenet::{Duration, MacId};
use slave_fw::description::DeviceDescription;
use slave_fw::serial::modbus::Framing;
use slave_fw::serial::{ProfileConfig, SerialSettings};
use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

/// `dnet-soft-slave`: the converter as a Linux process.
#[derive(Debug, Parser)]
#[command(
    name = "dnet-soft-slave",
    version = crate::VERSION,
    about = "The serial-to-DeviceNet converter as a Linux process: a group-2-only DeviceNet slave on a real CAN bus whose data comes from a serial instrument (the breaker profile or a Modbus RTU scan list) on a real serial port or behind a serial device server (TCP).",
    after_help = "Stops cleanly on SIGINT or SIGTERM (the log is flushed). Exit status: 0 after a clean stop, 1 when the bus or the serial port failed, 2 for a usage or configuration error (a --log or --state file that cannot be written among them; both are checked before the device goes on the bus)."
)]
pub struct SoftSlaveArgs {
    /// The CAN bus: `socketcan:IFACE` or `slcan:PATH[@SERIALBAUD]`.
    #[arg(
        long,
        value_name = "BUS",
        value_parser = parse_real_bus,
        help = "The CAN bus: socketcan:IFACE (e.g. socketcan:can0) or slcan:PATH[@SERIALBAUD] (e.g. slcan:/dev/ttyACM0@115200). The CAN bit rate is the description's network.baud_rate"
    )]
    pub bus: BusSpec,
    /// The instrument: a serial port, or a device server's TCP port.
    #[arg(
        long,
        value_name = "PORT",
        value_parser = parse_instrument_port,
        help = "The instrument: a serial port (e.g. /dev/ttyUSB0; baud rate, parity and stop bits from the description's profile), or tcp:HOST:PORT (e.g. tcp:192.168.127.254:4001, tcp:[fe80::1]:4001): a serial device server in TCP server mode (raw socket, e.g. Moxa NPort), its serial port set to the profile's settings. A lost or refused connection is retried after 0.5 s, doubling to at most 30 s; meanwhile the instrument counts as silent (the profile's stale policy) and the DeviceNet side keeps running"
    )]
    pub serial: InstrumentPort,
    /// The device description file (TOML) [default: the built-in reference converter: the
    /// breaker at MAC 5, 250 kbit/s, 9600 8N1].
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Use this MAC ID instead of the description's.
    #[arg(long, value_name = "N", value_parser = parse_mac)]
    pub mac: Option<MacId>,
    /// Write every CAN frame seen (received and sent) to FILE, in the format --format names, else
    /// the one FILE's extension names (.asc Vector, .trc PCAN-View 2.1, .csv python-can), else
    /// candump -L.
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// The --log file's format: candump, trc, asc or csv [default: from the file's extension,
    /// else candump].
    #[arg(long, value_name = "FORMAT", value_parser = parse_log_format, requires = "log")]
    pub format: Option<TraceFormat>,
    /// Keep what the board keeps in flash in FILE (JSON, replaced atomically): MAC ID, data rate
    /// and bus-off interrupt set over the network, and the configuration downloaded over the
    /// network; read at start, so a restart behaves like the board's power cycle [default: kept
    /// in memory until the process ends].
    #[arg(long, value_name = "FILE")]
    pub state: Option<PathBuf>,
    /// Stop after this many seconds [default: run until SIGINT or SIGTERM].
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub duration: Option<Duration>,
    /// Report nothing but errors (default: events and link changes on stderr).
    #[arg(long, short)]
    pub quiet: bool,
    /// Run with one deliberate fault: a mutant of `dnet-master conformance --self-test` (e.g.
    /// `answers-ucmm`), to see that the conformance suite catches it over this bus. Test
    /// equipment only: never on a plant network.
    #[arg(long, value_name = "ID", value_parser = converter_sim::mutants::parse)]
    pub mutant: Option<&'static converter_sim::mutants::Mutant>,
    /// Serve the firmware update object (class 0x6A) with DIR standing in for the board's flash
    /// and bootloader: dfu.bin (the DFU sectors and the resume log), active.bin (the applied
    /// image and its trailer, whose revision the soft slave then reports); needs --firmware-key.
    #[arg(long, value_name = "DIR", requires = "firmware_key")]
    pub firmware_dir: Option<PathBuf>,
    /// The Ed25519 public key images must be signed with: 32 raw bytes (the repository's TEST
    /// key is contrib/keys/test-ed25519.public).
    #[arg(long, value_name = "FILE", requires = "firmware_dir")]
    pub firmware_key: Option<PathBuf>,
    /// The board ID the update object accepts.
    #[arg(long, value_name = "N", default_value_t = crate::firmware::DEFAULT_BOARD_ID, requires = "firmware_dir")]
    pub firmware_board_id: u16,
}

/// `dnet-sim-breaker`: the simulated breaker on a serial port.
#[derive(Debug, Parser)]
#[command(
    name = "dnet-sim-breaker",
    version = crate::VERSION,
    about = "The simulated intelligent circuit breaker of the source paper on a serial port or pseudo-terminal: a status frame every second (0x68, 0x12, 18 data bytes, sum, 0x16), open/close/set-parameter/refresh commands obeyed and acknowledged.",
    after_help = "Logs one line per event (status frames sent, commands received, faults injected) to stdout or --log. Stops cleanly on SIGINT or SIGTERM. Exit status: 0 after a clean stop, 1 when the serial port failed, 2 for a usage error (a --log file that cannot be written among them)."
)]
pub struct SimBreakerArgs {
    /// The serial port or pty to serve (e.g. /dev/pts/3 from socat, /dev/ttyUSB1).
    #[arg(long, value_name = "PATH")]
    pub serial: PathBuf,
    /// Baud rate (8N1, the breaker's format).
    #[arg(long, default_value_t = 9600, value_parser = clap::value_parser!(u32).range(300..=4_000_000))]
    pub baud: u32,
    /// Seconds between status frames.
    #[arg(long, value_name = "SECONDS", default_value = "1", value_parser = parse_period)]
    pub period: Duration,
    /// Phase A, B, C, N currents reported while closed.
    #[arg(long, value_name = "A,B,C,N", default_value = "120,118,121,3", value_parser = parse_load)]
    pub load: [u8; 4],
    /// Start closed (default: open, as the reference input image shows).
    #[arg(long)]
    pub closed: bool,
    /// Stop sending after this many seconds (commands are still obeyed): a silent instrument.
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub silent_after: Option<Duration>,
    /// Every this many seconds send 6 bytes of garbage and spoil the next frame's checksum.
    #[arg(long, value_name = "SECONDS", value_parser = parse_period)]
    pub garbage_every: Option<Duration>,
    /// Write the event log to FILE instead of stdout.
    #[arg(long, value_name = "FILE")]
    pub log: Option<PathBuf>,
    /// Stop after this many seconds [default: run until SIGINT or SIGTERM].
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub duration: Option<Duration>,
}

/// Where the instrument is (`--serial`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum InstrumentPort {
    /// A local serial port or pty.
    Serial(PathBuf),
    /// A serial device server in TCP server mode: `tcp:HOST:PORT`.
    Tcp(TcpTarget),
}

impl std::fmt::Display for InstrumentPort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InstrumentPort::Serial(path) => write!(f, "{}", path.display()),
            InstrumentPort::Tcp(target) => write!(f, "{target}"),
        }
    }
}

/// `--serial`: `tcp:HOST:PORT`, else a path (`./tcp:x` for a file of that name).
pub fn parse_instrument_port(s: &str) -> Result<InstrumentPort, String> {
    match s.strip_prefix(crate::tcp::PREFIX) {
        Some(rest) => TcpTarget::parse(rest, s).map(InstrumentPort::Tcp),
        None if s.is_empty() => Err("an empty path: expected a serial port or tcp:HOST:PORT".into()),
        None => Ok(InstrumentPort::Serial(PathBuf::from(s))),
    }
}

/// `--bus`: a real bus; the simulated one lives inside `dnet-master`.
pub fn parse_real_bus(s: &str) -> Result<BusSpec, String> {
    match s.parse::<BusSpec>() {
        Ok(BusSpec::Sim) => Err(
            "the soft slave needs a real bus (socketcan:IFACE or slcan:PATH[@SERIALBAUD]); the simulated bus runs inside dnet-master (--bus sim)"
                .into(),
        ),
        Ok(spec) => Ok(spec),
        Err(e) => Err(e.replace("expected sim, ", "expected ")),
    }
}

/// `--format`: a trace format's name.
pub fn parse_log_format(s: &str) -> Result<TraceFormat, String> {
    TraceFormat::from_name(s)
        .ok_or_else(|| format!("unknown trace format '{s}' (one of: candump, trc, asc, csv)"))
}

/// A MAC ID, `0..=63`.
pub fn parse_mac(s: &str) -> Result<MacId, String> {
    s.trim()
        .parse::<u8>()
        .ok()
        .and_then(MacId::new)
        .ok_or_else(|| format!("MAC ID '{s}' is not a number of 0..=63"))
}

/// Seconds, `0` or more (`1.5`).
pub fn parse_seconds(s: &str) -> Result<Duration, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .and_then(from_secs_f64)
        .ok_or_else(|| format!("'{s}' is not a number of seconds >= 0"))
}

/// Seconds, at least one millisecond.
pub fn parse_period(s: &str) -> Result<Duration, String> {
    let d = parse_seconds(s)?;
    if d.total_micros() < 1000 {
        return Err(format!("'{s}': the period must be at least 0.001 s"));
    }
    Ok(d)
}

/// `A,B,C,N`: four currents, 0..=255 each.
pub fn parse_load(s: &str) -> Result<[u8; 4], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let mut load = [0u8; 4];
    if parts.len() != 4 {
        return Err(format!("'{s}': expected four currents A,B,C,N (e.g. 120,118,121,3)"));
    }
    for (slot, p) in load.iter_mut().zip(&parts) {
        *slot = p.parse().map_err(|_| format!("'{p}' in '{s}' is not a current of 0..=255 A"))?;
    }
    Ok(load)
}

/// The description the arguments name, with the `--mac` override applied.
pub fn load_description(args: &SoftSlaveArgs) -> Result<DeviceDescription, SoftSlaveError> {
    let mut description = match &args.config {
        Some(path) => DeviceDescription::load(path)?,
        None => DeviceDescription::reference(),
    };
    if let Some(mac) = args.mac {
        description.converter.device.mac_id = mac;
    }
    description.converter.validate()?;
    Ok(description)
}

fn profile_name(p: &ProfileConfig) -> &'static str {
    match p {
        ProfileConfig::Framed(_) => "framed serial",
        ProfileConfig::Modbus(m) => match m.framing {
            Framing::Rtu => "Modbus RTU",
            Framing::Ascii => "Modbus ASCII",
            Framing::Tcp => "Modbus TCP",
        },
    }
}

/// Modbus TCP (`framing = "tcp"`) needs an instrument reached over TCP: its MBAP frames on a
/// serial line would reach no instrument.
pub fn check_instrument_port(port: &InstrumentPort, profile: &ProfileConfig) -> Result<(), SoftSlaveError> {
    match (port, profile) {
        (InstrumentPort::Serial(path), ProfileConfig::Modbus(m)) if m.framing == Framing::Tcp => {
            Err(SoftSlaveError::Usage(format!(
                "--serial {}: the description's [profile.modbus] framing = \"tcp\" (Modbus TCP) needs --serial tcp:HOST:PORT; on a serial port use framing = \"rtu\" or \"ascii\"",
                path.display()
            )))
        }
        _ => Ok(()),
    }
}

/// Runs the soft slave until `stop` is set or `--duration` has passed; events and the closing
/// summary go to `report` unless `--quiet`.
pub fn run_soft_slave(
    args: &SoftSlaveArgs,
    stop: &AtomicBool,
    mut report: Box<dyn Write>,
) -> Result<RunSummary, SoftSlaveError> {
    if args.quiet {
        report = Box::new(std::io::sink());
    }
    let description = load_description(args)?;
    let state_file = args.state.as_ref().map(StateFile::new);
    let state = match &state_file {
        Some(f) => {
            let state = f.load()?;
            f.check_writable()?;
            state
        }
        None => StoredState::default(),
    };
    let base = description.converter;
    let (config, origin) = state.apply(&base, args.mac);
    if let slave_fw::converter::ConfigOrigin::Fault(e) = &origin {
        let _ = writeln!(report, "dnet-soft-slave: the stored configuration is refused ({e}): the description runs, with a configuration fault");
    }
    check_instrument_port(&args.serial, &config.profile)?;
    let serial_settings: SerialSettings = *config.profile.serial();
    let rate = Bitrate::from(config.device.baud_rate);
    let log = match &args.log {
        Some(path) => Some((
            LogWriter::create_as(path, log_format(path, args.format)?)
                .map_err(|source| SoftSlaveError::Log { path: path.display().to_string(), source })?,
            path.display().to_string(),
        )),
        None => None,
    };
    let clock = Clock::start();
    let (serial, line_text) = match &args.serial {
        InstrumentPort::Serial(path) => {
            let path = path.display().to_string();
            let text = format!("{path} ({})", settings_text(&serial_settings));
            (SerialLine::open(&path, &serial_settings, clock)?, text)
        }
        InstrumentPort::Tcp(target) => {
            let text = format!(
                "{target} (the device server's serial port at {}; reconnecting after {:.1} s doubling to {} s)",
                settings_text(&serial_settings),
                BACKOFF_FIRST.as_secs_f64(),
                BACKOFF_MAX.as_secs()
            );
            (TcpLine::open(target, clock), text)
        }
    };
    // The far end of an SLCAN line may be a host that starts later (the pty rig's master): the
    // set-up answers are not awaited.
    let bus = args.bus.open_as(rate, can_io::bus::slcan::SetUp::Peer)?;
    let _ = writeln!(
        report,
        "dnet-soft-slave: MAC {} at {rate} on {}, {} profile on {line_text}, input assembly {}",
        config.device.mac_id,
        bus.name(),
        profile_name(&config.profile),
        config.input.instance(),
    );
    if let Some(m) = args.mutant {
        let _ = writeln!(
            report,
            "dnet-soft-slave: MUTANT {}: {} (the conformance check {} must fail)",
            m.id, m.fault, m.target
        );
    }
    let firmware = match (&args.firmware_dir, &args.firmware_key) {
        (Some(dir), Some(key)) => Some(FirmwareDir::new(dir, key, args.firmware_board_id)?),
        _ => None,
    };
    let mut bridge = Bridge::new(base, bus, serial, clock)?;
    bridge.set_state(state, state_file, args.mac)?;
    if let Some(firmware) = firmware {
        bridge.set_firmware(firmware)?;
    }
    if let Some(m) = args.mutant {
        bridge.set_mutant(m);
    }
    if let Some((log, path)) = log {
        bridge.set_log(log, &path);
    }
    bridge.set_report(report);
    let summary = bridge.run(stop, args.duration)?;
    Ok(summary)
}

/// The closing report of a run.
pub fn summary_text(s: &RunSummary) -> String {
    let st = &s.stats;
    format!(
        "dnet-soft-slave: stopped after {:.1} s: CAN {} frames received, {} sent; serial {} bytes received, {} sent; \
         instrument frames {} received, {} checksum and {} framing errors, {} timeouts; commands {} sent, {} retried, {} failed, {} rejected; {} resets",
        s.elapsed.total_micros() as f64 / 1e6,
        s.can_received,
        s.can_sent,
        s.serial_bytes_received,
        s.serial_bytes_sent,
        st.frames_received,
        st.checksum_errors,
        st.framing_errors,
        st.timeouts,
        st.commands_sent,
        st.commands_retried,
        st.commands_failed,
        st.commands_rejected,
        s.resets,
    )
}

/// Runs the simulated breaker until `stop` is set or `--duration` has passed; the event log goes
/// to `--log` or `out`.
pub fn run_sim_breaker(
    args: &SimBreakerArgs,
    stop: &AtomicBool,
    out: Box<dyn Write>,
) -> Result<(), SoftSlaveError> {
    let log: Box<dyn Write> = match &args.log {
        Some(path) => Box::new(
            std::fs::File::create(path)
                .map_err(|source| SoftSlaveError::Log { path: path.display().to_string(), source })?,
        ),
        None => out,
    };
    let path = args.serial.display().to_string();
    let settings = SerialSettings::new_8n1(args.baud);
    let port = crate::serial::port_builder(&path, &settings)
        .timeout(std::time::Duration::from_millis(2))
        .open()
        .map_err(|source| SoftSlaveError::SerialOpen {
            path: path.clone(),
            settings: settings_text(&settings),
            source,
        })?;
    let options = BreakerOptions {
        period: args.period,
        load: args.load,
        closed: args.closed,
        silent_after: args.silent_after,
        garbage_every: args.garbage_every,
    };
    let mut runner = BreakerRunner::new(port, options, Clock::start(), log);
    runner.run(stop, args.duration).map_err(|source| SoftSlaveError::SerialIo {
        path,
        what: "serving",
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;
    use rstest::rstest;

    #[test]
    fn definitions_are_consistent() {
        SoftSlaveArgs::command().debug_assert();
        SimBreakerArgs::command().debug_assert();
    }

    #[rstest]
    #[case::socketcan("socketcan:can0", BusSpec::SocketCan { iface: "can0".into() })]
    #[case::slcan("slcan:/dev/ttyACM0@921600", BusSpec::Slcan { path: "/dev/ttyACM0".into(), baud: 921_600 })]
    fn real_buses(#[case] text: &str, #[case] spec: BusSpec) {
        assert_eq!(parse_real_bus(text), Ok(spec));
    }

    #[rstest]
    #[case::sim("sim", "needs a real bus")]
    #[case::unknown("vcan0", "expected socketcan:IFACE or slcan:PATH[@SERIALBAUD]")]
    #[case::empty("socketcan:", "needs an interface name")]
    fn refused_buses(#[case] text: &str, #[case] msg: &str) {
        let e = parse_real_bus(text).unwrap_err();
        assert!(e.contains(msg), "{e}");
        assert!(!e.contains("expected sim"), "{e}");
    }

    #[rstest]
    #[case::device("/dev/ttyUSB0", Ok(InstrumentPort::Serial("/dev/ttyUSB0".into())))]
    #[case::file_named_tcp("./tcp:x", Ok(InstrumentPort::Serial("./tcp:x".into())))]
    #[case::tcp("tcp:10.0.0.7:4001", Ok(InstrumentPort::Tcp(TcpTarget { host: "10.0.0.7".into(), port: 4001 })))]
    #[case::tcp_no_port("tcp:10.0.0.7", Err("'tcp:10.0.0.7': no port"))]
    #[case::tcp_bad_port("tcp:nport:http", Err("'tcp:nport:http': the port 'http' is not"))]
    #[case::empty("", Err("an empty path"))]
    fn instrument_ports(#[case] text: &str, #[case] want: Result<InstrumentPort, &str>) {
        match (parse_instrument_port(text), want) {
            (Ok(got), Ok(w)) => assert_eq!(got, w),
            (Err(e), Err(w)) => assert!(e.starts_with(w), "{e}"),
            (got, w) => panic!("{got:?} vs {w:?}"),
        }
    }

    #[rstest]
    #[case::tcp_on_a_port(
        Framing::Tcp,
        "/dev/ttyUSB0",
        Some("--serial /dev/ttyUSB0: the description's [profile.modbus] framing = \"tcp\"")
    )]
    #[case::tcp_on_tcp(Framing::Tcp, "tcp:10.0.0.7:502", None)]
    #[case::rtu_on_tcp(Framing::Rtu, "tcp:10.0.0.7:4001", None)]
    #[case::ascii_on_a_port(Framing::Ascii, "/dev/ttyUSB0", None)]
    fn modbus_tcp_needs_a_tcp_instrument(
        #[case] framing: Framing,
        #[case] port: &str,
        #[case] refused: Option<&str>,
    ) {
        let mut modbus = slave_fw::serial::modbus::ModbusConfig::new(Default::default());
        modbus.framing = framing;
        let port = parse_instrument_port(port).unwrap();
        match (check_instrument_port(&port, &ProfileConfig::Modbus(modbus)), refused) {
            (Ok(()), None) => {}
            (Err(e), Some(msg)) => {
                assert_eq!(e.exit_code(), 2);
                assert!(e.to_string().starts_with(msg), "{e}");
            }
            (got, want) => panic!("{got:?} vs {want:?}"),
        }
    }

    #[test]
    fn a_bad_tcp_port_is_a_usage_error_naming_the_argument() {
        let e = SoftSlaveArgs::try_parse_from([
            "dnet-soft-slave",
            "--bus",
            "slcan:/dev/null",
            "--serial",
            "tcp:nport",
        ])
        .unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let text = e.to_string();
        assert!(
            text.contains("invalid value 'tcp:nport' for '--serial <PORT>': 'tcp:nport': no port"),
            "{text}"
        );
    }

    #[rstest]
    #[case::whole("2", Some(2_000_000))]
    #[case::fraction("0.25", Some(250_000))]
    #[case::negative("-1", None)]
    #[case::word("soon", None)]
    fn seconds(#[case] text: &str, #[case] micros: Option<u64>) {
        assert_eq!(parse_seconds(text).ok().map(|d| d.total_micros()), micros);
    }

    #[test]
    fn periods_are_not_zero() {
        assert!(parse_period("0").unwrap_err().contains("at least 0.001 s"));
        assert_eq!(parse_period("0.5").unwrap(), Duration::from_millis(500));
    }

    #[rstest]
    #[case::ok("1,2,3,4", Ok([1, 2, 3, 4]))]
    #[case::spaces(" 10, 20 ,30,40", Ok([10, 20, 30, 40]))]
    #[case::three("1,2,3", Err("expected four currents"))]
    #[case::big("1,2,3,400", Err("'400' in '1,2,3,400' is not a current"))]
    fn loads(#[case] text: &str, #[case] want: Result<[u8; 4], &str>) {
        match (parse_load(text), want) {
            (Ok(got), Ok(w)) => assert_eq!(got, w),
            (Err(e), Err(w)) => assert!(e.contains(w), "{e}"),
            (got, w) => panic!("{got:?} vs {w:?}"),
        }
    }

    #[test]
    fn description_and_mac_override() {
        let args = SoftSlaveArgs::try_parse_from([
            "dnet-soft-slave",
            "--bus",
            "slcan:/dev/null",
            "--serial",
            "/dev/null",
            "--mac",
            "12",
        ])
        .unwrap();
        let d = load_description(&args).unwrap();
        assert_eq!(d.converter.device.mac_id.as_raw(), 12);
        assert_eq!(Bitrate::from(d.converter.device.baud_rate), Bitrate::K250);
    }

    #[test]
    fn missing_description_is_a_usage_error_naming_the_file() {
        let args = SoftSlaveArgs::try_parse_from([
            "dnet-soft-slave",
            "--bus",
            "socketcan:can0",
            "--serial",
            "/dev/null",
            "--config",
            "/nonexistent/breaker.toml",
        ])
        .unwrap();
        let e = load_description(&args).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().starts_with("/nonexistent/breaker.toml: cannot read"), "{e}");
    }

    #[test]
    fn summary_mentions_every_counter() {
        let text = summary_text(&RunSummary::default());
        for word in ["CAN", "serial", "checksum", "commands", "resets"] {
            assert!(text.contains(word), "{text}");
        }
    }
}
