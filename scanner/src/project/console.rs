//! The project compared with the running scanner (`dnet-master ui --project FILE`,
//! `GET /api/project/compare`).
//!
//! The scanner engine reads attributes one at a time between its cycles (Get_Attribute_Single on
//! the node's explicit connection); it cannot read a configuration image (Read_Chunk of the
//! configuration object, class 0x66). So, node by node, [`compare_running`] compares
//!
//! - **presence**: every node of the project in the scan list, and no node of the scan list
//!   missing from the project;
//! - **scan list**: the connection, and the I/O sizes the scanner read from the node;
//! - **identity**, as the project's keying says (exact: vendor, device type, product code, major
//!   and minor revision; compatible: a minor revision at least the file's; disabled: nothing),
//!   from what the scanner read when it brought the node up ([`NodeState::identity`]);
//! - **configuration**, by its consistency value (CCV, Identity attribute 9, protocol §II.5.3): the
//!   converter's CCV is the CRC-16/MODBUS of its stored configuration image without serial number,
//!   MAC ID and data rate (`slave_fw::converter::consistency`), so the project's expected value is
//!   that function over the image the project's configuration encodes to. (The configuration
//!   object's attribute 4, the image's CRC-32, is not used: it covers the device's own serial
//!   number and MAC ID, so two devices with the same configuration would differ.) A CCV tells
//!   whether the configurations are equal, not which key differs: `dnet-master project compare`
//!   reads the image and names the keys.
//! - **parameters**, each read (Parameter object, class 0x0F, instance N, attribute 1, decoded by
//!   its data type, attribute 5) and compared with the project's value.
//!
//! The CCV and the parameters are read only from a node the scanner has in I/O (ok or idle): a
//! node that does not answer would make each read wait for its timeout. One comparison makes at
//! most [`MAX_READS`] reads.
//!
//! Whatever could not be compared (an attribute the node did not give, an identity the scanner
//! never read, a keying that asks for nothing) is listed in [`RunningComparison::not_compared`]
//! with why. [`RunningComparison::equal`] is true only when something was compared, nothing
//! differs and nothing that should have been compared was left out.

use super::{Keying, Project, ProjectNode, ProjectParam};
use crate::model::{NodeState, NodeStatus};
use crate::params::{decode_value, PARAMETER_CLASS};
use serde::Serialize;

/// Identity object class (protocol §II.3).
const IDENTITY_CLASS: u16 = 0x01;
/// Identity attribute 9, the configuration consistency value.
const CCV_ATTRIBUTE: u8 = 9;
/// Attribute reads one comparison makes at most (each is answered between two scan cycles; a
/// project of 63 converters with their 9 parameters needs 1197); what would need more is listed
/// as not compared.
pub const MAX_READS: usize = 2048;

/// Reads one attribute of a node (`mac`, class, instance, attribute): the value's bytes, or why
/// not in words.
pub type ReadAttribute<'a> = dyn FnMut(u8, u16, u16, u8) -> Result<Vec<u8>, String> + 'a;

/// One difference between the project and the running network.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct RunningDifference {
    /// The node.
    pub mac: u8,
    /// What differs: `node`, `scan list connection`, `identity product_code (keying exact)`,
    /// `configuration (CCV, Identity attribute 9)`, `parameter 1 (Serial baud rate)`.
    pub what: String,
    /// The project's value.
    pub expected: String,
    /// The network's value.
    pub found: String,
}

/// A part of a node that was not compared, and why.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct NotCompared {
    /// The node.
    pub mac: u8,
    /// The part: `identity`, `configuration`, `parameter 3`, `scan list input_size`.
    pub what: String,
    /// Why, in words.
    pub why: String,
    /// Whether the project asked for it (`false`: the project itself asks for no comparison, as
    /// keying `disabled` does; this does not make the comparison unequal).
    pub wanted: bool,
}

/// How many of each part were compared.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ComparedParts {
    /// Project nodes found in the scan list.
    pub nodes: usize,
    /// Scan list entries (connection and sizes) compared.
    pub scan_list: usize,
    /// Identities compared (by keying).
    pub identity: usize,
    /// Configurations compared by CCV.
    pub configuration: usize,
    /// Parameters compared.
    pub parameters: usize,
}

/// The project against the running network ([module docs](self)).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct RunningComparison {
    /// What was compared.
    pub compared: ComparedParts,
    /// What was not, and why.
    pub not_compared: Vec<NotCompared>,
    /// Every difference, by MAC.
    pub differences: Vec<RunningDifference>,
}

