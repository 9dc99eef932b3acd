//! The real board's CAN driver: bxCAN1 through the `bxcan` crate, timing and filters from the
//! board crate.
//!
//! Only one frame is in the mailboxes at a time: the bxCAN sends pending mailboxes by identifier
//! priority, and the fragments of one message share an identifier, so one-at-a-time is what keeps
//! them in order.

use crate::can::{Busy, CanDriver};
use board::bit_timing;
use board::filters;
use board::hw::{self, BusState, Can1};
use bxcan::filter::Mask16;
use bxcan::{Fifo, Interrupts, StandardId};
use devicenet::slave::BaudRate;
use devicenet::{CanFrame, MacId};
use stm32f4xx_hal::nb;

/// bxCAN1 set up for one node.
pub struct Bxcan {
    can: bxcan::Can<Can1>,
}

impl Bxcan {
    /// Configures timing for `baud`, the acceptance filters for `mac` into FIFO 0, the
    /// interrupts, and joins the bus (without waiting for it to go idle).
    pub fn new(can1: Can1, baud: BaudRate, mac: MacId) -> Bxcan {
        let mut can = bxcan::Can::builder(can1)
            .set_bit_timing(bit_timing::for_baud_rate(baud).btr())
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
        Bxcan { can }
    }
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
        // Re-entering and leaving initialisation mode clears the error counters (RM0090
        // §32.4.2); the controller rejoins after 128 × 11 recessive bits.
        self.can.modify_config().leave_disabled();
        let _ = self.can.enable_non_blocking();
    }
}
