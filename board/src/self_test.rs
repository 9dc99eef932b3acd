//! The power-up self-test of the CAN path (real boards): before the node goes on the bus, the
//! bxCAN sends [`test_frame`] in **silent loopback** mode (RM0090 §32.5.3: the transmitter's
//! output is looped back to its receiver inside the chip and nothing reaches the CAN_TX pin, so
//! the test never disturbs the network) and must receive it back, unchanged, within
//! [`TIMEOUT`]. A failure is a major unrecoverable fault: the converter reports it in the
//! Identity status (bit 11) and shows Module Status solid red (protocol §6.2, §7.3), and
//! the node stays off the bus.
//!
//! What it proves: the CAN1 clock, the controller's leaving of initialisation mode, its bit
//! timing and the mailbox/FIFO path work. What it does not: the transceiver and the cable (in
//! loopback the controller does not see its RX pin).
//!
//! Sans-IO: the firmware's bxCAN adapter (`slave-fw-firmware`'s `can_bxcan`) sends the frame,
//! polls the FIFO and hands what came back (or nothing) with the time to [`SelfTest`].

use devicenet::{CanFrame, CanId, Duration, Instant};

/// The test frame: identifier 0x7FF (not a DeviceNet Group 1–4 identifier in use; it never leaves
/// the chip) and a pattern that sets and clears every bit position of each data byte pair.
pub const TEST_FRAME_ID: u16 = 0x7FF;
/// The test frame's data.
pub const TEST_DATA: [u8; 8] = [0x55, 0xAA, 0x00, 0xFF, 0x0F, 0xF0, 0x3C, 0xC3];

/// How long to wait for the frame to come back: a 8-byte frame takes at most 135 bits, about
/// 1.1 ms at 125 kbit/s; 10 ms leaves room for leaving initialisation mode (11 recessive bits).
pub const TIMEOUT: Duration = Duration::from_millis(10);

/// The test frame ([`TEST_FRAME_ID`], [`TEST_DATA`]).
pub fn test_frame() -> CanFrame {
    const ID: CanId = match CanId::new(TEST_FRAME_ID) {
        Some(id) => id,
        None => panic!("the test frame's identifier is 11 bits"),
    };
    match CanFrame::new(ID, &TEST_DATA) {
        Ok(frame) => frame,
        // 8 bytes always fit (a constant, not input).
        Err(_) => unreachable!(),
    }
}

/// Why the self-test failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Failure {
    /// The controller did not take the frame (no empty mailbox, or it never left initialisation).
    NotSent,
    /// Nothing came back within [`TIMEOUT`].
    NothingBack,
    /// A frame came back that is not the one sent.
    Corrupted,
}

/// The verdict so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Still waiting for the frame.
    Waiting,
    /// The frame came back: the node may go on the bus.
    Passed,
    /// A major unrecoverable fault: the node stays off the bus.
    Failed(Failure),
}

/// One run of the self-test, from the moment the frame was handed to the controller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SelfTest {
    sent_at: Instant,
    verdict: Verdict,
}

impl SelfTest {
    /// The test once the frame went to the controller at `now` (`sent`: it took it).
    pub fn start(sent: bool, now: Instant) -> SelfTest {
        let verdict = if sent { Verdict::Waiting } else { Verdict::Failed(Failure::NotSent) };
        SelfTest { sent_at: now, verdict }
    }

    /// A frame was received (in loopback: the only one that can be).
    pub fn handle_frame(&mut self, frame: &CanFrame, now: Instant) -> Verdict {
        if self.verdict == Verdict::Waiting {
            self.verdict = if now > self.sent_at + TIMEOUT {
                Verdict::Failed(Failure::NothingBack)
            } else if *frame == test_frame() {
                Verdict::Passed
            } else {
                Verdict::Failed(Failure::Corrupted)
            };
        }
        self.verdict
    }

    /// Nothing (more) received at `now`.
    pub fn handle_timeout(&mut self, now: Instant) -> Verdict {
        if self.verdict == Verdict::Waiting && now > self.sent_at + TIMEOUT {
            self.verdict = Verdict::Failed(Failure::NothingBack);
        }
        self.verdict
    }

    /// The verdict so far.
    pub fn verdict(&self) -> Verdict {
        self.verdict
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    #[test]
    fn the_frame_back_in_time_passes() {
        let mut t = SelfTest::start(true, ms(100));
        assert_eq!(t.handle_timeout(ms(105)), Verdict::Waiting);
        assert_eq!(t.handle_frame(&test_frame(), ms(106)), Verdict::Passed);
        assert_eq!(t.handle_timeout(ms(1000)), Verdict::Passed, "a verdict is final");
    }

    #[test]
    fn nothing_back_within_the_bound_fails() {
        let mut t = SelfTest::start(true, ms(100));
        assert_eq!(t.handle_timeout(ms(110)), Verdict::Waiting, "the bound itself is still in time");
        assert_eq!(t.handle_timeout(ms(111)), Verdict::Failed(Failure::NothingBack));
        assert_eq!(t.handle_frame(&test_frame(), ms(112)), Verdict::Failed(Failure::NothingBack));
    }

    #[test]
    fn a_late_frame_fails() {
        let mut t = SelfTest::start(true, ms(0));
        assert_eq!(t.handle_frame(&test_frame(), ms(11)), Verdict::Failed(Failure::NothingBack));
    }

    #[test]
    fn another_frame_fails() {
        let mut t = SelfTest::start(true, ms(0));
        let mut data = TEST_DATA;
        data[3] ^= 0x10;
        let wrong = CanFrame::new(CanId::new(TEST_FRAME_ID).unwrap(), &data).unwrap();
        assert_eq!(t.handle_frame(&wrong, ms(1)), Verdict::Failed(Failure::Corrupted));
    }

    #[test]
    fn a_frame_the_controller_did_not_take_fails_at_once() {
        assert_eq!(SelfTest::start(false, ms(0)).verdict(), Verdict::Failed(Failure::NotSent));
    }

    #[test]
    fn the_test_frame_is_what_the_constants_say() {
        let f = test_frame();
        assert_eq!((f.id().as_raw(), f.data()), (TEST_FRAME_ID, &TEST_DATA[..]));
    }
}
