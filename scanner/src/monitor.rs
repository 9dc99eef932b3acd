//! `monitor --mac N`: bring the device up, then poll it at the expected packet rate and show the
//! polled data decoded by the device's own profile, refreshed in place on a terminal, one line per
//! sample otherwise; `--csv FILE` records every sample, a row flushed as it is taken.
//!
//! ## Decoding: the device's description, or raw bytes
//!
//! The input image is decoded by an [`InputLayout`] taken from a device description:
//! `--description FILE` (any bus), else on the simulated bus the `--slave-config` file, else on the
//! simulated bus the built-in reference device (the breaker: without `--slave-config` the simulated
//! device *is* the reference converter). On a real bus without `--description` nothing is known of
//! the device, and the data is shown as raw hex bytes: monitor does not guess a profile.
//!
//! | profile | fields |
//! |---|---|
//! | breaker | the four phase currents and the switch state (`open`, `closed`, `unknown (0xXX)`) |
//! | framed | the image as hex bytes |
//! | Modbus | one field per read entry of the scan list: `u1 fc3 @40101+2: 230, 231` (unit, function, the first item in Modbus notation, count), registers decoded in the description's `byte_order`, coils and inputs as bits `0`/`1` |
//!
//! With input assembly 101 (`with_status`: produced size = image + 2) the status byte and the
//! freshness counter that follow the image are named: `link ok` / `STALE: LINK TIMEOUT` /
//! `link starting`, `errors seen`, `Modbus exception`, `request unanswered`, the last command's
//! outcome, and the freshness counter. A sample whose status says link timeout (bit 1) is stale:
//! `STALE` on its line, `stale` in the CSV and JSON. Data of another length than the description
//! produces is shown raw with the two sizes named.
//!
//! The CSV columns are `time_s`, the profile's fields (breaker: `phase_a,phase_b,phase_c,neutral,
//! switch`; Modbus: one column per register or bit, named `u1:40101`), then `status` (`0x01`),
//! `freshness`, `stale` (`1`/`0`; the three empty without a status byte) and `raw` (hex).
//!
//! ## How a run ends
//!
//! [`monitor`] returns the samples it took together with what ended the run
//! ([`MonitorRun::ended`]): nothing (`--count` or `--duration` reached), a failure, or an
//! interruption (SIGINT / SIGTERM through the session's stop). The command line reports the
//! samples in every case, and exits 128 + the signal after an interruption.
//!
//! ## `--reconnect`
//!
//! With `--reconnect` a lost connection does not end the run: a bus error (a SocketCAN interface
//! taken down, an adapter unplugged) or a poll left unanswered is reported as `connection lost`,
//! and the master tries every [`RECONNECT_INTERVAL`] to get the connections back without a new
//! duplicate MAC ID check of its own: Allocate explicit through the Group 2 Only port (an
//! explicit connection the device still holds for this master is used as it is), Release of a
//! poll connection left over, Allocate poll, sizes and expected packet rate again, then polling
//! goes on (`reconnected`). A device that restarted is simply asked until it is on-line again.
//! A device that does not answer at the start (the master's own network access done) is waited
//! for the same way (`waiting for it`, then `connected at T`); a `--duration` then
//! counts from the start of the run.
//!
//! The CSV header is written before the bring-up, so a run that ends before its first sample
//! leaves a CSV file with its header.

use converter_sim::device::{SWITCH_BYTE, SWITCH_CLOSED, SWITCH_OPEN};
use devicenet::explicit::GeneralStatus;
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::{Duration, Instant, MacId};
use harness_common::console::Progress;
use harness_common::error::HarnessError;
use master_core::client::Port;
use master_core::error::{MasterError, UsageError};
use master_core::io::{IoKind, IoOptions};
use master_core::master::{ConnectOptions, Master, MIN_POLL_TIMEOUT};
use master_core::session::Verdict;
use slave_fw::converter::{ConverterConfig, InputAssembly};
use slave_fw::serial::modbus::{ByteOrder, Function, ScanEntry};
use slave_fw::serial::{FramedProfileConfig, ProfileConfig, StatusByte};
use std::io::Write;

/// The breaker profile's view of the 18-byte poll response.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct BreakerStatus {
    /// Phase A, B, C and neutral currents (A).
    pub currents: [u8; 4],
    /// Switch state byte (`0x0F` open, `0xF0` closed).
    pub switch: u8,
}

impl BreakerStatus {
    /// Decodes the input image; `None` when it is shorter than the profile's 10 bytes.
    #[must_use]
    pub fn decode(input: &[u8]) -> Option<BreakerStatus> {
        let switch = *input.get(SWITCH_BYTE)?;
        Some(BreakerStatus { currents: [input[0], input[1], input[2], input[3]], switch })
    }

    /// `open`, `closed` or `unknown (0xXX)`.
    #[must_use]
    pub fn switch_text(&self) -> String {
        match self.switch {
            SWITCH_OPEN => "open".into(),
            SWITCH_CLOSED => "closed".into(),
            other => format!("unknown (0x{other:02X})"),
        }
    }
}

