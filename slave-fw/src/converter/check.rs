//! The value rules of a [`ConverterConfig`], in one place: the TOML device description loader
//! (`slave_fw::description`) and the configuration image decoder ([`super::image::decode`]) both
//! call [`ConverterConfig::check`], so a value refused by either is refused with the same key and
//! the same words (`profile.modbus.scan[1].offset: 30 is outside the allowed range 0..=4`).
//!
//! What stays with the loader is only what TOML has and the image has not: syntax, unknown keys,
//! names for enumerations (`baud_rate = "250k"`) and the optional `io.*_size` cross-checks.

use super::ConverterConfig;
use crate::serial::{ConfigError, Field, ProfileConfig};
use core::fmt;
use devicenet::slave::config::MAX_PRODUCT_NAME;
use devicenet::slave::ConfigError as NodeConfigError;
use devicenet::slave::DeviceConfig;
use devicenet::text::{self, TextSink};

/// A configuration value the converter cannot run with: the key as the description file spells
/// it ([`InvalidConfig::key`]) and why ([`InvalidConfig::message`]). `Display` gives
/// `key: message`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InvalidConfig {
    /// `identity.product_name` is empty or longer than [`MAX_PRODUCT_NAME`] (its length).
    ProductNameLength(usize),
    /// `identity.product_name` is not printable ASCII.
    ProductNameNotAscii,
    /// `identity.major_revision` is outside 1..=127.
    MajorRevision(u8),
    /// `network.mac_id` is outside 0..=63.
    MacId(u8),
    /// `network.baud_rate` is not a DeviceNet baud rate code (0, 1, 2); only an image can say so.
    BaudRate(u8),
    /// `network.epr_resolution_ms` is 0.
    EprResolutionZero,
    /// A value of the serial profile (`profile.…` or `profile.modbus.…`).
    Profile {
        /// Whether the profile is Modbus (its keys are under `profile.modbus`).
        modbus: bool,
        /// The profile's own error.
        error: ConfigError,
    },
    /// The node refuses the derived I/O configuration (`io`).
    Io(NodeConfigError),
}

impl InvalidConfig {
    /// The dotted key, as in the description file.
    pub const fn key(&self) -> Key<'_> {
        Key(self)
    }

    /// The key as numbers, for the device's refusal record.
    pub const fn key_code(&self) -> KeyCode {
        let (scope, number, index) = match self {
            InvalidConfig::ProductNameLength(_) | InvalidConfig::ProductNameNotAscii => (0, 0, None),
            InvalidConfig::MajorRevision(_) => (0, 1, None),
            InvalidConfig::MacId(_) => (0, 2, None),
            InvalidConfig::BaudRate(_) => (0, 3, None),
            InvalidConfig::EprResolutionZero => (0, 4, None),
            InvalidConfig::Io(_) => (0, 5, None),
            InvalidConfig::Profile { modbus, error } => {
                (if *modbus { 2 } else { 1 }, error.field.code(), error.index)
            }
        };
        KeyCode::new(scope, number, index)
    }

    /// What is wrong with the value.
    pub const fn message(&self) -> Message<'_> {
        Message(self)
    }
}

/// [`InvalidConfig::key`]: displays the dotted key.
#[derive(Clone, Copy, Debug)]
pub struct Key<'a>(&'a InvalidConfig);

/// [`InvalidConfig::message`]: displays what is wrong.
#[derive(Clone, Copy, Debug)]
pub struct Message<'a>(&'a InvalidConfig);

impl Key<'_> {
    /// Writes the key (the `Display` text) without `core::fmt` ([`devicenet::text`]).
    pub fn write_text(&self, out: &mut impl TextSink) {
        self.0.key_code().write_text(out);
    }
}

/// The keys outside the serial profile, in the order of their numbers in a [`KeyCode`].
const TOP_KEYS: [&str; 6] = [
    "identity.product_name",
    "identity.major_revision",
    "network.mac_id",
    "network.baud_rate",
    "network.epr_resolution_ms",
    "io",
];

