//! The device heartbeat and shutdown messages (protocol §3.7, §II.5,
//! docs/src/reference/io-connections.md), sent on our Group 2 message 3 identifier with our own MAC in the
//! header, unfragmented, 8 bytes (AN, LIM).
//!
//! - Heartbeat: every Identity attribute 10 seconds while on-line (0 = off, the default; TOSH,
//!   LIM), `<MAC> CD 01 00 <state> <flags> <CCV LE16>`; not before on-line (UNCONFIRMED, II.8
//!   item 6).
//! - Shutdown: after the response to an Identity Reset, before the device resets:
//!   `<MAC> CE 01 00 01 00 04 00` (class 1, instance 1, code 4: LIM's "remote reset").

use super::{NetworkState, SlaveNode};
use crate::messages::{DeviceHeartbeat, DeviceShutdown, DeviceState, HeartbeatFlags};
use crate::objects::class;
use crate::time::{Duration, Instant};

/// The shutdown code LIM sends for a remote (Identity) reset (§II.5.2; its name is UNCONFIRMED).
const SHUTDOWN_REMOTE_RESET: u16 = 4;

/// The heartbeat's interval and its timer.
#[derive(Clone, Copy, Debug)]
pub(super) struct Heartbeat {
    /// Identity attribute 10, seconds; 0 = off.
    pub(super) interval: u8,
    /// When the next heartbeat is due ([`Instant::MAX`]: off).
    pub(super) at: Instant,
    /// An Identity Reset was answered: the shutdown message follows the response.
    pub(super) shutdown_pending: bool,
}

impl Heartbeat {
    pub(super) const fn new() -> Heartbeat {
        Heartbeat { interval: 0, at: Instant::MAX, shutdown_pending: false }
    }
}

impl SlaveNode {
    /// Sets the heartbeat interval (Identity attribute 10) and restarts its timer.
    pub(super) fn set_heartbeat_interval(&mut self, seconds: u8, now: Instant) {
        self.heartbeat.interval = seconds;
        self.restart_heartbeat(now);
    }

    /// The next heartbeat one interval from `now` (on-line, or a new interval).
    pub(super) fn restart_heartbeat(&mut self, now: Instant) {
        self.heartbeat.at = match self.heartbeat.interval {
            0 => Instant::MAX,
            s => now + Duration::from_secs(u64::from(s)),
        };
    }

    /// Sends the heartbeat when it is due; while not on-line it is skipped.
    pub(super) fn step_heartbeat(&mut self, now: Instant) {
        if now < self.heartbeat.at {
            return;
        }
        self.restart_heartbeat(now);
        if !matches!(self.network, NetworkState::Online) {
            return;
        }
        let s = &self.app_status;
        let mut flags = HeartbeatFlags::default();
        if s.major_unrecoverable_fault || s.minor_unrecoverable_fault {
            flags = flags.union(HeartbeatFlags::DEVICE_FAULT);
        }
        if self.io_timed_out() {
            // A connection time-out is a system fault (LIM, §II.5.1).
            flags = flags.union(HeartbeatFlags::SYSTEM_FAULT);
        }
        let heartbeat = DeviceHeartbeat {
            xid: false,
            mac: self.config.mac_id,
            identity_instance: 1,
            state: DeviceState::from(self.identity_state()),
            flags,
            // Identity attribute 9; 0 without one, as LIM sends (§II.5.1, §II.5.3).
            configuration_consistency: self.configuration_consistency.unwrap_or(0),
        };
        let id = self.response_id();
        self.queue_data(id, &heartbeat.emit());
    }

    /// Queues the shutdown message of an answered Identity Reset.
    pub(super) fn send_pending_shutdown(&mut self) {
        if core::mem::take(&mut self.heartbeat.shutdown_pending) {
            let shutdown = DeviceShutdown {
                xid: false,
                mac: self.config.mac_id,
                class: class::IDENTITY,
                instance: 1,
                shutdown_code: SHUTDOWN_REMOTE_RESET,
            };
            let id = self.response_id();
            self.queue_data(id, &shutdown.emit());
        }
    }
}