impl RunningComparison {
    /// Whether anything at all was compared (a project node found in the scan list and one of its
    /// parts compared).
    #[must_use]
    pub fn anything_compared(&self) -> bool {
        let c = &self.compared;
        c.nodes > 0 && c.scan_list + c.identity + c.configuration + c.parameters > 0
    }

    /// Something was compared, nothing differs, nothing the project asked for was left out.
    #[must_use]
    pub fn equal(&self) -> bool {
        self.anything_compared() && self.differences.is_empty() && self.not_compared.iter().all(|n| !n.wanted)
    }
}

/// Compares `project` with the scanner's `nodes`, reading what the states do not hold with
/// `read` (module docs).
pub fn compare_running(
    project: &Project,
    nodes: &[NodeState],
    read: &mut ReadAttribute<'_>,
) -> RunningComparison {
    let mut c = RunningComparison::default();
    let mut reads = 0usize;
    let mut read = |mac: u8, class: u16, instance: u16, attribute: u8| {
        reads += 1;
        if reads > MAX_READS {
            return Err(format!("more than {MAX_READS} reads in one comparison"));
        }
        read(mac, class, instance, attribute)
    };
    let mut macs: Vec<u8> = project.node.iter().map(|n| n.mac).chain(nodes.iter().map(|n| n.mac)).collect();
    macs.sort_unstable();
    macs.dedup();
    for mac in macs {
        let file = project.node.iter().find(|n| n.mac == mac);
        let state = nodes.iter().find(|n| n.mac == mac);
        match (file, state) {
            (Some(_), None) => c.differences.push(RunningDifference {
                mac,
                what: "node".into(),
                expected: "in the scan list".into(),
                found: "not in the scan list".into(),
            }),
            (None, Some(s)) => c.differences.push(RunningDifference {
                mac,
                what: "node".into(),
                expected: "not in the project".into(),
                found: format!(
                    "in the scan list ({})",
                    s.identity.product_name.as_deref().unwrap_or("identity not read")
                ),
            }),
            (Some(f), Some(s)) => {
                c.compared.nodes += 1;
                compare_node(f, s, &mut read, &mut c);
            }
            (None, None) => {}
        }
    }
    c
}

fn compare_node(f: &ProjectNode, s: &NodeState, read: &mut ReadAttribute<'_>, c: &mut RunningComparison) {
    let mac = f.mac;
    compare_scan_list(f, s, c);
    compare_identity(f, s, c);
    // A node the scanner has not in I/O is not asked: each read would wait for its timeout.
    if !matches!(s.status, NodeStatus::Ok | NodeStatus::Idle) {
        let why = format!("not read: the node is {} (code {})", s.status.name(), s.code);
        if f.configuration.is_some() {
            not(c, mac, "configuration", why.clone());
        }
        for p in &f.param {
            not(c, mac, &format!("parameter {} ({})", p.number, p.name), why.clone());
        }
        return;
    }
    if let Some(config) = &f.configuration {
        match expected_ccv(config) {
            Ok(expected) => match read(mac, IDENTITY_CLASS, 1, CCV_ATTRIBUTE) {
                Ok(bytes) => match <[u8; 2]>::try_from(bytes.as_slice()) {
                    Ok(b) => {
                        c.compared.configuration += 1;
                        let found = u16::from_le_bytes(b);
                        if found != expected {
                            c.differences.push(RunningDifference {
                                mac,
                                what: "configuration (CCV, Identity attribute 9)".into(),
                                expected: format!("0x{expected:04X}"),
                                found: format!("0x{found:04X}"),
                            });
                        }
                    }
                    Err(_) => {
                        not(c, mac, "configuration", format!("the CCV read has {} bytes, not 2", bytes.len()))
                    }
                },
                Err(e) => {
                    not(c, mac, "configuration", format!("the CCV (Identity attribute 9) not read: {e}"))
                }
            },
            Err(e) => not(c, mac, "configuration", e.to_string()),
        }
    }
    for p in &f.param {
        compare_param(mac, p, read, c);
    }
}

/// Records a part that should have been compared and was not.
fn not(c: &mut RunningComparison, mac: u8, what: &str, why: String) {
    c.not_compared.push(NotCompared { mac, what: what.into(), why, wanted: true });
}

