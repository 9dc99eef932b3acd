//! Autobaud: finding the network's data rate by listening, for a board without switches that has
//! no data rate stored ([`crate::switches::resolve_stored`]). Sans-IO: the firmware's bxCAN
//! adapter (`slave-fw-firmware`'s `can_bxcan`, `board::hw::can_last_error`) feeds what the
//! controller saw and the time in, and [`Autobaud`] says which rate to listen at and when it
//! has found the network's.
//!
//! ## The rule
//!
//! 1. Listen in bxCAN **silent mode** (RM0090 §32.5.1: the controller receives but sends no bit,
//!    not even an acknowledgement or an error flag) at 125 kbit/s, then 250k, then 500k, then
//!    125k again, until a rate is found. A node must not disturb a running network while it does
//!    not know its rate; silent mode guarantees it.
//! 2. A rate is **found** when a complete frame is received there and the controller has seen
//!    no error at that rate since it started listening (the last error code, `CAN_ESR.LEC`,
//!    RM0090 §32.9.2, still "no error"). A frame at a wrong rate almost never passes the CRC and
//!    the stuffing rule; an error at the right rate (noise) only costs one more turn.
//! 3. A rate is **left** at the first error seen there (a wrong rate shows stuff, form or CRC
//!    errors at the first frame on the bus), or after [`DWELL`] with no frame (a quiet bus).
//! 4. Once found, the node re-initialises the controller in normal mode at that rate and joins
//!    (duplicate MAC ID check, protocol §7.1). Nothing is stored: the rate is stored only
//!    when the master sets it (DeviceNet object attribute 2), like a network-set MAC ID.
//!
//! Sources: WRC-CANX user manual (Western Reserve Controls / ProSoft, PUB 14.1, §5.1.4
//! "Autobaud Operation": an autobauding device does not send its duplicate MAC ID request at
//! power-up but waits for a valid message from a fixed-rate device and takes that message's
//! rate; with no such device it waits on); Contemporary Research TD960801-0MC manual §2.5.3
//! (determines the rate "by observing the traffic", 125/250/500 kbit/s); Rockwell Automation
//! XM-440 (GMSI10-UM009D-EN-P, DeviceNet object: autobaud by default, MAC ID default 63) and
//! 1738-ADNX (1738-UM001A-EN-P: modules "listen to communications on the DeviceNet network,
//! detect the rate of communication and automatically set their own baudrates"). That the
//! DeviceNet specification forbids any transmission, acknowledgements included, while the rate
//! is unknown is taken from the issue; the specification's own text was not retrieved.
//! The order of the rates, the "one error-free frame" criterion and [`DWELL`] are this crate's
//! choices: no source gives them.

use devicenet::slave::BaudRate;
use devicenet::{Duration, Instant};

/// How long a rate is listened to without a frame before the next is tried: 2 s, so that a
/// joining node's two duplicate MAC ID requests, 1 s apart (protocol §7.1), fall in one
/// dwell, while a bus with a scanning master (frames every few milliseconds) is found at once.
pub const DWELL: Duration = Duration::from_millis(2000);

/// The rates in the order they are tried.
pub const RATES: [BaudRate; 3] = [BaudRate::Kbps125, BaudRate::Kbps250, BaudRate::Kbps500];

/// What the controller should do next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Step {
    /// Keep listening at the current rate.
    Listen,
    /// Re-initialise the controller in silent mode at this rate (the previous one is left).
    ListenAt(BaudRate),
    /// The network's rate: re-initialise in normal mode at it and join.
    Found(BaudRate),
}

/// The autobaud state machine (module docs). Call [`Autobaud::handle_frame`] for each frame
/// received, [`Autobaud::handle_error`] when the controller reports an error, and
/// [`Autobaud::handle_timeout`] at [`Autobaud::poll_at`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Autobaud {
    index: usize,
    since: Instant,
    found: bool,
}

impl Autobaud {
    /// Starts listening at 125 kbit/s at `now`.
    pub const fn new(now: Instant) -> Autobaud {
        Autobaud { index: 0, since: now, found: false }
    }

