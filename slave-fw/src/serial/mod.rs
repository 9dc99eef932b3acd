//! Serial instrument profiles: everything between the UART and the converter's I/O images.
//!
//! ## How the converter drives a profile
//!
//! A [`Profile`] is a pure state machine (the contract is written on the type):
//!
//! 1. bytes read from the UART go to [`Profile::on_bytes`] with the time they arrived;
//! 2. the consumed poll data goes to [`Profile::set_outputs`] (an empty slice is an idle poll),
//!    a poll connection timeout to [`Profile::connection_fault`];
//! 3. after any of these, and whenever `now >= poll_at()`, the caller calls
//!    [`Profile::poll_transmit`] until it returns `None`, writing each returned frame to the UART;
//! 4. the produced poll data is [`Profile::input_image`], optionally followed by
//!    [`LinkStatus::to_bytes`] (status byte + freshness counter).
//!
//! ## Fixed memory
//!
//! Capacities are constants of this module ([`IMAGE_CAPACITY`], [`FRAME_CAPACITY`],
//! [`modbus::SCAN_LIST_CAPACITY`], …); configurations are checked against them by `validate()`,
//! which every constructor calls, so a running profile never meets a size it cannot hold.

pub mod breaker;
mod buffer;
pub mod checksum;
mod counter;
pub mod error;
pub mod framed;
pub mod framed_profile;
pub mod health;
pub mod line;
pub mod modbus;
pub mod profile;
pub mod sequencer;
pub mod trace;

pub use checksum::Checksum;
pub use error::{ConfigError, Conflict, Field, FieldPath, Problem};
pub use framed::{Frame, FrameCounters, FrameError, FrameParser, FramedConfig, LengthField};
pub use framed_profile::{AckFormat, CommandFormat, FramedProfile, FramedProfileConfig};
pub use health::{Counter, HealthConfig, LinkHealth, LinkState, LinkStatus, StalePolicy, Stats, StatusByte};
pub use line::{DataBits, Parity, SerialSettings, StopBits};
pub use profile::{Profile, ProfileConfig};
pub use sequencer::{
    Command, CommandCode, CommandOutcome, CommandSequencer, IdleAction, OutputMode, SequencerConfig,
    Transmission,
};

/// The largest input or output image a profile holds, in bytes.
pub const IMAGE_CAPACITY: usize = 64;

/// The largest frame a framed profile sends or receives, in bytes: start, length, 255 data bytes,
/// a two-byte checksum and the end delimiter.
pub const FRAME_CAPACITY: usize = 260;

/// The longest frame an [`IdleAction::Send`] may configure, in bytes.
pub const IDLE_FRAME_CAPACITY: usize = 32;
