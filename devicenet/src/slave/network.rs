//! Network access (protocol §7.1, §7.2): the duplicate MAC ID check at power-on and after
//! a bus-off reset, answering other nodes' checks for our MAC ID, and Communication Faulted.
//!
//! The check sends two requests [`DUP_MAC_INTERVAL`] apart and goes on-line one interval after
//! the second; any check for our MAC ID heard meanwhile means another node has it.

use super::{Event, SlaveNode};
use crate::id::{Group2Message, Identifier};
use crate::messages::DuplicateMacCheck;
use crate::time::{Duration, Instant};

/// Time between the two duplicate MAC ID requests, and from the second to on-line (protocol §7.1).
pub const DUP_MAC_INTERVAL: Duration = Duration::from_secs(1);

/// Why the node is in the Communication Faulted state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FaultReason {
    /// Another node uses our MAC ID (protocol §7.1).
    DuplicateMacId,
    /// The CAN controller went bus-off with BOI = 0 (protocol §7.2).
    BusOff,
}

/// Network access state (protocol §7.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NetworkState {
    /// Before [`SlaveNode::power_on`]: the node neither sends nor receives.
    PoweredOff,
    /// Duplicate MAC ID check in progress: `requests_sent` of 2 sent, next step at `deadline`.
    DuplicateMacCheck {
        /// Requests sent so far (1 or 2).
        requests_sent: u8,
        /// When the next request is sent, or the node goes on-line.
        deadline: Instant,
    },
    /// On-line.
    Online,
    /// Communication Faulted: silent until reset (protocol §7.4).
    CommunicationFaulted(FaultReason),
}

impl SlaveNode {
    /// Starts the duplicate MAC ID check by queueing the first request (protocol §7.1).
    ///
    /// A node whose application reports a major unrecoverable fault (its own hardware failed, e.g.
    /// the board's CAN self-test) never starts it: it stays off the network, not on-line, with the
    /// Network Status off and the Module Status red (protocol §7.3). This is the project's rule
    /// (issue 26: "the node stays off the bus"); no public source says what network access a
    /// faulted device must attempt.
    pub(super) fn start_duplicate_mac_check(&mut self, now: Instant) {
        if self.app_status.major_unrecoverable_fault {
            self.network = NetworkState::DuplicateMacCheck { requests_sent: 0, deadline: Instant::MAX };
            return;
        }
        self.send_duplicate_mac(false);
        self.network = NetworkState::DuplicateMacCheck { requests_sent: 1, deadline: now + DUP_MAC_INTERVAL };
    }

    /// The duplicate MAC ID check's timer: the second request, then on-line.
    pub(super) fn step_duplicate_mac_check(&mut self, now: Instant) {
        if let NetworkState::DuplicateMacCheck { requests_sent, deadline } = self.network {
            if now >= deadline {
                if self.app_status.major_unrecoverable_fault {
                    // Faulted during the check: no further request, never on-line.
                    self.network = NetworkState::DuplicateMacCheck { requests_sent, deadline: Instant::MAX };
                } else if requests_sent < 2 {
                    self.send_duplicate_mac(false);
                    self.network = NetworkState::DuplicateMacCheck {
                        requests_sent: 2,
                        deadline: deadline + DUP_MAC_INTERVAL,
                    };
                } else {
                    self.network = NetworkState::Online;
                    self.push_event(Event::Online);
                    self.restart_heartbeat(now);
                }
            }
        }
    }

    /// When the duplicate MAC ID check's next step is due ([`Instant::MAX`]: it does not run).
    pub(super) fn duplicate_mac_deadline(&self) -> Instant {
        match self.network {
            NetworkState::DuplicateMacCheck { deadline, .. } => deadline,
            _ => Instant::MAX,
        }
    }

    /// Queues our duplicate MAC ID check request or response (protocol §3.5).
    fn send_duplicate_mac(&mut self, response: bool) {
        let msg = DuplicateMacCheck {
            response,
            port: self.config.port,
            vendor_id: self.config.identity.vendor_id,
            serial_number: self.config.identity.serial_number,
        };
        let id = Identifier::group2(self.config.mac_id, Group2Message::DuplicateMacCheck);
        self.queue_data(id, &msg.emit());
    }

    /// A duplicate MAC ID check for our MAC ID from another node.
    pub(super) fn on_duplicate_mac(&mut self, data: &[u8]) {
        let Ok(check) = DuplicateMacCheck::parse(data) else { return };
        match self.network {
            // Any request or response for our MAC during our own check: someone else has it.
            NetworkState::DuplicateMacCheck { .. } => self.fault(FaultReason::DuplicateMacId),
            NetworkState::Online if !check.response => self.send_duplicate_mac(true),
            NetworkState::Online => self.fault(FaultReason::DuplicateMacId),
            NetworkState::PoweredOff | NetworkState::CommunicationFaulted(_) => {}
        }
    }
}
