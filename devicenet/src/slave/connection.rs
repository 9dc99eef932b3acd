//! Connection object instances of the Predefined Master/Slave Connection Set: 1 explicit, 2 poll,
//! 3 bit-strobe and 4 change-of-state/cyclic (protocol §5, §II.1, §II.2).
//!
//! A [`Connection`] holds the state, expected packet rate, watchdog timeout action and the
//! inactivity deadline (4 × EPR, protocol §5.3). Time-driven transitions happen in
//! [`Connection::expire`]; the node decides what an expiry means for the other connection (deferred
//! delete, protocol §5.2).

use crate::time::{Duration, Instant};

/// Connection object state, attribute 1 (protocol §5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConnectionState {
    /// 0: not allocated.
    NonExistent,
    /// 1: allocated, waiting for its expected packet rate.
    Configuring,
    /// 2: waiting for a connection ID (not used in the predefined set).
    WaitingForConnectionId,
    /// 3: established.
    Established,
    /// 4: the inactivity watchdog expired (I/O, action 0).
    TimedOut,
    /// 5: explicit connection whose watchdog expired while I/O connections exist (action 3).
    DeferredDelete,
}

impl ConnectionState {
    /// The attribute value.
    pub const fn attribute_value(self) -> u8 {
        match self {
            ConnectionState::NonExistent => 0,
            ConnectionState::Configuring => 1,
            ConnectionState::WaitingForConnectionId => 2,
            ConnectionState::Established => 3,
            ConnectionState::TimedOut => 4,
            ConnectionState::DeferredDelete => 5,
        }
    }
}

/// Watchdog timeout action, attribute 12 (protocol §5.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WatchdogAction {
    /// 0: transition to timed out (I/O only; the I/O default).
    TransitionToTimedOut,
    /// 1: auto delete (the explicit default).
    AutoDelete,
    /// 2: auto reset (I/O only).
    AutoReset,
    /// 3: deferred delete (explicit only).
    DeferredDelete,
}

impl WatchdogAction {
    /// The attribute value.
    pub const fn attribute_value(self) -> u8 {
        match self {
            WatchdogAction::TransitionToTimedOut => 0,
            WatchdogAction::AutoDelete => 1,
            WatchdogAction::AutoReset => 2,
            WatchdogAction::DeferredDelete => 3,
        }
    }
}

/// Which predefined connection an instance is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConnectionKind {
    /// Instance 1.
    Explicit,
    /// Instance 2.
    Poll,
    /// Instance 3: bit-strobe (protocol §II.1).
    Strobe,
    /// Instance 4: change of state or cyclic (protocol §II.2).
    ChangeOfState,
}

impl ConnectionKind {
    /// The Connection object instance number.
    pub const fn instance(self) -> u16 {
        match self {
            ConnectionKind::Explicit => 1,
            ConnectionKind::Poll => 2,
            ConnectionKind::Strobe => 3,
            ConnectionKind::ChangeOfState => 4,
        }
    }

    /// The watchdog action values legal for this kind (protocol §5.4).
    pub const fn parse_action(self, value: u8) -> Option<WatchdogAction> {
        match (self, value) {
            (ConnectionKind::Explicit, 1) => Some(WatchdogAction::AutoDelete),
            (ConnectionKind::Explicit, 3) => Some(WatchdogAction::DeferredDelete),
            // Every I/O connection takes the poll connection's actions (protocol §5.4, §II.1.1, §II.2.2).
            (ConnectionKind::Explicit, _) => None,
            (_, 0) => Some(WatchdogAction::TransitionToTimedOut),
            (_, 1) => Some(WatchdogAction::AutoDelete),
            (_, 2) => Some(WatchdogAction::AutoReset),
            _ => None,
        }
    }
}

/// The default explicit EPR, 2500 ms (protocol §5.3).
pub const EXPLICIT_DEFAULT_EPR_MS: u16 = 2500;
/// The largest EPR accepted (JB rejects larger values to avoid overflow after rounding).
pub const MAX_EPR_MS: u16 = 65000;

