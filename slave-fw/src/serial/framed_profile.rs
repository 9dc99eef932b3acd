//! The framed-serial profile: the breaker and every instrument that speaks a similar protocol.
//!
//! [`FramedProfile`] combines a [`FrameParser`], a [`CommandSequencer`] and a [`LinkHealth`]:
//!
//! * received frames whose data length is [`status_len`](FramedProfileConfig::status_len) become
//!   the input image;
//! * frames matching the [`AckFormat`] answer the command in progress (status `ok_status` →
//!   [`CommandOutcome::Ok`], anything else → [`CommandOutcome::Rejected`]);
//! * any other good frame counts as [`Stats::unexpected_frames`] (and as proof of life);
//! * commands from the poll outputs are framed as `wire code, argument bytes…` according to the
//!   [`CommandFormat`] table, padded with zeros for fixed-length framings.
//!
//! Everything that differs between instruments lives in [`FramedProfileConfig`]; the breaker is
//! [`breaker::profile_config`](super::breaker::profile_config).

use super::error::{as_u32, ConfigError, Conflict, Field, Problem};
use super::framed::{FrameError, FrameParser, FramedConfig, LengthField};
use super::health::{Counter, HealthConfig, LinkHealth, LinkStatus, Stats};
use super::line::SerialSettings;
use super::sequencer::{
    check_idle_frame, Command, CommandOutcome, CommandSequencer, SequencerConfig, Transmission,
};
use super::{FRAME_CAPACITY, IMAGE_CAPACITY};
use devicenet::Instant;
use heapless::Vec;

/// The most entries in [`FramedProfileConfig::commands`].
pub const MAX_COMMAND_FORMATS: usize = 8;

/// How the instrument acknowledges a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AckFormat {
    /// Data bytes in an acknowledgement (2 for the breaker: `cmd | flag, status`). With one byte
    /// there is no status and every acknowledgement is an acceptance.
    pub data_len: u8,
    /// Bits set in the first data byte of an acknowledgement, on top of the command's wire code
    /// (`0x80` for the breaker), `1..=255`.
    pub flag: u8,
    /// The status byte (second data byte) that means accepted.
    pub ok_status: u8,
}

/// How one poll command code is sent: `wire`, then the first `args` argument bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct CommandFormat {
    /// The poll command code (byte 0 of the outputs), `1..=255`.
    pub code: u8,
    /// The first data byte of the command frame.
    pub wire: u8,
    /// How many argument bytes (poll bytes 2…) follow, `0..=6`.
    pub args: u8,
}

/// Everything that describes a framed-serial instrument.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct FramedProfileConfig {
    /// The serial line (timing of transmissions).
    pub serial: SerialSettings,
    /// The framing of every frame, both directions.
    pub framing: FramedConfig,
    /// Data bytes in a status frame; also the length of the input image, `1..=64`.
    pub status_len: u8,
    /// How commands are acknowledged; `None` when the instrument does not answer commands (each
    /// command is then [`CommandOutcome::Ok`] once sent).
    pub ack: Option<AckFormat>,
    /// The commands the instrument understands.
    pub commands: Vec<CommandFormat, MAX_COMMAND_FORMATS>,
    /// Timeouts, retries, idle and fault frames.
    pub sequencer: SequencerConfig,
    /// Stale timeout and policy.
    pub health: HealthConfig,
}

impl FramedProfileConfig {
    /// The most data bytes an outgoing frame may carry before padding.
    fn max_tx_data(&self) -> usize {
        match self.framing.length {
            LengthField::Fixed(n) => usize::from(n),
            LengthField::Byte | LengthField::Delimited => usize::from(self.framing.max_len),
        }
    }

    /// Checks every field, and that status frames, acknowledgements, commands and idle/fault
    /// frames fit the framing.
    #[allow(clippy::manual_contains)] // No `memchr` in the firmware (size budget).
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.serial.validate()?;
        self.framing.validate()?;
        self.sequencer.validate()?;
        self.health.validate()?;

        // The data lengths a frame of this framing can carry: status frames, acknowledgements.
        let (min, max) = match self.framing.length {
            LengthField::Fixed(n) => (u32::from(n), u32::from(n)),
            LengthField::Byte | LengthField::Delimited => (1, u32::from(self.framing.max_len)),
        };
        ConfigError::check_range(
            Field::StatusLen,
            u32::from(self.status_len),
            min,
            max.min(as_u32(IMAGE_CAPACITY)),
        )?;

