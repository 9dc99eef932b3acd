//! The typed model: the sections a DeviceNet EDS defines, as Rust types, lowered from the raw
//! layer ([`Eds::from_raw`]).
//!
//! Lowering rules:
//!
//! - section names and keywords match ignoring case (and repeated spaces in section names);
//! - a section written twice is reported and its entries are merged; a keyword written twice is
//!   reported and the first one is used;
//! - what the model does not know is kept: unknown sections in [`Eds::other_sections`], unknown
//!   keywords (including vendor keywords such as `283_Firmware`) in the section's `other` list, both
//!   with their raw fields and positions, so the [`Writer`](crate::Writer) can emit them again;
//! - a single-valued entry whose value cannot be typed (`VendCode = abc;`) is reported and kept in
//!   `other`; a field of a multi-field entry (a parameter's data type, an I/O size) that cannot be
//!   typed is reported and left `None`.
//!
//! The two enum dialects are both kept as written: `EnumN = value, "text", ...;` inside
//! `[Params]` ([`ParamsSection::enums`]) and the legacy `[EnumPar]` section's
//! `ParamN = "text", "text", ...;` ([`EnumParSection::enums`]). [`Eds::enum_strings`] resolves
//! either to value/text pairs; legacy strings are numbered from the parameter's minimum (the
//! first string names the minimum value), which is how the vendor files in the corpus use them
//! (a parameter with range 100..=102 lists three strings).

use crate::diag::{Diagnostic, Rule, Span};
use crate::raw::{normalize_name, vendor_prefix, Field, FieldValue, RawEds, RawEntry, RawSection};
use crate::value::{ConnectionMask, DataType, Date, Descriptor, LinkPath, Revision, Time, Value};
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};

/// A whole EDS, typed.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Eds {
    /// `[File]`.
    pub file: Option<FileInfo>,
    /// `[Device]`: the identity.
    pub device: Option<Device>,
    /// `[Device Classification]`.
    pub classification: Option<DeviceClassification>,
    /// `[IO_Info]`.
    pub io_info: Option<IoInfo>,
    /// `[ParamClass]`.
    pub param_class: Option<ParamClass>,
    /// `[Params]`: parameters and `EnumN` enum strings.
    pub params: Option<ParamsSection>,
    /// `[EnumPar]`: legacy enum strings.
    pub enum_par: Option<EnumParSection>,
    /// `[Groups]`.
    pub groups: Option<GroupsSection>,
    /// Sections the model does not know, as written, in file order.
    pub other_sections: Vec<RawSection>,
}

/// `[File]`: the description of the EDS file itself.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FileInfo {
    /// `DescText`: what the file describes.
    pub desc_text: Option<String>,
    /// `CreateDate` (`MM-DD-YYYY`).
    pub create_date: Option<Date>,
    /// `CreateTime` (`HH:MM:SS`).
    pub create_time: Option<Time>,
    /// `ModDate`.
    pub mod_date: Option<Date>,
    /// `ModTime`.
    pub mod_time: Option<Time>,
    /// `Revision` of the file (`major.minor`).
    pub revision: Option<Revision>,
    /// `HomeURL`.
    pub home_url: Option<String>,
    /// Entries the model does not know or could not type.
    pub other: Vec<RawEntry>,
}

/// `[Device]`: the identity a scanner compares with the device (electronic keying).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Device {
    /// `VendCode`: ODVA vendor ID.
    pub vend_code: Option<u16>,
    /// `VendName`.
    pub vend_name: Option<String>,
    /// `ProdType`: device type (12 = communications adapter).
    pub prod_type: Option<u16>,
    /// `ProdTypeStr`.
    pub prod_type_str: Option<String>,
    /// `ProdCode`: product code.
    pub prod_code: Option<u16>,
    /// `MajRev`: major revision.
    pub maj_rev: Option<u8>,
    /// `MinRev`: minor revision.
    pub min_rev: Option<u8>,
    /// `ProdName`.
    pub prod_name: Option<String>,
    /// `Catalog`: catalog number.
    pub catalog: Option<String>,
    /// `Icon`: icon file name.
    pub icon: Option<String>,
    /// `IconContents`: the icon, encoded.
    pub icon_contents: Option<String>,
    /// Entries the model does not know or could not type.
    pub other: Vec<RawEntry>,
}

/// `[Device Classification]`: `ClassN = network, ...;`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DeviceClassification {
    /// Class number to its fields as text (`1 -> ["DeviceNet"]`).
    pub classes: BTreeMap<u32, Vec<String>>,
    /// Entries the model does not know.
    pub other: Vec<RawEntry>,
}

/// `[IO_Info]`: the I/O connections and their data.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct IoInfo {
    /// `Default`: the connection types enabled by default.
    pub default: Option<ConnectionMask>,
    /// `PollInfo`.
    pub poll: Option<ConnectionInfo>,
    /// `StrobeInfo`.
    pub strobe: Option<ConnectionInfo>,
    /// `COSInfo`.
    pub cos: Option<ConnectionInfo>,
    /// `CyclicInfo`.
    pub cyclic: Option<ConnectionInfo>,
    /// `InputN` (data the device produces), by N.
    pub inputs: BTreeMap<u32, IoEntry>,
    /// `OutputN` (data the device consumes), by N.
    pub outputs: BTreeMap<u32, IoEntry>,
    /// Entries the model does not know or could not type.
    pub other: Vec<RawEntry>,
}

/// `PollInfo`/`StrobeInfo`/`COSInfo`/`CyclicInfo = mask, default input, default output;`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ConnectionInfo {
    /// The connection types this one may be combined with.
    pub compatible: Option<ConnectionMask>,
    /// `N` of the default `InputN` (0: none).
    pub default_input: Option<u32>,
    /// `N` of the default `OutputN` (0: none).
    pub default_output: Option<u32>,
    /// Fields past the third, as written.
    pub extra: Vec<FieldValue>,
}

