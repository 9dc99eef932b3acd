//! Test equipment (feature `std`): a simulated intelligent circuit breaker.
//!
//! [`SimulatedBreaker`] speaks the source paper's protocol ([`slave_fw::serial::breaker`]) and is
//! sans-IO like the profiles: bytes in with [`on_bytes`](SimulatedBreaker::on_bytes), bytes out
//! with [`poll_transmit`](SimulatedBreaker::poll_transmit), next deadline from
//! [`poll_at`](SimulatedBreaker::poll_at). It runs on a virtual clock next to a
//! [`Profile`](slave_fw::serial::Profile) in tests, or behind a real pseudo-terminal in a process
//! that feeds it `std::time` instants.
//!
//! Behaviour:
//!
//! * a status frame every [`period`](SimulatedBreaker::with_period) (1 s), the first at start-up;
//! * status data: bytes 0–3 the phase currents (the configured load while closed, zero while
//!   open), byte 9 the switch state, bytes 10–17 parameters 0–3 as little-endian u16; it starts
//!   open with zero load and parameters;
//! * open, close, set parameter and refresh are acknowledged at once (`cmd | 0x80, status`);
//!   state changes show in the next status frame; refresh also sends a status frame at once;
//!   set parameter with an id above 3 is refused with [`breaker::ACK_BAD_ARGUMENT`];
//! * knobs: [`set_silent`](SimulatedBreaker::set_silent) (transmitter dead; commands still
//!   obeyed), [`set_ignore_commands`](SimulatedBreaker::set_ignore_commands) (commands logged but
//!   neither obeyed nor acknowledged), [`reject_commands`](SimulatedBreaker::reject_commands),
//!   [`corrupt_next_frames`](SimulatedBreaker::corrupt_next_frames) (bad checksums),
//!   [`send_garbage`](SimulatedBreaker::send_garbage), [`set_load`](SimulatedBreaker::set_load).

use devicenet::{Duration, Instant};
use slave_fw::serial::breaker::{self, Ack, BreakerCommand, StatusData, SwitchState};
use slave_fw::serial::{FrameCounters, FrameParser};
use std::collections::VecDeque;
use std::vec::Vec;

/// Parameters the simulated breaker knows (ids `0..PARAMETERS`).
pub const PARAMETERS: usize = 4;

#[derive(Clone, Debug)]
struct Queued {
    due: Instant,
    bytes: Vec<u8>,
    /// A frame (may be corrupted) rather than raw garbage.
    frame: bool,
}

/// A simulated breaker; see the [module docs](self).
#[derive(Clone, Debug)]
pub struct SimulatedBreaker {
    parser: FrameParser<32>,
    period: Duration,
    next_status: Instant,
    switch: SwitchState,
    load: [u8; 4],
    parameters: [u16; PARAMETERS],
    queue: VecDeque<Queued>,
    silent: bool,
    ignore_commands: bool,
    reject_with: Option<u8>,
    corrupt_frames: usize,
    commands: Vec<BreakerCommand>,
    status_frames_sent: u32,
}

impl SimulatedBreaker {
    /// A breaker powered up at `now`: open, no load, its first status frame due at once.
    pub fn new(now: Instant) -> Self {
        SimulatedBreaker {
            // The breaker framing always fits 32 bytes (22-byte status frames).
            parser: match FrameParser::new(breaker::FRAMING) {
                Ok(p) => p,
                Err(e) => unreachable!("breaker framing: {e}"),
            },
            period: Duration::from_secs(1),
            next_status: now,
            switch: SwitchState::Open,
            load: [0; 4],
            parameters: [0; PARAMETERS],
            queue: VecDeque::new(),
            silent: false,
            ignore_commands: false,
            reject_with: None,
            corrupt_frames: 0,
            commands: Vec::new(),
            status_frames_sent: 0,
        }
    }

    /// The same breaker with a different status period.
    pub fn with_period(mut self, period: Duration) -> Self {
        self.period = period;
        self
    }

    /// Takes bytes from the converter at `now`; commands are obeyed and acknowledged at once.
    pub fn on_bytes(&mut self, bytes: &[u8], now: Instant) {
        let mut received: Vec<Result<BreakerCommand, (u8, u8)>> = Vec::new();
        self.parser.push_slice(bytes, |event| {
            if let Ok(frame) = event {
                let data = frame.data();
                received.push(
                    BreakerCommand::parse(data)
                        .map_err(|status| (data.first().copied().unwrap_or(0), status)),
                );
            }
        });
        for r in received {
            match r {
                Ok(cmd) => self.on_command(cmd, now),
                Err((code, status)) => {
                    if !self.ignore_commands {
                        self.queue_frame(&Ack { command: code & !breaker::ACK_FLAG, status }.to_data(), now);
                    }
                }
            }
        }
    }

