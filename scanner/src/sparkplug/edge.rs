//! The edge node's metrics, kept between messages: what each device (DeviceNet node) is known to
//! hold, which metrics changed (report by exception), and the payloads of NBIRTH, DBIRTH, DDATA
//! and NDEATH. No network and no clock here: the caller gives the time and sends the bytes.

use super::proto::{self, DataType, Metric, Payload, PropertySet, PropertyValue, PropertyValueKind};
use crate::model::{NodeState, Sample, ScannerState};
use crate::monitor::{ImageProfile, InputLayout};
use crate::sample_values;
use crate::ui::{known_descriptions, layout_for};
use std::collections::BTreeMap;

/// The node control metric a host sets to `true` to ask for NBIRTH and every DBIRTH again.
pub const REBIRTH: &str = "Node Control/Rebirth";
/// The birth/death sequence number metric of NBIRTH and NDEATH.
pub const BD_SEQ: &str = "bdSeq";
/// The writable output image of a device (DCMD with `--sparkplug-commands`).
pub const OUTPUT_IMAGE: &str = "Outputs/Image";
/// The breaker's commands (DCMD with `--sparkplug-commands`; a breaker's DBIRTH only).
pub const BREAKER_OPEN: &str = "Commands/Open";
/// See [`BREAKER_OPEN`].
pub const BREAKER_CLOSE: &str = "Commands/Close";

/// A metric's value as this edge node knows it.
#[derive(Clone, Debug, PartialEq)]
pub enum MetricValue {
    /// Not known yet (sent with `is_null`).
    Null(DataType),
    /// Boolean.
    Bool(bool),
    /// UInt8, UInt16 or UInt32.
    Int(DataType, u32),
    /// UInt64.
    Long(u64),
    /// Double (a decoded input value).
    Double(f64),
    /// String.
    Text(String),
    /// Bytes (an image).
    Bytes(Vec<u8>),
}

impl MetricValue {
    fn datatype(&self) -> DataType {
        match self {
            MetricValue::Null(t) | MetricValue::Int(t, _) => *t,
            MetricValue::Bool(_) => DataType::Boolean,
            MetricValue::Long(_) => DataType::UInt64,
            MetricValue::Double(_) => DataType::Double,
            MetricValue::Text(_) => DataType::String,
            MetricValue::Bytes(_) => DataType::Bytes,
        }
    }

    /// Equal for report by exception: two NaN are the same value.
    fn same(&self, other: &MetricValue) -> bool {
        match (self, other) {
            (MetricValue::Double(a), MetricValue::Double(b)) => a == b || (a.is_nan() && b.is_nan()),
            (a, b) => a == b,
        }
    }
}

/// One metric: name, value, unit, and whether a host may write it.
#[derive(Clone, Debug, PartialEq)]
pub struct MetricDef {
    /// `Inputs/phase_a`, `Status/State`.
    pub name: String,
    /// The value.
    pub value: MetricValue,
    /// The engineering unit (`engUnit` property), when known.
    pub unit: Option<&'static str>,
    /// A host may write it with DCMD.
    pub writable: bool,
}

impl MetricDef {
    fn new(name: impl Into<String>, value: MetricValue) -> MetricDef {
        MetricDef { name: name.into(), value, unit: None, writable: false }
    }

    /// The protobuf metric at `timestamp` (ms); with `properties` for a birth.
    #[must_use]
    pub fn to_proto(&self, timestamp: u64, properties: bool) -> Metric {
        let (value, is_null) = match &self.value {
            MetricValue::Null(_) => (None, Some(true)),
            MetricValue::Bool(b) => (Some(proto::Value::BooleanValue(*b)), None),
            MetricValue::Int(_, v) => (Some(proto::Value::IntValue(*v)), None),
            MetricValue::Long(v) => (Some(proto::Value::LongValue(*v)), None),
            MetricValue::Double(v) => (Some(proto::Value::DoubleValue(*v)), None),
            MetricValue::Text(s) => (Some(proto::Value::StringValue(s.clone())), None),
            MetricValue::Bytes(b) => (Some(proto::Value::BytesValue(b.clone())), None),
        };
        let properties = properties.then(|| {
            let mut set = PropertySet::default();
            if let Some(unit) = self.unit {
                set.keys.push("engUnit".into());
                set.values.push(PropertyValue {
                    r#type: Some(DataType::String as u32),
                    is_null: None,
                    value: Some(PropertyValueKind::StringValue(unit.into())),
                });
            }
            set.keys.push("readOnly".into());
            set.values.push(PropertyValue {
                r#type: Some(DataType::Boolean as u32),
                is_null: None,
                value: Some(PropertyValueKind::BooleanValue(!self.writable)),
            });
            set
        });
        Metric {
            name: Some(self.name.clone()),
            timestamp: Some(timestamp),
            datatype: Some(self.value.datatype() as u32),
            is_null,
            properties,
            value,
            ..Metric::default()
        }
    }
}