    /// The rate being listened to.
    pub const fn rate(&self) -> BaudRate {
        RATES[self.index % RATES.len()]
    }

    /// When [`Autobaud::handle_timeout`] must run; `None` once found.
    pub fn poll_at(&self) -> Option<Instant> {
        (!self.found).then(|| self.since + DWELL)
    }

    /// A complete frame was received at the current rate; `error_seen` is whether the controller
    /// recorded an error (`LEC` not "no error") since it started listening at this rate.
    pub fn handle_frame(&mut self, error_seen: bool, now: Instant) -> Step {
        if self.found {
            return Step::Found(self.rate());
        }
        if error_seen {
            return self.next(now);
        }
        self.found = true;
        Step::Found(self.rate())
    }

    /// The controller reported a bus error at the current rate: the next rate.
    pub fn handle_error(&mut self, now: Instant) -> Step {
        if self.found {
            return Step::Found(self.rate());
        }
        self.next(now)
    }

    /// The dwell is over without a frame: the next rate; before it, keep listening.
    pub fn handle_timeout(&mut self, now: Instant) -> Step {
        match self.poll_at() {
            None => Step::Found(self.rate()),
            Some(at) if now >= at => self.next(now),
            Some(_) => Step::Listen,
        }
    }

    fn next(&mut self, now: Instant) -> Step {
        self.index = (self.index + 1) % RATES.len();
        self.since = now;
        Step::ListenAt(self.rate())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    #[test]
    fn starts_at_125k_and_a_clean_frame_finds_the_rate() {
        let mut a = Autobaud::new(ms(0));
        assert_eq!(a.rate(), BaudRate::Kbps125);
        assert_eq!(a.handle_timeout(ms(10)), Step::Listen);
        assert_eq!(a.handle_frame(false, ms(20)), Step::Found(BaudRate::Kbps125));
        assert_eq!(a.poll_at(), None, "nothing more to wait for");
    }

    #[test]
    fn an_error_moves_on_at_once_in_order_and_cycles() {
        let mut a = Autobaud::new(ms(0));
        assert_eq!(a.handle_error(ms(5)), Step::ListenAt(BaudRate::Kbps250));
        assert_eq!(a.handle_error(ms(6)), Step::ListenAt(BaudRate::Kbps500));
        assert_eq!(a.handle_error(ms(7)), Step::ListenAt(BaudRate::Kbps125));
        assert_eq!(a.poll_at(), Some(ms(7) + DWELL), "the dwell restarts with each rate");
    }

    #[test]
    fn a_frame_after_an_error_at_the_same_rate_does_not_count() {
        let mut a = Autobaud::new(ms(0));
        assert_eq!(a.handle_frame(true, ms(3)), Step::ListenAt(BaudRate::Kbps250));
        assert_eq!(a.handle_frame(false, ms(4)), Step::Found(BaudRate::Kbps250));
    }

    #[test]
    fn a_quiet_bus_cycles_through_the_rates_each_dwell() {
        let mut a = Autobaud::new(ms(0));
        let mut seen = std::vec::Vec::new();
        for turn in 1..=4 {
            assert_eq!(a.poll_at(), Some(ms(turn * 2000)));
            assert_eq!(a.handle_timeout(ms(turn * 2000 - 1)), Step::Listen);
            seen.push(a.handle_timeout(ms(turn * 2000)));
        }
        use BaudRate::*;
        let expected = [Kbps250, Kbps500, Kbps125, Kbps250].map(Step::ListenAt);
        assert_eq!(seen, expected);
    }

    #[test]
    fn found_stays_found() {
        let mut a = Autobaud::new(ms(0));
        a.handle_error(ms(1));
        assert_eq!(a.handle_frame(false, ms(2)), Step::Found(BaudRate::Kbps250));
        assert_eq!(a.handle_error(ms(3)), Step::Found(BaudRate::Kbps250));
        assert_eq!(a.handle_timeout(ms(99_999)), Step::Found(BaudRate::Kbps250));
    }
}