        if let Some(ack) = self.ack {
            ConfigError::check_range(Field::AckDataLen, u32::from(ack.data_len), min, max)?;
            ConfigError::check_range(Field::AckFlag, u32::from(ack.flag), 1, 255)?;
        }

        let max_data = self.max_tx_data();
        // The byte that data sent in a delimited frame must not contain.
        let end = match self.framing.length {
            LengthField::Delimited => self.framing.end,
            LengthField::Byte | LengthField::Fixed(_) => None,
        };
        let max_args = as_u32(max_data.saturating_sub(1).min(6));
        for (i, c) in self.commands.iter().enumerate() {
            check_command(c, self.commands.get(..i).unwrap_or(&[]), max_args, end).map_err(|e| e.at(i))?;
        }

        let actions = [
            (Field::SequencerOnIdle, &self.sequencer.on_idle),
            (Field::SequencerOnFault, &self.sequencer.on_fault),
        ];
        for (field, action) in actions {
            check_idle_frame(field, action, 0, max_data)?;
        }
        // Only a delimited framing has a byte the frames must not contain. Skipped through the
        // iterator: 32 bytes smaller than the plain loop, 36 than an `if let` around it (flash).
        for (field, action) in actions.into_iter().filter(|_| end.is_some()) {
            // A plain loop: `contains` on bytes would pull in `memchr` (flash).
            if action.frame().is_some_and(|frame| frame.iter().any(|&b| Some(b) == end)) {
                return Err(ConfigError::conflict(field, Conflict::ContainsEndDelimiter));
            }
        }
        FrameParser::<FRAME_CAPACITY>::check_capacity(&self.framing)
    }
}

/// Checks one entry of [`FramedProfileConfig::commands`] against the entries before it (the
/// caller adds the entry's index to the error).
#[allow(clippy::manual_contains)] // No `memchr` in the firmware (size budget).
fn check_command(
    c: &CommandFormat,
    before: &[CommandFormat],
    max_args: u32,
    end: Option<u8>,
) -> Result<(), ConfigError> {
    ConfigError::check_range(Field::CommandsCode, u32::from(c.code), 1, 255)?;
    ConfigError::check_range(Field::CommandsArgs, u32::from(c.args), 0, max_args)?;
    if let Some(other) = before.iter().position(|o| o.code == c.code) {
        let problem = Problem::Duplicate { other: other as u16 };
        return Err(ConfigError { field: Field::CommandsCode, index: None, problem });
    }
    if end == Some(c.wire) {
        return Err(ConfigError::conflict(Field::CommandsWire, Conflict::EqualsEndDelimiter));
    }
    Ok(())
}

/// A framed-serial instrument: input image from status frames, commands from poll outputs,
/// link health. Driven like every [`Profile`](super::Profile): see the [`serial`](super) module.
#[derive(Clone, Debug)]
pub struct FramedProfile {
    config: FramedProfileConfig,
    parser: FrameParser<FRAME_CAPACITY>,
    sequencer: CommandSequencer,
    health: LinkHealth,
    image: Vec<u8, IMAGE_CAPACITY>,
    tx: Vec<u8, FRAME_CAPACITY>,
}