/// A Sparkplug device: a DeviceNet node of one network. `network` is `None` for `ui` without
/// `--plant` (one network), the plant file's network name with `--plant`.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct DeviceKey {
    /// The plant network's name (`[A-Za-z0-9_-]`), `None` without `--plant`.
    pub network: Option<String>,
    /// The node's MAC ID.
    pub mac: u8,
}

impl DeviceKey {
    /// The node `mac` of the one network of `ui` without `--plant`.
    #[must_use]
    pub fn single(mac: u8) -> DeviceKey {
        DeviceKey { network: None, mac }
    }

    /// The node `mac` of network `network` (`None`: the one network).
    #[must_use]
    pub fn of(network: Option<&str>, mac: u8) -> DeviceKey {
        DeviceKey { network: network.map(str::to_owned), mac }
    }
}

/// The Sparkplug device ID of a DeviceNet node: `mac05`, or `NETWORK-mac05` for a plant network.
/// A network name is `[A-Za-z0-9_-]`, so the ID holds none of the characters Sparkplug B 3.0
/// forbids in a topic element (`+`, `/`, `#`).
#[must_use]
pub fn device_name(key: &DeviceKey) -> String {
    match &key.network {
        None => format!("mac{:02}", key.mac),
        Some(net) => format!("{net}-mac{:02}", key.mac),
    }
}

/// The device of a device ID: `macNN` (0..=63) without `--plant`; `NETWORK-macNN` with it (the
/// network as given, checked by the caller against the plant's). `None` for any other ID.
#[must_use]
pub fn device_key(name: &str, plant: bool) -> Option<DeviceKey> {
    let (network, mac) = match (plant, name.rsplit_once('-')) {
        (false, _) => (None, name),
        (true, Some((net, mac))) if crate::plant::valid_name(net) => (Some(net.to_owned()), mac),
        (true, _) => return None,
    };
    let digits = mac.strip_prefix("mac")?;
    if digits.len() != 2 || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let mac = digits.parse::<u8>().ok().filter(|m| *m <= 63)?;
    Some(DeviceKey { network, mac })
}

/// The unit of a decoded input value: the breaker's currents are in amperes; other profiles
/// carry no unit in their description.
fn unit_of(profile: &ImageProfile, name: &str) -> Option<&'static str> {
    let current = matches!(name, "phase_a" | "phase_b" | "phase_c" | "neutral");
    (*profile == ImageProfile::Breaker && current).then_some("A")
}

fn opt_int(t: DataType, v: Option<u32>) -> MetricValue {
    v.map_or(MetricValue::Null(t), |v| MetricValue::Int(t, v))
}

fn opt_text(v: Option<&str>) -> MetricValue {
    v.map_or(MetricValue::Null(DataType::String), |s| MetricValue::Text(s.into()))
}

/// What a device's DBIRTH holds, from the scanner's view of the node and its latest values.
fn device_metrics(node: &NodeState, layout: &InputLayout, values: &[(String, f64)]) -> Vec<MetricDef> {
    let id = &node.identity;
    let mut m = vec![
        MetricDef::new("Name", opt_text(node.name.as_deref())),
        MetricDef::new("Connection", MetricValue::Text(node.connection.clone())),
        MetricDef::new("Identity/Vendor ID", opt_int(DataType::UInt16, id.vendor_id.map(u32::from))),
        MetricDef::new("Identity/Device Type", opt_int(DataType::UInt16, id.device_type.map(u32::from))),
        MetricDef::new("Identity/Product Code", opt_int(DataType::UInt16, id.product_code.map(u32::from))),
        MetricDef::new("Identity/Revision", opt_text(id.revision.as_deref())),
        MetricDef::new("Identity/Serial Number", opt_int(DataType::UInt32, id.serial_number)),
        MetricDef::new("Identity/Product Name", opt_text(id.product_name.as_deref())),
        MetricDef::new("Status/State", MetricValue::Text(node.status.name().into())),
        MetricDef::new("Status/Code", MetricValue::Int(DataType::UInt8, u32::from(node.code))),
        MetricDef::new("Status/Detail", opt_text(node.detail.as_deref())),
        MetricDef::new("Inputs/Image", MetricValue::Bytes(node.input.clone())),
    ];
    for (name, v) in values {
        let mut def = MetricDef::new(format!("Inputs/{name}"), MetricValue::Double(*v));
        def.unit = unit_of(&layout.profile, name);
        m.push(def);
    }
    let mut output = MetricDef::new(OUTPUT_IMAGE, MetricValue::Bytes(node.output.clone()));
    output.writable = true;
    m.push(output);
    if layout.profile == ImageProfile::Breaker {
        for name in [BREAKER_OPEN, BREAKER_CLOSE] {
            let mut def = MetricDef::new(name, MetricValue::Bool(false));
            def.writable = true;
            m.push(def);
        }
    }
    m
}

