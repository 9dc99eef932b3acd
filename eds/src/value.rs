//! Value types of the typed model: numbers as EDS writes them, CIP data type codes, parameter
//! descriptors, connection masks, EPATHs, dates, times and revisions.

use serde::{Serialize, Serializer};
use std::fmt;

/// Parses an EDS integer: decimal (`283`, `-5`, `+7`, leading zeros allowed) or hexadecimal
/// written `0x`/`0X` (`0x00C6`). `None` on anything else or on overflow of `i128`.
pub fn parse_int(text: &str) -> Option<i128> {
    let text = text.trim();
    let (negative, digits) = match text.as_bytes().first()? {
        b'-' => (true, &text[1..]),
        b'+' => (false, &text[1..]),
        _ => (false, text),
    };
    let (radix, digits) = match digits.get(..2) {
        Some("0x" | "0X") => (16, &digits[2..]),
        _ => (10, digits),
    };
    if digits.is_empty() || !digits.chars().all(|c| c.is_digit(radix)) {
        return None;
    }
    let mut value: i128 = 0;
    for c in digits.chars() {
        let digit = i128::from(c.to_digit(radix)?);
        value = value.checked_mul(i128::from(radix))?.checked_add(digit)?;
    }
    Some(if negative { -value } else { value })
}

/// Parses a decimal real number (`1.5`, `-2e-3`); `inf`/`nan` spellings are refused.
pub fn parse_real(text: &str) -> Option<f64> {
    let text = text.trim();
    if text.is_empty()
        || !text.chars().all(|c| c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E'))
    {
        return None;
    }
    text.parse::<f64>().ok().filter(|v| v.is_finite())
}

/// A data value of a parameter (minimum, maximum, default) as written in the file.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Value {
    /// An integer (decimal or `0x` hex in the file).
    Int(i128),
    /// A real number (`1.5`, `1e3`).
    Real(f64),
    /// A quoted string (defaults of string parameters).
    Str(String),
    /// Unquoted text that is not a number, kept as written.
    Text(String),
}

impl Value {
    /// Reads unquoted text: an integer, else a real, else [`Value::Text`].
    pub fn from_text(text: &str) -> Value {
        if let Some(int) = parse_int(text) {
            Value::Int(int)
        } else if let Some(real) = parse_real(text) {
            Value::Real(real)
        } else {
            Value::Text(text.to_string())
        }
    }

    /// The integer, when this is one.
    pub fn as_int(&self) -> Option<i128> {
        match self {
            Value::Int(v) => Some(*v),
            _ => None,
        }
    }

    /// The value as a real number, when it is numeric.
    pub fn as_f64(&self) -> Option<f64> {
        match self {
            // Precision loss above 2^53 only affects comparisons between huge 64-bit values.
            Value::Int(v) => Some(*v as f64),
            Value::Real(v) => Some(*v),
            _ => None,
        }
    }
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Int(v) => write!(f, "{v}"),
            // `{:?}` keeps a decimal point ("1.0"), so the text reads back as a real.
            Value::Real(v) => write!(f, "{v:?}"),
            Value::Str(s) => write!(f, "{s:?}"),
            Value::Text(s) => f.write_str(s),
        }
    }
}

