//! Configuration errors: which field, and what is wrong with it.
//!
//! Every configuration type has a `validate()` returning the first [`ConfigError`] it finds. The
//! error names the field ([`Field`]: a number, spelled `scan.count` where it is written out), the
//! list index when the field is inside a list, and the allowed range, so the device description
//! loader can point at the offending line.

use core::fmt;
use devicenet::text::{self, TextSink};

/// A configuration value that a profile cannot run with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConfigError {
    /// The field (its key dotted from the configuration's root: `framing.max_len`, `scan.count`).
    pub field: Field,
    /// The index in the list the field belongs to (`scan[3]`), if any.
    pub index: Option<u16>,
    /// What is wrong with it.
    pub problem: Problem,
}

/// A field of a serial profile's configuration. A number, not the key: the key texts
/// ([`Field::key`]) are only linked where an error is written out (hosts), not into the firmware,
/// which reports the number ([`Field::code`]) in its refusal record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// `serial.baud`
    SerialBaud,
    /// `serial.data_bits`
    SerialDataBits,
    /// `serial.parity`
    SerialParity,
    /// `framing.max_len`
    FramingMaxLen,
    /// `framing.length`
    FramingLength,
    /// `framing.end`
    FramingEnd,
    /// `health.stale_timeout_ms`
    HealthStaleTimeout,
    /// `status_len`
    StatusLen,
    /// `ack.data_len`
    AckDataLen,
    /// `ack.flag`
    AckFlag,
    /// `commands.code`
    CommandsCode,
    /// `commands.args`
    CommandsArgs,
    /// `commands.wire`
    CommandsWire,
    /// `sequencer.on_idle`
    SequencerOnIdle,
    /// `sequencer.on_fault`
    SequencerOnFault,
    /// `sequencer.response_timeout_ms`
    SequencerResponseTimeout,
    /// `sequencer.retries`
    SequencerRetries,
    /// `response_timeout_ms`
    ResponseTimeout,
    /// `retries`
    Retries,
    /// `poll_period_ms`
    PollPeriod,
    /// `input_len`
    InputLen,
    /// `output_len`
    OutputLen,
    /// `scan`
    Scan,
    /// `scan.unit`
    ScanUnit,
    /// `scan.count`
    ScanCount,
    /// `scan.address`
    ScanAddress,
    /// `scan.offset`
    ScanOffset,
    /// `on_idle`
    OnIdle,
    /// `on_fault`
    OnFault,
    /// `framing` (Modbus)
    ModbusFraming,
    /// `scan.word_order`
    ScanWordOrder,
    /// `scan.period_ms`
    ScanPeriod,
    /// `scan.write`
    ScanWrite,
    /// `scan.trigger_offset`
    ScanTrigger,
    /// `valid_bits_offset`
    ValidBitsOffset,
}

impl Field {
    /// Every field, in code order.
    pub const ALL: [Field; 35] = [
        Field::SerialBaud,
        Field::SerialDataBits,
        Field::SerialParity,
        Field::FramingMaxLen,
        Field::FramingLength,
        Field::FramingEnd,
        Field::HealthStaleTimeout,
        Field::StatusLen,
        Field::AckDataLen,
        Field::AckFlag,
        Field::CommandsCode,
        Field::CommandsArgs,
        Field::CommandsWire,
        Field::SequencerOnIdle,
        Field::SequencerOnFault,
        Field::SequencerResponseTimeout,
        Field::SequencerRetries,
        Field::ResponseTimeout,
        Field::Retries,
        Field::PollPeriod,
        Field::InputLen,
        Field::OutputLen,
        Field::Scan,
        Field::ScanUnit,
        Field::ScanCount,
        Field::ScanAddress,
        Field::ScanOffset,
        Field::OnIdle,
        Field::OnFault,
        Field::ModbusFraming,
        Field::ScanWordOrder,
        Field::ScanPeriod,
        Field::ScanWrite,
        Field::ScanTrigger,
        Field::ValidBitsOffset,
    ];

