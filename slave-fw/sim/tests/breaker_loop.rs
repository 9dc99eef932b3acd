//! The breaker profile against the simulated breaker on a virtual clock: the serial half of the
//! issue's acceptance tests, without a pty. Bytes cross the "wire" instantly; polls are simulated
//! by calling `set_outputs` the way the converter will.

use converter_sim::SimulatedBreaker;
use devicenet::{Duration, Instant};
use slave_fw::serial::breaker::{BreakerCommand, SwitchState, SWITCH_CLOSED, SWITCH_OPEN};
use slave_fw::serial::{CommandOutcome, LinkState, Profile, ProfileConfig, StatusByte};

/// The converter's serial side and a breaker on one virtual clock.
struct Bench {
    now: Instant,
    profile: Profile,
    breaker: SimulatedBreaker,
}

impl Bench {
    fn new() -> Self {
        Self::with_config(ProfileConfig::breaker())
    }

    fn with_config(config: ProfileConfig) -> Self {
        let now = Instant::ZERO;
        Bench { now, profile: Profile::new(config, now).unwrap(), breaker: SimulatedBreaker::new(now) }
    }

    /// Moves every byte that is due now, both ways, until both sides are quiet.
    fn exchange(&mut self) {
        loop {
            let mut moved = false;
            while let Some(frame) = self.profile.poll_transmit(self.now) {
                let frame = frame.to_vec();
                self.breaker.on_bytes(&frame, self.now);
                moved = true;
            }
            while let Some(bytes) = self.breaker.poll_transmit(self.now) {
                self.profile.on_bytes(&bytes, self.now);
                moved = true;
            }
            if !moved {
                return;
            }
        }
    }

    /// Runs to `until`, stepping to each side's next deadline.
    fn run_until(&mut self, until: Instant) {
        loop {
            self.exchange();
            let next = [self.profile.poll_at(), self.breaker.poll_at()].into_iter().flatten().min();
            match next {
                Some(t) if t <= until => self.now = t.max(self.now),
                _ => break,
            }
        }
        self.now = until.max(self.now);
        self.exchange();
    }

    /// A poll from the scanner every `period` from now on, `count` times, with these outputs.
    fn polls(&mut self, outputs: &[u8], count: usize, period: Duration) {
        for _ in 0..count {
            self.profile.set_outputs(outputs, self.now);
            self.exchange();
            let until = self.now + period;
            self.run_until(until);
        }
    }

    fn secs(&self, s: u64) -> Instant {
        self.now + Duration::from_secs(s)
    }
}

const POLL: Duration = Duration::from_millis(10);

#[test]
fn data_reaches_the_input_image() {
    let mut b = Bench::new();
    b.breaker.set_load([10, 11, 12, 1]);
    b.run_until(Instant::from_millis(100));
    assert_eq!(b.profile.input_image()[9], SWITCH_OPEN);
    assert_eq!(&b.profile.input_image()[..4], &[0, 0, 0, 0]);
    assert_eq!(b.profile.status().state, LinkState::Ok);
    let until = b.secs(5);
    b.run_until(until);
    assert_eq!(b.profile.stats().frames_received, 6, "one status frame a second");
    assert_eq!(b.profile.status().freshness, 6);
}

#[test]
fn close_then_open_reach_the_breaker_exactly_once_despite_repeated_polls() {
    let mut b = Bench::new();
    b.breaker.set_load([10, 11, 12, 1]);
    b.polls(&[2, 1, 0, 0, 0, 0, 0, 0], 100, POLL);
    assert_eq!(b.breaker.commands(), &[BreakerCommand::Close]);
    assert_eq!(b.profile.status().command, CommandOutcome::Ok);
    let until = b.secs(1);
    b.run_until(until);
    assert_eq!(b.profile.input_image()[9], SWITCH_CLOSED);
    assert_eq!(&b.profile.input_image()[..4], &[10, 11, 12, 1]);

    b.polls(&[1, 2, 0, 0, 0, 0, 0, 0], 100, POLL);
    assert_eq!(b.breaker.commands(), &[BreakerCommand::Close, BreakerCommand::Open]);
    let until = b.secs(1);
    b.run_until(until);
    assert_eq!(b.profile.input_image()[9], SWITCH_OPEN);
    assert_eq!(b.profile.stats().commands_sent, 2);
    assert_eq!(b.profile.stats().commands_retried, 0);
}