macro_rules! data_types {
    ($( $(#[$doc:meta])* $variant:ident = $code:literal, $name:literal, $size:expr, $range:expr; )*) => {
        /// A CIP elementary data type code (CIP Vol 1 Appendix C), as used in a parameter's data
        /// type field. Unknown codes are kept in [`DataType::Unknown`].
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum DataType {
            $( $(#[$doc])* $variant, )*
            /// A code that is not a CIP elementary type.
            Unknown(u16),
        }

        impl DataType {
            /// The type for `code`; never fails.
            pub const fn from_code(code: u16) -> DataType {
                match code {
                    $( $code => DataType::$variant, )*
                    other => DataType::Unknown(other),
                }
            }

            /// The type code.
            pub const fn code(self) -> u16 {
                match self {
                    $( DataType::$variant => $code, )*
                    DataType::Unknown(code) => code,
                }
            }

            /// The CIP name (`USINT`, `SHORT_STRING`), or `None` for an unknown code.
            pub const fn name(self) -> Option<&'static str> {
                match self {
                    $( DataType::$variant => Some($name), )*
                    DataType::Unknown(_) => None,
                }
            }

            /// The size in bytes of a fixed-size type; `None` for strings, EPATH and unknown codes.
            pub const fn fixed_size(self) -> Option<u32> {
                match self {
                    $( DataType::$variant => $size, )*
                    DataType::Unknown(_) => None,
                }
            }

            /// The inclusive range of an integer or bit-string type.
            pub const fn int_range(self) -> Option<(i128, i128)> {
                match self {
                    $( DataType::$variant => $range, )*
                    DataType::Unknown(_) => None,
                }
            }
        }
    };
}

const fn unsigned(bits: u32) -> Option<(i128, i128)> {
    Some((0, (1i128 << bits) - 1))
}

const fn signed(bits: u32) -> Option<(i128, i128)> {
    Some((-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1))
}

data_types! {
    /// Boolean, 1 byte (0 or 1).
    Bool = 0xC1, "BOOL", Some(1), Some((0, 1));
    /// Signed 8-bit integer.
    Sint = 0xC2, "SINT", Some(1), signed(8);
    /// Signed 16-bit integer.
    Int = 0xC3, "INT", Some(2), signed(16);
    /// Signed 32-bit integer.
    Dint = 0xC4, "DINT", Some(4), signed(32);
    /// Signed 64-bit integer.
    Lint = 0xC5, "LINT", Some(8), signed(64);
    /// Unsigned 8-bit integer.
    Usint = 0xC6, "USINT", Some(1), unsigned(8);
    /// Unsigned 16-bit integer.
    Uint = 0xC7, "UINT", Some(2), unsigned(16);
    /// Unsigned 32-bit integer.
    Udint = 0xC8, "UDINT", Some(4), unsigned(32);
    /// Unsigned 64-bit integer.
    Ulint = 0xC9, "ULINT", Some(8), unsigned(64);
    /// IEEE 754 single precision.
    Real = 0xCA, "REAL", Some(4), None;
    /// IEEE 754 double precision.
    Lreal = 0xCB, "LREAL", Some(8), None;
    /// Synchronous time, 32-bit.
    Stime = 0xCC, "STIME", Some(4), signed(32);
    /// Date, 16-bit day count.
    Date = 0xCD, "DATE", Some(2), unsigned(16);
    /// Time of day, 32-bit milliseconds.
    TimeOfDay = 0xCE, "TIME_OF_DAY", Some(4), unsigned(32);
    /// Date and time (TIME_OF_DAY + DATE), 6 bytes.
    DateAndTime = 0xCF, "DATE_AND_TIME", Some(6), None;
    /// Character string, 1 byte per character, 16-bit length prefix.
    String = 0xD0, "STRING", None, None;
    /// Bit string, 8 bits.
    Byte = 0xD1, "BYTE", Some(1), unsigned(8);
    /// Bit string, 16 bits.
    Word = 0xD2, "WORD", Some(2), unsigned(16);
    /// Bit string, 32 bits.
    Dword = 0xD3, "DWORD", Some(4), unsigned(32);
    /// Bit string, 64 bits.
    Lword = 0xD4, "LWORD", Some(8), unsigned(64);
    /// Character string, 2 bytes per character.
    String2 = 0xD5, "STRING2", None, None;
    /// Duration, high resolution, 32-bit.
    Ftime = 0xD6, "FTIME", Some(4), signed(32);
    /// Duration, long, 64-bit.
    Ltime = 0xD7, "LTIME", Some(8), signed(64);
    /// Duration, short, 16-bit.
    Itime = 0xD8, "ITIME", Some(2), signed(16);
    /// Character string, N bytes per character.
    StringN = 0xD9, "STRINGN", None, None;
    /// Character string, 1 byte per character, 8-bit length prefix.
    ShortString = 0xDA, "SHORT_STRING", None, None;
    /// Duration, milliseconds, 32-bit.
    Time = 0xDB, "TIME", Some(4), signed(32);
    /// CIP path segments.
    Epath = 0xDC, "EPATH", None, None;
    /// Engineering units, 16-bit.
    EngUnit = 0xDD, "ENGUNIT", Some(2), unsigned(16);
    /// International character string.
    StringI = 0xDE, "STRINGI", None, None;
}

impl DataType {
    /// `true` for `REAL` and `LREAL`.
    pub const fn is_real(self) -> bool {
        matches!(self, DataType::Real | DataType::Lreal)
    }

    /// `true` for the character string types.
    pub const fn is_string(self) -> bool {
        matches!(
            self,
            DataType::String
                | DataType::String2
                | DataType::StringN
                | DataType::ShortString
                | DataType::StringI
        )
    }
}

impl fmt::Display for DataType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name() {
            Some(name) => f.write_str(name),
            None => write!(f, "0x{:02X}", self.code()),
        }
    }
}

impl Serialize for DataType {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.to_string())
    }
}

