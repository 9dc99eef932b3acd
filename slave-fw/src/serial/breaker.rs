//! The intelligent circuit breaker of the source paper, on top of the generic framing.
//!
//! Every second the breaker's controller sends a status frame
//! `0x68, 0x12, data[18], sum8(data), 0x16`: bytes 0–3 are the phase A, B, C and N currents,
//! byte 9 the switch state (`0x0F` open, `0xF0` closed). Commands use the same framing,
//! `0x68, len, cmd, args…, checksum, 0x16`: open `0x01`, close `0x02`, set parameter `0x03`
//! (parameter id, little-endian u16 value), refresh `0x04`. The breaker acknowledges each with
//! `0x68, 0x02, cmd | 0x80, status, checksum, 0x16`; status 0 means accepted.
//!
//! Status frames and acknowledgements are told apart by their length (18 vs 2 data bytes) and
//! the acknowledgement flag in the first data byte ([`Message::classify`]).
//!
//! The converter does not need this module to run a breaker: [`profile_config`] is a plain
//! [`FramedProfileConfig`] and a [`FramedProfile`](super::FramedProfile) does the rest. The typed
//! views here serve the simulated breaker, the tests, and anyone who wants to read a status frame.

use super::checksum::Checksum;
use super::framed::{FramedConfig, LengthField};
use super::framed_profile::{AckFormat, CommandFormat, FramedProfileConfig};
use super::health::HealthConfig;
use super::line::SerialSettings;
use super::sequencer::{Command, CommandCode, SequencerConfig};
use heapless::Vec;

/// The start byte of every frame.
pub const START: u8 = 0x68;
/// The end byte of every frame.
pub const END: u8 = 0x16;
/// Data bytes in a status frame.
pub const STATUS_LEN: usize = 18;
/// Data bytes in an acknowledgement.
pub const ACK_LEN: usize = 2;
/// Set in the first data byte of an acknowledgement: `cmd | ACK_FLAG`.
pub const ACK_FLAG: u8 = 0x80;

/// Wire code of the open command.
pub const CMD_OPEN: u8 = 0x01;
/// Wire code of the close command.
pub const CMD_CLOSE: u8 = 0x02;
/// Wire code of the set-parameter command.
pub const CMD_SET_PARAMETER: u8 = 0x03;
/// Wire code of the refresh command.
pub const CMD_REFRESH: u8 = 0x04;

/// Acknowledgement status: accepted. Any other status is a refusal, reported verbatim as
/// [`CommandOutcome::Rejected`](super::CommandOutcome::Rejected).
pub const ACK_OK: u8 = 0x00;
/// Acknowledgement status used by the simulated breaker: unknown command.
pub const ACK_UNKNOWN_COMMAND: u8 = 0x01;
/// Acknowledgement status used by the simulated breaker: bad argument (unknown parameter).
pub const ACK_BAD_ARGUMENT: u8 = 0x02;
/// Acknowledgement status used by the simulated breaker: wrong number of argument bytes.
pub const ACK_BAD_LENGTH: u8 = 0x03;

/// Byte 9 of a status frame when the breaker is open.
pub const SWITCH_OPEN: u8 = 0x0F;
/// Byte 9 of a status frame when the breaker is closed.
pub const SWITCH_CLOSED: u8 = 0xF0;

/// The breaker's framing: `0x68`, a length byte, at most 18 data bytes, sum-8, `0x16`.
pub const FRAMING: FramedConfig = FramedConfig {
    start: START,
    length: LengthField::Byte,
    end: Some(END),
    checksum: Checksum::Sum8,
    max_len: STATUS_LEN as u8,
};

/// The switch state, byte 9 of a status frame. Unknown values are kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SwitchState {
    /// `0x0F`.
    Open,
    /// `0xF0`.
    Closed,
    /// Anything else.
    Unknown(u8),
}

impl SwitchState {
    /// The byte as sent.
    pub const fn as_raw(self) -> u8 {
        match self {
            SwitchState::Open => SWITCH_OPEN,
            SwitchState::Closed => SWITCH_CLOSED,
            SwitchState::Unknown(b) => b,
        }
    }
}

