//! The harness's error type: every failure named, with its context (MAC, request, timeout name,
//! file and line), never a panic.

use can_io::bus::BusError;
use can_io::log::LogError;
use devicenet::explicit::GeneralStatus;
use devicenet::Duration;

/// Everything that can stop a command.
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    /// The bus failed.
    #[error("bus error: {0}")]
    Bus(#[from] BusError),
    /// A log or transcript file is malformed or unreadable.
    #[error("{0}")]
    Log(#[from] LogError),
    /// Nothing arrived in time.
    #[error("{what}: no answer from MAC {mac} within {after} ({timeout})")]
    Timeout {
        /// What the master was waiting for.
        what: String,
        /// The device.
        mac: u8,
        /// How long it waited.
        after: Duration,
        /// The name of the timeout that expired.
        timeout: &'static str,
    },
    /// The device answered with an error response.
    #[error("{what}: MAC {mac} answered with an error: {text}")]
    ErrorResponse {
        /// The request.
        what: String,
        /// The device.
        mac: u8,
        /// General status.
        general: GeneralStatus,
        /// Additional code.
        additional: u8,
        /// Both by name.
        text: String,
    },
    /// An answer broke the protocol so the sequence cannot go on.
    #[error("{what}: {reason}")]
    Protocol {
        /// The step.
        what: String,
        /// What was wrong.
        reason: String,
    },
    /// Another node uses a MAC ID we need.
    #[error("duplicate MAC ID {mac}: {detail}")]
    DuplicateMac {
        /// The MAC in conflict.
        mac: u8,
        /// Who answered.
        detail: String,
    },
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