/// What happened when a connection's inactivity timer expired.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Expiry {
    /// Nothing expired.
    None,
    /// The connection went to Timed Out.
    TimedOut,
    /// The connection must be deleted.
    Delete,
    /// The connection asks for deferred delete (the node decides between 5 and delete).
    DeferredDelete,
    /// Auto reset: the timer was restarted.
    Reset,
}

/// One Connection object instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Connection {
    /// Which instance this is.
    pub kind: ConnectionKind,
    /// Attribute 1.
    pub state: ConnectionState,
    /// Attribute 9, in ms (0 disables the inactivity timer).
    pub expected_packet_rate: u16,
    /// Attribute 12.
    pub watchdog_action: WatchdogAction,
    /// When the inactivity watchdog fires; [`Instant::MAX`] when it is not armed.
    pub deadline: Instant,
}

impl Connection {
    /// A non-existent instance of `kind`.
    pub const fn new(kind: ConnectionKind) -> Connection {
        Connection {
            kind,
            state: ConnectionState::NonExistent,
            expected_packet_rate: 0,
            watchdog_action: match kind {
                ConnectionKind::Explicit => WatchdogAction::AutoDelete,
                _ => WatchdogAction::TransitionToTimedOut,
            },
            deadline: Instant::MAX,
        }
    }

    /// `true` unless the instance is non-existent.
    pub const fn exists(&self) -> bool {
        !matches!(self.state, ConnectionState::NonExistent)
    }

    /// `true` when established.
    pub const fn is_established(&self) -> bool {
        matches!(self.state, ConnectionState::Established)
    }

    /// Allocation (protocol §5.2): explicit becomes established with EPR 2500 ms, the I/O connections
    /// configuring with EPR 0 (§II.1.1, §II.2.3).
    pub fn allocate(&mut self, now: Instant) {
        *self = Connection::new(self.kind);
        match self.kind {
            ConnectionKind::Explicit => {
                self.state = ConnectionState::Established;
                self.expected_packet_rate = EXPLICIT_DEFAULT_EPR_MS;
                self.restart_timer(now);
            }
            _ => self.state = ConnectionState::Configuring,
        }
    }

    /// Release or delete: back to non-existent with defaults.
    pub fn delete(&mut self) {
        *self = Connection::new(self.kind);
    }

    /// The inactivity time, 4 × EPR (protocol §5.3); `None` when the EPR is 0.
    pub fn inactivity_time(&self) -> Option<Duration> {
        match self.expected_packet_rate {
            0 => None,
            epr => Some(Duration::from_millis(4 * u64::from(epr))),
        }
    }

    /// Restarts the inactivity timer (a message was consumed, or the EPR changed).
    pub fn restart_timer(&mut self, now: Instant) {
        self.deadline = self.inactivity_time().map_or(Instant::MAX, |t| now + t);
    }

    /// Sets the EPR (already rounded) and restarts the timer; a configuring connection becomes
    /// established (protocol §5.2).
    pub fn set_expected_packet_rate(&mut self, epr: u16, now: Instant) {
        self.expected_packet_rate = epr;
        if self.state == ConnectionState::Configuring {
            self.state = ConnectionState::Established;
        }
        self.restart_timer(now);
    }