impl From<u8> for SwitchState {
    fn from(raw: u8) -> Self {
        match raw {
            SWITCH_OPEN => SwitchState::Open,
            SWITCH_CLOSED => SwitchState::Closed,
            b => SwitchState::Unknown(b),
        }
    }
}

/// The 18 data bytes of a status frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StatusData(pub [u8; STATUS_LEN]);

impl StatusData {
    /// The data of a status frame, if `data` is exactly 18 bytes.
    pub fn from_data(data: &[u8]) -> Option<StatusData> {
        data.try_into().ok().map(StatusData)
    }

    /// A status with these phase currents and switch state, all other bytes zero.
    pub fn new(currents: [u8; 4], switch: SwitchState) -> StatusData {
        let mut d = [0u8; STATUS_LEN];
        let [a, b, c, n] = currents;
        d[0] = a;
        d[1] = b;
        d[2] = c;
        d[3] = n;
        d[9] = switch.as_raw();
        StatusData(d)
    }

    /// Bytes 0–3: phase A, B, C and N currents.
    pub fn phase_currents(&self) -> [u8; 4] {
        [self.0[0], self.0[1], self.0[2], self.0[3]]
    }

    /// Byte 9: the switch state.
    pub fn switch_state(&self) -> SwitchState {
        SwitchState::from(self.0[9])
    }

    /// The 18 bytes.
    pub fn as_bytes(&self) -> &[u8; STATUS_LEN] {
        &self.0
    }
}

/// A command to the breaker.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BreakerCommand {
    /// `0x01`: open.
    Open,
    /// `0x02`: close.
    Close,
    /// `0x03 id value_lo value_hi`: set parameter `id` to `value`.
    SetParameter {
        /// Parameter id.
        id: u8,
        /// New value.
        value: u16,
    },
    /// `0x04`: send a status frame now.
    Refresh,
}

impl BreakerCommand {
    /// The wire code (first data byte).
    pub const fn code(&self) -> u8 {
        match self {
            BreakerCommand::Open => CMD_OPEN,
            BreakerCommand::Close => CMD_CLOSE,
            BreakerCommand::SetParameter { .. } => CMD_SET_PARAMETER,
            BreakerCommand::Refresh => CMD_REFRESH,
        }
    }

    /// The frame data: code and arguments.
    pub fn to_data(&self) -> Vec<u8, 4> {
        let mut v = Vec::new();
        let bytes: &[u8] = match *self {
            BreakerCommand::SetParameter { id, value } => {
                let [lo, hi] = value.to_le_bytes();
                &[CMD_SET_PARAMETER, id, lo, hi]
            }
            _ => &[self.code()],
        };
        // At most 4 bytes.
        let _ = v.extend_from_slice(bytes);
        v
    }

    /// Decodes frame data; on failure, the acknowledgement status the breaker answers with.
    pub fn parse(data: &[u8]) -> Result<BreakerCommand, u8> {
        match data {
            [CMD_OPEN] => Ok(BreakerCommand::Open),
            [CMD_CLOSE] => Ok(BreakerCommand::Close),
            [CMD_SET_PARAMETER, id, lo, hi] => {
                Ok(BreakerCommand::SetParameter { id: *id, value: u16::from_le_bytes([*lo, *hi]) })
            }
            [CMD_REFRESH] => Ok(BreakerCommand::Refresh),
            [CMD_OPEN | CMD_CLOSE | CMD_SET_PARAMETER | CMD_REFRESH, ..] => Err(ACK_BAD_LENGTH),
            _ => Err(ACK_UNKNOWN_COMMAND),
        }
    }

    /// The breaker command carried by poll outputs: code 1–4, set-parameter arguments in bytes
    /// 2–4 (id, value low, value high). `None` for code 0 and unknown codes.
    pub fn from_command(command: &Command) -> Option<BreakerCommand> {
        let [id, lo, hi, ..] = command.args;
        match CommandCode::from(command.code) {
            CommandCode::Open => Some(BreakerCommand::Open),
            CommandCode::Close => Some(BreakerCommand::Close),
            CommandCode::SetParameter => {
                Some(BreakerCommand::SetParameter { id, value: u16::from_le_bytes([lo, hi]) })
            }
            CommandCode::Refresh => Some(BreakerCommand::Refresh),
            CommandCode::None | CommandCode::Unknown(_) => None,
        }
    }
}