/// A key of the configuration as numbers ([`InvalidConfig::key_code`]): what the device's refusal
/// record carries instead of the key's text, which only hosts link ([`KeyCode::write_text`]).
///
/// ```text
/// byte  value
/// 0     scope: 0 outside the profile, 1 the framed profile (`profile.`), 2 Modbus (`profile.modbus.`)
/// 1     outside the profile: 0 identity.product_name, 1 identity.major_revision, 2 network.mac_id,
///       3 network.baud_rate, 4 network.epr_resolution_ms, 5 io; in a profile: its `Field::code`
/// 2-3   list index (UINT), 0xFFFF for none
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyCode(pub [u8; 4]);

impl KeyCode {
    /// The key's code: `scope`, `number` and list `index` (see the type's table).
    pub const fn new(scope: u8, number: u8, index: Option<u16>) -> KeyCode {
        let [lo, hi] = match index {
            Some(i) => i.to_le_bytes(),
            None => [0xFF, 0xFF],
        };
        KeyCode([scope, number, lo, hi])
    }

    /// Writes the key the code stands for, as the description file spells it
    /// (`profile.modbus.scan[1].offset`); a number no key has is written as such.
    pub fn write_text(&self, out: &mut impl TextSink) {
        let [scope, number, lo, hi] = self.0;
        let index = match u16::from_le_bytes([lo, hi]) {
            u16::MAX => None,
            i => Some(i),
        };
        let prefix = match scope {
            0 => match TOP_KEYS.get(usize::from(number)) {
                Some(key) => return out.text(key),
                None => "",
            },
            1 => "profile.",
            2 => "profile.modbus.",
            other => {
                out.text("(key of unknown scope ");
                out.decimal(other.into());
                return out.text(")");
            }
        };
        out.text(prefix);
        match Field::from_code(number).filter(|_| scope != 0) {
            Some(field) => field.write_path(index, out),
            None => {
                out.text("(unknown key ");
                out.decimal(number.into());
                out.text(")");
            }
        }
    }
}

impl fmt::Display for Key<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

impl Message<'_> {
    /// Writes what is wrong (the `Display` text) without `core::fmt` ([`devicenet::text`]).
    pub fn write_text(&self, out: &mut impl TextSink) {
        match self.0 {
            InvalidConfig::ProductNameLength(n) => {
                out.decimal(u32::try_from(*n).unwrap_or(u32::MAX));
                out.text(" characters, allowed 1..=");
                out.decimal(MAX_PRODUCT_NAME as u32);
            }
            InvalidConfig::ProductNameNotAscii => out.text("must be printable ASCII"),
            InvalidConfig::MajorRevision(v) => {
                out.decimal(u32::from(*v));
                out.text(" is outside 1..=127");
            }
            InvalidConfig::MacId(v) => {
                out.decimal(u32::from(*v));
                out.text(" is outside 0..=63");
            }
            InvalidConfig::BaudRate(v) => {
                out.decimal(u32::from(*v));
                out.text(" is not a baud rate code (0 125k, 1 250k, 2 500k)");
            }
            InvalidConfig::EprResolutionZero => out.text("0 is outside 1..=65535"),
            InvalidConfig::Profile { error, .. } => error.problem.write_text(out),
            InvalidConfig::Io(e) => e.write_text(out),
        }
    }
}

impl fmt::Display for Message<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

impl InvalidConfig {
    /// Writes `key: message` (the `Display` text) without `core::fmt` ([`devicenet::text`]).
    pub fn write_text(&self, out: &mut impl TextSink) {
        self.key().write_text(out);
        out.text(": ");
        self.message().write_text(out);
    }
}

impl fmt::Display for InvalidConfig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

impl core::error::Error for InvalidConfig {}

impl ConverterConfig {
    /// Checks every value the converter runs with, and returns the first one refused, named by
    /// its description-file key. The MAC ID and baud rate are typed and always valid here; their
    /// raw forms are checked where they are read ([`InvalidConfig::MacId`],
    /// [`InvalidConfig::BaudRate`]).
    pub fn check(&self) -> Result<(), InvalidConfig> {
        self.check_with(&self.device_config())
    }

