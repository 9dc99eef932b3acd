//! The generator: the EDS of our converter, built from its device description
//! ([`slave_fw::description::DeviceDescription`]), the same file the firmware and the soft slave
//! run from (style.md practice 9).
//!
//! Everything in the EDS is derived from the description, and everything it names is something
//! the device really serves:
//!
//! | section | content | where the device serves it |
//! |---|---|---|
//! | `[File]` | `DescText` from the product name; dates and revision from [`GenerateOptions`] | — |
//! | `[Device]` | vendor, device type (and its CIP name), product code, revision, product name, catalog | Identity object (class 0x01) attributes 1–4, 7 |
//! | `[Device Classification]` | `Class1 = DeviceNet` | — |
//! | `[IO_Info]` | `Default` poll (`0x0001`); `PollInfo`, `StrobeInfo`, `COSInfo`, `CyclicInfo` with the compatibility masks [`POLL_STROBE_COMPATIBLE`], [`COS_COMPATIBLE`], [`CYCLIC_COMPATIBLE`]; `Input1` = produced size P, path `20 04 24 <100 or 101> 30 03`, for poll, COS and cyclic (and bit-strobe when P <= 8); when P > 8 `Input2` = the strobe response, min(P, 8) bytes of the same assembly, bit-strobe only; `Output1` = consumed size, path `20 04 24 96 30 03`, for poll, COS and cyclic ([`OUTPUT_CONNECTIONS`]); `StrobeInfo` names no output | Connection instances 2 (poll), 3 (bit-strobe), 4 (COS/cyclic) attributes 7, 8, 14, 16; Assembly (class 0x04) |
//! | `[ParamClass]` | `MaxInst = 9`, `Descriptor = 0x0B`, `CfgAssembly = 0` | Parameter object (class 0x0F) class attributes 2, 8, 9 |
//! | `[Params]` 1–9 | the settings a commissioning tool edits (serial line, stale timeout and policy, input assembly, response timeout, retries, Modbus poll period): `ParamN` is Parameter instance N, link path `20 0F 24 NN 30 01` (protocol §II.4.4); writable, in force after a reset (the poll period is read-only for a framed instrument) | Parameter object ([`slave_fw::converter::PARAMETER_CLASS`]); names, units, help, types, ranges and access from its table, [`PARAMETERS`]; defaults are the description's values, what the device reports as attribute 12 |
//! | `[Params]` 10–12 | idle action, fault action, serial profile, read-only: `ParamN` is attribute N − 1 | settings object, class 0x65 instance 1 ([`slave_fw::converter::SETTINGS_CLASS`]); from its attribute table, [`SettingsAttribute`] |
//! | `[Params]` 13–15 | MAC ID, data rate, bus-off interrupt | DeviceNet object, class 0x03 instance 1, attributes 1–3 |
//! | `[Params]` 16–30 | serial link statistics and status, monitor parameters: `ParamN` is attribute N − 15 | serial link object, class 0x64 instance 1 ([`slave_fw::converter::SERIAL_LINK_CLASS`]); names, units, types and access from its attribute table, [`LinkAttribute`] |
//! | `[Params]` `EnumN` | the strings of every parameter that is a choice (the `EnumN` dialect only; no `[EnumPar]`) | — |
//! | `[Groups]` | serial line, instrument link, I/O behaviour, DeviceNet, statistics | — |
//!
//! The I/O connections announced are those the node offers (docs/src/reference/io-connections.md): poll,
//! bit-strobe, COS and cyclic, poll the default. Multicast poll has no `[IO_Info]` bit and
//! acknowledge suppression is a scanner setting, so neither appears. The layout follows the
//! DeviceNet files of `../shared/eds-corpus/` (Hilscher netX 90 and DNS V5): the same `Default`,
//! the same four compatibility masks, outputs masked `0x000D`, `StrobeInfo`'s default output 0. A
//! group-2-only DeviceNet slave's EDS has no `[Connection Manager]`: no DeviceNet file of the
//! corpus has one (it describes CIP connections of EtherNet/IP and ControlNet devices), so none is
//! written.
//!
//! Parameter defaults are the values of the description; ranges are those the description file
//! accepts (the `validate` limits of `slave_fw`). A setting the device does not serve over the
//! network (data bits, the Modbus byte order and scan list, the framing) is not a parameter: a
//! configuration tool could neither read nor write it. The Parameter object's descriptor has no
//! enumerated-strings bit (the device has no Get_Enum_String); the EDS sets it where it lists the
//! strings itself.
//!
//! The output is deterministic: the same description and options give the same bytes (golden
//! files in `tests/golden/`). Nothing in it depends on the clock, the machine or the path of the
//! description: the dates are [`GenerateOptions::date`] ([`DEFAULT_DATE`] unless given), and the
//! header comment names the description by file name only.