/// What changed, in the order it changed: for the sender to publish or to store.
#[derive(Clone, Debug, PartialEq)]
pub enum Change {
    /// A device appeared or its set of metrics changed: its DBIRTH is (re)sent.
    Birth(DeviceKey),
    /// Metrics of a device that changed at `unix_ms` (DDATA).
    Data {
        /// The device.
        key: DeviceKey,
        /// Milliseconds since the Unix epoch.
        unix_ms: u64,
        /// The changed metrics.
        metrics: Vec<MetricDef>,
    },
}

/// A device: its metrics by name (the DBIRTH set), and what a breaker command needs.
#[derive(Clone, Debug)]
pub struct Device {
    /// The metrics by name, latest values.
    pub metrics: BTreeMap<String, MetricDef>,
    /// The node's output image and size, for DCMD.
    pub output: Vec<u8>,
    /// The node's produced output size, when read.
    pub output_size: Option<u16>,
    /// How the node's input is decoded.
    pub layout: InputLayout,
}

/// The edge node's view of every device (see the [module docs](self)).
#[derive(Debug, Default)]
pub struct Edge {
    /// The devices by network and MAC ID.
    pub devices: BTreeMap<DeviceKey, Device>,
    /// Each network's scanner cycle count at its last [`Edge::update_network_state`] (DCMD waits
    /// on it); the key `None` is the one network without `--plant`.
    pub cycles: BTreeMap<Option<String>, u64>,
}

impl Edge {
    /// [`Edge::update_network_state`] of the one network without `--plant`.
    pub fn update_state(&mut self, state: &ScannerState, unix_ms: u64) -> Vec<Change> {
        self.update_network_state(None, state, unix_ms)
    }

    /// The cycle count of `network`'s scanner at its last state (0 before any).
    #[must_use]
    pub fn cycles_of(&self, network: Option<&str>) -> u64 {
        self.cycles.get(&network.map(str::to_owned)).copied().unwrap_or(0)
    }

    /// Takes network `network`'s scanner state after a cycle: new devices (a [`Change::Birth`]),
    /// changed status, identity, images (a [`Change::Data`]).
    pub fn update_network_state(
        &mut self,
        network: Option<&str>,
        state: &ScannerState,
        unix_ms: u64,
    ) -> Vec<Change> {
        let mut changes = Vec::new();
        self.cycles.insert(network.map(str::to_owned), state.cycles);
        for node in &state.nodes {
            let key = DeviceKey::of(network, node.mac);
            let layout = layout_for(node, known_descriptions());
            let known: Vec<(String, f64)> = match self.devices.get(&key) {
                Some(d) => d
                    .metrics
                    .values()
                    .filter_map(|m| match (&m.value, m.name.strip_prefix("Inputs/")) {
                        (MetricValue::Double(v), Some(n)) => Some((n.to_owned(), *v)),
                        _ => None,
                    })
                    .collect(),
                None => sample_values(&layout, &node.input),
            };
            let mut defs = device_metrics(node, &layout, &known);
            // A known device's input image is reported from its samples, in their order and with
            // their times (the state holds only the last one of the cycle).
            if let Some(image) = self.devices.get(&key).and_then(|d| d.metrics.get("Inputs/Image")) {
                for d in defs.iter_mut().filter(|d| d.name == "Inputs/Image") {
                    d.value = image.value.clone();
                }
            }
            changes.extend(self.merge(&key, defs, unix_ms, true));
            if let Some(d) = self.devices.get_mut(&key) {
                d.output.clone_from(&node.output);
                d.output_size = node.output_size;
                d.layout = layout;
            }
        }
        changes
    }

