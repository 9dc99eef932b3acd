//! What the scanner knows and shows, shared by `dnet-master scanner` (the engine, `crate::engine`), the
//! web console (`crate::ui`), the history database and the MQTT publisher: the scan list, each
//! node's status with the numeric code scanners display, the scanner's own state, and the commands
//! the console sends to the engine.
//!
//! Node status codes are those of Allen-Bradley's DeviceNet scanners (1756-DNB, 1747-SDN,
//! 1769-SDN), which every DeviceNet engineer reads off the scanner's display: "DeviceNet Status
//! Codes", Studio 5000 Logix Designer documentation, Rockwell Automation
//! (rockwellautomation.com/en-us/docs/studio-5000-logix-designer/.../devicenet-status-codes.html).
//! Checked against that page for the scanner (issue 15): 70 "the address of the scanner is already
//! in use by another device", 72 "slave device stopped communicating; if communication is not
//! reestablished during the next attempt, the status code changes to 78", 73 "identity
//! information does not match the electronic key (vendor, product code, product type)" read as
//! stated here; 77 (size), 78 (not present), 83 (error responses), 84 (initializing), 86 (zero
//! length / idle data) and 91 (bus-off) are the same page's later rows, which the stored copy
//! used for the check cuts off: taken from the 1756-DNB / 1769-SDN tables, not re-read.

use master_core::master::io::IoKind;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::io::Write;
use std::path::PathBuf;
use std::sync::mpsc::Sender;
use std::sync::Mutex;
use std::time::SystemTime;

/// One node of the scan list: what the scanner expects at a MAC ID.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanEntry {
    /// MAC ID, 0-63.
    pub mac: u8,
    /// The I/O connection: `poll`, `strobe`, `cos` or `cyclic` (the names of
    /// [`IoKind::name`]; [`ScanEntry::io_kind`]).
    #[serde(default = "poll")]
    pub connection: String,
    /// COS and cyclic: allocate with acknowledge suppression (allocation bit 0x40, protocol §II.2.5):
    /// the node's productions and the scanner's data are not acknowledged.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub ack_suppression: bool,
    /// COS: the production inhibit time to set, Connection 4 attribute 17, ms (`None`: the
    /// device's own, 0 after allocation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inhibit_ms: Option<u16>,
    /// Electronic key: Identity attribute 1; `None`: not checked.
    #[serde(default)]
    pub vendor_id: Option<u16>,
    /// Electronic key: Identity attribute 2.
    #[serde(default)]
    pub device_type: Option<u16>,
    /// Electronic key: Identity attribute 3.
    #[serde(default)]
    pub product_code: Option<u16>,
    /// Electronic key: Identity attribute 4 major revision.
    #[serde(default)]
    pub major_revision: Option<u8>,
    /// Electronic key: Identity attribute 4 minor revision (`compatible` keying: this or later).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub minor_revision: Option<u8>,
    /// The input size in bytes, what the node produces: poll response (Connection 2 attribute
    /// 7), strobe response (Connection 3 attribute 7, at most 8), COS/cyclic production
    /// (Connection 4 attribute 7).
    pub input_size: u16,
    /// The output size in bytes, what the node consumes: poll command or the scanner's COS/cyclic
    /// data (Connection 2 attribute 8). 0 for a strobed node: its output is its bit of the strobe
    /// command (the node's output image is then 1 byte, bit 0 that bit).
    pub output_size: u16,
    /// A name for the node in reports and the console (default: the product name read).
    #[serde(default)]
    pub name: Option<String>,
    /// Automatic device replacement for the node (`crate::adr`): `off` (default), `config` or
    /// `config+address`.
    #[serde(default, skip_serializing_if = "AdrMode::is_off")]
    pub adr: AdrMode,
    /// How the electronic key is compared: `exact` (default), `compatible` or `disabled`
    /// ([`crate::keying`]).
    #[serde(default, skip_serializing_if = "Keying::is_exact")]
    pub keying: Keying,
    /// `false`: the node is kept in the list but not scanned (maintenance).
    #[serde(default = "yes", skip_serializing_if = "Clone::clone")]
    pub enabled: bool,
}

fn poll() -> String {
    "poll".into()
}

fn yes() -> bool {
    true
}

