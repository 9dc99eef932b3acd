//! The master's error: every way an operation on the bus can stop, with what the user needs to act
//! on it (MAC, request, timeout name), never a panic.

use can_io::bus::BusError;
use devicenet::explicit::GeneralStatus;
use devicenet::messages::MessageError;
use devicenet::{Duration, FrameError, MacId};

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
    /// The master was asked for something it does not do: a device at the master's own MAC,
    /// options that contradict each other (a usage error: exit status 2).
    #[error(transparent)]
    Usage(#[from] UsageError),
    /// A request that cannot be built or is too long.
    #[error(transparent)]
    Request(#[from] RequestError),
    /// A frame the master builds does not fit a CAN frame.
    #[error("cannot build the frame: {0}")]
    Frame(#[from] FrameError),
    /// A message the master builds cannot be written.
    #[error("cannot build the message: {0}")]
    Message(#[from] MessageError),
    /// The device's connection set is allocated to another master (0x0C / 0x01, protocol §3.4).
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

impl MasterError {
    /// `true` for a usage error (what the user asked for cannot be done: exit status 2), as
    /// opposed to what the device or the bus did.
    #[must_use]
    pub fn is_usage(&self) -> bool {
        matches!(self, MasterError::Usage(_))
    }
}

/// What the master was asked for and does not do.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum UsageError {
    /// The device is at the master's own MAC ID.
    #[error("the device's MAC {0} is the master's own MAC")]
    OwnMac(MacId),
    /// The new MAC ID of a recovery is the master's own.
    #[error("--to {0} is the master's own MAC ID")]
    RecoverToOwnMac(MacId),
    /// More output bytes than the device consumes.
    #[error("--output has {given} bytes; the device consumes {consumed}{}", if *attribute { " (Connection 2 attribute 8)" } else { "" })]
    OutputTooLong {
        /// Bytes given.
        given: usize,
        /// Bytes the device consumes.
        consumed: u16,
        /// Name the attribute the size came from.
        attribute: bool,
    },
    /// Output data for a bit-strobe connection.
    #[error("--output: a bit-strobe command carries one bit per device and no output data (§II.1.2)")]
    StrobeOutput,
    /// An I/O operation with no strobe, COS or cyclic connection established.
    #[error("no strobe, COS or cyclic connection is established")]
    NoIoConnection,
    /// `establish_io` asked for poll.
    #[error("establish_io brings up strobe, COS or cyclic; poll is connect's")]
    PollIsConnects,
    /// A COS/cyclic option given with another connection type.
    #[error("{flag} applies to --io cos and --io cyclic (Connection 4), not to --io {kind}")]
    CosOptionMisplaced {
        /// The option.
        flag: &'static str,
        /// The connection type asked for.
        kind: String,
    },
    /// Acknowledge settings together with acknowledge suppression.
    #[error("--ack-timer and --retry-limit configure acknowledgements, which --ack-suppression turns off")]
    AckSettingsSuppressed,
    /// An acknowledge timer of 0.
    #[error("--ack-timer 0: the acknowledge timer is 1..=65535 ms")]
    AckTimerZero,
    /// A Who time-delay byte offset beyond the answer.
    #[error("time-delay byte offset {0}: Who's answer has 7 bytes, 0..=6")]
    TimeDelayOffset(u8),
    /// No faulted node with the serial number asked for answered.
    #[error("--serial 0x{serial:08X}: no faulted node with it answered; found {found}")]
    NoSuchSerial {
        /// The serial number asked for.
        serial: u32,
        /// The nodes that answered.
        found: String,
    },
    /// A configuration image read past the 16-bit chunk offset.
    #[error("image too long: {size} bytes asked for, a chunk offset is 16 bits (at most 65535)")]
    ImageTooLong {
        /// The size asked for.
        size: usize,
    },
    /// Several faulted nodes answered and none was chosen.
    #[error("{count} faulted nodes answered at MAC {mac}: {found}; choose one with --serial")]
    SeveralFaulted {
        /// How many.
        count: usize,
        /// Their MAC.
        mac: MacId,
        /// The nodes that answered.
        found: String,
    },
}

/// Why a request cannot be sent as it is.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum RequestError {
    /// The request cannot be written in the body format (reserved format, path too long).
    #[error("cannot build the request: {0}")]
    Build(devicenet::explicit::ExplicitError),
    /// The request is longer than the master sends.
    #[error("the request is {len} bytes; the master sends at most {max}")]
    TooLong {
        /// Its length, header included.
        len: usize,
        /// The longest message the master sends.
        max: usize,
    },
}
