//! A summary of a parsed EDS for people (`Display`) and programs (`Serialize`), as printed by
//! `dnet-eds parse`.

use crate::model::{Device, Eds, EnumDialect, FileInfo, Group, IoEntry, IoInfo, Param, ParamEnum};
use crate::raw::{FieldValue, RawEntry};
use crate::value::{AttributePath, Value};
use serde::Serialize;
use std::fmt;

/// What a file contains, in brief: identity, I/O, parameters, enums, groups, and what was kept
/// without being understood.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// `[File]`.
    pub file: Option<FileInfo>,
    /// `[Device]`.
    pub identity: Option<Device>,
    /// `[Device Classification]` values (`DeviceNet`).
    pub classification: Vec<String>,
    /// `[IO_Info]`.
    pub io_info: Option<IoInfo>,
    /// Number of parameters.
    pub param_count: usize,
    /// Every parameter with its decoded link target.
    pub params: Vec<ParamSummary>,
    /// Every enum, both dialects, resolved to values.
    pub enums: Vec<ParamEnum>,
    /// Groups with their numbers.
    pub groups: Vec<GroupSummary>,
    /// Unknown sections kept.
    pub kept_sections: Vec<KeptSection>,
    /// Unknown entries of known sections kept.
    pub kept_entries: Vec<KeptEntry>,
}

/// One parameter in a [`Summary`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ParamSummary {
    /// Parameter number N of `ParamN`.
    pub number: u32,
    /// The attribute the link path addresses, when it is a plain logical path.
    pub attribute: Option<AttributePath>,
    /// All fields.
    #[serde(flatten)]
    pub param: Param,
}

/// One group in a [`Summary`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct GroupSummary {
    /// Group number N of `GroupN`.
    pub number: u32,
    /// Name and members.
    #[serde(flatten)]
    pub group: Group,
}

/// An unknown section kept as is.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct KeptSection {
    /// Name as written.
    pub name: String,
    /// Line of its header.
    pub line: u32,
    /// Number of entries.
    pub entries: usize,
}

/// An unknown entry of a known section, kept as is.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct KeptEntry {
    /// The section.
    pub section: String,
    /// The keyword as written.
    pub keyword: String,
    /// Line of the keyword.
    pub line: u32,
    /// The fields as written.
    pub fields: Vec<FieldValue>,
}

impl Summary {
    /// Summarizes `eds`.
    pub fn of(eds: &Eds) -> Summary {
        Summary {
            file: eds.file.clone(),
            identity: eds.device.clone(),
            classification: eds
                .classification
                .iter()
                .flat_map(|c| c.classes.values().flatten().cloned())
                .collect(),
            io_info: eds.io_info.clone(),
            param_count: eds.param_count(),
            params: eds
                .params()
                .map(|(number, p)| ParamSummary {
                    number,
                    attribute: p.link_path.as_ref().and_then(|l| l.attribute()),
                    param: p.clone(),
                })
                .collect(),
            enums: eds.enums(),
            groups: eds.groups().map(|(number, g)| GroupSummary { number, group: g.clone() }).collect(),
            kept_sections: eds
                .other_sections
                .iter()
                .map(|s| KeptSection { name: s.name.clone(), line: s.span.line, entries: s.entries.len() })
                .collect(),
            kept_entries: eds
                .other_entries()
                .into_iter()
                .map(|(section, e): (&str, &RawEntry)| KeptEntry {
                    section: section.to_string(),
                    keyword: e.keyword.clone(),
                    line: e.span.line,
                    fields: e.fields.iter().map(|f| f.value.clone()).collect(),
                })
                .collect(),
        }
    }
}

fn opt<T: fmt::Display>(value: &Option<T>) -> String {
    value.as_ref().map_or_else(|| "?".to_string(), T::to_string)
}

fn opt_str(value: &Option<String>) -> String {
    value.as_ref().map_or_else(|| "?".to_string(), |s| format!("{s:?}"))
}