    fn on_command(&mut self, cmd: BreakerCommand, now: Instant) {
        self.commands.push(cmd);
        if self.ignore_commands {
            return;
        }
        if let Some(status) = self.reject_with {
            self.queue_frame(&Ack { command: cmd.code(), status }.to_data(), now);
            return;
        }
        let mut status = breaker::ACK_OK;
        match cmd {
            BreakerCommand::Open => self.switch = SwitchState::Open,
            BreakerCommand::Close => self.switch = SwitchState::Closed,
            BreakerCommand::SetParameter { id, value } => match self.parameters.get_mut(usize::from(id)) {
                Some(p) => *p = value,
                None => status = breaker::ACK_BAD_ARGUMENT,
            },
            BreakerCommand::Refresh => {}
        }
        self.queue_frame(&Ack { command: cmd.code(), status }.to_data(), now);
        if cmd == BreakerCommand::Refresh {
            let data = self.status_data();
            self.queue_frame(data.as_bytes(), now);
            self.status_frames_sent += 1;
        }
    }

    fn queue_frame(&mut self, data: &[u8], now: Instant) {
        let mut out = [0u8; 32];
        if let Some(bytes) = breaker::FRAMING.encode(data, &mut out).ok().and_then(|n| out.get(..n)) {
            self.queue.push_back(Queued { due: now, bytes: bytes.to_vec(), frame: true });
        }
    }

    /// Returns the next bytes the breaker sends at `now` (a frame, or garbage), if any.
    pub fn poll_transmit(&mut self, now: Instant) -> Option<Vec<u8>> {
        if now >= self.next_status {
            let data = self.status_data();
            self.queue_frame(data.as_bytes(), now);
            self.status_frames_sent += 1;
            while self.next_status <= now {
                self.next_status += self.period;
            }
        }
        if self.silent {
            self.queue.clear();
            return None;
        }
        let front = self.queue.front()?;
        if front.due > now {
            return None;
        }
        let mut q = self.queue.pop_front()?;
        if q.frame && self.corrupt_frames > 0 {
            self.corrupt_frames -= 1;
            let checksum = q.bytes.len().saturating_sub(2);
            if let Some(b) = q.bytes.get_mut(checksum) {
                *b ^= 0x5A;
            }
        }
        Some(q.bytes)
    }

    /// When to call [`poll_transmit`](Self::poll_transmit) next.
    pub fn poll_at(&self) -> Option<Instant> {
        let queued = self.queue.front().map(|q| q.due);
        Some(queued.map_or(self.next_status, |q| q.min(self.next_status)))
    }

    /// The status data the next status frame carries.
    pub fn status_data(&self) -> StatusData {
        let currents = if self.switch == SwitchState::Closed { self.load } else { [0; 4] };
        let mut data = StatusData::new(currents, self.switch);
        for (k, p) in self.parameters.iter().enumerate() {
            if let Some(dst) = data.0.get_mut(10 + 2 * k..12 + 2 * k) {
                dst.copy_from_slice(&p.to_le_bytes());
            }
        }
        data
    }

    /// Stops (`true`) or resumes sending anything; commands are still obeyed while silent.
    pub fn set_silent(&mut self, silent: bool) {
        self.silent = silent;
    }

    /// Logs commands without obeying or acknowledging them (`true`), or back to normal.
    pub fn set_ignore_commands(&mut self, ignore: bool) {
        self.ignore_commands = ignore;
    }

    /// Refuses every command with this acknowledgement status (`None`: obey again).
    pub fn reject_commands(&mut self, status: Option<u8>) {
        self.reject_with = status;
    }

    /// Sends the next `n` frames with a wrong checksum.
    pub fn corrupt_next_frames(&mut self, n: usize) {
        self.corrupt_frames = n;
    }

    /// Sends these raw bytes before the next frame.
    pub fn send_garbage(&mut self, bytes: &[u8], now: Instant) {
        self.queue.push_back(Queued { due: now, bytes: bytes.to_vec(), frame: false });
    }

    /// The phase A, B, C, N currents reported while closed.
    pub fn set_load(&mut self, currents: [u8; 4]) {
        self.load = currents;
    }

    /// Trips or sets the switch by hand (as if operated locally).
    pub fn set_switch(&mut self, state: SwitchState) {
        self.switch = state;
    }

    /// The switch state.
    pub fn switch_state(&self) -> SwitchState {
        self.switch
    }

    /// Parameter `id`, if the breaker knows it.
    pub fn parameter(&self, id: u8) -> Option<u16> {
        self.parameters.get(usize::from(id)).copied()
    }

    /// Every command received, in order (including ignored and refused ones).
    pub fn commands(&self) -> &[BreakerCommand] {
        &self.commands
    }

    /// Status frames produced so far (sent or, while silent, dropped).
    pub fn status_frames_sent(&self) -> u32 {
        self.status_frames_sent
    }

