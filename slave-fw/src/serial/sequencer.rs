//! The command sequencer: poll output bytes become instrument commands, executed exactly once.
//!
//! The 8 consumed poll bytes are a [`Command`]: byte 0 the code (0 none, 1 open, 2 close,
//! 3 set parameter, 4 refresh), byte 1 a sequence number, bytes 2–7 the arguments. A scanner
//! repeats its outputs on every poll, so the sequencer acts only on a *change* of code or sequence
//! number: the command is sent once, retried on timeout a bounded number of times, and its
//! [`CommandOutcome`] reported. To repeat a command the scanner bumps the sequence number.
//!
//! An idle poll (zero-length output) or a poll connection timeout never triggers a command. What
//! the instrument is told instead is configured ([`IdleAction`]) and sent once per entry into the
//! idle or fault state.
//!
//! The sequencer knows nothing about the wire: the profile that owns it encodes each
//! [`Transmission`] and reports answers with [`CommandSequencer::complete`]. Driving order:
//!
//! 1. [`set_outputs`](CommandSequencer::set_outputs) / [`connection_fault`](CommandSequencer::connection_fault) as polls arrive;
//! 2. [`poll`](CommandSequencer::poll) at `now` (answer timeouts, retries);
//! 3. while [`next_transmission`](CommandSequencer::next_transmission) returns one: encode it,
//!    hand it to the UART, and report it with [`transmitted`](CommandSequencer::transmitted);
//! 4. call again at [`poll_at`](CommandSequencer::poll_at).
//!
//! After a restart the first outputs with a non-zero code are executed unless
//! [`SequencerConfig::execute_first`] is `false`, in which case they only set the baseline.

use super::counter::bump;
use super::error::{as_u32, ConfigError, Field};
use super::IDLE_FRAME_CAPACITY;
use devicenet::{Duration, Instant};
use heapless::Vec;

/// The command code, byte 0 of the poll output. Unknown codes are kept.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CommandCode {
    /// 0: no command.
    #[default]
    None,
    /// 1: open the breaker.
    Open,
    /// 2: close the breaker.
    Close,
    /// 3: set a parameter (arguments: parameter id, value low byte, value high byte).
    SetParameter,
    /// 4: ask the instrument for fresh data now.
    Refresh,
    /// Any other code; the profile decides whether it has a wire format for it.
    Unknown(u8),
}

impl CommandCode {
    /// The code as sent by the scanner.
    pub const fn as_raw(self) -> u8 {
        match self {
            CommandCode::None => 0,
            CommandCode::Open => 1,
            CommandCode::Close => 2,
            CommandCode::SetParameter => 3,
            CommandCode::Refresh => 4,
            CommandCode::Unknown(c) => c,
        }
    }
}

impl From<u8> for CommandCode {
    fn from(raw: u8) -> Self {
        match raw {
            0 => CommandCode::None,
            1 => CommandCode::Open,
            2 => CommandCode::Close,
            3 => CommandCode::SetParameter,
            4 => CommandCode::Refresh,
            c => CommandCode::Unknown(c),
        }
    }
}

/// A command as carried in the 8 consumed poll bytes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Command {
    /// Byte 0, the command code as sent ([`CommandCode::from`] says what it means). Kept raw: the
    /// sequencer and the framed profile only compare and copy it (firmware size budget).
    pub code: u8,
    /// Byte 1: a new sequence number makes the same code a new command.
    pub sequence: u8,
    /// Bytes 2–7.
    pub args: [u8; 6],
}

impl Command {
    /// The length of the consumed assembly that carries a command.
    pub const LEN: usize = 8;

