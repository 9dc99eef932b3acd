//! The master's error: every way an operation on the bus can stop, with what the user needs to act
//! on it (MAC, request, timeout name), never a panic.

use can_io::bus::BusError;
use devicenet::explicit::GeneralStatus;
use devicenet::Duration;

/// Why an operation of the [`Master`](crate::master::Master), the [`Session`](crate::session::Session)
/// or a [`Transaction`](crate::client::Transaction) stopped.
#[derive(Debug, thiserror::Error)]
pub enum MasterError {
    /// The bus failed.
    #[error("bus error: {0}")]
    Bus(#[from] BusError),
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
    /// The master was asked for something it does not do: a request that cannot be built or is
    /// too long, a device at the master's own MAC, options that contradict each other.
    #[error("{0}")]
    Invalid(String),
    /// The device's connection set is allocated to another master (0x0C / 0x01, notes §3.4).
    #[error("MAC {mac} is allocated to another master{}: a device serves one master at a time; release it there, or reset the device", owner.map_or_else(|| " (its MAC was not seen on the bus)".to_string(), |m| format!(" (MAC {m})")))]
    AllocationConflict {
        /// The device.
        mac: u8,
        /// The other master's MAC, when its traffic was seen.
        owner: Option<u8>,
    },
    /// A stop was asked for (SIGINT, SIGTERM) while the operation waited on the bus.
    #[error("interrupted by {}", crate::stop::signal_name(*signal))]
    Interrupted {
        /// The signal's number.
        signal: i32,
    },
    /// The session's log file could not be written.
    #[error("cannot write the log file: {source}")]
    LogWrite {
        /// The OS error.
        source: std::io::Error,
    },
}
