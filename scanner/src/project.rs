//! Network projects: the whole network in one TOML file, as RSNetWorx keeps it — the scan list,
//! each node's identity and keying, its stored configuration and its parameters — uploaded from
//! the network, compared with it, and downloaded back to it.
//!
//! ```toml
//! # dnet-master project (dnet-master project upload)
//! format = 1
//!
//! [[node]]
//! mac = 5
//! connection = "poll"          # the scan list entry: poll, strobe, cos or cyclic
//! input_size = 18
//! output_size = 8
//! name = "breaker feeder 1"    # optional
//! keying = "exact"             # exact (default), compatible or disabled
//! configuration = '''
//! [identity]
//! ...                          # the stored configuration, as `configure --read` writes it
//! '''
//!
//! [node.identity]
//! vendor_id = 0x1234
//! device_type = 0x000C
//! product_code = 1
//! major_revision = 1
//! minor_revision = 1
//! product_name = "Serial-DeviceNet Bridge"   # recorded, not compared
//! serial_number = 0x12345678                 # recorded, not compared
//!
//! [[node.param]]
//! number = 1                   # Parameter object instance (class 0x0F)
//! name = "Serial baud rate"
//! value = 9600
//! units = "baud"               # optional, recorded
//! read_only = false            # optional: a read-only parameter is compared, never written
//! ```
//!
//! [`parse`] refuses what it does not know: an unknown key at any depth, a MAC above 63 or given
//! twice, a keying or connection of no known name, a configuration the description reader
//! refuses (its own error, with the project file's line). Every error names the file and line.
//!
//! [`compare`] compares two projects — the file and the network read as a project
//! ([`network::read`]) — node by node: present on both sides, the scan list entry, the identity as
//! the node's keying says ([`crate::keying`]: exact: vendor, device type, product code, major and
//! minor revision equal; compatible: the same, with the network's minor revision the file's or
//! later; disabled: nothing), the
//! configuration key by key (`profile.serial.baud`), the parameters one by one (by instance
//! number: name and value). Product name and serial number are recorded, not compared: a
//! replacement device of the same kind has its own serial number.

pub mod console;
pub mod network;
#[cfg(test)]
mod tests;

use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use std::ops::Range;

/// The file format this code writes and reads.
pub const FORMAT: u32 = 1;

/// Why a project file was refused: the file, the line (1-based; 0 when the file as a whole), and
/// what is wrong.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct ProjectError {
    /// The file.
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// How a node's identity is compared: the scanner's keying ([`crate::keying`]), the same rule.
pub use crate::keying::Keying;

/// A node's identity (Identity object, class 1, instance 1).
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct NodeIdentity {
    /// Attribute 1.
    pub vendor_id: u16,
    /// Attribute 2.
    pub device_type: u16,
    /// Attribute 3.
    pub product_code: u16,
    /// Attribute 4, major.
    pub major_revision: u8,
    /// Attribute 4, minor.
    pub minor_revision: u8,
    /// Attribute 7 (recorded, not compared).
    #[serde(default)]
    pub product_name: String,
    /// Attribute 6 (recorded, not compared).
    #[serde(default)]
    pub serial_number: Option<u32>,
}

impl NodeIdentity {
    /// The electronic key: attributes 1–4.
    #[must_use]
    pub fn electronic_key(&self) -> crate::keying::ElectronicKey {
        crate::keying::ElectronicKey {
            vendor_id: Some(self.vendor_id),
            device_type: Some(self.device_type),
            product_code: Some(self.product_code),
            major_revision: Some(self.major_revision),
            minor_revision: Some(self.minor_revision),
        }
    }
}

/// One parameter (a Parameter object instance).
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectParam {
    /// Instance number.
    pub number: u32,
    /// Name (attribute 7).
    pub name: String,
    /// The value decoded by its data type.
    #[serde(default)]
    pub value: Option<i64>,
    /// The raw value in hex, when it has no number (a value of another type).
    #[serde(default)]
    pub raw: Option<String>,
    /// Units (recorded).
    #[serde(default)]
    pub units: String,
    /// Descriptor bit 4: compared, never written.
    #[serde(default)]
    pub read_only: bool,
}

impl ProjectParam {
    /// The value as written in reports: the number, else the raw hex.
    #[must_use]
    pub fn value_text(&self) -> String {
        match (self.value, &self.raw) {
            (Some(v), _) => v.to_string(),
            (None, Some(raw)) => format!("0x{raw}"),
            (None, None) => "-".into(),
        }
    }
}

