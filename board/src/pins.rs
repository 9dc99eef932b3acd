//! Pins as values: the boards' pin assignments ([`crate::boards`]) are written with them, and the
//! host tests check them (no pin serves twice, SWD stays free). The typed HAL pins are taken in
//! `board::hw` (target builds only); the application never names a pin.

/// A GPIO port.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Port {
    /// GPIOA.
    A,
    /// GPIOB.
    B,
    /// GPIOC.
    C,
}

impl Port {
    /// The port's index: its enable bit in `RCC_AHB1ENR` (GPIOAEN is bit 0).
    pub const fn index(self) -> u8 {
        match self {
            Port::A => 0,
            Port::B => 1,
            Port::C => 2,
        }
    }
}

/// A pin: port and number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pin {
    /// The port.
    pub port: Port,
    /// The pin number, 0–15.
    pub number: u8,
}

/// The pin `number` of `port`.
pub const fn pin(port: Port, number: u8) -> Pin {
    Pin { port, number }
}