fn compare_scan_list(f: &ProjectNode, s: &NodeState, c: &mut RunningComparison) {
    let mac = f.mac;
    c.compared.scan_list += 1;
    if f.connection != s.connection {
        c.differences.push(RunningDifference {
            mac,
            what: "scan list connection".into(),
            expected: f.connection.clone(),
            found: s.connection.clone(),
        });
    }
    for (what, expected, found) in
        [("input_size", f.input_size, s.input_size), ("output_size", f.output_size, s.output_size)]
    {
        match found {
            Some(found) if found != expected => c.differences.push(RunningDifference {
                mac,
                what: format!("scan list {what}"),
                expected: expected.to_string(),
                found: found.to_string(),
            }),
            Some(_) => {}
            None => {
                not(c, mac, &format!("scan list {what}"), "the scanner has not read the node's size".into())
            }
        }
    }
}

fn compare_identity(f: &ProjectNode, s: &NodeState, c: &mut RunningComparison) {
    let mac = f.mac;
    if f.keying == Keying::Disabled {
        c.not_compared.push(NotCompared {
            mac,
            what: "identity".into(),
            why: "keying = \"disabled\" in the project".into(),
            wanted: false,
        });
        return;
    }
    let id = &s.identity;
    let revision = id.revision.as_deref().and_then(|r| r.split_once('.'));
    let revision = revision.and_then(|(a, b)| Some((a.parse::<u8>().ok()?, b.parse::<u8>().ok()?)));
    let (Some(vendor), Some(device_type), Some(product_code), Some((major, minor))) =
        (id.vendor_id, id.device_type, id.product_code, revision)
    else {
        not(
            c,
            mac,
            "identity",
            format!("the scanner has not read the node's identity (status {:?})", s.status),
        );
        return;
    };
    c.compared.identity += 1;
    let fi = &f.identity;
    let keying = f.keying.name();
    for (what, expected, found) in [
        ("vendor_id", fi.vendor_id, vendor),
        ("device_type", fi.device_type, device_type),
        ("product_code", fi.product_code, product_code),
        ("major_revision", u16::from(fi.major_revision), u16::from(major)),
    ] {
        if expected != found {
            c.differences.push(RunningDifference {
                mac,
                what: format!("identity {what} (keying {keying})"),
                expected: expected.to_string(),
                found: found.to_string(),
            });
        }
    }
    let minor_ok = match f.keying {
        Keying::Compatible => minor >= fi.minor_revision,
        _ => minor == fi.minor_revision,
    };
    if !minor_ok {
        c.differences.push(RunningDifference {
            mac,
            what: format!("identity minor_revision (keying {keying})"),
            expected: fi.minor_revision.to_string(),
            found: minor.to_string(),
        });
    }
}

fn compare_param(mac: u8, p: &ProjectParam, read: &mut ReadAttribute<'_>, c: &mut RunningComparison) {
    let what = format!("parameter {} ({})", p.number, p.name);
    let Ok(instance) = u16::try_from(p.number) else {
        not(c, mac, &what, "the instance number is beyond 65535".into());
        return;
    };
    let value = match read(mac, PARAMETER_CLASS, instance, 1) {
        Ok(v) => v,
        Err(e) => return not(c, mac, &what, format!("not read: {e}")),
    };
    let found = match (p.value, &p.raw) {
        (Some(_), _) => {
            let data_type = match read(mac, PARAMETER_CLASS, instance, 5) {
                Ok(t) => t.first().copied().unwrap_or(0),
                Err(e) => return not(c, mac, &what, format!("its data type not read: {e}")),
            };
            match decode_value(data_type, &value) {
                Some(v) => v.to_string(),
                None => {
                    return not(
                        c,
                        mac,
                        &what,
                        format!(
                            "the value read ({}) has no number of data type 0x{data_type:02X}",
                            hex(&value)
                        ),
                    )
                }
            }
        }
        (None, Some(_)) => format!("0x{}", hex(&value)),
        (None, None) => return not(c, mac, &what, "the project gives no value".into()),
    };
    c.compared.parameters += 1;
    let expected = match (p.value, &p.raw) {
        (Some(v), _) => v.to_string(),
        (None, Some(raw)) => format!("0x{}", raw.to_ascii_uppercase()),
        (None, None) => String::new(),
    };
    if expected != found {
        c.differences.push(RunningDifference { mac, what, expected, found });
    }
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02X}")).collect()
}

