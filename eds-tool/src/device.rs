//! `check-device`: a device on the bus against its EDS (electronic keying).
//!
//! A scanner refuses a device whose identity or I/O sizes disagree with the EDS it was configured
//! with, the most common DeviceNet field fault. [`check_device`] reads over the bus, through the
//! master of `master-core`, what a scanner compares, and lists every disagreement:
//!
//! | what | EDS | device |
//! |---|---|---|
//! | vendor ID, device type, product code, major revision (the key) | `[Device]` `VendCode`, `ProdType`, `ProdCode`, `MajRev` | Identity attributes 1, 2, 3, 4 |
//! | produced and consumed size | the `InputN`/`OutputN` that `PollInfo` names by default | poll connection (Connection instance 2) attributes 7 and 8, after allocating poll; Assembly attribute 4 of the EDS's instances when poll cannot be allocated |
//! | produced and consumed path | the same entries' paths | Connection 2 attributes 14 and 16 |
//! | connection types | `PollInfo`, `StrobeInfo`, `COSInfo`, `CyclicInfo`, the `Default` mask and every connection mask | whether the device accepts the allocation (each accepted one is released at once) |
//! | bit-strobe, change-of-state and cyclic produced size | the size of the `InputN` that `StrobeInfo`, `COSInfo`, `CyclicInfo` name by default | attribute 7 of Connection instance 3 (bit-strobe) or 4 (COS, cyclic), read while the probe holds the allocation |
//!
//! Minor revision and product name are shown as notes: a scanner does not key on them.
//!
//! The sequence on the bus: the master's duplicate MAC ID check, wait for the device, Allocate
//! explicit through the Group 2 Only port, the Identity reads, Allocate poll, the connection
//! reads, the probes of the other connection types (each: Allocate, the produced size when
//! accepted, Release), Release poll and explicit. A device that another master owns refuses the
//! first allocation; that is an error, not a disagreement.

use can_io::bus::{Bitrate, Bus, BusSpec};
use can_io::log::LogWriter;
use converter_sim::{OpenError, SimSetup};
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::{Duration, MacId};
use eds::model::{ConnectionInfo, Eds, IoEntry, Param};
use eds::value::{AttributePath, ConnectionMask, DataType, LinkPath, Value};
use master_core::bring_up::{BringUp, Refusal, Step};
use master_core::client::{Port, ReplyBody};
use master_core::decode;
use master_core::error::MasterError;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use serde::Serialize;
use slave_fw::description::DeviceDescription;
use std::fmt;
use std::path::PathBuf;

/// How one comparison came out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// EDS and device agree.
    Agree,
    /// They disagree: a scanner keyed on this EDS refuses the device, or configures it wrongly.
    Disagree,
    /// Shown for information; not part of the key.
    Note,
}

/// One comparison: what, the EDS's value, the device's value.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Finding {
    /// What was compared, with the EDS keyword (`product code (ProdCode)`).
    pub what: String,
    /// The EDS's value, as text (`(missing)` when the EDS does not say).
    pub eds: String,
    /// The device's value, as text (the error response when it refused).
    pub device: String,
    /// The outcome.
    pub verdict: Verdict,
}

/// What [`check_device`] found.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct DeviceReport {
    /// The device's MAC ID.
    pub mac: u8,
    /// Every comparison, in the order made.
    pub findings: Vec<Finding>,
}

impl DeviceReport {
    /// The disagreements.
    pub fn disagreements(&self) -> impl Iterator<Item = &Finding> {
        self.findings.iter().filter(|f| f.verdict == Verdict::Disagree)
    }

    /// `true` when nothing disagrees.
    #[must_use = "a device check whose verdict is ignored tests nothing"]
    pub fn agrees(&self) -> bool {
        self.disagreements().next().is_none()
    }

    /// The finding about `what` (matched as a prefix, `"product code"`), for tests and tools.
    pub fn finding(&self, what: &str) -> Option<&Finding> {
        self.findings.iter().find(|f| f.what.starts_with(what))
    }
}