    /// The breaker's own receive counters (frames from the converter).
    pub fn parser_counters(&self) -> &FrameCounters {
        self.parser.counters()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slave_fw::serial::breaker::Message;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    fn messages(b: &mut SimulatedBreaker, now: Instant) -> Vec<Message> {
        let mut parser = FrameParser::<32>::new(breaker::FRAMING).unwrap();
        let mut out = Vec::new();
        while let Some(bytes) = b.poll_transmit(now) {
            parser.push_slice(&bytes, |e| {
                if let Ok(f) = e {
                    out.push(Message::classify(f.data()));
                }
            });
        }
        out
    }

    fn frame(data: &[u8]) -> Vec<u8> {
        let mut out = [0u8; 32];
        let n = breaker::FRAMING.encode(data, &mut out).unwrap();
        out[..n].to_vec()
    }

    #[test]
    fn status_every_second_starting_open() {
        let mut b = SimulatedBreaker::new(ms(0));
        assert_eq!(b.poll_at(), Some(ms(0)));
        let m = messages(&mut b, ms(0));
        assert_eq!(m, std::vec![Message::Status(StatusData::new([0; 4], SwitchState::Open))]);
        assert_eq!(b.poll_at(), Some(ms(1000)));
        assert!(messages(&mut b, ms(999)).is_empty());
        assert_eq!(messages(&mut b, ms(1000)).len(), 1);
    }

    #[test]
    fn close_is_acked_and_shows_in_the_next_status() {
        let mut b = SimulatedBreaker::new(ms(0));
        b.set_load([10, 11, 12, 1]);
        messages(&mut b, ms(0));
        b.on_bytes(&frame(&[0x02]), ms(100));
        assert_eq!(messages(&mut b, ms(100)), std::vec![Message::Ack(Ack { command: 2, status: 0 })]);
        let m = messages(&mut b, ms(1000));
        assert_eq!(m, std::vec![Message::Status(StatusData::new([10, 11, 12, 1], SwitchState::Closed))]);
        assert_eq!(b.commands(), &[BreakerCommand::Close]);
    }

    #[test]
    fn refresh_sends_status_at_once_and_parameters_show() {
        let mut b = SimulatedBreaker::new(ms(0));
        messages(&mut b, ms(0));
        b.on_bytes(&frame(&[0x03, 0x01, 0x34, 0x12]), ms(10));
        b.on_bytes(&frame(&[0x04]), ms(10));
        let m = messages(&mut b, ms(10));
        assert_eq!(m.len(), 3);
        let Message::Status(s) = m[2] else { panic!("{m:?}") };
        assert_eq!(&s.as_bytes()[12..14], &[0x34, 0x12]);
        assert_eq!(b.parameter(1), Some(0x1234));
    }

    #[test]
    fn refusals() {
        let mut b = SimulatedBreaker::new(ms(0));
        messages(&mut b, ms(0));
        b.on_bytes(&frame(&[0x03, 0x09, 0, 0]), ms(1));
        b.on_bytes(&frame(&[0x07]), ms(1));
        b.reject_commands(Some(0x42));
        b.on_bytes(&frame(&[0x02]), ms(1));
        let m = messages(&mut b, ms(1));
        assert_eq!(
            m,
            std::vec![
                Message::Ack(Ack { command: 3, status: breaker::ACK_BAD_ARGUMENT }),
                Message::Ack(Ack { command: 7, status: breaker::ACK_UNKNOWN_COMMAND }),
                Message::Ack(Ack { command: 2, status: 0x42 }),
            ]
        );
        assert_eq!(b.switch_state(), SwitchState::Open);
    }

    #[test]
    fn knobs_silent_ignore_corrupt_garbage() {
        let mut b = SimulatedBreaker::new(ms(0));
        b.set_silent(true);
        b.on_bytes(&frame(&[0x02]), ms(0));
        assert!(b.poll_transmit(ms(0)).is_none());
        assert_eq!(b.switch_state(), SwitchState::Closed, "obeyed while silent");
        b.set_silent(false);
        b.set_ignore_commands(true);
        b.on_bytes(&frame(&[0x01]), ms(10));
        assert!(messages(&mut b, ms(10)).is_empty());
        assert_eq!(b.switch_state(), SwitchState::Closed);
        assert_eq!(b.commands().len(), 2);
        b.send_garbage(&[0xDE, 0xAD], ms(1000));
        b.corrupt_next_frames(1);
        assert_eq!(b.poll_transmit(ms(1000)), Some(std::vec![0xDE, 0xAD]));
        let bad = b.poll_transmit(ms(1000)).unwrap();
        let mut p = FrameParser::<32>::new(breaker::FRAMING).unwrap();
        p.push_slice(&bad, |_| {});
        assert_eq!(p.counters().bad_checksum, 1);
        assert_eq!(b.status_frames_sent(), 2);
    }
}