/// The descriptor word of a parameter (the Parameter object's Descriptor attribute bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct Descriptor(pub u16);

impl Descriptor {
    /// Bit 0: the link path may be set.
    pub const SETTABLE_PATH: u16 = 1 << 0;
    /// Bit 1: enumerated strings are supported.
    pub const ENUMERATED_STRINGS: u16 = 1 << 1;
    /// Bit 2: scaling is supported.
    pub const SCALING: u16 = 1 << 2;
    /// Bit 3: scaling links are supported.
    pub const SCALING_LINKS: u16 = 1 << 3;
    /// Bit 4: the parameter is read only.
    pub const READ_ONLY: u16 = 1 << 4;
    /// Bit 5: the parameter is a monitor parameter (changes by itself).
    pub const MONITOR: u16 = 1 << 5;
    /// Bit 6: extended precision scaling.
    pub const EXTENDED_PRECISION: u16 = 1 << 6;

    /// `true` when every bit of `mask` is set.
    pub const fn has(self, mask: u16) -> bool {
        self.0 & mask == mask
    }

    /// Bit 1.
    pub const fn enumerated_strings(self) -> bool {
        self.has(Self::ENUMERATED_STRINGS)
    }

    /// Bit 2.
    pub const fn scaling(self) -> bool {
        self.has(Self::SCALING)
    }

    /// Bit 4.
    pub const fn read_only(self) -> bool {
        self.has(Self::READ_ONLY)
    }

    /// Bit 5.
    pub const fn monitor(self) -> bool {
        self.has(Self::MONITOR)
    }
}

/// The I/O connection types of `[IO_Info]` masks: bit 0 poll, 1 bit-strobe, 2 change of state,
/// 3 cyclic.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct ConnectionMask(pub u16);

impl ConnectionMask {
    /// Bit 0: polled I/O.
    pub const POLL: u16 = 1 << 0;
    /// Bit 1: bit-strobed I/O.
    pub const STROBE: u16 = 1 << 1;
    /// Bit 2: change-of-state I/O.
    pub const COS: u16 = 1 << 2;
    /// Bit 3: cyclic I/O.
    pub const CYCLIC: u16 = 1 << 3;
    /// The four defined bits; bits 4–15 are reserved.
    pub const ALL: u16 = Self::POLL | Self::STROBE | Self::COS | Self::CYCLIC;

    /// `true` when every bit of `mask` is set.
    pub const fn has(self, mask: u16) -> bool {
        self.0 & mask == mask
    }

    /// The names of the set bits (`poll`, `strobe`, `cos`, `cyclic`, `bitN` for others).
    pub fn names(self) -> Vec<String> {
        (0..16)
            .filter(|bit| self.0 & (1 << bit) != 0)
            .map(|bit| match bit {
                0 => "poll".to_string(),
                1 => "strobe".to_string(),
                2 => "cos".to_string(),
                3 => "cyclic".to_string(),
                other => format!("bit{other}"),
            })
            .collect()
    }
}