impl fmt::Display for DeviceReport {
    /// A table (what, EDS, device, verdict), then the disagreements one per line, then a count.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let width = |pick: fn(&Finding) -> &str, title: &str| {
            self.findings.iter().map(|x| pick(x).chars().count()).chain([title.len()]).max().unwrap_or(0)
        };
        let (w0, w1, w2) =
            (width(|x| &x.what, "what"), width(|x| &x.eds, "EDS"), width(|x| &x.device, "device"));
        writeln!(f, "{:<w0$}  {:<w1$}  {:<w2$}  verdict", "what", "EDS", "device")?;
        for x in &self.findings {
            let verdict = match x.verdict {
                Verdict::Agree => "ok",
                Verdict::Disagree => "DISAGREES",
                Verdict::Note => "note",
            };
            writeln!(f, "{:<w0$}  {:<w1$}  {:<w2$}  {verdict}", x.what, x.eds, x.device)?;
        }
        let disagreements: Vec<&Finding> = self.disagreements().collect();
        if disagreements.is_empty() {
            return write!(f, "MAC {}: the device agrees with the EDS", self.mac);
        }
        writeln!(f)?;
        for x in &disagreements {
            writeln!(f, "disagreement: {}: EDS {}, device {}", x.what, x.eds, x.device)?;
        }
        write!(
            f,
            "MAC {}: {} disagreement{} with the EDS",
            self.mac,
            disagreements.len(),
            if disagreements.len() == 1 { "" } else { "s" }
        )
    }
}

/// Where the device is: the bus, and for the simulated bus the device on it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BusOptions {
    /// `sim`, `socketcan:IFACE` or `slcan:PATH[@SERIALBAUD]`.
    pub bus: BusSpec,
    /// CAN bit rate (sim and SLCAN). `None`: on the simulated bus the simulated device's own
    /// data rate, on SLCAN 250 kbit/s; SocketCAN interfaces are configured outside.
    pub bitrate: Option<Bitrate>,
    /// The device's MAC ID; on the simulated bus the soft slave is put there.
    pub mac: MacId,
    /// Simulated bus: the device description the soft slave runs; `None` is the reference device
    /// (`slave-fw/descriptions/breaker.toml`).
    pub slave_config: Option<PathBuf>,
}

/// Why [`check_on_bus`] could not check the device.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// The exchange with the device stopped: the bus, a timeout, an error response where none is
    /// allowed, a broken protocol, a duplicate MAC ID.
    #[error(transparent)]
    Master(#[from] MasterError),
    /// A bad option or option combination.
    #[error("{0}")]
    Usage(String),
    /// The device description given with `slave_config` was refused.
    #[error("{0}")]
    Description(#[from] slave_fw::description::DescriptionError),
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Write {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
}

/// Opens the bus `options` name. On the simulated bus one soft slave runs the description at
/// `options.mac`, powered on when the master is on-line, as `dnet-master --bus sim` does
/// ([`converter_sim::open_bus`], the one way every program opens a bus).
///
/// # Errors
///
/// [`DeviceError::Description`] for a bad description file, [`DeviceError::Usage`] for
/// `slave_config` on a real bus, [`MasterError::Bus`] when the interface or port cannot be
/// opened.
pub fn open_bus(options: &BusOptions) -> Result<Box<dyn Bus>, DeviceError> {
    if options.slave_config.is_some() && options.bus != BusSpec::Sim {
        return Err(DeviceError::Usage(
            "--slave-config describes the simulated device; it needs --bus sim".to_string(),
        ));
    }
    let mut setup = match &options.slave_config {
        Some(path) => SimSetup::described(DeviceDescription::load(path)?.converter),
        None => SimSetup::reference(),
    };
    setup.macs = vec![options.mac];
    let bitrate = match options.bus {
        BusSpec::Sim => options.bitrate.unwrap_or_else(|| Bitrate::from(setup.config.device.baud_rate)),
        _ => options.bitrate.unwrap_or(Bitrate::K250),
    };
    converter_sim::open_bus(&options.bus, bitrate, &setup).map_err(|e| match e {
        OpenError::Setup(msg) => DeviceError::Usage(msg),
        OpenError::Bus(e) => DeviceError::Master(MasterError::Bus(e)),
    })
}

/// The master's side of the check, and what to check beyond the key.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CheckOptions {
    /// The master's MAC ID (0 unless another node holds it).
    pub master_mac: MacId,
    /// Explicit response timeout.
    pub response_timeout: Duration,
    /// Also read every parameter's link path attribute: one the device does not serve, or serves
    /// with another size than the parameter's data size, disagrees; a value other than the
    /// default is a note (the device may simply be configured otherwise).
    pub params: bool,
}

impl Default for CheckOptions {
    /// MAC 0, the harness's 1 s response timeout, no parameter reads.
    fn default() -> Self {
        let config = MasterConfig::default();
        CheckOptions { master_mac: config.mac, response_timeout: config.response_timeout, params: false }
    }
}

impl CheckOptions {
    /// The harness configuration.
    pub fn master_config(&self) -> MasterConfig {
        MasterConfig {
            mac: self.master_mac,
            response_timeout: self.response_timeout,
            ..MasterConfig::default()
        }
    }
}

/// What the EDS says the device is; `None` where it does not say.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Expected {
    /// `VendCode`.
    pub vendor_id: Option<u16>,
    /// `ProdType`.
    pub device_type: Option<u16>,
    /// `ProdCode`.
    pub product_code: Option<u16>,
    /// `MajRev`.
    pub major_revision: Option<u8>,
    /// `MinRev`.
    pub minor_revision: Option<u8>,
    /// `ProdName`.
    pub product_name: Option<String>,
    /// The `InputN` `PollInfo` names by default: its keyword and entry.
    pub poll_input: Option<(String, IoEntry)>,
    /// The `OutputN` `PollInfo` names by default: its keyword and entry.
    pub poll_output: Option<(String, IoEntry)>,
    /// Per connection type (poll, bit-strobe, change of state, cyclic): where the EDS announces
    /// it (`PollInfo`, `Default`, `Input1 mask`); empty when it does not.
    pub announced: Vec<(ConnectionType, Vec<String>)>,
    /// Per connection type other than poll whose `...Info` entry the EDS has: the default input's
    /// keyword (`Input2`) and size, what a scanner expects the connection to produce (size 0 for
    /// default input 0, none; `None` when the entry or its size is missing).
    pub produced: Vec<(ConnectionType, String, Option<u32>)>,
}