/// One node of a project.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectNode {
    /// MAC ID.
    pub mac: u8,
    /// The scan list's connection: poll, strobe, cos or cyclic.
    #[serde(default = "poll")]
    pub connection: String,
    /// Input size (what the node produces).
    pub input_size: u16,
    /// Output size (what the node consumes).
    pub output_size: u16,
    /// A name for the node.
    #[serde(default)]
    pub name: Option<String>,
    /// How the identity is compared.
    #[serde(default)]
    pub keying: Keying,
    /// The identity.
    pub identity: NodeIdentity,
    /// The stored configuration as a device description (`None`: the node has no configuration
    /// object).
    #[serde(default)]
    pub configuration: Option<String>,
    /// The parameters, by instance.
    #[serde(default)]
    pub param: Vec<ProjectParam>,
}

fn poll() -> String {
    "poll".into()
}

/// A network project.
#[derive(Clone, Debug, Default, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct Project {
    /// The file format ([`FORMAT`]).
    pub format: u32,
    /// The nodes, by MAC.
    #[serde(default)]
    pub node: Vec<ProjectNode>,
}

/// The connection names a scan list knows.
const CONNECTIONS: [&str; 4] = ["poll", "strobe", "cos", "cyclic"];

/// 1-based line of byte `at` in `text`.
fn line_of(text: &str, at: usize) -> usize {
    text.get(..at.min(text.len())).map_or(1, |b| b.matches('\n').count() + 1)
}

/// Where each node's values are, for the checks after the typed read.
#[derive(Deserialize)]
struct Spans {
    #[serde(default)]
    node: Vec<toml::Spanned<SpannedNode>>,
}

#[derive(Deserialize)]
struct SpannedNode {
    mac: Option<toml::Spanned<toml::Value>>,
    connection: Option<toml::Spanned<toml::Value>>,
    configuration: Option<toml::Spanned<toml::Value>>,
}

/// Reads a project from `text` (`file` names it in errors). See the [module docs](self).
pub fn parse(text: &str, file: &str) -> Result<Project, ProjectError> {
    let error = |line: usize, message: String| ProjectError { file: file.to_string(), line, message };
    let project: Project = toml::from_str(text).map_err(|e| {
        let line = e.span().map_or(0, |s| line_of(text, s.start));
        error(line, e.message().trim().replace("field", "key"))
    })?;
    let spans: Spans = toml::from_str(text).map_err(|e| error(0, e.message().trim().to_string()))?;
    let at = |i: usize, pick: fn(&SpannedNode) -> Option<Range<usize>>| -> usize {
        let node = spans.node.get(i);
        node.and_then(|n| pick(n.get_ref()))
            .or_else(|| node.map(toml::Spanned::span))
            .map_or(0, |s| line_of(text, s.start))
    };
    if project.format != FORMAT {
        return Err(error(1, format!("format {}: this dnet-master reads format {FORMAT}", project.format)));
    }
    let mut seen = BTreeMap::new();
    for (i, n) in project.node.iter().enumerate() {
        let mac_line = at(i, |n| n.mac.as_ref().map(toml::Spanned::span));
        if n.mac > 63 {
            return Err(error(mac_line, format!("node.mac = {}: a MAC ID is 0..=63", n.mac)));
        }
        if let Some(first) = seen.insert(n.mac, mac_line) {
            return Err(error(mac_line, format!("MAC {} is given twice (first at line {first})", n.mac)));
        }
        if !CONNECTIONS.contains(&n.connection.as_str()) {
            let line = at(i, |n| n.connection.as_ref().map(toml::Spanned::span));
            return Err(error(
                line,
                format!("node.connection = \"{}\": one of {}", n.connection, CONNECTIONS.join(", ")),
            ));
        }
        let mut numbers = BTreeMap::new();
        for p in &n.param {
            if numbers.insert(p.number, ()).is_some() {
                return Err(error(mac_line, format!("MAC {}: parameter {} is given twice", n.mac, p.number)));
            }
        }
        if let Some(config) = &n.configuration {
            check_configuration(text, config, at(i, configuration_span))
                .map_err(|(line, message)| error(line, format!("MAC {} configuration: {message}", n.mac)))?;
        }
    }
    let mut project = project;
    project.node.sort_by_key(|n| n.mac);
    Ok(project)
}

fn configuration_span(n: &SpannedNode) -> Option<Range<usize>> {
    n.configuration.as_ref().map(toml::Spanned::span)
}

