//! The emulated board's CAN driver: SLCAN lines on USART1 (QEMU has no bxCAN).
//!
//! The host side is a serial CAN adapter's user (`dnet-master --bus slcan:PTY`); the codec and
//! the adapter state machine are `can_io::slcan` (the one codec, shared with the host). Host lines are handled in the USART1 receive
//! interrupt: commands are answered at once, frames for this node (the same acceptance list as the
//! bxCAN filter) go to the node task. While the host has not opened the channel the transmitter
//! reports [`Busy`], as a bxCAN mailbox stays pending on a bus with no other node. The channel
//! state survives the board's own reset (an Identity Reset), as a real adapter's would: it is kept
//! in `board::hw::retained`.

use crate::can::{Busy, CanDriver};
use board::filters;
use board::hw::BusState;
use board::hw::{SerialEvent, Usart};
use can_io::slcan::{self, Adapter, LineBuffer};
use devicenet::{CanFrame, MacId};
use stm32f4xx_hal::pac::USART1;

/// The SLCAN "adapter" on USART1.
pub struct Slcan {
    serial: Usart<USART1>,
    lines: LineBuffer,
    adapter: Adapter,
    mac: MacId,
}

impl Slcan {
    /// The adapter for node `mac`, closed, with the receive interrupt on.
    pub fn new(mut serial: Usart<USART1>, mac: MacId) -> Slcan {
        serial.listen(SerialEvent::RxNotEmpty);
        // The adapter is not reset with the board: after an Identity Reset the host's open
        // channel stays open (board::hw::retained; closed after a power-on).
        let adapter = board::hw::retained::load().map_or(Adapter::new(), Adapter::from_bits);
        Slcan { serial, lines: LineBuffer::new(), adapter, mac }
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_byte(b);
        }
    }

    fn write_byte(&mut self, b: u8) {
        // USART1 at 115200 bit/s; QEMU's transmitter is always ready.
        while !self.serial.try_write(b) {}
    }
}

impl CanDriver for Slcan {
    fn set_mac(&mut self, mac: MacId) {
        self.mac = mac;
    }

    fn try_transmit(&mut self, frame: &CanFrame) -> Result<(), Busy> {
        if !self.adapter.is_open() {
            return Err(Busy);
        }
        slcan::write_frame_line(frame, |b| self.write_byte(b));
        Ok(())
    }

    fn receive(&mut self) -> Option<CanFrame> {
        loop {
            let byte = self.serial.read()?;
            if let Some(line) = self.lines.push(byte) {
                let response = self.adapter.handle_line(line);
                // Stored after every line, changed or not: two word stores.
                board::hw::retained::store(self.adapter.to_bits());
                self.write(response.reply);
                if let Some(frame) = response.frame {
                    if filters::accepts(self.mac, frame.id().as_raw()) {
                        return Some(frame);
                    }
                }
            }
        }
    }

    fn bus_state(&mut self) -> BusState {
        BusState::ErrorActive
    }

    fn clear_transmit_interrupt(&mut self) {}

    fn restart(&mut self) {}
}
