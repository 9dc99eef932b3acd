//! Serial line settings and the character timing derived from them.
//!
//! The UART itself is configured by the firmware's board crate or by the soft slave's serial port;
//! the profiles only need the timing: how long a character takes on the wire, how long a frame
//! takes to send, and the Modbus RTU inter-frame silence (3.5 character times, fixed at 1750 µs
//! above 19200 baud; Modbus over Serial Line V1.02 §2.5.1.1).

use super::error::{ConfigError, Field};
use devicenet::Duration;

/// Data bits per character.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum DataBits {
    /// 7 data bits (ASCII instruments).
    Seven,
    /// 8 data bits (binary protocols, Modbus RTU).
    #[default]
    Eight,
}

/// The parity bit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Parity {
    /// No parity bit.
    #[default]
    None,
    /// Even parity (the Modbus default).
    Even,
    /// Odd parity.
    Odd,
}

/// Stop bits per character.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum StopBits {
    /// One stop bit.
    #[default]
    One,
    /// Two stop bits.
    Two,
}

/// Baud rate and character format of the instrument's serial line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct SerialSettings {
    /// Bits per second, `300..=4_000_000`.
    pub baud: u32,
    /// Data bits per character.
    pub data_bits: DataBits,
    /// Parity.
    pub parity: Parity,
    /// Stop bits.
    pub stop_bits: StopBits,
}

impl Default for SerialSettings {
    /// 9600 baud, 8N1.
    fn default() -> Self {
        SerialSettings::new_8n1(9600)
    }
}

impl SerialSettings {
    /// The lowest baud rate accepted by [`validate`](Self::validate).
    pub const MIN_BAUD: u32 = 300;
    /// The highest baud rate accepted by [`validate`](Self::validate).
    pub const MAX_BAUD: u32 = 4_000_000;

    /// `baud` with 8 data bits, no parity, one stop bit.
    pub const fn new_8n1(baud: u32) -> Self {
        SerialSettings { baud, data_bits: DataBits::Eight, parity: Parity::None, stop_bits: StopBits::One }
    }

    /// `baud` with 8 data bits, even parity, one stop bit (the Modbus RTU default).
    pub const fn new_8e1(baud: u32) -> Self {
        SerialSettings { baud, data_bits: DataBits::Eight, parity: Parity::Even, stop_bits: StopBits::One }
    }

