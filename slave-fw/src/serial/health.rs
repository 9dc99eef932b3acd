//! Instrument-link health: stale detection, the status byte, the freshness counter, statistics.
//!
//! The scanner sees the serial side's health without explicit messaging: the extended input
//! assembly appends [`LinkStatus::to_bytes`] — the [`StatusByte`] and a freshness counter — to the
//! instrument data. When no good frame has arrived for the stale timeout the link is
//! [`LinkState::Timeout`] and the input image follows the [`StalePolicy`].
//!
//! ## Status byte
//!
//! | bit | name | set while |
//! |---|---|---|
//! | 0 | [`LINK_OK`](StatusByte::LINK_OK) | a good frame arrived within the stale timeout |
//! | 1 | [`LINK_TIMEOUT`](StatusByte::LINK_TIMEOUT) | no good frame for the stale timeout (image held or cleared per policy) |
//! | 2 | [`FRAME_ERRORS`](StatusByte::FRAME_ERRORS) | framing or checksum errors, or garbage bytes, seen since the last good frame |
//! | 3 | [`EXCEPTION`](StatusByte::EXCEPTION) | Modbus: an exception response in the current or the last complete scan cycle |
//! | 4–6 | [`COMMAND_MASK`](StatusByte::COMMAND_MASK) | the last command's outcome: 0 none, 1 pending, 2 ok, 3 rejected, 4 failed (no answer after retries), 5 unsupported |
//! | 7 | [`REQUEST_TIMEOUT`](StatusByte::REQUEST_TIMEOUT) | Modbus: a request went unanswered after all retries in the current or the last complete scan cycle |
//!
//! Neither bit 0 nor bit 1 is set while [`LinkState::Starting`]: no frame yet, and the stale
//! timeout since start-up has not run out.
//!
//! The freshness counter (the second byte) increments, wrapping, on every good frame from the
//! instrument, so the scanner can tell new data from held data.

use super::error::{ConfigError, Field};
use super::sequencer::CommandOutcome;
use devicenet::{Duration, Instant};

/// What the input image shows while the link is stale.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum StalePolicy {
    /// Keep the last values received (the status byte says they are stale).
    #[default]
    HoldLastValue,
    /// Set the whole input image to zero.
    Clear,
}

/// Stale detection settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct HealthConfig {
    /// Milliseconds without a good frame after which the link is stale, `1..=3_600_000`.
    pub stale_timeout_ms: u32,
    /// What the input image shows while stale.
    pub stale_policy: StalePolicy,
}

impl Default for HealthConfig {
    /// 3 s (three missed breaker status frames), hold last value.
    fn default() -> Self {
        HealthConfig { stale_timeout_ms: 3000, stale_policy: StalePolicy::HoldLastValue }
    }
}

impl HealthConfig {
    /// The longest stale timeout accepted, one hour.
    pub const MAX_STALE_TIMEOUT_MS: u32 = 3_600_000;

    /// Checks the stale timeout range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        ConfigError::check_range(
            Field::HealthStaleTimeout,
            self.stale_timeout_ms,
            1,
            Self::MAX_STALE_TIMEOUT_MS,
        )
    }

    /// The stale timeout as a duration.
    pub fn stale_timeout(&self) -> Duration {
        Duration::from_millis(u64::from(self.stale_timeout_ms))
    }
}

/// The state of the link to the instrument.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LinkState {
    /// No good frame yet, and the stale timeout since start-up has not run out.
    Starting,
    /// A good frame arrived within the stale timeout.
    Ok,
    /// No good frame for the stale timeout.
    Timeout,
}