/// `InputN`/`OutputN = size, bits, mask, name, path size, path, help;`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct IoEntry {
    /// Size in bytes.
    pub size: Option<u32>,
    /// Number of meaningful bits.
    pub bits: Option<u32>,
    /// The connection types that may carry this data.
    pub mask: Option<ConnectionMask>,
    /// Name.
    pub name: String,
    /// Path size in bytes.
    pub path_size: Option<u32>,
    /// Path to the data (usually an assembly instance).
    pub path: Option<LinkPath>,
    /// Help string (often the list of what the bytes contain).
    pub help: String,
    /// Fields past the seventh, as written.
    pub extra: Vec<FieldValue>,
}

/// `[ParamClass]`: the Parameter object class attributes.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ParamClass {
    /// `MaxInst`: number of parameter instances.
    pub max_inst: Option<u32>,
    /// `Descriptor`: class descriptor bits.
    pub descriptor: Option<u16>,
    /// `CfgAssembly`: configuration assembly instance.
    pub cfg_assembly: Option<u32>,
    /// Entries the model does not know or could not type.
    pub other: Vec<RawEntry>,
}

/// `[Params]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ParamsSection {
    /// `ParamN`, by N.
    pub params: BTreeMap<u32, Param>,
    /// `EnumN = value, "text", value, "text", ...;`, by N.
    pub enums: BTreeMap<u32, Vec<EnumEntry>>,
    /// Entries the model does not know.
    pub other: Vec<RawEntry>,
}

/// `[EnumPar]`: the legacy dialect, `ParamN = "text", "text", ...;`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct EnumParSection {
    /// The strings of parameter N, in order (the first names the parameter's minimum).
    pub enums: BTreeMap<u32, Vec<String>>,
    /// Entries the model does not know.
    pub other: Vec<RawEntry>,
}

/// `[Groups]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct GroupsSection {
    /// `GroupN`, by N.
    pub groups: BTreeMap<u32, Group>,
    /// Entries the model does not know.
    pub other: Vec<RawEntry>,
}

/// `GroupN = name, count, param, param, ...;` (the count is implied by `params`).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Group {
    /// Group name.
    pub name: String,
    /// Parameter numbers, in order.
    pub params: Vec<u32>,
}

/// One value/text pair of an enumerated parameter.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct EnumEntry {
    /// The parameter value.
    pub value: i128,
    /// What the value means.
    pub text: String,
}

/// Which dialect an enum was written in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum EnumDialect {
    /// `EnumN` inside `[Params]`, explicit values.
    Params,
    /// Legacy `[EnumPar]` section, values implied (minimum, minimum + 1, ...).
    EnumPar,
}

/// The enum strings of one parameter, resolved to value/text pairs.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct ParamEnum {
    /// The parameter number.
    pub param: u32,
    /// Where it was written.
    pub dialect: EnumDialect,
    /// The pairs, in file order.
    pub entries: Vec<EnumEntry>,
}

/// `Scaling` fields of a parameter: displayed value =
/// `(value + offset) * multiplier / divisor * base` (CIP Parameter object scaling formula).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Scaling {
    /// Multiplier.
    pub multiplier: Option<i64>,
    /// Divisor.
    pub divisor: Option<i64>,
    /// Base.
    pub base: Option<i64>,
    /// Offset.
    pub offset: Option<i64>,
}

/// Scaling links of a parameter: the parameter number whose value replaces each scaling field
/// (0 or empty: none).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ScalingLinks {
    /// Multiplier link.
    pub multiplier: Option<u32>,
    /// Divisor link.
    pub divisor: Option<u32>,
    /// Base link.
    pub base: Option<u32>,
    /// Offset link.
    pub offset: Option<u32>,
}

/// One `ParamN` entry with all fields of a DeviceNet parameter (fields 1–21, see
/// [`Param::FIELD_NAMES`]); fields past the 21st are kept in `extra`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Param {
    /// Field 1: reserved (0), in older files the Parameter object placeholder.
    pub reserved: Option<i64>,
    /// Field 2: link path size in bytes.
    pub link_path_size: Option<u32>,
    /// Field 3: link path: the attribute that holds the value.
    pub link_path: Option<LinkPath>,
    /// Field 4: descriptor bits.
    pub descriptor: Option<Descriptor>,
    /// Field 5: data type code.
    pub data_type: Option<DataType>,
    /// Field 6: data size in bytes.
    pub data_size: Option<u32>,
    /// Field 7: name.
    pub name: String,
    /// Field 8: units.
    pub units: String,
    /// Field 9: help string.
    pub help: String,
    /// Field 10: minimum value.
    pub min: Option<Value>,
    /// Field 11: maximum value.
    pub max: Option<Value>,
    /// Field 12: default value.
    pub default: Option<Value>,
    /// Fields 13–16: scaling multiplier, divisor, base, offset.
    pub scaling: Scaling,
    /// Fields 17–20: scaling links.
    pub links: ScalingLinks,
    /// Field 21: decimal places.
    pub decimal_places: Option<u32>,
    /// Fields 22 and later (international strings and other extensions), as written.
    pub extra: Vec<FieldValue>,
}

impl Param {
    /// Number of fields of a DeviceNet parameter entry.
    pub const FIELD_COUNT: usize = 21;

    /// Names of the fields, in order (index 0 is field 1).
    pub const FIELD_NAMES: [&'static str; Param::FIELD_COUNT] = [
        "reserved",
        "link path size",
        "link path",
        "descriptor",
        "data type",
        "data size",
        "name",
        "units",
        "help string",
        "minimum",
        "maximum",
        "default",
        "scaling multiplier",
        "scaling divisor",
        "scaling base",
        "scaling offset",
        "multiplier link",
        "divisor link",
        "base link",
        "offset link",
        "decimal places",
    ];
}

impl Eds {
    /// Parameter `n`.
    pub fn param(&self, n: u32) -> Option<&Param> {
        self.params.as_ref()?.params.get(&n)
    }

    /// All parameters, by number.
    pub fn params(&self) -> impl Iterator<Item = (u32, &Param)> {
        self.params.iter().flat_map(|s| s.params.iter().map(|(n, p)| (*n, p)))
    }

    /// Number of parameters.
    pub fn param_count(&self) -> usize {
        self.params.as_ref().map_or(0, |s| s.params.len())
    }

