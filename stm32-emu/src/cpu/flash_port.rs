//! The FLASH interface model ([`crate::flash::Flash`]) as the machine connects it: its
//! register block is a [`Peripheral`]; it keeps the array itself, so CPU stores into flash go
//! to its [`Flash::array_write`] and the CPU sees its [`Flash::image`].
//!
//! Its bus errors ([`Flash::take_bus_error`], a wrong key) stop the machine with a bus fault
//! ([`Machine::bus_error`]); its stalls ([`Flash::take_stall`], an access while BSY waits for
//! the operation) go to the machine's clock ([`Machine::stall`]). CPU loads from the array
//! never reach the model (the CPU reads the machine's copy), so they do not stall.

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

    /// Passes the model's bus error and stall of the access on to the machine.
    fn report(&mut self, machine: &mut dyn Machine) {
        if self.flash.take_bus_error() {
            machine.bus_error();
        }
        let stall = self.flash.take_stall();
        if stall > 0 {
            machine.stall(stall);
        }
    }
}

impl Peripheral for FlashPort {
    fn name(&self) -> &'static str {
        self.flash.name()
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        let value = self.flash.read(offset, width, machine);
        self.report(machine);
        value
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        self.flash.write(offset, width, value, machine);
        self.report(machine);
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
        self.report(machine);
        true
    }

    fn flash_array(&self) -> Option<&[u8]> {
        Some(self.flash.image())
    }

    fn flash_load(&mut self, offset: u32, bytes: &[u8]) {
        self.flash.load(offset as usize, bytes);
    }
}