/// Statistics of the serial side, readable by explicit messaging (vendor-specific object).
/// Every counter wraps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Good frames received (verified framing and checksum / CRC).
    pub frames_received: u32,
    /// Frames written to the UART, retries and idle/fault frames included.
    pub frames_sent: u32,
    /// Frames discarded for a checksum or CRC mismatch.
    pub checksum_errors: u32,
    /// Frames discarded for bad framing (end delimiter, length, overflow), Modbus responses that
    /// do not answer the request, and bursts of bytes nobody asked for.
    pub framing_errors: u32,
    /// Bytes skipped outside any frame (garbage).
    pub discarded_bytes: u32,
    /// Good frames the profile does not recognise (neither status nor acknowledgement).
    pub unexpected_frames: u32,
    /// Expected answers that did not arrive in time (each attempt counts).
    pub timeouts: u32,
    /// Times the link went stale ([`LinkState::Timeout`]).
    pub link_timeouts: u32,
    /// Commands sent (first attempts). For Modbus, writes of changed outputs.
    pub commands_sent: u32,
    /// Command retransmissions after a timeout or a corrupted answer.
    pub commands_retried: u32,
    /// Commands given up after all retries.
    pub commands_failed: u32,
    /// Commands the instrument refused (non-zero acknowledgement status, Modbus exception).
    pub commands_rejected: u32,
    /// Modbus exception responses, reads and writes.
    pub modbus_exceptions: u32,
}

/// One of the [`Stats`] counters: its place in the table [`LinkHealth::counts`] keeps. The first
/// twelve are in the order of the serial link object's attributes 1–12, so a counter attribute is
/// read by its id less one (a table, not a match over the fields: firmware size budget).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Counter {
    /// [`Stats::frames_received`].
    FramesReceived = 0,
    /// [`Stats::checksum_errors`].
    ChecksumErrors = 1,
    /// [`Stats::framing_errors`].
    FramingErrors = 2,
    /// [`Stats::timeouts`].
    Timeouts = 3,
    /// [`Stats::commands_sent`].
    CommandsSent = 4,
    /// [`Stats::commands_retried`].
    CommandsRetried = 5,
    /// [`Stats::commands_failed`].
    CommandsFailed = 6,
    /// [`Stats::commands_rejected`].
    CommandsRejected = 7,
    /// [`Stats::modbus_exceptions`].
    ModbusExceptions = 8,
    /// [`Stats::frames_sent`].
    FramesSent = 9,
    /// [`Stats::discarded_bytes`].
    DiscardedBytes = 10,
    /// [`Stats::link_timeouts`].
    LinkTimeouts = 11,
    /// [`Stats::unexpected_frames`].
    UnexpectedFrames = 12,
}

impl Counter {
    /// The number of counters (the last one's place, plus one).
    pub const COUNT: usize = Counter::UnexpectedFrames as usize + 1;
}

impl Stats {
    /// The statistics from the table of counters indexed by [`Counter`].
    pub fn from_counts(c: &[u32; Counter::COUNT]) -> Stats {
        let get = |k: Counter| c.get(k as usize).copied().unwrap_or(0);
        Stats {
            frames_received: get(Counter::FramesReceived),
            frames_sent: get(Counter::FramesSent),
            checksum_errors: get(Counter::ChecksumErrors),
            framing_errors: get(Counter::FramingErrors),
            discarded_bytes: get(Counter::DiscardedBytes),
            unexpected_frames: get(Counter::UnexpectedFrames),
            timeouts: get(Counter::Timeouts),
            link_timeouts: get(Counter::LinkTimeouts),
            commands_sent: get(Counter::CommandsSent),
            commands_retried: get(Counter::CommandsRetried),
            commands_failed: get(Counter::CommandsFailed),
            commands_rejected: get(Counter::CommandsRejected),
            modbus_exceptions: get(Counter::ModbusExceptions),
        }
    }
}

/// The status byte of the extended input assembly; the bit layout is in the [module docs](self).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct StatusByte(u8);

impl StatusByte {
    /// Bit 0: a good frame arrived within the stale timeout.
    pub const LINK_OK: u8 = 0x01;
    /// Bit 1: no good frame for the stale timeout.
    pub const LINK_TIMEOUT: u8 = 0x02;
    /// Bit 2: framing or checksum errors since the last good frame.
    pub const FRAME_ERRORS: u8 = 0x04;
    /// Bit 3: a Modbus exception in the current or last scan cycle.
    pub const EXCEPTION: u8 = 0x08;
    /// Bits 4–6: the last command's outcome code ([`CommandOutcome::code`]).
    pub const COMMAND_MASK: u8 = 0x70;
    /// The shift of the command outcome field.
    pub const COMMAND_SHIFT: u32 = 4;
    /// Bit 7: a Modbus request unanswered after retries in the current or last scan cycle.
    pub const REQUEST_TIMEOUT: u8 = 0x80;

