//! CAN bit timing for the bxCAN controller (RM0090 §32.7.7, register `CAN_BTR`).
//!
//! A bit is `1 + BS1 + BS2` time quanta of `prescaler / f_APB1` each; the sample point sits at the
//! end of BS1. DeviceNet (and CiA 301 for these rates) wants the sample point near 87.5 %. For a
//! board's APB1 clock (PCLK1) [`bit_timing`] finds, for every DeviceNet rate, the integer
//! prescaler and segment split whose sample point is closest to 87.5 %, preferring more quanta on
//! a tie. At 42 MHz (the STM32F405 boards):
//!
//! | rate | prescaler | quanta | BS1 | BS2 | SJW | sample point |
//! |---|---|---|---|---|---|---|
//! | 125 kbit/s | 21 | 16 | 13 | 2 | 2 | 87.5 % |
//! | 250 kbit/s | 21 | 8 | 6 | 1 | 1 | 87.5 % |
//! | 500 kbit/s | 6 | 14 | 11 | 2 | 2 | 85.7 % |
//!
//! At 45 MHz (the NUCLEO-F446RE):
//!
//! | rate | prescaler | quanta | BS1 | BS2 | SJW | sample point |
//! |---|---|---|---|---|---|---|
//! | 125 kbit/s | 45 | 8 | 6 | 1 | 1 | 87.5 % |
//! | 250 kbit/s | 12 | 15 | 12 | 2 | 2 | 86.7 % |
//! | 500 kbit/s | 6 | 15 | 12 | 2 | 2 | 86.7 % |
//!
//! Everything here is `const fn`, so the firmware's register values are computed at compile time
//! (a board clock without a timing for every rate fails the build) and unit-tested on the host for
//! every board ([`crate::boards`]).

use crate::clocks::PCLK1_HZ;
use devicenet::slave::BaudRate;

/// The sample point DeviceNet asks for, in per mille of the bit time.
pub const TARGET_SAMPLE_POINT_PERMILLE: u32 = 875;

/// Largest BS1 the bxCAN accepts.
pub const MAX_BS1: u8 = 16;
/// Largest BS2 the bxCAN accepts.
pub const MAX_BS2: u8 = 8;
/// Largest resynchronisation jump width the bxCAN accepts.
pub const MAX_SJW: u8 = 4;
/// Largest baud-rate prescaler (10-bit field + 1).
pub const MAX_PRESCALER: u16 = 1024;

/// One bit-timing configuration of the bxCAN.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BitTiming {
    /// Clock cycles per time quantum, `1..=1024`.
    pub prescaler: u16,
    /// Time segment 1 (propagation + phase 1) in quanta, `1..=16`.
    pub bs1: u8,
    /// Time segment 2 (phase 2) in quanta, `1..=8`.
    pub bs2: u8,
    /// Resynchronisation jump width in quanta, `1..=4`.
    pub sjw: u8,
}

impl BitTiming {
    /// Quanta per bit: the synchronisation segment plus BS1 and BS2.
    pub const fn quanta(&self) -> u32 {
        1 + self.bs1 as u32 + self.bs2 as u32
    }

    /// The bit rate this timing gives at `pclk_hz`, rounded down.
    pub const fn bit_rate(&self, pclk_hz: u32) -> u32 {
        pclk_hz / (self.prescaler as u32 * self.quanta())
    }

    /// The sample point in per mille of the bit time.
    pub const fn sample_point_permille(&self) -> u32 {
        (1 + self.bs1 as u32) * 1000 / self.quanta()
    }

    /// The `CAN_BTR` register value: `SJW[25:24]`, `TS2[22:20]`, `TS1[19:16]`, `BRP[9:0]`, each
    /// stored minus one; loop-back and silent mode off.
    pub const fn btr(&self) -> u32 {
        ((self.sjw as u32 - 1) << 24)
            | ((self.bs2 as u32 - 1) << 20)
            | ((self.bs1 as u32 - 1) << 16)
            | (self.prescaler as u32 - 1)
    }
}