#[test]
fn refresh_and_set_parameter() {
    let mut b = Bench::new();
    b.run_until(Instant::from_millis(100));
    let before = b.profile.status().freshness;
    b.polls(&[3, 1, 1, 0x34, 0x12, 0, 0, 0], 1, POLL);
    assert_eq!(b.breaker.parameter(1), Some(0x1234));
    b.polls(&[4, 2, 0, 0, 0, 0, 0, 0], 1, POLL);
    assert_eq!(&b.profile.input_image()[12..14], &[0x34, 0x12], "refresh brought the new status at once");
    assert_eq!(b.profile.status().freshness, before.wrapping_add(3), "two acks and a status frame");
}

#[test]
fn refused_command_is_reported() {
    let mut b = Bench::new();
    b.polls(&[3, 1, 9, 0, 0, 0, 0, 0], 5, POLL);
    assert_eq!(b.profile.status().command, CommandOutcome::Rejected(0x02));
    assert_eq!(b.profile.status().status_byte().command_code(), 3);
    assert_eq!(b.profile.stats().commands_rejected, 1);
}

#[test]
fn unanswered_command_is_retried_a_bounded_number_of_times() {
    let mut b = Bench::new();
    b.breaker.set_ignore_commands(true);
    b.polls(&[2, 1, 0, 0, 0, 0, 0, 0], 400, POLL);
    assert_eq!(b.breaker.commands().len(), 3, "1 + 2 retries");
    assert_eq!(b.profile.status().command, CommandOutcome::Failed);
    assert_eq!(b.breaker.switch_state(), SwitchState::Open);
    let s = b.profile.stats();
    assert_eq!((s.commands_sent, s.commands_retried, s.commands_failed), (1, 2, 1));
}

#[test]
fn idle_polls_and_connection_faults_never_send_a_command() {
    let mut b = Bench::new();
    b.polls(&[], 50, POLL);
    b.profile.connection_fault(b.now);
    let until = b.secs(2);
    b.run_until(until);
    b.polls(&[0, 0, 0, 0, 0, 0, 0, 0], 50, POLL);
    assert!(b.breaker.commands().is_empty());
    assert_eq!(b.breaker.parser_counters().frames, 0);
}

#[test]
fn silent_breaker_is_reported_stale_within_the_timeout() {
    let mut b = Bench::new();
    b.breaker.set_load([5, 5, 5, 0]);
    b.polls(&[2, 1, 0, 0, 0, 0, 0, 0], 1, POLL);
    let until = b.secs(2);
    b.run_until(until);
    let last_frame = Instant::from_secs(2);
    b.breaker.set_silent(true);
    b.run_until(last_frame + Duration::from_millis(2999));
    assert_eq!(b.profile.status().state, LinkState::Ok);
    b.run_until(last_frame + Duration::from_millis(3000));
    let status = b.profile.status();
    assert_eq!(status.state, LinkState::Timeout);
    assert!(status.status_byte().contains(StatusByte::LINK_TIMEOUT));
    assert_eq!(b.profile.input_image()[0], 5, "default policy holds the last value");
    b.breaker.set_silent(false);
    let until = b.secs(1);
    b.run_until(until);
    assert_eq!(b.profile.status().state, LinkState::Ok);
    assert_eq!(b.profile.stats().link_timeouts, 1);
}

#[test]
fn silent_breaker_with_clear_policy() {
    let mut config = slave_fw::serial::FramedProfileConfig::breaker();
    config.health.stale_policy = slave_fw::serial::StalePolicy::Clear;
    let mut b = Bench::with_config(ProfileConfig::Framed(config));
    b.polls(&[2, 1, 0, 0, 0, 0, 0, 0], 1, POLL);
    let until = b.secs(1);
    b.run_until(until);
    assert_eq!(b.profile.input_image()[9], SWITCH_CLOSED);
    b.breaker.set_silent(true);
    let until = b.secs(4);
    b.run_until(until);
    assert_eq!(b.profile.input_image(), &[0u8; 18]);
}

#[test]
fn garbage_and_bad_checksums_are_counted_and_survived() {
    let mut b = Bench::new();
    b.run_until(Instant::from_millis(500));
    b.breaker.send_garbage(&[0x00, 0x68, 0x99, 0x16, 0xFF, 0x68], b.now);
    b.breaker.corrupt_next_frames(2);
    let until = b.secs(2);
    b.run_until(until);
    let s = b.profile.stats();
    assert_eq!(s.checksum_errors, 2);
    assert!(s.framing_errors >= 1, "{s:?}");
    assert!(s.discarded_bytes >= 3, "{s:?}");
    assert!(b.profile.status().frame_errors, "no good frame since");
    let until = b.secs(1);
    b.run_until(until);
    assert!(!b.profile.status().frame_errors);
    assert_eq!(b.profile.status().state, LinkState::Ok);
    assert_eq!(b.profile.input_image()[9], SWITCH_OPEN);
}
