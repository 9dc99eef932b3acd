//! What the address space shows of the scanner's state, as plain values: one [`Value`] per
//! variable, computed from a [`ScannerState`] without touching the server, so that the layout is
//! tested on its own and the server only copies changes.
//!
//! Each node of the scan list is an object `MACnn` under `Objects/DeviceNet`, with:
//!
//! | folder | variables |
//! |---|---|
//! | (the object) | `Name`, `Connection`, `InputImage`, `OutputImage` |
//! | `Identity` | `VendorId`, `DeviceType`, `ProductCode`, `Revision`, `SerialNumber`, `ProductName` |
//! | `Status` | `Status` (`ok`, `not_present`, ...), `Code` (the scanner status code), `Detail`, `Exchanges` |
//! | `Inputs` | the values the node's profile decodes ([`dnet_scanner::sample_values`]), by name |
//! | `Parameters` | a breaker's parameters 0-3 |
//!
//! A value not known yet (an identity attribute not read) is an empty variant of the variable's
//! data type.

use dnet_scanner::model::{NodeState, ScannerState, ScannerStatus};
use dnet_scanner::monitor::{BreakerStatus, ImageProfile, InputLayout};
use dnet_scanner::ui::{known_descriptions, layout_for};
use opcua::types::{ByteString, DataTypeId, Variant};

/// Where a variable sits under a node's object.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Folder {
    /// On the node's object itself.
    Node,
    /// `Identity`.
    Identity,
    /// `Status`.
    Status,
    /// `Inputs`.
    Inputs,
    /// `Parameters`.
    Parameters,
}

impl Folder {
    /// The folders under a node's object.
    pub const SUBFOLDERS: [Folder; 4] =
        [Folder::Identity, Folder::Status, Folder::Inputs, Folder::Parameters];

    /// The folder's browse name; `None` for the object itself.
    #[must_use]
    pub fn name(self) -> Option<&'static str> {
        match self {
            Folder::Node => None,
            Folder::Identity => Some("Identity"),
            Folder::Status => Some("Status"),
            Folder::Inputs => Some("Inputs"),
            Folder::Parameters => Some("Parameters"),
        }
    }
}

/// An engineering unit (OPC UA EUInformation, UNECE Recommendation 20 common codes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unit {
    /// Ampere, UNECE code `AMP`.
    Ampere,
}

impl Unit {
    /// The UNECE common code.
    #[must_use]
    pub fn code(self) -> &'static str {
        match self {
            Unit::Ampere => "AMP",
        }
    }

    /// The symbol shown.
    #[must_use]
    pub fn symbol(self) -> &'static str {
        match self {
            Unit::Ampere => "A",
        }
    }

    /// The name in words.
    #[must_use]
    pub fn description(self) -> &'static str {
        match self {
            Unit::Ampere => "ampere",
        }
    }

    /// EUInformation's `unitId`: the common code's (up to 3) ASCII bytes, big-endian in an i32
    /// (OPC 10000-8 v1.05 §5.6.3.3, the mapping of UN/CEFACT codes).
    #[must_use]
    pub fn unit_id(self) -> i32 {
        self.code().bytes().fold(0i32, |id, b| (id << 8) | i32::from(b))
    }
}

/// One variable of the address space.
#[derive(Clone, Debug, PartialEq)]
pub struct Value {
    /// The folder it is in.
    pub folder: Folder,
    /// Its browse name (`VendorId`, `phase_a`).
    pub name: String,
    /// Its data type.
    pub data_type: DataTypeId,
    /// Its value (empty: not known).
    pub value: Variant,
    /// Its engineering unit, if it has one.
    pub unit: Option<Unit>,
}

impl Value {
    fn new(folder: Folder, name: &str, data_type: DataTypeId, value: impl Into<Variant>) -> Value {
        Value { folder, name: name.to_string(), data_type, value: value.into(), unit: None }
    }

    /// Its path below the node's object: `Identity/VendorId`, `InputImage`.
    #[must_use]
    pub fn path(&self) -> String {
        match self.folder.name() {
            Some(f) => format!("{f}/{}", self.name),
            None => self.name.clone(),
        }
    }
}

