//! A peripheral model the machine owns and the world outside the chip reaches too.
//!
//! [`Stm32::add_peripheral`](stm32_emu::machine::Stm32::add_peripheral) takes the model by value;
//! the emulated board keeps a second handle on the same model to drive its outside (the bxCAN
//! model's bus side, the USART's line, the GPIO pins the switches hold).

use std::cell::RefCell;
use std::rc::Rc;
use stm32_emu::periph::{ClockGate, Clocks, Machine, Nanos, Peripheral, ResetKind, Width};

/// A model behind a shared handle; the machine's copy delegates every call to it.
pub struct Shared<P>(pub Rc<RefCell<P>>);

impl<P> Shared<P> {
    /// Wraps `model`; [`Shared::handle`] gives the world's handle.
    pub fn new(model: P) -> Shared<P> {
        Shared(Rc::new(RefCell::new(model)))
    }

    /// Another handle on the same model.
    pub fn handle(&self) -> Rc<RefCell<P>> {
        Rc::clone(&self.0)
    }
}

impl<P: Peripheral> Peripheral for Shared<P> {
    fn name(&self) -> &'static str {
        self.0.borrow().name()
    }
    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        self.0.borrow_mut().read(offset, width, machine)
    }
    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        self.0.borrow_mut().write(offset, width, value, machine);
    }
    fn advance(&mut self, now: Nanos, machine: &mut dyn Machine) {
        self.0.borrow_mut().advance(now, machine);
    }
    fn reset(&mut self, kind: ResetKind) {
        self.0.borrow_mut().reset(kind);
    }
    fn next_event(&self) -> Option<Nanos> {
        self.0.borrow().next_event()
    }
    // The machine asks every model for the clocks while the world drives one of them through
    // its own handle (`Stm32::with_machine`): that model, borrowed then, is not the RCC.
    fn clocks(&self) -> Option<Clocks> {
        self.0.try_borrow().ok()?.clocks()
    }
    fn clock_gate(&self, gate: ClockGate) -> Option<bool> {
        self.0.try_borrow().ok()?.clock_gate(gate)
    }
}
