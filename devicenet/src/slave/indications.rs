//! The Module and Network Status LEDs (protocol §7.3): what each shows for the node's
//! state, when the indication last changed (the flashing phase), and the power-up test.

use super::{NetworkState, SlaveNode};
use crate::led::{self, Indication, Leds};
use crate::time::Instant;

impl SlaveNode {
    /// What the Module and Network Status LEDs show now, including the power-up test
    /// (protocol §7.3).
    // Out of line: inlined into the firmware's async task it costs some 25 bytes more of flash.
    #[inline(never)]
    pub fn leds(&self, now: Instant) -> Leds {
        if let Some(on) = self.powered_on_at {
            if let Some(test) = led::self_test(now - on) {
                return test;
            }
        }
        Leds {
            module: self.module_indication.0.lit(self.module_indication.1, now),
            network: self.network_indication.0.lit(self.network_indication.1, now),
        }
    }

    /// The Network Status indication (protocol §7.3).
    pub fn network_indication(&self) -> Indication {
        match self.network {
            NetworkState::PoweredOff | NetworkState::DuplicateMacCheck { .. } => Indication::Off,
            // A faulted node that accepted an Identify flashes red/green (RA 1734-IN055, §II.0).
            NetworkState::CommunicationFaulted(_) if self.offline.identified => Indication::FlashingRedGreen,
            NetworkState::CommunicationFaulted(_) => Indication::Red,
            NetworkState::Online if self.io_timed_out() => Indication::FlashingRed,
            NetworkState::Online if self.master.is_some() => Indication::Green,
            NetworkState::Online => Indication::FlashingGreen,
        }
    }

    /// The Module Status indication (protocol §7.3).
    pub fn module_indication(&self) -> Indication {
        let s = &self.app_status;
        if matches!(self.network, NetworkState::PoweredOff) {
            Indication::Off
        } else if s.major_unrecoverable_fault || s.major_recoverable_fault {
            Indication::Red
        } else if s.minor_recoverable_fault || s.minor_unrecoverable_fault {
            Indication::FlashingRed
        } else if s.standby {
            Indication::FlashingGreen
        } else {
            Indication::Green
        }
    }

    /// Records the instant an indication changes, so flashing starts in phase.
    pub(super) fn update_indications(&mut self, now: Instant) {
        let net = self.network_indication();
        if net != self.network_indication.0 {
            self.network_indication = (net, now);
        }
        let module = self.module_indication();
        if module != self.module_indication.0 {
            self.module_indication = (module, now);
        }
    }
}