use crate::model::{
    Device, DeviceClassification, Eds, EnumEntry, FileInfo, Group, GroupsSection, IoEntry, IoInfo,
    ParamClass, ParamsSection, Scaling, ScalingLinks,
};
use crate::value::{ConnectionMask, DataType, Date, Descriptor, LinkPath, Revision, Time, Value};
use crate::{Param, Writer};
use devicenet::objects::class;
use devicenet::slave::{strobe_produced_size, STROBE_MAX_SIZE};
use slave_fw::converter::objects::{
    Access, AttributeSpec, AttributeType, LinkAttribute, SettingsAttribute, SettingsValues,
};
use slave_fw::converter::parameters::{Parameter, ParameterDef, CLASS_DESCRIPTOR, PARAMETERS};
use slave_fw::converter::{ConverterConfig, InputAssembly, OUTPUT_ASSEMBLY, PARAMETER_CLASS};
use slave_fw::description::DeviceDescription;
use slave_fw::serial::modbus::units::valid_bits_len;
use slave_fw::serial::modbus::{ByteOrder, Framing, ModbusConfig, ScanEntry, WordOrder};
use slave_fw::serial::{HealthConfig, IdleAction, ProfileConfig, SequencerConfig, SerialSettings};

mod units;
pub use units::{FIRST_UNIT_PARAM, PARAMS_PER_UNIT};

/// The `CreateDate` and `ModDate` written when [`GenerateOptions::date`] is not changed.
pub const DEFAULT_DATE: Date = Date { year: 2025, month: 1, day: 1 };
/// The `CreateTime` and `ModTime` written (midnight, so the file does not depend on the clock).
pub const FILE_TIME: Time = Time { hour: 0, minute: 0, second: 0 };
/// The `[File] Revision` written when [`GenerateOptions::revision`] is not changed.
pub const DEFAULT_REVISION: Revision = Revision { major: 1, minor: 0 };

/// Number of Parameter object parameters: `Param1` to `Param9` are Parameter instances 1 to 9
/// ([`PARAMETERS`]).
pub const PARAMETER_OBJECT_PARAM_COUNT: u32 = PARAMETERS.len() as u32;
/// Number of the first settings object parameter: `ParamN` reads class 0x65 attribute `N - 1`
/// (attributes 9 to 11; attributes 1 to 8 are Parameter instances 1 to 8).
pub const FIRST_SETTINGS_PARAM: u32 = PARAMETER_OBJECT_PARAM_COUNT + 1;
/// The settings object attributes that are parameters of their own.
pub const SETTINGS_PARAMS: [SettingsAttribute; 3] =
    [SettingsAttribute::IdleAction, SettingsAttribute::FaultAction, SettingsAttribute::SerialProfile];
/// Number of the first DeviceNet object parameter (MAC ID); 14 is the data rate, 15 the bus-off
/// interrupt.
pub const FIRST_DEVICENET_PARAM: u32 = FIRST_SETTINGS_PARAM + SETTINGS_PARAMS.len() as u32;
/// Number of the first serial link parameter: `ParamN` reads class 0x64 attribute
/// `N - FIRST_LINK_PARAM + 1`.
pub const FIRST_LINK_PARAM: u32 = FIRST_DEVICENET_PARAM + 3;
/// Number of serial link parameters (class 0x64 attributes 1 to 15, [`LinkAttribute::ALL`]).
pub const LINK_PARAM_COUNT: u32 = LinkAttribute::ALL.len() as u32;

/// What the generated file says about itself.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GenerateOptions {
    /// `CreateDate` and `ModDate`.
    pub date: Date,
    /// `[File] Revision`: the revision of the EDS file itself (not of the device).
    pub revision: Revision,
    /// The description's file name for the header comment (`breaker.toml`); `None` writes no
    /// source line.
    pub source: Option<String>,
}

impl Default for GenerateOptions {
    /// [`DEFAULT_DATE`], [`DEFAULT_REVISION`], no source.
    fn default() -> Self {
        GenerateOptions { date: DEFAULT_DATE, revision: DEFAULT_REVISION, source: None }
    }
}