/// A change of the scan list while the scanner runs (the console's `POST /api/scanlist/...`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ListEdit {
    /// A new entry (its MAC not in the list).
    Add(ScanEntry),
    /// The entry at the entry's MAC replaced (the node is brought up again).
    Edit(ScanEntry),
    /// The entry at the MAC removed (its connections released).
    Remove(u8),
    /// The node at the MAC enabled or disabled (maintenance: kept, not scanned).
    Enable {
        /// MAC ID.
        mac: u8,
        /// `false`: disabled.
        enabled: bool,
    },
}

/// A scan-list entry's automatic device replacement (ADR, Rockwell's and ABB's term).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum AdrMode {
    /// No replacement.
    #[default]
    #[serde(rename = "off")]
    Off,
    /// Configuration recovery: a replacement at the node's MAC whose configuration consistency
    /// value differs gets the stored configuration.
    #[serde(rename = "config")]
    Config,
    /// Configuration and address recovery: a replacement at MAC 63 is also moved to the node's MAC.
    #[serde(rename = "config+address")]
    ConfigAddress,
}

impl AdrMode {
    /// `true` for [`AdrMode::Off`].
    #[must_use]
    pub fn is_off(&self) -> bool {
        *self == AdrMode::Off
    }

    /// The name in the scan list file.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            AdrMode::Off => "off",
            AdrMode::Config => "config",
            AdrMode::ConfigAddress => "config+address",
        }
    }
}

pub use crate::keying::Keying;

impl ScanEntry {
    /// The entry's electronic key (the parts it gives).
    #[must_use]
    pub fn electronic_key(&self) -> crate::keying::ElectronicKey {
        crate::keying::ElectronicKey {
            vendor_id: self.vendor_id,
            device_type: self.device_type,
            product_code: self.product_code,
            major_revision: self.major_revision,
            minor_revision: self.minor_revision,
        }
    }

    /// The connection type: the [`IoKind`] named by `connection` (poll for a name that is none,
    /// which [`super::parse_scan_list`] refuses).
    #[must_use]
    pub fn io_kind(&self) -> IoKind {
        IoKind::ALL.into_iter().find(|k| k.name() == self.connection).unwrap_or(IoKind::Poll)
    }
}

/// A scan list file (TOML): `[[node]]` tables, and the scanner's own settings.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScanList {
    /// The inter-scan delay in ms; `None`: computed from the scan list and the data rate.
    #[serde(default)]
    pub interscan_delay_ms: Option<u32>,
    /// The expected packet rate given to every node, ms; `None`: computed.
    #[serde(default)]
    pub expected_packet_rate_ms: Option<u16>,
    /// The nodes, in MAC order.
    #[serde(default, rename = "node")]
    pub nodes: Vec<ScanEntry>,
}

/// A node's status, with the code a DeviceNet scanner shows for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeStatus {
    /// In I/O, data exchanged this cycle (code 0: no fault).
    Ok,
    /// In I/O, the device produces idle (zero-length) data (code 86).
    Idle,
    /// Nothing answers at the MAC (code 78).
    NotPresent,
    /// The identity does not match the scan list's electronic key (code 73).
    KeyingMismatch,
    /// The I/O sizes do not match the scan list (code 77).
    SizeMismatch,
    /// It stopped answering polls or strobes, or its COS/cyclic productions stopped (code 72; 78
    /// if it stays away).
    TimedOut,
    /// It answered an allocation or configuration request with an error (code 83).
    ErrorResponse,
    /// Two devices at the MAC: one of them failed its duplicate MAC ID check and is Communication
    /// Faulted. The scanner codes have none for it (70 is the scanner's own duplicate): shown as 78,
    /// with this status's name, see [`NodeStatus::code`].
    CommunicationFaulted,
    /// Being brought into I/O (code 84).
    Initializing,
    /// Disabled in the scan list (maintenance): kept, not scanned. A scanner shows no fault for
    /// a node it does not scan: code 0, with this status's name.
    Disabled,
}