    /// The byte as read by the scanner.
    pub const fn from_raw(raw: u8) -> Self {
        StatusByte(raw)
    }

    /// The byte as sent to the scanner.
    pub const fn as_raw(self) -> u8 {
        self.0
    }

    /// Whether all bits of `mask` are set.
    pub const fn contains(self, mask: u8) -> bool {
        self.0 & mask == mask
    }

    /// The command outcome code in bits 4–6.
    pub const fn command_code(self) -> u8 {
        (self.0 & Self::COMMAND_MASK) >> Self::COMMAND_SHIFT
    }
}

/// A snapshot of the serial side's health, as the converter reports it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LinkStatus {
    /// The link state.
    pub state: LinkState,
    /// Framing or checksum errors, or garbage, since the last good frame.
    pub frame_errors: bool,
    /// Modbus: an exception in the current or last complete scan cycle.
    pub exception: bool,
    /// Modbus: a request unanswered after all retries in the current or last complete scan cycle.
    pub request_timeout: bool,
    /// The last command's outcome.
    pub command: CommandOutcome,
    /// Increments, wrapping, on every good frame from the instrument.
    pub freshness: u8,
}

impl LinkStatus {
    /// The status byte (layout in the [module docs](self)).
    pub fn status_byte(&self) -> StatusByte {
        let mut b = match self.state {
            LinkState::Starting => 0,
            LinkState::Ok => StatusByte::LINK_OK,
            LinkState::Timeout => StatusByte::LINK_TIMEOUT,
        };
        if self.frame_errors {
            b |= StatusByte::FRAME_ERRORS;
        }
        if self.exception {
            b |= StatusByte::EXCEPTION;
        }
        if self.request_timeout {
            b |= StatusByte::REQUEST_TIMEOUT;
        }
        b |= (self.command.code() << StatusByte::COMMAND_SHIFT) & StatusByte::COMMAND_MASK;
        StatusByte(b)
    }

    /// The two bytes the extended input assembly appends: status byte, freshness counter.
    pub fn to_bytes(&self) -> [u8; 2] {
        [self.status_byte().as_raw(), self.freshness]
    }
}

/// Tracks the link to the instrument: staleness, errors since the last good frame, freshness,
/// and the [`Stats`] every profile keeps.
#[derive(Clone, Debug)]
pub struct LinkHealth {
    config: HealthConfig,
    state: LinkState,
    /// When the link goes stale unless a good frame arrives first.
    stale_at: Instant,
    frame_errors: bool,
    freshness: u8,
    /// The [`Stats`] as a table indexed by [`Counter`].
    counts: [u32; Counter::COUNT],
}