/// The EDS model of the converter `description` describes; see the [module docs](self).
#[must_use = "the generated EDS is the only output"]
pub fn generate(description: &DeviceDescription, options: &GenerateOptions) -> Eds {
    let device = description.converter.device_config();
    let id = &device.identity;
    let product_name = id.product_name.as_str().to_string();
    let params = parameters(description);
    let mut params_section = ParamsSection::default();
    for p in &params {
        params_section.params.insert(p.number, p.to_param());
        if !p.choices.is_empty() {
            let entries = p
                .choices
                .iter()
                .map(|(value, text)| EnumEntry { value: *value, text: text.clone() })
                .collect();
            params_section.enums.insert(p.number, entries);
        }
    }
    Eds {
        file: Some(FileInfo {
            desc_text: Some(format!("{product_name}: serial-to-DeviceNet converter")),
            create_date: Some(options.date),
            create_time: Some(FILE_TIME),
            mod_date: Some(options.date),
            mod_time: Some(FILE_TIME),
            revision: Some(options.revision),
            home_url: None,
            other: Vec::new(),
        }),
        device: Some(Device {
            vend_code: Some(id.vendor_id),
            vend_name: Some(description.vendor_name.clone()),
            prod_type: Some(id.device_type),
            prod_type_str: Some(device_type_name(id.device_type)),
            prod_code: Some(id.product_code),
            maj_rev: Some(id.major_revision),
            min_rev: Some(id.minor_revision),
            prod_name: Some(product_name),
            catalog: Some(description.catalog.clone()).filter(|c| !c.is_empty()),
            icon: None,
            icon_contents: None,
            other: Vec::new(),
        }),
        classification: Some(DeviceClassification {
            classes: [(1, vec!["DeviceNet".to_string()])].into_iter().collect(),
            other: Vec::new(),
        }),
        io_info: Some(io_info(description)),
        param_class: Some(ParamClass {
            max_inst: Some(PARAMETERS.len() as u32),
            descriptor: Some(CLASS_DESCRIPTOR),
            cfg_assembly: Some(0),
            other: Vec::new(),
        }),
        params: Some(params_section),
        enum_par: None,
        groups: Some(groups(description)),
        other_sections: Vec::new(),
    }
}

/// The EDS text of `description`: [`generate`] written by the [`Writer`] with a header comment
/// naming the generator and [`GenerateOptions::source`].
#[must_use = "the generated EDS is the only output"]
pub fn generate_text(description: &DeviceDescription, options: &GenerateOptions) -> String {
    let mut writer = Writer::new().header_comment(match &options.source {
        Some(source) => format!("Generated by dnet-eds from the device description {source}."),
        None => "Generated by dnet-eds from a device description.".to_string(),
    });
    writer = writer.header_comment(
        "Edit the description and run `dnet-eds generate` again rather than editing this file.",
    );
    writer.write(&generate(description, options))
}

/// The CIP name of a device type (CIP Vol 1 Table 5A-2.x device profiles), as EDS files write it
/// in `ProdTypeStr`; `Vendor Specific` for 0x64..=0xC7, else `Device Type 0xNN`.
pub fn device_type_name(device_type: u16) -> String {
    let name = match device_type {
        0x00 => "Generic Device",
        0x02 => "AC Drive",
        0x03 => "Motor Overload",
        0x04 => "Limit Switch",
        0x05 => "Inductive Proximity Switch",
        0x06 => "Photoelectric Sensor",
        0x07 => "General Purpose Discrete I/O",
        0x09 => "Resolver",
        0x0C => "Communications Adapter",
        0x0E => "Programmable Logic Controller",
        0x10 => "Position Controller",
        0x13 => "DC Drive",
        0x15 => "Contactor",
        0x16 => "Motor Starter",
        0x17 => "Soft Start",
        0x18 => "Human-Machine Interface",
        0x1A => "Mass Flow Controller",
        0x1B => "Pneumatic Valve",
        0x1C => "Vacuum Pressure Gauge",
        0x22 => "Encoder",
        0x64..=0xC7 => "Vendor Specific",
        other => return format!("Device Type 0x{other:02X}"),
    };
    name.to_string()
}

/// `PollInfo` and `StrobeInfo`: combinable with every other I/O connection type.
/// (hilscher_netx90_dns.eds, hilscher_dns_v5_simple.eds, hilscher_dns_v5_extended.eds: `0x000F`.)
pub const POLL_STROBE_COMPATIBLE: ConnectionMask = ConnectionMask(
    ConnectionMask::POLL | ConnectionMask::STROBE | ConnectionMask::COS | ConnectionMask::CYCLIC,
);
/// `COSInfo`: poll, bit-strobe and COS, not cyclic: COS and cyclic are the one Connection instance
/// 4, and the node refuses them together (docs/src/reference/io-connections.md, Allocation). The
/// Hilscher files
/// write the same `0x0007`.
pub const COS_COMPATIBLE: ConnectionMask =
    ConnectionMask(ConnectionMask::POLL | ConnectionMask::STROBE | ConnectionMask::COS);
/// `CyclicInfo`: poll, bit-strobe and cyclic, not COS (the Hilscher files' `0x000B`).
pub const CYCLIC_COMPATIBLE: ConnectionMask =
    ConnectionMask(ConnectionMask::POLL | ConnectionMask::STROBE | ConnectionMask::CYCLIC);
/// The connections that carry the output assembly: poll, and COS or cyclic when poll is not
/// allocated; a bit-strobe consumes one bit of the strobe command instead (the Hilscher files'
/// `OutputN` mask `0x000D`).
pub const OUTPUT_CONNECTIONS: ConnectionMask =
    ConnectionMask(ConnectionMask::POLL | ConnectionMask::COS | ConnectionMask::CYCLIC);