/// How the instrument's image is decoded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ImageProfile {
    /// Nothing known: raw bytes.
    Raw,
    /// The breaker preset: phase currents and the switch.
    Breaker,
    /// Another framed instrument: the image as bytes.
    Framed,
    /// A Modbus gateway: one field per read entry of the scan list.
    Modbus {
        /// Register byte order in the image.
        byte_order: ByteOrder,
        /// The read entries (functions 1–4), in scan-list order.
        reads: Vec<ScanEntry>,
    },
}

/// What the poll response carries: the decoded image and, with assembly 101, the status byte and
/// the freshness counter. See the [module docs](self).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InputLayout {
    /// How the image is decoded.
    pub profile: ImageProfile,
    /// The image's length in bytes (0 for [`ImageProfile::Raw`]).
    pub image_len: usize,
    /// The status byte and the freshness counter follow the image (assembly 101).
    pub with_status: bool,
}

/// `true` when `c` is the breaker preset (a `kind = "breaker"` description may change only its
/// serial line, health and sequencer, never its frames).
fn is_breaker(c: &FramedProfileConfig) -> bool {
    let b = FramedProfileConfig::breaker();
    c.framing == b.framing && c.status_len == b.status_len && c.ack == b.ack && c.commands == b.commands
}

impl InputLayout {
    /// Nothing known of the device: raw bytes, no status byte assumed.
    #[must_use]
    pub fn raw() -> InputLayout {
        InputLayout { profile: ImageProfile::Raw, image_len: 0, with_status: false }
    }

    /// The layout of the converter `config` describes (a description's `converter`).
    #[must_use]
    pub fn from_converter(config: &ConverterConfig) -> InputLayout {
        let profile = match &config.profile {
            ProfileConfig::Framed(c) if is_breaker(c) => ImageProfile::Breaker,
            ProfileConfig::Framed(_) => ImageProfile::Framed,
            ProfileConfig::Modbus(m) => ImageProfile::Modbus {
                byte_order: m.byte_order,
                reads: m.scan.iter().filter(|e| !e.function.is_write()).copied().collect(),
            },
        };
        InputLayout {
            profile,
            image_len: config.profile.input_len(),
            with_status: config.input == InputAssembly::WithStatus,
        }
    }

    /// The produced size the layout expects; `None` for raw bytes.
    #[must_use]
    pub fn produced_size(&self) -> Option<usize> {
        match self.profile {
            ImageProfile::Raw => None,
            _ => Some(self.image_len + if self.with_status { 2 } else { 0 }),
        }
    }

    /// The CSV columns of the profile's fields.
    pub fn field_columns(&self) -> Vec<String> {
        match &self.profile {
            ImageProfile::Raw | ImageProfile::Framed => Vec::new(),
            ImageProfile::Breaker => {
                ["phase_a", "phase_b", "phase_c", "neutral", "switch"].map(String::from).to_vec()
            }
            ImageProfile::Modbus { reads, .. } => reads
                .iter()
                .flat_map(|e| (0..e.count).map(move |i| format!("u{}:{}", e.unit, modbus_ref(e, i))))
                .collect(),
        }
    }

    /// Decodes one poll response.
    #[must_use]
    pub fn decode(&self, input: &[u8]) -> Decoded {
        let Some(size) = self.produced_size() else {
            return Decoded::default();
        };
        if input.len() != size {
            return Decoded {
                note: Some(format!("{} bytes; the description produces {size}", input.len())),
                ..Decoded::default()
            };
        }
        let (image, tail) = input.split_at(self.image_len);
        let link = match tail {
            [status, freshness] if self.with_status => Some(LinkView::new(*status, *freshness)),
            _ => None,
        };
        let fields = match &self.profile {
            ImageProfile::Raw => Vec::new(),
            ImageProfile::Breaker => breaker_fields(image),
            ImageProfile::Framed => vec![Field {
                name: "data".into(),
                values: image.iter().map(|b| u16::from(*b)).collect(),
                text: master_core::decode::hex(image),
            }],
            ImageProfile::Modbus { byte_order, reads } => {
                reads.iter().map(|e| modbus_field(e, *byte_order, image)).collect()
            }
        };
        Decoded { fields, link, note: None }
    }
}

/// The Modbus reference of item `i` of `e`: `40001` for holding register 0 (`0xxxx` coils,
/// `1xxxx` inputs, `3xxxx` input registers, `4xxxx` holding registers; six digits past 9999).
fn modbus_ref(e: &ScanEntry, i: u16) -> String {
    let prefix = match e.function {
        Function::ReadCoils => 0,
        Function::ReadDiscreteInputs => 1,
        Function::ReadInputRegisters => 3,
        _ => 4,
    };
    let number = u32::from(e.address) + u32::from(i) + 1;
    if number <= 9999 {
        format!("{prefix}{number:04}")
    } else {
        format!("{prefix}{number:05}")
    }
}