/// The description reader's verdict on a node's configuration; an error comes with the line in
/// the project file (`starts`: the line of the `configuration =` value).
fn check_configuration(text: &str, config: &str, starts: usize) -> Result<(), (usize, String)> {
    match slave_fw::description::DeviceDescription::parse(config) {
        Ok(_) => Ok(()),
        Err(e) => {
            // The value's first line is the one after `'''` (a newline right after the opening
            // delimiter is not part of the string).
            let opening = text.lines().nth(starts.saturating_sub(1)).unwrap_or_default();
            let first = if opening.trim_end().ends_with("'''") || opening.trim_end().ends_with("\"\"\"") {
                starts + 1
            } else {
                starts
            };
            match e.kind {
                slave_fw::description::DescriptionErrorKind::Toml(t) => {
                    let key = t.key.map(|k| format!("{k}: ")).unwrap_or_default();
                    Err(((first + t.line).saturating_sub(1), format!("{key}{}", t.message)))
                }
                slave_fw::description::DescriptionErrorKind::Invalid { key, message, .. } => {
                    Err((starts, format!("{key}: {message}")))
                }
                slave_fw::description::DescriptionErrorKind::Io(e) => Err((starts, e.to_string())),
            }
        }
    }
}

/// Reads the project file at `path`.
pub fn read(path: &std::path::Path) -> Result<Project, ProjectError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| ProjectError {
        file: file.clone(),
        line: 0,
        message: format!("cannot read the project: {e}"),
    })?;
    parse(&text, &file)
}

/// A TOML basic string.
fn quoted(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// The project as TOML, in the form [`parse`] reads (`parse(write(p)) == p`).
#[must_use]
pub fn write(project: &Project, header: &str) -> String {
    let mut out = String::new();
    for line in header.lines() {
        out.push_str(&format!("# {line}\n"));
    }
    out.push_str(&format!("format = {}\n", project.format));
    for n in &project.node {
        out.push_str(&format!(
            "\n[[node]]\nmac = {}\nconnection = {}\ninput_size = {}\noutput_size = {}\n",
            n.mac,
            quoted(&n.connection),
            n.input_size,
            n.output_size
        ));
        if let Some(name) = &n.name {
            out.push_str(&format!("name = {}\n", quoted(name)));
        }
        out.push_str(&format!("keying = \"{}\"\n", n.keying.name()));
        if let Some(config) = &n.configuration {
            if config.contains("'''") {
                out.push_str(&format!("configuration = {}\n", quoted(config)));
            } else {
                out.push_str(&format!("configuration = '''\n{config}'''\n"));
            }
        }
        let id = &n.identity;
        out.push_str(&format!(
            "\n[node.identity]\nvendor_id = 0x{:04X}\ndevice_type = 0x{:04X}\nproduct_code = {}\n\
             major_revision = {}\nminor_revision = {}\nproduct_name = {}\n",
            id.vendor_id,
            id.device_type,
            id.product_code,
            id.major_revision,
            id.minor_revision,
            quoted(&id.product_name)
        ));
        if let Some(s) = id.serial_number {
            out.push_str(&format!("serial_number = 0x{s:08X}\n"));
        }
        for p in &n.param {
            out.push_str(&format!("\n[[node.param]]\nnumber = {}\nname = {}\n", p.number, quoted(&p.name)));
            if let Some(v) = p.value {
                out.push_str(&format!("value = {v}\n"));
            }
            if let Some(raw) = &p.raw {
                out.push_str(&format!("raw = {}\n", quoted(raw)));
            }
            if !p.units.is_empty() {
                out.push_str(&format!("units = {}\n", quoted(&p.units)));
            }
            out.push_str(&format!("read_only = {}\n", p.read_only));
        }
    }
    out
}

/// One difference between the file and the network.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Difference {
    /// The node.
    pub mac: u8,
    /// What differs: `node`, `identity vendor_id`, `configuration profile.serial.baud`,
    /// `parameter 1 (Serial baud rate)`, `scan list input_size`.
    pub what: String,
    /// The file's value (`-`: absent).
    pub file: String,
    /// The network's value (`-`: absent).
    pub network: String,
}

impl fmt::Display for Difference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "MAC {}: {}: file {}, network {}", self.mac, self.what, self.file, self.network)
    }
}

/// The result of a comparison.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Comparison {
    /// Every difference, by MAC.
    pub differences: Vec<Difference>,
    /// Nodes of the file found on the network and compared.
    pub compared: usize,
    /// Parameters compared.
    pub params_compared: usize,
    /// Configuration keys compared.
    pub configuration_keys_compared: usize,
}

