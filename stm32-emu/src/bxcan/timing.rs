//! Bit timing: the nominal bit rate `CAN_BTR` and PCLK1 give (RM0090 §32.7.7 "Bit timing"), and
//! the rule by which the model decides whether a controller can follow a bus at another rate.
//!
//! RM0090 §32.7.7: a bit is `SYNC_SEG + BS1 + BS2` with `SYNC_SEG` one quantum,
//! `t_BS1 = t_q × (TS1 + 1)`, `t_BS2 = t_q × (TS2 + 1)` and `t_q = (BRP + 1) × t_PCLK`;
//! resynchronisation lengthens BS1 or shortens BS2 by up to `SJW + 1` quanta.
//!
//! ## When the rates differ
//!
//! RM0090 refers to ISO 11898 for resynchronisation. The model takes the oscillator tolerance of
//! the CAN bit-timing literature (Hartwich and Bassemir, "The Configuration of the CAN Bit
//! Timing", Bosch 1999, conditions 1 and 2), with `n` quanta per bit, `PS1 = BS1` (the
//! propagation segment counted into phase segment 1, as on a short bus) and `PS2 = BS2`:
//!
//! ```text
//! df ≤ min(PS1, PS2) / (2 × (13 × n − PS2))      (resynchronise across 10 bits of stuff-free
//! df ≤ SJW / (20 × n)                              recessive-dominant edges, and 13 bits to an error flag)
//! ```
//!
//! `df` is the tolerance of one node against the nominal rate, so two nodes may differ by
//! `2 × df`. [`BitTiming::follows`] says a controller follows a bus when its rate is within
//! `2 × df` (its own `df`) of the bus's. Beyond that it decodes nothing (every frame is a
//! receive error to it) and nothing it sends is decoded. This is the model's rule: real
//! controllers degrade gradually near the limit (sporadic errors), which no source quantifies.

/// `CAN_BTR` fields (RM0090 §32.9.2): `BRP[9:0]`, `TS1[19:16]`, `TS2[22:20]`, `SJW[25:24]`, each
/// stored minus one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BitTiming {
    /// Clock cycles per quantum, `BRP + 1`.
    pub prescaler: u32,
    /// Bit segment 1 in quanta, `TS1 + 1`.
    pub bs1: u32,
    /// Bit segment 2 in quanta, `TS2 + 1`.
    pub bs2: u32,
    /// Resynchronisation jump width in quanta, `SJW + 1`.
    pub sjw: u32,
}

impl BitTiming {
    /// The timing fields of a `CAN_BTR` value (mode bits ignored).
    pub const fn from_btr(btr: u32) -> BitTiming {
        BitTiming {
            prescaler: (btr & 0x3FF) + 1,
            bs1: ((btr >> 16) & 0xF) + 1,
            bs2: ((btr >> 20) & 0x7) + 1,
            sjw: ((btr >> 24) & 0x3) + 1,
        }
    }

    /// Quanta per bit: `1 + BS1 + BS2`.
    pub const fn quanta(&self) -> u32 {
        1 + self.bs1 + self.bs2
    }

    /// PCLK cycles per bit.
    pub const fn cycles_per_bit(&self) -> u32 {
        self.prescaler * self.quanta()
    }

    /// The nominal bit rate at `pclk1_hz` in bit/s (RM0090 §32.7.7), rounded down.
    pub const fn bit_rate(&self, pclk1_hz: u32) -> u32 {
        pclk1_hz / self.cycles_per_bit()
    }

    /// The duration of `bits` bit times at `pclk1_hz`, in nanoseconds (at least 1 ns per call
    /// with bits > 0, so that a deadline always lies ahead).
    pub fn bits_to_nanos(&self, bits: u64, pclk1_hz: u32) -> u64 {
        if pclk1_hz == 0 {
            return u64::MAX;
        }
        let cycles = bits * u64::from(self.cycles_per_bit());
        (cycles * 1_000_000_000).div_ceil(u64::from(pclk1_hz)).max(u64::from(bits > 0))
    }

    /// The oscillator tolerance `df` of this timing (module docs), as a fraction.
    pub fn tolerance(&self) -> f64 {
        let n = f64::from(self.quanta());
        let ps2 = f64::from(self.bs2);
        let phase = f64::from(self.bs1.min(self.bs2)) / (2.0 * (13.0 * n - ps2));
        let jump = f64::from(self.sjw) / (20.0 * n);
        phase.min(jump)
    }

    /// Whether a controller with this timing at `pclk1_hz` follows a bus at `bus_bit_rate`
    /// (module docs: within `2 × df`).
    pub fn follows(&self, pclk1_hz: u32, bus_bit_rate: u32) -> bool {
        if pclk1_hz == 0 || bus_bit_rate == 0 {
            return false;
        }
        let own = f64::from(pclk1_hz) / f64::from(self.cycles_per_bit());
        let bus = f64::from(bus_bit_rate);
        (own - bus).abs() <= 2.0 * self.tolerance() * bus
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    // The board's values (board::bit_timing) at 42 MHz.
    #[case::k125_at_42_mhz(0x011C_0014, 42_000_000, 125_000)]
    #[case::k250_at_42_mhz(0x0005_0014, 42_000_000, 250_000)]
    #[case::k500_at_42_mhz(0x011A_0005, 42_000_000, 500_000)]
    // The reset value 0x0123_0000: BRP 0, TS1 3, TS2 2: 1 + 4 + 3 = 8 quanta of one cycle.
    #[case::reset_value_at_hsi(0x0123_0000, 16_000_000, 2_000_000)]
    fn nominal_rate(#[case] btr: u32, #[case] pclk1: u32, #[case] rate: u32) {
        assert_eq!(BitTiming::from_btr(btr).bit_rate(pclk1), rate);
        assert!(BitTiming::from_btr(btr).follows(pclk1, rate));
    }

    #[rstest]
    // The 42 MHz register values with the reset clock (HSI, 16 MHz): 47.6 kbit/s, not 125.
    #[case::k125_btr_at_hsi(0x011C_0014, 16_000_000, 125_000, false)]
    // 0.5 % fast: within 2 × df (df = 2 / (2 × (13 × 16 − 2)) = 0.485 % at 125k).
    #[case::k125_half_percent_fast(0x011C_0014, 42_210_000, 125_000, true)]
    // 1.5 % fast: beyond.
    #[case::k125_one_and_a_half_percent_fast(0x011C_0014, 42_630_000, 125_000, false)]
    #[case::k250_on_a_125k_bus(0x0005_0014, 42_000_000, 125_000, false)]
    fn following_another_rate(#[case] btr: u32, #[case] pclk1: u32, #[case] bus: u32, #[case] follows: bool) {
        assert_eq!(BitTiming::from_btr(btr).follows(pclk1, bus), follows);
    }

    #[test]
    fn tolerance_of_the_board_timing() {
        let t = BitTiming::from_btr(0x011C_0014);
        assert_eq!((t.prescaler, t.bs1, t.bs2, t.sjw), (21, 13, 2, 2));
        assert!((t.tolerance() - 2.0 / 412.0).abs() < 1e-12);
    }

    #[test]
    fn bit_times() {
        // 125 kbit/s: 8 µs a bit; 128 × 11 bits = 11.264 ms.
        let t = BitTiming::from_btr(0x011C_0014);
        assert_eq!(t.bits_to_nanos(128 * 11, 42_000_000), 11_264_000);
    }
}