/// One read entry's values from `image`.
fn modbus_field(e: &ScanEntry, order: ByteOrder, image: &[u8]) -> Field {
    let at = usize::from(e.offset);
    let values: Vec<u16> = if e.function.is_bits() {
        (0..usize::from(e.count))
            .map(|i| image.get(at + i / 8).map_or(0, |b| u16::from((b >> (i % 8)) & 1)))
            .collect()
    } else {
        (0..usize::from(e.count))
            .map(|i| {
                let b = [image.get(at + 2 * i), image.get(at + 2 * i + 1)].map(|b| b.copied().unwrap_or(0));
                match order {
                    ByteOrder::LittleEndian => u16::from_le_bytes(b),
                    ByteOrder::BigEndian => u16::from_be_bytes(b),
                }
            })
            .collect()
    };
    let name = format!("u{} fc{} @{}+{}", e.unit, e.function.code(), modbus_ref(e, 0), e.count);
    let list: Vec<String> = values.iter().map(ToString::to_string).collect();
    Field { text: format!("{name}: {}", list.join(", ")), name, values }
}

fn breaker_fields(image: &[u8]) -> Vec<Field> {
    let Some(b) = BreakerStatus::decode(image) else {
        return Vec::new();
    };
    let mut fields: Vec<Field> = ["phase_a", "phase_b", "phase_c", "neutral"]
        .iter()
        .zip(b.currents)
        .map(|(name, a)| Field { name: (*name).into(), values: vec![u16::from(a)], text: format!("{a} A") })
        .collect();
    fields.push(Field { name: "switch".into(), values: vec![u16::from(b.switch)], text: b.switch_text() });
    fields
}

/// One decoded field of the image.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Field {
    /// `phase_a`, `switch`, `data`, or a Modbus entry `u1 fc3 @40101+2`.
    pub name: String,
    /// Its values: a current, the switch byte, bytes, registers, or bits (0/1).
    pub values: Vec<u16>,
    /// As shown: `120 A`, `closed`, `u1 fc3 @40101+2: 230, 231`.
    pub text: String,
}

/// The status byte and the freshness counter of assembly 101, decoded (bit layout in the guide,
/// docs/src/reference/io-data.md,
/// "Input assemblies and the status byte").
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct LinkView {
    /// The status byte as received.
    pub status: u8,
    /// The freshness counter.
    pub freshness: u8,
    /// `ok` (bit 0), `timeout` (bit 1) or `starting` (neither).
    pub link: &'static str,
    /// Bit 2: framing or checksum errors seen since the last good frame.
    pub errors_seen: bool,
    /// Bit 3: a Modbus exception.
    pub exception: bool,
    /// Bit 7: a Modbus request unanswered after all retries.
    pub request_unanswered: bool,
    /// Bits 4–6: `none`, `pending`, `ok`, `rejected`, `failed`, `unsupported` (or `code N`).
    pub command: &'static str,
}

impl LinkView {
    /// Decodes the two bytes.
    #[must_use]
    pub fn new(status: u8, freshness: u8) -> LinkView {
        let s = StatusByte::from_raw(status);
        let link = if s.contains(StatusByte::LINK_TIMEOUT) {
            "timeout"
        } else if s.contains(StatusByte::LINK_OK) {
            "ok"
        } else {
            "starting"
        };
        let command = match s.command_code() {
            0 => "none",
            1 => "pending",
            2 => "ok",
            3 => "rejected",
            4 => "failed",
            5 => "unsupported",
            6 => "code 6",
            _ => "code 7",
        };
        LinkView {
            status,
            freshness,
            link,
            errors_seen: s.contains(StatusByte::FRAME_ERRORS),
            exception: s.contains(StatusByte::EXCEPTION),
            request_unanswered: s.contains(StatusByte::REQUEST_TIMEOUT),
            command,
        }
    }

    /// Status bit 1: the instrument has been silent for the stale timeout; the data is held or
    /// cleared, not live.
    #[must_use]
    pub fn stale(&self) -> bool {
        self.link == "timeout"
    }

    /// `link ok, command none, freshness 12` / `STALE: LINK TIMEOUT, errors seen, ...`.
    #[must_use]
    pub fn text(&self) -> String {
        let mut parts = vec![match self.link {
            "timeout" => "STALE: LINK TIMEOUT".to_string(),
            other => format!("link {other}"),
        }];
        if self.errors_seen {
            parts.push("errors seen".into());
        }
        if self.exception {
            parts.push("Modbus exception".into());
        }
        if self.request_unanswered {
            parts.push("request unanswered".into());
        }
        parts.push(format!("command {}", self.command));
        parts.push(format!("freshness {}", self.freshness));
        parts.join(", ")
    }
}

/// A poll response decoded by an [`InputLayout`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Decoded {
    /// The image's fields (none for raw bytes, or when the size does not fit).
    pub fields: Vec<Field>,
    /// The status byte and freshness counter, with assembly 101.
    pub link: Option<LinkView>,
    /// Why the data is shown raw although a description was given.
    pub note: Option<String>,
}