/// An I/O connection type of the predefined master/slave set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ConnectionType {
    /// Polled I/O.
    Poll,
    /// Bit-strobed I/O.
    BitStrobe,
    /// Change-of-state I/O.
    ChangeOfState,
    /// Cyclic I/O.
    Cyclic,
}

impl ConnectionType {
    /// All four, in `[IO_Info]` mask bit order.
    pub const ALL: [ConnectionType; 4] = [
        ConnectionType::Poll,
        ConnectionType::BitStrobe,
        ConnectionType::ChangeOfState,
        ConnectionType::Cyclic,
    ];

    /// The `[IO_Info]` mask bit.
    pub const fn mask(self) -> u16 {
        match self {
            ConnectionType::Poll => ConnectionMask::POLL,
            ConnectionType::BitStrobe => ConnectionMask::STROBE,
            ConnectionType::ChangeOfState => ConnectionMask::COS,
            ConnectionType::Cyclic => ConnectionMask::CYCLIC,
        }
    }

    /// The allocation choice bit (protocol §3.4).
    pub const fn choice(self) -> AllocationChoice {
        match self {
            ConnectionType::Poll => AllocationChoice::POLL,
            ConnectionType::BitStrobe => AllocationChoice::BIT_STROBE,
            ConnectionType::ChangeOfState => AllocationChoice::CHANGE_OF_STATE,
            ConnectionType::Cyclic => AllocationChoice::CYCLIC,
        }
    }

    /// The `[IO_Info]` keyword of its connection entry.
    pub const fn keyword(self) -> &'static str {
        match self {
            ConnectionType::Poll => "PollInfo",
            ConnectionType::BitStrobe => "StrobeInfo",
            ConnectionType::ChangeOfState => "COSInfo",
            ConnectionType::Cyclic => "CyclicInfo",
        }
    }
}

impl fmt::Display for ConnectionType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ConnectionType::Poll => "poll",
            ConnectionType::BitStrobe => "bit-strobe",
            ConnectionType::ChangeOfState => "change-of-state",
            ConnectionType::Cyclic => "cyclic",
        })
    }
}

impl Expected {
    /// What `eds` says.
    pub fn of(eds: &Eds) -> Expected {
        let device = eds.device.clone().unwrap_or_default();
        let io = eds.io_info.clone().unwrap_or_default();
        let pick = |n: Option<u32>, list: &std::collections::BTreeMap<u32, IoEntry>, prefix: &str| {
            let n = n.filter(|&n| n != 0)?;
            list.get(&n).map(|e| (format!("{prefix}{n}"), e.clone()))
        };
        let poll = io.poll.as_ref();
        let poll_input = pick(poll.and_then(|p| p.default_input), &io.inputs, "Input");
        let poll_output = pick(poll.and_then(|p| p.default_output), &io.outputs, "Output");
        let infos: [Option<&ConnectionInfo>; 4] =
            [io.poll.as_ref(), io.strobe.as_ref(), io.cos.as_ref(), io.cyclic.as_ref()];
        let announced = ConnectionType::ALL
            .iter()
            .zip(infos)
            .map(|(&kind, info)| {
                let bit = kind.mask();
                let mut sources = Vec::new();
                if info.is_some() {
                    sources.push(kind.keyword().to_string());
                }
                if io.default.is_some_and(|m| m.has(bit)) {
                    sources.push("Default".to_string());
                }
                for (other, info) in ConnectionType::ALL.iter().zip(infos) {
                    if *other != kind && info.and_then(|i| i.compatible).is_some_and(|m| m.has(bit)) {
                        sources.push(format!("{} mask", other.keyword()));
                    }
                }
                for (prefix, list) in [("Input", &io.inputs), ("Output", &io.outputs)] {
                    for (n, entry) in list {
                        if entry.mask.is_some_and(|m| m.has(bit)) {
                            sources.push(format!("{prefix}{n} mask"));
                        }
                    }
                }
                (kind, sources)
            })
            .collect();
        let produced = ConnectionType::ALL
            .iter()
            .zip(infos)
            .skip(1)
            .filter_map(|(&kind, info)| {
                let n = info?.default_input;
                let (keyword, size) = match n {
                    Some(0) => (format!("{} default input 0", kind.keyword()), Some(0)),
                    Some(n) => (format!("Input{n}"), io.inputs.get(&n).and_then(|e| e.size)),
                    None => (format!("{} default input", kind.keyword()), None),
                };
                Some((kind, keyword, size))
            })
            .collect();
        Expected {
            vendor_id: device.vend_code,
            device_type: device.prod_type,
            product_code: device.prod_code,
            major_revision: device.maj_rev,
            minor_revision: device.min_rev,
            product_name: device.prod_name,
            poll_input,
            poll_output,
            announced,
            produced,
        }
    }

