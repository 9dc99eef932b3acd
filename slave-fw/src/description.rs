//! The device description file: one TOML file describes a converter for the soft slave, the
//! firmware build and the EDS generator (style.md practice 9: one source of truth).
//!
//! ```toml
//! [identity]
//! vendor_id = 0x1234            # your ODVA vendor ID (0x1234 is a placeholder)
//! vendor_name = "Example Automation"
//! device_type = 0x000C          # communications adapter
//! product_code = 1
//! major_revision = 1
//! minor_revision = 1
//! serial_number = 0x12345678
//! product_name = "Serial-DeviceNet Bridge"
//! catalog = "SDN-1"
//!
//! [network]
//! mac_id = 5
//! baud_rate = "250k"            # "125k", "250k" or "500k"
//! bus_off_interrupt = false
//!
//! [io]
//! input_assembly = "plain"      # "plain" (instance 100) or "with_status" (101)
//!
//! [profile]
//! kind = "breaker"              # "breaker", "framed" or "modbus"
//! ```
//!
//! Every field is checked; an error names the file, the key (`profile.modbus.scan[1].offset`),
//! the value and the allowed range, or the line and column of a syntax error. Unknown keys are
//! errors too, in every table at every depth, so a misspelt setting never goes unnoticed: every
//! configuration type read from the file refuses keys it does not know (`deny_unknown_fields`;
//! none is flattened or untagged, which would defeat it), and the error gives the line, the column
//! and the dotted key (`breaker.toml: TOML parse error at line 36, column 1:
//! profile.serial.parityy: unknown key ...`). The complete reference, with every optional key, is
//! in the guide (docs/src/reference/description-file.md) and in `slave-fw/descriptions/`.

use crate::converter::{ConverterConfig, InputAssembly, InvalidConfig};
use crate::serial::modbus::units::valid_bits_len;
use crate::serial::modbus::{ByteOrder, Framing, ModbusConfig, ScanEntry, SCAN_LIST_CAPACITY};
use crate::serial::{
    FramedProfileConfig, HealthConfig, IdleAction, ProfileConfig, SequencerConfig, SerialSettings,
    IMAGE_CAPACITY,
};
use devicenet::slave::{BaudRate, DeviceConfig, Identity, Switches};
use devicenet::MacId;
use serde::Deserialize;
use std::fmt;
use std::path::{Path, PathBuf};

/// A parsed and validated device description.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceDescription {
    /// What the converter runs with.
    pub converter: ConverterConfig,
    /// The vendor's name (EDS `VendName`).
    pub vendor_name: String,
    /// The catalog number (EDS `Catalog`).
    pub catalog: String,
}

/// Why a description was refused.
#[derive(Debug)]
pub struct DescriptionError {
    /// The file, when the description came from one.
    pub file: Option<PathBuf>,
    /// What is wrong.
    pub kind: DescriptionErrorKind,
}

/// What is wrong with a description.
#[derive(Debug)]
pub enum DescriptionErrorKind {
    /// The file could not be read.
    Io(std::io::Error),
    /// TOML syntax, a missing or unknown key, or a value of the wrong type, where it is.
    Toml(TomlError),
    /// A value outside its range or in conflict with another.
    Invalid {
        /// The dotted key.
        key: String,
        /// Why.
        message: String,
        /// The 1-based line of the key in the text (of the nearest enclosing entry when the key
        /// itself is not written, a default), when the text was parsed.
        line: Option<usize>,
    },
}

impl fmt::Display for DescriptionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{}: ", file.display())?;
        }
        match &self.kind {
            DescriptionErrorKind::Io(e) => write!(f, "cannot read the device description: {e}"),
            DescriptionErrorKind::Toml(e) => write!(f, "{e}"),
            DescriptionErrorKind::Invalid { key, message, line: Some(line) } => {
                write!(f, "line {line}: {key}: {message}")
            }
            DescriptionErrorKind::Invalid { key, message, line: None } => write!(f, "{key}: {message}"),
        }
    }
}

impl std::error::Error for DescriptionError {}

/// What the TOML reader refused, and where: the line and column (1-based, counted in characters)
/// and the dotted key there (`profile.modbus.scan[1].offset`; none for a syntax error outside any
/// key).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TomlError {
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
    /// The dotted key at that place, when there is one.
    pub key: Option<String>,
    /// What is wrong (`unknown key `parityy`, expected one of ...`, `missing field `parity``).
    pub message: String,
}

impl fmt::Display for TomlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "TOML parse error at line {}, column {}: ", self.line, self.column)?;
        if let Some(key) = &self.key {
            write!(f, "{key}: ")?;
        }
        f.write_str(&self.message)
    }
}

