//! The real board's CAN driver: bxCAN1 through the `bxcan` crate, timing and filters from the
//! board crate.
//!
//! [`Bxcan::start`] brings the controller up in three steps, all before the converter task runs
//! (in `init`, interrupts masked, time counted in [`POLL_STEP`]s of a busy wait):
//!
//! 1. the power-up self-test in silent loopback mode ([`board::self_test`]): on failure the
//!    controller is left in initialisation mode and the driver sends and receives nothing, for
//!    good (the node stays off the bus; the converter reports the major fault);
//! 2. with no data rate known (a board without switches, nothing stored), autobaud in silent
//!    mode ([`board::autobaud`]); it waits as long as the bus stays quiet;
//! 3. normal mode at the rate, the node's acceptance filters, the interrupts.
//!
//! The emulated board has no bxCAN and does none of this (`can_slcan`).
//!
//! Only one frame is in the mailboxes at a time: the bxCAN sends pending mailboxes by identifier
//! priority, and the fragments of one message share an identifier, so one-at-a-time is what keeps
//! them in order.

use crate::can::{Busy, CanDriver};
use board::autobaud::{Autobaud, Step};
use board::bit_timing;
use board::clocks;
use board::filters;
use board::hw::{self, BusState, Can1};
use board::self_test::{self, Failure, SelfTest, Verdict};
use bxcan::filter::{Mask16, Mask32};
use bxcan::{Fifo, Interrupts, StandardId};
use devicenet::slave::BaudRate;
use devicenet::{CanFrame, Duration, Instant, MacId};
use stm32f4xx_hal::nb;

/// One step of the start-up's polling loops: a busy wait of about 100 µs (the polling itself
/// adds a little), shorter than a frame at 500 kbit/s.
const POLL_STEP: Duration = Duration::from_micros(100);

/// bxCAN1 set up for one node, or kept off the bus after a failed self-test.
pub struct Bxcan {
    can: bxcan::Can<Can1>,
    /// The self-test passed and the controller is on the bus; otherwise nothing goes out.
    on_bus: bool,
}

/// The time of the start-up loops, in [`POLL_STEP`]s (interrupts are masked in `init`, so the
/// SysTick count does not run).
struct StepClock {
    now: Instant,
}

impl StepClock {
    /// Waits one step; the time after it.
    fn step(&mut self) -> Instant {
        cortex_m::asm::delay(clocks::SYSCLK_HZ / 10_000);
        self.now += POLL_STEP;
        self.now
    }
}

impl Bxcan {
    /// Self-tests the controller, finds the rate by autobaud when `autobaud` (else uses `baud`),
    /// and joins the bus with the acceptance filters for `mac` (module docs). The rate it joined
    /// at, or why the self-test failed (the driver then stays off the bus). Autobaud may listen
    /// for as long as the bus stays quiet: it calls `feed` (the watchdog's, `crate::trial`) at
    /// every step.
    pub fn start(
        can1: Can1,
        baud: BaudRate,
        autobaud: bool,
        mac: MacId,
        feed: impl Fn(),
    ) -> (Bxcan, Result<BaudRate, Failure>) {
        let mut clock = StepClock { now: Instant::ZERO };
        let mut can = bxcan::Can::builder(can1)
            .set_bit_timing(bit_timing::for_baud_rate(baud).btr())
            .set_loopback(true)
            .set_silent(true)
            .leave_disabled();
        // Every frame into FIFO 0 while testing and listening; `set_filters` replaces bank 0.
        can.modify_filters().enable_bank(filters::FILTER_BANK, Fifo::Fifo0, Mask32::accept_all());
        if let Err(failure) = run_self_test(&mut can, &mut clock) {
            // Through initialisation into sleep mode, and left there: nothing reaches CAN_TX.
            can.modify_config().leave_disabled();
            return (Bxcan { can, on_bus: false }, Err(failure));
        }
        let rate = if autobaud { find_rate(&mut can, &mut clock, feed) } else { baud };
        can.modify_config()
            .set_loopback(false)
            .set_silent(false)
            .set_bit_timing(bit_timing::for_baud_rate(rate).btr())
            .set_automatic_retransmit(true)
            .leave_disabled();
        set_filters(&mut can, mac);
        can.enable_interrupts(
            Interrupts::TRANSMIT_MAILBOX_EMPTY
                | Interrupts::FIFO0_MESSAGE_PENDING
                | Interrupts::FIFO1_MESSAGE_PENDING
                | Interrupts::ERROR,
        );
        hw::enable_can_error_interrupts();
        // Leaves initialisation mode once the bus has been idle for 11 bits; no need to wait.
        let _ = can.enable_non_blocking();
        // Bus-off is the converter's to end (bus-off interrupt setting), not the controller's.
        hw::disable_automatic_bus_off_management();
        (Bxcan { can, on_bus: true }, Ok(rate))
    }
}

/// The self-test in silent loopback mode ([`board::self_test`]): the test frame out, and back
/// within its bound.
fn run_self_test(can: &mut bxcan::Can<Can1>, clock: &mut StepClock) -> Result<(), Failure> {
    // In silent loopback the controller sees its own recessive output: it leaves initialisation
    // mode after 11 bit times.
    let started = clock.now;
    while can.enable_non_blocking().is_err() {
        if clock.step() > started + self_test::TIMEOUT {
            return Err(Failure::NotSent);
        }
    }
    let sent =
        self_test::test_frame().to_embedded::<bxcan::Frame>().is_some_and(|f| can.transmit(&f).is_ok());
    let mut test = SelfTest::start(sent, clock.now);
    loop {
        let verdict = match can.receive() {
            Ok(frame) => match CanFrame::from_embedded(&frame) {
                Ok(frame) => test.handle_frame(&frame, clock.now),
                Err(_) => Verdict::Failed(Failure::Corrupted),
            },
            Err(_) => test.handle_timeout(clock.step()),
        };
        match verdict {
            Verdict::Waiting => {}
            Verdict::Passed => return Ok(()),
            Verdict::Failed(failure) => return Err(failure),
        }
    }
}

