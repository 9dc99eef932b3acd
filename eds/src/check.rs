//! `check`: everything wrong with an EDS file, graded error or warning, each with its position.
//!
//! The report combines three passes:
//!
//! 1. syntax ([`RawEds::parse_lenient`], recovering so every error is listed);
//! 2. lowering ([`Eds::from_raw`]): duplicates, values of the wrong form, unknown keywords;
//! 3. the semantic checks of [`check_model`]: required sections and keys, cross references
//!    (groups, enums, scaling links, default I/O entries), `min <= default <= max`, values that
//!    fit their data type, data sizes that match the data type code, enum values within range,
//!    and the I/O connections of `[IO_Info]` (below).
//!
//! ## `[IO_Info]`
//!
//! Masks are DeviceNet's four connection bits (0 poll, 1 bit-strobe, 2 change of state, 3
//! cyclic). The checks, and what they follow (the DeviceNet files of `../shared/eds-corpus/`:
//! `hilscher_netx90_dns.eds`, `hilscher_dns_v5_simple.eds`, `hilscher_dns_v5_extended.eds`):
//!
//! | finding | severity | rule |
//! |---|---|---|
//! | a `PollInfo`/`StrobeInfo`/`COSInfo`/`CyclicInfo` default input or output that does not exist | error | `io-reference` |
//! | a connection with no default input and no `InputN` whose mask includes it: nothing tells a scanner its size | warning | `io-reference` |
//! | a default input or output whose mask excludes the connection | warning | `connection-mask` |
//! | `Default` enabling a connection that has no `...Info` | warning | `connection-mask` |
//! | a reserved mask bit (4–15) in `Default`, an `...Info` or an `InputN`/`OutputN` | warning | `connection-mask` |
//! | change of state and cyclic combined (`Default`, `COSInfo`, `CyclicInfo`): both are Connection instance 4, a node refuses them together (the corpus writes `COSInfo = 0x0007`, `CyclicInfo = 0x000B`) | warning | `connection-mask` |
//! | two `...Info` masks that disagree (poll says it combines with bit-strobe, `StrobeInfo` says it does not) | warning | `connection-mask` |
//! | `StrobeInfo`'s default input over 8 bytes: a bit-strobe response is at most 8 bytes, never fragmented | warning | `strobe-size` |
//! | an `InputN`/`OutputN` with more bits than bytes | error | `io-size` |
//!
//! The strobe size is a warning, not an error: two of the three vendor files name their 10-byte
//! `Input1` for the bit-strobe, so a real scanner evidently accepts such a file (it configures a
//! size the device cannot send). Other inputs whose mask includes bit-strobe are not judged by
//! size: the corpus marks every input `0x000F`, whatever its size, and picks a small one for the
//! strobe. `StrobeInfo` naming no default output (0) is the corpus's norm; a file that names one
//! is not faulted. A `[Connection Manager]` section (the CIP connections of EtherNet/IP and
//! ControlNet) is kept as written and not checked: no DeviceNet file of the corpus has one.
//!
//! Positions come from the text, so a model built in code (by a generator) is checked by writing
//! it first: `check_str(&Writer::new().write(&eds))`.

use crate::diag::{Diagnostic, Rule, Severity, Span};
use crate::error::EdsError;
use crate::model::{entry_key, Eds, IoEntry, Known, Param};
use crate::raw::{RawEds, RawEntry};
use crate::text::{decode, Encoding};
use crate::value::{parse_int, ConnectionMask, DataType, Value};
use devicenet::slave::STROBE_MAX_SIZE;
use serde::Serialize;
use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::path::{Path, PathBuf};

/// The findings of [`check`] on one file.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// The file checked, when it was a file.
    pub file: Option<PathBuf>,
    /// The encoding the text was decoded with (`None` when the input was refused before).
    pub encoding: Option<Encoding>,
    /// Every finding, ordered by position.
    pub diagnostics: Vec<Diagnostic>,
}

impl Report {
    /// The error diagnostics.
    pub fn errors(&self) -> impl Iterator<Item = &Diagnostic> {
        self.diagnostics.iter().filter(|d| d.severity == Severity::Error)
    }

