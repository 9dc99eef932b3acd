//! The harness's error type: every failure of a command named, with its context (file and line,
//! frame index), never a panic. The master's own failures (MAC, request, timeout name) are
//! [`MasterError`]s, carried as they are.

use can_io::bus::BusError;
use can_io::log::LogError;
use can_io::trace::write::LogFormatError;
use can_io::trace::TraceFormat;
use devicenet::MacId;
use master_core::error::MasterError;
use std::fmt;

/// Everything that can stop a command.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    /// An operation of the master stopped: bus, timeout, error response, protocol, duplicate MAC.
    #[error(transparent)]
    Master(#[from] MasterError),
    /// A log or transcript file is malformed or unreadable.
    #[error("{0}")]
    Log(#[from] LogError),
    /// `--format` without `--log`.
    #[error("--format names the format of the --log file: give --log FILE too")]
    FormatWithoutLog,
    /// `--format` names a format `--log` cannot write.
    #[error("--format {format}: --log writes candump, trc, asc or csv (a pcap capture: --pcap FILE)")]
    FormatNotWritable {
        /// The format given.
        format: TraceFormat,
    },
    /// The `--log` file's format cannot be told or written.
    #[error(transparent)]
    LogFormat(#[from] LogFormatError),
    /// The bus options were refused where the bus is opened (an unknown bus, a bad simulated
    /// device setup); the opener's reason, which names the option.
    #[error("{detail}")]
    BusSetup {
        /// The opener's reason.
        detail: String,
    },
    /// The device addressed is at the master's own MAC.
    #[error("the device's MAC {mac} is the master's own MAC (--master-mac)")]
    DeviceIsMaster {
        /// The MAC.
        mac: MacId,
    },
    /// A transcript without any frame of a device, and no `--mac`.
    #[error("{path}: the transcript has no device frames; give the device with --mac")]
    TranscriptWithoutDevice {
        /// The transcript.
        path: String,
    },
    /// A transcript of several devices, and no `--mac`.
    #[error("{path}: the transcript has several devices (MAC {}); choose one with --mac", mac_list(macs))]
    TranscriptDevices {
        /// The transcript.
        path: String,
        /// Its devices.
        macs: Vec<MacId>,
    },
    /// A transcript with no frame at all.
    #[error("the transcript holds no frame")]
    EmptyTranscript,
    /// `--master-mac` differs from the transcript's master, whose frames a replay sends as
    /// recorded.
    #[error("--master-mac {given}: the transcript's master is MAC {recorded}, and a replay sends its frames as recorded; leave --master-mac out or give {recorded}")]
    MasterMacNotTranscript {
        /// `--master-mac`.
        given: MacId,
        /// The transcript's master.
        recorded: MacId,
    },
    /// `conformance --self-test` on another bus than the simulated one.
    #[error("--self-test runs the suite against simulated mutant devices: it needs --bus sim, not {bus}")]
    SelfTestNeedsSim {
        /// The bus given.
        bus: String,
    },
    /// An option that `conformance --self-test` has no use for.
    #[error("{option} has no meaning with --self-test, which builds its own devices and buses")]
    NotWithSelfTest {
        /// The option.
        option: &'static str,
    },
    /// The self-test's master at its device's MAC.
    #[error("the self-test's device is at MAC {mac}: give the master another MAC (--master-mac)")]
    SelfTestMasterMac {
        /// The self-test device's MAC.
        mac: MacId,
    },
    /// Two options of which only one can be given.
    #[error("{first} and {second}: choose one")]
    ChooseOne {
        /// One.
        first: &'static str,
        /// The other.
        second: &'static str,
    },
    /// An option's value out of its range.
    #[error("{option} {value}: expected {expected}")]
    InvalidValue {
        /// The option.
        option: &'static str,
        /// The value given.
        value: String,
        /// What it must be.
        expected: &'static str,
    },
    /// A command given neither of the inputs it needs.
    #[error("configure needs {option}")]
    MissingOption {
        /// What is missing.
        option: &'static str,
    },
    /// A directory given on the command line does not exist.
    #[error("{option} {path}: no such directory (create it first)")]
    NoSuchDirectory {
        /// The option.
        option: &'static str,
        /// The path given.
        path: String,
    },
    /// A file given on the command line cannot be read.
    #[error("{path}: cannot read the {what}: {error}")]
    Read {
        /// The file.
        path: String,
        /// What it should hold (`scan list`).
        what: &'static str,
        /// The OS error.
        error: std::io::Error,
    },
    /// A scan list file refused: where, the key, and why.
    #[error("{file}:{} scan list{}: {message}", at(*line, *column), key.as_ref().map_or_else(String::new, |k| format!(" (key `{k}`)")))]
    ScanList {
        /// The file.
        file: String,
        /// 1-based line (0: the file as a whole).
        line: usize,
        /// 1-based column.
        column: usize,
        /// The key at fault, when known.
        key: Option<String>,
        /// Why.
        message: String,
    },
    /// An EDS file refused: the file and the EDS reader's reason.
    #[error("{path}: {error}")]
    Eds {
        /// The file.
        path: String,
        /// The reader's error (`eds::EdsError`).
        error: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The sample history database cannot be used (`dnet_scanner::history::HistoryError`, which
    /// names the file).
    #[error(transparent)]
    History(Box<dyn std::error::Error + Send + Sync>),
    /// `--mqtt URL` refused: the URL and why.
    #[error("--mqtt {url}: {detail}")]
    Mqtt {
        /// The URL given.
        url: String,
        /// Why.
        detail: String,
    },
    /// The console cannot listen on the address given.
    #[error("cannot listen on {address}: {error}")]
    Listen {
        /// `--listen`.
        address: String,
        /// The OS error.
        error: std::io::Error,
    },
    /// The console cannot start (no random token, no worker thread).
    #[error("cannot start the console{}: {error}", if address.is_empty() { String::new() } else { format!(" on {address}") })]
    ConsoleStart {
        /// `--listen` (empty: before the address is used).
        address: String,
        /// What failed, as the OS said (`no random token: …`).
        error: String,
    },
    /// A network scan's MAC range out of 0..=63 or reversed.
    #[error("invalid MAC range {from}..={to}: MAC IDs are 0..=63")]
    MacRange {
        /// First MAC.
        from: u8,
        /// Last MAC.
        to: u8,
    },
    /// An EDS parameter whose link path names no attribute.
    #[error("Param{number} \"{name}\": its link path names no attribute")]
    ParamWithoutAttribute {
        /// The parameter's number.
        number: u32,
        /// Its name.
        name: String,
    },
    /// `--set NAME=…` names no parameter of the device.
    #[error("no parameter named \"{name}\"; the device has: {}", known.iter().map(|k| format!("\"{k}\"")).collect::<Vec<_>>().join(", "))]
    UnknownParameter {
        /// The name given.
        name: String,
        /// The device's parameters.
        known: Vec<String>,
    },
    /// A parameter's value refused (`--set`): malformed, or not representable in its data type.
    #[error("{detail}")]
    ParamValue {
        /// What is wrong, naming the assignment or the parameter.
        detail: String,
    },
    /// A device description that cannot be encoded into a configuration image.
    #[error("the description cannot be encoded: {0}")]
    Image(slave_fw::converter::image::ImageError),
    /// A configuration image too long for the download's size field.
    #[error("image too long: {bytes} bytes")]
    ImageTooLong {
        /// Its length.
        bytes: usize,
    },
    /// A description read from the device that cannot be written as TOML.
    #[error("{detail}")]
    DescriptionNotWritable {
        /// The writer's reason.
        detail: String,
    },
    /// A converter configuration refused by the simulated device.
    #[error("{0}")]
    Converter(slave_fw::converter::ConverterConfigError),
    /// A frame that cannot be built (more than 8 data bytes).
    #[error("{0}")]
    Frame(devicenet::FrameError),
    /// A message that cannot be encoded.
    #[error("{0}")]
    Message(devicenet::messages::MessageError),
    /// The device description file given with `--slave-config` was refused.
    #[error("{0}")]
    Description(#[from] slave_fw::description::DescriptionError),
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The exchange finished but some frame checks failed (see the table).
    #[error("{0} check(s) failed")]
    ChecksFailed(usize),
    /// A check that would have compared nothing of the device under test: failed, never passed.
    #[error("nothing compared: {0}")]
    NothingCompared(String),
    /// No device answers at the MAC: it sent no duplicate MAC ID check and answered nothing.
    #[error("no device answers at MAC {mac}: {detail}")]
    NoDevice {
        /// The MAC.
        mac: MacId,
        /// What was tried and not answered.
        detail: String,
    },
    /// The command ended, but what it allocated could not be released.
    #[error("could not release the device's connections: {0}")]
    Release(Box<MasterError>),
    /// The device answered a configuration step with an error response.
    #[error("MAC {mac} refused the configuration ({step}): {response}: {reason}")]
    ConfigurationRefused {
        /// The device.
        mac: MacId,
        /// The step (`Begin_Download`, …).
        step: &'static str,
        /// The error response, decoded.
        response: String,
        /// The device's own reason, read back from it.
        reason: String,
    },
    /// The image read back after a download is not the one downloaded.
    #[error("MAC {mac}: the stored image read back differs from the one downloaded ({bytes} bytes)")]
    ReadBackDiffers {
        /// The device.
        mac: MacId,
        /// The image's length.
        bytes: usize,
    },
    /// The device did not come back on-line after the reset that applies a configuration.
    #[error("MAC {mac} did not come back on-line within {within} of its reset (watched MAC {}){}", watched.iter().map(ToString::to_string).collect::<Vec<_>>().join(" and "), notes.iter().map(|n| format!("; {n}")).collect::<String>())]
    NotBackOnline {
        /// The device.
        mac: MacId,
        /// How long it was waited for.
        within: devicenet::Duration,
        /// The MACs watched for its duplicate MAC ID check.
        watched: Vec<MacId>,
        /// What the master noted meanwhile.
        notes: Vec<String>,
    },
    /// The configuration image the device serves does not decode.
    #[error("MAC {mac} serves a configuration image that does not decode: {detail}")]
    ImageUndecodable {
        /// The device.
        mac: MacId,
        /// The decoder's reason.
        detail: String,
    },
    /// The device answered the write of a parameter with an error response.
    #[error("MAC {mac} refused {name} = {value}: {response}")]
    ParameterRefused {
        /// The device.
        mac: MacId,
        /// The parameter.
        name: String,
        /// The value written.
        value: i64,
        /// The error response, decoded.
        response: String,
    },
    /// A replay diverged from its transcript.
    #[error("{0}")]
    Divergence(Box<Divergence>),
    /// A firmware update stopped (`firmware-update`); a file that does not fit the device is a
    /// usage error, the device's refusals are not.
    #[error(transparent)]
    Update(Box<master_core::update::UpdateError>),
}

impl HarnessError {
    /// The exit status of `dnet-master` for this error: 2 for usage and configuration errors (bad
    /// option or file, a description refused, an output file that cannot be written), 128 + the
    /// signal for an interruption, 1 for everything the device or the bus did.
    #[must_use]
    pub fn exit_code(&self) -> u8 {
        match self {
            HarnessError::Log(_) | HarnessError::Description(_) | HarnessError::Write { .. } => 2,
            HarnessError::Master(m) if m.is_usage() => 2,
            e if e.is_usage() => 2,
            HarnessError::Master(MasterError::Interrupted { signal }) => {
                master_core::stop::exit_status(*signal)
            }
            _ => 1,
        }
    }
}

impl HarnessError {
    /// A bad command-line value, option combination or input file: exit status 2.
    #[must_use]
    pub fn is_usage(&self) -> bool {
        if let HarnessError::Update(u) = self {
            return matches!(**u, master_core::update::UpdateError::File { .. });
        }
        !matches!(
            self,
            HarnessError::Master(_)
                | HarnessError::Log(_)
                | HarnessError::Description(_)
                | HarnessError::Write { .. }
                | HarnessError::ChecksFailed(_)
                | HarnessError::NothingCompared(_)
                | HarnessError::NoDevice { .. }
                | HarnessError::Release(_)
                | HarnessError::ConfigurationRefused { .. }
                | HarnessError::ReadBackDiffers { .. }
                | HarnessError::NotBackOnline { .. }
                | HarnessError::ImageUndecodable { .. }
                | HarnessError::ParameterRefused { .. }
                | HarnessError::Divergence(_)
        )
    }

    /// The signal that interrupted the command, if one did.
    #[must_use]
    pub fn interrupted_by(&self) -> Option<i32> {
        match self {
            HarnessError::Master(MasterError::Interrupted { signal }) => Some(*signal),
            _ => None,
        }
    }
}

/// `5, 6`.
fn mac_list(macs: &[MacId]) -> String {
    macs.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
}

/// `7:7:` (nothing for line 0, the file as a whole).
fn at(line: usize, column: usize) -> String {
    if line == 0 {
        String::new()
    } else {
        format!("{line}:{column}:")
    }
}

impl From<BusError> for HarnessError {
    fn from(e: BusError) -> HarnessError {
        HarnessError::Master(MasterError::Bus(e))
    }
}

/// A frame with its text.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ShownFrame {
    /// Transcript line (for expected and context frames).
    pub line: Option<usize>,
    /// Time: recorded (transcript) or seen (actual), seconds.
    pub time: String,
    /// `ID#DATA`.
    pub frame: String,
    /// Decoded meaning.
    pub meaning: String,
}

/// Where and how a replay (`master_harness::replay`) left its transcript.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Divergence {
    /// 0-based index of the transcript frame at which it happened.
    pub index: usize,
    /// Frames in the transcript.
    pub total: usize,
    /// What happened.
    pub reason: String,
    /// The transcript frame expected (or the stimulus that was next).
    pub expected: Option<ShownFrame>,
    /// What the device sent instead (`None`: nothing).
    pub actual: Option<ShownFrame>,
    /// The transcript frames before it.
    pub before: Vec<ShownFrame>,
}

impl fmt::Display for Divergence {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let line =
            self.expected.as_ref().and_then(|e| e.line).map_or_else(String::new, |l| format!("line {l}, "));
        writeln!(
            f,
            "replay diverged at transcript {line}frame {} of {}: {}",
            self.index + 1,
            self.total,
            self.reason
        )?;
        let show = |f: &mut fmt::Formatter<'_>, label: &str, s: &Option<ShownFrame>| match s {
            Some(s) => writeln!(f, "  {label:<9} {:<28} {} ({})", s.frame, s.meaning, s.time),
            None => writeln!(f, "  {label:<9} nothing"),
        };
        show(f, "expected:", &self.expected)?;
        show(f, "actual:", &self.actual)?;
        if !self.before.is_empty() {
            writeln!(f, "frames before it:")?;
            for b in &self.before {
                writeln!(
                    f,
                    "  line {:>4}  {:>14}  {:<28} {}",
                    b.line.unwrap_or(0),
                    b.time,
                    b.frame,
                    b.meaning
                )?;
            }
        }
        Ok(())
    }
}