/// Options of `monitor`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MonitorOptions {
    /// Bring-up options (polls are ignored: monitor polls itself).
    pub connect: ConnectOptions,
    /// Stop after this many samples.
    pub count: Option<u64>,
    /// Stop after this much bus time of monitoring.
    pub duration: Option<Duration>,
    /// Refresh in place (terminal) instead of a line per sample.
    pub in_place: bool,
    /// Report a lost connection and get it back instead of stopping (`--reconnect`).
    pub reconnect: bool,
    /// How the poll response is decoded.
    pub layout: InputLayout,
    /// The I/O connection (`--io`): poll, or samples from bit-strobe responses or COS/cyclic
    /// productions.
    pub io: IoOptions,
}

/// How often `--reconnect` tries to get a lost connection back.
pub const RECONNECT_INTERVAL: Duration = Duration::from_secs(1);

/// The poll connection as the device set it up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PollSetup {
    produced: u16,
    consumed: u16,
    epr: Duration,
}

/// `true` for the failures `--reconnect` rides out: the bus failed, or the device did not answer.
fn is_connection_loss(e: &MasterError) -> bool {
    matches!(e, MasterError::Bus(_) | MasterError::Timeout { .. })
}

/// Marks the last frame from the device, an error response the reconnection expected, as fine.
fn accept_last_answer(master: &mut Master<'_, '_>, note: &str) {
    if let Some(i) = master.session.records().iter().rposition(|r| r.origin == can_io::bus::Origin::Remote) {
        master.session.set_verdict(i, Verdict::Ok(note.into()));
    }
}

/// One attempt to get a strobe, COS or cyclic connection back: explicit through the Group 2 Only
/// port (or the one still held), the connection released if left over, allocated and configured
/// again.
fn reestablish_io(
    master: &mut Master<'_, '_>,
    target: MacId,
    epr_ms: u16,
    io: &IoOptions,
) -> Result<PollSetup, MasterError> {
    master.end_io();
    match master.allocate(target, Port::Group2Only, AllocationChoice::EXPLICIT) {
        Ok(_) => {}
        Err(MasterError::ErrorResponse { general: GeneralStatus::AlreadyInRequestedState, .. }) => {
            accept_last_answer(master, "explicit connection still allocated to this master");
        }
        Err(e) => return Err(e),
    }
    match master.release(target, io.kind.choice()) {
        Ok(()) => {}
        Err(MasterError::ErrorResponse { .. }) => accept_last_answer(master, "no I/O connection left over"),
        Err(e) => return Err(e),
    }
    master.establish_io(target, epr_ms, io)?;
    let c = master.io_connection().ok_or(UsageError::NoIoConnection)?;
    Ok(PollSetup {
        produced: c.produced,
        consumed: c.consumed,
        epr: Duration::from_millis(u64::from(c.epr_ms.max(1))),
    })
}

/// One attempt to get the connections back (see the [module docs](self)).
fn reestablish(master: &mut Master<'_, '_>, target: MacId, epr_ms: u16) -> Result<PollSetup, MasterError> {
    match master.allocate(target, Port::Group2Only, AllocationChoice::EXPLICIT) {
        Ok(_) => {}
        Err(MasterError::ErrorResponse { general: GeneralStatus::AlreadyInRequestedState, .. }) => {
            accept_last_answer(master, "explicit connection still allocated to this master");
        }
        Err(e) => return Err(e),
    }
    match master.release(target, AllocationChoice::POLL) {
        Ok(()) => {}
        Err(MasterError::ErrorResponse { .. }) => accept_last_answer(master, "no poll connection left over"),
        Err(e) => return Err(e),
    }
    master.allocate(target, Port::Explicit, AllocationChoice::POLL)?;
    let produced = master.get_u16(target, class::CONNECTION, 2, 7)?.unwrap_or(0);
    let consumed = master.get_u16(target, class::CONNECTION, 2, 8)?.unwrap_or(0);
    let (data, _) = master.set(target, class::CONNECTION, 2, 9, &epr_ms.to_le_bytes())?;
    let applied = match data.as_slice() {
        [a, b] => u16::from_le_bytes([*a, *b]),
        _ => epr_ms,
    };
    Ok(PollSetup { produced, consumed, epr: Duration::from_millis(u64::from(applied.max(1))) })
}

/// Waits until `deadline` on a bus that may be failing: errors are ridden out, with a short real
/// pause so a bus that fails at once every time is not spun on; a stop asked for ends the wait.
fn wait_through_errors(master: &mut Master<'_, '_>, deadline: Instant) -> Result<(), MasterError> {
    while master.session.now() < deadline {
        match master.idle_until(deadline) {
            Ok(()) => {}
            Err(e @ MasterError::Interrupted { .. }) => return Err(e),
            Err(_) => std::thread::sleep(std::time::Duration::from_millis(20)),
        }
    }
    Ok(())
}