/// The timing for `bit_rate` at `pclk_hz` with the sample point closest to `sample_point_permille`,
/// or `None` when no integer prescaler gives the rate exactly with 8 to 25 quanta per bit.
///
/// Ties go to the configuration with more quanta (finer resynchronisation). SJW is BS2 capped at
/// [`MAX_SJW`], the usual choice for a long bus.
pub const fn bit_timing(pclk_hz: u32, bit_rate: u32, sample_point_permille: u32) -> Option<BitTiming> {
    if bit_rate == 0 {
        return None;
    }
    let mut best: Option<BitTiming> = None;
    let mut best_error = u32::MAX;
    let mut quanta = 25u32;
    while quanta >= 8 {
        let per_bit = bit_rate as u64 * quanta as u64;
        if (pclk_hz as u64) % per_bit == 0 {
            let prescaler = (pclk_hz as u64 / per_bit) as u32;
            if prescaler >= 1 && prescaler <= MAX_PRESCALER as u32 {
                // Quanta up to the sample point (sync + BS1), rounded to the nearest.
                let mut before = (quanta * sample_point_permille + 500) / 1000;
                if before > 1 + MAX_BS1 as u32 {
                    before = 1 + MAX_BS1 as u32;
                }
                if before < 2 {
                    before = 2;
                }
                let bs1 = before - 1;
                let bs2 = quanta - before;
                if bs2 >= 1 && bs2 <= MAX_BS2 as u32 {
                    let sp = before * 1000 / quanta;
                    let error = sp.abs_diff(sample_point_permille);
                    if error < best_error {
                        best_error = error;
                        let sjw = if bs2 < MAX_SJW as u32 { bs2 } else { MAX_SJW as u32 };
                        best = Some(BitTiming {
                            prescaler: prescaler as u16,
                            bs1: bs1 as u8,
                            bs2: bs2 as u8,
                            sjw: sjw as u8,
                        });
                    }
                }
            }
        }
        quanta -= 1;
    }
    best
}

/// The timing for a DeviceNet rate at `pclk1_hz`, `None` when that clock cannot make the rate.
pub const fn for_clock(pclk1_hz: u32, rate: BaudRate) -> Option<BitTiming> {
    let bits = match rate {
        BaudRate::Kbps125 => 125_000,
        BaudRate::Kbps250 => 250_000,
        BaudRate::Kbps500 => 500_000,
    };
    bit_timing(pclk1_hz, bits, TARGET_SAMPLE_POINT_PERMILLE)
}

/// The selected board's timing for a DeviceNet rate at its APB1 clock.
pub const fn for_baud_rate(rate: BaudRate) -> BitTiming {
    match rate {
        BaudRate::Kbps125 => KBPS125,
        BaudRate::Kbps250 => KBPS250,
        BaudRate::Kbps500 => KBPS500,
    }
}

const fn unwrap_timing(t: Option<BitTiming>) -> BitTiming {
    match t {
        Some(t) => t,
        // Evaluated at compile time: a board clock without a valid timing fails the build.
        None => panic!("no CAN bit timing for this clock"),
    }
}

/// The clock the timings below are computed for: PCLK1, or half of it with the self-test's
/// `fault-btr` (every rate then runs twice as fast on the wire).
const TIMING_CLOCK_HZ: u32 = if cfg!(feature = "fault-btr") { PCLK1_HZ / 2 } else { PCLK1_HZ };

