//! The FLASH interface model ([`crate::flash::Flash`]) as the machine connects it: its
//! register block is a [`Peripheral`]; it keeps the array itself, so CPU stores into flash go
//! to its [`Flash::array_write`] and the CPU sees its [`Flash::image`].
//!
//! Its bus errors ([`Flash::take_bus_error`], a wrong key) stop the machine with a bus fault
//! ([`Machine::bus_error`]). Not connected: its stalls ([`Flash::take_stall`], an access
//! while BSY waits for the operation); the machine does not add them to its clock, the
//! firmware polls BSY instead.

use crate::flash::Flash;
use crate::periph::{Machine, Nanos, Peripheral, ResetKind, Width};

/// [`Flash`] with the array connected to the machine.
pub struct FlashPort {
    flash: Flash,
}

impl FlashPort {
    /// Connects `flash`.
    pub fn new(flash: Flash) -> FlashPort {
        FlashPort { flash }
    }

    /// The model.
    pub fn flash(&self) -> &Flash {
        &self.flash
    }
}

impl Peripheral for FlashPort {
    fn name(&self) -> &'static str {
        self.flash.name()
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        self.flash.read(offset, width, machine)
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        self.flash.write(offset, width, value, machine);
        if self.flash.take_bus_error() {
            machine.bus_error();
        }
    }

    fn advance(&mut self, now: Nanos, machine: &mut dyn Machine) {
        self.flash.advance(now, machine);
    }

    fn reset(&mut self, kind: ResetKind) {
        self.flash.reset(kind);
    }

    fn next_event(&self) -> Option<Nanos> {
        self.flash.next_event()
    }

    fn flash_store(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) -> bool {
        self.flash.array_write(offset, width, value, machine);
        true
    }

    fn flash_array(&self) -> Option<&[u8]> {
        Some(self.flash.image())
    }

    fn flash_load(&mut self, offset: u32, bytes: &[u8]) {
        self.flash.load(offset as usize, bytes);
    }
}