/// Tries every [`RECONNECT_INTERVAL`] to get the I/O connection of `opts` back (see the
/// [module docs](self)) until it is, or until `end`; the connection and the attempts it took, or
/// `None` (said on `out`) when the run ended first. A stop asked for ends the wait.
fn get_back(
    master: &mut Master<'_, '_>,
    opts: &MonitorOptions,
    end: Option<Instant>,
    out: &mut dyn Write,
) -> Result<Option<(PollSetup, u32)>, HarnessError> {
    let target = opts.connect.target;
    let epr_ms = opts.connect.epr_ms;
    let mut attempts = 0u32;
    loop {
        attempts += 1;
        let tried = master.session.now();
        if end.is_some_and(|e| tried > e) {
            writeln!(out, "not reconnected before the end of the run")
                .map_err(|source| HarnessError::Write { path: "the output".into(), source })?;
            return Ok(None);
        }
        let again = match opts.io.kind {
            IoKind::Poll => reestablish(master, target, epr_ms),
            _ => reestablish_io(master, target, epr_ms, &opts.io),
        };
        match again {
            Ok(s) => return Ok(Some((s, attempts))),
            Err(e) if is_connection_loss(&e) || matches!(e, MasterError::ErrorResponse { .. }) => {
                wait_through_errors(master, tried + RECONNECT_INTERVAL)?;
            }
            Err(e) => return Err(e.into()),
        }
    }
}

/// One sample.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Sample {
    /// Bus time, microseconds.
    pub time_us: u64,
    /// The image's fields, decoded by the device's profile (empty for raw bytes).
    pub fields: Vec<Field>,
    /// The status byte and the freshness counter, when the assembly carries them.
    pub link: Option<LinkView>,
    /// The status byte says link timeout: the data is held or cleared, not live.
    pub stale: bool,
    /// Why the data is not decoded although a description was given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
    /// The raw input data.
    pub raw: Vec<u8>,
}

impl Sample {
    /// The sample taken at `time_us` of `raw`, decoded by `layout`.
    #[must_use]
    pub fn new(time_us: u64, raw: Vec<u8>, layout: &InputLayout) -> Sample {
        let d = layout.decode(&raw);
        Sample {
            time_us,
            stale: d.link.is_some_and(|l| l.stale()),
            fields: d.fields,
            link: d.link,
            note: d.note,
            raw,
        }
    }

    /// The field called `name`.
    #[must_use]
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }
}

/// The CSV header written by `--csv` for `layout`.
pub fn csv_header(layout: &InputLayout) -> String {
    let mut columns = vec!["time_s".to_string()];
    columns.extend(layout.field_columns());
    columns.extend(["status", "freshness", "stale", "raw"].map(String::from));
    columns.join(",")
}

/// One CSV line for a sample, with the columns of [`csv_header`].
#[must_use]
pub fn csv_line(s: &Sample, layout: &InputLayout) -> String {
    let raw = master_core::decode::hex(&s.raw).replace(' ', "");
    let mut cells = vec![format!("{}.{:06}", s.time_us / 1_000_000, s.time_us % 1_000_000)];
    let width = layout.field_columns().len();
    let mut values: Vec<String> = match layout.profile {
        ImageProfile::Breaker => s
            .fields
            .iter()
            .map(|f| match f.name.as_str() {
                "switch" => f.text.clone(),
                _ => f.values.first().map(ToString::to_string).unwrap_or_default(),
            })
            .collect(),
        _ => s.fields.iter().flat_map(|f| f.values.iter().map(ToString::to_string)).collect(),
    };
    values.resize(width, String::new());
    cells.extend(values);
    match &s.link {
        Some(l) => cells.extend([
            format!("0x{:02X}", l.status),
            l.freshness.to_string(),
            if l.stale() { "1" } else { "0" }.to_string(),
        ]),
        None => cells.extend([String::new(), String::new(), String::new()]),
    }
    cells.push(raw);
    cells.join(",")
}

/// Bus time in seconds with milliseconds: `5.100s`.
fn seconds_text(us: u64) -> String {
    format!("{}.{:03}s", us / 1_000_000, (us / 1000) % 1000)
}

/// The line shown for a sample.
#[must_use]
pub fn display_line(s: &Sample, layout: &InputLayout) -> String {
    let t = seconds_text(s.time_us);
    let hex = master_core::decode::hex(&s.raw);
    let data = match (&layout.profile, &s.note) {
        (_, Some(note)) => format!("{hex} ({note})"),
        (ImageProfile::Breaker, None) if s.fields.len() == 5 => {
            let v = |i: usize| s.fields[i].values.first().copied().unwrap_or(0);
            format!(
                "A {:>3} A  B {:>3} A  C {:>3} A  N {:>3} A  switch {}",
                v(0),
                v(1),
                v(2),
                v(3),
                s.fields[4].text
            )
        }
        (ImageProfile::Raw, None) => hex,
        (_, None) => s.fields.iter().map(|f| f.text.clone()).collect::<Vec<_>>().join("  "),
    };
    match &s.link {
        Some(l) => format!("{t:>10}  {data}  | {}", l.text()),
        None => format!("{t:>10}  {data}"),
    }
}

