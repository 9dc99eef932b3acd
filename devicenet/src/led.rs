//! Module Status and Network Status LED indications (devicenet-notes §7.3).
//!
//! The node decides *what* each bicolour LED indicates ([`Indication`]); [`Indication::lit`] turns
//! an indication and the time into the colour to drive now, so the firmware only writes pins.
//! Flashing is 0.5 s on / 0.5 s off; the power-up self-test is JB's sequence in 0.25 s steps:
//! MS green, MS red, off, NS green, NS red, off.

use crate::time::{Duration, Instant};

/// What one bicolour LED shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Indication {
    /// Dark.
    Off,
    /// Solid green.
    Green,
    /// Green, 0.5 s on / 0.5 s off.
    FlashingGreen,
    /// Solid red.
    Red,
    /// Red, 0.5 s on / 0.5 s off.
    FlashingRed,
    /// Red and green alternating (self-test, or comm-faulted identify).
    FlashingRedGreen,
}

/// The colour a bicolour LED is lit with at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Lit {
    /// Dark.
    Off,
    /// Green only.
    Green,
    /// Red only.
    Red,
}

/// Half a flash period.
pub const FLASH_HALF_PERIOD: Duration = Duration::from_millis(500);
/// One step of the power-up LED test.
pub const SELF_TEST_STEP: Duration = Duration::from_millis(250);
/// The whole power-up LED test (six steps).
pub const SELF_TEST_DURATION: Duration = Duration::from_millis(1500);

impl Indication {
    /// The colour to show at `now`; flashing phases are aligned to `since`, the instant the
    /// indication began, so a flash always starts with its lit half.
    pub fn lit(self, since: Instant, now: Instant) -> Lit {
        let half = FLASH_HALF_PERIOD.total_micros();
        let phase = (now - since).total_micros() / half;
        let first_half = phase % 2 == 0;
        match self {
            Indication::Off => Lit::Off,
            Indication::Green => Lit::Green,
            Indication::Red => Lit::Red,
            Indication::FlashingGreen if first_half => Lit::Green,
            Indication::FlashingRed if first_half => Lit::Red,
            Indication::FlashingRedGreen if first_half => Lit::Red,
            Indication::FlashingRedGreen => Lit::Green,
            Indication::FlashingGreen | Indication::FlashingRed => Lit::Off,
        }
    }
}

/// Both LEDs at one instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Leds {
    /// Module Status.
    pub module: Lit,
    /// Network Status.
    pub network: Lit,
}

/// The power-up LED test (JB): `Some` while it runs, `elapsed` after power-on.
pub fn self_test(elapsed: Duration) -> Option<Leds> {
    let step = elapsed.total_micros() / SELF_TEST_STEP.total_micros();
    let (module, network) = match step {
        0 => (Lit::Green, Lit::Off),
        1 => (Lit::Red, Lit::Off),
        2 => (Lit::Off, Lit::Off),
        3 => (Lit::Off, Lit::Green),
        4 => (Lit::Off, Lit::Red),
        5 => (Lit::Off, Lit::Off),
        _ => return None,
    };
    Some(Leds { module, network })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::solid_green(Indication::Green, 700, Lit::Green)]
    #[case::flash_green_on(Indication::FlashingGreen, 100, Lit::Green)]
    #[case::flash_green_off(Indication::FlashingGreen, 600, Lit::Off)]
    #[case::flash_green_on_again(Indication::FlashingGreen, 1000, Lit::Green)]
    #[case::flash_red_off(Indication::FlashingRed, 999, Lit::Off)]
    #[case::red_green_red(Indication::FlashingRedGreen, 0, Lit::Red)]
    #[case::red_green_green(Indication::FlashingRedGreen, 500, Lit::Green)]
    #[case::off(Indication::Off, 0, Lit::Off)]
    fn indication_at(#[case] ind: Indication, #[case] ms: u64, #[case] lit: Lit) {
        let since = Instant::from_secs(10);
        assert_eq!(ind.lit(since, since + Duration::from_millis(ms)), lit);
    }

    #[rstest]
    #[case::ms_green(0, Some(Leds { module: Lit::Green, network: Lit::Off }))]
    #[case::ms_red(250, Some(Leds { module: Lit::Red, network: Lit::Off }))]
    #[case::ns_green(800, Some(Leds { module: Lit::Off, network: Lit::Green }))]
    #[case::ns_red(1000, Some(Leds { module: Lit::Off, network: Lit::Red }))]
    #[case::last_off(1499, Some(Leds { module: Lit::Off, network: Lit::Off }))]
    #[case::done(1500, None)]
    fn self_test_sequence(#[case] ms: u64, #[case] leds: Option<Leds>) {
        assert_eq!(self_test(Duration::from_millis(ms)), leds);
    }
}