    /// The command in poll output bytes; `None` for an idle (zero-length) poll. Shorter outputs
    /// are padded with zeros, bytes past the eighth are ignored.
    pub fn from_outputs(outputs: &[u8]) -> Option<Command> {
        let (&code, rest) = outputs.split_first()?;
        let mut bytes = [0u8; 7];
        for (slot, &b) in bytes.iter_mut().zip(rest) {
            *slot = b;
        }
        let [sequence, a0, a1, a2, a3, a4, a5] = bytes;
        Some(Command { code, sequence, args: [a0, a1, a2, a3, a4, a5] })
    }

    /// The 8 poll output bytes of this command.
    pub fn to_bytes(&self) -> [u8; 8] {
        let [a0, a1, a2, a3, a4, a5] = self.args;
        [self.code, self.sequence, a0, a1, a2, a3, a4, a5]
    }
}

/// What became of the last command.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CommandOutcome {
    /// No command yet.
    #[default]
    None,
    /// Sent or about to be sent; no answer yet.
    Pending,
    /// The instrument accepted it.
    Ok,
    /// The instrument refused it with this status (acknowledgement status, Modbus exception code).
    Rejected(u8),
    /// No valid answer after all retries.
    Failed,
    /// The profile has no wire format for this command code.
    Unsupported,
}

impl CommandOutcome {
    /// The 3-bit code shown in the status byte: 0 none, 1 pending, 2 ok, 3 rejected, 4 failed,
    /// 5 unsupported.
    pub const fn code(self) -> u8 {
        match self {
            CommandOutcome::None => 0,
            CommandOutcome::Pending => 1,
            CommandOutcome::Ok => 2,
            CommandOutcome::Rejected(_) => 3,
            CommandOutcome::Failed => 4,
            CommandOutcome::Unsupported => 5,
        }
    }
}

/// What the instrument is told on entry into the idle or fault state.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum IdleAction {
    /// Nothing.
    #[default]
    Nothing,
    /// These bytes, wrapped in the profile's framing: the data of a framed frame, or a Modbus ADU
    /// without its CRC (unit address, function, data).
    Send(Vec<u8, IDLE_FRAME_CAPACITY>),
}

impl IdleAction {
    /// [`IdleAction::Send`] of `bytes`; `None` if longer than [`IDLE_FRAME_CAPACITY`].
    pub fn send(bytes: &[u8]) -> Option<IdleAction> {
        Vec::from_slice(bytes).ok().map(IdleAction::Send)
    }

    /// The bytes to send, if any.
    pub fn frame(&self) -> Option<&[u8]> {
        match self {
            IdleAction::Nothing => None,
            IdleAction::Send(bytes) => Some(bytes.as_slice()),
        }
    }
}

/// Timing and idle/fault behaviour of the [`CommandSequencer`].
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct SequencerConfig {
    /// Milliseconds to wait for the answer, counted from the end of the command's transmission,
    /// `1..=60_000`.
    pub response_timeout_ms: u32,
    /// Retransmissions after a timeout before the command is [`CommandOutcome::Failed`],
    /// `0..=10`.
    pub retries: u8,
    /// Whether the first outputs after start-up execute their command (`true`), or only set the
    /// baseline that later outputs are compared with (`false`).
    pub execute_first: bool,
    /// Sent once on entry into idle (zero-length poll).
    pub on_idle: IdleAction,
    /// Sent once on entry into fault (poll connection timeout).
    pub on_fault: IdleAction,
}

impl Default for SequencerConfig {
    /// 500 ms response timeout, 2 retries, execute the first command, nothing on idle or fault.
    fn default() -> Self {
        SequencerConfig {
            response_timeout_ms: 500,
            retries: 2,
            execute_first: true,
            on_idle: IdleAction::Nothing,
            on_fault: IdleAction::Nothing,
        }
    }
}

impl SequencerConfig {
    /// The longest response timeout accepted, one minute.
    pub const MAX_RESPONSE_TIMEOUT_MS: u32 = 60_000;
    /// The most retries accepted.
    pub const MAX_RETRIES: u8 = 10;

