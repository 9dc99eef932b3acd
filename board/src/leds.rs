//! The status LEDs of the selected board ([`crate::boards::LedWiring`]).
//!
//! The reference board has the two bicolour LEDs DeviceNet asks for, Module Status (MS) and
//! Network Status (NS), each a red/green pair driven high to light through its resistor:
//!
//! | pin | LED |
//! |---|---|
//! | PC0 | MS green |
//! | PC1 | MS red |
//! | PC2 | NS green |
//! | PC3 | NS red |
//!
//! The Olimex STM32-P405 (PC12) and the NUCLEO-F446RE (LD2, PA5) have one LED each; it shows
//! what [`single_lit`] says: the Network Status while the Module Status is green, and the Module
//! Status's red when it is red (a fault outweighs the network state):
//!
//! | MS | NS | the one LED |
//! |---|---|---|
//! | green (operational) | off | off: not on-line (duplicate MAC check, no other node) |
//! | green | flashing green or red | flashing: on-line not allocated, or connection timed out |
//! | green | green or red | on: allocated to a master, or duplicate MAC / bus-off |
//! | flashing red (minor fault) | any | flashing |
//! | red (major fault) | any | on |
//! | flashing green (standby) | any | as NS in the green half, off in the other |
//!
//! In the power-up test it is lit for the MS red step only (0.25–0.5 s after power-up): in the MS
//! green step the NS is still off, and the NS steps leave it off (checked on the exact ELF by
//! exact-firmware's `leds` scenario).
//!
//! The bus tells the rest (the Identity object's status, `dnet-master`).
//!
//! The core decides what to show ([`devicenet::led`], protocol §7.3, power-up test included);
//! [`bsrr`] turns that into one write of the port's bit set/reset register, so the firmware only
//! writes it.

use devicenet::led::{Leds, Lit};

use crate::boards::{LedWiring, SELECTED};
use crate::pins::Port;

/// The selected board's LEDs.
pub const WIRING: LedWiring = SELECTED.leds;

/// `(green, red)` levels for one LED.
pub const fn colour_levels(lit: Lit) -> (bool, bool) {
    match lit {
        Lit::Off => (false, false),
        Lit::Green => (true, false),
        Lit::Red => (false, true),
    }
}

/// Levels of the four bicolour pins, MS green, MS red, NS green, NS red (high = lit).
pub const fn pin_levels(leds: Leds) -> [bool; 4] {
    let (ms_green, ms_red) = colour_levels(leds.module);
    let (ns_green, ns_red) = colour_levels(leds.network);
    [ms_green, ms_red, ns_green, ns_red]
}

/// Whether a board's one LED is lit (see the module docs).
pub const fn single_lit(leds: Leds) -> bool {
    match leds.module {
        Lit::Green => !matches!(leds.network, Lit::Off),
        other => !matches!(other, Lit::Off),
    }
}

/// The port the LEDs are on.
pub const fn port(wiring: LedWiring) -> Port {
    match wiring {
        LedWiring::Bicolour { ms_green } => ms_green.port,
        LedWiring::Single(pin) => pin.port,
    }
}

/// The pins of the LEDs on [`port`], as a mask of pin numbers.
pub const fn pin_mask(wiring: LedWiring) -> u16 {
    match wiring {
        LedWiring::Bicolour { ms_green } => 0xF << ms_green.number,
        LedWiring::Single(pin) => 1 << pin.number,
    }
}

/// The `MODER` bits of the LED pins (two per pin), and the value that makes them outputs.
pub const fn moder_mask_and_outputs(wiring: LedWiring) -> (u32, u32) {
    let pins = pin_mask(wiring);
    let (mut mask, mut outputs) = (0u32, 0u32);
    let mut pin = 0;
    while pin < 16 {
        if pins & (1 << pin) != 0 {
            mask |= 0b11 << (2 * pin);
            outputs |= 0b01 << (2 * pin);
        }
        pin += 1;
    }
    (mask, outputs)
}

/// The `BSRR` value of the LEDs' port that shows `leds` in one write: set bits for the lit pins,
/// reset bits (16 up) for the others, nothing for any other pin.
pub const fn bsrr(wiring: LedWiring, leds: Leds) -> u32 {
    match wiring {
        LedWiring::Bicolour { ms_green } => {
            let levels = pin_levels(leds);
            let mut value = 0u32;
            let mut i = 0;
            while i < 4 {
                let pin = ms_green.number as u32 + i as u32;
                value |= if levels[i] { 1 << pin } else { 1 << (pin + 16) };
                i += 1;
            }
            value
        }
        LedWiring::Single(pin) => {
            let pin = pin.number as u32;
            if single_lit(leds) {
                1 << pin
            } else {
                1 << (pin + 16)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boards::{nucleo_f446re, olimex_p405, reference};
    use rstest::rstest;

    #[rstest]
    #[case::all_off(Lit::Off, Lit::Off, [false, false, false, false], 0x000F_0000)]
    #[case::ms_green(Lit::Green, Lit::Off, [true, false, false, false], 0x000E_0001)]
    #[case::ms_red(Lit::Red, Lit::Off, [false, true, false, false], 0x000D_0002)]
    #[case::ns_green(Lit::Off, Lit::Green, [false, false, true, false], 0x000B_0004)]
    #[case::ns_red_ms_green(Lit::Green, Lit::Red, [true, false, false, true], 0x0006_0009)]
    fn mapping(#[case] module: Lit, #[case] network: Lit, #[case] levels: [bool; 4], #[case] value: u32) {
        let leds = Leds { module, network };
        assert_eq!(pin_levels(leds), levels);
        assert_eq!(bsrr(reference::BOARD.leds, leds), value);
    }

    #[rstest]
    #[case::not_online(Lit::Green, Lit::Off, false)]
    #[case::online(Lit::Green, Lit::Green, true)]
    #[case::duplicate_mac(Lit::Green, Lit::Red, true)]
    #[case::standby_phase_off(Lit::Off, Lit::Green, false)]
    #[case::minor_fault_phase_on(Lit::Red, Lit::Off, true)]
    #[case::major_fault(Lit::Red, Lit::Green, true)]
    fn one_led(#[case] module: Lit, #[case] network: Lit, #[case] lit: bool) {
        let leds = Leds { module, network };
        assert_eq!(single_lit(leds), lit);
        // Olimex STM32-P405: PC12; NUCLEO-F446RE: PA5.
        let (olimex, nucleo) = if lit { (1 << 12, 1 << 5) } else { (1 << 28, 1 << 21) };
        assert_eq!(bsrr(olimex_p405::BOARD.leds, leds), olimex);
        assert_eq!(bsrr(nucleo_f446re::BOARD.leds, leds), nucleo);
    }

    #[test]
    fn moder_bits() {
        assert_eq!(moder_mask_and_outputs(reference::BOARD.leds), (0xFF, 0x55));
        assert_eq!(moder_mask_and_outputs(olimex_p405::BOARD.leds), (0b11 << 24, 0b01 << 24));
        assert_eq!(moder_mask_and_outputs(nucleo_f446re::BOARD.leds), (0b11 << 10, 0b01 << 10));
        assert_eq!((port(reference::BOARD.leds), port(nucleo_f446re::BOARD.leds)), (Port::C, Port::A));
    }

    #[test]
    fn a_colour_pair_is_never_both_lit() {
        for lit in [Lit::Off, Lit::Green, Lit::Red] {
            assert_ne!(colour_levels(lit), (true, true));
        }
    }
}