impl fmt::Display for ConnectionMask {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "0x{:04X}", self.0)?;
        let names = self.names();
        if !names.is_empty() {
            write!(f, " ({})", names.join(", "))?;
        }
        Ok(())
    }
}

/// A class/instance/attribute address decoded from a logical EPATH.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct AttributePath {
    /// Class ID.
    pub class: u16,
    /// Instance ID.
    pub instance: u16,
    /// Attribute ID, when the path has one.
    pub attribute: Option<u16>,
}

impl fmt::Display for AttributePath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "class 0x{:02X} instance {}", self.class, self.instance)?;
        if let Some(attribute) = self.attribute {
            write!(f, " attribute {attribute}")?;
        }
        Ok(())
    }
}

/// A path as written in an EDS string field (`"20 05 24 02 30 64"`).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum LinkPath {
    /// Hex bytes.
    Bytes(Vec<u8>),
    /// Anything else (paths with parameter references such as `[Param3]`, vendor notations),
    /// kept as written.
    Symbolic(String),
}

impl LinkPath {
    /// Reads a path string: whitespace-separated hex bytes, else [`LinkPath::Symbolic`].
    pub fn parse(text: &str) -> LinkPath {
        let bytes: Option<Vec<u8>> = text
            .split_whitespace()
            .map(|byte| if byte.len() <= 2 { u8::from_str_radix(byte, 16).ok() } else { None })
            .collect();
        match bytes {
            Some(bytes) => LinkPath::Bytes(bytes),
            None => LinkPath::Symbolic(text.to_string()),
        }
    }

    /// The bytes of a hex path.
    pub fn bytes(&self) -> Option<&[u8]> {
        match self {
            LinkPath::Bytes(bytes) => Some(bytes),
            LinkPath::Symbolic(_) => None,
        }
    }

    /// The class/instance(/attribute) address of a logical path made of 8- or 16-bit class,
    /// instance and attribute segments (`20 cc 24 ii 30 aa`, `21 00 cc cc ...`).
    pub fn attribute(&self) -> Option<AttributePath> {
        let mut bytes = self.bytes()?;
        let mut segment = |kinds: (u8, u8)| -> Option<u16> {
            let (&kind, rest) = bytes.split_first()?;
            if kind == kinds.0 {
                let (&value, rest) = rest.split_first()?;
                bytes = rest;
                Some(u16::from(value))
            } else if kind == kinds.1 {
                match rest {
                    [_pad, lo, hi, rest @ ..] => {
                        bytes = rest;
                        Some(u16::from_le_bytes([*lo, *hi]))
                    }
                    _ => None,
                }
            } else {
                None
            }
        };
        let class = segment((0x20, 0x21))?;
        let instance = segment((0x24, 0x25))?;
        let attribute = segment((0x30, 0x31));
        if !bytes.is_empty() {
            return None;
        }
        Some(AttributePath { class, instance, attribute })
    }
}

impl fmt::Display for LinkPath {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LinkPath::Bytes(bytes) => {
                for (i, byte) in bytes.iter().enumerate() {
                    if i > 0 {
                        f.write_str(" ")?;
                    }
                    write!(f, "{byte:02X}")?;
                }
                Ok(())
            }
            LinkPath::Symbolic(text) => f.write_str(text),
        }
    }
}

impl Serialize for LinkPath {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(&self.to_string())
    }
}

/// A date written `MM-DD-YYYY` in `[File]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Date {
    /// Year, e.g. 2021.
    pub year: u16,
    /// Month, 1..=12.
    pub month: u8,
    /// Day of month, 1..=31.
    pub day: u8,
}