impl FramedProfile {
    /// A profile for `config`, started at `now` (the stale timeout runs from here). The input image
    /// starts as `status_len` zero bytes.
    pub fn new(config: FramedProfileConfig, now: Instant) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(FramedProfile::build(config, now))
    }

    /// The profile for `config`, which [`FramedProfileConfig::validate`] has accepted: nothing
    /// is checked twice, and nothing fails. Out of line: the large value is built in its return
    /// slot, not copied piece by piece through the caller's frame (firmware size budget).
    #[inline(never)]
    pub(crate) fn build(config: FramedProfileConfig, now: Instant) -> Self {
        let parser = FrameParser::build(config.framing);
        let sequencer = CommandSequencer::build(config.sequencer.clone());
        let health = LinkHealth::build(config.health, now);
        let mut image = Vec::new();
        // validate() bounds status_len by IMAGE_CAPACITY.
        let _ = image.resize(usize::from(config.status_len).min(IMAGE_CAPACITY), 0);
        FramedProfile { config, parser, sequencer, health, image, tx: Vec::new() }
    }

    /// The configuration.
    pub fn config(&self) -> &FramedProfileConfig {
        &self.config
    }

    /// Takes bytes read from the UART at `now`.
    pub fn on_bytes(&mut self, bytes: &[u8], now: Instant) {
        let FramedProfile { config, parser, sequencer, health, image, .. } = self;
        for &b in bytes {
            let skipped_before = parser.counters().skipped_bytes;
            parser.push(b, |event| match event {
                Ok(frame) => on_frame(config, sequencer, health, image, frame.data(), now),
                Err(FrameError::BadChecksum) => health.on_checksum_error(),
                Err(FrameError::BadEnd | FrameError::BadLength | FrameError::Overflow) => {
                    health.on_framing_error()
                }
            });
            health.on_discarded_bytes(parser.counters().skipped_bytes.wrapping_sub(skipped_before));
        }
        self.sync_stats();
    }

    /// Takes the consumed poll data received at `now`: the 8 command bytes, or an empty slice for
    /// an idle poll.
    pub fn set_outputs(&mut self, outputs: &[u8], now: Instant) {
        self.sequencer.set_outputs(outputs, now);
    }

    /// The poll connection timed out at `now`.
    pub fn connection_fault(&mut self, now: Instant) {
        self.sequencer.connection_fault(now);
    }

    /// Advances timers to `now`: answer timeouts and retries, stale detection and policy.
    pub fn poll(&mut self, now: Instant) {
        self.sequencer.poll(now);
        if self.health.poll(now) {
            self.health.apply_stale_policy(&mut self.image);
        }
        self.sync_stats();
    }

    /// Advances to `now` and returns the next frame to write to the UART, if any. Call until
    /// `None`.
    #[must_use = "the bytes are handed out once: dropped ones are never sent"]
    pub fn poll_transmit(&mut self, now: Instant) -> Option<&[u8]> {
        self.poll(now);
        while let Some(t) = self.sequencer.next_transmission(now) {
            let encoded = match t {
                // The command in progress is the last one started: framed from where the sequencer
                // keeps it, not from the transmission's copy (flash).
                Transmission::Command { .. } => match self.sequencer.last_command() {
                    Some(command) => encode_command(&self.config, command, &mut self.tx),
                    None => false,
                },
                Transmission::Idle | Transmission::Fault => {
                    let frame = self.sequencer.frame_for(t).unwrap_or(&[]);
                    encode_padded(&self.config.framing, frame, &mut self.tx)
                }
            };
            // A command that cannot be framed has an unknown code (validated configurations never
            // fail otherwise): it is not sent, and ends unsupported. An idle/fault frame that
            // cannot be framed is passed over as if sent. Without acknowledgements a command is
            // done once sent. One call site each for recording and completing (flash).
            let command = matches!(t, Transmission::Command { .. });
            if encoded || !command {
                let tx_done =
                    if encoded { now + self.config.serial.transmit_time(self.tx.len()) } else { now };
                self.sequencer.record_transmitted(t, tx_done);
            }
            if command && (!encoded || self.config.ack.is_none()) {
                let outcome = if encoded { CommandOutcome::Ok } else { CommandOutcome::Unsupported };
                self.sequencer.complete(outcome);
            }
            if encoded {
                self.health.count(Counter::FramesSent);
                self.sync_stats();
                return Some(&self.tx);
            }
        }
        self.sync_stats();
        None
    }

    /// When to call [`poll_transmit`](Self::poll_transmit) next.
    pub fn poll_at(&self) -> Option<Instant> {
        match (self.sequencer.poll_at(), self.health.poll_at()) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The input image: the data of the last status frame (or zeros, per policy and start-up).
    pub fn input_image(&self) -> &[u8] {
        &self.image
    }

    /// The link status.
    pub fn status(&self) -> LinkStatus {
        self.health.status(self.sequencer.outcome(), false, false)
    }

    /// The statistics.
    pub fn stats(&self) -> Stats {
        self.health.stats()
    }

    /// The statistics as a table indexed by [`Counter`].
    pub fn counts(&self) -> &[u32; Counter::COUNT] {
        self.health.counts()
    }

    /// The command sequencer (last command, outcome, mode).
    pub fn sequencer(&self) -> &CommandSequencer {
        &self.sequencer
    }

    /// The frame parser's counters by rejection kind.
    pub fn parser_counters(&self) -> &super::FrameCounters {
        self.parser.counters()
    }

    fn sync_stats(&mut self) {
        let c = *self.sequencer.counters();
        let h = &mut self.health;
        h.set_count(Counter::CommandsSent, c.sent);
        h.set_count(Counter::CommandsRetried, c.retried);
        h.set_count(Counter::CommandsFailed, c.failed);
        h.set_count(Counter::CommandsRejected, c.rejected);
        h.set_count(Counter::Timeouts, c.timeouts);
    }
}