    fn announces(&self, kind: ConnectionType) -> &[String] {
        self.announced.iter().find(|(k, _)| *k == kind).map_or(&[], |(_, s)| s.as_slice())
    }

    /// The default input keyword and size of `kind`'s `...Info` entry; `None` without the entry.
    fn produced(&self, kind: ConnectionType) -> Option<(&str, Option<u32>)> {
        self.produced.iter().find(|(k, _, _)| *k == kind).map(|(_, keyword, size)| (keyword.as_str(), *size))
    }
}

/// Names, Connection 2 size and path attributes, and the EDS entry of one I/O direction.
type IoDirection<'a> = (&'static str, &'static str, u8, u8, Option<&'a (String, IoEntry)>);

/// The outcome of one request: the value, or the device's error response by name.
type Read = Result<Vec<u8>, String>;

/// Runs `step` on the device through the bring-up engine; an error response is a value
/// (`Err(text)`), a timeout or bus failure an error.
fn ask(master: &mut Master<'_, '_>, node: &mut BringUp, step: Step) -> Result<Read, MasterError> {
    let (body, _) = master.run_step(node, step, Refusal::Report)?;
    Ok(match body {
        ReplyBody::Success(data) => Ok(data),
        // The general status by name; the additional code only when there is one (0xFF: none).
        ReplyBody::Error { general, additional: 0xFF } => Err(general.to_string()),
        ReplyBody::Error { general, additional } => {
            Err(format!("{general}, additional code 0x{additional:02X}"))
        }
    })
}

fn get(
    master: &mut Master<'_, '_>,
    node: &mut BringUp,
    class_id: u16,
    instance: u16,
    attribute: u8,
) -> Result<Read, MasterError> {
    ask(master, node, Step::Get { class: class_id, instance, attribute })
}

/// Allocates `choice` through the explicit connection; a refusal is a finding.
fn allocate(
    master: &mut Master<'_, '_>,
    node: &mut BringUp,
    choice: AllocationChoice,
) -> Result<Read, MasterError> {
    ask(master, node, Step::Allocate { port: Port::Explicit, choice })
}

/// Releases what this check allocated; a refusal is an error (the master owns it).
fn release(
    master: &mut Master<'_, '_>,
    node: &mut BringUp,
    choice: AllocationChoice,
) -> Result<(), MasterError> {
    master.run_step(node, Step::Release { port: Port::Explicit, choice }, Refusal::Stop)?;
    Ok(())
}

fn uint(read: &Read) -> Result<u16, String> {
    match read {
        Ok(bytes) => match bytes.as_slice() {
            [a, b] => Ok(u16::from_le_bytes([*a, *b])),
            other => Err(format!("{} bytes ({}), a UINT has 2", other.len(), decode::hex(other))),
        },
        Err(e) => Err(e.clone()),
    }
}

fn show<T: fmt::Display>(value: Option<T>) -> String {
    value.map_or_else(|| "(missing)".to_string(), |v| v.to_string())
}

fn hex16(value: Option<u16>) -> String {
    value.map_or_else(|| "(missing)".to_string(), |v| format!("0x{v:04X}"))
}