/// An acknowledgement: `cmd | 0x80, status`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Ack {
    /// The wire code of the acknowledged command.
    pub command: u8,
    /// [`ACK_OK`] or a refusal status.
    pub status: u8,
}

impl Ack {
    /// The frame data.
    pub fn to_data(&self) -> [u8; ACK_LEN] {
        [self.command | ACK_FLAG, self.status]
    }

    /// Decodes frame data: 2 bytes, the first with [`ACK_FLAG`].
    pub fn parse(data: &[u8]) -> Option<Ack> {
        match data {
            [cmd, status] if cmd & ACK_FLAG != 0 => Some(Ack { command: cmd & !ACK_FLAG, status: *status }),
            _ => None,
        }
    }
}

/// A frame from the breaker, classified.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Message {
    /// A status frame (18 data bytes).
    Status(StatusData),
    /// An acknowledgement (2 data bytes, flag set).
    Ack(Ack),
    /// Anything else with valid framing.
    Other,
}

impl Message {
    /// Tells status frames from acknowledgements by length and first data byte.
    pub fn classify(data: &[u8]) -> Message {
        if let Some(ack) = Ack::parse(data) {
            Message::Ack(ack)
        } else if let Some(status) = StatusData::from_data(data) {
            Message::Status(status)
        } else {
            Message::Other
        }
    }
}

impl FramedProfileConfig {
    /// The breaker of the source paper ([`profile_config`]).
    pub fn breaker() -> Self {
        profile_config()
    }
}