/// Frames `command` into `tx`; `false` if the code has no [`CommandFormat`].
fn encode_command(config: &FramedProfileConfig, command: &Command, tx: &mut Vec<u8, FRAME_CAPACITY>) -> bool {
    let Some(format) = command_format(config, command) else {
        return false;
    };
    let [a0, a1, a2, a3, a4, a5] = command.args;
    let data = [format.wire, a0, a1, a2, a3, a4, a5];
    // More than six argument bytes cannot be taken from the poll: the wire code alone.
    let len = if format.args <= 6 { 1 + usize::from(format.args) } else { 1 };
    encode_padded(&config.framing, data.get(..len).unwrap_or(&[]), tx)
}

#[inline(never)]
fn command_format(config: &FramedProfileConfig, command: &Command) -> Option<CommandFormat> {
    config.commands.iter().copied().find(|f| f.code == command.code)
}

/// Frames `data` into `out`, padded with zeros up to (or cut to) a fixed length; `false`, with
/// `out` empty, when the framing does not take it. The same frame as
/// [`FramedConfig::encode_to_vec`] of the padded data, written straight into `out`: no padded
/// copy, no zero-filled buffer written twice (firmware size budget).
#[allow(clippy::manual_contains)] // No `memchr` in the firmware (size budget).
fn encode_padded(framing: &FramedConfig, data: &[u8], out: &mut Vec<u8, FRAME_CAPACITY>) -> bool {
    out.clear();
    let len = match framing.length {
        LengthField::Fixed(n) => usize::from(n),
        LengthField::Byte | LengthField::Delimited if data.len() <= usize::from(framing.max_len) => {
            data.len()
        }
        LengthField::Byte | LengthField::Delimited => return false,
    };
    if let (LengthField::Delimited, Some(end)) = (framing.length, framing.end) {
        // A plain loop: `contains` on bytes would pull in `memchr` (flash).
        if data.iter().any(|&b| b == end) {
            return false;
        }
    }
    let header = framing.header_len();
    // At most 2 + 255 + 3 = FRAME_CAPACITY bytes (`len` is a `u8` value): no push can fail.
    // Single bytes pushed in line; `extend_from_slice` only where the length varies (flash).
    const _: () = assert!(2 + 255 + 3 <= FRAME_CAPACITY);
    let _ = out.push(framing.start);
    if framing.length == LengthField::Byte {
        let _ = out.push(len as u8);
    }
    for i in 0..len {
        let _ = out.push(data.get(i).copied().unwrap_or(0));
    }
    let sum = framing.checksum.wire_bytes(out.get(header..).unwrap_or(&[]));
    let _ = out.extend_from_slice(sum.get(..framing.checksum.byte_len()).unwrap_or(&[]));
    if let Some(end) = framing.end {
        let _ = out.push(end);
    }
    true
}

/// Handles one good frame's data.
fn on_frame(
    config: &FramedProfileConfig,
    sequencer: &mut CommandSequencer,
    health: &mut LinkHealth,
    image: &mut Vec<u8, IMAGE_CAPACITY>,
    data: &[u8],
    now: Instant,
) {
    health.on_frame(now);
    if let Some(ack) = config.ack {
        if let Some((wire, status)) = parse_ack(&ack, data) {
            // The command's wire code looked up only while an answer is awaited (flash).
            let awaited = sequencer.awaiting_answer().then(|| sequencer.active()).flatten();
            if awaited.and_then(|c| command_format(config, c)).map(|f| f.wire) == Some(wire) {
                let outcome = if status == ack.ok_status {
                    CommandOutcome::Ok
                } else {
                    CommandOutcome::Rejected(status)
                };
                sequencer.complete(outcome);
            }
            return;
        }
    }
    if data.len() == image.len() {
        image.copy_from_slice(data);
    } else {
        health.count(Counter::UnexpectedFrames);
    }
}