    /// The warning diagnostics.
    pub fn warnings(&self) -> impl Iterator<Item = &Diagnostic> {
        self.diagnostics.iter().filter(|d| d.severity == Severity::Warning)
    }

    /// `true` when at least one error was found.
    #[must_use = "a check whose verdict is ignored tests nothing"]
    pub fn has_errors(&self) -> bool {
        self.errors().next().is_some()
    }

    /// The rules that fired, in diagnostic order (handy in tests).
    pub fn rules(&self) -> Vec<Rule> {
        self.diagnostics.iter().map(|d| d.rule).collect()
    }
}

impl fmt::Display for Report {
    /// One line per diagnostic, `FILE:LINE:COLUMN: SEVERITY[RULE]: MESSAGE`, then a count line.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = self.file.as_deref().map_or_else(|| "<input>".to_string(), |p| p.display().to_string());
        for diagnostic in &self.diagnostics {
            writeln!(f, "{file}:{diagnostic}")?;
        }
        let errors = self.errors().count();
        let warnings = self.warnings().count();
        write!(f, "{file}: {errors} error{}, {warnings} warning{}", plural(errors), plural(warnings))
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// Checks an EDS given as bytes (UTF-8, else Latin-1).
#[must_use = "a check whose report is ignored tests nothing"]
pub fn check(bytes: &[u8]) -> Report {
    match decode(bytes) {
        Ok((text, encoding)) => {
            let mut report = check_str(&text);
            report.encoding = Some(encoding);
            report
        }
        Err(error) => Report {
            file: None,
            encoding: None,
            diagnostics: vec![Diagnostic::error(Rule::Limit, error.span, error.kind.to_string())],
        },
    }
}

/// Checks decoded EDS text.
#[must_use = "a check whose report is ignored tests nothing"]
pub fn check_str(text: &str) -> Report {
    let (raw, syntax) = RawEds::parse_lenient(text);
    let mut diagnostics: Vec<Diagnostic> = syntax
        .into_iter()
        .map(|e| {
            let rule = match e.kind {
                crate::SyntaxError::TooLarge { .. }
                | crate::SyntaxError::TooMany { .. }
                | crate::SyntaxError::TooDeep(_) => Rule::Limit,
                _ => Rule::Syntax,
            };
            Diagnostic::error(rule, e.span, e.kind.to_string())
        })
        .collect();
    let (eds, lowering) = Eds::from_raw(&raw);
    diagnostics.extend(lowering);
    diagnostics.extend(check_model(&eds, &raw));
    diagnostics.sort_by(|a, b| {
        (a.span, std::cmp::Reverse(a.severity), a.rule, &a.message).cmp(&(
            b.span,
            std::cmp::Reverse(b.severity),
            b.rule,
            &b.message,
        ))
    });
    diagnostics.dedup();
    Report { file: None, encoding: Some(Encoding::Utf8), diagnostics }
}

/// Reads and checks the file at `path`.
///
/// # Errors
///
/// [`EdsError::Io`] when the file cannot be read; problems in the file are in the report.
pub fn check_file(path: impl AsRef<Path>) -> Result<Report, EdsError> {
    let path = path.as_ref();
    let bytes = crate::read_bytes(path)?;
    let mut report = check(&bytes);
    report.file = Some(path.to_path_buf());
    Ok(report)
}

/// Where entries and their fields are in the source, by section and keyword.
struct Locator<'a> {
    entries: HashMap<(Known, String), &'a RawEntry>,
    sections: HashMap<Known, Span>,
}

impl<'a> Locator<'a> {
    fn new(raw: &'a RawEds) -> Locator<'a> {
        let mut locator = Locator { entries: HashMap::new(), sections: HashMap::new() };
        for section in &raw.sections {
            let Some(kind) = Known::of(&section.name) else { continue };
            locator.sections.entry(kind).or_insert(section.span);
            for entry in &section.entries {
                locator.entries.entry((kind, entry_key(&entry.keyword))).or_insert(entry);
            }
        }
        locator
    }

    fn entry(&self, kind: Known, key: &str) -> Option<&'a RawEntry> {
        self.entries.get(&(kind, entry_key(key))).copied()
    }

    fn section(&self, kind: Known) -> Span {
        self.sections.get(&kind).copied().unwrap_or(Span::START)
    }