    /// [`Edge::update_network_samples`] of the one network without `--plant`.
    pub fn update_samples(&mut self, samples: &[Sample]) -> Vec<Change> {
        self.update_network_samples(None, samples)
    }

    /// Takes network `network`'s decoded samples: changed input values (a [`Change::Data`] at the
    /// sample's time), a value of a name the device's DBIRTH did not hold (a [`Change::Birth`]).
    pub fn update_network_samples(&mut self, network: Option<&str>, samples: &[Sample]) -> Vec<Change> {
        let mut changes = Vec::new();
        for s in samples {
            let key = DeviceKey::of(network, s.mac);
            let Some(device) = self.devices.get(&key) else { continue };
            let mut defs: Vec<MetricDef> = device
                .metrics
                .values()
                .filter(|m| !m.name.starts_with("Inputs/") || m.name == "Inputs/Image")
                .cloned()
                .collect();
            for def in &mut defs {
                if def.name == "Inputs/Image" {
                    def.value = MetricValue::Bytes(s.input.clone());
                }
            }
            for (name, v) in &s.values {
                let mut def = MetricDef::new(format!("Inputs/{name}"), MetricValue::Double(*v));
                def.unit = unit_of(&device.layout.profile, name);
                defs.push(def);
            }
            let at = u64::try_from(s.unix_ms).unwrap_or(0);
            changes.extend(self.merge(&key, defs, at, false));
        }
        changes
    }

    /// Merges the full metric set of `key`: a new set of names is a birth (with `keep_inputs`,
    /// input values the set leaves out are kept), changed values are data.
    fn merge(
        &mut self,
        key: &DeviceKey,
        defs: Vec<MetricDef>,
        unix_ms: u64,
        keep_inputs: bool,
    ) -> Vec<Change> {
        let Some(device) = self.devices.get_mut(key) else {
            let metrics = defs.into_iter().map(|d| (d.name.clone(), d)).collect();
            let device =
                Device { metrics, output: Vec::new(), output_size: None, layout: InputLayout::raw() };
            self.devices.insert(key.clone(), device);
            return vec![Change::Birth(key.clone())];
        };
        let mut names: Vec<&str> = defs.iter().map(|d| d.name.as_str()).collect();
        if keep_inputs {
            names.extend(device.metrics.keys().filter(|n| n.starts_with("Inputs/")).map(String::as_str));
        }
        names.sort_unstable();
        names.dedup();
        let same_names =
            names.len() == device.metrics.len() && names.iter().all(|n| device.metrics.contains_key(*n));
        if !same_names {
            if !keep_inputs {
                device.metrics.retain(|_, m| !m.name.starts_with("Inputs/"));
            }
            for d in defs {
                device.metrics.insert(d.name.clone(), d);
            }
            return vec![Change::Birth(key.clone())];
        }
        let mut changed = Vec::new();
        for d in defs {
            if let Some(old) = device.metrics.get_mut(&d.name) {
                if !old.value.same(&d.value) {
                    old.value = d.value.clone();
                    changed.push(d);
                }
            }
        }
        if changed.is_empty() {
            Vec::new()
        } else {
            vec![Change::Data { key: key.clone(), unix_ms, metrics: changed }]
        }
    }

    /// NBIRTH: `bdSeq` and [`REBIRTH`], seq 0.
    #[must_use]
    pub fn nbirth(&self, bd_seq: u64, unix_ms: u64) -> Payload {
        let metrics = vec![
            MetricDef::new(BD_SEQ, MetricValue::Long(bd_seq)).to_proto(unix_ms, false),
            MetricDef { writable: true, ..MetricDef::new(REBIRTH, MetricValue::Bool(false)) }
                .to_proto(unix_ms, true),
        ];
        Payload { timestamp: Some(unix_ms), metrics, seq: Some(0), ..Payload::default() }
    }

    /// DBIRTH of `key` with every metric, its unit and whether it is writable; `None` for a device
    /// not seen.
    #[must_use]
    pub fn dbirth(&self, key: &DeviceKey, unix_ms: u64, seq: u8) -> Option<Payload> {
        let device = self.devices.get(key)?;
        let metrics = device.metrics.values().map(|m| m.to_proto(unix_ms, true)).collect();
        Some(Payload { timestamp: Some(unix_ms), metrics, seq: Some(u64::from(seq)), ..Payload::default() })
    }
}