    /// [`ConverterConfig::check`] for a configuration whose device half is derived already, equal
    /// to its [`ConverterConfig::device_config`] ([`super::image::decode`] builds it so): the node's
    /// check reads the device half in place, not a copy of it (firmware size).
    pub(crate) fn check_derived(&self) -> Result<(), InvalidConfig> {
        self.check_with(&self.device)
    }

    /// [`ConverterConfig::check`], with `device` the device half with its derived values.
    fn check_with(&self, device: &DeviceConfig) -> Result<(), InvalidConfig> {
        let id = &self.device.identity;
        let name_len = id.product_name.len();
        if name_len == 0 || name_len > MAX_PRODUCT_NAME {
            return Err(InvalidConfig::ProductNameLength(name_len));
        }
        if !id.product_name.bytes().all(|b| (0x20..0x7F).contains(&b)) {
            return Err(InvalidConfig::ProductNameNotAscii);
        }
        if !(1..=127).contains(&id.major_revision) {
            return Err(InvalidConfig::MajorRevision(id.major_revision));
        }
        if self.device.epr_resolution_ms == 0 {
            return Err(InvalidConfig::EprResolutionZero);
        }
        let modbus = matches!(self.profile, ProfileConfig::Modbus(_));
        self.profile.validate().map_err(|error| InvalidConfig::Profile { modbus, error })?;
        device.validate().map_err(InvalidConfig::Io)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::modbus::{Function, ModbusConfig, ScanEntry};
    use rstest::rstest;
    use std::string::ToString;

    fn modbus() -> ConverterConfig {
        let scan = heapless::Vec::from_iter([
            ScanEntry {
                unit: 1,
                function: Function::ReadInputRegisters,
                address: 0,
                count: 2,
                offset: 0,
                word_order: Default::default(),
                period_ms: None,
                write: Default::default(),
                trigger_offset: None,
            },
            ScanEntry {
                unit: 1,
                function: Function::ReadInputRegisters,
                address: 8,
                count: 1,
                offset: 30,
                word_order: Default::default(),
                period_ms: None,
                write: Default::default(),
                trigger_offset: None,
            },
        ]);
        let mut m = ModbusConfig::new(scan);
        m.input_len = 8;
        ConverterConfig { profile: ProfileConfig::Modbus(m), ..ConverterConfig::breaker_reference() }
    }

    #[rstest]
    #[case::reference(ConverterConfig::breaker_reference(), None)]
    #[case::modbus_offset(
        modbus(),
        Some("profile.modbus.scan[1].offset: 30 is outside the allowed range 0..=6")
    )]
    #[case::major(
        { let mut c = ConverterConfig::breaker_reference(); c.device.identity.major_revision = 0; c },
        Some("identity.major_revision: 0 is outside 1..=127")
    )]
    #[case::empty_name(
        { let mut c = ConverterConfig::breaker_reference(); c.device.identity.product_name.clear(); c },
        Some("identity.product_name: 0 characters, allowed 1..=32")
    )]
    #[case::epr(
        { let mut c = ConverterConfig::breaker_reference(); c.device.epr_resolution_ms = 0; c },
        Some("network.epr_resolution_ms: 0 is outside 1..=65535")
    )]
    #[case::framed_health(
        { let mut c = ConverterConfig::breaker_reference();
          if let ProfileConfig::Framed(f) = &mut c.profile { f.health.stale_timeout_ms = 0 } c },
        Some("profile.health.stale_timeout_ms: 0 is outside the allowed range 1..=3600000")
    )]
    fn check(#[case] config: ConverterConfig, #[case] expected: Option<&str>) {
        assert_eq!(config.check().err().map(|e| e.to_string()).as_deref(), expected);
    }

    #[test]
    fn raw_network_values() {
        assert_eq!(InvalidConfig::MacId(70).to_string(), "network.mac_id: 70 is outside 0..=63");
        assert_eq!(InvalidConfig::BaudRate(3).key().to_string(), "network.baud_rate");
    }
}
