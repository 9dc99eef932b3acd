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
        lower::lower(raw)
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

mod lower;
#[cfg(test)]
mod tests;