    /// The entry's position, else its section's.
    fn span(&self, kind: Known, key: &str) -> Span {
        self.entry(kind, key).map_or_else(|| self.section(kind), |e| e.span)
    }

    /// Field `index`'s position, else the entry's.
    fn field(&self, kind: Known, key: &str, index: usize) -> Span {
        match self.entry(kind, key) {
            Some(entry) => entry.fields.get(index).map_or(entry.span, |f| f.span),
            None => self.section(kind),
        }
    }
}

const FILE_REQUIRED: &[&str] = &["DescText", "CreateDate", "CreateTime", "Revision"];
const DEVICE_REQUIRED: &[&str] =
    &["VendCode", "VendName", "ProdType", "ProdTypeStr", "ProdCode", "MajRev", "MinRev", "ProdName"];

/// The semantic checks on a lowered model; `raw` is the file it came from, for positions.
pub fn check_model(eds: &Eds, raw: &RawEds) -> Vec<Diagnostic> {
    let mut checker = Checker { eds, at: Locator::new(raw), out: Vec::new() };
    checker.required();
    checker.classification();
    checker.io_info();
    checker.params();
    checker.enums();
    checker.groups();
    checker.out
}

struct Checker<'a> {
    eds: &'a Eds,
    at: Locator<'a>,
    out: Vec<Diagnostic>,
}

