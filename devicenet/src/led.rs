//! Module Status and Network Status LED indications (protocol §7.3).
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
        let first_half = first_half(now - since);
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

/// Whether `elapsed` since an indication began falls in the first half of a flash period.
///
/// The remainder modulo the period is taken a byte at a time in 32-bit arithmetic: the Cortex-M4
/// has no 64-bit divide, and a `u64` division would bring the 864-byte library routine into the
/// firmware (`slave-fw/firmware/size-budget.toml`).
fn first_half(elapsed: Duration) -> bool {
    const HALF: u32 = FLASH_HALF_PERIOD.total_micros() as u32;
    // A period under 2^24 µs keeps `rem << 8` within 32 bits.
    const _: () = assert!(2 * (HALF as u64) < 1 << 24);
    let mut rem = 0u32;
    for byte in elapsed.total_micros().to_be_bytes() {
        rem = ((rem << 8) | u32::from(byte)) % (2 * HALF);
    }
    rem < HALF
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
    // Six steps: anything beyond is over, and what is left fits 32 bits (no 64-bit divide).
    let step =
        u32::try_from(elapsed.total_micros()).map_or(6, |us| us / SELF_TEST_STEP.total_micros() as u32);
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

    #[rstest]
    #[case::start(0)]
    #[case::just_before_half(499_999)]
    #[case::half(500_000)]
    #[case::period(1_000_000)]
    #[case::an_hour(3_600_000_123)]
    #[case::beyond_32_bits(0x1_2345_6789_ABCD)]
    #[case::max(u64::MAX)]
    fn flash_phase_as_by_division(#[case] micros: u64) {
        let by_division = (micros / FLASH_HALF_PERIOD.total_micros()) % 2 == 0;
        assert_eq!(first_half(Duration::from_micros(micros)), by_division);
    }
}