impl LinkHealth {
    /// A tracker in [`LinkState::Starting`]; the stale timeout runs from `now`.
    pub fn new(config: HealthConfig, now: Instant) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(LinkHealth::build(config, now))
    }

    /// A tracker for `config`, which [`HealthConfig::validate`] has accepted.
    pub(crate) fn build(config: HealthConfig, now: Instant) -> Self {
        LinkHealth {
            config,
            state: LinkState::Starting,
            stale_at: now + config.stale_timeout(),
            frame_errors: false,
            freshness: 0,
            counts: [0; Counter::COUNT],
        }
    }

    /// The configuration.
    pub fn config(&self) -> &HealthConfig {
        &self.config
    }

    /// A good frame arrived at `now`: the link is ok, errors are cleared, freshness increments.
    pub fn on_frame(&mut self, now: Instant) {
        self.count(Counter::FramesReceived);
        self.freshness = self.freshness.wrapping_add(1);
        self.frame_errors = false;
        self.state = LinkState::Ok;
        self.stale_at = now + self.config.stale_timeout();
    }

    /// A frame was discarded for its checksum.
    pub fn on_checksum_error(&mut self) {
        self.count(Counter::ChecksumErrors);
        self.frame_errors = true;
    }

    /// A frame was discarded for its framing (or did not answer the request).
    pub fn on_framing_error(&mut self) {
        self.count(Counter::FramingErrors);
        self.frame_errors = true;
    }

    /// `n` bytes were skipped outside any frame. Out of line in the firmware only: there the test,
    /// the addition and the flag at each of its callers cost more than the call (firmware size);
    /// on a host the call sits on every received byte's path and cost the soft slave 50 ns of its
    /// instrument-to-COS latency (`cargo bench -p converter-sim --bench io_modes`).
    #[cfg_attr(target_os = "none", inline(never))]
    pub fn on_discarded_bytes(&mut self, n: u32) {
        if n > 0 {
            self.add(Counter::DiscardedBytes, n);
            self.frame_errors = true;
        }
    }

    /// Advances to `now`; returns `true` exactly when the link has just gone stale, so the owner
    /// applies the [`StalePolicy`] (see [`apply_stale_policy`](Self::apply_stale_policy)).
    pub fn poll(&mut self, now: Instant) -> bool {
        if self.state != LinkState::Timeout && now >= self.stale_at {
            self.state = LinkState::Timeout;
            self.count(Counter::LinkTimeouts);
            true
        } else {
            false
        }
    }

    /// Zeroes `image` under [`StalePolicy::Clear`]; leaves it under
    /// [`StalePolicy::HoldLastValue`].
    pub fn apply_stale_policy(&self, image: &mut [u8]) {
        if self.config.stale_policy == StalePolicy::Clear {
            image.fill(0);
        }
    }

    /// When [`poll`](Self::poll) must next be called: the stale deadline, unless already stale.
    pub fn poll_at(&self) -> Option<Instant> {
        (self.state != LinkState::Timeout).then_some(self.stale_at)
    }

    /// The link state as of the last [`poll`](Self::poll) or frame.
    pub fn state(&self) -> LinkState {
        self.state
    }

    /// The freshness counter.
    pub fn freshness(&self) -> u8 {
        self.freshness
    }

    /// Whether errors were seen since the last good frame.
    pub fn frame_errors(&self) -> bool {
        self.frame_errors
    }

    /// The statistics.
    pub fn stats(&self) -> Stats {
        Stats::from_counts(&self.counts)
    }

    /// The statistics as a table indexed by [`Counter`].
    pub fn counts(&self) -> &[u32; Counter::COUNT] {
        &self.counts
    }

    /// Adds one to `counter`, for the profile that owns this tracker to count its own events.
    /// Inline: a call at each counting site costs more than the increment it replaces (an
    /// out-of-line increment measured +66 bytes of flash).
    #[inline]
    pub fn count(&mut self, counter: Counter) {
        self.add(counter, 1);
    }

    /// Adds `n` to `counter`, wrapping.
    #[inline]
    fn add(&mut self, counter: Counter, n: u32) {
        if let Some(c) = self.counts.get_mut(counter as usize) {
            *c = c.wrapping_add(n);
        }
    }

    /// Sets `counter`, for the profile that folds counts kept elsewhere into its statistics.
    pub fn set_count(&mut self, counter: Counter, value: u32) {
        if let Some(c) = self.counts.get_mut(counter as usize) {
            *c = value;
        }
    }

    /// A status snapshot with the profile's own fields.
    pub fn status(&self, command: CommandOutcome, exception: bool, request_timeout: bool) -> LinkStatus {
        LinkStatus {
            state: self.state,
            frame_errors: self.frame_errors,
            exception,
            request_timeout,
            command,
            freshness: self.freshness,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn health(policy: StalePolicy) -> LinkHealth {
        LinkHealth::new(HealthConfig { stale_timeout_ms: 3000, stale_policy: policy }, ms(0)).unwrap()
    }

    #[test]
    fn starting_then_ok_then_stale_then_ok() {
        let mut h = health(StalePolicy::HoldLastValue);
        assert_eq!(h.state(), LinkState::Starting);
        assert_eq!(h.poll_at(), Some(ms(3000)));
        h.on_frame(ms(1000));
        assert_eq!(h.state(), LinkState::Ok);
        assert!(!h.poll(ms(3999)));
        assert!(h.poll(ms(4000)), "stale exactly at the deadline");
        assert!(!h.poll(ms(5000)), "reported once");
        assert_eq!(h.state(), LinkState::Timeout);
        assert_eq!(h.poll_at(), None);
        h.on_frame(ms(6000));
        assert_eq!(h.state(), LinkState::Ok);
        assert_eq!(h.stats().link_timeouts, 1);
        assert_eq!(h.stats().frames_received, 2);
    }

    #[test]
    fn never_hearing_the_instrument_goes_stale() {
        let mut h = health(StalePolicy::HoldLastValue);
        assert!(h.poll(ms(3000)));
        assert_eq!(h.state(), LinkState::Timeout);
    }

    #[rstest]
    #[case::hold(StalePolicy::HoldLastValue, [7, 8, 9])]
    #[case::clear(StalePolicy::Clear, [0, 0, 0])]
    fn stale_policy(#[case] policy: StalePolicy, #[case] image_after: [u8; 3]) {
        let h = health(policy);
        let mut image = [7, 8, 9];
        h.apply_stale_policy(&mut image);
        assert_eq!(image, image_after);
    }

    #[test]
    fn freshness_counts_good_frames_and_wraps() {
        let mut h = health(StalePolicy::HoldLastValue);
        for i in 0..300u64 {
            h.on_frame(ms(i));
        }
        assert_eq!(h.freshness(), (300 % 256) as u8);
    }

    #[test]
    fn errors_flag_clears_on_next_good_frame() {
        let mut h = health(StalePolicy::HoldLastValue);
        h.on_checksum_error();
        assert!(h.frame_errors());
        h.on_frame(ms(1));
        assert!(!h.frame_errors());
        h.on_framing_error();
        h.on_discarded_bytes(0);
        assert!(h.frame_errors());
        h.on_frame(ms(2));
        h.on_discarded_bytes(3);
        assert!(h.frame_errors());
        assert_eq!(
            (h.stats().checksum_errors, h.stats().framing_errors, h.stats().discarded_bytes),
            (1, 1, 3)
        );
    }

    #[rstest]
    #[case::starting(LinkState::Starting, false, false, false, CommandOutcome::None, 0x00)]
    #[case::ok(LinkState::Ok, false, false, false, CommandOutcome::None, 0x01)]
    #[case::timeout(LinkState::Timeout, false, false, false, CommandOutcome::None, 0x02)]
    #[case::ok_errors(LinkState::Ok, true, false, false, CommandOutcome::None, 0x05)]
    #[case::exception(LinkState::Ok, false, true, false, CommandOutcome::None, 0x09)]
    #[case::pending(LinkState::Ok, false, false, false, CommandOutcome::Pending, 0x11)]
    #[case::command_ok(LinkState::Ok, false, false, false, CommandOutcome::Ok, 0x21)]
    #[case::rejected(LinkState::Ok, false, false, false, CommandOutcome::Rejected(2), 0x31)]
    #[case::failed(LinkState::Timeout, false, false, false, CommandOutcome::Failed, 0x42)]
    #[case::unsupported(LinkState::Ok, false, false, false, CommandOutcome::Unsupported, 0x51)]
    #[case::request_timeout(LinkState::Ok, false, false, true, CommandOutcome::None, 0x81)]
    #[case::everything(LinkState::Ok, true, true, true, CommandOutcome::Failed, 0xCD)]
    fn status_byte_layout(
        #[case] state: LinkState,
        #[case] frame_errors: bool,
        #[case] exception: bool,
        #[case] request_timeout: bool,
        #[case] command: CommandOutcome,
        #[case] raw: u8,
    ) {
        let s = LinkStatus { state, frame_errors, exception, request_timeout, command, freshness: 42 };
        assert_eq!(s.status_byte().as_raw(), raw);
        assert_eq!(s.to_bytes(), [raw, 42]);
        assert_eq!(s.status_byte().command_code(), command.code());
    }

    #[rstest]
    #[case::zero(0, false)]
    #[case::one(1, true)]
    #[case::hour(3_600_000, true)]
    #[case::too_long(3_600_001, false)]
    fn validate(#[case] stale_timeout_ms: u32, #[case] ok: bool) {
        let c = HealthConfig { stale_timeout_ms, ..HealthConfig::default() };
        assert_eq!(c.validate().is_ok(), ok);
        assert_eq!(LinkHealth::new(c, ms(0)).is_ok(), ok);
    }
}