/// Compares the `file` project with the `network` read as a project. See the [module docs](self).
#[must_use]
pub fn compare(file: &Project, network: &Project) -> Comparison {
    let mut c = Comparison::default();
    let find = |p: &Project, mac: u8| p.node.iter().find(|n| n.mac == mac).cloned();
    let mut macs: Vec<u8> = file.node.iter().chain(&network.node).map(|n| n.mac).collect();
    macs.sort_unstable();
    macs.dedup();
    for mac in macs {
        let diff =
            |what: &str, file: String, network: String| Difference { mac, what: what.into(), file, network };
        match (find(file, mac), find(network, mac)) {
            (Some(_), None) => {
                c.differences.push(diff("node", "present".into(), "absent (no answer)".into()))
            }
            (None, Some(n)) => c.differences.push(diff(
                "node",
                "absent".into(),
                format!("present ({})", n.identity.product_name),
            )),
            (Some(f), Some(n)) => {
                c.compared += 1;
                compare_node(&f, &n, &mut c);
            }
            (None, None) => {}
        }
    }
    c
}

fn compare_node(f: &ProjectNode, n: &ProjectNode, c: &mut Comparison) {
    let mac = f.mac;
    let mut push = |what: String, file: String, network: String| {
        c.differences.push(Difference { mac, what, file, network });
    };
    for (what, a, b) in [
        ("scan list connection", f.connection.clone(), n.connection.clone()),
        ("scan list input_size", f.input_size.to_string(), n.input_size.to_string()),
        ("scan list output_size", f.output_size.to_string(), n.output_size.to_string()),
    ] {
        if a != b {
            push(what.into(), a, b);
        }
    }
    let (fi, ni) = (&f.identity, &n.identity);
    for m in crate::keying::mismatches(f.keying, &fi.electronic_key(), &ni.electronic_key()) {
        let read = m.read.map_or_else(|| "-".into(), |v| v.to_string());
        push(format!("identity {} (keying {})", m.part.key(), f.keying.name()), m.expected.to_string(), read);
    }
    match (&f.configuration, &n.configuration) {
        (Some(a), Some(b)) => {
            let (a, b) = (flatten_toml(a), flatten_toml(b));
            let mut keys: Vec<&String> = a.keys().chain(b.keys()).collect();
            keys.sort_unstable();
            keys.dedup();
            for key in keys {
                c.configuration_keys_compared += 1;
                let (x, y) = (a.get(key), b.get(key));
                if x != y {
                    let text = |v: Option<&String>| v.cloned().unwrap_or_else(|| "-".into());
                    push(format!("configuration {key}"), text(x), text(y));
                }
            }
        }
        (Some(_), None) => {
            push("configuration".into(), "stored".into(), "none (no configuration object)".into())
        }
        (None, Some(_)) => push("configuration".into(), "none".into(), "stored".into()),
        (None, None) => {}
    }
    let mut numbers: Vec<u32> = f.param.iter().chain(&n.param).map(|p| p.number).collect();
    numbers.sort_unstable();
    numbers.dedup();
    for number in numbers {
        let (a, b) =
            (f.param.iter().find(|p| p.number == number), n.param.iter().find(|p| p.number == number));
        c.params_compared += 1;
        let label = |p: &ProjectParam| format!("parameter {number} ({})", p.name);
        match (a, b) {
            (Some(a), Some(b)) => {
                if !a.name.eq_ignore_ascii_case(&b.name) {
                    push(format!("parameter {number} name"), a.name.clone(), b.name.clone());
                } else if (a.value, &a.raw) != (b.value, &b.raw) {
                    push(label(a), a.value_text(), b.value_text());
                }
            }
            (Some(a), None) => push(label(a), a.value_text(), "absent".into()),
            (None, Some(b)) => push(label(b), "absent".into(), b.value_text()),
            (None, None) => {}
        }
    }
}

/// A TOML document's leaves by dotted key (`profile.serial.baud`, `profile.modbus.scan[1].offset`),
/// each value as TOML writes it. Text that is not TOML is one leaf, the whole text.
#[must_use]
pub fn flatten_toml(text: &str) -> BTreeMap<String, String> {
    let mut out = BTreeMap::new();
    match text.parse::<toml::Table>() {
        Ok(table) => flatten_into(&mut out, String::new(), &toml::Value::Table(table)),
        Err(_) => {
            out.insert(String::new(), text.to_string());
        }
    }
    out
}

fn flatten_into(out: &mut BTreeMap<String, String>, key: String, value: &toml::Value) {
    match value {
        toml::Value::Table(t) => {
            for (k, v) in t {
                let key = if key.is_empty() { k.clone() } else { format!("{key}.{k}") };
                flatten_into(out, key, v);
            }
        }
        toml::Value::Array(a) if a.iter().all(toml::Value::is_table) && !a.is_empty() => {
            for (i, v) in a.iter().enumerate() {
                flatten_into(out, format!("{key}[{i}]"), v);
            }
        }
        other => {
            out.insert(key, other.to_string());
        }
    }
}