fn io_line(f: &mut fmt::Formatter<'_>, key: &str, e: &IoEntry) -> fmt::Result {
    write!(f, "  {key:<10} {} bytes, {} bits", opt(&e.size), opt(&e.bits))?;
    if let Some(mask) = e.mask {
        write!(f, ", {mask}")?;
    }
    if let Some(path) = &e.path {
        write!(f, ", path {path}")?;
    }
    writeln!(f, ", {:?}", e.name)
}

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.file {
            Some(file) => writeln!(
                f,
                "file:           {} revision {}, created {} {}, modified {} {}",
                opt_str(&file.desc_text),
                opt(&file.revision),
                opt(&file.create_date),
                opt(&file.create_time),
                opt(&file.mod_date),
                opt(&file.mod_time),
            )?,
            None => writeln!(f, "file:           no [File] section")?,
        }
        match &self.identity {
            Some(d) => writeln!(
                f,
                "identity:       vendor {} {}, device type {} {}, product code {} {}, revision {}.{}, catalog {}",
                opt(&d.vend_code),
                opt_str(&d.vend_name),
                opt(&d.prod_type),
                opt_str(&d.prod_type_str),
                opt(&d.prod_code),
                opt_str(&d.prod_name),
                opt(&d.maj_rev),
                opt(&d.min_rev),
                opt_str(&d.catalog),
            )?,
            None => writeln!(f, "identity:       no [Device] section")?,
        }
        if self.classification.is_empty() {
            writeln!(f, "classification: none")?;
        } else {
            writeln!(f, "classification: {}", self.classification.join(", "))?;
        }
        match &self.io_info {
            Some(io) => {
                writeln!(f, "I/O:            default {}", opt(&io.default))?;
                for (name, info) in
                    [("poll", &io.poll), ("strobe", &io.strobe), ("cos", &io.cos), ("cyclic", &io.cyclic)]
                {
                    if let Some(info) = info {
                        let io = |n: Option<u32>, prefix: &str| match n {
                            None => "?".to_string(),
                            Some(0) => "none".to_string(),
                            Some(n) => format!("{prefix}{n}"),
                        };
                        writeln!(
                            f,
                            "  {name:<10} combines with {}, default input {}, default output {}",
                            opt(&info.compatible),
                            io(info.default_input, "Input"),
                            io(info.default_output, "Output")
                        )?;
                    }
                }
                for (n, e) in &io.inputs {
                    io_line(f, &format!("Input{n}"), e)?;
                }
                for (n, e) in &io.outputs {
                    io_line(f, &format!("Output{n}"), e)?;
                }
            }
            None => writeln!(f, "I/O:            no [IO_Info] section")?,
        }
        writeln!(f, "parameters:     {}", self.param_count)?;
        for p in &self.params {
            let param = &p.param;
            let show = |v: &Option<Value>| v.as_ref().map_or_else(|| "-".to_string(), Value::to_string);
            write!(
                f,
                "  Param{:<5} {:?} {}, {} byte{}, {}..={} default {}",
                p.number,
                param.name,
                opt(&param.data_type),
                opt(&param.data_size),
                if param.data_size == Some(1) { "" } else { "s" },
                show(&param.min),
                show(&param.max),
                show(&param.default)
            )?;
            if !param.units.is_empty() {
                write!(f, " {}", param.units)?;
            }
            match (&p.attribute, &param.link_path) {
                (Some(attribute), _) => write!(f, ", {attribute}")?,
                (None, Some(path)) => write!(f, ", path {path}")?,
                (None, None) => {}
            }
            writeln!(f)?;
        }
        let legacy = self.enums.iter().filter(|e| e.dialect == EnumDialect::EnumPar).count();
        writeln!(
            f,
            "enums:          {} ({} EnumN, {} [EnumPar])",
            self.enums.len(),
            self.enums.len() - legacy,
            legacy
        )?;
        for e in &self.enums {
            let dialect = match e.dialect {
                EnumDialect::Params => format!("Enum{}", e.param),
                EnumDialect::EnumPar => "[EnumPar]".to_string(),
            };
            let entries: Vec<String> =
                e.entries.iter().map(|x| format!("{} {:?}", x.value, x.text)).collect();
            writeln!(f, "  Param{:<5} {dialect}: {}", e.param, entries.join(", "))?;
        }
        writeln!(f, "groups:         {}", self.groups.len())?;
        for g in &self.groups {
            let members: Vec<String> = g.group.params.iter().map(|p| format!("Param{p}")).collect();
            writeln!(f, "  Group{:<5} {:?}: {}", g.number, g.group.name, members.join(", "))?;
        }
        let (sections, entries) = (self.kept_sections.len(), self.kept_entries.len());
        write!(
            f,
            "kept:           {sections} unknown section{}, {entries} unknown entr{}",
            if sections == 1 { "" } else { "s" },
            if entries == 1 { "y" } else { "ies" }
        )?;
        for s in &self.kept_sections {
            write!(f, "\n  [{}] line {}, {} entries", s.name, s.line, s.entries)?;
        }
        for e in &self.kept_entries {
            write!(f, "\n  [{}] {} line {}", e.section, e.keyword, e.line)?;
        }
        Ok(())
    }
}