    /// The key, dotted from the profile's root, as the description file spells it (`scan.count`).
    pub const fn key(self) -> &'static str {
        match self {
            Field::SerialBaud => "serial.baud",
            Field::SerialDataBits => "serial.data_bits",
            Field::SerialParity => "serial.parity",
            Field::FramingMaxLen => "framing.max_len",
            Field::FramingLength => "framing.length",
            Field::FramingEnd => "framing.end",
            Field::HealthStaleTimeout => "health.stale_timeout_ms",
            Field::StatusLen => "status_len",
            Field::AckDataLen => "ack.data_len",
            Field::AckFlag => "ack.flag",
            Field::CommandsCode => "commands.code",
            Field::CommandsArgs => "commands.args",
            Field::CommandsWire => "commands.wire",
            Field::SequencerOnIdle => "sequencer.on_idle",
            Field::SequencerOnFault => "sequencer.on_fault",
            Field::SequencerResponseTimeout => "sequencer.response_timeout_ms",
            Field::SequencerRetries => "sequencer.retries",
            Field::ResponseTimeout => "response_timeout_ms",
            Field::Retries => "retries",
            Field::PollPeriod => "poll_period_ms",
            Field::InputLen => "input_len",
            Field::OutputLen => "output_len",
            Field::Scan => "scan",
            Field::ScanUnit => "scan.unit",
            Field::ScanCount => "scan.count",
            Field::ScanAddress => "scan.address",
            Field::ScanOffset => "scan.offset",
            Field::OnIdle => "on_idle",
            Field::OnFault => "on_fault",
            Field::ModbusFraming => "framing",
            Field::ScanWordOrder => "scan.word_order",
            Field::ScanPeriod => "scan.period_ms",
            Field::ScanWrite => "scan.write",
            Field::ScanTrigger => "scan.trigger_offset",
            Field::ValidBitsOffset => "valid_bits_offset",
        }
    }

    /// Its number in [`Field::ALL`] (the refusal record's).
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The field numbered `code`.
    pub fn from_code(code: u8) -> Option<Field> {
        Field::ALL.get(usize::from(code)).copied()
    }
}

/// What is wrong with a configuration field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Problem {
    /// The value lies outside `min..=max`.
    OutOfRange {
        /// The configured value.
        value: u32,
        /// The smallest allowed value.
        min: u32,
        /// The largest allowed value.
        max: u32,
    },
    /// The field conflicts with another setting; the reason says which and why.
    Conflict(Conflict),
    /// The image bytes of this list entry overlap those of the entry at `other`.
    Overlap {
        /// Index of the entry it overlaps.
        other: u16,
    },
    /// The same key appears again at `other`.
    Duplicate {
        /// Index of the first entry with the same key.
        other: u16,
    },
}

/// Why a field conflicts with another setting ([`Problem::Conflict`]). A code, not the sentence:
/// the words ([`Conflict::text`]) are only linked where an error is written out (hosts), not into
/// the firmware, which reports the code ([`Conflict::code`]) in its refusal record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Conflict {
    /// `framing.end` of a delimited frame is not set.
    NoEndDelimiter,
    /// `framing.end` of a delimited frame equals its start byte.
    EndEqualsStart,
    /// A frame (idle, fault) contains the end delimiter.
    ContainsEndDelimiter,
    /// A command's wire code equals the end delimiter.
    EqualsEndDelimiter,
    /// Modbus RTU with 7 data bits.
    ModbusDataBits,
    /// 7 data bits without parity, which the adapter board's USART cannot make (the firmware's
    /// own check).
    SevenBitsNeedParity,
    /// Modbus TCP framing on a device without a TCP port (the firmware's own check).
    NoTcpPort,
    /// A 32-bit word order on a scan entry that is not a register read or multiple-register
    /// write with an even count.
    WordOrderNeedsPairs,
    /// A `write` mode other than "change" on a read entry.
    WriteModeOnRead,
    /// `write = "cyclic"` without `period_ms`.
    CyclicNeedsPeriod,
    /// `write = "trigger"` without `trigger_offset`.
    TriggerNeedsOffset,
    /// `period_ms` on a write entry that is not `write = "cyclic"`.
    PeriodNeedsCyclic,
    /// `trigger_offset` on a write entry that is not `write = "trigger"`.
    TriggerNeedsTriggerMode,
    /// A read entry with both `period_ms` and `trigger_offset`.
    PeriodOrTrigger,
    /// A `trigger_offset` with no output image.
    TriggerNeedsOutput,
}