/// Compares a keyed value: missing in the EDS or unreadable from the device disagrees too.
fn keyed<T: PartialEq + Copy>(
    what: &str,
    eds: Option<T>,
    device: Result<T, String>,
    text: impl Fn(Option<T>) -> String,
) -> Finding {
    let verdict = match (&eds, &device) {
        (Some(e), Ok(d)) if e == d => Verdict::Agree,
        _ => Verdict::Disagree,
    };
    let device = match device {
        Ok(d) => text(Some(d)),
        Err(e) => format!("error: {e}"),
    };
    Finding { what: what.to_string(), eds: text(eds), device, verdict }
}

fn note(what: &str, eds: String, device: String, same: bool) -> Finding {
    let verdict = if same { Verdict::Agree } else { Verdict::Note };
    Finding { what: what.to_string(), eds, device, verdict }
}

/// Reads the identity and connection facts of the device at `target` and compares them with
/// `eds`; see the [module docs](self). Every frame goes through `master`'s session (its
/// transcript and log).
///
/// # Errors
///
/// A [`MasterError`] when the exchange cannot be completed: the device does not answer, the bus
/// fails, another master owns the device, or an answer breaks the protocol. Values the device
/// refuses to give are findings, not errors.
pub fn check_device(
    master: &mut Master<'_, '_>,
    target: MacId,
    eds: &Eds,
    options: &CheckOptions,
) -> Result<DeviceReport, MasterError> {
    let expected = Expected::of(eds);
    master.prepare(target)?;
    let mut node = master.bring_up(target);
    let node = &mut node;
    master.run_step(
        node,
        Step::Allocate { port: Port::Group2Only, choice: AllocationChoice::EXPLICIT },
        Refusal::Stop,
    )?;
    let mut findings = Vec::new();

    // Identity (class 0x01 instance 1): the electronic key.
    let vendor = get(master, node, class::IDENTITY, 1, 1)?;
    findings.push(keyed("vendor ID (VendCode)", expected.vendor_id, uint(&vendor), hex16));
    let device_type = get(master, node, class::IDENTITY, 1, 2)?;
    findings.push(keyed("device type (ProdType)", expected.device_type, uint(&device_type), show));
    let product_code = get(master, node, class::IDENTITY, 1, 3)?;
    findings.push(keyed("product code (ProdCode)", expected.product_code, uint(&product_code), show));
    let revision = get(master, node, class::IDENTITY, 1, 4)?;
    let revision = match &revision {
        Ok(bytes) => match bytes.as_slice() {
            [major, minor] => Ok((*major, *minor)),
            other => Err(format!("{} bytes ({}), a revision has 2", other.len(), decode::hex(other))),
        },
        Err(e) => Err(e.clone()),
    };
    findings.push(keyed(
        "major revision (MajRev)",
        expected.major_revision,
        revision.clone().map(|r| r.0),
        show,
    ));
    let minor = revision.map(|r| r.1);
    findings.push(note(
        "minor revision (MinRev, not keyed)",
        show(expected.minor_revision),
        minor.clone().map_or_else(|e| format!("error: {e}"), |m| m.to_string()),
        minor.ok() == expected.minor_revision,
    ));
    let name = match get(master, node, class::IDENTITY, 1, 7)? {
        Ok(bytes) => match bytes.split_first() {
            Some((&len, text)) if usize::from(len) == text.len() => {
                Ok(String::from_utf8_lossy(text).into_owned())
            }
            _ => Err(format!("not a SHORT_STRING: {}", decode::hex(&bytes))),
        },
        Err(e) => Err(e),
    };
    findings.push(note(
        "product name (ProdName, not keyed)",
        expected.product_name.as_ref().map_or_else(|| "(missing)".to_string(), |n| format!("{n:?}")),
        name.as_ref().map_or_else(|e| format!("error: {e}"), |n| format!("{n:?}")),
        name.ok() == expected.product_name,
    ));

    // The poll connection: sizes and paths as a scanner sees them.
    let poll_sources = expected.announces(ConnectionType::Poll).to_vec();
    let poll = allocate(master, node, AllocationChoice::POLL)?;
    findings.push(connection_finding(ConnectionType::Poll, &poll_sources, &poll));
    // Per direction: names, Connection 2 size and path attributes, the EDS entry.
    let directions: [IoDirection<'_>; 2] = [
        ("produced size", "produced path", 7, 14, expected.poll_input.as_ref()),
        ("consumed size", "consumed path", 8, 16, expected.poll_output.as_ref()),
    ];
    for (size_what, path_what, size_attr, path_attr, entry) in directions {
        let keyword = entry.map_or_else(|| "PollInfo default".to_string(), |(k, _)| k.clone());
        let eds_size = entry.and_then(|(_, e)| e.size);
        let eds_path = entry.and_then(|(_, e)| e.path.clone());
        if poll.is_ok() {
            let size = get(master, node, class::CONNECTION, 2, size_attr)?;
            findings.push(keyed(
                &format!("{size_what} ({keyword})"),
                eds_size,
                uint(&size).map(u32::from),
                show,
            ));
            let path = get(master, node, class::CONNECTION, 2, path_attr)?;
            findings.push(path_finding(&format!("{path_what} ({keyword})"), eds_path.as_ref(), &path));
        } else {
            // Poll refused: the assembly the EDS names still tells its size.
            let instance =
                eds_path.as_ref().and_then(LinkPath::attribute).filter(|a| a.class == class::ASSEMBLY);
            let device = match instance {
                Some(a) => uint(&get(master, node, class::ASSEMBLY, a.instance, 4)?)
                    .map(u32::from)
                    .map_err(|e| format!("{e} (assembly {} attribute 4; poll refused)", a.instance)),
                None => Err("not read: poll refused and the EDS names no assembly".to_string()),
            };
            findings.push(keyed(&format!("{size_what} ({keyword})"), eds_size, device, show));
        }
    }

    // The other connection types: does the device accept what the EDS announces, and does the
    // connection produce the size of the EDS's default input?
    // (docs/src/reference/io-connections.md: Connection
    // 3 produces min(P, 8) bytes, Connection 4 P bytes.)
    for (kind, instance) in
        [(ConnectionType::BitStrobe, 3), (ConnectionType::ChangeOfState, 4), (ConnectionType::Cyclic, 4)]
    {
        let sources = expected.announces(kind).to_vec();
        let outcome = allocate(master, node, kind.choice())?;
        let size = match (&outcome, expected.produced(kind)) {
            (Ok(_), Some(eds)) => Some((eds, get(master, node, class::CONNECTION, instance, 7)?)),
            _ => None,
        };
        if outcome.is_ok() {
            release(master, node, kind.choice())?;
        }
        findings.push(connection_finding(kind, &sources, &outcome));
        if let Some(((keyword, eds_size), device)) = size {
            findings.push(keyed(
                &format!("{kind} produced size ({keyword})"),
                eds_size,
                uint(&device).map(u32::from),
                show,
            ));
        }
    }

    if options.params {
        for (n, param) in eds.params() {
            findings.push(param_finding(master, node, n, param)?);
        }
    }

    // Give the connections back so a scanner can have the device.
    if poll.is_ok() {
        release(master, node, AllocationChoice::POLL)?;
    }
    release(master, node, AllocationChoice::EXPLICIT)?;
    Ok(DeviceReport { mac: target.as_raw(), findings })
}