    /// Runs the watchdog at `now` (protocol §5.2 row "Inactivity timer expiry").
    pub fn expire(&mut self, now: Instant) -> Expiry {
        if now < self.deadline {
            return Expiry::None;
        }
        self.deadline = Instant::MAX;
        match self.watchdog_action {
            WatchdogAction::TransitionToTimedOut => {
                self.state = ConnectionState::TimedOut;
                Expiry::TimedOut
            }
            WatchdogAction::AutoDelete => Expiry::Delete,
            WatchdogAction::AutoReset => {
                self.restart_timer(now);
                Expiry::Reset
            }
            WatchdogAction::DeferredDelete => Expiry::DeferredDelete,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::explicit_auto_delete(ConnectionKind::Explicit, 1, Some(WatchdogAction::AutoDelete))]
    #[case::explicit_deferred(ConnectionKind::Explicit, 3, Some(WatchdogAction::DeferredDelete))]
    #[case::explicit_timed_out_invalid(ConnectionKind::Explicit, 0, None)]
    #[case::explicit_auto_reset_invalid(ConnectionKind::Explicit, 2, None)]
    #[case::poll_timed_out(ConnectionKind::Poll, 0, Some(WatchdogAction::TransitionToTimedOut))]
    #[case::poll_auto_delete(ConnectionKind::Poll, 1, Some(WatchdogAction::AutoDelete))]
    #[case::poll_auto_reset(ConnectionKind::Poll, 2, Some(WatchdogAction::AutoReset))]
    #[case::poll_deferred_invalid(ConnectionKind::Poll, 3, None)]
    #[case::out_of_range(ConnectionKind::Poll, 4, None)]
    fn watchdog_action_legality(
        #[case] kind: ConnectionKind,
        #[case] v: u8,
        #[case] a: Option<WatchdogAction>,
    ) {
        assert_eq!(kind.parse_action(v), a);
        if let Some(a) = a {
            assert_eq!(a.attribute_value(), v);
        }
    }

    #[test]
    fn explicit_is_instance_1_and_poll_instance_2() {
        // The Predefined Master/Slave Connection Set's instances (protocol §5).
        assert_eq!(ConnectionKind::Explicit.instance(), 1);
        assert_eq!(ConnectionKind::Poll.instance(), 2);
    }

    #[test]
    fn explicit_allocation_arms_ten_seconds() {
        let mut c = Connection::new(ConnectionKind::Explicit);
        c.allocate(Instant::from_secs(1));
        assert_eq!(c.state, ConnectionState::Established);
        assert_eq!(c.expected_packet_rate, 2500);
        assert_eq!(c.deadline, Instant::from_secs(11));
    }

    #[test]
    fn poll_configuring_until_epr() {
        let mut c = Connection::new(ConnectionKind::Poll);
        c.allocate(Instant::ZERO);
        assert_eq!(c.state, ConnectionState::Configuring);
        assert_eq!(c.deadline, Instant::MAX);
        c.set_expected_packet_rate(100, Instant::from_secs(1));
        assert_eq!(c.state, ConnectionState::Established);
        assert_eq!(c.deadline, Instant::from_millis(1400));
    }

    #[rstest]
    #[case::timed_out(0, Expiry::TimedOut, ConnectionState::TimedOut)]
    #[case::auto_delete(1, Expiry::Delete, ConnectionState::Established)]
    #[case::auto_reset(2, Expiry::Reset, ConnectionState::Established)]
    fn poll_expiry(#[case] action: u8, #[case] expiry: Expiry, #[case] state: ConnectionState) {
        let mut c = Connection::new(ConnectionKind::Poll);
        c.allocate(Instant::ZERO);
        c.watchdog_action = ConnectionKind::Poll.parse_action(action).unwrap();
        c.set_expected_packet_rate(100, Instant::ZERO);
        assert_eq!(c.expire(Instant::from_millis(399)), Expiry::None);
        assert_eq!(c.expire(Instant::from_millis(400)), expiry);
        assert_eq!(c.state, state);
        if expiry == Expiry::Reset {
            assert_eq!(c.deadline, Instant::from_millis(800));
        }
    }

    #[test]
    fn epr_zero_disables_timer() {
        let mut c = Connection::new(ConnectionKind::Poll);
        c.allocate(Instant::ZERO);
        c.set_expected_packet_rate(0, Instant::ZERO);
        assert_eq!(c.state, ConnectionState::Established);
        assert_eq!(c.deadline, Instant::MAX);
        assert_eq!(c.expire(Instant::from_secs(1_000_000)), Expiry::None);
    }
}