impl Conflict {
    /// Every reason, in code order.
    pub const ALL: [Conflict; 15] = [
        Conflict::NoEndDelimiter,
        Conflict::EndEqualsStart,
        Conflict::ContainsEndDelimiter,
        Conflict::EqualsEndDelimiter,
        Conflict::ModbusDataBits,
        Conflict::SevenBitsNeedParity,
        Conflict::NoTcpPort,
        Conflict::WordOrderNeedsPairs,
        Conflict::WriteModeOnRead,
        Conflict::CyclicNeedsPeriod,
        Conflict::TriggerNeedsOffset,
        Conflict::PeriodNeedsCyclic,
        Conflict::TriggerNeedsTriggerMode,
        Conflict::PeriodOrTrigger,
        Conflict::TriggerNeedsOutput,
    ];

    /// The reason in words.
    pub const fn text(self) -> &'static str {
        match self {
            Conflict::NoEndDelimiter => "a delimited frame needs an end byte",
            Conflict::EndEqualsStart => "the end byte of a delimited frame must differ from the start byte",
            Conflict::ContainsEndDelimiter => "contains the end delimiter",
            Conflict::EqualsEndDelimiter => "equals the end delimiter",
            Conflict::ModbusDataBits => "Modbus RTU uses 8 data bits",
            Conflict::SevenBitsNeedParity => "7 data bits need parity on this USART",
            Conflict::NoTcpPort => "Modbus TCP needs a TCP connection, which this device does not have",
            Conflict::WordOrderNeedsPairs => {
                "a 32-bit word order needs function 3, 4 or 16 and an even register count"
            }
            Conflict::WriteModeOnRead => "applies to write entries (functions 5, 6, 15, 16) only",
            Conflict::CyclicNeedsPeriod => "write = \"cyclic\" needs period_ms",
            Conflict::TriggerNeedsOffset => "write = \"trigger\" needs trigger_offset",
            Conflict::PeriodNeedsCyclic => "a write entry takes period_ms with write = \"cyclic\" only",
            Conflict::TriggerNeedsTriggerMode => {
                "a write entry takes trigger_offset with write = \"trigger\" only"
            }
            Conflict::PeriodOrTrigger => "a read entry takes period_ms or trigger_offset, not both",
            Conflict::TriggerNeedsOutput => "a trigger byte needs an output image (output_len is 0)",
        }
    }

    /// Its number in [`Conflict::ALL`] (the refusal record's).
    pub const fn code(self) -> u8 {
        self as u8
    }

    /// The reason numbered `code`.
    pub fn from_code(code: u32) -> Option<Conflict> {
        Conflict::ALL.get(usize::try_from(code).ok()?).copied()
    }
}

impl ConfigError {
    /// An [`Problem::OutOfRange`] error for `field`.
    pub const fn out_of_range(field: Field, value: u32, min: u32, max: u32) -> Self {
        ConfigError { field, index: None, problem: Problem::OutOfRange { value, min, max } }
    }

    /// A [`Problem::Conflict`] error for `field`.
    pub const fn conflict(field: Field, why: Conflict) -> Self {
        ConfigError { field, index: None, problem: Problem::Conflict(why) }
    }

    /// The same error, located at list index `index`.
    pub const fn at(mut self, index: usize) -> Self {
        self.index = Some(if index > u16::MAX as usize { u16::MAX } else { index as u16 });
        self
    }

    /// `Ok` when `min <= value <= max`, otherwise an [`Problem::OutOfRange`] error.
    pub fn check_range(field: Field, value: u32, min: u32, max: u32) -> Result<(), ConfigError> {
        if (min..=max).contains(&value) {
            Ok(())
        } else {
            Err(ConfigError::out_of_range(field, value, min, max))
        }
    }
}

/// Converts a length or offset to `u32` for error reports, saturating.
pub(crate) fn as_u32(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

impl ConfigError {
    /// The field with its list index, as the configuration spells it (`scan[3].count`).
    pub const fn path(&self) -> FieldPath<'_> {
        FieldPath(self)
    }
}

/// [`ConfigError::path`]: displays the field with its list index.
#[derive(Clone, Copy, Debug)]
pub struct FieldPath<'a>(&'a ConfigError);