    /// All groups, by number.
    pub fn groups(&self) -> impl Iterator<Item = (u32, &Group)> {
        self.groups.iter().flat_map(|s| s.groups.iter().map(|(n, g)| (*n, g)))
    }

    /// The enum strings of parameter `n` as value/text pairs: `EnumN` from `[Params]` when
    /// present, else the legacy `[EnumPar]` list numbered from the parameter's minimum (0 when
    /// the minimum is not an integer).
    pub fn enum_strings(&self, n: u32) -> Option<ParamEnum> {
        if let Some(entries) = self.params.as_ref().and_then(|s| s.enums.get(&n)) {
            return Some(ParamEnum { param: n, dialect: EnumDialect::Params, entries: entries.clone() });
        }
        self.legacy_enum(n)
    }

    fn legacy_enum(&self, n: u32) -> Option<ParamEnum> {
        let strings = self.enum_par.as_ref()?.enums.get(&n)?;
        let first = self.param(n).and_then(|p| p.min.as_ref()).and_then(Value::as_int).unwrap_or(0);
        let entries = strings
            .iter()
            .zip(0i128..)
            .map(|(text, i)| EnumEntry { value: first.saturating_add(i), text: text.clone() })
            .collect();
        Some(ParamEnum { param: n, dialect: EnumDialect::EnumPar, entries })
    }

    /// Every enum of the file in both dialects, resolved, ordered by parameter then dialect (a
    /// parameter written in both dialects appears twice).
    pub fn enums(&self) -> Vec<ParamEnum> {
        let mut all: Vec<ParamEnum> = Vec::new();
        if let Some(section) = &self.params {
            all.extend(section.enums.iter().map(|(n, entries)| ParamEnum {
                param: *n,
                dialect: EnumDialect::Params,
                entries: entries.clone(),
            }));
        }
        if let Some(section) = &self.enum_par {
            all.extend(section.enums.keys().filter_map(|n| self.legacy_enum(*n)));
        }
        all.sort_by_key(|e| (e.param, e.dialect));
        all
    }

    /// Everything kept without being understood: `(section, entry)` pairs for unknown keywords
    /// in known sections, in section order.
    pub fn other_entries(&self) -> Vec<(&'static str, &RawEntry)> {
        let lists: [(&'static str, Option<&Vec<RawEntry>>); 8] = [
            ("File", self.file.as_ref().map(|s| &s.other)),
            ("Device", self.device.as_ref().map(|s| &s.other)),
            ("Device Classification", self.classification.as_ref().map(|s| &s.other)),
            ("IO_Info", self.io_info.as_ref().map(|s| &s.other)),
            ("ParamClass", self.param_class.as_ref().map(|s| &s.other)),
            ("Params", self.params.as_ref().map(|s| &s.other)),
            ("EnumPar", self.enum_par.as_ref().map(|s| &s.other)),
            ("Groups", self.groups.as_ref().map(|s| &s.other)),
        ];
        let mut all = Vec::new();
        for (section, entries) in lists {
            all.extend(entries.into_iter().flatten().map(|e| (section, e)));
        }
        all
    }

    /// Lowers a raw file to the typed model, with the problems found on the way (duplicates,
    /// values of the wrong form, unknown keywords and sections).
    pub fn from_raw(raw: &RawEds) -> (Eds, Vec<Diagnostic>) {
        let mut lower = Lower { diagnostics: Vec::new() };
        let eds = lower.eds(raw);
        (eds, lower.diagnostics)
    }
}

/// The sections the model knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) enum Known {
    File,
    Device,
    Classification,
    IoInfo,
    ParamClass,
    Params,
    EnumPar,
    Groups,
}

impl Known {
    pub(crate) fn of(name: &str) -> Option<Known> {
        Some(match normalize_name(name).as_str() {
            "file" => Known::File,
            "device" => Known::Device,
            "device classification" => Known::Classification,
            "io_info" => Known::IoInfo,
            "paramclass" => Known::ParamClass,
            "params" => Known::Params,
            "enumpar" => Known::EnumPar,
            "groups" => Known::Groups,
            _ => return None,
        })
    }

    pub(crate) const fn name(self) -> &'static str {
        match self {
            Known::File => "File",
            Known::Device => "Device",
            Known::Classification => "Device Classification",
            Known::IoInfo => "IO_Info",
            Known::ParamClass => "ParamClass",
            Known::Params => "Params",
            Known::EnumPar => "EnumPar",
            Known::Groups => "Groups",
        }
    }
}

/// CIP sections this model does not type but which are standard, so not worth a warning.
const STANDARD_SECTIONS: &[&str] = &[
    "assembly",
    "connection manager",
    "port",
    "capacity",
    "modular",
    "connection configuration",
    "variant",
    "event enumeration",
    "symbolic translation",
    "internationalization",
];

/// `Param07` -> `("param", 7)`: a keyword made of letters then a decimal number.
pub(crate) fn numbered(keyword: &str) -> Option<(String, u32)> {
    let split = keyword.find(|c: char| c.is_ascii_digit())?;
    let (prefix, digits) = keyword.split_at(split);
    if prefix.is_empty()
        || !prefix.chars().all(|c| c.is_ascii_alphabetic())
        || digits.len() > 9
        || !digits.bytes().all(|b| b.is_ascii_digit())
    {
        return None;
    }
    Some((prefix.to_ascii_lowercase(), digits.parse().ok()?))
}

/// The key two keywords of one section collide on: lower case, numbers without leading zeros.
pub(crate) fn entry_key(keyword: &str) -> String {
    match numbered(keyword) {
        Some((prefix, n)) => format!("{prefix}{n}"),
        None => keyword.to_ascii_lowercase(),
    }
}

fn numbered_as(keyword: &str, prefix: &str) -> Option<u32> {
    numbered(keyword).filter(|(p, _)| p == prefix).map(|(_, n)| n)
}

/// Stores `value` in `slot` when there is one; `true` when stored.
fn set<T>(slot: &mut Option<T>, value: Option<T>) -> bool {
    let stored = value.is_some();
    if stored {
        *slot = value;
    }
    stored
}