/// The breaker as a [`FramedProfileConfig`]: 9600 8N1, the framing above, 18-byte status frames
/// as the input image, acknowledgements `cmd | 0x80, status` with 0 = ok, commands 1–4 mapped to
/// wire codes 1–4 (set parameter takes 3 argument bytes), 500 ms response timeout with 2 retries,
/// stale after 3 s, hold last value.
pub fn profile_config() -> FramedProfileConfig {
    let command = |code, wire, args| CommandFormat { code, wire, args };
    // Four entries, capacity 8 (checked at compile time).
    let commands = Vec::from_array([
        command(1, CMD_OPEN, 0),
        command(2, CMD_CLOSE, 0),
        command(3, CMD_SET_PARAMETER, 3),
        command(4, CMD_REFRESH, 0),
    ]);
    FramedProfileConfig {
        serial: SerialSettings::new_8n1(9600),
        framing: FRAMING,
        status_len: STATUS_LEN as u8,
        ack: Some(AckFormat { data_len: ACK_LEN as u8, flag: ACK_FLAG, ok_status: ACK_OK }),
        commands,
        sequencer: SequencerConfig::default(),
        health: HealthConfig::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::FrameParser;
    use rstest::rstest;

    #[rstest]
    #[case::open(BreakerCommand::Open, &[0x68, 0x01, 0x01, 0x01, 0x16])]
    #[case::close(BreakerCommand::Close, &[0x68, 0x01, 0x02, 0x02, 0x16])]
    #[case::set_parameter(BreakerCommand::SetParameter { id: 2, value: 0x1234 }, &[0x68, 0x04, 0x03, 0x02, 0x34, 0x12, 0x4B, 0x16])]
    #[case::refresh(BreakerCommand::Refresh, &[0x68, 0x01, 0x04, 0x04, 0x16])]
    fn command_frames(#[case] cmd: BreakerCommand, #[case] wire: &[u8]) {
        let mut out = [0u8; 32];
        let n = FRAMING.encode(&cmd.to_data(), &mut out).unwrap();
        assert_eq!(&out[..n], wire);
        let mut parser = FrameParser::<32>::new(FRAMING).unwrap();
        let mut decoded = None;
        parser.push_slice(wire, |e| decoded = Some(BreakerCommand::parse(e.unwrap().data())));
        assert_eq!(decoded, Some(Ok(cmd)));
    }

    #[rstest]
    #[case::unknown(&[0x09], ACK_UNKNOWN_COMMAND)]
    #[case::empty(&[], ACK_UNKNOWN_COMMAND)]
    #[case::open_with_args(&[0x01, 0x00], ACK_BAD_LENGTH)]
    #[case::set_short(&[0x03, 0x01, 0x02], ACK_BAD_LENGTH)]
    fn command_parse_errors(#[case] data: &[u8], #[case] status: u8) {
        assert_eq!(BreakerCommand::parse(data), Err(status));
    }

    #[rstest]
    #[case::open([1, 5, 0, 0, 0, 0, 0, 0], Some(BreakerCommand::Open))]
    #[case::set([3, 5, 2, 0x34, 0x12, 9, 9, 9], Some(BreakerCommand::SetParameter { id: 2, value: 0x1234 }))]
    #[case::none([0, 5, 0, 0, 0, 0, 0, 0], None)]
    #[case::unknown([9, 5, 0, 0, 0, 0, 0, 0], None)]
    fn from_poll_command(#[case] bytes: [u8; 8], #[case] cmd: Option<BreakerCommand>) {
        assert_eq!(BreakerCommand::from_command(&Command::from_outputs(&bytes).unwrap()), cmd);
    }

    #[test]
    fn status_frame_view() {
        let data = [10, 11, 12, 1, 0, 0, 0, 0, 0, 0xF0, 0, 0, 0, 0, 0, 0, 0, 0];
        let s = StatusData::from_data(&data).unwrap();
        assert_eq!(s.phase_currents(), [10, 11, 12, 1]);
        assert_eq!(s.switch_state(), SwitchState::Closed);
        assert_eq!(StatusData::new([10, 11, 12, 1], SwitchState::Closed), s);
        assert_eq!(StatusData::from_data(&data[..17]), None);
        let mut wire = [0u8; 32];
        let n = FRAMING.encode(s.as_bytes(), &mut wire).unwrap();
        assert_eq!(&wire[..3], &[0x68, 0x12, 10]);
        assert_eq!(&wire[n - 2..n], &[0x12, 0x16]);
    }

    #[rstest]
    #[case::open(0x0F, SwitchState::Open)]
    #[case::closed(0xF0, SwitchState::Closed)]
    #[case::between(0x00, SwitchState::Unknown(0x00))]
    fn switch_states(#[case] raw: u8, #[case] state: SwitchState) {
        assert_eq!(SwitchState::from(raw), state);
        assert_eq!(state.as_raw(), raw);
    }

    #[rstest]
    #[case::ack(&[0x81, 0x00], Message::Ack(Ack { command: 1, status: 0 }))]
    #[case::nak(&[0x83, 0x02], Message::Ack(Ack { command: 3, status: 2 }))]
    #[case::two_bytes_no_flag(&[0x01, 0x00], Message::Other)]
    #[case::status(&[0; 18], Message::Status(StatusData([0; 18])))]
    #[case::odd_length(&[0; 5], Message::Other)]
    fn classify(#[case] data: &[u8], #[case] message: Message) {
        assert_eq!(Message::classify(data), message);
    }

    #[test]
    fn ack_to_data() {
        assert_eq!(Ack { command: 2, status: 0 }.to_data(), [0x82, 0x00]);
    }

    #[test]
    fn preset_is_valid() {
        profile_config().validate().unwrap();
    }
}

/// The framed profile driven with the breaker's configuration: status frames, commands and their
/// acknowledgements, retries, idle frames, stale policy, and configuration checks.
#[cfg(test)]
mod profile_tests {
    use super::{self as breaker, StatusData, SwitchState};
    use crate::serial::checksum::Checksum;
    use crate::serial::framed::{FramedConfig, LengthField};
    use crate::serial::framed_profile::{AckFormat, CommandFormat, FramedProfile, FramedProfileConfig};
    use crate::serial::{
        CommandOutcome, HealthConfig, IdleAction, LinkState, Problem, SequencerConfig, SerialSettings,
        StalePolicy, StatusByte,
    };
    use devicenet::Instant;
    use heapless::Vec;
    use proptest::prelude::*;
    use rstest::rstest;
    use std::vec::Vec as StdVec;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn frame(data: &[u8]) -> StdVec<u8> {
        let mut out = [0u8; 64];
        let n = breaker::FRAMING.encode(data, &mut out).unwrap();
        out[..n].to_vec()
    }

    fn status(currents: [u8; 4], switch: SwitchState) -> StdVec<u8> {
        frame(StatusData::new(currents, switch).as_bytes())
    }

    fn breaker_profile(policy: StalePolicy) -> FramedProfile {
        let mut c = breaker::profile_config();
        c.health.stale_policy = policy;
        FramedProfile::new(c, ms(0)).unwrap()
    }

    fn drain(p: &mut FramedProfile, now: Instant) -> StdVec<StdVec<u8>> {
        let mut out = StdVec::new();
        while let Some(f) = p.poll_transmit(now) {
            out.push(f.to_vec());
            assert!(out.len() < 10);
        }
        out
    }

    #[test]
    fn status_frame_fills_the_image() {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        assert_eq!(p.input_image(), &[0u8; 18]);
        assert_eq!(p.status().state, LinkState::Starting);
        p.on_bytes(&status([10, 11, 12, 1], SwitchState::Closed), ms(5));
        assert_eq!(&p.input_image()[..4], &[10, 11, 12, 1]);
        assert_eq!(p.input_image()[9], 0xF0);
        let s = p.status();
        assert_eq!((s.state, s.freshness), (LinkState::Ok, 1));
        assert_eq!(s.status_byte().as_raw(), StatusByte::LINK_OK);
        assert_eq!(p.stats().frames_received, 1);
    }

    #[test]
    fn open_command_sent_once_for_a_hundred_polls_and_acked() {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        let mut sent = StdVec::new();
        for i in 0..100u64 {
            p.set_outputs(&[1, 1, 0, 0, 0, 0, 0, 0], ms(i * 10));
            sent.extend(drain(&mut p, ms(i * 10)));
            if i == 2 {
                p.on_bytes(&frame(&[0x81, 0x00]), ms(i * 10 + 5));
            }
        }
        assert_eq!(sent, std::vec![std::vec![0x68, 0x01, 0x01, 0x01, 0x16]]);
        assert_eq!(p.status().command, CommandOutcome::Ok);
        assert_eq!(p.stats().commands_sent, 1);
        assert_eq!(p.stats().frames_sent, 1);
    }

    #[test]
    fn set_parameter_carries_its_arguments() {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        p.set_outputs(&[3, 1, 2, 0x34, 0x12, 0xEE, 0xEE, 0xEE], ms(0));
        assert_eq!(
            drain(&mut p, ms(0)),
            std::vec![std::vec![0x68, 0x04, 0x03, 0x02, 0x34, 0x12, 0x4B, 0x16]]
        );
    }

    #[rstest]
    #[case::accepted(0x00, CommandOutcome::Ok)]
    #[case::refused(0x02, CommandOutcome::Rejected(2))]
    fn ack_status(#[case] status: u8, #[case] outcome: CommandOutcome) {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        p.set_outputs(&[2, 1, 0, 0, 0, 0, 0, 0], ms(0));
        drain(&mut p, ms(0));
        p.on_bytes(&frame(&[0x82, status]), ms(10));
        assert_eq!(p.status().command, outcome);
    }

    #[test]
    fn ack_for_another_command_is_ignored() {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        p.set_outputs(&[2, 1, 0, 0, 0, 0, 0, 0], ms(0));
        drain(&mut p, ms(0));
        p.on_bytes(&frame(&[0x81, 0x00]), ms(10));
        assert_eq!(p.status().command, CommandOutcome::Pending);
        assert_eq!(p.input_image(), &[0u8; 18], "an ack is not status data");
        assert_eq!(p.status().freshness, 1, "but it is a good frame");
    }

    #[test]
    fn unanswered_command_retries_then_fails() {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        p.set_outputs(&[1, 1, 0, 0, 0, 0, 0, 0], ms(0));
        let mut frames = 0;
        let mut t = ms(0);
        for _ in 0..20 {
            frames += drain(&mut p, t).len();
            match p.poll_at() {
                Some(next) => t = next,
                None => break,
            }
        }
        assert_eq!(frames, 3, "1 + 2 retries");
        assert_eq!(p.status().command, CommandOutcome::Failed);
        assert_eq!(p.status().status_byte().command_code(), 4);
        let s = p.stats();
        assert_eq!((s.commands_sent, s.commands_retried, s.commands_failed, s.timeouts), (1, 2, 1, 3));
    }

    #[test]
    fn unknown_command_code_is_unsupported() {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        p.set_outputs(&[9, 1, 0, 0, 0, 0, 0, 0], ms(0));
        assert!(drain(&mut p, ms(0)).is_empty());
        assert_eq!(p.status().command, CommandOutcome::Unsupported);
    }

    #[test]
    fn idle_poll_never_sends_a_command_and_idle_frame_goes_once() {
        let mut c = breaker::profile_config();
        c.sequencer.on_idle = IdleAction::send(&[0x04]).unwrap();
        let mut p = FramedProfile::new(c, ms(0)).unwrap();
        let mut sent = StdVec::new();
        for i in 0..100 {
            p.set_outputs(&[], ms(i));
            sent.extend(drain(&mut p, ms(i)));
        }
        assert_eq!(sent, std::vec![std::vec![0x68, 0x01, 0x04, 0x04, 0x16]]);
        assert_eq!(p.stats().commands_sent, 0);
    }

    #[rstest]
    #[case::hold(StalePolicy::HoldLastValue, 10)]
    #[case::clear(StalePolicy::Clear, 0)]
    fn stale_policy_and_status(#[case] policy: StalePolicy, #[case] current_after: u8) {
        let mut p = breaker_profile(policy);
        p.on_bytes(&status([10, 10, 10, 0], SwitchState::Closed), ms(1000));
        drain(&mut p, ms(3999));
        assert_eq!(p.status().state, LinkState::Ok);
        assert_eq!(p.poll_at(), Some(ms(4000)));
        drain(&mut p, ms(4000));
        let s = p.status();
        assert_eq!(s.state, LinkState::Timeout);
        assert_eq!(s.status_byte().as_raw() & 0x03, StatusByte::LINK_TIMEOUT);
        assert_eq!(s.freshness, 1, "no new frame");
        assert_eq!(p.input_image()[0], current_after);
        assert_eq!(p.stats().link_timeouts, 1);
        p.on_bytes(&status([20, 20, 20, 0], SwitchState::Closed), ms(5000));
        assert_eq!((p.status().state, p.status().freshness, p.input_image()[0]), (LinkState::Ok, 2, 20));
    }

    #[test]
    fn garbage_and_bad_checksums_are_counted_and_survived() {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        let mut bad = status([1, 2, 3, 4], SwitchState::Open);
        let n = bad.len();
        bad[n - 2] ^= 0xFF;
        let mut bytes = std::vec![0x00, 0x55, 0x68, 0x30];
        bytes.extend_from_slice(&bad);
        p.on_bytes(&bytes, ms(10));
        let s = p.status();
        assert!(s.frame_errors);
        assert_eq!(s.status_byte().as_raw() & StatusByte::FRAME_ERRORS, StatusByte::FRAME_ERRORS);
        assert_eq!(p.stats().checksum_errors, 1);
        assert_eq!(p.stats().framing_errors, 1, "0x68 0x30: bad length");
        assert!(p.stats().discarded_bytes >= 3);
        p.on_bytes(&status([5, 6, 7, 8], SwitchState::Open), ms(20));
        assert_eq!(&p.input_image()[..4], &[5, 6, 7, 8]);
        assert!(!p.status().frame_errors);
        assert_eq!(p.parser_counters().bad_checksum, 1);
    }

    #[test]
    fn unexpected_frames_are_counted() {
        let mut p = breaker_profile(StalePolicy::HoldLastValue);
        p.on_bytes(&frame(&[1, 2, 3]), ms(0));
        assert_eq!(p.stats().unexpected_frames, 1);
        assert_eq!(p.status().state, LinkState::Ok);
    }

    #[test]
    fn instrument_without_acks_and_fixed_framing() {
        let c = FramedProfileConfig {
            serial: SerialSettings::new_8n1(19200),
            framing: FramedConfig {
                start: 0x02,
                length: LengthField::Fixed(4),
                end: Some(0x03),
                checksum: Checksum::Xor8,
                max_len: 4,
            },
            status_len: 4,
            ack: None,
            commands: Vec::from_slice(&[CommandFormat { code: 1, wire: b'O', args: 1 }]).unwrap(),
            sequencer: SequencerConfig::default(),
            health: HealthConfig::default(),
        };
        let mut p = FramedProfile::new(c, ms(0)).unwrap();
        p.set_outputs(&[1, 7, 0x55, 0, 0, 0, 0, 0], ms(0));
        // 'O' 0x55 padded to 4 bytes, XOR = 0x4F ^ 0x55 = 0x1A.
        assert_eq!(drain(&mut p, ms(0)), std::vec![std::vec![0x02, b'O', 0x55, 0, 0, 0x1A, 0x03]]);
        assert_eq!(p.status().command, CommandOutcome::Ok);
        p.on_bytes(&[0x02, 1, 2, 3, 4, 4, 0x03], ms(1));
        assert_eq!(p.input_image(), &[1, 2, 3, 4]);
    }

    fn breaker_with(f: impl FnOnce(&mut FramedProfileConfig)) -> FramedProfileConfig {
        let mut c = breaker::profile_config();
        f(&mut c);
        c
    }

    #[rstest]
    #[case::status_len_zero(breaker_with(|c| c.status_len = 0), "status_len", None)]
    #[case::status_len_too_long(breaker_with(|c| c.status_len = 19), "status_len", None)]
    #[case::ack_len(breaker_with(|c| c.ack = Some(AckFormat { data_len: 30, flag: 0x80, ok_status: 0 })), "ack.data_len", None)]
    #[case::ack_flag(breaker_with(|c| c.ack = Some(AckFormat { data_len: 2, flag: 0, ok_status: 0 })), "ack.flag", None)]
    #[case::command_code_zero(breaker_with(|c| c.commands[1].code = 0), "commands.code", Some(1))]
    #[case::command_args(breaker_with(|c| c.commands[2].args = 7), "commands.args", Some(2))]
    #[case::duplicate(breaker_with(|c| c.commands[3].code = 1), "commands.code", Some(3))]
    #[case::idle_frame_too_long(breaker_with(|c| c.sequencer.on_idle = IdleAction::send(&[0; 19]).unwrap()), "sequencer.on_idle", None)]
    #[case::framing(breaker_with(|c| c.framing.max_len = 0), "framing.max_len", None)]
    #[case::serial(breaker_with(|c| c.serial.baud = 1), "serial.baud", None)]
    #[case::health(breaker_with(|c| c.health.stale_timeout_ms = 0), "health.stale_timeout_ms", None)]
    #[case::sequencer(breaker_with(|c| c.sequencer.retries = 200), "sequencer.retries", None)]
    fn validate_rejects(#[case] c: FramedProfileConfig, #[case] field: &str, #[case] index: Option<u16>) {
        let e = c.validate().unwrap_err();
        assert_eq!((e.field.key(), e.index), (field, index), "{e}");
        assert!(FramedProfile::new(c, ms(0)).is_err());
    }

    #[test]
    fn duplicate_names_the_first_entry() {
        let e = breaker_with(|c| c.commands[3].code = 1).validate().unwrap_err();
        assert_eq!(e.problem, Problem::Duplicate { other: 0 });
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_and_outputs_never_panic(
            chunks in proptest::collection::vec((proptest::collection::vec(any::<u8>(), 0..64), proptest::collection::vec(any::<u8>(), 0..10), 0u64..2000), 0..40)
        ) {
            let mut p = breaker_profile(StalePolicy::Clear);
            let mut now = ms(0);
            for (bytes, outputs, dt) in chunks {
                now += devicenet::Duration::from_millis(dt);
                p.on_bytes(&bytes, now);
                p.set_outputs(&outputs, now);
                drain(&mut p, now);
                prop_assert_eq!(p.input_image().len(), 18);
                if let Some(t) = p.poll_at() {
                    prop_assert!(t >= ms(0));
                }
            }
        }
    }
}