/// What a monitor run took, and how it ended.
#[derive(Debug)]
pub struct MonitorRun {
    /// Every sample taken, also those before a failure or an interruption.
    pub samples: Vec<Sample>,
    /// `None` when the run reached its `--count` or `--duration`; else what ended it (a failure,
    /// or [`MasterError::Interrupted`] when SIGINT / SIGTERM asked for a stop).
    pub ended: Option<HarnessError>,
}

/// Brings the device up and monitors it. Samples are shown on `out` (the progress line cleared
/// first) and written to `csv`, each row flushed as it is taken. The samples are returned however
/// the run ended.
pub fn monitor(
    master: &mut Master<'_, '_>,
    opts: &MonitorOptions,
    out: &mut dyn Write,
    csv: Option<&mut dyn Write>,
    progress: &mut Progress<'_>,
) -> MonitorRun {
    let mut samples = Vec::new();
    let mut shown = false;
    let r = run(master, opts, out, csv, progress, &mut samples, &mut shown);
    if opts.in_place && shown {
        // The refreshed line is ended however the run ended, so what follows starts on its own.
        let _ = writeln!(out);
    }
    MonitorRun { samples, ended: r.err() }
}

fn run(
    master: &mut Master<'_, '_>,
    opts: &MonitorOptions,
    out: &mut dyn Write,
    mut csv: Option<&mut dyn Write>,
    progress: &mut Progress<'_>,
    samples: &mut Vec<Sample>,
    shown: &mut bool,
) -> Result<(), HarnessError> {
    let target = opts.connect.target;
    let mut connect = opts.connect.clone();
    connect.polls = 0;
    connect.verify_state = false;
    let write_err = |source| HarnessError::Write { path: "the output".into(), source };
    let csv_err = |source| HarnessError::Write { path: "the CSV file".into(), source };
    // The header first: a run stopped or failed before its first sample still leaves a CSV file
    // a reader can take.
    if let Some(w) = csv.as_deref_mut() {
        writeln!(w, "{}", csv_header(&opts.layout)).map_err(csv_err)?;
        w.flush().map_err(csv_err)?;
    }
    let kind = opts.io.kind;
    let begun = master.session.now();
    let (mut setup, consumed, start, end) = match master.connect_io(&connect, &opts.io) {
        Ok(summary) => {
            progress.clear();
            let consumed = summary.consumed_size.unwrap_or(0);
            let epr_ms = summary.expected_packet_rate_ms.unwrap_or(connect.epr_ms).max(1);
            let setup = PollSetup {
                produced: summary.produced_size.unwrap_or(0),
                consumed,
                epr: Duration::from_millis(u64::from(epr_ms)),
            };
            let start = master.session.now();
            (setup, consumed, start, opts.duration.map(|d| start + d))
        }
        // The master is on-line and the device does not answer: `--reconnect` waits for it, within
        // the run's --duration counted from the start.
        Err(e) if opts.reconnect && is_connection_loss(&e) && master.online_at().is_some() => {
            progress.clear();
            writeln!(out, "MAC {target} does not answer: {e}; waiting for it (--reconnect)")
                .map_err(write_err)?;
            let end = opts.duration.map(|d| begun + d);
            let Some((setup, attempts)) = get_back(master, opts, end, out)? else {
                return Ok(());
            };
            let start = master.session.now();
            writeln!(out, "connected at {} after {attempts} attempt(s)", seconds_text(start.total_micros()))
                .map_err(write_err)?;
            (setup, setup.consumed, start, end)
        }
        Err(e) => return Err(e.into()),
    };
    let output = connect.output.clone().unwrap_or_else(|| vec![0; usize::from(consumed)]);
    let mut next = start;
    loop {
        if opts.count.is_some_and(|c| samples.len() as u64 >= c) || end.is_some_and(|e| next > e) {
            break;
        }
        let timeout = if setup.epr > MIN_POLL_TIMEOUT { setup.epr } else { MIN_POLL_TIMEOUT };
        let mut polled = master.session.now();
        let cycle = match kind {
            IoKind::Poll => master.idle_until(next).and_then(|()| {
                polled = master.session.now();
                master.poll(target, &output, setup.produced, setup.consumed, timeout)
            }),
            IoKind::Strobe => master.idle_until(next).and_then(|()| {
                polled = master.session.now();
                master.strobe()
            }),
            // The device produces on its own schedule: the sample is its production, then the
            // master's data goes out (Connection 2, when the device consumes any).
            IoKind::ChangeOfState | IoKind::Cyclic => master.await_production().and_then(|input| {
                polled = master.session.now();
                if setup.consumed > 0 {
                    master.send_output(&output)?;
                }
                Ok(input)
            }),
        };
        let raw = match cycle {
            Ok(raw) => raw,
            Err(e) if opts.reconnect && is_connection_loss(&e) => {
                let lost = master.session.now();
                let at = |t: Instant| seconds_text(t.total_micros());
                writeln!(
                    out,
                    "{}connection lost at {}: {e}",
                    if opts.in_place && *shown { "\n" } else { "" },
                    at(lost)
                )
                .map_err(write_err)?;
                *shown = false;
                let Some((again, attempts)) = get_back(master, opts, end, out)? else {
                    return Ok(());
                };
                setup = again;
                let back = master.session.now();
                writeln!(out, "reconnected at {} after {attempts} attempt(s)", at(back))
                    .map_err(write_err)?;
                next = back;
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        let sample = Sample::new(polled.total_micros(), raw, &opts.layout);
        if let Some(w) = csv.as_deref_mut() {
            // Flushed row by row: a reader tailing the file sees every sample as it is taken.
            writeln!(w, "{}", csv_line(&sample, &opts.layout)).map_err(csv_err)?;
            w.flush().map_err(csv_err)?;
        }
        if opts.in_place {
            write!(out, "\r\x1b[2K{}", display_line(&sample, &opts.layout)).map_err(write_err)?;
        } else {
            writeln!(out, "{}", display_line(&sample, &opts.layout)).map_err(write_err)?;
        }
        out.flush().map_err(write_err)?;
        *shown = true;
        samples.push(sample);
        next = polled + setup.epr;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use can_io::bus::Bus;
    use devicenet::reference::INPUT_IMAGE;

    #[test]
    fn reference_image_is_an_open_breaker() {
        let s = BreakerStatus::decode(&INPUT_IMAGE).unwrap();
        assert_eq!(s.currents, [0; 4]);
        assert_eq!(s.switch_text(), "open");
        assert_eq!(BreakerStatus::decode(&[0; 9]), None);
    }

    /// A bus whose interface goes down between `from` and `until`: sending fails, the first read
    /// reports the error (as a SocketCAN socket does with ENETDOWN), frames do not pass.
    struct Outage {
        inner: can_io::sim::SimBus,
        from: Instant,
        until: Instant,
        reported: bool,
    }

    impl Outage {
        fn down(&mut self) -> bool {
            let now = self.inner.now();
            now >= self.from && now < self.until
        }
        fn error() -> can_io::bus::BusError {
            can_io::bus::BusError::Io {
                what: "sim0".into(),
                source: std::io::Error::other("network is down"),
            }
        }
    }

    impl can_io::bus::Bus for Outage {
        fn name(&self) -> &str {
            "sim0"
        }
        fn now(&mut self) -> Instant {
            self.inner.now()
        }
        fn send(&mut self, frame: &devicenet::CanFrame) -> Result<(), can_io::bus::BusError> {
            if self.down() {
                return Err(Outage::error());
            }
            self.inner.send(frame)
        }
        fn recv(
            &mut self,
            deadline: Instant,
        ) -> Result<Option<can_io::bus::BusEvent>, can_io::bus::BusError> {
            if self.down() && !std::mem::replace(&mut self.reported, true) {
                return Err(Outage::error());
            }
            self.inner.recv(deadline)
        }
    }

    fn monitor_through_outage(reconnect: bool) -> (MonitorRun, String, usize) {
        use can_io::sim::{PowerOn, SimBus};
        let mut sim = SimBus::new(can_io::bus::Bitrate::K250);
        sim.attach(
            Box::new(converter_sim::device::SoftSlave::reference(MacId::from_low_bits(5))),
            PowerOn::WhenMasterOnline,
        );
        let mut bus =
            Outage { inner: sim, from: Instant::from_secs(7), until: Instant::from_secs(9), reported: false };
        let mut session = master_core::session::Session::new(&mut bus);
        let mut master = Master::new(&mut session, master_core::master::MasterConfig::default());
        let opts = MonitorOptions {
            connect: ConnectOptions::default(),
            count: None,
            duration: Some(Duration::from_secs(8)),
            in_place: false,
            reconnect,
            layout: InputLayout::from_converter(&ConverterConfig::breaker_reference()),
            io: IoOptions::default(),
        };
        let mut out = Vec::new();
        let r = monitor(&mut master, &opts, &mut out, None, &mut Progress::off());
        let failures = master.session.failures();
        (r, String::from_utf8_lossy(&out).into_owned(), failures)
    }

    #[test]
    fn reconnect_rides_out_an_outage() {
        let (r, out, failures) = monitor_through_outage(true);
        assert!(r.ended.is_none(), "{:?}", r.ended);
        let samples = r.samples;
        assert!(out.contains("connection lost at 7."), "{out}");
        assert!(out.contains("reconnected at 9."), "{out}");
        let after = samples.iter().filter(|s| s.time_us > 9_000_000).count();
        assert!(after > 20, "polling goes on after the outage: {after} samples\n{out}");
        assert!(samples.iter().all(|s| s.raw == INPUT_IMAGE), "{out}");
        assert_eq!(failures, 0, "{out}");
    }

    #[test]
    fn without_reconnect_the_loss_ends_the_run() {
        let (r, out, _) = monitor_through_outage(false);
        let e = r.ended.unwrap();
        assert!(!r.samples.is_empty(), "the samples before the loss are kept");
        assert!(matches!(e, HarnessError::Master(MasterError::Bus(_))), "{e}");
        assert!(!out.contains("connection lost"), "{out}");
    }

    fn breaker() -> InputLayout {
        InputLayout::from_converter(&ConverterConfig::breaker_reference())
    }

    fn meter() -> InputLayout {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../slave-fw/descriptions/modbus-meter.toml");
        InputLayout::from_converter(
            &slave_fw::description::DeviceDescription::load(path.as_ref()).unwrap().converter,
        )
    }

    #[test]
    fn csv_lines() {
        let layout = breaker();
        assert_eq!(
            csv_header(&layout),
            "time_s,phase_a,phase_b,phase_c,neutral,switch,status,freshness,stale,raw"
        );
        let s = Sample::new(5_100_000, INPUT_IMAGE.to_vec(), &layout);
        assert_eq!(csv_line(&s, &layout), "5.100000,0,0,0,0,open,,,,0000000000000000000F0000000000000000");
        let short = Sample::new(1, vec![1, 2], &layout);
        assert_eq!(csv_line(&short, &layout), "0.000001,,,,,,,,,0102");
        assert_eq!(short.note.as_deref(), Some("2 bytes; the description produces 18"));
        let raw = InputLayout::raw();
        assert_eq!(csv_header(&raw), "time_s,status,freshness,stale,raw");
        assert_eq!(csv_line(&Sample::new(1, vec![1, 2], &raw), &raw), "0.000001,,,,0102");
    }

    #[test]
    fn breaker_with_status_names_the_status_byte() {
        let mut config = ConverterConfig::breaker_reference();
        config.input = InputAssembly::WithStatus;
        let layout = InputLayout::from_converter(&config);
        assert_eq!(layout.produced_size(), Some(20));
        let mut raw = INPUT_IMAGE.to_vec();
        raw.extend([0x21, 7]);
        let s = Sample::new(2_000_000, raw.clone(), &layout);
        assert!(!s.stale);
        assert_eq!(
            display_line(&s, &layout),
            "    2.000s  A   0 A  B   0 A  C   0 A  N   0 A  switch open  | link ok, command ok, freshness 7"
        );
        raw[18] = 0x06;
        let s = Sample::new(2_000_000, raw, &layout);
        assert!(s.stale);
        let line = display_line(&s, &layout);
        assert!(line.ends_with("| STALE: LINK TIMEOUT, errors seen, command none, freshness 7"), "{line}");
        assert!(csv_line(&s, &layout).ends_with(",open,0x06,7,1,0000000000000000000F00000000000000000607"));
    }

    #[test]
    fn modbus_fields_follow_the_scan_list() {
        let layout = meter();
        assert_eq!(layout.produced_size(), Some(14));
        assert_eq!(
            layout.field_columns(),
            ["u1:30001", "u1:30002", "u1:30003", "u1:30004", "u1:40101", "u1:40102"]
        );
        // Little-endian registers: 230 = 0x00E6, 231 = 0x00E7; status: link ok, request unanswered.
        let raw = vec![1, 0, 2, 0, 3, 0, 0x10, 0x27, 0xE6, 0, 0xE7, 0, 0x81, 3];
        let s = Sample::new(0, raw, &layout);
        let line = display_line(&s, &layout);
        assert!(line.contains("u1 fc4 @30001+4: 1, 2, 3, 10000  u1 fc3 @40101+2: 230, 231"), "{line}");
        assert!(line.ends_with("| link ok, request unanswered, command none, freshness 3"), "{line}");
        assert!(!line.contains("switch"), "{line}");
        let mut be = layout.clone();
        if let ImageProfile::Modbus { byte_order, .. } = &mut be.profile {
            *byte_order = ByteOrder::BigEndian;
        }
        let s = Sample::new(0, s.raw, &be);
        assert_eq!(s.field("u1 fc3 @40101+2").unwrap().values, [0xE600, 0xE700]);
    }

    #[test]
    fn modbus_bits_and_references() {
        let coils = ScanEntry {
            unit: 2,
            function: Function::ReadCoils,
            address: 9,
            count: 10,
            offset: 0,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        };
        let f = modbus_field(&coils, ByteOrder::LittleEndian, &[0b1000_0101, 0b10]);
        assert_eq!(f.text, "u2 fc1 @00010+10: 1, 0, 1, 0, 0, 0, 0, 1, 0, 1");
        let far = ScanEntry {
            unit: 1,
            function: Function::ReadHoldingRegisters,
            address: 9999,
            count: 1,
            offset: 0,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        };
        assert_eq!(modbus_ref(&far, 0), "410000");
    }
}