fn field_text(value: &FieldValue) -> String {
    match value {
        FieldValue::Empty => String::new(),
        FieldValue::Text(t) | FieldValue::Str(t) => t.clone(),
        FieldValue::List(fields) => {
            let inner: Vec<String> = fields.iter().map(|f| field_text(&f.value)).collect();
            format!("{{{}}}", inner.join(", "))
        }
    }
}

struct Lower {
    diagnostics: Vec<Diagnostic>,
}

/// A field of an entry, or the entry's position when the field is missing.
fn field_at(entry: &RawEntry, index: usize) -> (Option<&Field>, Span) {
    match entry.fields.get(index) {
        Some(field) => (Some(field), field.span),
        None => (None, entry.span),
    }
}

impl Lower {
    fn error(&mut self, rule: Rule, span: Span, message: String) {
        self.diagnostics.push(Diagnostic::error(rule, span, message));
    }

    fn warning(&mut self, rule: Rule, span: Span, message: String) {
        self.diagnostics.push(Diagnostic::warning(rule, span, message));
    }

    fn eds(&mut self, raw: &RawEds) -> Eds {
        // Entries of each known section, merged over repeats, first of each keyword only.
        let mut known: HashMap<Known, Vec<&RawEntry>> = HashMap::new();
        let mut first_header: HashMap<String, Span> = HashMap::new();
        let mut seen_keys: HashMap<(Known, String), Span> = HashMap::new();
        let mut eds = Eds::default();
        for section in &raw.sections {
            let normalized = normalize_name(&section.name);
            if let Some(first) = first_header.get(&normalized) {
                self.error(
                    Rule::DuplicateSection,
                    section.span,
                    format!("section [{}] appears again (first at {first})", section.name),
                );
            } else {
                first_header.insert(normalized.clone(), section.span);
            }
            let Some(kind) = Known::of(&section.name) else {
                self.unknown_section(section, &normalized);
                eds.other_sections.push(section.clone());
                continue;
            };
            let entries = known.entry(kind).or_default();
            for entry in &section.entries {
                let key = (kind, entry_key(&entry.keyword));
                if let Some(first) = seen_keys.get(&key) {
                    self.error(
                        Rule::DuplicateEntry,
                        entry.span,
                        format!(
                            "`{}` appears again in [{}] (first at {first}); this one is ignored",
                            entry.keyword,
                            kind.name()
                        ),
                    );
                    continue;
                }
                seen_keys.insert(key, entry.span);
                entries.push(entry);
            }
        }
        let mut take = |kind: Known| known.remove(&kind);
        let (file, device, classification, io_info, param_class, params, enum_par, groups) = (
            take(Known::File),
            take(Known::Device),
            take(Known::Classification),
            take(Known::IoInfo),
            take(Known::ParamClass),
            take(Known::Params),
            take(Known::EnumPar),
            take(Known::Groups),
        );
        eds.file = file.map(|e| self.file(&e));
        eds.device = device.map(|e| self.device(&e));
        eds.classification = classification.map(|e| self.classification(&e));
        eds.io_info = io_info.map(|e| self.io_info(&e));
        eds.param_class = param_class.map(|e| self.param_class(&e));
        eds.params = params.map(|e| self.params(&e));
        eds.enum_par = enum_par.map(|e| self.enum_par(&e));
        eds.groups = groups.map(|e| self.groups(&e));
        eds
    }

    fn unknown_section(&mut self, section: &RawSection, normalized: &str) {
        let standard = STANDARD_SECTIONS.contains(&normalized) || normalized.ends_with(" class");
        if !standard && vendor_prefix(&section.name).is_none() {
            self.warning(
                Rule::UnknownSection,
                section.span,
                format!("unknown section [{}] is kept as is", section.name),
            );
        }
    }

    fn unknown_keyword(&mut self, entry: &RawEntry, section: Known) {
        if entry.vendor_prefix().is_none() {
            self.warning(
                Rule::UnknownKeyword,
                entry.span,
                format!("unknown keyword `{}` in [{}] is kept as is", entry.keyword, section.name()),
            );
        }
    }