impl TomlError {
    /// Locates `e` in `text`: its line and column, and the dotted key of the innermost entry
    /// whose key or value holds the error's first character (a table header stands for its
    /// table: a missing key is reported there). Serde's "unknown field" is called a key, as TOML
    /// names it.
    fn new(e: &toml::de::Error, text: &str) -> TomlError {
        let at = e.span().map_or(0, |s| s.start).min(text.len());
        let before = text.get(..at).unwrap_or_default();
        let line = before.matches('\n').count() + 1;
        let column = before.rsplit('\n').next().unwrap_or_default().chars().count() + 1;
        let key = toml::de::DeTable::parse(text).ok().and_then(|root| {
            let mut best = None;
            key_at(root.get_ref(), at, &mut String::new(), &mut best);
            best
        });
        let message = e.message().trim_end();
        let message = match message.strip_prefix("unknown field ") {
            Some(rest) => format!("unknown key {rest}"),
            None => message.to_string(),
        };
        TomlError { line, column, key, message }
    }
}

/// Finds the deepest entry of `table` (at dotted `path`) whose key or value span holds `at`, into
/// `best`.
fn key_at(table: &toml::de::DeTable<'_>, at: usize, path: &mut String, best: &mut Option<String>) {
    for (key, value) in table {
        let len = path.len();
        if !path.is_empty() {
            path.push('.');
        }
        path.push_str(key.get_ref());
        value_at(value, key.span().contains(&at), at, path, best);
        path.truncate(len);
    }
}

fn value_at(
    value: &toml::Spanned<toml::de::DeValue<'_>>,
    on_key: bool,
    at: usize,
    path: &mut String,
    best: &mut Option<String>,
) {
    if on_key || value.span().contains(&at) {
        *best = Some(path.clone());
    }
    match value.get_ref() {
        toml::de::DeValue::Table(t) => key_at(t, at, path, best),
        toml::de::DeValue::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                let len = path.len();
                path.push_str(&format!("[{i}]"));
                value_at(item, false, at, path, best);
                path.truncate(len);
            }
        }
        _ => {}
    }
}

fn invalid(key: impl Into<String>, message: impl Into<String>) -> DescriptionErrorKind {
    DescriptionErrorKind::Invalid { key: key.into(), message: message.into(), line: None }
}

/// The 1-based line of dotted `key` (`profile.modbus.scan[1].word_order`) in `text`, or of the
/// deepest entry on its path that the text writes.
fn line_of(text: &str, key: &str) -> Option<usize> {
    let root = toml::de::DeTable::parse(text).ok()?;
    let mut best: Option<(usize, usize)> = None;
    entry_at(root.get_ref(), key, &mut String::new(), &mut best);
    let at = best?.1.min(text.len());
    Some(text.get(..at).unwrap_or_default().matches('\n').count() + 1)
}

/// Records in `best` (path length, key start) the deepest entry of `table` at `path` that `key`
/// runs through.
fn entry_at(table: &toml::de::DeTable<'_>, key: &str, path: &mut String, best: &mut Option<(usize, usize)>) {
    for (k, value) in table {
        let len = path.len();
        if !path.is_empty() {
            path.push('.');
        }
        path.push_str(k.get_ref());
        entry_value(value, k.span().start, key, path, best);
        path.truncate(len);
    }
}