/// Opens the bus, runs [`check_device`] on it at `bus.mac`, and closes it; every frame goes to
/// `log` when given, in the format its extension names (`.asc`, `.trc`, `.csv`; else `candump -L`),
/// as every program's `--log` ([`can_io::trace::write::log_format`]).
///
/// # Errors
///
/// Those of [`open_bus`] and [`check_device`], [`DeviceError::Usage`] when the device is at the
/// master's own MAC or the log's extension names a format that is read, not written (`.pcap`), and
/// [`DeviceError::Write`] when the log file cannot be created.
pub fn check_on_bus(
    eds: &Eds,
    bus: &BusOptions,
    options: &CheckOptions,
    log: Option<&std::path::Path>,
) -> Result<DeviceReport, DeviceError> {
    if bus.mac == options.master_mac {
        return Err(DeviceError::Usage(format!("the device's MAC {} is the master's own MAC", bus.mac)));
    }
    let format = log
        .map(|path| can_io::trace::write::log_format(path, None))
        .transpose()
        .map_err(|e| DeviceError::Usage(e.to_string()))?;
    let mut open = open_bus(bus)?;
    let mut session = Session::new(open.as_mut());
    if let (Some(path), Some(format)) = (log, format) {
        let writer = LogWriter::create_as(path, format)
            .map_err(|source| DeviceError::Write { path: path.display().to_string(), source })?;
        session.set_log(writer);
    }
    let mut master = Master::new(&mut session, options.master_config());
    let report = check_device(&mut master, bus.mac, eds, options);
    session.flush()?;
    Ok(report?)
}

