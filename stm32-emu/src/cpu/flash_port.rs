//! The FLASH interface model ([`crate::flash::Flash`]) as the machine connects it: its
//! register block is a [`Peripheral`]; it keeps the array itself, so CPU stores into flash go
//! to its [`Flash::array_write`] and the CPU sees its [`Flash::image`].
//!
//! Its bus errors ([`Flash::take_bus_error`], a wrong key) stop the machine with a bus fault
//! ([`Machine::bus_error`]); its stalls ([`Flash::take_stall`], an access while BSY waits for
//! the operation) go to the machine's clock ([`Machine::stall`]); its planned power cut
//! ([`Flash::power_cut`]) stops the machine ([`Machine::power_cut`]), once. CPU loads from the array
//! never reach the model (the CPU reads the machine's copy), so they do not stall; but code that
//! runs from flash cannot fetch its next instruction while an operation is under way (RM0090
//! §3.6.4: a flash read while BSY stalls the bus), so an access that starts a program or an erase
//! while the core executes from flash ([`Machine::fetches_from_flash`]) stalls the core until the
//! operation ends ([`Flash::stall_until_idle`]): no instruction runs and no interrupt is taken
//! meanwhile, SysTick's wraps pend one interrupt, as on the chip, where a firmware's millisecond
//! count falls behind by the erase. (The F4's ART instruction cache could serve a loop that fits
//! in it during the operation; RM0090 does not say, and the model does not.)

use crate::flash::Flash;
use crate::periph::{Machine, Nanos, Peripheral, ResetKind, Width};

/// [`Flash`] with the array connected to the machine.
pub struct FlashPort {
    flash: Flash,
    /// The model's power cut was reported to the machine (it stays in the model, which ignores
    /// writes after it, across the power-up that follows).
    cut_reported: bool,
}

impl FlashPort {
    /// Connects `flash`.
    pub fn new(flash: Flash) -> FlashPort {
        FlashPort { flash, cut_reported: false }
    }

    /// The model.
    pub fn flash(&self) -> &Flash {
        &self.flash
    }

    /// Holds the core until the operation an access started ends when the core's code is in
    /// flash (module docs).
    fn fetch_stall(&mut self, machine: &mut dyn Machine) {
        if self.flash.next_event().is_some() && machine.fetches_from_flash() {
            self.flash.stall_until_idle();
        }
    }

    /// Passes the model's bus error and stall of the access on to the machine.
    fn report(&mut self, machine: &mut dyn Machine) {
        if self.flash.take_bus_error() {
            machine.bus_error();
        }
        if self.flash.power_cut().is_some() && !self.cut_reported {
            self.cut_reported = true;
            machine.power_cut();
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
        self.fetch_stall(machine);
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
        self.fetch_stall(machine);
        self.report(machine);
        true
    }

    fn flash_array(&self) -> Option<&[u8]> {
        Some(self.flash.image())
    }

    fn flash_load(&mut self, offset: u32, bytes: &[u8]) {
        self.flash.load(offset as usize, bytes);
    }

    fn flash_operations(&self) -> Option<u64> {
        Some(self.flash.operations())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flash::{CutKind, FlashTiming, KEY1, KEY2};
    use crate::gpio::tests::TestMachine;
    use crate::periph::{ClockGate, Clocks};

    /// A machine that counts the power cuts reported to it, adds up its stalls and runs its
    /// code from flash or not.
    #[derive(Default)]
    struct CutMachine {
        inner: TestMachine,
        cuts: u32,
        stalled: Nanos,
        code_in_flash: bool,
    }

    impl Machine for CutMachine {
        fn clocks(&self) -> Clocks {
            self.inner.clocks()
        }
        fn clock_enabled(&self, gate: ClockGate) -> bool {
            self.inner.clock_enabled(gate)
        }
        fn set_irq(&mut self, irq: u16, level: bool) {
            self.inner.set_irq(irq, level);
        }
        fn now(&self) -> Nanos {
            self.inner.now()
        }
        fn power_cut(&mut self) {
            self.cuts += 1;
        }
        fn stall(&mut self, nanos: Nanos) {
            self.stalled += nanos;
        }
        fn fetches_from_flash(&self) -> bool {
            self.code_in_flash
        }
    }

    /// Unlocks CR and starts the erase of sector 1 (SER, SNB 1, STRT; RM0090 §3.9.5); returns
    /// SR read right after (BSY is bit 16).
    fn erase_sector_1(port: &mut FlashPort, m: &mut CutMachine) -> u32 {
        port.write(0x04, Width::Word, KEY1, m);
        port.write(0x04, Width::Word, KEY2, m);
        port.write(0x10, Width::Word, 1 << 1 | 1 << 3, m);
        port.write(0x10, Width::Word, 1 << 16 | 1 << 1 | 1 << 3, m);
        port.read(0x0C, Width::Word, m)
    }

    #[test]
    fn code_in_flash_stalls_through_an_erase() {
        let timing = FlashTiming::DATASHEET;
        let mut port = FlashPort::new(Flash::new().with_timing(timing));
        let m = &mut CutMachine { code_in_flash: true, ..CutMachine::default() };
        let sr = erase_sector_1(&mut port, m);
        assert_eq!(sr & 1 << 16, 0, "BSY clear by the next instruction");
        assert_eq!(m.stalled, timing.erase_16k[0], "the whole erase (PSIZE x8) as a stall");
        assert_eq!(port.flash().image()[0x4000], 0xFF);
    }

    #[test]
    fn code_in_ram_runs_on_during_an_erase() {
        let mut port = FlashPort::new(Flash::new().with_timing(FlashTiming::DATASHEET));
        let m = &mut CutMachine::default();
        let sr = erase_sector_1(&mut port, m);
        assert_ne!(sr & 1 << 16, 0, "BSY set: the code polls it");
        assert_eq!(m.stalled, 0);
    }

    #[test]
    fn a_planned_power_cut_is_reported_to_the_machine_once() {
        let mut flash = Flash::new().with_timing(FlashTiming::FAST);
        flash.plan_power_cut(0, CutKind::Before);
        let mut port = FlashPort::new(flash);
        let m = &mut CutMachine::default();
        // KEYR (0x04): the unlock sequence; CR (0x10): PG, PSIZE x8 (RM0090 §3.9.2, §3.9.5).
        port.write(0x04, Width::Word, KEY1, m);
        port.write(0x04, Width::Word, KEY2, m);
        port.write(0x10, Width::Word, 1, m);
        assert!(port.flash_store(0xE_0000, Width::Byte, 0, m));
        assert_eq!((m.cuts, port.flash().power_cut().map(|c| c.operation)), (1, Some(0)));
        assert_eq!(port.flash().image()[0xE_0000], 0xFF, "the operation did not start");
        port.flash_store(0xE_0001, Width::Byte, 0, m);
        port.reset(ResetKind::PowerOn);
        let _ = port.read(0x0C, Width::Word, m);
        assert_eq!(m.cuts, 1, "reported once");
    }
}