impl FieldPath<'_> {
    /// Writes the path (the `Display` text) without `core::fmt` ([`devicenet::text`]).
    pub fn write_text(&self, out: &mut impl TextSink) {
        self.0.field.write_path(self.0.index, out);
    }
}

impl Field {
    /// Writes the key with the list index `index`, if any, as the configuration spells it:
    /// `scan[3].count` (the list name is the part before the first dot).
    pub fn write_path(self, index: Option<u16>, out: &mut impl TextSink) {
        let field = self.key();
        let Some(i) = index else {
            return out.text(field);
        };
        // A plain loop, not `split_once`: that would pull in `memchr` (flash). The rest keeps its
        // dot.
        let dot = field.bytes().position(|b| b == b'.').unwrap_or(field.len());
        let (list, rest) = field.split_at_checked(dot).unwrap_or((field, ""));
        out.text(list);
        out.text("[");
        out.decimal(u32::from(i));
        out.text("]");
        out.text(rest);
    }
}

impl fmt::Display for FieldPath<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

impl Problem {
    /// Writes the message (the `Display` text) without `core::fmt` ([`devicenet::text`]).
    pub fn write_text(&self, out: &mut impl TextSink) {
        match *self {
            Problem::OutOfRange { value, min, max } => {
                out.decimal(value);
                out.text(" is outside the allowed range ");
                out.decimal(min);
                out.text("..=");
                out.decimal(max);
            }
            Problem::Conflict(why) => out.text(why.text()),
            Problem::Overlap { other } => {
                out.text("overlaps the image bytes of entry ");
                out.decimal(u32::from(other));
            }
            Problem::Duplicate { other } => {
                out.text("duplicates entry ");
                out.decimal(u32::from(other));
            }
        }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

impl ConfigError {
    /// Writes `path: problem` (the `Display` text) without `core::fmt` ([`devicenet::text`]).
    pub fn write_text(&self, out: &mut impl TextSink) {
        self.path().write_text(out);
        out.text(": ");
        self.problem.write_text(out);
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

impl core::error::Error for ConfigError {}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;
    use std::string::ToString;

    #[rstest]
    #[case::plain(
        ConfigError::out_of_range(Field::SerialBaud, 5, 300, 4_000_000),
        "serial.baud: 5 is outside the allowed range 300..=4000000"
    )]
    #[case::indexed(ConfigError::out_of_range(Field::ScanCount, 200, 1, 125).at(3), "scan[3].count: 200 is outside the allowed range 1..=125")]
    #[case::overlap(ConfigError { field: Field::ScanOffset, index: Some(2), problem: Problem::Overlap { other: 0 } }, "scan[2].offset: overlaps the image bytes of entry 0")]
    #[case::conflict(
        ConfigError::conflict(Field::FramingEnd, Conflict::NoEndDelimiter),
        "framing.end: a delimited frame needs an end byte"
    )]
    #[case::list_itself(ConfigError::out_of_range(Field::Scan, 9, 0, 8).at(8), "scan[8]: 9 is outside the allowed range 0..=8")]
    fn display(#[case] e: ConfigError, #[case] text: &str) {
        assert_eq!(e.to_string(), text);
    }

    #[test]
    fn conflict_codes_are_their_place_in_all() {
        for (i, c) in Conflict::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(c.code()), i);
            assert_eq!(Conflict::from_code(i as u32), Some(c));
        }
        assert_eq!(Conflict::from_code(Conflict::ALL.len() as u32), None);
    }

    #[test]
    fn field_codes_are_their_place_in_all_and_keys_are_unique() {
        for (i, f) in Field::ALL.into_iter().enumerate() {
            assert_eq!(usize::from(f.code()), i);
            assert_eq!(Field::from_code(i as u8), Some(f));
            assert_eq!(Field::ALL.iter().filter(|g| g.key() == f.key()).count(), 1, "{}", f.key());
        }
        assert_eq!(Field::from_code(Field::ALL.len() as u8), None);
    }

    #[test]
    fn check_range_bounds_are_inclusive() {
        assert!(ConfigError::check_range(Field::Retries, 1, 1, 3).is_ok());
        assert!(ConfigError::check_range(Field::Retries, 3, 1, 3).is_ok());
        assert!(ConfigError::check_range(Field::Retries, 4, 1, 3).is_err());
    }
}