    /// The only field of a single-valued entry.
    fn single<'e>(&mut self, entry: &'e RawEntry) -> Option<&'e FieldValue> {
        if entry.fields.len() != 1 {
            self.error(
                Rule::FieldCount,
                entry.span,
                format!("`{}` takes one value, found {} fields", entry.keyword, entry.fields.len()),
            );
            return None;
        }
        Some(&entry.fields[0].value)
    }

    fn single_string(&mut self, entry: &RawEntry) -> Option<String> {
        let value = self.single(entry)?;
        self.string(value, entry.fields[0].span, &entry.keyword)
    }

    fn string(&mut self, value: &FieldValue, span: Span, what: &str) -> Option<String> {
        match value {
            FieldValue::Str(text) => Some(text.clone()),
            FieldValue::Empty => Some(String::new()),
            FieldValue::Text(text) => {
                self.warning(Rule::UnquotedString, span, format!("{what}: string `{text}` should be quoted"));
                Some(text.clone())
            }
            FieldValue::List(_) => {
                self.error(
                    Rule::InvalidValue,
                    span,
                    format!("{what}: expected a string, found a {{ }} group"),
                );
                None
            }
        }
    }

    /// A single value read by `parse`, described as `form` in the error.
    fn single_typed<T>(
        &mut self,
        entry: &RawEntry,
        form: &str,
        parse: impl Fn(&str) -> Option<T>,
    ) -> Option<T> {
        let value = self.single(entry)?;
        let parsed = match value {
            FieldValue::Text(text) => parse(text),
            _ => None,
        };
        if parsed.is_none() {
            self.error(
                Rule::InvalidValue,
                entry.fields[0].span,
                format!("`{}`: expected {form}, found {}", entry.keyword, describe(value)),
            );
        }
        parsed
    }

    fn single_int<T: TryFrom<i128>>(&mut self, entry: &RawEntry, form: &str) -> Option<T> {
        self.single_typed(entry, form, |t| crate::value::parse_int(t).and_then(|v| T::try_from(v).ok()))
    }

    /// Field `index` of `entry` as an integer of type `T`; empty or missing is `None` silently.
    fn int_field<T: TryFrom<i128>>(&mut self, entry: &RawEntry, index: usize, what: &str) -> Option<T> {
        let (field, span) = field_at(entry, index);
        let value = &field?.value;
        match value {
            FieldValue::Empty => None,
            FieldValue::Text(text) => match crate::value::parse_int(text) {
                Some(v) => match T::try_from(v) {
                    Ok(v) => Some(v),
                    Err(_) => {
                        self.error(
                            Rule::InvalidValue,
                            span,
                            format!("`{}` {what}: {v} is out of range", entry.keyword),
                        );
                        None
                    }
                },
                None => {
                    self.error(
                        Rule::InvalidValue,
                        span,
                        format!("`{}` {what}: expected an integer, found {}", entry.keyword, describe(value)),
                    );
                    None
                }
            },
            other => {
                self.error(
                    Rule::InvalidValue,
                    span,
                    format!("`{}` {what}: expected an integer, found {}", entry.keyword, describe(other)),
                );
                None
            }
        }
    }

    fn string_field(&mut self, entry: &RawEntry, index: usize, what: &str) -> String {
        let (field, span) = field_at(entry, index);
        match field {
            Some(field) => {
                self.string(&field.value, span, &format!("`{}` {what}", entry.keyword)).unwrap_or_default()
            }
            None => String::new(),
        }
    }

    fn path_field(&mut self, entry: &RawEntry, index: usize) -> Option<LinkPath> {
        let (field, span) = field_at(entry, index);
        match &field?.value {
            FieldValue::Empty => None,
            FieldValue::Str(text) | FieldValue::Text(text) => Some(LinkPath::parse(text)),
            FieldValue::List(_) => {
                self.error(Rule::InvalidValue, span, format!("`{}` path: expected a string", entry.keyword));
                None
            }
        }
    }

    fn value_field(&mut self, entry: &RawEntry, index: usize, what: &str) -> Option<Value> {
        let (field, span) = field_at(entry, index);
        match &field?.value {
            FieldValue::Empty => None,
            FieldValue::Text(text) => Some(Value::from_text(text)),
            FieldValue::Str(text) => Some(Value::Str(text.clone())),
            FieldValue::List(_) => {
                self.error(
                    Rule::InvalidValue,
                    span,
                    format!("`{}` {what}: unexpected {{ }} group", entry.keyword),
                );
                None
            }
        }
    }

    fn need_fields(&mut self, entry: &RawEntry, need: usize, what: &str) {
        if entry.fields.len() < need {
            self.error(
                Rule::FieldCount,
                entry.span,
                format!("`{}` has {} fields; {what} has {need}", entry.keyword, entry.fields.len()),
            );
        }
    }

    fn file(&mut self, entries: &[&RawEntry]) -> FileInfo {
        let mut info = FileInfo::default();
        for &entry in entries {
            let typed = match entry_key(&entry.keyword).as_str() {
                "desctext" => set(&mut info.desc_text, self.single_string(entry)),
                "createdate" => {
                    set(&mut info.create_date, self.single_typed(entry, "a date MM-DD-YYYY", Date::parse))
                }
                "createtime" => {
                    set(&mut info.create_time, self.single_typed(entry, "a time HH:MM:SS", Time::parse))
                }
                "moddate" => {
                    set(&mut info.mod_date, self.single_typed(entry, "a date MM-DD-YYYY", Date::parse))
                }
                "modtime" => {
                    set(&mut info.mod_time, self.single_typed(entry, "a time HH:MM:SS", Time::parse))
                }
                "revision" => set(
                    &mut info.revision,
                    self.single_typed(entry, "a revision major.minor", Revision::parse),
                ),
                "homeurl" => set(&mut info.home_url, self.single_string(entry)),
                _ => {
                    self.unknown_keyword(entry, Known::File);
                    false
                }
            };
            if !typed {
                info.other.push(entry.clone());
            }
        }
        info
    }

    fn device(&mut self, entries: &[&RawEntry]) -> Device {
        let mut device = Device::default();
        for &entry in entries {
            let typed = match entry_key(&entry.keyword).as_str() {
                "vendcode" => set(&mut device.vend_code, self.single_int(entry, "a vendor ID 0..=65535")),
                "vendname" => set(&mut device.vend_name, self.single_string(entry)),
                "prodtype" => set(&mut device.prod_type, self.single_int(entry, "a device type 0..=65535")),
                "prodtypestr" => set(&mut device.prod_type_str, self.single_string(entry)),
                "prodcode" => set(&mut device.prod_code, self.single_int(entry, "a product code 0..=65535")),
                "majrev" => set(&mut device.maj_rev, self.single_int(entry, "a major revision 0..=255")),
                "minrev" => set(&mut device.min_rev, self.single_int(entry, "a minor revision 0..=255")),
                "prodname" => set(&mut device.prod_name, self.single_string(entry)),
                "catalog" => set(&mut device.catalog, self.single_string(entry)),
                "icon" => set(&mut device.icon, self.single_string(entry)),
                "iconcontents" => set(&mut device.icon_contents, self.single_string(entry)),
                _ => {
                    self.unknown_keyword(entry, Known::Device);
                    false
                }
            };
            if !typed {
                device.other.push(entry.clone());
            }
        }
        device
    }

    fn classification(&mut self, entries: &[&RawEntry]) -> DeviceClassification {
        let mut classification = DeviceClassification::default();
        for &entry in entries {
            match numbered_as(&entry.keyword, "class") {
                Some(n) => {
                    let values = entry.fields.iter().map(|f| field_text(&f.value)).collect();
                    classification.classes.insert(n, values);
                }
                None => {
                    self.unknown_keyword(entry, Known::Classification);
                    classification.other.push(entry.clone());
                }
            }
        }
        classification
    }

    fn io_info(&mut self, entries: &[&RawEntry]) -> IoInfo {
        let mut io = IoInfo::default();
        for &entry in entries {
            let key = entry_key(&entry.keyword);
            let typed = match key.as_str() {
                "default" => set(
                    &mut io.default,
                    self.single_int(entry, "a connection mask 0..=0xFFFF").map(ConnectionMask),
                ),
                "pollinfo" => {
                    io.poll = Some(self.connection_info(entry));
                    true
                }
                "strobeinfo" => {
                    io.strobe = Some(self.connection_info(entry));
                    true
                }
                "cosinfo" => {
                    io.cos = Some(self.connection_info(entry));
                    true
                }
                "cyclicinfo" => {
                    io.cyclic = Some(self.connection_info(entry));
                    true
                }
                _ => match numbered(&entry.keyword) {
                    Some((prefix, n)) if prefix == "input" => {
                        let input = self.io_entry(entry);
                        io.inputs.insert(n, input);
                        true
                    }
                    Some((prefix, n)) if prefix == "output" => {
                        let output = self.io_entry(entry);
                        io.outputs.insert(n, output);
                        true
                    }
                    _ => {
                        self.unknown_keyword(entry, Known::IoInfo);
                        false
                    }
                },
            };
            if !typed {
                io.other.push(entry.clone());
            }
        }
        io
    }

    fn connection_info(&mut self, entry: &RawEntry) -> ConnectionInfo {
        self.need_fields(entry, 3, "a connection entry (mask, default input, default output)");
        ConnectionInfo {
            compatible: self.int_field(entry, 0, "mask").map(ConnectionMask),
            default_input: self.int_field(entry, 1, "default input"),
            default_output: self.int_field(entry, 2, "default output"),
            extra: entry.fields.iter().skip(3).map(|f| f.value.clone()).collect(),
        }
    }

    fn io_entry(&mut self, entry: &RawEntry) -> IoEntry {
        if entry.fields.len() < 3 {
            self.need_fields(entry, 7, "an I/O entry (size, bits, mask, name, path size, path, help)");
        } else if entry.fields.len() < 7 {
            self.warning(
                Rule::FieldCount,
                entry.span,
                format!(
                    "`{}` has {} fields; an I/O entry has 7 (size, bits, mask, name, path size, path, help)",
                    entry.keyword,
                    entry.fields.len()
                ),
            );
        }
        IoEntry {
            size: self.int_field(entry, 0, "size"),
            bits: self.int_field(entry, 1, "bits"),
            mask: self.int_field(entry, 2, "mask").map(ConnectionMask),
            name: self.string_field(entry, 3, "name"),
            path_size: self.int_field(entry, 4, "path size"),
            path: self.path_field(entry, 5),
            help: self.string_field(entry, 6, "help string"),
            extra: entry.fields.iter().skip(7).map(|f| f.value.clone()).collect(),
        }
    }

    fn param_class(&mut self, entries: &[&RawEntry]) -> ParamClass {
        let mut class = ParamClass::default();
        for &entry in entries {
            let typed = match entry_key(&entry.keyword).as_str() {
                "maxinst" => set(&mut class.max_inst, self.single_int(entry, "an instance count")),
                "descriptor" => set(&mut class.descriptor, self.single_int(entry, "a descriptor 0..=0xFFFF")),
                "cfgassembly" => set(&mut class.cfg_assembly, self.single_int(entry, "an assembly instance")),
                _ => {
                    self.unknown_keyword(entry, Known::ParamClass);
                    false
                }
            };
            if !typed {
                class.other.push(entry.clone());
            }
        }
        class
    }

    fn params(&mut self, entries: &[&RawEntry]) -> ParamsSection {
        let mut section = ParamsSection::default();
        for &entry in entries {
            match numbered(&entry.keyword) {
                Some((prefix, n)) if prefix == "param" => {
                    if n == 0 {
                        self.error(
                            Rule::InvalidValue,
                            entry.span,
                            "parameter numbers start at 1 (Param0)".to_string(),
                        );
                    }
                    let param = self.param(entry);
                    section.params.insert(n, param);
                }
                Some((prefix, n)) if prefix == "enum" => {
                    let entries = self.enum_pairs(entry);
                    section.enums.insert(n, entries);
                }
                _ => {
                    self.unknown_keyword(entry, Known::Params);
                    section.other.push(entry.clone());
                }
            }
        }
        section
    }

    fn param(&mut self, entry: &RawEntry) -> Param {
        if entry.fields.len() < Param::FIELD_COUNT {
            self.error(
                Rule::FieldCount,
                entry.span,
                format!(
                    "`{}` has {} fields; a parameter entry has {} (the last ones present are taken as {})",
                    entry.keyword,
                    entry.fields.len(),
                    Param::FIELD_COUNT,
                    Param::FIELD_NAMES[entry.fields.len().clamp(1, Param::FIELD_COUNT) - 1],
                ),
            );
        }
        let names = Param::FIELD_NAMES;
        let data_type: Option<u16> = self.int_field(entry, 4, names[4]);
        Param {
            reserved: self.int_field(entry, 0, names[0]),
            link_path_size: self.int_field(entry, 1, names[1]),
            link_path: self.path_field(entry, 2),
            descriptor: self.int_field(entry, 3, names[3]).map(Descriptor),
            data_type: data_type.map(DataType::from_code),
            data_size: self.int_field(entry, 5, names[5]),
            name: self.string_field(entry, 6, names[6]),
            units: self.string_field(entry, 7, names[7]),
            help: self.string_field(entry, 8, names[8]),
            min: self.value_field(entry, 9, names[9]),
            max: self.value_field(entry, 10, names[10]),
            default: self.value_field(entry, 11, names[11]),
            scaling: Scaling {
                multiplier: self.int_field(entry, 12, names[12]),
                divisor: self.int_field(entry, 13, names[13]),
                base: self.int_field(entry, 14, names[14]),
                offset: self.int_field(entry, 15, names[15]),
            },
            links: ScalingLinks {
                multiplier: self.int_field(entry, 16, names[16]),
                divisor: self.int_field(entry, 17, names[17]),
                base: self.int_field(entry, 18, names[18]),
                offset: self.int_field(entry, 19, names[19]),
            },
            decimal_places: self.int_field(entry, 20, names[20]),
            extra: entry.fields.iter().skip(Param::FIELD_COUNT).map(|f| f.value.clone()).collect(),
        }
    }

    fn enum_pairs(&mut self, entry: &RawEntry) -> Vec<EnumEntry> {
        if entry.fields.len() % 2 != 0 {
            self.error(
                Rule::FieldCount,
                entry.span,
                format!(
                    "`{}` has {} fields; enum strings come in value, \"text\" pairs",
                    entry.keyword,
                    entry.fields.len()
                ),
            );
        }
        let mut pairs: Vec<EnumEntry> = Vec::new();
        let mut seen: HashMap<i128, Span> = HashMap::new();
        for i in (0..entry.fields.len() / 2).map(|i| i * 2) {
            let Some(value) = self.int_field::<i128>(entry, i, "enum value") else {
                continue;
            };
            let span = entry.fields[i].span;
            if let Some(first) = seen.get(&value) {
                self.error(
                    Rule::DuplicateEntry,
                    span,
                    format!("`{}` names value {value} twice (first at {first})", entry.keyword),
                );
                continue;
            }
            seen.insert(value, span);
            let text = self.string_field(entry, i + 1, "enum string");
            pairs.push(EnumEntry { value, text });
        }
        pairs
    }

    fn enum_par(&mut self, entries: &[&RawEntry]) -> EnumParSection {
        let mut section = EnumParSection::default();
        for &entry in entries {
            match numbered_as(&entry.keyword, "param") {
                Some(n) => {
                    let strings =
                        (0..entry.fields.len()).map(|i| self.string_field(entry, i, "enum string")).collect();
                    section.enums.insert(n, strings);
                }
                None => {
                    self.unknown_keyword(entry, Known::EnumPar);
                    section.other.push(entry.clone());
                }
            }
        }
        section
    }

    fn groups(&mut self, entries: &[&RawEntry]) -> GroupsSection {
        let mut section = GroupsSection::default();
        for &entry in entries {
            let Some(n) = numbered_as(&entry.keyword, "group") else {
                self.unknown_keyword(entry, Known::Groups);
                section.other.push(entry.clone());
                continue;
            };
            self.need_fields(entry, 2, "a group (name, count, parameters...)");
            let name = self.string_field(entry, 0, "name");
            let count: Option<u32> = self.int_field(entry, 1, "parameter count");
            let mut params = Vec::new();
            let mut listed_once = std::collections::HashSet::new();
            for i in 2..entry.fields.len() {
                if entry.fields[i].value.is_empty() {
                    self.error(
                        Rule::InvalidValue,
                        entry.fields[i].span,
                        format!("`{}` lists an empty parameter number", entry.keyword),
                    );
                    continue;
                }
                if let Some(p) = self.int_field::<u32>(entry, i, "parameter number") {
                    if !listed_once.insert(p) {
                        self.warning(
                            Rule::GroupCount,
                            entry.fields[i].span,
                            format!("`{}` lists Param{p} twice", entry.keyword),
                        );
                    }
                    params.push(p);
                }
            }
            let listed = entry.fields.len().saturating_sub(2);
            if let Some(count) = count.filter(|&c| usize::try_from(c).ok() != Some(listed)) {
                self.warning(
                    Rule::GroupCount,
                    entry.fields.get(1).map_or(entry.span, |f| f.span),
                    format!("`{}` declares {count} parameters but lists {listed}", entry.keyword),
                );
            }
            section.groups.insert(n, Group { name, params });
        }
        section
    }
}

