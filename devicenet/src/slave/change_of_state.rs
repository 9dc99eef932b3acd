//! Change-of-state and cyclic I/O (Connection instance 4; protocol §II.2,
//! docs/src/reference/io-connections.md) with the Acknowledge Handler (class 0x2B, §II.2.4).
//!
//! - Cyclic: the input image is produced every expected packet rate (EPR).
//! - Change of state: produced when the application says it changed
//!   ([`SlaveNode::input_changed`]), no sooner than the production inhibit time after the last
//!   production, and at the latest every EPR (the "heartbeat" of NI and RA 1769-SDN).
//! - Productions go out on Group 1 message 13, I/O-fragmented above 8 bytes (protocol §4.2).
//!   Unless acknowledgement is suppressed, the master acknowledges each with a zero-length frame on
//!   Group 2 message 2; without it the node sends the whole series again after the acknowledge
//!   timer, up to the retry limit (§II.2.1: the only consistent reading, UNCONFIRMED), then reports
//!   [`Event::RetryLimitReached`] and goes on.
//! - When poll is not allocated, Connection 2 consumes the master's COS/cyclic data (Group 2
//!   message 5) and acknowledges it with a zero-length frame on Group 1 message 15 (§II.2.5,
//!   in `polled_io.rs`).

use super::{Event, SlaveNode};
use crate::id::{Group1MessageId, Identifier};
use crate::messages::AllocationChoice;
use crate::time::{Duration, Instant};

/// The Acknowledge Handler object's settable attributes (class 0x2B instance 1, §II.2.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AckHandler {
    /// Attribute 1: how long to wait for an acknowledgement, ms (1-65535).
    pub acknowledge_timer_ms: u16,
    /// Attribute 2: acknowledge timeouts before [`Event::RetryLimitReached`].
    pub retry_limit: u8,
}

impl AckHandler {
    /// 16 ms and one retry (U3K, XM, TOSH, LIKA; §II.2.4).
    pub const DEFAULT: AckHandler = AckHandler { acknowledge_timer_ms: 16, retry_limit: 1 };
}

/// The production state of Connection instance 4.
#[derive(Clone, Copy, Debug)]
pub(super) struct Production {
    /// When the next production is due: the cyclic period, or the COS heartbeat
    /// ([`Instant::MAX`]: none).
    due: Instant,
    /// A change of state waits for the production inhibit time to end.
    changed: bool,
    /// Attribute 17, production inhibit time, ms.
    pub(super) inhibit_ms: u16,
    /// The earliest instant of the next change-of-state production.
    inhibit_until: Instant,
    /// Waiting for the master's acknowledgement until then ([`Instant::MAX`]: not waiting).
    ack_deadline: Instant,
    /// Acknowledge timeouts since the last acknowledged or triggered production.
    retries: u8,
}

impl Production {
    pub(super) const fn new() -> Production {
        Production {
            due: Instant::MAX,
            changed: false,
            inhibit_ms: 0,
            inhibit_until: Instant::ZERO,
            ack_deadline: Instant::MAX,
            retries: 0,
        }
    }
}

impl SlaveNode {
    /// The application says the input image changed (new instrument data, a status change): a
    /// change-of-state connection produces it as soon as the production inhibit time allows.
    pub fn input_changed(&mut self, now: Instant) {
        if self.allocation.contains(AllocationChoice::CHANGE_OF_STATE) {
            self.production.changed = true;
            self.step_production(now);
        }
    }

    /// `true` when the COS/cyclic connection runs without acknowledgements.
    pub(super) fn ack_suppressed(&self) -> bool {
        self.allocation.contains(AllocationChoice::ACK_SUPPRESSION)
    }

    /// Connection 4 became established: the first production is due at once, and a Connection 2
    /// created to consume the master's COS/cyclic data is established with it.
    pub(super) fn cos_established(&mut self, now: Instant) {
        self.production = Production { inhibit_ms: self.production.inhibit_ms, ..Production::new() };
        self.production.due = now;
        if !self.allocation.contains(AllocationChoice::POLL) && self.poll.exists() {
            self.poll.state = super::ConnectionState::Established;
        }
        if self.ack_suppressed() {
            // It consumes nothing, so it has no inactivity watchdog (§II.2.3, UNCONFIRMED).
            self.cos.deadline = Instant::MAX;
        }
    }

    /// The production timers: acknowledge timeouts, the cyclic period or COS heartbeat, and a
    /// change waiting for the inhibit time.
    pub(super) fn step_production(&mut self, now: Instant) {
        if !self.cos.is_established() {
            return;
        }
        let p = &mut self.production;
        let mut again = false;
        if now >= p.ack_deadline {
            p.ack_deadline = Instant::MAX;
            if p.retries < self.ack_handler.retry_limit {
                p.retries += 1;
                again = true;
            } else {
                p.retries = 0;
                self.push_event(Event::RetryLimitReached);
            }
        }
        let p = &self.production;
        let due = now >= p.due;
        let change = p.changed && now >= p.inhibit_until;
        if due || change || again {
            self.produce(now, again);
        }
    }

    /// When [`step_production`](Self::step_production) must run next ([`Instant::MAX`]: not
    /// before another input).
    pub(super) fn production_at(&self) -> Instant {
        if !self.cos.is_established() {
            return Instant::MAX;
        }
        let p = &self.production;
        let change = if p.changed { p.inhibit_until } else { Instant::MAX };
        p.due.min(change).min(p.ack_deadline)
    }

    /// Produces the input image on Group 1 message 13, fragmented above 8 bytes.
    fn produce(&mut self, now: Instant, retry: bool) {
        self.send_input(Identifier::group1(Group1MessageId::COS_CYCLIC, self.config.mac_id));
        let epr = Duration::from_millis(u64::from(self.cos.expected_packet_rate));
        let ack = Duration::from_millis(u64::from(self.ack_handler.acknowledge_timer_ms));
        let suppressed = self.ack_suppressed();
        let p = &mut self.production;
        if !retry {
            p.retries = 0;
        }
        p.changed = false;
        p.inhibit_until = now + Duration::from_millis(u64::from(p.inhibit_ms));
        p.due = now + epr;
        p.ack_deadline = if suppressed { Instant::MAX } else { now + ack };
    }

    /// A frame on our COS/cyclic acknowledge identifier (Group 2 message 2): zero length.
    #[inline(never)]
    pub(super) fn on_cos_ack(&mut self, data: &[u8], now: Instant) {
        if !self.cos.is_established() || self.ack_suppressed() || !data.is_empty() {
            self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
            return;
        }
        self.production.ack_deadline = Instant::MAX;
        self.production.retries = 0;
        self.cos.restart_timer(now);
    }
}