impl Date {
    /// Reads `MM-DD-YYYY`; `None` on another form or an impossible month or day.
    pub fn parse(text: &str) -> Option<Date> {
        let mut parts = text.trim().split('-');
        let (month, day, year) = (parts.next()?, parts.next()?, parts.next()?);
        if parts.next().is_some() || year.len() != 4 || month.len() > 2 || day.len() > 2 {
            return None;
        }
        let date = Date { year: year.parse().ok()?, month: month.parse().ok()?, day: day.parse().ok()? };
        ((1..=12).contains(&date.month) && (1..=31).contains(&date.day)).then_some(date)
    }
}

impl fmt::Display for Date {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:02}-{:02}-{:04}", self.month, self.day, self.year)
    }
}

/// A time of day written `HH:MM:SS` in `[File]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Time {
    /// Hours, 0..=23.
    pub hour: u8,
    /// Minutes, 0..=59.
    pub minute: u8,
    /// Seconds, 0..=59.
    pub second: u8,
}

impl Time {
    /// Reads `HH:MM:SS` (or `HH:MM`); `None` on another form or an impossible time.
    pub fn parse(text: &str) -> Option<Time> {
        let parts: Vec<&str> = text.trim().split(':').collect();
        if !(2..=3).contains(&parts.len()) || parts.iter().any(|p| p.is_empty() || p.len() > 2) {
            return None;
        }
        let number = |p: &str| p.parse::<u8>().ok();
        let time = Time {
            hour: number(parts[0])?,
            minute: number(parts[1])?,
            second: match parts.get(2) {
                Some(p) => number(p)?,
                None => 0,
            },
        };
        (time.hour < 24 && time.minute < 60 && time.second < 60).then_some(time)
    }
}

impl fmt::Display for Time {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:02}:{:02}:{:02}", self.hour, self.minute, self.second)
    }
}

/// An EDS file revision written `major.minor` (`1.1`, `2.10`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Revision {
    /// Major revision.
    pub major: u8,
    /// Minor revision.
    pub minor: u8,
}

impl Revision {
    /// Reads `major.minor` (or a bare `major`, minor 0).
    pub fn parse(text: &str) -> Option<Revision> {
        let text = text.trim();
        let (major, minor) = text.split_once('.').unwrap_or((text, "0"));
        let digits = |p: &str| !p.is_empty() && p.len() <= 3 && p.bytes().all(|b| b.is_ascii_digit());
        if !digits(major) || !digits(minor) {
            return None;
        }
        Some(Revision { major: major.parse().ok()?, minor: minor.parse().ok()? })
    }
}

