//! The harness's error type: every failure of a command named, with its context (file and line,
//! frame index), never a panic. The master's own failures (MAC, request, timeout name) are
//! [`MasterError`]s, carried as they are.

use can_io::bus::BusError;
use can_io::log::LogError;
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
    /// A bad command-line value or option combination.
    #[error("{0}")]
    Usage(String),
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
    /// The device refused or failed a configuration step (the device's reason included).
    #[error("{0}")]
    Refused(String),
    /// A replay diverged from its transcript.
    #[error("{0}")]
    Divergence(Box<Divergence>),
}

impl HarnessError {
    /// The exit status of `dnet-master` for this error: 2 for usage and configuration errors (bad
    /// option or file, a description refused, an output file that cannot be written), 128 + the
    /// signal for an interruption, 1 for everything the device or the bus did.
    #[must_use]
    pub fn exit_code(&self) -> u8 {
        match self {
            HarnessError::Usage(_)
            | HarnessError::Log(_)
            | HarnessError::Description(_)
            | HarnessError::Write { .. }
            | HarnessError::Master(MasterError::Invalid(_)) => 2,
            HarnessError::Master(MasterError::Interrupted { signal }) => {
                master_core::stop::exit_status(*signal)
            }
            _ => 1,
        }
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