fn entry_value(
    value: &toml::Spanned<toml::de::DeValue<'_>>,
    start: usize,
    key: &str,
    path: &mut String,
    best: &mut Option<(usize, usize)>,
) {
    let on_path = key
        .strip_prefix(path.as_str())
        .is_some_and(|rest| rest.is_empty() || rest.starts_with('.') || rest.starts_with('['));
    if !on_path {
        return;
    }
    if best.is_none_or(|(n, _)| path.len() > n) {
        *best = Some((path.len(), start));
    }
    match value.get_ref() {
        toml::de::DeValue::Table(t) => entry_at(t, key, path, best),
        toml::de::DeValue::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                let len = path.len();
                path.push_str(&format!("[{i}]"));
                entry_value(item, item.span().start, key, path, best);
                path.truncate(len);
            }
        }
        _ => {}
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    identity: IdentitySection,
    network: NetworkSection,
    #[serde(default)]
    io: IoSection,
    profile: ProfileSection,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IdentitySection {
    vendor_id: u16,
    #[serde(default)]
    vendor_name: String,
    device_type: u16,
    product_code: u16,
    major_revision: u8,
    minor_revision: u8,
    serial_number: u32,
    product_name: String,
    #[serde(default)]
    catalog: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NetworkSection {
    mac_id: u8,
    baud_rate: String,
    #[serde(default)]
    bus_off_interrupt: bool,
    #[serde(default = "one")]
    epr_resolution_ms: u16,
    #[serde(default)]
    programmable: bool,
}

fn one() -> u16 {
    1
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct IoSection {
    #[serde(default)]
    input_assembly: InputAssembly,
    produced_size: Option<u16>,
    consumed_size: Option<u16>,
}

#[derive(Deserialize, Clone, Copy, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
enum ProfileKind {
    Breaker,
    Framed,
    Modbus,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProfileSection {
    kind: ProfileKind,
    /// Breaker: overrides of the preset.
    serial: Option<SerialSettings>,
    health: Option<HealthConfig>,
    sequencer: Option<SequencerConfig>,
    /// `kind = "framed"`: the whole framed-profile configuration.
    framed: Option<FramedProfileConfig>,
    /// `kind = "modbus"`.
    modbus: Option<ModbusSection>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModbusSection {
    serial: Option<SerialSettings>,
    framing: Option<Framing>,
    response_timeout_ms: Option<u32>,
    retries: Option<u8>,
    poll_period_ms: Option<u32>,
    byte_order: Option<ByteOrder>,
    health: Option<HealthConfig>,
    on_idle: Option<IdleAction>,
    on_fault: Option<IdleAction>,
    valid_bits_offset: Option<u16>,
    scan: Vec<ScanEntry>,
}

impl DeviceDescription {
    /// The built-in description: the reference converter with the breaker (guide:
    /// docs/src/reference/description-file.md).
    pub fn reference() -> DeviceDescription {
        DeviceDescription {
            converter: ConverterConfig::breaker_reference(),
            vendor_name: "Example Automation".into(),
            catalog: "SDN-1".into(),
        }
    }

    /// Reads and validates a description file.
    pub fn load(path: &Path) -> Result<DeviceDescription, DescriptionError> {
        let with_file = |kind| DescriptionError { file: Some(path.to_path_buf()), kind };
        let text = std::fs::read_to_string(path).map_err(|e| with_file(DescriptionErrorKind::Io(e)))?;
        Self::parse(&text).map_err(|e| with_file(e.kind))
    }

    /// Parses and validates description text.
    pub fn parse(text: &str) -> Result<DeviceDescription, DescriptionError> {
        let no_file = |kind| DescriptionError { file: None, kind };
        let file: File = toml::from_str(text)
            .map_err(|e| no_file(DescriptionErrorKind::Toml(TomlError::new(&e, text))))?;
        build(file).map_err(|kind| match kind {
            DescriptionErrorKind::Invalid { line: None, key, message } => {
                no_file(DescriptionErrorKind::Invalid { line: line_of(text, &key), key, message })
            }
            other => no_file(other),
        })
    }
}

impl From<InvalidConfig> for DescriptionErrorKind {
    fn from(e: InvalidConfig) -> Self {
        invalid(e.key().to_string(), e.message().to_string())
    }
}

/// Builds the configuration from the file. Only what is TOML's own is checked here (the product
/// name's length before it is stored, the MAC ID's raw number, baud rate names, which tables go
/// with which profile kind, the optional `io.*_size` cross-checks); every value rule is
/// [`ConverterConfig::check`], shared with the configuration image decoder.
fn build(file: File) -> Result<DeviceDescription, DescriptionErrorKind> {
    let id = file.identity;
    let mut product_name = heapless::String::new();
    if product_name.push_str(&id.product_name).is_err() {
        return Err(InvalidConfig::ProductNameLength(id.product_name.len()).into());
    }
    let net = file.network;
    let mac_id = MacId::new(net.mac_id).ok_or(InvalidConfig::MacId(net.mac_id))?;
    let baud_rate = match net.baud_rate.to_ascii_lowercase().as_str() {
        "125k" | "125000" => BaudRate::Kbps125,
        "250k" | "250000" => BaudRate::Kbps250,
        "500k" | "500000" => BaudRate::Kbps500,
        other => {
            return Err(invalid(
                "network.baud_rate",
                format!("\"{other}\" is not one of \"125k\", \"250k\", \"500k\""),
            ))
        }
    };
    let device = DeviceConfig {
        identity: Identity {
            vendor_id: id.vendor_id,
            device_type: id.device_type,
            product_code: id.product_code,
            major_revision: id.major_revision,
            minor_revision: id.minor_revision,
            serial_number: id.serial_number,
            product_name,
        },
        mac_id,
        baud_rate,
        port: 0,
        bus_off_interrupt: net.bus_off_interrupt,
        switches: Switches { programmable: net.programmable, ..Switches::default() },
        // Replaced by ConverterConfig::device_config from the profile.
        input_assembly: 100,
        output_assembly: 150,
        produced_size: 0,
        consumed_size: 0,
        epr_resolution_ms: net.epr_resolution_ms,
    };
    let profile = build_profile(file.profile)?;
    let mut converter = ConverterConfig { device, profile, input: file.io.input_assembly };
    converter.check()?;
    let derived = converter.device_config();
    if let Some(p) = file.io.produced_size.filter(|&p| p != derived.produced_size) {
        return Err(invalid(
            "io.produced_size",
            format!("{p} disagrees with the profile and assembly, which produce {}", derived.produced_size),
        ));
    }
    if let Some(c) = file.io.consumed_size.filter(|&c| c != derived.consumed_size) {
        return Err(invalid(
            "io.consumed_size",
            format!("{c} disagrees with the profile, which consumes {}", derived.consumed_size),
        ));
    }
    converter.device = derived;
    Ok(DeviceDescription { converter, vendor_name: id.vendor_name, catalog: id.catalog })
}

fn build_profile(section: ProfileSection) -> Result<ProfileConfig, DescriptionErrorKind> {
    let misplaced =
        |key: &str, kind: &str| invalid(format!("profile.{key}"), format!("not used with kind = \"{kind}\""));
    match section.kind {
        ProfileKind::Breaker => {
            if section.framed.is_some() {
                return Err(misplaced("framed", "breaker"));
            }
            if section.modbus.is_some() {
                return Err(misplaced("modbus", "breaker"));
            }
            let mut c = FramedProfileConfig::breaker();
            if let Some(s) = section.serial {
                c.serial = s;
            }
            if let Some(h) = section.health {
                c.health = h;
            }
            if let Some(q) = section.sequencer {
                c.sequencer = q;
            }
            Ok(ProfileConfig::Framed(c))
        }
        ProfileKind::Framed => {
            if section.modbus.is_some() {
                return Err(misplaced("modbus", "framed"));
            }
            if section.serial.is_some() || section.health.is_some() || section.sequencer.is_some() {
                return Err(invalid(
                    "profile",
                    "with kind = \"framed\" put serial, health and sequencer inside [profile.framed]",
                ));
            }
            let c = section.framed.ok_or_else(|| {
                invalid("profile.framed", "missing: kind = \"framed\" needs a [profile.framed] table")
            })?;
            Ok(ProfileConfig::Framed(c))
        }
        ProfileKind::Modbus => {
            if section.framed.is_some() {
                return Err(misplaced("framed", "modbus"));
            }
            if section.serial.is_some() || section.health.is_some() || section.sequencer.is_some() {
                return Err(invalid(
                    "profile",
                    "with kind = \"modbus\" put serial and health inside [profile.modbus]",
                ));
            }
            let m = section.modbus.ok_or_else(|| {
                invalid("profile.modbus", "missing: kind = \"modbus\" needs a [profile.modbus] table")
            })?;
            if m.scan.is_empty() || m.scan.len() > SCAN_LIST_CAPACITY {
                return Err(invalid(
                    "profile.modbus.scan",
                    format!("{} entries, allowed 1..={SCAN_LIST_CAPACITY}", m.scan.len()),
                ));
            }
            let scan = heapless::Vec::from_iter(m.scan);
            let mut c = ModbusConfig::new(scan);
            if let Some(s) = m.serial {
                c.serial = s;
            }
            if let Some(v) = m.framing {
                c.framing = v;
            }
            if let Some(v) = m.response_timeout_ms {
                c.response_timeout_ms = v;
            }
            if let Some(v) = m.retries {
                c.retries = v;
            }
            if let Some(v) = m.poll_period_ms {
                c.poll_period_ms = v;
            }
            if let Some(v) = m.byte_order {
                c.byte_order = v;
            }
            if let Some(v) = m.health {
                c.health = v;
            }
            if let Some(v) = m.on_idle {
                c.on_idle = v;
            }
            if let Some(v) = m.on_fault {
                c.on_fault = v;
            }
            if let Some(offset) = m.valid_bits_offset {
                // The input image grows to hold the bits; `validate` names the key when they
                // cannot fit.
                let end = usize::from(offset) + valid_bits_len(c.scan.len());
                if end <= IMAGE_CAPACITY {
                    c.input_len = c.input_len.max(end as u16);
                }
                c.valid_bits_offset = Some(offset);
            }
            Ok(ProfileConfig::Modbus(c))
        }
    }
}
