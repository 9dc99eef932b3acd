//! Pin assignment of the adapter board (STM32F405RG, LQFP64).
//!
//! | pin | function | set-up |
//! |---|---|---|
//! | PA1 | RS-485 driver enable (DE, and /RE tied to it) | push-pull output, low = receive |
//! | PA2 / PA3 | USART2 TX / RX to the instrument (RS-485 or RS-232 transceiver) | AF7 |
//! | PA9 / PA10 | USART1 TX / RX, service port (SLCAN in the emulated build) | AF7 (emulated); input, pull-up (real board: unused) |
//! | PB0–PB7 | DIP switches 1–8 to ground ([`crate::switches`]) | input, pull-up |
//! | PB8 / PB9 | CAN1 RX / TX to the isolated transceiver | AF9 |
//! | PC0–PC3 | MS green, MS red, NS green, NS red ([`crate::leds`]) | push-pull output, high = lit |
//!
//! The RS-232 variant of the board leaves PA1 unconnected; driving it is harmless. The typed
//! pins are taken in `board::hw` (target builds only); the application never names a pin.

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

/// A pin: port and number.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pin {
    /// The port.
    pub port: Port,
    /// The pin number, 0–15.
    pub number: u8,
}

const fn pin(port: Port, number: u8) -> Pin {
    Pin { port, number }
}

/// RS-485 driver enable.
pub const RS485_DE: Pin = pin(Port::A, 1);
/// USART2 TX (instrument).
pub const INSTRUMENT_TX: Pin = pin(Port::A, 2);
/// USART2 RX (instrument).
pub const INSTRUMENT_RX: Pin = pin(Port::A, 3);
/// USART1 TX (service port).
pub const SERVICE_TX: Pin = pin(Port::A, 9);
/// USART1 RX (service port).
pub const SERVICE_RX: Pin = pin(Port::A, 10);
/// The first DIP switch; switches 1–8 are PB0–PB7.
pub const SWITCH_1: Pin = pin(Port::B, 0);
/// CAN1 RX.
pub const CAN_RX: Pin = pin(Port::B, 8);
/// CAN1 TX.
pub const CAN_TX: Pin = pin(Port::B, 9);
/// The first LED pin; the LEDs are PC0–PC3.
pub const LED_MS_GREEN: Pin = pin(Port::C, 0);

/// Every pin the board uses, for the overlap check.
pub const ALL: [Pin; 9] =
    [RS485_DE, INSTRUMENT_TX, INSTRUMENT_RX, SERVICE_TX, SERVICE_RX, SWITCH_1, CAN_RX, CAN_TX, LED_MS_GREEN];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn switches_leds_and_can_do_not_overlap() {
        // Switches take PB0..=PB7, LEDs PC0..=PC3; CAN must sit above the switches.
        const { assert!(CAN_RX.number > SWITCH_1.number + 7 && CAN_TX.number > SWITCH_1.number + 7) };
        for (i, a) in ALL.iter().enumerate() {
            for b in &ALL[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }
}