fn io_info(description: &DeviceDescription) -> IoInfo {
    let converter = &description.converter;
    let device = converter.device_config();
    let (input_name, output_name) = match (&converter.profile, converter.input) {
        (ProfileConfig::Framed(_), InputAssembly::Plain) => ("Instrument data", "Command"),
        (ProfileConfig::Framed(_), InputAssembly::WithStatus) => {
            ("Instrument data and link status", "Command")
        }
        (ProfileConfig::Modbus(_), InputAssembly::Plain) => ("Modbus inputs", "Modbus outputs"),
        (ProfileConfig::Modbus(_), InputAssembly::WithStatus) => {
            ("Modbus inputs and link status", "Modbus outputs")
        }
    };
    let entry = |size: u16, mask: ConnectionMask, name: String, instance: u8, help: String| IoEntry {
        size: Some(u32::from(size)),
        bits: Some(u32::from(size) * 8),
        mask: Some(mask),
        name,
        path_size: Some(6),
        path: Some(LinkPath::Bytes(assembly_data_path(instance).to_vec())),
        help,
        extra: Vec::new(),
    };
    let info = |compatible: ConnectionMask, input: u32, output: u32| crate::model::ConnectionInfo {
        compatible: Some(compatible),
        default_input: Some(input),
        default_output: Some(output),
        extra: Vec::new(),
    };
    // The strobe response is the first min(P, 8) bytes of the input assembly. When that is the
    // whole assembly, Input1 serves every connection; otherwise a second entry with the same path
    // and the strobe size serves the bit-strobe: hilscher_netx90_dns.eds lists inputs of several
    // sizes on one assembly path and names its 8-byte one for the strobe.
    let strobe_size = strobe_produced_size(device.produced_size);
    let whole = strobe_size == device.produced_size;
    let input_mask = if whole { POLL_STROBE_COMPATIBLE } else { OUTPUT_CONNECTIONS };
    let mut inputs = vec![entry(
        device.produced_size,
        input_mask,
        input_name.to_string(),
        device.input_assembly,
        input_help(description),
    )];
    if !whole {
        inputs.push(entry(
            strobe_size,
            ConnectionMask(ConnectionMask::STROBE),
            format!("{input_name}, first {strobe_size} bytes"),
            device.input_assembly,
            format!(
                "{} of Input1: a bit-strobe response carries at most {STROBE_MAX_SIZE} bytes and is \
                 never fragmented",
                bytes(0, usize::from(strobe_size))
            ),
        ));
    }
    let strobe_input = if whole { 1 } else { 2 };
    IoInfo {
        default: Some(ConnectionMask(ConnectionMask::POLL)),
        poll: Some(info(POLL_STROBE_COMPATIBLE, 1, 1)),
        // The strobe command is not an output assembly: 0, no default output.
        strobe: Some(info(POLL_STROBE_COMPATIBLE, strobe_input, 0)),
        cos: Some(info(COS_COMPATIBLE, 1, 1)),
        cyclic: Some(info(CYCLIC_COMPATIBLE, 1, 1)),
        inputs: (1..).zip(inputs).collect(),
        outputs: [(
            1,
            entry(
                device.consumed_size,
                OUTPUT_CONNECTIONS,
                output_name.to_string(),
                OUTPUT_ASSEMBLY,
                output_help(description),
            ),
        )]
        .into_iter()
        .collect(),
        other: Vec::new(),
    }
}

/// The path to an assembly instance's data attribute: class 0x04, instance, attribute 3.
pub fn assembly_data_path(instance: u8) -> [u8; 6] {
    logical_path(class::ASSEMBLY, instance, 3)
}

/// `20 cc 24 ii 30 aa`: logical segments with an 8-bit class, instance and attribute (CIP Vol 1
/// Appendix C-1.4.2). Every class named here is below 0x100.
fn logical_path(class_id: u16, instance: u8, attribute: u8) -> [u8; 6] {
    [0x20, u8::try_from(class_id).unwrap_or(u8::MAX), 0x24, instance, 0x30, attribute]
}

/// `bytes 0-7` or `byte 12`.
fn bytes(start: usize, len: usize) -> String {
    match len {
        0 | 1 => format!("byte {start}"),
        _ => format!("bytes {start}-{}", start.saturating_add(len - 1)),
    }
}

fn modbus_item(e: &ScanEntry) -> String {
    let (one, many) = match e.function.code() {
        1 | 5 | 15 => ("coil", "coils"),
        2 => ("discrete input", "discrete inputs"),
        3 | 6 | 16 => ("holding register", "holding registers"),
        _ => ("input register", "input registers"),
    };
    let items = if e.count == 1 {
        format!("{one} {}", e.address)
    } else {
        format!("{many} {}-{}", e.address, (u32::from(e.address) + u32::from(e.count)).saturating_sub(1))
    };
    // The default (registers one by one) is not named: such descriptions keep their help text.
    let pairs = match e.word_order {
        WordOrder::Registers => "",
        WordOrder::Abcd => ", 32-bit values sent ABCD",
        WordOrder::Badc => ", 32-bit values sent BADC",
        WordOrder::Cdab => ", 32-bit values sent CDAB",
        WordOrder::Dcba => ", 32-bit values sent DCBA",
    };
    format!(
        "{}: unit {} {items} (function {}{pairs}{})",
        bytes(usize::from(e.offset), e.image_len()),
        e.unit,
        e.function.code(),
        schedule_text(e)
    )
}