/// `(wire code, status)` of an acknowledgement, if `data` is one.
fn parse_ack(ack: &AckFormat, data: &[u8]) -> Option<(u8, u8)> {
    if data.len() != usize::from(ack.data_len) {
        return None;
    }
    let (&first, rest) = data.split_first()?;
    if first & ack.flag != ack.flag {
        return None;
    }
    Some((first & !ack.flag, rest.first().copied().unwrap_or(ack.ok_status)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::breaker::FRAMING as BREAKER;
    use crate::serial::Checksum;
    use proptest::prelude::*;

    /// The frame as `encode_padded` first built it: pad (or cut) to a fixed length, then
    /// [`FramedConfig::encode_to_vec`].
    fn encode_padded_reference(framing: &FramedConfig, data: &[u8]) -> Option<std::vec::Vec<u8>> {
        let mut padded: Vec<u8, 255> = Vec::from_slice(data).ok()?;
        if let LengthField::Fixed(n) = framing.length {
            padded.resize(usize::from(n), 0).ok()?;
        }
        let mut out: Vec<u8, FRAME_CAPACITY> = Vec::new();
        framing.encode_to_vec(&padded, &mut out).ok()?;
        Some(out.to_vec())
    }

    fn any_framing() -> impl Strategy<Value = FramedConfig> {
        let fixed = |n, checksum| FramedConfig {
            start: 0x02,
            length: LengthField::Fixed(n),
            end: Some(0x03),
            checksum,
            max_len: 255,
        };
        prop_oneof![
            Just(BREAKER),
            Just(FramedConfig { max_len: 255, ..BREAKER }),
            Just(fixed(4, Checksum::Xor8)),
            Just(fixed(255, Checksum::Crc16Modbus)),
            Just(FramedConfig { end: None, checksum: Checksum::Crc16Modbus, ..BREAKER }),
            Just(FramedConfig {
                start: b':',
                length: LengthField::Delimited,
                end: Some(b'\n'),
                checksum: Checksum::None,
                max_len: 8,
            }),
        ]
    }

    /// `validate` as it was before it was written for size: the order of its checks decides
    /// which error a configuration with several faults reports.
    #[allow(clippy::manual_contains)]
    fn validate_reference(c: &FramedProfileConfig) -> Result<(), ConfigError> {
        use crate::serial::sequencer::check_idle_frame;
        c.serial.validate()?;
        c.framing.validate()?;
        c.sequencer.validate()?;
        c.health.validate()?;
        let (min, max) = match c.framing.length {
            LengthField::Fixed(n) => (u32::from(n), u32::from(n)),
            LengthField::Byte | LengthField::Delimited => (1, u32::from(c.framing.max_len)),
        };
        let max = max.min(as_u32(IMAGE_CAPACITY));
        ConfigError::check_range(Field::StatusLen, u32::from(c.status_len), min, max)?;
        if let Some(ack) = c.ack {
            let (min, max) = match c.framing.length {
                LengthField::Fixed(n) => (u32::from(n), u32::from(n)),
                LengthField::Byte | LengthField::Delimited => (1, u32::from(c.framing.max_len)),
            };
            ConfigError::check_range(Field::AckDataLen, u32::from(ack.data_len), min, max)?;
            ConfigError::check_range(Field::AckFlag, u32::from(ack.flag), 1, 255)?;
        }
        let max_data = c.max_tx_data();
        for (i, f) in c.commands.iter().enumerate() {
            ConfigError::check_range(Field::CommandsCode, u32::from(f.code), 1, 255).map_err(|e| e.at(i))?;
            let max_args = max_data.saturating_sub(1).min(6);
            ConfigError::check_range(Field::CommandsArgs, u32::from(f.args), 0, as_u32(max_args))
                .map_err(|e| e.at(i))?;
            if let Some(other) = c.commands.iter().take(i).position(|o| o.code == f.code) {
                return Err(ConfigError {
                    field: Field::CommandsCode,
                    index: None,
                    problem: Problem::Duplicate { other: other as u16 },
                }
                .at(i));
            }
            if c.framing.length == LengthField::Delimited && c.framing.end == Some(f.wire) {
                return Err(ConfigError::conflict(Field::CommandsWire, Conflict::EqualsEndDelimiter).at(i));
            }
        }
        check_idle_frame(Field::SequencerOnIdle, &c.sequencer.on_idle, 0, max_data)?;
        check_idle_frame(Field::SequencerOnFault, &c.sequencer.on_fault, 0, max_data)?;
        for (field, action) in
            [(Field::SequencerOnIdle, &c.sequencer.on_idle), (Field::SequencerOnFault, &c.sequencer.on_fault)]
        {
            if let (LengthField::Delimited, Some(end), Some(frame)) =
                (c.framing.length, c.framing.end, action.frame())
            {
                if frame.iter().any(|&b| b == end) {
                    return Err(ConfigError::conflict(field, Conflict::ContainsEndDelimiter));
                }
            }
        }
        FrameParser::<FRAME_CAPACITY>::check_capacity(&c.framing)
    }

    /// Configurations around every limit `validate` checks: each field mostly valid, so that
    /// every check, and every pair of faults, is reached.
    fn any_config() -> impl Strategy<Value = FramedProfileConfig> {
        let len = || prop_oneof![8 => Just(18u8), 2 => Just(255), 1 => Just(0), 1 => Just(1), 1 => Just(2), 1 => Just(7), 1 => Just(64), 1 => Just(65), 1 => any::<u8>()];
        let length = prop_oneof![3 => Just(LengthField::Byte), 2 => Just(LengthField::Delimited), 2 => len().prop_map(LengthField::Fixed)];
        let checksum = prop_oneof![Just(Checksum::None), Just(Checksum::Sum8), Just(Checksum::Crc16Modbus)];
        let framing = (
            prop_oneof![8 => Just(0x68u8), 1 => Just(0x16)],
            length,
            prop_oneof![1 => Just(None), 8 => Just(Some(0x16u8)), 1 => Just(Some(0x68))],
            checksum,
            len(),
        )
            .prop_map(|(start, length, end, checksum, max_len)| FramedConfig {
                start,
                length,
                end,
                checksum,
                max_len,
            });
        let ack = proptest::option::of(
            (len(), prop_oneof![1 => Just(0u8), 8 => Just(0x80)], any::<u8>())
                .prop_map(|(data_len, flag, ok_status)| AckFormat { data_len, flag, ok_status }),
        );
        let command = (prop_oneof![1 => Just(0u8), 3 => Just(1), 3 => Just(2), 3 => Just(3), 3 => Just(4)], prop_oneof![Just(1u8), Just(0x16), any::<u8>()], prop_oneof![3 => Just(0u8), 1 => Just(3), 1 => Just(5), 1 => Just(6), 1 => Just(7), 1 => any::<u8>()])
            .prop_map(|(code, wire, args)| CommandFormat { code, wire, args });
        let commands = proptest::collection::vec(command, 0..=MAX_COMMAND_FORMATS);
        let action = || {
            prop_oneof![
                Just(crate::serial::IdleAction::Nothing),
                proptest::collection::vec(prop_oneof![1 => Just(0x16u8), 8 => Just(0u8)], 0..=32)
                    .prop_map(|v| crate::serial::IdleAction::send(&v).unwrap()),
            ]
        };
        let sequencer = (
            prop_oneof![20 => Just(500u32), 1 => Just(0), 1 => Just(1), 1 => Just(60_000), 1 => Just(60_001)],
            prop_oneof![20 => Just(2u8), 1 => Just(10), 1 => Just(11)],
            action(),
            action(),
        )
            .prop_map(|(response_timeout_ms, retries, on_idle, on_fault)| SequencerConfig {
                response_timeout_ms,
                retries,
                execute_first: true,
                on_idle,
                on_fault,
            });
        let health = prop_oneof![20 => Just(3000u32), 1 => Just(0), 1 => Just(1), 1 => Just(3_600_000), 1 => Just(3_600_001)]
            .prop_map(|stale_timeout_ms| HealthConfig { stale_timeout_ms, ..HealthConfig::default() });
        let baud = prop_oneof![20 => Just(9600u32), 1 => Just(299), 1 => Just(300), 1 => Just(4_000_000), 1 => Just(4_000_001)];
        (baud, framing, len(), ack, commands, sequencer, health).prop_map(
            |(baud, framing, status_len, ack, commands, sequencer, health)| FramedProfileConfig {
                serial: SerialSettings::new_8n1(baud),
                framing,
                status_len,
                ack,
                commands: Vec::from_slice(&commands).unwrap(),
                sequencer,
                health,
            },
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(4096))]
        #[test]
        fn validate_matches_reference(c in any_config()) {
            prop_assert_eq!(c.validate(), validate_reference(&c));
        }
    }

    proptest! {
        #[test]
        fn encode_padded_matches_pad_then_encode(
            framing in any_framing(),
            data in proptest::collection::vec(prop_oneof![Just(b'\n'), any::<u8>()], 0..40),
        ) {
            let mut out: Vec<u8, FRAME_CAPACITY> = Vec::from_slice(&[0xEE; 7]).unwrap();
            let ok = encode_padded(&framing, &data, &mut out);
            let expected = encode_padded_reference(&framing, &data);
            prop_assert_eq!(ok, expected.is_some());
            prop_assert_eq!(out.as_slice(), expected.as_deref().unwrap_or(&[]));
        }
    }
}
