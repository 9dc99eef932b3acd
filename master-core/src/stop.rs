//! A request to stop, from a signal handler or another thread: the [`Session`](crate::session::Session)
//! checks it while it waits on the bus and ends the operation with
//! [`MasterError::Interrupted`](crate::error::MasterError::Interrupted), so the command that ran it
//! can still flush what it recorded and release the device.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// SIGINT (Ctrl-C).
pub const SIGINT: i32 = 2;
/// SIGTERM.
pub const SIGTERM: i32 = 15;

/// A shared stop request: 0 while none, else the number of the signal that asked.
#[derive(Clone, Debug, Default)]
pub struct Stop(Arc<AtomicUsize>);

impl Stop {
    /// No stop requested yet.
    pub fn new() -> Stop {
        Stop::default()
    }

    /// The flag itself, for `signal_hook::flag::register_usize`.
    pub fn flag(&self) -> Arc<AtomicUsize> {
        Arc::clone(&self.0)
    }

    /// Asks for a stop on behalf of `signal`.
    pub fn request(&self, signal: i32) {
        self.0.store(usize::try_from(signal).unwrap_or(1).max(1), Ordering::SeqCst);
    }

    /// The signal that asked for a stop, if one did.
    pub fn requested(&self) -> Option<i32> {
        match self.0.load(Ordering::SeqCst) {
            0 => None,
            n => Some(i32::try_from(n).unwrap_or(i32::MAX)),
        }
    }
}

/// `SIGINT`, `SIGTERM` or `signal N`.
pub fn signal_name(signal: i32) -> String {
    match signal {
        SIGINT => "SIGINT".into(),
        SIGTERM => "SIGTERM".into(),
        n => format!("signal {n}"),
    }
}

/// The exit status of a program stopped by `signal`: 128 + the signal number (130 for SIGINT, 143
/// for SIGTERM), as shells report it.
pub fn exit_status(signal: i32) -> u8 {
    u8::try_from(128 + signal.clamp(0, 127)).unwrap_or(128)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_is_seen_by_every_clone() {
        let stop = Stop::new();
        let seen = stop.clone();
        assert_eq!(seen.requested(), None);
        stop.request(SIGTERM);
        assert_eq!(seen.requested(), Some(SIGTERM));
        assert_eq!(exit_status(SIGINT), 130);
        assert_eq!(exit_status(SIGTERM), 143);
        assert_eq!(signal_name(SIGINT), "SIGINT");
    }
}