/// Reads parameter `n`'s attribute and compares it with the parameter's size and default.
fn param_finding(
    master: &mut Master<'_, '_>,
    node: &mut BringUp,
    n: u32,
    param: &Param,
) -> Result<Finding, MasterError> {
    let what = format!("Param{n} {:?}", param.name);
    let address = param.link_path.as_ref().and_then(LinkPath::attribute);
    let Some(AttributePath { class: class_id, instance, attribute: Some(attribute) }) = address else {
        let path = param.link_path.as_ref().map_or_else(|| "(none)".to_string(), |p| format!("\"{p}\""));
        return Ok(note(
            &what,
            format!("link path {path}"),
            "not read: not an attribute path".to_string(),
            false,
        ));
    };
    let Ok(attribute) = u8::try_from(attribute) else {
        return Ok(note(
            &what,
            format!("attribute {attribute}"),
            "not read: attribute above 255".to_string(),
            false,
        ));
    };
    let at = format!("class 0x{class_id:02X} instance {instance} attribute {attribute}");
    let bytes = match get(master, node, class_id, instance, attribute)? {
        Ok(bytes) => bytes,
        Err(e) => {
            return Ok(Finding { what, eds: at, device: format!("error: {e}"), verdict: Verdict::Disagree });
        }
    };
    let size = param.data_type.and_then(DataType::fixed_size).or(param.data_size);
    if let Some(size) = size.filter(|&s| usize::try_from(s).ok() != Some(bytes.len())) {
        return Ok(Finding {
            what,
            eds: format!("{at}, {size} bytes"),
            device: format!("{} bytes ({})", bytes.len(), decode::hex(&bytes)),
            verdict: Verdict::Disagree,
        });
    }
    let signed =
        matches!(param.data_type, Some(DataType::Sint | DataType::Int | DataType::Dint | DataType::Lint));
    let value = integer(&bytes, signed);
    let default = param.default.as_ref().and_then(Value::as_int);
    let monitor = param.descriptor.is_some_and(|d| d.monitor());
    let (eds_text, verdict) = match default {
        // A monitor parameter's default says nothing about its value now.
        _ if monitor => (format!("{at}, monitor"), Verdict::Agree),
        Some(d) if value == Some(d) => (format!("{at}, default {d}"), Verdict::Agree),
        Some(d) => (format!("{at}, default {d}"), Verdict::Note),
        None => (at, Verdict::Agree),
    };
    let device = value.map_or_else(|| decode::hex(&bytes), |v| v.to_string());
    Ok(Finding { what, eds: eds_text, device, verdict })
}

/// A little-endian integer of 1 to 8 bytes.
fn integer(bytes: &[u8], signed: bool) -> Option<i128> {
    if bytes.is_empty() || bytes.len() > 8 {
        return None;
    }
    let mut raw = [0u8; 16];
    raw[..bytes.len()].copy_from_slice(bytes);
    let negative = signed && bytes.last().is_some_and(|b| b & 0x80 != 0);
    if negative {
        raw[bytes.len()..].fill(0xFF);
    }
    Some(i128::from_le_bytes(raw))
}

fn connection_finding(kind: ConnectionType, sources: &[String], outcome: &Read) -> Finding {
    let eds = if sources.is_empty() {
        "not announced".to_string()
    } else {
        format!("announced ({})", sources.join(", "))
    };
    let (device, accepted) = match outcome {
        Ok(_) => ("accepts".to_string(), true),
        Err(e) => (format!("refuses: {e}"), false),
    };
    let verdict = match (sources.is_empty(), accepted) {
        (false, false) => Verdict::Disagree,
        (true, true) => Verdict::Note,
        _ => Verdict::Agree,
    };
    Finding { what: format!("{kind} connection"), eds, device, verdict }
}