impl Checker<'_> {
    fn error(&mut self, rule: Rule, span: Span, message: String) {
        self.out.push(Diagnostic::error(rule, span, message));
    }

    fn warning(&mut self, rule: Rule, span: Span, message: String) {
        self.out.push(Diagnostic::warning(rule, span, message));
    }

    fn required(&mut self) {
        for (kind, present, keys) in [
            (Known::File, self.eds.file.is_some(), FILE_REQUIRED),
            (Known::Device, self.eds.device.is_some(), DEVICE_REQUIRED),
        ] {
            if !present {
                self.error(
                    Rule::MissingSection,
                    Span::START,
                    format!("required section [{}] is missing", kind.name()),
                );
                continue;
            }
            for key in keys {
                if self.at.entry(kind, key).is_none() {
                    let span = self.at.section(kind);
                    self.error(Rule::MissingKey, span, format!("[{}] has no `{key}`", kind.name()));
                }
            }
        }
        if self.eds.io_info.is_none() {
            self.warning(
                Rule::MissingSection,
                Span::START,
                "no [IO_Info] section: a scanner cannot learn the I/O connections and sizes".to_string(),
            );
        }
    }

    fn classification(&mut self) {
        let Some(classification) = &self.eds.classification else { return };
        let devicenet = classification
            .classes
            .values()
            .flatten()
            .any(|class| class.trim().eq_ignore_ascii_case("DeviceNet"));
        if !devicenet {
            let span = self.at.section(Known::Classification);
            self.warning(
                Rule::Classification,
                span,
                "[Device Classification] does not name DeviceNet (expected `ClassN = DeviceNet;`)"
                    .to_string(),
            );
        }
    }

    fn io_info(&mut self) {
        let Some(io) = &self.eds.io_info else { return };
        let connections = [
            ("PollInfo", &io.poll, ConnectionMask::POLL, "poll"),
            ("StrobeInfo", &io.strobe, ConnectionMask::STROBE, "strobe"),
            ("COSInfo", &io.cos, ConnectionMask::COS, "cos"),
            ("CyclicInfo", &io.cyclic, ConnectionMask::CYCLIC, "cyclic"),
        ];
        if let Some(mask) = io.default {
            let span = self.at.span(Known::IoInfo, "Default");
            self.mask_bits("Default", mask, span);
        }
        for (key, info, bit, name) in connections {
            let Some(info) = info else {
                if io.default.is_some_and(|d| d.has(bit)) {
                    let span = self.at.span(Known::IoInfo, "Default");
                    self.warning(
                        Rule::ConnectionMask,
                        span,
                        format!("`Default` enables {name} connections but there is no `{key}`"),
                    );
                }
                continue;
            };
            if let Some(mask) = info.compatible {
                let span = self.at.field(Known::IoInfo, key, 0);
                self.mask_bits(key, mask, span);
            }
            for (index, number, entries, prefix) in [
                (1, info.default_input, &io.inputs, "Input"),
                (2, info.default_output, &io.outputs, "Output"),
            ] {
                let Some(n) = number.filter(|&n| n != 0) else { continue };
                let span = self.at.field(Known::IoInfo, key, index);
                match entries.get(&n) {
                    None => self.error(
                        Rule::IoReference,
                        span,
                        format!("`{key}` names {prefix}{n} as its default, but there is no `{prefix}{n}`"),
                    ),
                    Some(IoEntry { mask: Some(mask), .. }) if !mask.has(bit) => self.warning(
                        Rule::ConnectionMask,
                        span,
                        format!("`{key}` uses {prefix}{n} by default, but {prefix}{n}'s mask {mask} excludes {name}"),
                    ),
                    Some(_) => {}
                }
            }
            let default_input = info.default_input.filter(|&n| n != 0);
            if default_input.is_none() && !io.inputs.values().any(|e| e.mask.is_some_and(|m| m.has(bit))) {
                let span = self.at.field(Known::IoInfo, key, 1);
                self.warning(
                    Rule::IoReference,
                    span,
                    format!(
                        "`{key}` names no default input and no InputN's mask includes {name}: nothing \
                         tells a scanner what the connection produces"
                    ),
                );
            }
        }
        self.exclusive_cos_cyclic(io);
        self.symmetric_masks(&connections);
        self.strobe_size(io);
        for (prefix, entries) in [("Input", &io.inputs), ("Output", &io.outputs)] {
            for (n, entry) in entries {
                let key = format!("{prefix}{n}");
                if let (Some(size), Some(bits)) = (entry.size, entry.bits) {
                    if u64::from(bits) > u64::from(size) * 8 {
                        let span = self.at.field(Known::IoInfo, &key, 1);
                        self.error(
                            Rule::IoSize,
                            span,
                            format!(
                                "`{key}` uses {bits} bits but is only {size} byte{}",
                                plural(size as usize)
                            ),
                        );
                    }
                }
                if let Some(mask) = entry.mask {
                    let span = self.at.field(Known::IoInfo, &key, 2);
                    self.mask_bits(&key, mask, span);
                }
                self.path_size(Known::IoInfo, &key, 4, entry.path_size, entry.path.as_ref());
            }
        }
    }

    /// A mask with bits beyond DeviceNet's four connection types.
    fn mask_bits(&mut self, key: &str, mask: ConnectionMask, span: Span) {
        let reserved = mask.0 & !ConnectionMask::ALL;
        if reserved != 0 {
            self.warning(
                Rule::ConnectionMask,
                span,
                format!(
                    "`{key}` mask {mask} sets reserved bits 0x{reserved:04X}: only bits 0-3 (poll, strobe, \
                     cos, cyclic) are defined"
                ),
            );
        }
    }

    /// Change of state and cyclic are both Connection instance 4: a mask that combines them
    /// announces an allocation a node refuses.
    fn exclusive_cos_cyclic(&mut self, io: &crate::model::IoInfo) {
        let both = ConnectionMask::COS | ConnectionMask::CYCLIC;
        let masks = [
            ("Default", io.default, None),
            ("COSInfo", io.cos.as_ref().and_then(|i| i.compatible), Some(0)),
            ("CyclicInfo", io.cyclic.as_ref().and_then(|i| i.compatible), Some(0)),
        ];
        for (key, mask, field) in masks {
            let Some(mask) = mask.filter(|m| m.has(both)) else { continue };
            let span = match field {
                Some(index) => self.at.field(Known::IoInfo, key, index),
                None => self.at.span(Known::IoInfo, key),
            };
            self.warning(
                Rule::ConnectionMask,
                span,
                format!(
                    "`{key}` mask {mask} combines cos and cyclic: both are Connection instance 4, one or \
                     the other (COSInfo 0x0007, CyclicInfo 0x000B)"
                ),
            );
        }
    }

    /// Two connections whose masks disagree on whether they combine (COS with cyclic is
    /// [`Self::exclusive_cos_cyclic`]'s).
    fn symmetric_masks(
        &mut self,
        connections: &[(&str, &Option<crate::model::ConnectionInfo>, u16, &str); 4],
    ) {
        let mask = |info: &Option<crate::model::ConnectionInfo>| info.as_ref().and_then(|i| i.compatible);
        for (i, &(key_a, info_a, bit_a, name_a)) in connections.iter().enumerate() {
            for &(key_b, info_b, bit_b, name_b) in &connections[i + 1..] {
                if bit_a | bit_b == ConnectionMask::COS | ConnectionMask::CYCLIC {
                    continue;
                }
                let (Some(a), Some(b)) = (mask(info_a), mask(info_b)) else { continue };
                if a.has(bit_b) != b.has(bit_a) {
                    let span = self.at.field(Known::IoInfo, key_a, 0);
                    let (yes, no) = if a.has(bit_b) { (key_a, key_b) } else { (key_b, key_a) };
                    self.warning(
                        Rule::ConnectionMask,
                        span,
                        format!(
                            "`{yes}` says {name_a} and {name_b} combine but `{no}` says they do not \
                             (`{key_a}` {a}, `{key_b}` {b})"
                        ),
                    );
                }
            }
        }
    }

    /// A bit-strobe response carries at most [`STROBE_MAX_SIZE`] bytes and is never fragmented.
    fn strobe_size(&mut self, io: &crate::model::IoInfo) {
        let Some(n) = io.strobe.as_ref().and_then(|i| i.default_input).filter(|&n| n != 0) else { return };
        let Some(size) = io.inputs.get(&n).and_then(|e| e.size) else { return };
        if size > u32::from(STROBE_MAX_SIZE) {
            let span = self.at.field(Known::IoInfo, "StrobeInfo", 1);
            self.warning(
                Rule::StrobeSize,
                span,
                format!(
                    "`StrobeInfo` uses Input{n} ({size} bytes) by default, but a bit-strobe response \
                     carries at most {STROBE_MAX_SIZE} bytes and is never fragmented"
                ),
            );
        }
    }

    fn path_size(
        &mut self,
        kind: Known,
        key: &str,
        index: usize,
        size: Option<u32>,
        path: Option<&crate::LinkPath>,
    ) {
        let Some(bytes) = path.and_then(|p| p.bytes()) else { return };
        let declared = size.unwrap_or(0);
        if usize::try_from(declared).ok() != Some(bytes.len()) {
            let span = self.at.field(kind, key, index);
            self.error(
                Rule::PathSize,
                span,
                format!("`{key}` declares a {declared}-byte path but its path has {} bytes", bytes.len()),
            );
        }
    }

    fn params(&mut self) {
        let eds = self.eds;
        for (n, param) in eds.params() {
            self.param(n, param);
        }
    }

    fn param(&mut self, n: u32, p: &Param) {
        let key = format!("Param{n}");
        let field = |c: &Self, i: usize| c.at.field(Known::Params, &key, i);
        if p.reserved.is_some_and(|r| r != 0) {
            let span = field(self, 0);
            self.warning(Rule::Reserved, span, format!("`{key}` reserved field is not 0"));
        }
        self.path_size(Known::Params, &key, 1, p.link_path_size, p.link_path.as_ref());
        match p.data_type {
            None => {
                let span = field(self, 4);
                self.error(Rule::InvalidValue, span, format!("`{key}` has no data type"));
            }
            Some(DataType::Unknown(code)) => {
                let span = field(self, 4);
                self.warning(
                    Rule::UnknownDataType,
                    span,
                    format!("`{key}` data type 0x{code:02X} is not a CIP elementary type; its values are not checked"),
                );
            }
            Some(data_type) => self.param_values(&key, p, data_type),
        }
        if p.scaling.divisor == Some(0) {
            let span = field(self, 13);
            let message = format!("`{key}` scaling divisor is 0");
            if p.descriptor.is_some_and(|d| d.scaling()) {
                self.error(Rule::Scaling, span, message);
            } else {
                self.warning(Rule::Scaling, span, message + " (scaling is not enabled in the descriptor)");
            }
        }
        let links = [p.links.multiplier, p.links.divisor, p.links.base, p.links.offset];
        for (i, link) in links.into_iter().enumerate() {
            if let Some(target) = link.filter(|&l| l != 0) {
                if self.eds.param(target).is_none() {
                    let span = field(self, 16 + i);
                    self.error(
                        Rule::UndefinedParam,
                        span,
                        format!(
                            "`{key}` {} refers to Param{target}, which does not exist",
                            Param::FIELD_NAMES[16 + i]
                        ),
                    );
                }
            }
        }
        let has_enum = self.eds.enum_strings(n).is_some();
        match p.descriptor {
            Some(d) if d.enumerated_strings() && !has_enum => {
                let span = field(self, 3);
                self.warning(
                    Rule::EnumDescriptor,
                    span,
                    format!("`{key}` descriptor announces enumerated strings but there are none (no Enum{n} nor [EnumPar] Param{n})"),
                );
            }
            Some(d) if !d.enumerated_strings() && has_enum => {
                let span = field(self, 3);
                self.warning(
                    Rule::EnumDescriptor,
                    span,
                    format!("`{key}` has enumerated strings but its descriptor 0x{:04X} lacks bit 1 (enumerated strings)", d.0),
                );
            }
            _ => {}
        }
    }

    fn param_values(&mut self, key: &str, p: &Param, data_type: DataType) {
        if let (Some(fixed), Some(size)) = (data_type.fixed_size(), p.data_size) {
            if fixed != size {
                let span = self.at.field(Known::Params, key, 5);
                self.error(
                    Rule::DataSize,
                    span,
                    format!(
                        "`{key}` data size {size} does not match data type {data_type} (0x{:02X}, {fixed} byte{})",
                        data_type.code(),
                        plural(fixed as usize)
                    ),
                );
            }
        }
        if p.data_size.is_none() {
            let span = self.at.field(Known::Params, key, 5);
            self.error(Rule::InvalidValue, span, format!("`{key}` has no data size"));
        }
        if data_type.is_string() || data_type == DataType::Epath {
            return;
        }
        let values = [(9, "minimum", &p.min), (10, "maximum", &p.max), (11, "default", &p.default)];
        let mut numbers: [Option<f64>; 3] = [None; 3];
        for (slot, (index, label, value)) in values.into_iter().enumerate() {
            let Some(value) = value else { continue };
            let span = self.at.field(Known::Params, key, index);
            match value {
                Value::Int(v) => {
                    if let Some((lo, hi)) = data_type.int_range() {
                        if !(lo..=hi).contains(v) {
                            self.error(
                                Rule::TypeRange,
                                span,
                                format!("`{key}` {label} {v} does not fit {data_type} ({lo}..={hi})"),
                            );
                        }
                    }
                }
                Value::Real(v) => {
                    if !data_type.is_real() {
                        self.error(
                            Rule::TypeRange,
                            span,
                            format!("`{key}` {label} {v:?} is not an integer ({data_type})"),
                        );
                    }
                }
                Value::Str(_) | Value::Text(_) => {
                    self.error(
                        Rule::InvalidValue,
                        span,
                        format!("`{key}` {label} {value} is not a number ({data_type})"),
                    );
                }
            }
            numbers[slot] = value.as_f64();
        }
        let [min, max, default] = numbers;
        if let (Some(lo), Some(hi)) = (min, max) {
            if lo > hi {
                let span = self.at.field(Known::Params, key, 9);
                self.error(
                    Rule::RangeOrder,
                    span,
                    format!("`{key}` minimum {} is greater than maximum {}", show(&p.min), show(&p.max)),
                );
                return;
            }
        }
        if let Some(d) = default {
            if min.is_some_and(|lo| d < lo) || max.is_some_and(|hi| d > hi) {
                let span = self.at.field(Known::Params, key, 11);
                self.error(
                    Rule::DefaultOutOfRange,
                    span,
                    format!(
                        "`{key}` default {} is outside {}..={}",
                        show(&p.default),
                        show(&p.min),
                        show(&p.max)
                    ),
                );
            }
        }
    }

    fn enums(&mut self) {
        let eds = self.eds;
        let explicit: BTreeMap<u32, usize> =
            eds.params.iter().flat_map(|s| s.enums.iter().map(|(n, e)| (*n, e.len()))).collect();
        for (&n, _) in explicit.iter() {
            let key = format!("Enum{n}");
            let Some(param) = eds.param(n) else {
                let span = self.at.span(Known::Params, &key);
                self.error(
                    Rule::UndefinedParam,
                    span,
                    format!("`{key}` gives strings for Param{n}, which does not exist"),
                );
                continue;
            };
            let entries = eds.enum_strings(n).map(|e| e.entries).unwrap_or_default();
            let value_spans =
                self.at.entry(Known::Params, &key).map(|r| first_spans(r.fields.iter().step_by(2)));
            for entry in &entries {
                if outside(param, entry.value) {
                    // Point at the value's own field when it can be found.
                    let span = value_spans
                        .as_ref()
                        .and_then(|spans| spans.get(&entry.value).copied())
                        .unwrap_or_else(|| self.at.span(Known::Params, &key));
                    self.warning(
                        Rule::EnumOutOfRange,
                        span,
                        format!(
                            "`{key}` value {} (\"{}\") is outside Param{n}'s range {}..={}",
                            entry.value,
                            entry.text,
                            show(&param.min),
                            show(&param.max)
                        ),
                    );
                }
            }
        }
        let Some(legacy) = &eds.enum_par else { return };
        for (&n, strings) in &legacy.enums {
            let key = format!("Param{n}");
            let span = self.at.span(Known::EnumPar, &key);
            let Some(param) = eds.param(n) else {
                self.error(
                    Rule::UndefinedParam,
                    span,
                    format!("[EnumPar] `{key}` gives strings for Param{n}, which does not exist"),
                );
                continue;
            };
            if explicit.contains_key(&n) {
                self.warning(
                    Rule::EnumConflict,
                    span,
                    format!("Param{n} has strings both in `Enum{n}` and in [EnumPar]; `Enum{n}` is used"),
                );
            }
            let range =
                param.min.as_ref().and_then(Value::as_int).zip(param.max.as_ref().and_then(Value::as_int));
            if let Some((lo, hi)) = range.filter(|(lo, hi)| lo <= hi) {
                let count = i128::try_from(strings.len()).unwrap_or(i128::MAX);
                let values = hi.saturating_sub(lo).saturating_add(1);
                if count != values {
                    self.warning(
                        Rule::EnumCount,
                        span,
                        format!(
                            "[EnumPar] `{key}` has {count} string{} for the {values} value{} {lo}..={hi}",
                            plural(strings.len()),
                            if values == 1 { "" } else { "s" }
                        ),
                    );
                }
            }
        }
    }

    fn groups(&mut self) {
        let eds = self.eds;
        for (n, group) in eds.groups() {
            let key = format!("Group{n}");
            let member_spans =
                self.at.entry(Known::Groups, &key).map(|r| first_spans(r.fields.iter().skip(2)));
            for &p in &group.params {
                if eds.param(p).is_some() {
                    continue;
                }
                let span = member_spans
                    .as_ref()
                    .and_then(|spans| spans.get(&i128::from(p)).copied())
                    .unwrap_or_else(|| self.at.span(Known::Groups, &key));
                self.error(
                    Rule::UndefinedParam,
                    span,
                    format!("`{key}` (\"{}\") lists Param{p}, which does not exist", group.name),
                );
            }
        }
    }
}

/// The position of the first field holding each integer value.
fn first_spans<'f>(fields: impl Iterator<Item = &'f crate::Field>) -> HashMap<i128, Span> {
    let mut spans = HashMap::new();
    for field in fields {
        if let Some(value) = field.value.as_text().and_then(parse_int) {
            spans.entry(value).or_insert(field.span);
        }
    }
    spans
}

/// `true` when `value` is outside the parameter's integer `min..=max` (unknown bounds: inside).
fn outside(param: &Param, value: i128) -> bool {
    let min = param.min.as_ref().and_then(Value::as_int);
    let max = param.max.as_ref().and_then(Value::as_int);
    match (min, max) {
        // An inverted range is reported on its own (range-order); its enum values are not judged.
        (Some(lo), Some(hi)) if lo > hi => false,
        _ => min.is_some_and(|lo| value < lo) || max.is_some_and(|hi| value > hi),
    }
}

fn show(value: &Option<Value>) -> String {
    value.as_ref().map_or_else(|| "(none)".to_string(), Value::to_string)
}

#[cfg(test)]
mod tests;