impl NodeStatus {
    /// The numeric node status code (Rockwell's DeviceNet status codes): 0 ok, 72 stopped
    /// communicating, 73 keying mismatch, 77 size mismatch, 78 not present, 83 error response,
    /// 84 initializing, 86 idle data. Communication Faulted has no code of its own there; it is
    /// shown as 78 (the node does not take part) with its own status name.
    #[must_use]
    pub fn code(self) -> u8 {
        match self {
            NodeStatus::Ok | NodeStatus::Disabled => 0,
            NodeStatus::TimedOut => 72,
            NodeStatus::KeyingMismatch => 73,
            NodeStatus::SizeMismatch => 77,
            NodeStatus::NotPresent | NodeStatus::CommunicationFaulted => 78,
            NodeStatus::ErrorResponse => 83,
            NodeStatus::Initializing => 84,
            NodeStatus::Idle => 86,
        }
    }

    /// The name used in text, JSON and the console (`ok`, `not_present`, ...).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            NodeStatus::Ok => "ok",
            NodeStatus::Idle => "idle",
            NodeStatus::NotPresent => "not_present",
            NodeStatus::KeyingMismatch => "keying_mismatch",
            NodeStatus::SizeMismatch => "size_mismatch",
            NodeStatus::TimedOut => "timed_out",
            NodeStatus::ErrorResponse => "error_response",
            NodeStatus::CommunicationFaulted => "communication_faulted",
            NodeStatus::Initializing => "initializing",
            NodeStatus::Disabled => "disabled",
        }
    }
}

/// What was read of a node's identity.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Identity {
    /// Identity attribute 1.
    pub vendor_id: Option<u16>,
    /// Identity attribute 2.
    pub device_type: Option<u16>,
    /// Identity attribute 3.
    pub product_code: Option<u16>,
    /// Identity attribute 4, `major.minor`.
    pub revision: Option<String>,
    /// Identity attribute 6.
    pub serial_number: Option<u32>,
    /// Identity attribute 7.
    pub product_name: Option<String>,
}

impl Identity {
    /// What the device answered for the electronic key (attributes 1–4).
    #[must_use]
    pub fn electronic_key(&self) -> crate::keying::ElectronicKey {
        crate::keying::ElectronicKey {
            vendor_id: self.vendor_id,
            device_type: self.device_type,
            product_code: self.product_code,
            ..Default::default()
        }
        .with_revision_text(self.revision.as_deref())
    }

    /// Keeps the value of Identity attribute `attribute` (instance 1) as read: 1-3 as u16, 4 as
    /// `major.minor`, 6 as u32, 7 the product name (a value of the wrong length is kept as
    /// unknown); `false` for an attribute it does not hold.
    pub fn take_attribute(&mut self, attribute: u8, data: &[u8]) -> bool {
        match attribute {
            1 => self.vendor_id = master_core::decode::u16_of(data),
            2 => self.device_type = master_core::decode::u16_of(data),
            3 => self.product_code = master_core::decode::u16_of(data),
            4 => {
                self.revision = match data {
                    [major, minor] => Some(format!("{major}.{minor}")),
                    _ => None,
                }
            }
            6 => {
                self.serial_number = match data {
                    [a, b, c, d] => Some(u32::from_le_bytes([*a, *b, *c, *d])),
                    _ => None,
                }
            }
            7 => self.product_name = master_core::decode::short_string(data),
            _ => return false,
        }
        true
    }
}

/// One node as the scanner sees it now.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeState {
    /// MAC ID.
    pub mac: u8,
    /// The scan list's `name` for the node (`feeder 1`), if it gives one.
    #[serde(default)]
    pub name: Option<String>,
    /// The I/O connection of the scan list: `poll`, `strobe`, `cos` or `cyclic`.
    #[serde(default = "poll")]
    pub connection: String,
    /// COS/cyclic with acknowledge suppression.
    #[serde(default)]
    pub ack_suppression: bool,
    /// Status.
    pub status: NodeStatus,
    /// [`NodeStatus::code`].
    pub code: u8,
    /// What the status is about, in words (`expected product code 99, read 100`).
    pub detail: Option<String>,
    /// The identity read.
    pub identity: Identity,
    /// The I/O sizes read (input = produced by the node, output = consumed).
    pub input_size: Option<u16>,
    /// The output size read.
    pub output_size: Option<u16>,
    /// The last input image received.
    pub input: Vec<u8>,
    /// The output image sent while the node is ok (a strobed node: 1 byte, bit 0 its strobe bit).
    pub output: Vec<u8>,
    /// Cycles with data exchanged.
    pub exchanges: u64,
    /// Bus time of the last exchange, microseconds.
    pub last_exchange_us: Option<u64>,
}