/// An entry's schedule when it is not the default (every scan cycle, or on change): such
/// descriptions keep their help text. The schedule is no parameter: the device serves no scan
/// list over the network.
fn schedule_text(e: &ScanEntry) -> String {
    let verb = if e.function.is_write() { "sent" } else { "read" };
    match (e.trigger_offset, e.period_ms) {
        (Some(b), _) => format!(", {verb} once per change of output byte {b}"),
        (None, Some(p)) if e.function.is_write() => format!(", also sent every {p} ms"),
        (None, Some(p)) => format!(", read every {p} ms"),
        (None, None) => String::new(),
    }
}

fn modbus_layout(m: &ModbusConfig, writes: bool) -> String {
    let mut entries: Vec<&ScanEntry> = m.scan.iter().filter(|e| e.function.is_write() == writes).collect();
    entries.sort_by_key(|e| e.offset);
    let order = match m.byte_order {
        ByteOrder::LittleEndian => "registers low byte first",
        ByteOrder::BigEndian => "registers high byte first",
    };
    let list: Vec<String> = entries.into_iter().map(modbus_item).collect();
    // RTU, the default, is not named: RTU descriptions keep their help text.
    let framing = match m.framing {
        Framing::Rtu => "",
        Framing::Ascii => "; Modbus ASCII",
        Framing::Tcp => "; Modbus TCP",
    };
    format!("{}; {order}{framing}", list.join("; "))
}

fn input_help(description: &DeviceDescription) -> String {
    let converter = &description.converter;
    let len = converter.profile.input_len();
    let data = match &converter.profile {
        ProfileConfig::Framed(_) => format!("{}: the data of the instrument's status frame", bytes(0, len)),
        ProfileConfig::Modbus(m) => match m.valid_bits_offset {
            Some(offset) => format!(
                "{}; {}: data-valid bits, bit k for scan entry k (1 while its last transaction \
                 succeeded within the stale timeout)",
                modbus_layout(m, false),
                bytes(usize::from(offset), valid_bits_len(m.scan.len()))
            ),
            None => modbus_layout(m, false),
        },
    };
    match converter.input {
        InputAssembly::Plain => data,
        InputAssembly::WithStatus => format!(
            "{data}; byte {len}: link status (bit 0 link ok, 1 link timeout, 2 frame errors, 3 Modbus \
             exception, 4-6 last command outcome, 7 request timeout); byte {}: freshness counter",
            len + 1
        ),
    }
}

fn output_help(description: &DeviceDescription) -> String {
    match &description.converter.profile {
        ProfileConfig::Framed(_) => {
            "byte 0: command code, byte 1: sequence number, bytes 2-7: arguments; \
                                     a command is executed once, when the code or the sequence number changes"
                .to_string()
        }
        ProfileConfig::Modbus(m) => {
            let writes = || m.scan.iter().filter(|e| e.function.is_write());
            let on_change =
                match (writes().all(|e| e.write.is_change()), writes().any(|e| e.write.is_change())) {
                    (true, _) => "; written when they change",
                    (false, true) => "; the others written when they change",
                    (false, false) => "",
                };
            let mut triggers: Vec<u16> = m.scan.iter().filter_map(|e| e.trigger_offset).collect();
            triggers.sort_unstable();
            triggers.dedup();
            let triggers: String = triggers
                .iter()
                .map(|b| format!("; byte {b}: trigger byte, each change of value sends the entries it names"))
                .collect();
            format!("{}{on_change}{triggers}", modbus_layout(m, true))
        }
    }
}

/// One generated parameter, before it becomes a [`Param`].
struct Spec {
    number: u32,
    path: [u8; 6],
    descriptor: u16,
    data_type: DataType,
    name: String,
    units: &'static str,
    help: String,
    min: i128,
    max: i128,
    default: i128,
    choices: Vec<(i128, String)>,
}

impl Spec {
    fn to_param(&self) -> Param {
        let descriptor = if self.choices.is_empty() {
            self.descriptor
        } else {
            self.descriptor | Descriptor::ENUMERATED_STRINGS
        };
        Param {
            reserved: Some(0),
            link_path_size: Some(6),
            link_path: Some(LinkPath::Bytes(self.path.to_vec())),
            descriptor: Some(Descriptor(descriptor)),
            data_type: Some(self.data_type),
            data_size: self.data_type.fixed_size(),
            name: self.name.clone(),
            units: self.units.to_string(),
            help: self.help.clone(),
            min: Some(Value::Int(self.min)),
            max: Some(Value::Int(self.max)),
            default: Some(Value::Int(self.default)),
            // Scaling is off in the descriptor; the neutral values are written for tools that
            // read the fields anyway.
            scaling: Scaling { multiplier: Some(1), divisor: Some(1), base: Some(1), offset: Some(0) },
            links: ScalingLinks { multiplier: Some(0), divisor: Some(0), base: Some(0), offset: Some(0) },
            decimal_places: Some(0),
            extra: Vec::new(),
        }
    }
}

