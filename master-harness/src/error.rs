//! The harness's error type: every failure of a command named, with its context (file and line,
//! frame index), never a panic. The master's own failures (MAC, request, timeout name) are
//! [`MasterError`]s, carried as they are.

use can_io::bus::BusError;
use can_io::log::LogError;
use master_core::error::MasterError;

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
    /// A replay diverged from its transcript.
    #[error("{0}")]
    Divergence(Box<crate::replay::Divergence>),
}

impl From<BusError> for HarnessError {
    fn from(e: BusError) -> HarnessError {
        HarnessError::Master(MasterError::Bus(e))
    }
}