    /// Checks the baud rate range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        ConfigError::check_range(Field::SerialBaud, self.baud, Self::MIN_BAUD, Self::MAX_BAUD)
    }

    /// Bits on the wire per character: start bit, data bits, parity bit, stop bits
    /// (10 for 8N1, 11 for 8E1 or 8N2).
    pub const fn bits_per_char(&self) -> u32 {
        let data = match self.data_bits {
            DataBits::Seven => 7,
            DataBits::Eight => 8,
        };
        let parity = match self.parity {
            Parity::None => 0,
            Parity::Even | Parity::Odd => 1,
        };
        let stop = match self.stop_bits {
            StopBits::One => 1,
            StopBits::Two => 2,
        };
        1 + data + parity + stop
    }

    /// `tenths_of_chars / 10` character times, rounded up to the microsecond. A baud rate outside
    /// [`SerialSettings::MIN_BAUD`]`..=`[`SerialSettings::MAX_BAUD`] (rejected by `validate`) is
    /// taken as the nearest bound.
    ///
    /// 32-bit divisions only: the Cortex-M4 has no 64-bit divide, and a `u64` division would bring
    /// the 864-byte library routine into the firmware (`slave-fw/firmware/size-budget.toml`).
    fn char_tenths(&self, tenths_of_chars: u32) -> Duration {
        let baud = self.baud.clamp(Self::MIN_BAUD, Self::MAX_BAUD);
        let bit_tenths = tenths_of_chars.saturating_mul(self.bits_per_char());
        // µs = ⌈bit_tenths · 100 000 / baud⌉, the fraction carried in two steps (×100, ×1000)
        // so that every product stays under 2^32 (remainders are below MAX_BAUD = 4·10^6).
        let (whole, rest) = (bit_tenths / baud, bit_tenths % baud);
        let (hundreds, rest) = (rest * 100 / baud, rest * 100 % baud);
        let thousands = (rest * 1000).div_ceil(baud);
        Duration::from_micros(u64::from(whole) * 100_000 + u64::from(hundreds) * 1000 + u64::from(thousands))
    }

    /// The time one character takes on the wire, rounded up to the microsecond.
    pub fn char_time(&self) -> Duration {
        self.char_tenths(10)
    }

    /// The time `bytes` characters take on the wire, rounded up to the microsecond.
    pub fn transmit_time(&self, bytes: usize) -> Duration {
        self.char_tenths(u32::try_from(bytes).unwrap_or(u32::MAX).saturating_mul(10))
    }

    /// The Modbus RTU inter-frame silence t3.5: 3.5 character times, or a fixed 1750 µs above
    /// 19200 baud (Modbus over Serial Line §2.5.1.1).
    pub fn modbus_interframe_silence(&self) -> Duration {
        if self.baud > 19200 {
            Duration::from_micros(1750)
        } else {
            self.char_tenths(35)
        }
    }

    /// The Modbus RTU inter-character timeout t1.5: 1.5 character times, or a fixed 750 µs above
    /// 19200 baud (same section). Given for completeness: the master here delimits responses by
    /// their length, see [`super::modbus`].
    pub fn modbus_intercharacter_timeout(&self) -> Duration {
        if self.baud > 19200 {
            Duration::from_micros(750)
        } else {
            self.char_tenths(15)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    /// The 32-bit arithmetic gives what a 64-bit division gives, over the baud range.
    #[test]
    fn char_tenths_as_by_64_bit_division() {
        let bauds = [300, 301, 1200, 9600, 19200, 38400, 115_200, 921_600, 1_000_003, 3_999_999, 4_000_000];
        for baud in bauds {
            for data_bits in [DataBits::Seven, DataBits::Eight] {
                let s = SerialSettings { baud, data_bits, ..SerialSettings::new_8e1(baud) };
                for tenths in [0, 1, 10, 15, 35, 2560, 123_457, 10_000_000] {
                    let bit_tenths = u64::from(tenths) * u64::from(s.bits_per_char());
                    let expected = (bit_tenths * 1_000_000).div_ceil(u64::from(baud) * 10);
                    assert_eq!(s.char_tenths(tenths).total_micros(), expected, "{baud} baud, {tenths}");
                }
            }
        }
    }

    const S8N2: SerialSettings = SerialSettings {
        baud: 9600,
        data_bits: DataBits::Eight,
        parity: Parity::None,
        stop_bits: StopBits::Two,
    };
    const S7E1: SerialSettings = SerialSettings {
        baud: 9600,
        data_bits: DataBits::Seven,
        parity: Parity::Even,
        stop_bits: StopBits::One,
    };
    const S8E2: SerialSettings = SerialSettings {
        baud: 9600,
        data_bits: DataBits::Eight,
        parity: Parity::Even,
        stop_bits: StopBits::Two,
    };

    #[rstest]
    #[case::n81(SerialSettings::new_8n1(9600), 10)]
    #[case::e81(SerialSettings::new_8e1(9600), 11)]
    #[case::n82(S8N2, 11)]
    #[case::e71(S7E1, 10)]
    #[case::e82(S8E2, 12)]
    fn bits_per_char(#[case] s: SerialSettings, #[case] bits: u32) {
        assert_eq!(s.bits_per_char(), bits);
    }

    // 3.5 × bits / baud, rounded up to the microsecond; 1750 µs above 19200 baud.
    #[rstest]
    #[case::b1200_8n1(SerialSettings::new_8n1(1200), 29_167)]
    #[case::b9600_8n1(SerialSettings::new_8n1(9600), 3_646)]
    #[case::b9600_8e1(SerialSettings::new_8e1(9600), 4_011)]
    #[case::b9600_8n2(S8N2, 4_011)]
    #[case::b19200_8n1(SerialSettings::new_8n1(19200), 1_823)]
    #[case::b19200_8e1(SerialSettings::new_8e1(19200), 2_006)]
    #[case::b38400_fixed(SerialSettings::new_8n1(38400), 1_750)]
    #[case::b115200_fixed(SerialSettings::new_8e1(115_200), 1_750)]
    fn interframe_silence(#[case] s: SerialSettings, #[case] micros: u64) {
        assert_eq!(s.modbus_interframe_silence().total_micros(), micros);
    }

    #[rstest]
    #[case::b9600_8n1(SerialSettings::new_8n1(9600), 1_563)]
    #[case::b38400_fixed(SerialSettings::new_8n1(38400), 750)]
    fn intercharacter_timeout(#[case] s: SerialSettings, #[case] micros: u64) {
        assert_eq!(s.modbus_intercharacter_timeout().total_micros(), micros);
    }

    #[rstest]
    #[case::one_char_9600(SerialSettings::new_8n1(9600), 1, 1_042)]
    #[case::breaker_status_9600(SerialSettings::new_8n1(9600), 22, 22_917)]
    #[case::modbus_read_19200(SerialSettings::new_8e1(19200), 8, 4_584)]
    #[case::nothing(SerialSettings::new_8n1(9600), 0, 0)]
    fn transmit_time(#[case] s: SerialSettings, #[case] bytes: usize, #[case] micros: u64) {
        assert_eq!(s.transmit_time(bytes).total_micros(), micros);
    }

    #[rstest]
    #[case::too_slow(299, false)]
    #[case::min(300, true)]
    #[case::max(4_000_000, true)]
    #[case::too_fast(4_000_001, false)]
    fn validate_baud(#[case] baud: u32, #[case] ok: bool) {
        let r = SerialSettings::new_8n1(baud).validate();
        assert_eq!(r.is_ok(), ok, "{r:?}");
        if let Err(e) = r {
            assert_eq!(e.field, Field::SerialBaud);
        }
    }

    #[test]
    fn zero_baud_does_not_divide_by_zero() {
        let s = SerialSettings::new_8n1(0);
        assert!(s.char_time().total_micros() > 0);
    }
}
