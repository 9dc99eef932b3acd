//! The bicolour Module Status (MS) and Network Status (NS) LEDs on PC0–PC3.
//!
//! Each LED is a red/green pair, each colour driven high to light through its resistor:
//!
//! | pin | LED |
//! |---|---|
//! | PC0 | MS green |
//! | PC1 | MS red |
//! | PC2 | NS green |
//! | PC3 | NS red |
//!
//! The core decides what to show ([`devicenet::led`], notes §7.3, power-up test included);
//! [`pin_levels`] and [`bsrr`] turn that into pin levels, so the firmware only writes them.

use devicenet::led::{Leds, Lit};

/// GPIOC pin of the MS green LED.
pub const MS_GREEN_PIN: u8 = 0;
/// GPIOC pin of the MS red LED.
pub const MS_RED_PIN: u8 = 1;
/// GPIOC pin of the NS green LED.
pub const NS_GREEN_PIN: u8 = 2;
/// GPIOC pin of the NS red LED.
pub const NS_RED_PIN: u8 = 3;

/// `(green, red)` levels for one LED.
pub const fn colour_levels(lit: Lit) -> (bool, bool) {
    match lit {
        Lit::Off => (false, false),
        Lit::Green => (true, false),
        Lit::Red => (false, true),
    }
}

/// Levels of PC0–PC3, index = pin number (high = lit).
pub const fn pin_levels(leds: Leds) -> [bool; 4] {
    let (ms_green, ms_red) = colour_levels(leds.module);
    let (ns_green, ns_red) = colour_levels(leds.network);
    [ms_green, ms_red, ns_green, ns_red]
}

/// The GPIOC `BSRR` value that shows `leds` in one write (set bits 0–3, reset bits 16–19).
pub const fn bsrr(leds: Leds) -> u32 {
    let levels = pin_levels(leds);
    let mut value = 0u32;
    let mut pin = 0;
    while pin < 4 {
        value |= if levels[pin] { 1 << pin } else { 1 << (pin + 16) };
        pin += 1;
    }
    value
}

#[cfg(test)]
mod tests {
    use super::*;
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
        assert_eq!(bsrr(leds), value);
    }

    #[test]
    fn a_colour_pair_is_never_both_lit() {
        for lit in [Lit::Off, Lit::Green, Lit::Red] {
            assert_ne!(colour_levels(lit), (true, true));
        }
    }
}