/// `value` or an empty variant.
fn maybe<T: Into<Variant>>(value: Option<T>) -> Variant {
    value.map_or(Variant::Empty, Into::into)
}

/// The browse name of the node's object: `MAC05`.
#[must_use]
pub fn node_name(mac: u8) -> String {
    format!("MAC{mac:02}")
}

/// The variables of the scanner's own object (`Objects/DeviceNet/Scanner`).
#[must_use]
pub fn scanner_values(state: &ScannerState) -> Vec<Value> {
    let status = match state.status {
        ScannerStatus::Starting => "starting",
        ScannerStatus::Running => "running",
        ScannerStatus::BusWarning => "bus_warning",
        ScannerStatus::BusOff => "bus_off",
        ScannerStatus::DuplicateMac => "duplicate_mac",
        ScannerStatus::Stopped => "stopped",
    };
    vec![
        Value::new(Folder::Node, "Mac", DataTypeId::Byte, state.mac),
        Value::new(Folder::Node, "Status", DataTypeId::String, status),
        Value::new(Folder::Node, "Cycles", DataTypeId::UInt64, state.cycles),
        Value::new(Folder::Node, "CycleMs", DataTypeId::Double, state.cycle_ms),
        Value::new(Folder::Node, "BusLoad", DataTypeId::Double, state.bus_load),
    ]
}

/// How the node's input image is decoded (the console's rule: its identity names a known
/// description).
#[must_use]
pub fn layout(node: &NodeState) -> InputLayout {
    layout_for(node, known_descriptions())
}

/// `true` when the node is recognised as the breaker (it then has Open and Close).
#[must_use]
pub fn is_breaker(node: &NodeState) -> bool {
    layout(node).profile == ImageProfile::Breaker
}

/// The variables of one node of the scan list.
#[must_use]
pub fn node_values(node: &NodeState) -> Vec<Value> {
    let id = &node.identity;
    let mut v = vec![
        Value::new(Folder::Node, "Name", DataTypeId::String, maybe(node.name.clone())),
        Value::new(Folder::Node, "Connection", DataTypeId::String, node.connection.as_str()),
        Value::new(Folder::Node, "InputImage", DataTypeId::ByteString, ByteString::from(node.input.clone())),
        Value::new(
            Folder::Node,
            "OutputImage",
            DataTypeId::ByteString,
            ByteString::from(node.output.clone()),
        ),
        Value::new(Folder::Identity, "VendorId", DataTypeId::UInt16, maybe(id.vendor_id)),
        Value::new(Folder::Identity, "DeviceType", DataTypeId::UInt16, maybe(id.device_type)),
        Value::new(Folder::Identity, "ProductCode", DataTypeId::UInt16, maybe(id.product_code)),
        Value::new(Folder::Identity, "Revision", DataTypeId::String, maybe(id.revision.clone())),
        Value::new(Folder::Identity, "SerialNumber", DataTypeId::UInt32, maybe(id.serial_number)),
        Value::new(Folder::Identity, "ProductName", DataTypeId::String, maybe(id.product_name.clone())),
        Value::new(Folder::Status, "Status", DataTypeId::String, node.status.name()),
        Value::new(Folder::Status, "Code", DataTypeId::Byte, node.code),
        Value::new(Folder::Status, "Detail", DataTypeId::String, maybe(node.detail.clone())),
        Value::new(Folder::Status, "Exchanges", DataTypeId::UInt64, node.exchanges),
    ];
    let layout = layout(node);
    for (name, number) in dnet_scanner::sample_values(&layout, &node.input) {
        let unit = match (&layout.profile, name.as_str()) {
            (ImageProfile::Breaker, "phase_a" | "phase_b" | "phase_c" | "neutral") => Some(Unit::Ampere),
            _ => None,
        };
        v.push(Value { unit, ..Value::new(Folder::Inputs, &name, DataTypeId::Double, number) });
    }
    if layout.profile == ImageProfile::Breaker {
        let image = node.input.get(..layout.image_len).unwrap_or_default();
        if let Some(b) = BreakerStatus::decode(image) {
            v.push(Value::new(Folder::Inputs, "switch_state", DataTypeId::String, b.switch_text()));
        }
        // Parameters 0-3: image bytes 10-17, little-endian (guide: reference/io-data.md).
        for i in 0..4 {
            if let Some(&[lo, hi]) = image.get(10 + 2 * i..12 + 2 * i) {
                let name = format!("param_{i}");
                v.push(Value::new(
                    Folder::Parameters,
                    &name,
                    DataTypeId::UInt16,
                    u16::from_le_bytes([lo, hi]),
                ));
            }
        }
    }
    v
}