/// An attribute of instance 1.
fn attribute_path(class_id: u16, attribute: u8) -> [u8; 6] {
    logical_path(class_id, 1, attribute)
}

fn choices(list: &[(i128, &str)]) -> Vec<(i128, String)> {
    list.iter().map(|(v, t)| (*v, (*t).to_string())).collect()
}

/// What the settings parameters' help and ranges depend on beyond the values (which come from
/// [`SettingsValues`]): the profile's limits and its idle and fault frames.
struct Settings<'a> {
    max_response_timeout_ms: u32,
    max_retries: u8,
    on_idle: &'a IdleAction,
    on_fault: &'a IdleAction,
    modbus: bool,
}

impl<'a> Settings<'a> {
    fn of(profile: &'a ProfileConfig) -> Settings<'a> {
        match profile {
            ProfileConfig::Framed(c) => Settings {
                max_response_timeout_ms: SequencerConfig::MAX_RESPONSE_TIMEOUT_MS,
                max_retries: SequencerConfig::MAX_RETRIES,
                on_idle: &c.sequencer.on_idle,
                on_fault: &c.sequencer.on_fault,
                modbus: false,
            },
            ProfileConfig::Modbus(c) => Settings {
                max_response_timeout_ms: ModbusConfig::MAX_RESPONSE_TIMEOUT_MS,
                max_retries: ModbusConfig::MAX_RETRIES,
                on_idle: &c.on_idle,
                on_fault: &c.on_fault,
                modbus: true,
            },
        }
    }
}

fn action_help(s: &Settings<'_>, action: &IdleAction, when: &str) -> String {
    let what = if s.modbus { "Modbus request" } else { "frame" };
    let configured = match action.frame() {
        None => "nothing".to_string(),
        Some(bytes) => {
            let hex: Vec<String> = bytes.iter().map(|b| format!("{b:02X}")).collect();
            if s.modbus {
                format!("{} + CRC", hex.join(" "))
            } else {
                format!("data {}", hex.join(" "))
            }
        }
    };
    format!("What the converter sends the instrument once {when}: nothing, or the configured {what} (configured: {configured})")
}

const READ_ONLY: u16 = Descriptor::READ_ONLY;
const MONITOR: u16 = Descriptor::READ_ONLY | Descriptor::MONITOR;

fn parameters(description: &DeviceDescription) -> Vec<Spec> {
    let converter = &description.converter;
    let device = converter.device_config();
    let s = Settings::of(&converter.profile);
    let input_len = converter.profile.input_len();
    let values = SettingsValues::of_config(&converter.profile, converter.input);
    let mut specs: Vec<Spec> =
        PARAMETERS.iter().map(|d| parameter_object_param(d, converter, &s, input_len)).collect();
    specs.extend(SETTINGS_PARAMS.into_iter().zip(FIRST_SETTINGS_PARAM..).map(|(a, n)| {
        let shown = setting_presentation(a, &s, input_len);
        attribute_param(n, a.spec(), a.read(&values), shown)
    }));
    let programmable = device.switches.programmable;
    let (switch_descriptor, switch_help) = if programmable {
        (0, "; settable over the network (program position), in force after a reset")
    } else {
        (READ_ONLY, "; set by the DIP switches")
    };
    let devicenet = |attribute: u8| attribute_path(class::DEVICENET, attribute);
    specs.extend([
        Spec {
            number: FIRST_DEVICENET_PARAM,
            path: devicenet(1),
            descriptor: switch_descriptor,
            data_type: DataType::Usint,
            name: "MAC ID".into(),
            units: "",
            help: format!("The node address on DeviceNet{switch_help}"),
            min: 0,
            max: 63,
            default: device.mac_id.as_raw().into(),
            choices: Vec::new(),
        },
        Spec {
            number: FIRST_DEVICENET_PARAM + 1,
            path: devicenet(2),
            descriptor: switch_descriptor,
            data_type: DataType::Usint,
            name: "Data rate".into(),
            units: "",
            help: format!("The DeviceNet data rate{switch_help}"),
            min: 0,
            max: 2,
            default: device.baud_rate.attribute_value().into(),
            choices: choices(&[(0, "125 kbit/s"), (1, "250 kbit/s"), (2, "500 kbit/s")]),
        },
        Spec {
            number: FIRST_DEVICENET_PARAM + 2,
            path: devicenet(3),
            descriptor: 0,
            data_type: DataType::Bool,
            name: "Bus-off interrupt".into(),
            units: "",
            help: "What the CAN controller does on bus-off".into(),
            min: 0,
            max: 1,
            default: u8::from(device.bus_off_interrupt).into(),
            choices: choices(&[(0, "Hold in bus-off"), (1, "Reset and continue")]),
        },
    ]);
    specs.extend(link_parameters());
    specs.extend(units::unit_parameters(description));
    specs
}

/// The serial link object's attributes as monitor parameters, from
/// [`slave_fw::converter::objects::LinkAttribute`]; each starts at 0.
fn link_parameters() -> Vec<Spec> {
    LinkAttribute::ALL
        .into_iter()
        .map(|a| attribute_param(FIRST_LINK_PARAM + u32::from(a.id()) - 1, a.spec(), 0, link_presentation(a)))
        .collect()
}

/// What the EDS says about an attribute beyond the converter's table
/// ([`slave_fw::converter::objects`]): help text, range and the strings of a choice.
struct Presentation {
    help: String,
    min: i128,
    max: i128,
    choices: Vec<(i128, String)>,
}

impl Presentation {
    fn new(help: impl Into<String>, min: impl Into<i128>, max: impl Into<i128>) -> Presentation {
        Presentation { help: help.into(), min: min.into(), max: max.into(), choices: Vec::new() }
    }