/// 125 kbit/s at the selected board's PCLK1.
pub const KBPS125: BitTiming = unwrap_timing(for_clock(TIMING_CLOCK_HZ, BaudRate::Kbps125));
/// 250 kbit/s at the selected board's PCLK1.
pub const KBPS250: BitTiming = unwrap_timing(for_clock(TIMING_CLOCK_HZ, BaudRate::Kbps250));
/// 500 kbit/s at the selected board's PCLK1.
pub const KBPS500: BitTiming = unwrap_timing(for_clock(TIMING_CLOCK_HZ, BaudRate::Kbps500));

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    const F405_PCLK1: u32 = 42_000_000;
    const F446_PCLK1: u32 = 45_000_000;

    #[rstest]
    #[case::f405_k125(F405_PCLK1, BaudRate::Kbps125, BitTiming { prescaler: 21, bs1: 13, bs2: 2, sjw: 2 }, 0x011C_0014)]
    #[case::f405_k250(F405_PCLK1, BaudRate::Kbps250, BitTiming { prescaler: 21, bs1: 6, bs2: 1, sjw: 1 }, 0x0005_0014)]
    #[case::f405_k500(F405_PCLK1, BaudRate::Kbps500, BitTiming { prescaler: 6, bs1: 11, bs2: 2, sjw: 2 }, 0x011A_0005)]
    #[case::f446_k125(F446_PCLK1, BaudRate::Kbps125, BitTiming { prescaler: 45, bs1: 6, bs2: 1, sjw: 1 }, 0x0005_002C)]
    #[case::f446_k250(F446_PCLK1, BaudRate::Kbps250, BitTiming { prescaler: 12, bs1: 12, bs2: 2, sjw: 2 }, 0x011B_000B)]
    #[case::f446_k500(F446_PCLK1, BaudRate::Kbps500, BitTiming { prescaler: 6, bs1: 12, bs2: 2, sjw: 2 }, 0x011B_0005)]
    fn devicenet_rates(
        #[case] pclk1: u32,
        #[case] rate: BaudRate,
        #[case] timing: BitTiming,
        #[case] btr: u32,
    ) {
        let t = for_clock(pclk1, rate).unwrap();
        assert_eq!(t, timing);
        assert_eq!(t.btr(), btr);
        // Exact rate, no rounding.
        assert_eq!(t.bit_rate(pclk1), rate.bits_per_second());
        assert_eq!(pclk1 % (u32::from(t.prescaler) * t.quanta()), 0);
    }

    #[test]
    fn the_selected_boards_timing_is_its_clocks() {
        for rate in [BaudRate::Kbps125, BaudRate::Kbps250, BaudRate::Kbps500] {
            assert_eq!(Some(for_baud_rate(rate)), for_clock(PCLK1_HZ, rate));
        }
    }

    #[rstest]
    fn sample_point_near_87_5_percent(
        #[values(BaudRate::Kbps125, BaudRate::Kbps250, BaudRate::Kbps500)] rate: BaudRate,
        #[values(F405_PCLK1, F446_PCLK1)] pclk1: u32,
    ) {
        let t = for_clock(pclk1, rate).unwrap();
        let sp = t.sample_point_permille();
        assert!((850..=880).contains(&sp), "{rate:?}: sample point {sp} ‰");
        assert!((1..=MAX_BS1).contains(&t.bs1));
        assert!((1..=MAX_BS2).contains(&t.bs2));
        assert!((1..=MAX_SJW).contains(&t.sjw) && t.sjw <= t.bs2);
        assert!((8..=25).contains(&t.quanta()));
    }

    #[rstest]
    #[case::zero_rate(42_000_000, 0)]
    #[case::not_divisible(42_000_000, 333_333)]
    #[case::too_fast(16_000_000, 4_000_000)]
    fn impossible_rates(#[case] pclk: u32, #[case] rate: u32) {
        assert_eq!(bit_timing(pclk, rate, 875), None);
    }

    #[test]
    fn other_clocks() {
        // HSI (16 MHz), 500 kbit/s: 16 quanta of 2 cycles, 14/16 = 87.5 %.
        let t = bit_timing(16_000_000, 500_000, 875).unwrap();
        assert_eq!(t, BitTiming { prescaler: 2, bs1: 13, bs2: 2, sjw: 2 });
        assert_eq!(t.sample_point_permille(), 875);
    }
}