/// Autobaud ([`board::autobaud`]): listens in silent mode, rate after rate, until one is found.
fn find_rate(can: &mut bxcan::Can<Can1>, clock: &mut StepClock, feed: impl Fn()) -> BaudRate {
    let mut autobaud = Autobaud::new(clock.now);
    // The receive error counter when listening at this rate started: it rises with each receive
    // error (and falls by one with each good frame, which is no error).
    let mut rec_at_start = listen_at(can, autobaud.rate());
    loop {
        feed();
        let now = clock.step();
        // Leaves initialisation mode after 11 recessive bits: at once on a quiet bus, between
        // frames on a busy one.
        let _ = can.enable_non_blocking();
        let (error, rec) = hw::can_take_error();
        let error_seen = error || rec > rec_at_start;
        let step = match can.receive() {
            // A frame (or several: an overrun); the FIFO holds nothing else in silent mode.
            Ok(_) | Err(nb::Error::Other(_)) => autobaud.handle_frame(error_seen, now),
            Err(nb::Error::WouldBlock) if error_seen => autobaud.handle_error(now),
            Err(nb::Error::WouldBlock) => autobaud.handle_timeout(now),
        };
        match step {
            Step::Listen => {}
            Step::ListenAt(rate) => rec_at_start = listen_at(can, rate),
            Step::Found(rate) => return rate,
        }
    }
}

/// Re-initialises the controller in silent mode at `rate`; the receive error counter then.
fn listen_at(can: &mut bxcan::Can<Can1>, rate: BaudRate) -> u8 {
    can.modify_config()
        .set_loopback(false)
        .set_silent(true)
        .set_bit_timing(bit_timing::for_baud_rate(rate).btr())
        .leave_disabled();
    // Frames of the previous rate are not this one's.
    while !matches!(can.receive(), Err(nb::Error::WouldBlock)) {}
    let _ = can.enable_non_blocking();
    let (_, rec) = hw::can_take_error();
    rec
}

/// Filter bank 0: every Group 2 message of `mac`, and every master's bit-strobe; bank 1: the
/// Offline Connection Set's two requests, data frames only ([`board::filters`]). Both banks in
/// 16-bit mask mode, so that one bank set-up serves both.
fn set_filters(can: &mut bxcan::Can<Can1>, mac: MacId) {
    let own = Mask16::frames_with_std_id(std_id(filters::own_group2(mac)), std_id(filters::OWN_MASK));
    let strobe = Mask16::frames_with_std_id(std_id(filters::STROBE_ID), std_id(filters::STROBE_MASK));
    let mut offline =
        Mask16::frames_with_std_id(std_id(filters::OFFLINE_REQUESTS[0]), std_id(filters::OFFLINE_MASK));
    offline.data_frames_only();
    let mut banks = can.modify_filters();
    banks.enable_bank(filters::FILTER_BANK, Fifo::Fifo0, [own, strobe]);
    banks.enable_bank(filters::OFFLINE_FILTER_BANK, Fifo::Fifo0, [offline, offline]);
}

/// An identifier or mask of the filter module, all within 11 bits by construction.
fn std_id(raw: u16) -> StandardId {
    StandardId::new(raw).unwrap_or(StandardId::ZERO)
}

impl CanDriver for Bxcan {
    fn try_transmit(&mut self, frame: &CanFrame) -> Result<(), Busy> {
        if !self.on_bus {
            // Off the bus after a failed self-test: taken and dropped.
            return Ok(());
        }
        if !self.can.is_transmitter_idle() {
            return Err(Busy);
        }
        let bx: bxcan::Frame = frame.to_embedded().ok_or(Busy)?;
        match self.can.transmit(&bx) {
            Ok(_) => Ok(()),
            Err(_) => Err(Busy),
        }
    }

    fn receive(&mut self) -> Option<CanFrame> {
        if !self.on_bus {
            return None;
        }
        loop {
            match self.can.receive() {
                // Only standard identifiers pass the filters; a conversion failure cannot
                // happen, but is dropped like any foreign frame.
                Ok(frame) => match CanFrame::from_embedded(&frame) {
                    Ok(f) => return Some(f),
                    Err(_) => continue,
                },
                Err(nb::Error::WouldBlock) => return None,
                // A FIFO overran: frames were lost, the next one is still valid.
                Err(nb::Error::Other(_)) => continue,
            }
        }
    }

    fn bus_state(&mut self) -> BusState {
        hw::can_bus_state()
    }

    fn clear_transmit_interrupt(&mut self) {
        self.can.clear_tx_interrupt();
    }

    fn set_mac(&mut self, mac: MacId) {
        set_filters(&mut self.can, mac);
    }

    fn restart(&mut self) {
        if !self.on_bus {
            return;
        }
        // Re-entering and leaving initialisation mode clears the error counters (RM0090
        // §32.4.2); the controller rejoins after 128 × 11 recessive bits.
        self.can.modify_config().leave_disabled();
        let _ = self.can.enable_non_blocking();
        hw::disable_automatic_bus_off_management();
    }
}