    fn choices(mut self, list: &[(i128, &str)]) -> Presentation {
        self.choices = choices(list);
        self
    }
}

/// `ParamN` for Parameter instance N (`def`), its value in `config` the default: the table's
/// name, units, help, type, range and access; the strings of a choice are the settings object's.
fn parameter_object_param(
    def: &ParameterDef,
    config: &ConverterConfig,
    s: &Settings<'_>,
    input_len: usize,
) -> Spec {
    let p = def.parameter;
    // Instances 1-8 are the settings object's attributes 1-8; the poll period has no choices.
    let choices = SettingsAttribute::from_id(p.instance())
        .filter(|_| p != Parameter::PollPeriod)
        .map(|a| setting_presentation(a, s, input_len).choices)
        .unwrap_or_default();
    Spec {
        number: p.instance().into(),
        path: logical_path(PARAMETER_CLASS, p.instance(), 1),
        descriptor: p.descriptor(config),
        data_type: data_type(def.data_type),
        name: def.name.into(),
        units: def.units,
        help: def.help.to_string(),
        min: def.min.into(),
        max: def.max.into(),
        default: p.read(config).into(),
        choices,
    }
}

fn data_type(t: AttributeType) -> DataType {
    match t {
        AttributeType::Usint => DataType::Usint,
        AttributeType::Udint => DataType::Udint,
        AttributeType::Byte => DataType::Byte,
    }
}

/// Parameter `number` for the vendor attribute `spec` (instance 1), with the value `default`.
fn attribute_param(number: u32, spec: AttributeSpec, default: u32, shown: Presentation) -> Spec {
    Spec {
        number,
        path: attribute_path(spec.class, spec.id),
        descriptor: match spec.access {
            Access::Get => READ_ONLY,
            Access::GetMonitor => MONITOR,
        },
        data_type: data_type(spec.data_type),
        name: spec.name.into(),
        units: spec.units,
        help: shown.help,
        min: shown.min,
        max: shown.max,
        default: default.into(),
        choices: shown.choices,
    }
}

/// Help, range and choices of a settings attribute for the described profile.
fn setting_presentation(a: SettingsAttribute, s: &Settings<'_>, input_len: usize) -> Presentation {
    use SettingsAttribute as A;
    let send = if s.modbus { "Send Modbus request" } else { "Send frame" };
    match a {
        A::SerialBaud => Presentation::new(
            "Bit rate of the serial line to the instrument",
            SerialSettings::MIN_BAUD,
            SerialSettings::MAX_BAUD,
        ),
        A::SerialParity => Presentation::new("Parity bit of every character on the serial line", 0, 2)
            .choices(&[(0, "None"), (1, "Odd"), (2, "Even")]),
        A::SerialStopBits => Presentation::new("Stop bits of every character on the serial line", 1, 2)
            .choices(&[(1, "1 stop bit"), (2, "2 stop bits")]),
        A::StaleTimeout => Presentation::new(
            "Time without a good answer from the instrument after which the link is stale (Module \
             Status flashes red, the input data follows the stale policy)",
            1,
            HealthConfig::MAX_STALE_TIMEOUT_MS,
        ),
        A::StalePolicy => Presentation::new("What the input data shows while the link is stale", 0, 1)
            .choices(&[(0, "Hold last value"), (1, "Clear to zero")]),
        A::InputAssembly => Presentation {
            choices: vec![
                (
                    InputAssembly::Plain.instance().into(),
                    format!("Instrument data ({} bytes)", InputAssembly::Plain.produced_size(input_len)),
                ),
                (
                    InputAssembly::WithStatus.instance().into(),
                    format!(
                        "Instrument data and link status ({} bytes)",
                        InputAssembly::WithStatus.produced_size(input_len)
                    ),
                ),
            ],
            ..Presentation::new(
                "The assembly instance the poll connection produces",
                InputAssembly::Plain.instance(),
                InputAssembly::WithStatus.instance(),
            )
        },
        A::ResponseTimeout => Presentation::new(
            if s.modbus {
                "Wait for a Modbus response, counted from the end of the request"
            } else {
                "Wait for the instrument's acknowledgement of a command, counted from the end of the command"
            },
            1,
            s.max_response_timeout_ms,
        ),
        A::Retries => Presentation::new(
            if s.modbus {
                "Repetitions of a Modbus request after a timeout or a corrupted answer"
            } else {
                "Retransmissions of a command after a timeout before it is reported failed"
            },
            0,
            s.max_retries,
        ),
        A::IdleAction => {
            Presentation::new(action_help(s, s.on_idle, "the scanner goes idle (zero-length poll)"), 0, 1)
                .choices(&[(0, "Nothing"), (1, send)])
        }
        A::FaultAction => {
            Presentation::new(action_help(s, s.on_fault, "the poll connection times out"), 0, 1)
                .choices(&[(0, "Nothing"), (1, send)])
        }
        A::SerialProfile => Presentation::new("The instrument protocol on the serial line", 0, 1)
            .choices(&[(0, "Framed serial"), (1, "Modbus RTU master")]),
        // Not an EDS parameter (not in SETTINGS_PARAMS): read by `dnet-master serial-trace` and
        // the console to decode the line trace.
        A::ModbusFraming => Presentation::new("The Modbus framing on the serial line", 0, 2).choices(&[
            (0, "RTU"),
            (1, "ASCII"),
            (2, "TCP (MBAP)"),
        ]),
    }
}

/// Help, range and choices of a serial link attribute.
fn link_presentation(a: LinkAttribute) -> Presentation {
    use LinkAttribute as A;
    let counter = |help: &str| Presentation::new(format!("{help}; wraps at 2^32"), 0, u32::MAX);
    match a {
        A::FramesReceived => {
            counter("Good frames received from the instrument (framing and checksum verified)")
        }
        A::ChecksumErrors => counter("Frames discarded for a checksum or CRC mismatch"),
        A::FramingErrors => {
            counter("Frames discarded for bad framing, answers to nothing asked, bursts of stray bytes")
        }
        A::AnswerTimeouts => counter("Expected answers that did not arrive in time (every attempt counts)"),
        A::CommandsSent => counter("Commands sent (first attempts); Modbus: writes of changed outputs"),
        A::CommandsRetried => counter("Command retransmissions after a timeout or a corrupted answer"),
        A::CommandsFailed => counter("Commands given up after all retries"),
        A::CommandsRejected => {
            counter("Commands the instrument refused (negative acknowledgement, Modbus exception)")
        }
        A::ModbusExceptions => counter("Modbus exception responses, reads and writes"),
        A::FramesSent => counter("Frames written to the serial line, retries and idle/fault frames included"),
        A::DiscardedBytes => counter("Bytes skipped outside any frame"),
        A::LinkTimeouts => counter("Times the link went stale"),
        A::StatusByte => Presentation::new(
            "Bit 0 link ok, 1 link timeout, 2 frame errors, 3 Modbus exception, 4-6 last command outcome \
             (0 none, 1 pending, 2 ok, 3 rejected, 4 failed, 5 unsupported), 7 request timeout",
            0,
            255,
        ),
        A::Freshness => Presentation::new("Counts good frames from the instrument, wrapping at 256", 0, 255),
        A::LinkState => {
            Presentation::new("The instrument link: starting (nothing received yet), ok, or stale", 0, 2)
                .choices(&[(0, "Starting"), (1, "Ok"), (2, "Stale")])
        }
    }
}

fn groups(description: &DeviceDescription) -> GroupsSection {
    let link: Vec<u32> = (FIRST_LINK_PARAM..FIRST_LINK_PARAM + LINK_PARAM_COUNT).collect();
    let list = [
        ("Serial line", vec![FIRST_SETTINGS_PARAM + 2, 1, 2, 3]),
        ("Instrument link", vec![4, 5, 7, 8, 9]),
        ("I/O behaviour", vec![6, FIRST_SETTINGS_PARAM, FIRST_SETTINGS_PARAM + 1]),
        ("DeviceNet", vec![FIRST_DEVICENET_PARAM, FIRST_DEVICENET_PARAM + 1, FIRST_DEVICENET_PARAM + 2]),
        ("Serial link statistics", link),
        ("Modbus units", units::unit_group(description)),
    ];
    GroupsSection {
        groups: list
            .into_iter()
            .filter(|(_, params)| !params.is_empty())
            .zip(1u32..)
            .map(|((name, params), n)| (n, Group { name: name.to_string(), params }))
            .collect(),
        other: Vec::new(),
    }
}

#[cfg(test)]
mod tests;