    /// Checks the timeout and retry ranges.
    pub fn validate(&self) -> Result<(), ConfigError> {
        ConfigError::check_range(
            Field::SequencerResponseTimeout,
            self.response_timeout_ms,
            1,
            Self::MAX_RESPONSE_TIMEOUT_MS,
        )?;
        ConfigError::check_range(
            Field::SequencerRetries,
            u32::from(self.retries),
            0,
            u32::from(Self::MAX_RETRIES),
        )
    }

    /// The response timeout as a duration.
    pub fn response_timeout(&self) -> Duration {
        Duration::from_millis(u64::from(self.response_timeout_ms))
    }
}

/// Checks that a configured idle/fault frame is at most `max` bytes.
pub(crate) fn check_idle_frame(
    field: Field,
    action: &IdleAction,
    min: usize,
    max: usize,
) -> Result<(), ConfigError> {
    match action.frame() {
        Some(f) => ConfigError::check_range(field, as_u32(f.len()), as_u32(min), as_u32(max)),
        None => Ok(()),
    }
}

/// What the poll outputs currently say.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum OutputMode {
    /// No outputs since start-up.
    Startup,
    /// Outputs with data: commands are taken from them.
    Run,
    /// Zero-length polls.
    Idle,
    /// The poll connection timed out.
    Fault,
}

/// Something the owner of a [`CommandSequencer`] must send now.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Transmission {
    /// A command; `attempt` is 1 for the first transmission.
    Command {
        /// The command.
        command: Command,
        /// 1-based attempt number.
        attempt: u8,
    },
    /// The configured idle frame ([`SequencerConfig::on_idle`]).
    Idle,
    /// The configured fault frame ([`SequencerConfig::on_fault`]).
    Fault,
}

/// The sequencer's own counters; the profile folds them into its [`super::Stats`]. They wrap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SequencerCounters {
    /// Commands sent (first attempts).
    pub sent: u32,
    /// Retransmissions.
    pub retried: u32,
    /// Commands given up after all retries.
    pub failed: u32,
    /// Commands refused by the instrument.
    pub rejected: u32,
    /// Answers that did not arrive in time (each attempt).
    pub timeouts: u32,
    /// Idle and fault frames sent.
    pub idle_frames: u32,
}

/// The command in progress; the command itself is [`CommandSequencer::last_command`] (kept once:
/// every command started is also the last one, firmware size budget).
///
/// Its two states share their instant: a flag and one field, not an enum of two variants that
/// each carry one (firmware size).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Active {
    /// Transmissions so far.
    attempts: u8,
    /// Sent, the answer due by `at`; otherwise to be (re)sent as soon as possible, due since `at`.
    awaiting: bool,
    at: Instant,
}

/// Turns poll outputs into commands sent exactly once, with retries and a reported outcome.
/// See the [module docs](self) for the driving order.
#[derive(Clone, Debug)]
pub struct CommandSequencer {
    config: SequencerConfig,
    mode: OutputMode,
    /// The idle/fault frame of the current mode is due since this instant ([`Instant::MAX`]:
    /// none; the clock never gets there). Not an `Option`: firmware size.
    mode_frame_due: Instant,
    /// (code, sequence) of the last outputs seen.
    last_key: Option<(u8, u8)>,
    active: Option<Active>,
    outcome: CommandOutcome,
    last_command: Option<Command>,
    counters: SequencerCounters,
}

impl CommandSequencer {
    /// A sequencer with no command yet.
    pub fn new(config: SequencerConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(CommandSequencer::build(config))
    }