/// The scanner's own status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ScannerStatus {
    /// Network access in progress (its duplicate MAC ID check).
    Starting,
    /// Scanning.
    Running,
    /// The bus is in error-warning state (many transmit or receive errors).
    BusWarning,
    /// The controller went bus-off (code 91).
    BusOff,
    /// Another node has the scanner's MAC ID (code 70).
    DuplicateMac,
    /// Stopped (`--cycles` reached, or a signal).
    Stopped,
}

/// Everything the scanner shows: its state, the cycle figures and every node.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScannerState {
    /// The scanner's MAC ID.
    pub mac: u8,
    /// Its status.
    pub status: ScannerStatus,
    /// Full scan cycles done.
    pub cycles: u64,
    /// Median time of a full scan cycle, ms (over the last cycles).
    pub cycle_ms: f64,
    /// Bus load over the last cycles, 0.0-1.0 (time on the wire / time).
    pub bus_load: f64,
    /// The inter-scan delay in force, ms.
    pub interscan_delay_ms: u32,
    /// The expected packet rate in force, ms.
    pub expected_packet_rate_ms: u16,
    /// The nodes of the scan list, in MAC order.
    pub nodes: Vec<NodeState>,
}

/// A decoded frame for the console's trace view.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameRow {
    /// Sequence number (the console asks for rows after the last one it has).
    pub seq: u64,
    /// Bus time, microseconds.
    pub time_us: u64,
    /// `ID#DATA`.
    pub frame: String,
    /// The 11-bit identifier.
    pub id: u16,
    /// The data bytes.
    pub data: Vec<u8>,
    /// Sent by the scanner.
    pub own: bool,
    /// The MAC ID the frame concerns (source or destination), if any.
    pub mac: Option<u8>,
    /// The message kind for the filter (`explicit`, `io`, `duplicate_mac`, `ucmm`, `offline`).
    pub kind: String,
    /// `dnet-master decode`'s text.
    pub meaning: String,
    /// The completed message, for the last fragment of a series.
    pub message: Option<String>,
}

/// One input sample of a node, for the history database and MQTT.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    /// MAC ID.
    pub mac: u8,
    /// Wall-clock time, milliseconds since the Unix epoch.
    pub unix_ms: i64,
    /// Bus time, microseconds.
    pub bus_us: u64,
    /// The input image.
    pub input: Vec<u8>,
    /// The values decoded by the node's profile (`name`, number), in order.
    pub values: Vec<(String, f64)>,
}

/// Milliseconds since the Unix epoch, now.
#[must_use]
pub fn unix_ms_now() -> i64 {
    SystemTime::now().duration_since(SystemTime::UNIX_EPOCH).map_or(0, |d| d.as_millis() as i64)
}

/// The answer to a console command: `Ok` with what was read (empty for a write), or the error in
/// words (the device's error response by name, a timeout, a node that is not ok).
pub type Reply = Result<Vec<u8>, String>;