/// Why no CCV could be computed for a project's configuration.
#[derive(Debug, thiserror::Error)]
pub enum CcvError {
    /// The description reader refused it.
    #[error("the project's configuration is refused: {0}")]
    Description(slave_fw::description::DescriptionError),
    /// It does not encode to an image.
    #[error("the project's configuration does not encode to an image: {0}")]
    Image(slave_fw::converter::image::ImageError),
}

/// The CCV a device storing the configuration `description` reports: the consistency value of
/// the image it encodes to (`slave_fw::converter::consistency::consistency_value`).
pub fn expected_ccv(description: &str) -> Result<u16, CcvError> {
    let d = slave_fw::description::DeviceDescription::parse(description).map_err(CcvError::Description)?;
    let image = slave_fw::converter::image::encode_to_vec(&d.converter).map_err(CcvError::Image)?;
    Ok(slave_fw::converter::consistency::consistency_value(&image))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Identity, NodeStatus};
    use crate::project::{NodeIdentity, FORMAT};
    use slave_fw::converter::consistency::FACTORY_CCV;
    use slave_fw::description::DeviceDescription;

    fn reference_config() -> String {
        DeviceDescription::reference().to_toml().unwrap()
    }

    fn file_node(mac: u8) -> ProjectNode {
        ProjectNode {
            mac,
            connection: "poll".into(),
            input_size: 18,
            output_size: 8,
            name: None,
            keying: Keying::Exact,
            identity: NodeIdentity {
                vendor_id: 0x1234,
                device_type: 0x0C,
                product_code: 1,
                major_revision: 1,
                minor_revision: 2,
                product_name: String::new(),
                serial_number: None,
            },
            configuration: Some(reference_config()),
            param: vec![ProjectParam {
                number: 1,
                name: "Serial baud rate".into(),
                value: Some(9600),
                raw: None,
                units: String::new(),
                read_only: false,
            }],
        }
    }

    fn state(mac: u8) -> NodeState {
        NodeState {
            mac,
            name: None,
            connection: "poll".into(),
            ack_suppression: false,
            status: NodeStatus::Ok,
            code: 0,
            detail: None,
            identity: Identity {
                vendor_id: Some(0x1234),
                device_type: Some(0x0C),
                product_code: Some(1),
                revision: Some("1.2".into()),
                serial_number: Some(7),
                product_name: Some("Serial-DeviceNet Bridge".into()),
            },
            input_size: Some(18),
            output_size: Some(8),
            input: Vec::new(),
            output: Vec::new(),
            exchanges: 1,
            last_exchange_us: None,
        }
    }

    /// A device answering with the factory CCV and parameter 1 = `baud` (UDINT, data type 0xC8).
    fn device(baud: u32) -> impl FnMut(u8, u16, u16, u8) -> Result<Vec<u8>, String> {
        move |_, class, instance, attribute| match (class, instance, attribute) {
            (IDENTITY_CLASS, 1, CCV_ATTRIBUTE) => Ok(FACTORY_CCV.to_le_bytes().to_vec()),
            (PARAMETER_CLASS, 1, 1) => Ok(baud.to_le_bytes().to_vec()),
            (PARAMETER_CLASS, 1, 5) => Ok(vec![0xC8]),
            _ => Err("0x14 attribute not supported".into()),
        }
    }

    fn one(n: ProjectNode) -> Project {
        Project { format: FORMAT, node: vec![n] }
    }

    #[test]
    fn the_reference_configuration_has_the_factory_ccv() {
        assert_eq!(expected_ccv(&reference_config()).unwrap(), FACTORY_CCV);
        let refused = expected_ccv("[network]\nmac_id = 70\n").unwrap_err();
        assert!(matches!(refused, CcvError::Description(_)), "{refused}");
        assert!(refused.to_string().starts_with("the project's configuration is refused: "), "{refused}");
    }

    #[test]
    fn an_equal_network_lists_what_was_compared() {
        let c = compare_running(&one(file_node(5)), &[state(5)], &mut device(9600));
        assert_eq!(c.differences, []);
        assert_eq!(c.not_compared, []);
        let parts = ComparedParts { nodes: 1, scan_list: 1, identity: 1, configuration: 1, parameters: 1 };
        assert_eq!(c.compared, parts);
        assert!(c.equal());
    }

    #[test]
    fn a_changed_parameter_and_product_code_are_differences() {
        let mut s = state(5);
        s.identity.product_code = Some(2);
        let c = compare_running(&one(file_node(5)), &[s], &mut device(19200));
        let found: Vec<(&str, &str, &str)> =
            c.differences.iter().map(|d| (d.what.as_str(), d.expected.as_str(), d.found.as_str())).collect();
        assert_eq!(
            found,
            [
                ("identity product_code (keying exact)", "1", "2"),
                ("parameter 1 (Serial baud rate)", "9600", "19200")
            ]
        );
        assert!(!c.equal());
    }

    #[test]
    fn another_configuration_is_a_ccv_difference() {
        let mut d = DeviceDescription::reference();
        d.converter.device.identity.product_code += 1;
        let mut f = file_node(5);
        f.configuration = Some(d.to_toml().unwrap());
        let c = compare_running(&one(f), &[state(5)], &mut device(9600));
        assert_eq!(c.differences.len(), 1, "{c:?}");
        assert_eq!(c.differences[0].what, "configuration (CCV, Identity attribute 9)");
        assert_eq!(c.differences[0].found, format!("0x{FACTORY_CCV:04X}"));
    }

    #[test]
    fn nothing_read_is_not_equal() {
        let mut s = state(5);
        s.identity = Identity::default();
        s.input_size = None;
        s.output_size = None;
        let mut f = file_node(5);
        f.connection = "poll".into();
        let mut silent = |_: u8, _: u16, _: u16, _: u8| Err::<Vec<u8>, String>("no answer".into());
        let c = compare_running(&one(f), &[s], &mut silent);
        assert_eq!(c.differences, []);
        let parts: Vec<&str> = c.not_compared.iter().map(|n| n.what.as_str()).collect();
        assert_eq!(
            parts,
            [
                "scan list input_size",
                "scan list output_size",
                "identity",
                "configuration",
                "parameter 1 (Serial baud rate)"
            ]
        );
        assert!(!c.equal(), "nothing but the connection compared is no \"equal\"");
        let empty = compare_running(&Project { format: FORMAT, node: vec![] }, &[], &mut silent);
        assert!(!empty.anything_compared() && !empty.equal());
    }

    #[test]
    fn a_node_not_in_io_is_not_read() {
        let mut s = state(5);
        s.status = NodeStatus::TimedOut;
        s.code = 72;
        let mut asked = 0;
        let mut count = |_: u8, _: u16, _: u16, _: u8| {
            asked += 1;
            Err::<Vec<u8>, String>("no answer".into())
        };
        let c = compare_running(&one(file_node(5)), &[s], &mut count);
        assert_eq!(asked, 0);
        assert_eq!(c.compared.identity, 1, "the identity the scanner read is still compared");
        let why: Vec<&str> = c.not_compared.iter().map(|n| n.why.as_str()).collect();
        assert_eq!(why, ["not read: the node is timed_out (code 72)"; 2], "{c:?}");
        assert!(!c.equal());
    }

    #[test]
    fn the_reads_are_bounded() {
        let mut f = file_node(5);
        f.param = (1..=3000)
            .map(|number| ProjectParam {
                number,
                name: format!("p{number}"),
                value: Some(0),
                ..Default::default()
            })
            .collect();
        let mut asked = 0;
        let mut zero = |_: u8, _: u16, _: u16, _: u8| {
            asked += 1;
            Ok::<Vec<u8>, String>(vec![0, 0])
        };
        let c = compare_running(&one(f), &[state(5)], &mut zero);
        assert_eq!(asked, MAX_READS);
        assert!(
            c.not_compared.iter().any(|n| n.why.contains("more than 2048 reads")),
            "{:?}",
            c.not_compared.last()
        );
        assert!(!c.equal());
    }

    #[test]
    fn missing_and_extra_nodes_are_differences() {
        let c = compare_running(&one(file_node(5)), &[state(6)], &mut device(9600));
        let found: Vec<(u8, &str)> = c.differences.iter().map(|d| (d.mac, d.found.as_str())).collect();
        assert_eq!(found, [(5, "not in the scan list"), (6, "in the scan list (Serial-DeviceNet Bridge)")]);
        assert!(!c.anything_compared() && !c.equal());
    }

    #[test]
    fn keying_disabled_is_said_and_not_held_against() {
        let mut f = file_node(5);
        f.keying = Keying::Disabled;
        let mut s = state(5);
        s.identity.vendor_id = Some(1);
        let c = compare_running(&one(f), &[s], &mut device(9600));
        assert_eq!(c.compared.identity, 0);
        assert_eq!(c.not_compared.len(), 1);
        assert!(!c.not_compared[0].wanted);
        assert!(c.equal(), "{c:?}");
    }
}