fn describe(value: &FieldValue) -> String {
    match value {
        FieldValue::Empty => "nothing".to_string(),
        FieldValue::Text(text) => format!("`{text}`"),
        FieldValue::Str(text) => format!("the string \"{text}\""),
        FieldValue::List(_) => "a { } group".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn lower(src: &str) -> (Eds, Vec<Diagnostic>) {
        Eds::from_raw(&RawEds::parse(src).unwrap())
    }

    fn rules(diagnostics: &[Diagnostic]) -> Vec<Rule> {
        diagnostics.iter().map(|d| d.rule).collect()
    }

    #[rstest]
    #[case::param("Param07", Some(("param".to_string(), 7)))]
    #[case::upper("INPUT1", Some(("input".to_string(), 1)))]
    #[case::no_number("Default", None)]
    #[case::vendor("1_Param3", None)]
    #[case::too_long("Param1234567890", None)]
    fn splits_numbered_keywords(#[case] keyword: &str, #[case] expected: Option<(String, u32)>) {
        assert_eq!(numbered(keyword), expected);
    }

    #[test]
    fn lowers_identity_case_insensitively() {
        let (eds, diagnostics) = lower(
            "[device]\nvendcode = 0x011B;\nVENDNAME = \"Hilscher\";\nProdType = 12;\nMajRev = 5; MinRev = 4;",
        );
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        let device = eds.device.unwrap();
        assert_eq!(device.vend_code, Some(283));
        assert_eq!(device.vend_name.as_deref(), Some("Hilscher"));
        assert_eq!((device.maj_rev, device.min_rev), (Some(5), Some(4)));
    }

    #[rstest]
    #[case::not_a_number("[Device]\nVendCode = abc;", Rule::InvalidValue)]
    #[case::too_big("[Device]\nVendCode = 70000;", Rule::InvalidValue)]
    #[case::two_values("[Device]\nVendCode = 1, 2;", Rule::FieldCount)]
    #[case::bad_date("[File]\nCreateDate = 2020-01-01;", Rule::InvalidValue)]
    fn keeps_untypeable_entries(#[case] src: &str, #[case] rule: Rule) {
        let (eds, diagnostics) = lower(src);
        assert_eq!(rules(&diagnostics), vec![rule]);
        let kept = eds.other_entries();
        assert_eq!(kept.len(), 1);
    }

    #[test]
    fn keeps_vendor_keywords_silently_and_warns_on_unknown_ones() {
        let (eds, diagnostics) = lower("[Device]\n1_VendorKeyword = 5;\nColour = \"red\";");
        assert_eq!(rules(&diagnostics), vec![Rule::UnknownKeyword]);
        let kept: Vec<&str> = eds.other_entries().iter().map(|(_, e)| e.keyword.as_str()).collect();
        assert_eq!(kept, ["1_VendorKeyword", "Colour"]);
    }

    #[test]
    fn merges_repeated_sections_and_reports_duplicates() {
        let (eds, diagnostics) = lower("[Device]\nVendCode = 1;\n[Device]\nVendCode = 2;\nProdCode = 3;");
        assert_eq!(rules(&diagnostics), vec![Rule::DuplicateSection, Rule::DuplicateEntry]);
        let device = eds.device.unwrap();
        assert_eq!((device.vend_code, device.prod_code), (Some(1), Some(3)));
    }

    #[test]
    fn param_fields_in_order() {
        let (eds, diagnostics) = lower(
            "[Params]\nParam1 = 0, 6, \"20 05 24 02 30 64\", 0x002E, 0xC6, 1, \"Name\", \"ms\", \"Help\",\n\
             1, 10, 5, 2, 3, 4, 5, 6, 7, 8, 9, 2, \"extra\";",
        );
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        let p = eds.param(1).unwrap();
        assert_eq!(p.reserved, Some(0));
        assert_eq!(p.link_path_size, Some(6));
        assert_eq!(p.link_path.as_ref().and_then(LinkPath::attribute).map(|a| a.attribute), Some(Some(100)));
        assert_eq!(p.descriptor, Some(Descriptor(0x2E)));
        assert_eq!(p.data_type, Some(DataType::Usint));
        assert_eq!(p.data_size, Some(1));
        assert_eq!((p.name.as_str(), p.units.as_str(), p.help.as_str()), ("Name", "ms", "Help"));
        assert_eq!(
            (p.min.clone(), p.max.clone(), p.default.clone()),
            (Some(Value::Int(1)), Some(Value::Int(10)), Some(Value::Int(5)))
        );
        assert_eq!(
            p.scaling,
            Scaling { multiplier: Some(2), divisor: Some(3), base: Some(4), offset: Some(5) }
        );
        assert_eq!(
            p.links,
            ScalingLinks { multiplier: Some(6), divisor: Some(7), base: Some(8), offset: Some(9) }
        );
        assert_eq!(p.decimal_places, Some(2));
        assert_eq!(p.extra, vec![FieldValue::Str("extra".into())]);
    }

    #[test]
    fn empty_param_fields_are_none() {
        let (eds, diagnostics) =
            lower("[Params]\nParam1 = 0, ,, 0x0012, 0xC7, 2, \"IO\", \"\", \"\", 0,2,0, ,,,, ,,,, ;\nEnum1 = 0,\"In\", 1,\"Out\";");
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        let p = eds.param(1).unwrap();
        assert_eq!((p.link_path_size, &p.link_path, p.decimal_places), (None, &None, None));
        assert_eq!(p.scaling, Scaling::default());
        let e = eds.enum_strings(1).unwrap();
        assert_eq!(e.dialect, EnumDialect::Params);
        assert_eq!(e.entries[1], EnumEntry { value: 1, text: "Out".into() });
    }

    #[test]
    fn legacy_enums_are_numbered_from_the_minimum() {
        let (eds, _) = lower(
            "[Params]\nParam1 = 0,,,0x02,0xC6,1,\"A\",\"\",\"\",100,102,100,1,1,1,0,0,0,0,0,0;\n\
             [EnumPar]\nParam1 = \"a\", \"b\", \"c\";",
        );
        let e = eds.enum_strings(1).unwrap();
        assert_eq!(e.dialect, EnumDialect::EnumPar);
        let values: Vec<i128> = e.entries.iter().map(|e| e.value).collect();
        assert_eq!(values, [100, 101, 102]);
    }

    #[rstest]
    #[case::short_param("[Params]\nParam1 = 0, 6;", Rule::FieldCount)]
    #[case::odd_enum("[Params]\nEnum1 = 0, \"a\", 1;", Rule::FieldCount)]
    #[case::duplicate_enum_value("[Params]\nEnum1 = 0, \"a\", 0, \"b\";", Rule::DuplicateEntry)]
    #[case::bad_data_type(
        "[Params]\nParam1 = 0,,,0,BOOL,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;",
        Rule::InvalidValue
    )]
    #[case::group_count("[Groups]\nGroup1 = \"G\", 3, 1, 2;", Rule::GroupCount)]
    #[case::group_member_twice("[Groups]\nGroup1 = \"G\", 2, 1, 1;", Rule::GroupCount)]
    #[case::param_zero("[Params]\nParam0 = 0,,,0,0xC6,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;", Rule::InvalidValue)]
    #[case::unquoted_name("[Device]\nProdName = Widget;", Rule::UnquotedString)]
    #[case::duplicate_param("[Params]\nParam1 = 0,,,0,0xC6,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;\nParam01 = 0,,,0,0xC6,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;", Rule::DuplicateEntry)]
    #[case::unknown_section("[Colours]\nRed = 1;", Rule::UnknownSection)]
    fn reports_lowering_problems(#[case] src: &str, #[case] rule: Rule) {
        let (_, diagnostics) = lower(src);
        assert!(rules(&diagnostics).contains(&rule), "{diagnostics:?}");
    }

    #[rstest]
    #[case::vendor_section("[283_Private]\nA = 1;")]
    #[case::cip_class_section("[Identity Class]\nRevision = 1;")]
    #[case::assembly("[Assembly]\nAssem100 = \"x\", , 4, 0x0000, , , 32, Param1;")]
    fn keeps_known_unmodelled_sections_silently(#[case] src: &str) {
        let (eds, diagnostics) = lower(src);
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        assert_eq!(eds.other_sections.len(), 1);
    }

    #[test]
    fn groups_and_io_info() {
        let (eds, diagnostics) = lower(
            "[IO_Info]\nDefault = 0x0001;\nPollInfo = 0x000F, 1, 1;\n\
             Input1 = 10, 80, 0x000F, \"In\", 6, \"20 04 24 65 30 03\", \"help\";\n\
             [Groups]\nGroup1 = \"Assemblies\", 2, 1, 2;",
        );
        assert!(diagnostics.is_empty(), "{diagnostics:?}");
        let io = eds.io_info.unwrap();
        assert_eq!(io.default, Some(ConnectionMask(1)));
        assert_eq!(io.poll.unwrap().default_input, Some(1));
        let input = &io.inputs[&1];
        assert_eq!((input.size, input.bits, input.path_size), (Some(10), Some(80), Some(6)));
        assert_eq!(eds.groups.unwrap().groups[&1], Group { name: "Assemblies".into(), params: vec![1, 2] });
    }
}
