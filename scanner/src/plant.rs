//! The plant file of `dnet-master ui --plant FILE.toml`: several DeviceNet networks, each with its
//! own bus and scan list, behind one console and one MQTT / Sparkplug namespace.
//!
//! ```toml
//! [[network]]
//! name = "line-a"                 # unique, [A-Za-z0-9_-], at most 32 characters
//! bus = "slcan:/dev/ttyUSB0"      # as --bus: sim, socketcan:IFACE, slcan:PATH[@SERIALBAUD]
//! scanlist = "line-a.toml"        # relative to the plant file
//! bitrate = "500k"                # optional (default: --bitrate)
//! master_mac = 0                  # optional (default: --master-mac, else 0)
//!
//! [[network]]
//! name = "line-b"
//! bus = "socketcan:can1"
//! scanlist = "line-b.toml"
//! ```
//!
//! [`read_plant`] reads the file and every scan list it names before anything is opened: every
//! error names the file, line and key ([`PlantError`]), a scan list's errors also the network.
//! Unknown keys are errors at every depth.

use crate::list::read_scan_list;
use crate::model::ScanList;
use can_io::bus::{Bitrate, BusSpec};
use harness_common::error::HarnessError;
use serde::Deserialize;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The most networks one plant file may name (each runs a thread of its own).
pub const MAX_NETWORKS: usize = 16;
/// The longest network name.
pub const MAX_NAME: usize = 32;

/// A plant file refused.
#[derive(Debug, thiserror::Error)]
pub enum PlantError {
    /// The file cannot be read.
    #[error("{file}: cannot read the plant file: {error}")]
    Read {
        /// The file.
        file: String,
        /// Why.
        error: std::io::Error,
    },
    /// A value or the file's structure refused: where, the key, and why.
    #[error("{file}:{line}:{column} plant file{}: {message}", key.as_ref().map_or_else(String::new, |k| format!(" (key `{k}`)")))]
    At {
        /// The file.
        file: String,
        /// 1-based line (0: the file as a whole).
        line: usize,
        /// 1-based column.
        column: usize,
        /// The key at fault, when known.
        key: Option<String>,
        /// Why.
        message: String,
    },
    /// A network's scan list refused.
    #[error("network {network}: {source}")]
    ScanList {
        /// The network's name.
        network: String,
        /// The scan list's error (file, line, key).
        source: Box<HarnessError>,
    },
}

/// One network of the plant, checked.
#[derive(Clone, Debug)]
pub struct PlantNetwork {
    /// Its name, unique in the plant, `[A-Za-z0-9_-]`.
    pub name: String,
    /// The bus as written (`slcan:/dev/ttyUSB0`).
    pub bus_text: String,
    /// The bus.
    pub bus: BusSpec,
    /// The scan list's file (the plant file's directory joined).
    pub scanlist: PathBuf,
    /// The scan list, read and checked.
    pub scan_list: ScanList,
    /// The bit rate (`None`: the command line's).
    pub bitrate: Option<Bitrate>,
    /// The scanner's MAC ID on this network.
    pub master_mac: u8,
}