fn path_finding(what: &str, eds: Option<&LinkPath>, device: &Read) -> Finding {
    let target = |p: &LinkPath| p.attribute().map(|a| (a.class, a.instance));
    let device_path = device.as_ref().map(|bytes| LinkPath::Bytes(bytes.clone()));
    let verdict = match (eds, &device_path) {
        // Compared by class and instance, so 8- and 16-bit segments or an omitted attribute agree.
        (Some(e), Ok(d)) if target(e).is_some() && target(e) == target(d) => Verdict::Agree,
        _ => Verdict::Disagree,
    };
    let text = |p: &LinkPath| match p.attribute() {
        Some(AttributePath { class: 0x04, instance, .. }) => format!("\"{p}\" (assembly {instance})"),
        _ => format!("\"{p}\""),
    };
    Finding {
        what: what.to_string(),
        eds: eds.map_or_else(|| "(missing)".to_string(), text),
        device: device_path.as_ref().map_or_else(|e| format!("error: {e}"), text),
        verdict,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expected_reads_keys_and_announcements() {
        let eds = eds::parse_str(
            "[Device]\nVendCode = 283; ProdType = 12; ProdCode = 34; MajRev = 5; MinRev = 4;\n\
             [IO_Info]\nDefault = 0x0001;\nPollInfo = 0x0005, 1, 2;\nCOSInfo = 0x0005, 1, 0;\n\
             Input1 = 10, 80, 0x0005, \"in\", 6, \"20 04 24 65 30 03\", \"\";\n\
             Output2 = 6, 48, 0x0001, \"out\", 6, \"20 04 24 64 30 03\", \"\";\n",
        )
        .unwrap();
        let e = Expected::of(&eds);
        assert_eq!(
            (e.vendor_id, e.device_type, e.product_code, e.major_revision),
            (Some(283), Some(12), Some(34), Some(5))
        );
        assert_eq!(e.poll_input.as_ref().map(|(k, i)| (k.as_str(), i.size)), Some(("Input1", Some(10))));
        assert_eq!(e.poll_output.as_ref().map(|(k, o)| (k.as_str(), o.size)), Some(("Output2", Some(6))));
        assert_eq!(
            e.announces(ConnectionType::Poll),
            ["PollInfo", "Default", "COSInfo mask", "Input1 mask", "Output2 mask"]
        );
        assert_eq!(e.announces(ConnectionType::ChangeOfState), ["COSInfo", "PollInfo mask", "Input1 mask"]);
        assert!(e.announces(ConnectionType::BitStrobe).is_empty());
        assert_eq!(e.produced, [(ConnectionType::ChangeOfState, "Input1".to_string(), Some(10))]);
    }

    #[test]
    fn integers_of_every_width() {
        assert_eq!(integer(&[0x80, 0x25, 0, 0], false), Some(9600));
        assert_eq!(integer(&[0xFF], true), Some(-1));
        assert_eq!(integer(&[0xFF], false), Some(255));
        assert_eq!(integer(&[0, 0x80], true), Some(-32768));
        assert_eq!(integer(&[], false), None);
        assert_eq!(integer(&[0; 9], false), None);
    }

    #[test]
    fn connection_verdicts() {
        let announced = ["StrobeInfo".to_string()];
        let refused: Read = Err("resource unavailable".into());
        let accepted: Read = Ok(vec![0]);
        assert_eq!(
            connection_finding(ConnectionType::BitStrobe, &announced, &refused).verdict,
            Verdict::Disagree
        );
        assert_eq!(
            connection_finding(ConnectionType::BitStrobe, &announced, &accepted).verdict,
            Verdict::Agree
        );
        assert_eq!(connection_finding(ConnectionType::BitStrobe, &[], &refused).verdict, Verdict::Agree);
        assert_eq!(connection_finding(ConnectionType::BitStrobe, &[], &accepted).verdict, Verdict::Note);
    }

    #[test]
    fn paths_compare_by_class_and_instance() {
        let eds = LinkPath::parse("20 04 24 64");
        let agree = path_finding("p", Some(&eds), &Ok(vec![0x20, 0x04, 0x24, 0x64, 0x30, 0x03]));
        assert_eq!(agree.verdict, Verdict::Agree);
        let other = path_finding("p", Some(&eds), &Ok(vec![0x20, 0x04, 0x24, 0x65, 0x30, 0x03]));
        assert_eq!(
            (other.verdict, other.device.as_str()),
            (Verdict::Disagree, "\"20 04 24 65 30 03\" (assembly 101)")
        );
        assert_eq!(path_finding("p", None, &Ok(vec![])).verdict, Verdict::Disagree);
    }

    #[test]
    fn keyed_values_need_both_sides() {
        assert_eq!(keyed("x", Some(1u16), Ok(1), show).verdict, Verdict::Agree);
        assert_eq!(keyed("x", Some(1u16), Ok(2), show).verdict, Verdict::Disagree);
        assert_eq!(keyed("x", None, Ok(2u16), show).eds, "(missing)");
        let refused = keyed("x", Some(1u16), Err("attribute not supported".into()), show);
        assert_eq!(
            (refused.verdict, refused.device.as_str()),
            (Verdict::Disagree, "error: attribute not supported")
        );
    }

    #[test]
    fn report_lists_disagreements() {
        let report = DeviceReport {
            mac: 5,
            findings: vec![
                Finding {
                    what: "vendor ID (VendCode)".into(),
                    eds: "0x1234".into(),
                    device: "0x1234".into(),
                    verdict: Verdict::Agree,
                },
                Finding {
                    what: "product code (ProdCode)".into(),
                    eds: "7".into(),
                    device: "1".into(),
                    verdict: Verdict::Disagree,
                },
            ],
        };
        assert!(!report.agrees());
        let text = report.to_string();
        assert!(text.contains("disagreement: product code (ProdCode): EDS 7, device 1"), "{text}");
        assert!(text.ends_with("MAC 5: 1 disagreement with the EDS"), "{text}");
        assert_eq!(report.finding("product code").map(|f| f.device.as_str()), Some("1"));
    }
}