    /// A sequencer for `config`, which [`SequencerConfig::validate`] has accepted.
    pub(crate) fn build(config: SequencerConfig) -> Self {
        CommandSequencer {
            config,
            mode: OutputMode::Startup,
            mode_frame_due: Instant::MAX,
            last_key: None,
            active: None,
            outcome: CommandOutcome::None,
            last_command: None,
            counters: SequencerCounters::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SequencerConfig {
        &self.config
    }

    /// Takes the consumed poll data received at `now`. A zero-length slice is an idle poll: it
    /// never triggers a command, and enters [`OutputMode::Idle`].
    pub fn set_outputs(&mut self, outputs: &[u8], now: Instant) {
        // The key from the raw bytes; the command is decoded only when it starts (flash).
        let Some((&code, rest)) = outputs.split_first() else {
            self.enter(OutputMode::Idle, now);
            return;
        };
        if self.mode != OutputMode::Run {
            self.mode = OutputMode::Run;
            self.mode_frame_due = Instant::MAX;
        }
        let key = (code, rest.first().copied().unwrap_or(0));
        let first = self.last_key.is_none();
        if self.last_key == Some(key) {
            return;
        }
        self.last_key = Some(key);
        if (first && !self.config.execute_first) || code == 0 {
            return;
        }
        // A new command supersedes one still in progress.
        self.active = Some(Active { attempts: 0, awaiting: false, at: now });
        self.outcome = CommandOutcome::Pending;
        self.last_command = Command::from_outputs(outputs);
    }

    /// The poll connection timed out at `now`: enter [`OutputMode::Fault`]. Never triggers a
    /// command; a command already in progress finishes.
    pub fn connection_fault(&mut self, now: Instant) {
        self.enter(OutputMode::Fault, now);
    }

    fn enter(&mut self, mode: OutputMode, now: Instant) {
        if self.mode == mode {
            return;
        }
        self.mode = mode;
        let frame = self.mode_action().and_then(IdleAction::frame).is_some();
        self.mode_frame_due = if frame { now } else { Instant::MAX };
    }

    fn mode_action(&self) -> Option<&IdleAction> {
        match self.mode {
            OutputMode::Idle => Some(&self.config.on_idle),
            OutputMode::Fault => Some(&self.config.on_fault),
            OutputMode::Startup | OutputMode::Run => None,
        }
    }

    /// Advances to `now`: an answer not received by its deadline schedules a retry, or fails the
    /// command once the retries are spent.
    pub fn poll(&mut self, now: Instant) {
        let Some(active) = self.active.as_mut() else {
            return;
        };
        if !active.awaiting || now < active.at {
            return;
        }
        bump(&mut self.counters.timeouts);
        if active.attempts > self.config.retries {
            self.active = None;
            self.outcome = CommandOutcome::Failed;
            bump(&mut self.counters.failed);
        } else {
            // Due again since the deadline.
            active.awaiting = false;
        }
    }

    /// What must be sent now, if anything: the idle/fault frame first, then a due command.
    /// Report it with [`transmitted`](Self::transmitted) once handed to the UART.
    pub fn next_transmission(&self, now: Instant) -> Option<Transmission> {
        if self.mode_frame_due <= now {
            match self.mode {
                OutputMode::Idle => return Some(Transmission::Idle),
                OutputMode::Fault => return Some(Transmission::Fault),
                OutputMode::Startup | OutputMode::Run => {}
            }
        }
        let active = self.active.as_ref()?;
        if active.awaiting || active.at > now {
            return None;
        }
        Some(Transmission::Command {
            command: *self.last_command.as_ref()?,
            attempt: active.attempts.saturating_add(1),
        })
    }

    /// `transmission` (from [`next_transmission`](Self::next_transmission)) was handed to the UART
    /// at `now` and is on the wire until `tx_done`; the answer timeout runs from `tx_done`.
    pub fn transmitted(&mut self, transmission: Transmission, now: Instant, tx_done: Instant) {
        if self.next_transmission(now) == Some(transmission) {
            self.record_transmitted(transmission, tx_done);
        }
    }

    /// [`transmitted`](Self::transmitted) for the transmission that
    /// [`next_transmission`](Self::next_transmission) has just returned, the sequencer untouched
    /// since: the profile's own path skips the comparison (firmware size budget).
    pub(crate) fn record_transmitted(&mut self, transmission: Transmission, tx_done: Instant) {
        match transmission {
            Transmission::Idle | Transmission::Fault => {
                self.mode_frame_due = Instant::MAX;
                bump(&mut self.counters.idle_frames);
            }
            Transmission::Command { attempt, .. } => {
                if let Some(active) = self.active.as_mut() {
                    active.attempts = attempt;
                    active.awaiting = true;
                    active.at = tx_done + self.config.response_timeout();
                    bump(if attempt <= 1 { &mut self.counters.sent } else { &mut self.counters.retried });
                }
            }
        }
    }

    /// Ends the command in progress with `outcome`: the instrument's answer
    /// ([`CommandOutcome::Ok`] or [`CommandOutcome::Rejected`]), or
    /// [`CommandOutcome::Unsupported`] when the profile cannot encode it. An answer is taken once
    /// the command has been sent at least once, also while a retry is due. Returns whether a
    /// command was ended.
    pub fn complete(&mut self, outcome: CommandOutcome) -> bool {
        let Some(active) = self.active else {
            return false;
        };
        let answer = matches!(outcome, CommandOutcome::Ok | CommandOutcome::Rejected(_));
        if answer && active.attempts == 0 {
            return false;
        }
        self.active = None;
        self.outcome = outcome;
        match outcome {
            CommandOutcome::Rejected(_) => bump(&mut self.counters.rejected),
            CommandOutcome::Failed => bump(&mut self.counters.failed),
            CommandOutcome::None
            | CommandOutcome::Pending
            | CommandOutcome::Ok
            | CommandOutcome::Unsupported => {}
        }
        true
    }

    /// The command in progress (sent or due), if any.
    pub fn active(&self) -> Option<&Command> {
        self.active.and(self.last_command.as_ref())
    }

    /// Whether the command in progress has been sent at least once (an answer is welcome).
    pub fn awaiting_answer(&self) -> bool {
        self.active.is_some_and(|a| a.attempts > 0)
    }

    /// The outcome of the last command.
    pub fn outcome(&self) -> CommandOutcome {
        self.outcome
    }

    /// The last command started, whatever its outcome.
    pub fn last_command(&self) -> Option<&Command> {
        self.last_command.as_ref()
    }

    /// The current output mode.
    pub fn mode(&self) -> OutputMode {
        self.mode
    }

    /// The idle/fault frame for `transmission`, if it is one.
    pub fn frame_for(&self, transmission: Transmission) -> Option<&[u8]> {
        match transmission {
            Transmission::Idle => self.config.on_idle.frame(),
            Transmission::Fault => self.config.on_fault.frame(),
            Transmission::Command { .. } => None,
        }
    }

    /// The counters.
    pub fn counters(&self) -> &SequencerCounters {
        &self.counters
    }

    /// When to call [`poll`](Self::poll) / [`next_transmission`](Self::next_transmission) next.
    pub fn poll_at(&self) -> Option<Instant> {
        let at = self.active.map_or(Instant::MAX, |a| a.at).min(self.mode_frame_due);
        (at != Instant::MAX).then_some(at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;
    use std::vec::Vec as StdVec;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn sequencer(config: SequencerConfig) -> CommandSequencer {
        CommandSequencer::new(config).unwrap()
    }

    fn config(retries: u8) -> SequencerConfig {
        SequencerConfig { response_timeout_ms: 100, retries, ..SequencerConfig::default() }
    }

    /// Sends everything due at `now` (transmission takes no time) and returns it.
    fn drain(s: &mut CommandSequencer, now: Instant) -> StdVec<Transmission> {
        s.poll(now);
        let mut out = StdVec::new();
        while let Some(t) = s.next_transmission(now) {
            s.transmitted(t, now, now);
            out.push(t);
            assert!(out.len() < 10, "runaway");
        }
        out
    }

    fn commands(ts: &[Transmission]) -> usize {
        ts.iter().filter(|t| matches!(t, Transmission::Command { .. })).count()
    }

    const OPEN_1: [u8; 8] = [1, 1, 0, 0, 0, 0, 0, 0];
    const OPEN_2: [u8; 8] = [1, 2, 0, 0, 0, 0, 0, 0];
    const CLOSE_2: [u8; 8] = [2, 2, 0, 0, 0, 0, 0, 0];

    #[rstest]
    #[case::idle(&[], None)]
    #[case::full(&[3, 9, 1, 0x34, 0x12, 0, 0, 0], Some(Command { code: 3, sequence: 9, args: [1, 0x34, 0x12, 0, 0, 0] }))]
    #[case::short_padded(&[1, 7], Some(Command { code: 1, sequence: 7, args: [0; 6] }))]
    #[case::long_truncated(&[4, 1, 1, 2, 3, 4, 5, 6, 7, 8], Some(Command { code: 4, sequence: 1, args: [1, 2, 3, 4, 5, 6] }))]
    #[case::unknown_code(&[0x42, 0], Some(Command { code: 0x42, sequence: 0, args: [0; 6] }))]
    fn command_from_outputs(#[case] bytes: &[u8], #[case] command: Option<Command>) {
        assert_eq!(Command::from_outputs(bytes), command);
        if let (Some(c), 8) = (command, bytes.len()) {
            assert_eq!(c.to_bytes().as_slice(), bytes);
        }
    }

    #[test]
    fn command_codes_round_trip() {
        for raw in 0..=255u8 {
            assert_eq!(CommandCode::from(raw).as_raw(), raw);
        }
    }

    #[test]
    fn same_output_repeated_sends_exactly_once() {
        let mut s = sequencer(config(2));
        let mut sent = 0;
        for i in 0..100 {
            s.set_outputs(&OPEN_1, ms(i * 10));
            if i == 5 {
                assert!(s.complete(CommandOutcome::Ok));
            }
            sent += commands(&drain(&mut s, ms(i * 10)));
        }
        assert_eq!(sent, 1);
        assert_eq!(s.outcome(), CommandOutcome::Ok);
        assert_eq!(s.counters().sent, 1);
    }

    #[rstest]
    #[case::new_sequence(OPEN_1, OPEN_2)]
    #[case::new_code(OPEN_2, CLOSE_2)]
    fn change_sends_a_new_command(#[case] first: [u8; 8], #[case] second: [u8; 8]) {
        let mut s = sequencer(config(0));
        s.set_outputs(&first, ms(0));
        assert_eq!(commands(&drain(&mut s, ms(0))), 1);
        s.complete(CommandOutcome::Ok);
        s.set_outputs(&second, ms(10));
        let ts = drain(&mut s, ms(10));
        assert_eq!(
            ts,
            std::vec![Transmission::Command { command: Command::from_outputs(&second).unwrap(), attempt: 1 }]
        );
        assert_eq!(s.outcome(), CommandOutcome::Pending);
    }

    #[test]
    fn timeout_retries_are_bounded_then_failed() {
        let mut s = sequencer(config(2));
        s.set_outputs(&OPEN_1, ms(0));
        let mut attempts = StdVec::new();
        for t in (0..=1000).step_by(10) {
            s.set_outputs(&OPEN_1, ms(t));
            for tx in drain(&mut s, ms(t)) {
                if let Transmission::Command { attempt, .. } = tx {
                    attempts.push((t, attempt));
                }
            }
        }
        assert_eq!(attempts, std::vec![(0, 1), (100, 2), (200, 3)]);
        assert_eq!(s.outcome(), CommandOutcome::Failed);
        let c = s.counters();
        assert_eq!((c.sent, c.retried, c.timeouts, c.failed), (1, 2, 3, 1));
        assert_eq!(s.poll_at(), None);
    }

    #[test]
    fn timeout_counts_from_end_of_transmission() {
        let mut s = sequencer(config(0));
        s.set_outputs(&OPEN_1, ms(0));
        let t = s.next_transmission(ms(0)).unwrap();
        s.transmitted(t, ms(0), ms(5));
        assert_eq!(s.poll_at(), Some(ms(105)));
        s.poll(ms(104));
        assert_eq!(s.outcome(), CommandOutcome::Pending);
        s.poll(ms(105));
        assert_eq!(s.outcome(), CommandOutcome::Failed);
    }

    #[rstest]
    #[case::ok(CommandOutcome::Ok, 0)]
    #[case::rejected(CommandOutcome::Rejected(2), 1)]
    fn answer_ends_the_command(#[case] outcome: CommandOutcome, #[case] rejected: u32) {
        let mut s = sequencer(config(2));
        s.set_outputs(&OPEN_1, ms(0));
        assert!(!s.complete(CommandOutcome::Ok), "not sent yet: no answer possible");
        drain(&mut s, ms(0));
        assert!(s.awaiting_answer());
        assert!(s.complete(outcome));
        assert_eq!(s.outcome(), outcome);
        assert_eq!(s.counters().rejected, rejected);
        assert!(drain(&mut s, ms(1000)).is_empty(), "no retry after an answer");
        assert!(!s.complete(CommandOutcome::Ok), "a second answer is stray");
    }

    #[test]
    fn late_answer_while_retry_due_is_taken() {
        let mut s = sequencer(config(2));
        s.set_outputs(&OPEN_1, ms(0));
        drain(&mut s, ms(0));
        s.poll(ms(100));
        assert!(s.complete(CommandOutcome::Ok));
        assert!(drain(&mut s, ms(100)).is_empty());
    }

    #[test]
    fn idle_and_fault_never_send_a_command() {
        let mut s = sequencer(config(2));
        for i in 0..50 {
            s.set_outputs(&[], ms(i));
            s.connection_fault(ms(i));
            assert!(drain(&mut s, ms(i)).is_empty());
        }
        assert_eq!(s.outcome(), CommandOutcome::None);
        assert_eq!(s.counters().sent, 0);
    }

    #[test]
    fn idle_and_fault_frames_once_per_entry() {
        let cfg = SequencerConfig {
            on_idle: IdleAction::send(&[0x04]).unwrap(),
            on_fault: IdleAction::send(&[0x01]).unwrap(),
            ..config(0)
        };
        let mut s = sequencer(cfg);
        let mut log = StdVec::new();
        let mut step = |s: &mut CommandSequencer, t: u64, what: &str| {
            match what {
                "idle" => s.set_outputs(&[], ms(t)),
                "fault" => s.connection_fault(ms(t)),
                _ => s.set_outputs(&[0, 0, 0, 0, 0, 0, 0, 0], ms(t)),
            }
            log.extend(drain(s, ms(t)));
        };
        for (t, what) in ["idle", "idle", "idle", "run", "idle", "idle", "fault", "fault", "run", "fault"]
            .iter()
            .enumerate()
        {
            step(&mut s, t as u64, what);
        }
        use Transmission::{Fault, Idle};
        assert_eq!(log, std::vec![Idle, Idle, Fault, Fault]);
        assert_eq!(s.frame_for(Idle), Some(&[0x04][..]));
        assert_eq!(s.frame_for(Fault), Some(&[0x01][..]));
        assert_eq!(s.counters().idle_frames, 4);
    }

    #[test]
    fn leaving_idle_before_the_frame_went_out_cancels_it() {
        let cfg = SequencerConfig { on_idle: IdleAction::send(&[0x04]).unwrap(), ..config(0) };
        let mut s = sequencer(cfg);
        s.set_outputs(&[], ms(0));
        s.set_outputs(&OPEN_1, ms(0));
        assert_eq!(commands(&drain(&mut s, ms(0))), 1);
        assert_eq!(s.counters().idle_frames, 0);
    }

    #[test]
    fn same_command_after_idle_or_fault_is_not_repeated() {
        let mut s = sequencer(config(0));
        s.set_outputs(&OPEN_1, ms(0));
        assert_eq!(commands(&drain(&mut s, ms(0))), 1);
        s.complete(CommandOutcome::Ok);
        s.set_outputs(&[], ms(10));
        s.connection_fault(ms(20));
        s.set_outputs(&OPEN_1, ms(30));
        assert!(drain(&mut s, ms(30)).is_empty());
    }

    #[test]
    fn code_none_sends_nothing_and_lets_a_command_finish() {
        let mut s = sequencer(config(0));
        s.set_outputs(&OPEN_1, ms(0));
        drain(&mut s, ms(0));
        s.set_outputs(&[0, 2, 0, 0, 0, 0, 0, 0], ms(1));
        assert!(drain(&mut s, ms(1)).is_empty());
        assert!(s.complete(CommandOutcome::Ok));
    }

    #[test]
    fn new_command_supersedes_one_in_progress() {
        let mut s = sequencer(config(2));
        s.set_outputs(&OPEN_1, ms(0));
        drain(&mut s, ms(0));
        s.set_outputs(&CLOSE_2, ms(10));
        let ts = drain(&mut s, ms(10));
        assert_eq!(
            ts,
            std::vec![Transmission::Command {
                command: Command::from_outputs(&CLOSE_2).unwrap(),
                attempt: 1
            }]
        );
        assert_eq!(s.active().map(|c| CommandCode::from(c.code)), Some(CommandCode::Close));
    }

    #[rstest]
    #[case::execute(true, 1)]
    #[case::baseline(false, 0)]
    fn first_outputs(#[case] execute_first: bool, #[case] sent: usize) {
        let mut s = sequencer(SequencerConfig { execute_first, ..config(0) });
        s.set_outputs(&OPEN_1, ms(0));
        assert_eq!(commands(&drain(&mut s, ms(0))), sent);
        s.set_outputs(&OPEN_2, ms(1));
        assert_eq!(commands(&drain(&mut s, ms(1))), 1, "a later change always executes");
    }

    #[test]
    fn unsupported_ends_without_sending() {
        let mut s = sequencer(config(0));
        s.set_outputs(&[0x42, 1], ms(0));
        assert!(matches!(s.next_transmission(ms(0)), Some(Transmission::Command { .. })));
        assert!(s.complete(CommandOutcome::Unsupported));
        assert_eq!(s.outcome(), CommandOutcome::Unsupported);
        assert!(drain(&mut s, ms(0)).is_empty());
    }

    #[test]
    fn transmitted_ignores_a_stale_transmission() {
        let mut s = sequencer(config(0));
        s.transmitted(Transmission::Idle, ms(0), ms(0));
        assert_eq!(s.counters().idle_frames, 0);
    }

    #[rstest]
    #[case::timeout_zero(SequencerConfig { response_timeout_ms: 0, ..SequencerConfig::default() }, "sequencer.response_timeout_ms")]
    #[case::timeout_long(SequencerConfig { response_timeout_ms: 60_001, ..SequencerConfig::default() }, "sequencer.response_timeout_ms")]
    #[case::retries(SequencerConfig { retries: 11, ..SequencerConfig::default() }, "sequencer.retries")]
    fn validate_rejects(#[case] c: SequencerConfig, #[case] field: &str) {
        assert_eq!(c.validate().unwrap_err().field.key(), field);
    }

    #[test]
    fn idle_action_capacity() {
        assert!(IdleAction::send(&[0; IDLE_FRAME_CAPACITY]).is_some());
        assert!(IdleAction::send(&[0; IDLE_FRAME_CAPACITY + 1]).is_none());
        assert_eq!(IdleAction::Nothing.frame(), None);
    }
}