/// A plant file, read and checked.
#[derive(Clone, Debug)]
pub struct Plant {
    /// The file.
    pub file: PathBuf,
    /// The networks, in the file's order.
    pub networks: Vec<PlantNetwork>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlantFile {
    #[serde(default, rename = "network")]
    networks: Vec<Spanned<NetworkFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NetworkFile {
    name: Spanned<String>,
    bus: Spanned<String>,
    scanlist: Spanned<String>,
    #[serde(default)]
    bitrate: Option<Spanned<String>>,
    #[serde(default)]
    master_mac: Option<Spanned<i64>>,
}

fn line_col(text: &str, at: usize) -> (usize, usize) {
    let before = text.get(..at.min(text.len())).unwrap_or("");
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

fn at(text: &str, file: &str, span: Option<Range<usize>>, key: Option<&str>, message: &str) -> PlantError {
    let (line, column) = span.map_or((0, 0), |s| line_col(text, s.start));
    // serde names an unknown key in its message: `unknown field `bitrat``.
    let unknown = || message.strip_prefix("unknown field `")?.split('`').next().map(str::to_string);
    PlantError::At {
        file: file.to_string(),
        line,
        column,
        key: key.map(str::to_string).or_else(unknown),
        message: message.to_string(),
    }
}

/// `true` for a name of 1 to [`MAX_NAME`] characters of `[A-Za-z0-9_-]` (it becomes part of
/// URLs, MQTT topics and Sparkplug device IDs).
#[must_use]
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME
        && name.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

/// A plant file's networks from `text` (`file` names it in errors), without reading the scan
/// lists: [`NetworkSpec`]s with the scan list's path joined to `dir`.
pub fn parse_plant(text: &str, file: &str, dir: &Path) -> Result<Vec<NetworkSpec>, PlantError> {
    let plant: PlantFile =
        toml::from_str(text).map_err(|e| at(text, file, e.span(), None, e.message().trim()))?;
    if plant.networks.is_empty() {
        return Err(at(text, file, None, None, "no [[network]]: nothing to scan"));
    }
    if plant.networks.len() > MAX_NETWORKS {
        let span = plant.networks.get(MAX_NETWORKS).map(Spanned::span);
        let message = format!("{} networks: at most {MAX_NETWORKS}", plant.networks.len());
        return Err(at(text, file, span, None, &message));
    }
    let mut specs: Vec<NetworkSpec> = Vec::new();
    for n in plant.networks.iter().map(Spanned::get_ref) {
        let name = n.name.get_ref();
        if !valid_name(name) {
            let message = format!("bad network name {name:?}: 1 to {MAX_NAME} characters of A-Z a-z 0-9 _ -");
            return Err(at(text, file, Some(n.name.span()), Some("name"), &message));
        }
        if specs.iter().any(|s| s.name == *name) {
            let message = format!("network name {name:?} is given twice");
            return Err(at(text, file, Some(n.name.span()), Some("name"), &message));
        }
        let bus: BusSpec = n.bus.get_ref().parse().map_err(|e: String| {
            at(text, file, Some(n.bus.span()), Some("bus"), &format!("bad bus {:?}: {e}", n.bus.get_ref()))
        })?;
        if let Some(other) = specs.iter().find(|s| s.bus != BusSpec::Sim && same_device(&s.bus, &bus)) {
            let message =
                format!("bus {:?} is network {:?}'s too: one network per bus", n.bus.get_ref(), other.name);
            return Err(at(text, file, Some(n.bus.span()), Some("bus"), &message));
        }
        let bitrate = match &n.bitrate {
            None => None,
            Some(b) => Some(b.get_ref().parse::<Bitrate>().map_err(|e| {
                at(
                    text,
                    file,
                    Some(b.span()),
                    Some("bitrate"),
                    &format!("bad bitrate {:?}: {e}", b.get_ref()),
                )
            })?),
        };
        let master_mac = match &n.master_mac {
            None => None,
            Some(m) => match u8::try_from(*m.get_ref()) {
                Ok(mac) if mac <= 63 => Some(mac),
                _ => {
                    let message = format!("master MAC {} is out of range 0..=63", m.get_ref());
                    return Err(at(text, file, Some(m.span()), Some("master_mac"), &message));
                }
            },
        };
        if n.scanlist.get_ref().is_empty() {
            return Err(at(text, file, Some(n.scanlist.span()), Some("scanlist"), "empty scan list path"));
        }
        specs.push(NetworkSpec {
            name: name.clone(),
            bus_text: n.bus.get_ref().clone(),
            bus,
            scanlist: dir.join(n.scanlist.get_ref()),
            bitrate,
            master_mac,
        });
    }
    Ok(specs)
}

/// Whether two buses name the same device (interface or serial port).
fn same_device(a: &BusSpec, b: &BusSpec) -> bool {
    match (a, b) {
        (BusSpec::SocketCan { iface: x }, BusSpec::SocketCan { iface: y }) => x == y,
        (BusSpec::Slcan { path: x, .. }, BusSpec::Slcan { path: y, .. }) => x == y,
        _ => false,
    }
}

/// One `[[network]]` as written, its scan list not yet read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NetworkSpec {
    /// Its name.
    pub name: String,
    /// The bus as written.
    pub bus_text: String,
    /// The bus.
    pub bus: BusSpec,
    /// The scan list's path (joined to the plant file's directory).
    pub scanlist: PathBuf,
    /// The bit rate given.
    pub bitrate: Option<Bitrate>,
    /// The master MAC given.
    pub master_mac: Option<u8>,
}

/// Reads the plant file at `path` and every scan list it names (relative to the file's
/// directory); `default_master_mac` is the scanner's MAC where a network gives none.
pub fn read_plant(path: &Path, default_master_mac: u8) -> Result<Plant, PlantError> {
    let file = path.display().to_string();
    let text =
        std::fs::read_to_string(path).map_err(|error| PlantError::Read { file: file.clone(), error })?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let specs = parse_plant(&text, &file, dir)?;
    let mut networks = Vec::with_capacity(specs.len());
    for s in specs {
        let master_mac = s.master_mac.unwrap_or(default_master_mac);
        let scan_list = read_scan_list(&s.scanlist, master_mac)
            .map_err(|e| PlantError::ScanList { network: s.name.clone(), source: Box::new(e) })?;
        networks.push(PlantNetwork {
            name: s.name,
            bus_text: s.bus_text,
            bus: s.bus,
            scanlist: s.scanlist,
            scan_list,
            bitrate: s.bitrate,
            master_mac,
        });
    }
    Ok(Plant { file: path.to_path_buf(), networks })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn parse(text: &str) -> Result<Vec<NetworkSpec>, PlantError> {
        parse_plant(text, "plant.toml", Path::new("/p"))
    }

    fn refused(text: &str) -> (usize, Option<String>, String) {
        match parse(text) {
            Err(PlantError::At { line, key, message, file, .. }) => {
                assert_eq!(file, "plant.toml");
                (line, key, message)
            }
            other => panic!("expected a refusal, got {other:?}"),
        }
    }

    const TWO: &str = "[[network]]\nname = \"a\"\nbus = \"slcan:/dev/pts/1\"\nscanlist = \"a.toml\"\n\
        bitrate = \"500k\"\nmaster_mac = 2\n\n[[network]]\nname = \"line_B-2\"\nbus = \"sim\"\nscanlist = \"sub/b.toml\"\n";

    #[test]
    fn two_networks_are_read_in_order() {
        let specs = parse(TWO).unwrap();
        assert_eq!(specs.len(), 2);
        assert_eq!(specs[0].name, "a");
        assert_eq!(specs[0].bus, BusSpec::Slcan { path: "/dev/pts/1".into(), baud: 115_200 });
        assert_eq!(specs[0].scanlist, Path::new("/p/a.toml"));
        assert_eq!(specs[0].bitrate, Some("500k".parse().unwrap()));
        assert_eq!(specs[0].master_mac, Some(2));
        assert_eq!(specs[1].name, "line_B-2");
        assert_eq!(specs[1].bus, BusSpec::Sim);
        assert_eq!(specs[1].scanlist, Path::new("/p/sub/b.toml"));
        assert_eq!((specs[1].bitrate, specs[1].master_mac), (None, None));
    }

    const NET: &str = "[[network]]\nname = \"a\"\nbus = \"sim\"\nscanlist = \"a.toml\"\n";

    #[rstest]
    #[case::unknown_key(&format!("{NET}bitrat = \"500k\"\n"), 5, Some("bitrat"), "unknown field")]
    #[case::unknown_top_key(&format!("scan = 1\n{NET}"), 1, Some("scan"), "unknown field")]
    #[case::missing_bus("[[network]]\nname = \"a\"\nscanlist = \"a.toml\"\n", 1, None, "missing field `bus`")]
    #[case::bad_name(
        "[[network]]\nname = \"a b\"\nbus = \"sim\"\nscanlist = \"a.toml\"\n",
        2,
        Some("name"),
        "bad network name"
    )]
    #[case::empty_name(
        "[[network]]\nname = \"\"\nbus = \"sim\"\nscanlist = \"a.toml\"\n",
        2,
        Some("name"),
        "bad network name"
    )]
    #[case::twice(&format!("{NET}{NET}"), 6, Some("name"), "given twice")]
    #[case::bad_bus(
        "[[network]]\nname = \"a\"\nbus = \"can0\"\nscanlist = \"a.toml\"\n",
        3,
        Some("bus"),
        "bad bus \"can0\""
    )]
    #[case::same_port(
        "[[network]]\nname = \"a\"\nbus = \"slcan:/dev/x\"\nscanlist = \"a.toml\"\n[[network]]\nname = \"b\"\nbus = \"slcan:/dev/x@9600\"\nscanlist = \"b.toml\"\n",
        7, Some("bus"), "network \"a\"'s too")]
    #[case::bad_bitrate(&format!("{NET}bitrate = \"9k\"\n"), 5, Some("bitrate"), "bad bitrate")]
    #[case::mac_range(&format!("{NET}master_mac = 64\n"), 5, Some("master_mac"), "out of range")]
    #[case::mac_negative(&format!("{NET}master_mac = -1\n"), 5, Some("master_mac"), "out of range")]
    #[case::wrong_type(
        "[[network]]\nname = 3\nbus = \"sim\"\nscanlist = \"a.toml\"\n",
        2,
        None,
        "invalid type"
    )]
    #[case::empty_path(
        "[[network]]\nname = \"a\"\nbus = \"sim\"\nscanlist = \"\"\n",
        4,
        Some("scanlist"),
        "empty"
    )]
    #[case::nothing("", 0, None, "no [[network]]")]
    #[case::syntax("[[network]\n", 1, None, "")]
    fn errors_name_line_and_key(
        #[case] text: &str,
        #[case] line: usize,
        #[case] key: Option<&str>,
        #[case] says: &str,
    ) {
        let (l, k, message) = refused(text);
        assert_eq!(l, line, "{message}");
        assert_eq!(k.as_deref(), key, "{message}");
        assert!(message.contains(says), "{message:?} does not say {says:?}");
    }

    #[test]
    fn too_many_networks_are_refused() {
        let text: String = (0..=MAX_NETWORKS)
            .map(|i| format!("[[network]]\nname = \"n{i}\"\nbus = \"sim\"\nscanlist = \"a.toml\"\n"))
            .collect();
        let (line, _, message) = refused(&text);
        assert_eq!(line, 4 * MAX_NETWORKS + 1);
        assert!(message.contains("at most 16"), "{message}");
    }

    #[test]
    fn a_scan_list_error_names_the_network_and_its_file() {
        let dir = std::env::temp_dir().join(format!("dnet-plant-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("a.toml"), "[[node]]\nmac = 70\ninput_size = 1\noutput_size = 1\n").unwrap();
        std::fs::write(dir.join("plant.toml"), NET).unwrap();
        let e = read_plant(&dir.join("plant.toml"), 0).unwrap_err().to_string();
        std::fs::remove_dir_all(&dir).unwrap();
        assert!(e.starts_with("network a: "), "{e}");
        assert!(e.contains("a.toml:2"), "{e}");
        assert!(e.contains("out of range"), "{e}");
    }

    #[test]
    fn a_missing_file_is_named() {
        let e = read_plant(Path::new("/nonexistent/plant.toml"), 0).unwrap_err().to_string();
        assert!(e.starts_with("/nonexistent/plant.toml: cannot read"), "{e}");
    }
}