/// NDEATH: `bdSeq` only, no seq (the MQTT will).
#[must_use]
pub fn ndeath(bd_seq: u64) -> Payload {
    Payload {
        timestamp: Some(crate::model::unix_ms_now().try_into().unwrap_or(0)),
        metrics: vec![MetricDef::new(BD_SEQ, MetricValue::Long(bd_seq)).to_proto(0, false)],
        ..Payload::default()
    }
}

/// DDATA of changed metrics (`historical`: replayed from the store).
#[must_use]
pub fn ddata(metrics: &[MetricDef], unix_ms: u64, seq: u8, historical: bool) -> Payload {
    let metrics = metrics
        .iter()
        .map(|m| {
            let mut p = m.to_proto(unix_ms, false);
            if historical {
                p.is_historical = Some(true);
            }
            p
        })
        .collect();
    Payload { timestamp: Some(unix_ms), metrics, seq: Some(u64::from(seq)), ..Payload::default() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Identity, NodeStatus, ScannerStatus};

    fn breaker_node(status: NodeStatus, input: Vec<u8>) -> NodeState {
        let reference = slave_fw::description::DeviceDescription::reference();
        let id = &reference.converter.device.identity;
        NodeState {
            mac: 5,
            name: Some("feeder".into()),
            connection: "poll".into(),
            ack_suppression: false,
            status,
            code: status.code(),
            detail: None,
            identity: Identity {
                vendor_id: Some(id.vendor_id),
                device_type: Some(12),
                product_code: Some(id.product_code),
                revision: Some("1.1".into()),
                serial_number: Some(1),
                product_name: Some(id.product_name.to_string()),
            },
            input_size: Some(input.len() as u16),
            output_size: Some(8),
            input,
            output: vec![0; 8],
            exchanges: 1,
            last_exchange_us: Some(1),
        }
    }

    fn state(nodes: Vec<NodeState>) -> ScannerState {
        ScannerState {
            mac: 0,
            status: ScannerStatus::Running,
            cycles: 1,
            cycle_ms: 1.0,
            bus_load: 0.1,
            interscan_delay_ms: 2,
            expected_packet_rate_ms: 300,
            nodes,
        }
    }

    fn image_len() -> usize {
        InputLayout::from_converter(&slave_fw::description::DeviceDescription::reference().converter)
            .image_len
    }

    #[test]
    fn a_new_device_is_born_then_reported_by_exception() {
        let mut edge = Edge::default();
        let zeros = vec![0u8; image_len()];
        let s = state(vec![breaker_node(NodeStatus::Ok, zeros.clone())]);
        assert_eq!(edge.update_state(&s, 1000), vec![Change::Birth(DeviceKey::single(5))]);
        assert_eq!(edge.update_state(&s, 2000), vec![], "nothing changed: nothing sent");
        let birth = edge.dbirth(&DeviceKey::single(5), 1000, 1).unwrap();
        let phase_a = birth.metrics.iter().find(|m| m.name.as_deref() == Some("Inputs/phase_a")).unwrap();
        assert_eq!(phase_a.datatype, Some(DataType::Double as u32));
        assert_eq!(phase_a.properties.as_ref().unwrap().keys, ["engUnit", "readOnly"]);
        assert!(birth.metrics.iter().any(|m| m.name.as_deref() == Some(BREAKER_CLOSE)));

        let mut input = zeros.clone();
        input[0] = 120;
        let sample = Sample {
            mac: 5,
            unix_ms: 3000,
            bus_us: 0,
            input: input.clone(),
            values: vec![
                ("phase_a".into(), 120.0),
                ("phase_b".into(), 0.0),
                ("phase_c".into(), 0.0),
                ("neutral".into(), 0.0),
                ("switch".into(), 0.0),
            ],
        };
        let changes = edge.update_samples(std::slice::from_ref(&sample));
        let [Change::Data { key, unix_ms: 3000, metrics }] = changes.as_slice() else {
            panic!("{changes:?}")
        };
        assert_eq!(key, &DeviceKey::single(5));
        let names: Vec<&str> = metrics.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names, ["Inputs/Image", "Inputs/phase_a"], "only what changed");
        assert_eq!(edge.update_samples(&[sample]), vec![], "the same sample again: nothing");
    }

    #[test]
    fn a_status_change_is_data_and_a_new_value_name_is_a_birth() {
        let mut edge = Edge::default();
        let zeros = vec![0u8; image_len()];
        edge.update_state(&state(vec![breaker_node(NodeStatus::Ok, zeros.clone())]), 1);
        let changes = edge.update_state(&state(vec![breaker_node(NodeStatus::TimedOut, zeros)]), 2);
        let [Change::Data { metrics, .. }] = changes.as_slice() else { panic!("{changes:?}") };
        assert!(metrics
            .iter()
            .any(|m| m.name == "Status/State" && m.value == MetricValue::Text("timed_out".into())));
        let odd =
            Sample { mac: 5, unix_ms: 3, bus_us: 0, input: vec![1], values: vec![("data".into(), 1.0)] };
        assert_eq!(edge.update_samples(&[odd]), vec![Change::Birth(DeviceKey::single(5))]);
    }

    #[test]
    fn nbirth_holds_bd_seq_and_rebirth_at_seq_0_and_ndeath_the_same_bd_seq() {
        let edge = Edge::default();
        let n = edge.nbirth(7, 1);
        assert_eq!(n.seq, Some(0));
        assert_eq!(n.metrics[0].name.as_deref(), Some(BD_SEQ));
        assert_eq!(n.metrics[0].value, Some(proto::Value::LongValue(7)));
        assert_eq!(n.metrics[1].name.as_deref(), Some(REBIRTH));
        let d = ndeath(7);
        assert_eq!((d.seq, d.metrics[0].value.clone()), (None, Some(proto::Value::LongValue(7))));
    }

    #[rstest::rstest]
    #[case::mac05("mac05", Some(5))]
    #[case::mac63("mac63", Some(63))]
    #[case::mac64("mac64", None)]
    #[case::short("mac5", None)]
    #[case::sign("mac+5", None)]
    #[case::other("node05", None)]
    #[case::network_without_plant("line-a-mac05", None)]
    fn device_names(#[case] name: &str, #[case] mac: Option<u8>) {
        assert_eq!(device_key(name, false), mac.map(DeviceKey::single));
        if let Some(m) = mac {
            assert_eq!(device_name(&DeviceKey::single(m)), name);
        }
    }

    /// With `--plant` a device ID is `NETWORK-macNN`: the network is the part before the last `-`
    /// (network names may hold `-` themselves).
    #[rstest::rstest]
    #[case::plain("a-mac05", Some(("a", 5)))]
    #[case::dashed("line-b-mac63", Some(("line-b", 63)))]
    #[case::underscore("hall_2-mac00", Some(("hall_2", 0)))]
    #[case::no_network("mac05", None)]
    #[case::empty_network("-mac05", None)]
    #[case::bad_network("a+b-mac05", None)]
    #[case::bad_mac("a-mac64", None)]
    #[case::no_mac("a-b", None)]
    fn plant_device_names(#[case] name: &str, #[case] key: Option<(&str, u8)>) {
        let key = key.map(|(n, m)| DeviceKey::of(Some(n), m));
        assert_eq!(device_key(name, true), key);
        if let Some(k) = &key {
            assert_eq!(device_name(k), name);
        }
    }

    /// Two networks with a node at the same MAC ID: two devices, each born and updated on its own.
    #[test]
    fn the_same_mac_on_two_networks_is_two_devices() {
        let mut edge = Edge::default();
        let zeros = vec![0u8; image_len()];
        let s = state(vec![breaker_node(NodeStatus::Ok, zeros.clone())]);
        let a = DeviceKey::of(Some("a"), 5);
        let b = DeviceKey::of(Some("b"), 5);
        assert_eq!(edge.update_network_state(Some("a"), &s, 1), vec![Change::Birth(a.clone())]);
        assert_eq!(edge.update_network_state(Some("b"), &s, 1), vec![Change::Birth(b.clone())]);
        let timed_out = state(vec![breaker_node(NodeStatus::TimedOut, zeros)]);
        let changes = edge.update_network_state(Some("b"), &timed_out, 2);
        assert!(matches!(changes.as_slice(), [Change::Data { key, .. }] if *key == b), "{changes:?}");
        assert_eq!(edge.update_network_state(Some("a"), &s, 3), vec![], "a's node did not change");
        assert_eq!(edge.devices.len(), 2);
    }
}