impl fmt::Display for Revision {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.major, self.minor)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::decimal("283", Some(283))]
    #[case::leading_zeros("0001", Some(1))]
    #[case::negative("-32768", Some(-32768))]
    #[case::plus("+7", Some(7))]
    #[case::hex_lower("0x00c6", Some(0xC6))]
    #[case::hex_upper_x("0X002E", Some(0x2E))]
    #[case::negative_hex("-0x10", Some(-16))]
    #[case::spaces(" 12 ", Some(12))]
    #[case::bare_0x("0x", None)]
    #[case::real("1.5", None)]
    #[case::word("abc", None)]
    #[case::hex_without_prefix("C6", None)]
    #[case::overflow("0xFFFFFFFFFFFFFFFFFFFFFFFFFFFFFFFFFF", None)]
    fn parses_integers(#[case] text: &str, #[case] expected: Option<i128>) {
        assert_eq!(parse_int(text), expected);
    }

    #[rstest]
    #[case::int("42", Value::Int(42))]
    #[case::real("1.5", Value::Real(1.5))]
    #[case::exponent("-2e3", Value::Real(-2000.0))]
    #[case::infinity("inf", Value::Text("inf".into()))]
    #[case::text("Param3", Value::Text("Param3".into()))]
    fn reads_values(#[case] text: &str, #[case] expected: Value) {
        assert_eq!(Value::from_text(text), expected);
    }

    #[rstest]
    #[case::bool(0xC1, Some(1))]
    #[case::sint(0xC2, Some(1))]
    #[case::int(0xC3, Some(2))]
    #[case::dint(0xC4, Some(4))]
    #[case::usint(0xC6, Some(1))]
    #[case::uint(0xC7, Some(2))]
    #[case::udint(0xC8, Some(4))]
    #[case::real(0xCA, Some(4))]
    #[case::byte(0xD1, Some(1))]
    #[case::word(0xD2, Some(2))]
    #[case::dword(0xD3, Some(4))]
    #[case::string(0xD0, None)]
    #[case::short_string(0xDA, None)]
    #[case::unknown(0x42, None)]
    fn data_type_sizes(#[case] code: u16, #[case] size: Option<u32>) {
        let data_type = DataType::from_code(code);
        assert_eq!(data_type.fixed_size(), size);
        assert_eq!(data_type.code(), code);
    }

    #[rstest]
    #[case::usint(DataType::Usint, (0, 255))]
    #[case::sint(DataType::Sint, (-128, 127))]
    #[case::int(DataType::Int, (-32768, 32767))]
    #[case::udint(DataType::Udint, (0, 4_294_967_295))]
    #[case::lint(DataType::Lint, (i128::from(i64::MIN), i128::from(i64::MAX)))]
    fn data_type_ranges(#[case] data_type: DataType, #[case] range: (i128, i128)) {
        assert_eq!(data_type.int_range(), Some(range));
    }

    #[rstest]
    #[case::connection_attr_100("20 05 24 02 30 64", Some(AttributePath { class: 5, instance: 2, attribute: Some(100) }))]
    #[case::assembly_instance("20 04 24 65", Some(AttributePath { class: 4, instance: 0x65, attribute: None }))]
    #[case::sixteen_bit("21 00 0F 00 25 00 2C 01 30 01", Some(AttributePath { class: 0x0F, instance: 300, attribute: Some(1) }))]
    #[case::trailing_bytes("20 05 24 02 30 64 00", None)]
    #[case::symbolic("20 04 24 [Param3]", None)]
    #[case::empty("", None)]
    fn decodes_attribute_paths(#[case] text: &str, #[case] expected: Option<AttributePath>) {
        assert_eq!(LinkPath::parse(text).attribute(), expected);
    }

    #[test]
    fn link_path_prints_upper_case_hex() {
        assert_eq!(LinkPath::parse("20 0f 24 1").to_string(), "20 0F 24 01");
        assert_eq!(LinkPath::parse("[Param1]"), LinkPath::Symbolic("[Param1]".into()));
    }

    #[rstest]
    #[case::ok("01-16-2020", Some(Date { year: 2020, month: 1, day: 16 }))]
    #[case::short_parts("1-6-2020", Some(Date { year: 2020, month: 1, day: 6 }))]
    #[case::month_13("13-01-2020", None)]
    #[case::iso("2020-01-16", None)]
    fn parses_dates(#[case] text: &str, #[case] expected: Option<Date>) {
        assert_eq!(Date::parse(text), expected);
    }

    #[rstest]
    #[case::ok("14:33:53", Some(Time { hour: 14, minute: 33, second: 53 }))]
    #[case::no_seconds("08:05", Some(Time { hour: 8, minute: 5, second: 0 }))]
    #[case::hour_24("24:00:00", None)]
    fn parses_times(#[case] text: &str, #[case] expected: Option<Time>) {
        assert_eq!(Time::parse(text), expected);
    }

    #[rstest]
    #[case::one_one("1.1", Some(Revision { major: 1, minor: 1 }))]
    #[case::two_ten("2.10", Some(Revision { major: 2, minor: 10 }))]
    #[case::bare("3", Some(Revision { major: 3, minor: 0 }))]
    #[case::too_big("300.1", None)]
    #[case::text("v1", None)]
    fn parses_revisions(#[case] text: &str, #[case] expected: Option<Revision>) {
        assert_eq!(Revision::parse(text), expected);
    }

    #[test]
    fn connection_mask_names() {
        assert_eq!(ConnectionMask(0x000D).to_string(), "0x000D (poll, cos, cyclic)");
    }
}