#[cfg(test)]
pub(crate) mod tests_support {
    use dnet_scanner::model::{Identity, NodeState, NodeStatus};
    use slave_fw::description::DeviceDescription;

    /// The reference breaker at MAC 5 with the image `input`.
    pub(crate) fn breaker_node(input: Vec<u8>) -> NodeState {
        let known = DeviceDescription::reference().converter.device.identity;
        NodeState {
            mac: 5,
            name: Some("feeder 1".into()),
            connection: "poll".into(),
            ack_suppression: false,
            status: NodeStatus::Ok,
            code: 0,
            detail: None,
            identity: Identity {
                vendor_id: Some(known.vendor_id),
                device_type: None,
                product_code: Some(known.product_code),
                revision: Some("1.2".into()),
                serial_number: Some(77),
                product_name: None,
            },
            input_size: Some(u16::try_from(input.len()).unwrap()),
            output_size: Some(8),
            input,
            output: vec![0; 8],
            exchanges: 3,
            last_exchange_us: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::tests_support::breaker_node;
    use super::*;
    use dnet_scanner::model::Identity;

    fn find<'a>(values: &'a [Value], path: &str) -> &'a Value {
        values.iter().find(|v| v.path() == path).unwrap_or_else(|| panic!("no {path}"))
    }

    #[test]
    fn ampere_unit_id_is_the_unece_code_in_ascii() {
        // 'A' 'M' 'P' = 0x41 0x4D 0x50.
        assert_eq!(Unit::Ampere.unit_id(), 0x0041_4D50);
    }

    #[test]
    fn a_breaker_shows_currents_in_amperes_its_switch_and_parameters() {
        let mut input = vec![0u8; 18];
        input[..4].copy_from_slice(&[120, 121, 119, 3]);
        input[converter_sim::device::SWITCH_BYTE] = converter_sim::device::SWITCH_CLOSED;
        input[10..12].copy_from_slice(&500u16.to_le_bytes());
        let node = breaker_node(input.clone());
        assert!(is_breaker(&node));
        let v = node_values(&node);
        let a = find(&v, "Inputs/phase_a");
        assert_eq!((a.value.clone(), a.unit), (Variant::Double(120.0), Some(Unit::Ampere)));
        assert_eq!(find(&v, "Inputs/neutral").value, Variant::Double(3.0));
        assert_eq!(find(&v, "Inputs/switch").unit, None);
        assert_eq!(find(&v, "Inputs/switch_state").value, Variant::from("closed"));
        assert_eq!(find(&v, "Parameters/param_0").value, Variant::UInt16(500));
        assert_eq!(find(&v, "InputImage").value, Variant::from(ByteString::from(input)));
        assert_eq!(find(&v, "Identity/SerialNumber").value, Variant::UInt32(77));
        assert_eq!(find(&v, "Identity/DeviceType").value, Variant::Empty);
        assert_eq!(find(&v, "Status/Status").value, Variant::from("ok"));
        assert_eq!(find(&v, "Name").value, Variant::from("feeder 1"));
    }

    #[test]
    fn an_unknown_device_has_raw_images_only() {
        let mut node = breaker_node(vec![1, 2, 3]);
        node.identity = Identity::default();
        assert!(!is_breaker(&node));
        let v = node_values(&node);
        assert!(v.iter().all(|x| x.folder != Folder::Inputs && x.folder != Folder::Parameters));
        assert_eq!(find(&v, "InputImage").value, Variant::from(ByteString::from(vec![1, 2, 3])));
    }
}