/// What the console asks the scanner to do; the scanner's loop carries it out between cycles and
/// answers on `reply`.
#[derive(Debug)]
pub enum ConsoleCommand {
    /// Put `data` in the node's output image (sent with each poll, as its strobe bit, or as the
    /// scanner's COS/cyclic data while the node is ok; refused with an error while it is not, or
    /// when the size is not the node's output size; a strobed node takes 1 byte, 0 or 1).
    SetOutput {
        /// MAC ID.
        mac: u8,
        /// The whole output image.
        data: Vec<u8>,
        /// The answer.
        reply: Sender<Reply>,
    },
    /// Get_Attribute_Single on the node's explicit connection.
    Get {
        /// MAC ID.
        mac: u8,
        /// Class.
        class: u16,
        /// Instance.
        instance: u16,
        /// Attribute.
        attribute: u8,
        /// The answer: the value's bytes.
        reply: Sender<Reply>,
    },
    /// Set_Attribute_Single on the node's explicit connection.
    Set {
        /// MAC ID.
        mac: u8,
        /// Class.
        class: u16,
        /// Instance.
        instance: u16,
        /// Attribute.
        attribute: u8,
        /// The value's bytes.
        value: Vec<u8>,
        /// The answer (empty on success).
        reply: Sender<Reply>,
    },
    /// Any explicit request (`service` with `data`) on the node's explicit connection, answered
    /// with the device's reply, success or error response (the serial-line analyzer's Read_Trace,
    /// `ui::serial_trace_api`).
    Request {
        /// MAC ID.
        mac: u8,
        /// The service code.
        service: u8,
        /// Class.
        class: u16,
        /// Instance.
        instance: u16,
        /// The request data after the path.
        data: Vec<u8>,
        /// The device's reply, or why there was none (a timeout, a node that is not ok).
        reply: Sender<Result<master_core::client::ReplyBody, String>>,
    },
    /// The events after sequence number `since` ([`crate::events`]).
    Events {
        /// The last sequence number seen (0: all).
        since: u64,
        /// The events, oldest first.
        reply: Sender<Vec<crate::events::ScanEvent>>,
    },
    /// A change of the scan list while the scanner runs.
    EditList {
        /// The change.
        edit: ListEdit,
        /// The answer (empty on success).
        reply: Sender<Reply>,
    },
    /// The bus and node health report ([`crate::health`]), after clearing the statistics when
    /// `clear`.
    Health {
        /// Clear first.
        clear: bool,
        /// The report.
        reply: Sender<crate::health::HealthReport>,
    },
}

/// Where the console finds the history of samples (the SQLite database in `crate::history`).
pub trait HistoryStore: Send + Sync {
    /// The samples of `mac` with `from_ms <= unix_ms <= to_ms`, oldest first, at most `limit`
    /// (the newest `limit` when there are more).
    fn samples(&self, mac: u8, from_ms: i64, to_ms: i64, limit: usize) -> Result<Vec<Sample>, String>;
    /// Writes the samples of `mac` (every node: `None`) in the time range as CSV with a header
    /// line (`unix_ms,time,mac,input_hex,` then one column per value name); the number of rows.
    fn export_csv(
        &self,
        mac: Option<u8>,
        from_ms: i64,
        to_ms: i64,
        out: &mut dyn Write,
    ) -> Result<usize, String>;
}

/// A history shared between the loop that records it and the console that reads it.
impl<T: HistoryStore + ?Sized> HistoryStore for std::sync::Arc<T> {
    fn samples(&self, mac: u8, from_ms: i64, to_ms: i64, limit: usize) -> Result<Vec<Sample>, String> {
        (**self).samples(mac, from_ms, to_ms, limit)
    }

    fn export_csv(
        &self,
        mac: Option<u8>,
        from_ms: i64,
        to_ms: i64,
        out: &mut dyn Write,
    ) -> Result<usize, String> {
        (**self).export_csv(mac, from_ms, to_ms, out)
    }
}

/// How many frames the console's trace view keeps (the oldest are dropped).
pub const FRAME_RING: usize = 5000;

/// What the scanner's loop and the console share: the latest state, the recent frames, the
/// command queue and the history.
pub struct Shared {
    /// The scanner's state after its last cycle.
    pub state: Mutex<ScannerState>,
    /// The last [`FRAME_RING`] frames, oldest first.
    pub frames: Mutex<VecDeque<FrameRow>>,
    /// Commands for the scanner's loop.
    pub commands: Mutex<Sender<ConsoleCommand>>,
    /// The sample history, when kept.
    pub history: Option<Box<dyn HistoryStore>>,
    /// Where the console's recordings go (`record-TIMESTAMP.log` / `.pcap`).
    pub record_dir: PathBuf,
    /// The MQTT publisher's state in words, when `--mqtt` is given (`connected to URL`,
    /// `broker unreachable: ...`).
    pub mqtt: Mutex<Option<String>>,
    /// The audit log every command is recorded in (the history's, or in memory without one).
    pub audit: std::sync::Arc<dyn crate::audit::Audit>,
}

impl Shared {
    /// Appends frames to the ring, dropping the oldest beyond [`FRAME_RING`].
    pub fn push_frames(&self, rows: impl IntoIterator<Item = FrameRow>) {
        if let Ok(mut ring) = self.frames.lock() {
            for row in rows {
                if ring.len() == FRAME_RING {
                    ring.pop_front();
                }
                ring.push_back(row);
            }
        }
    }
}
