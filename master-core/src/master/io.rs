//! The I/O connections of issue 14 next to poll: bit-strobe (Connection 3), change of state and
//! cyclic (Connection 4) with the Acknowledge Handler, as `docs/src/reference/io-connections.md`
//! and the notes
//! (§1.2, §1.3, §4.2, §II.1, §II.2) describe them, each frame checked.
//!
//! | kind | allocation | the master sends | the device answers |
//! |---|---|---|---|
//! | [`IoKind::Strobe`] | 0x04 (Connection 3) | 8-byte bit-strobe on `0x400 \| master << 3`, the device's bit = byte `MAC / 8`, bit `MAC % 8` | `0x380 \| MAC`, the first `min(P, 8)` input bytes, never fragmented |
//! | [`IoKind::ChangeOfState`], [`IoKind::Cyclic`] | 0x10 / 0x20, + 0x40 to suppress acknowledgements (Connection 4; Connection 2 consumes the master's data) | a zero-length acknowledgement on `0x402 \| MAC << 3` after each production (not when suppressed); its output on `0x400 \| MAC << 3 \| 5` | the input on `0x340 \| MAC` (I/O-fragmented when over 8 bytes); a zero-length acknowledgement of the master's data on `0x3C0 \| MAC` (not when suppressed) |
//!
//! ## What is checked
//!
//! - the connection's attributes against the identifiers and sizes on the wire: produced and
//!   consumed connection IDs (attributes 4, 5) and sizes (7, 8);
//! - every frame's identifier and length: a strobe response of exactly attribute 7 bytes, a
//!   production reassembled to attribute 7 bytes with 7 data bytes a fragment, acknowledgements
//!   of zero length, none under acknowledge suppression;
//! - timing ([`IoOptions::judge_timing`]): a cyclic connection produces every EPR, a COS
//!   connection at the latest every EPR (and not sooner than its production inhibit time after
//!   the previous production), the first production at the latest one EPR after the Set EPR;
//!   the tolerance is max(EPR / 5, 20 ms) ([`timing_tolerance`]);
//! - a series sent again with the same data within the acknowledge timer (+ 50 ms, at most half
//!   an EPR) after one the master acknowledged late is a re-send (the Acknowledge Handler,
//!   §II.2.4), counted and not judged; after a timely acknowledgement the same data again is a
//!   production of its own, and its interval is judged (a cyclic connection that re-sends
//!   although acknowledged fails the EPR).

use super::{Master, MIN_POLL_TIMEOUT};
use crate::decode::{self, hex};
use crate::error::{MasterError, UsageError};
use crate::session::Verdict;
use can_io::bus::Origin;
use devicenet::fragment::{io_fragments, IoFragment, IoReassembler};
use devicenet::id::Group1MessageId;
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::{CanFrame, CanId, Duration, Group2Message, Identifier, Instant, MacId};
use std::collections::VecDeque;

/// The Acknowledge Handler object (class 0x2B, protocol §II.2.4).
pub const ACKNOWLEDGE_HANDLER: u16 = 0x2B;

/// The device's default acknowledge timer when the master did not read it (protocol §II.2.4: 16 ms).
pub const DEFAULT_ACK_TIMER_MS: u16 = 16;

/// The kind of I/O connection `connect --io` and `monitor --io` bring up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum IoKind {
    /// Polled I/O, Connection 2 (the reference bring-up of protocol §2).
    #[default]
    Poll,
    /// Bit-strobed I/O, Connection 3 (protocol §II.1).
    Strobe,
    /// Change of state, Connection 4 (protocol §II.2).
    ChangeOfState,
    /// Cyclic, Connection 4 (protocol §II.2).
    Cyclic,
}

impl IoKind {
    /// Every kind, in the order of the allocation bits.
    pub const ALL: [IoKind; 4] = [IoKind::Poll, IoKind::Strobe, IoKind::ChangeOfState, IoKind::Cyclic];

    /// The allocation choice bit of the connection (protocol §3.4).
    pub const fn choice(self) -> AllocationChoice {
        match self {
            IoKind::Poll => AllocationChoice::POLL,
            IoKind::Strobe => AllocationChoice::BIT_STROBE,
            IoKind::ChangeOfState => AllocationChoice::CHANGE_OF_STATE,
            IoKind::Cyclic => AllocationChoice::CYCLIC,
        }
    }

    /// The Connection object instance (protocol §5: 2 poll, 3 bit-strobe, 4 COS/cyclic).
    pub const fn instance(self) -> u16 {
        match self {
            IoKind::Poll => 2,
            IoKind::Strobe => 3,
            IoKind::ChangeOfState | IoKind::Cyclic => 4,
        }
    }

    /// The name on the command line: `poll`, `strobe`, `cos`, `cyclic`.
    pub const fn name(self) -> &'static str {
        match self {
            IoKind::Poll => "poll",
            IoKind::Strobe => "strobe",
            IoKind::ChangeOfState => "cos",
            IoKind::Cyclic => "cyclic",
        }
    }

    /// `true` for change of state and cyclic (Connection 4).
    pub const fn is_cos_cyclic(self) -> bool {
        matches!(self, IoKind::ChangeOfState | IoKind::Cyclic)
    }
}

impl std::fmt::Display for IoKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for IoKind {
    type Err = String;
    fn from_str(s: &str) -> Result<IoKind, String> {
        match s {
            "poll" => Ok(IoKind::Poll),
            "strobe" | "bit-strobe" => Ok(IoKind::Strobe),
            "cos" | "change-of-state" => Ok(IoKind::ChangeOfState),
            "cyclic" => Ok(IoKind::Cyclic),
            other => Err(format!("'{other}': expected poll, strobe, cos or cyclic")),
        }
    }
}

/// How the I/O connection is brought up and judged (`connect --io`, `monitor --io`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IoOptions {
    /// The connection (`--io`, default poll).
    pub kind: IoKind,
    /// Allocate with acknowledge suppression, 0x40 (`--ack-suppression`, COS and cyclic only).
    pub ack_suppression: bool,
    /// Production inhibit time to set, Connection 4 attribute 17, ms (`--inhibit`); `None`: the
    /// device's own (0 after allocation).
    pub inhibit_ms: Option<u16>,
    /// Acknowledge timer to set, Acknowledge Handler attribute 1, ms (`--ack-timer`); `None`: the
    /// device's own (read back).
    pub ack_timer_ms: Option<u16>,
    /// Retry limit to set, Acknowledge Handler attribute 2 (`--retry-limit`); `None`: the
    /// device's own (read back).
    pub retry_limit: Option<u8>,
    /// Judge the production intervals: `false` where the bus's timestamps do not show the
    /// device's timing (SLCAN buffers frames on a serial line), the intervals are then noted only.
    pub judge_timing: bool,
}

impl Default for IoOptions {
    fn default() -> Self {
        IoOptions {
            kind: IoKind::Poll,
            ack_suppression: false,
            inhibit_ms: None,
            ack_timer_ms: None,
            retry_limit: None,
            judge_timing: true,
        }
    }
}

impl IoOptions {
    /// Options for `kind` with the defaults otherwise.
    pub fn of(kind: IoKind) -> IoOptions {
        IoOptions { kind, ..IoOptions::default() }
    }

    /// The allocation choice for the I/O connection (the explicit connection is allocated first).
    pub fn choice(&self) -> AllocationChoice {
        let c = self.kind.choice();
        if self.ack_suppression {
            c | AllocationChoice::ACK_SUPPRESSION
        } else {
            c
        }
    }

    /// Refuses options that contradict each other.
    pub fn validate(&self) -> Result<(), MasterError> {
        let cos = self.kind.is_cos_cyclic();
        let misplaced = [
            (self.ack_suppression && !cos, "--ack-suppression"),
            (self.ack_timer_ms.is_some() && !cos, "--ack-timer"),
            (self.retry_limit.is_some() && !cos, "--retry-limit"),
            (self.inhibit_ms.is_some() && !cos, "--inhibit"),
        ];
        if let Some((_, flag)) = misplaced.iter().find(|(m, _)| *m) {
            return Err(UsageError::CosOptionMisplaced { flag, kind: self.kind.to_string() }.into());
        }
        if self.ack_suppression && (self.ack_timer_ms.is_some() || self.retry_limit.is_some()) {
            return Err(UsageError::AckSettingsSuppressed.into());
        }
        if self.ack_timer_ms == Some(0) {
            return Err(UsageError::AckTimerZero.into());
        }
        Ok(())
    }
}

/// The timing tolerance for an EPR: max(EPR / 5, 20 ms).
pub fn timing_tolerance(epr: Duration) -> Duration {
    let fifth = Duration::from_micros(epr.total_micros() / 5);
    let floor = Duration::from_millis(20);
    if fifth > floor {
        fifth
    } else {
        floor
    }
}

/// What the I/O connection is and what it did, for the report (JSON `device.io`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct IoSummary {
    /// The connection kind.
    pub kind: IoKind,
    /// Acknowledge suppression allocated.
    pub ack_suppression: bool,
    /// The Connection instance.
    pub instance: u16,
    /// Attribute 4, the produced connection ID.
    pub produced_id: Option<u16>,
    /// Attribute 5, the consumed connection ID.
    pub consumed_id: Option<u16>,
    /// COS/cyclic: the size of the master's data (Connection 2 attribute 8).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub output_size: Option<u16>,
    /// COS: the production inhibit time, ms (attribute 17).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inhibit_time_ms: Option<u16>,
    /// Acknowledged COS/cyclic: the acknowledge timer, ms (Acknowledge Handler attribute 1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ack_timer_ms: Option<u16>,
    /// Acknowledged COS/cyclic: the retry limit (Acknowledge Handler attribute 2).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub retry_limit: Option<u8>,
    /// Strobe responses received.
    pub strobe_responses: u32,
    /// COS/cyclic productions received (re-sends not counted).
    pub productions: u32,
    /// Productions sent again by the device (not acknowledged in time).
    pub re_sent: u32,
    /// Acknowledgements the master sent.
    pub acks_sent: u32,
    /// The master's COS/cyclic data sent.
    pub outputs_sent: u32,
    /// Acknowledgements of the master's data received.
    pub outputs_acknowledged: u32,
    /// The shortest interval between two productions, ms.
    pub interval_min_ms: Option<f64>,
    /// The longest interval between two productions, ms.
    pub interval_max_ms: Option<f64>,
}

/// An I/O connection as the device set it up, and the state of the exchange on it.
#[derive(Clone, Debug)]
pub struct IoConnection {
    /// The device.
    pub target: MacId,
    /// How it was brought up.
    pub options: IoOptions,
    /// The input size: attribute 7 of the I/O connection (poll 2, strobe 3, COS/cyclic 4).
    pub produced: u16,
    /// What the master sends: poll attribute 8, strobe 8, COS/cyclic Connection 2 attribute 8.
    pub consumed: u16,
    /// The EPR the device applied, ms (the one requested until the Set EPR response is judged).
    pub epr_ms: u16,
    /// When the master sent the Set EPR request, on which the device establishes the connection.
    pub established_at: Instant,
    /// Counters and attributes for the report.
    pub summary: IoSummary,
    /// Productions complete but not yet handed out (they came while the master waited for
    /// something else).
    pending: VecDeque<Vec<u8>>,
    /// The reassembly of the production in progress.
    series: IoSeries,
    /// Start (first fragment) and data of the last production, and when the master acknowledged it.
    last: Option<(Instant, Vec<u8>, Option<Instant>)>,
    /// When the master's data went out, while its acknowledgement is awaited.
    output_pending: Option<Instant>,
    /// The first frame of the series in progress.
    series_start: Option<Instant>,
    /// Given back by [`Master::resume_io`] at this time: the first production is timed from it.
    resumed: Option<Instant>,
    /// Given back, and no production begun since: fragments before the next first fragment end a
    /// production the master did not see begin.
    resync: bool,
}

impl IoConnection {
    fn epr(&self) -> Duration {
        Duration::from_millis(u64::from(self.epr_ms.max(1)))
    }

    fn acked(&self) -> bool {
        !self.options.ack_suppression
    }

    /// How long the master waits for a strobe response or its data's acknowledgement: the EPR,
    /// at least [`MIN_POLL_TIMEOUT`].
    pub fn response_timeout(&self) -> Duration {
        let epr = self.epr();
        if epr > MIN_POLL_TIMEOUT {
            epr
        } else {
            MIN_POLL_TIMEOUT
        }
    }

    /// How long the master waits for the next production: 2 × EPR + the tolerance, so a late
    /// one is still seen and judged.
    pub fn production_timeout(&self) -> Duration {
        let epr = self.epr();
        epr + epr + timing_tolerance(epr)
    }

    fn note_interval(&mut self, ms: f64) {
        let s = &mut self.summary;
        s.interval_min_ms = Some(s.interval_min_ms.map_or(ms, |m| m.min(ms)));
        s.interval_max_ms = Some(s.interval_max_ms.map_or(ms, |m| m.max(ms)));
    }
}

/// One I/O message coming in frame by frame (a poll response, a COS/cyclic production): whole in
/// one frame up to 8 bytes, else I/O fragments (protocol §4.2), each checked against the size.
#[derive(Clone, Debug)]
pub(crate) struct IoSeries {
    produced: u16,
    left: usize,
    rx: Box<IoReassembler<{ decode::MAX_IO_MESSAGE }>>,
}

/// What a frame of an [`IoSeries`] made of it.
pub(crate) enum SeriesStep {
    /// A fragment, in sequence; the message goes on.
    Fragment(Verdict),
    /// The whole message.
    Complete(Vec<u8>, Verdict),
    /// A fragment refused; the series starts over.
    Rejected(Verdict),
}

impl IoSeries {
    /// A series of `produced` bytes; `what` names the message in the verdicts.
    pub(crate) fn new(produced: u16) -> IoSeries {
        IoSeries { produced, left: usize::from(produced), rx: Box::new(IoReassembler::new()) }
    }

    /// Takes one frame's data; `what` names the message (`poll response`).
    pub(crate) fn take(&mut self, data: &[u8], what: &str) -> SeriesStep {
        let produced = self.produced;
        if produced <= 8 {
            let failures = if data.len() == usize::from(produced) {
                Vec::new()
            } else {
                vec![format!("DLC {}, expected the produced size {produced}", data.len())]
            };
            let v = Verdict::Ok(format!("{what}, {} bytes", data.len())).with_failures(failures);
            return SeriesStep::Complete(data.to_vec(), v);
        }
        let mut failures = Vec::new();
        if let Ok(frag) = IoFragment::parse(data) {
            let remaining = if frag.fragment.kind == devicenet::fragment::FragmentKind::First {
                usize::from(produced)
            } else {
                self.left
            };
            let want = 1 + remaining.min(7);
            if data.len() != want {
                failures.push(format!("DLC {}, expected {want} ({remaining} data bytes left)", data.len()));
            }
            self.left = remaining.saturating_sub(frag.data.len());
        }
        match self.rx.receive(data) {
            Ok(Some(whole)) => {
                let whole = whole.to_vec();
                if whole.len() != usize::from(produced) {
                    failures.push(format!(
                        "reassembled {} bytes, expected the produced size {produced}",
                        whole.len()
                    ));
                }
                self.left = usize::from(produced);
                let note = format!("last fragment; {} bytes reassembled", whole.len());
                SeriesStep::Complete(whole, Verdict::Ok(note).with_failures(failures))
            }
            Ok(None) => SeriesStep::Fragment(
                Verdict::Ok(format!("{what} fragment in sequence")).with_failures(failures),
            ),
            Err(e) => {
                failures.push(format!("fragment rejected: {e}"));
                self.left = usize::from(produced);
                SeriesStep::Rejected(Verdict::Fail(failures))
            }
        }
    }
}

/// The 8 data bytes of a bit-strobe command with the bit of `mac` set (protocol §II.1.2: byte
/// `MAC / 8`, bit `MAC % 8`).
pub fn strobe_data(mac: MacId) -> [u8; 8] {
    let mut d = [0u8; 8];
    let m = mac.as_raw();
    d[usize::from(m / 8)] = 1 << (m % 8);
    d
}

impl Master<'_, '_> {
    /// The identifier of the master's bit-strobe command (Group 2 message 0 with the master's
    /// MAC, protocol §1.2).
    pub fn strobe_id(&self) -> CanId {
        Identifier::group2(self.config.mac, Group2Message::BitStrobeCommand)
    }

    /// Reads a UINT attribute of Connection `instance` and checks it against `want`.
    fn expect_u16(
        &mut self,
        target: MacId,
        instance: u16,
        attr: u8,
        want: Option<u16>,
        what: &str,
    ) -> Result<Option<u16>, MasterError> {
        let value = self.get_u16(target, class::CONNECTION, instance, attr)?;
        if let (Some(v), Some(w)) = (value, want) {
            if v != w {
                let last = self.last_record;
                self.judge(last, "", vec![format!("{what} 0x{v:04X} ({v}), expected 0x{w:04X} ({w})")]);
            }
        }
        Ok(value)
    }

    /// Allocates and configures the I/O connection of `io` at `target`, whose explicit connection
    /// is allocated: Allocate through the explicit connection, its attributes read and checked
    /// (4, 5, 7, 8; for COS/cyclic also Connection 2's sizes), the production inhibit time and
    /// the Acknowledge Handler attributes set or read, then the EPR set (the connection is then
    /// established). Not for poll (the reference bring-up does poll, [`Master::connect`]).
    pub fn establish_io(&mut self, target: MacId, epr_ms: u16, io: &IoOptions) -> Result<(), MasterError> {
        io.validate()?;
        let kind = io.kind;
        if kind == IoKind::Poll {
            return Err(UsageError::PollIsConnects.into());
        }
        let inst = kind.instance();
        self.allocate(target, super::Port::Explicit, io.choice())?;
        let master = self.config.mac;
        let mut summary =
            IoSummary { kind, ack_suppression: io.ack_suppression, instance: inst, ..IoSummary::default() };
        let (produced, consumed) = match kind {
            IoKind::Strobe => {
                summary.produced_id = self.expect_u16(
                    target,
                    inst,
                    4,
                    Some(Identifier::group1(Group1MessageId::BIT_STROBE_RESPONSE, target).as_raw()),
                    "produced connection ID",
                )?;
                summary.consumed_id = self.expect_u16(
                    target,
                    inst,
                    5,
                    Some(Identifier::group2(master, Group2Message::BitStrobeCommand).as_raw()),
                    "consumed connection ID (the strobe of the owner's MAC)",
                )?;
                let produced = self.get_u16(target, class::CONNECTION, inst, 7)?.unwrap_or(0);
                if produced > 8 {
                    let last = self.last_record;
                    self.judge(
                        last,
                        "",
                        vec![format!(
                            "produced size {produced}: a strobe response carries at most 8 bytes (notes II.1.3)"
                        )],
                    );
                }
                self.expect_u16(target, inst, 8, Some(8), "consumed size (the strobe's 8 bytes)")?;
                (produced, 8)
            }
            _ => {
                summary.produced_id = self.expect_u16(
                    target,
                    inst,
                    4,
                    Some(Identifier::group1(Group1MessageId::COS_CYCLIC, target).as_raw()),
                    "produced connection ID",
                )?;
                let ack_id = if io.ack_suppression {
                    0xFFFF
                } else {
                    Identifier::group2(target, Group2Message::CosCyclicAck).as_raw()
                };
                summary.consumed_id =
                    self.expect_u16(target, inst, 5, Some(ack_id), "consumed connection ID")?;
                let produced = self.get_u16(target, class::CONNECTION, inst, 7)?.unwrap_or(0);
                self.expect_u16(target, inst, 8, Some(0), "consumed size (acknowledgements are empty)")?;
                // Connection 2 consumes the master's data and produces the zero-length
                // acknowledgement (§II.2.5, EAT).
                self.expect_u16(
                    target,
                    2,
                    7,
                    Some(0),
                    "Connection 2 produced size (the empty acknowledgement)",
                )?;
                let consumed = self.get_u16(target, class::CONNECTION, 2, 8)?.unwrap_or(0);
                summary.output_size = Some(consumed);
                if let Some(pit) = io.inhibit_ms {
                    let (data, i) = self.set(target, class::CONNECTION, inst, 17, &pit.to_le_bytes())?;
                    let note = format!("production inhibit time {pit} ms set");
                    let failures = match data.as_slice() {
                        [] => Vec::new(),
                        [a, b] if u16::from_le_bytes([*a, *b]) >= pit => Vec::new(),
                        other => vec![format!("Set inhibit time response data {}", hex(other))],
                    };
                    self.judge(i, &note, failures);
                    summary.inhibit_time_ms = Some(pit);
                } else if kind == IoKind::ChangeOfState {
                    summary.inhibit_time_ms = self.get_u16(target, class::CONNECTION, inst, 17)?;
                }
                if !io.ack_suppression {
                    if let Some(t) = io.ack_timer_ms {
                        let (_, i) = self.set(target, ACKNOWLEDGE_HANDLER, 1, 1, &t.to_le_bytes())?;
                        self.judge(i, &format!("acknowledge timer {t} ms set"), Vec::new());
                    }
                    if let Some(n) = io.retry_limit {
                        let (_, i) = self.set(target, ACKNOWLEDGE_HANDLER, 1, 2, &[n])?;
                        self.judge(i, &format!("retry limit {n} set"), Vec::new());
                    }
                    summary.ack_timer_ms = self.get_u16(target, ACKNOWLEDGE_HANDLER, 1, 1)?;
                    let (data, i) = self.get(target, ACKNOWLEDGE_HANDLER, 1, 2)?;
                    match data.as_slice() {
                        [n] => {
                            summary.retry_limit = Some(*n);
                            self.judge(i, &format!("retry limit {n}"), Vec::new());
                        }
                        other => {
                            self.judge(i, "", vec![format!("retry limit {}, a USINT has 1 byte", hex(other))])
                        }
                    }
                    for (want, got, what) in [
                        (io.ack_timer_ms, summary.ack_timer_ms, "acknowledge timer"),
                        (io.retry_limit.map(u16::from), summary.retry_limit.map(u16::from), "retry limit"),
                    ] {
                        if let (Some(w), Some(g)) = (want, got) {
                            if w != g {
                                let last = self.last_record;
                                self.judge(last, "", vec![format!("{what} reads {g}, {w} was set")]);
                            }
                        }
                    }
                }
                (produced, consumed)
            }
        };
        // The connection is the master's before the Set EPR goes out: the device establishes it on
        // that request and may produce before the response completes (a COS connection produces
        // at once, protocol §II.2.3), and the master judges the frames around the response only once
        // the exchange is over. They are the connection's frames, not unexpected ones.
        self.io = Some(IoConnection {
            target,
            options: io.clone(),
            produced,
            consumed,
            epr_ms,
            established_at: self.session.now(),
            summary,
            pending: VecDeque::new(),
            series: IoSeries::new(produced),
            last: None,
            output_pending: None,
            series_start: None,
            resumed: None,
            resync: false,
        });
        match self.set_epr(target, inst, epr_ms, kind) {
            Ok(applied) => {
                if let Some(conn) = &mut self.io {
                    conn.epr_ms = applied;
                }
                Ok(())
            }
            Err(e) => {
                self.io = None;
                Err(e)
            }
        }
    }

    /// The I/O connection brought up by [`Master::establish_io`], while it runs.
    pub fn io_connection(&self) -> Option<&IoConnection> {
        self.io.as_ref()
    }

    /// Forgets the I/O connection (released, or lost): its frames are no longer expected.
    pub fn end_io(&mut self) -> Option<IoConnection> {
        self.io.take()
    }

    /// Gives back `conn`, taken with [`Master::end_io`] while the device still runs it (a check
    /// watched its frames itself): its frames are the connection's again until it is released.
    /// What came meanwhile was the taker's to judge, so the master starts afresh: the first
    /// production is timed from now, and the fragments that end a production begun before now are
    /// noted, not reassembled.
    pub fn resume_io(&mut self, mut conn: IoConnection) {
        conn.pending.clear();
        conn.series = IoSeries::new(conn.produced);
        conn.series_start = None;
        conn.last = None;
        conn.output_pending = None;
        conn.resumed = Some(self.session.now());
        conn.resync = true;
        self.io = Some(conn);
    }

    /// Runs `f` on the I/O connection, taken out of the master meanwhile (so frames that are not
    /// its own are judged as usual).
    fn with_io<T>(
        &mut self,
        f: impl FnOnce(&mut Self, &mut IoConnection) -> Result<T, MasterError>,
    ) -> Result<T, MasterError> {
        let Some(mut conn) = self.io.take() else {
            return Err(UsageError::NoIoConnection.into());
        };
        let r = f(self, &mut conn);
        self.io = Some(conn);
        r
    }

    /// Takes record `i` when it belongs to the I/O connection (a production, an acknowledgement);
    /// `false` when it does not.
    pub(crate) fn io_claims(&mut self, i: usize) -> Result<bool, MasterError> {
        let Some(conn) = &self.io else { return Ok(false) };
        let id = self.session.record(i).frame.id();
        let target = conn.target;
        let mine = conn.options.kind.is_cos_cyclic()
            && (id == Identifier::group1(Group1MessageId::COS_CYCLIC, target)
                || id == Identifier::group1(Group1MessageId::POLL_RESPONSE, target));
        if !mine {
            return Ok(false);
        }
        self.with_io(|m, conn| m.io_frame(conn, i))?;
        Ok(true)
    }

    /// Sets the EPR of Connection `inst` and checks the value applied (rounded up, protocol §5.3).
    pub(crate) fn set_epr(
        &mut self,
        target: MacId,
        inst: u16,
        epr_ms: u16,
        kind: IoKind,
    ) -> Result<u16, MasterError> {
        let (data, i) = self.set(target, class::CONNECTION, inst, 9, &epr_ms.to_le_bytes())?;
        Ok(match data.as_slice() {
            [a, b] => {
                let applied = u16::from_le_bytes([*a, *b]);
                let failures = if applied >= epr_ms {
                    Vec::new()
                } else {
                    vec![format!(
                        "EPR applied {applied} ms is below the {epr_ms} ms requested (must round up)"
                    )]
                };
                self.judge(i, &format!("EPR {applied} ms applied; {kind} connection established"), failures);
                applied
            }
            [] => {
                self.judge(i, "EPR set (no applied value returned)", Vec::new());
                epr_ms
            }
            other => {
                self.judge(i, "", vec![format!("EPR response data {}, expected 2 bytes", hex(other))]);
                epr_ms
            }
        })
    }

    /// One bit-strobe cycle: the strobe with the device's bit set, then its response (at most 8
    /// bytes, never fragmented, exactly the produced size). Returns the input bytes.
    pub fn strobe(&mut self) -> Result<Vec<u8>, MasterError> {
        self.with_io(|m, conn| m.strobe_on(conn))
    }

    fn strobe_on(&mut self, conn: &mut IoConnection) -> Result<Vec<u8>, MasterError> {
        let target = conn.target;
        let frame = CanFrame::new(self.strobe_id(), &strobe_data(target))?;
        self.session.send(&frame)?;
        let timeout = conn.response_timeout();
        let deadline = self.session.now() + timeout;
        let response_id = Identifier::group1(Group1MessageId::BIT_STROBE_RESPONSE, target);
        let Some((i, rec)) = self.next_wanted(deadline, |f| f.id() == response_id)? else {
            return Err(MasterError::Timeout {
                what: format!("bit-strobe of MAC {target}"),
                mac: target.as_raw(),
                after: timeout,
                timeout: "strobe response timeout",
            });
        };
        let data = rec.frame.data().to_vec();
        let mut failures = Vec::new();
        if data.len() != usize::from(conn.produced) {
            failures.push(format!("DLC {}, expected the produced size {}", data.len(), conn.produced));
        }
        let note = format!("bit-strobe response, {} bytes (never fragmented, notes II.1.3)", data.len());
        self.session.set_verdict(i, Verdict::Ok(note).with_failures(failures));
        conn.summary.strobe_responses += 1;
        Ok(data)
    }

    /// Waits for the next COS/cyclic production of `conn` (reassembled, acknowledged unless
    /// suppressed, its timing judged); returns its data. A production that came while the master
    /// waited for something else is returned first.
    pub fn await_production(&mut self) -> Result<Vec<u8>, MasterError> {
        self.with_io(|m, conn| m.await_production_on(conn))
    }

    fn await_production_on(&mut self, conn: &mut IoConnection) -> Result<Vec<u8>, MasterError> {
        if let Some(p) = conn.pending.pop_front() {
            return Ok(p);
        }
        let timeout = conn.production_timeout();
        let deadline = self.session.now() + timeout;
        loop {
            let Some(i) = self.session.next(deadline)? else {
                let what = match conn.options.kind {
                    IoKind::Cyclic => "cyclic production (every EPR)",
                    _ => "change-of-state production (at the latest every EPR)",
                };
                return Err(MasterError::Timeout {
                    what: format!("{what} of MAC {}", conn.target),
                    mac: conn.target.as_raw(),
                    after: timeout,
                    timeout: "2 x EPR + tolerance",
                });
            };
            self.io_frame(conn, i)?;
            if let Some(p) = conn.pending.pop_front() {
                return Ok(p);
            }
        }
    }

    /// Sends the master's COS/cyclic data (Group 2 message 5, I/O-fragmented when Connection 2
    /// consumes more than 8 bytes) and, unless suppressed, waits for the device's zero-length
    /// acknowledgement; productions that come meanwhile are kept for [`Master::await_production`].
    pub fn send_output(&mut self, output: &[u8]) -> Result<(), MasterError> {
        self.with_io(|m, conn| m.send_output_on(conn, output))
    }

    fn send_output_on(&mut self, conn: &mut IoConnection, output: &[u8]) -> Result<(), MasterError> {
        let target = conn.target;
        let id = Identifier::group2(target, Group2Message::PollCommand);
        let frames: Vec<CanFrame> = if conn.consumed > 8 {
            io_fragments(output).filter_map(|p| CanFrame::new(id, &p).ok()).collect()
        } else {
            CanFrame::new(id, output).into_iter().collect()
        };
        for f in &frames {
            self.session.send(f)?;
        }
        conn.summary.outputs_sent += 1;
        let sent = self.session.now();
        if !conn.acked() {
            return Ok(());
        }
        conn.output_pending = Some(sent);
        let timeout = conn.response_timeout();
        let deadline = sent + timeout;
        while conn.output_pending.is_some() {
            let Some(i) = self.session.next(deadline)? else {
                return Err(MasterError::Timeout {
                    what: format!("acknowledgement of the master's COS/cyclic data by MAC {target}"),
                    mac: target.as_raw(),
                    after: timeout,
                    timeout: "acknowledgement timeout (the EPR, at least 100 ms)",
                });
            };
            self.io_frame(conn, i)?;
        }
        Ok(())
    }

    /// Judges one record for the COS/cyclic exchange of `conn`.
    fn io_frame(&mut self, conn: &mut IoConnection, i: usize) -> Result<(), MasterError> {
        let rec = self.session.record(i).clone();
        if rec.origin == Origin::Local {
            return Ok(());
        }
        let target = conn.target;
        let production_id = Identifier::group1(Group1MessageId::COS_CYCLIC, target);
        let output_ack_id = Identifier::group1(Group1MessageId::POLL_RESPONSE, target);
        if rec.frame.id() == output_ack_id && conn.options.kind.is_cos_cyclic() {
            let mut failures = Vec::new();
            if !rec.frame.data().is_empty() {
                failures.push(format!(
                    "DLC {}, the acknowledgement of the master's data is empty (Connection 2 produced size 0)",
                    rec.frame.data().len()
                ));
            }
            let note = if conn.options.ack_suppression {
                failures.push("an acknowledgement under acknowledge suppression (notes II.2.1)".into());
                "acknowledgement".to_string()
            } else if let Some(sent) = conn.output_pending.take() {
                conn.summary.outputs_acknowledged += 1;
                format!(
                    "acknowledgement of the master's data, {:.1} ms after it",
                    (rec.at - sent).total_micros() as f64 / 1000.0
                )
            } else {
                failures.push("an acknowledgement while no data of the master awaits one".into());
                "acknowledgement".to_string()
            };
            self.session.set_verdict(i, Verdict::Ok(note).with_failures(failures));
            return Ok(());
        }
        if rec.frame.id() != production_id {
            return self.other(i);
        }
        let what = match conn.options.kind {
            IoKind::Cyclic => "cyclic production",
            _ => "change-of-state production",
        };
        if conn.resync {
            let first = conn.produced <= 8 || rec.frame.data().first().is_some_and(|b| b & 0xC0 == 0);
            if !first {
                let note = format!(
                    "{what} fragment: the end of a production begun before the master took the connection back"
                );
                self.session.set_verdict(i, Verdict::Info(note));
                return Ok(());
            }
            conn.resync = false;
        }
        if conn.series_start.is_none() {
            conn.series_start = Some(rec.at);
        }
        match conn.series.take(rec.frame.data(), what) {
            SeriesStep::Fragment(v) => self.session.set_verdict(i, v),
            SeriesStep::Rejected(v) => {
                conn.series_start = None;
                self.session.set_verdict(i, v);
            }
            SeriesStep::Complete(data, v) => {
                let start = conn.series_start.take().unwrap_or(rec.at);
                let (v, resent) = self.judge_production(conn, start, &data, v);
                self.session.set_verdict(i, v);
                if conn.acked() {
                    let ack = CanFrame::new(Identifier::group2(target, Group2Message::CosCyclicAck), &[])?;
                    self.session.send(&ack)?;
                    conn.summary.acks_sent += 1;
                }
                if !resent {
                    let acked_at = conn.acked().then(|| self.session.now());
                    conn.last = Some((start, data.clone(), acked_at));
                    conn.pending.push_back(data);
                }
            }
        }
        Ok(())
    }

    /// The verdict on a complete production that started at `start`: a re-send, or a new
    /// production whose interval is judged.
    fn judge_production(
        &mut self,
        conn: &mut IoConnection,
        start: Instant,
        data: &[u8],
        v: Verdict,
    ) -> (Verdict, bool) {
        let epr = conn.epr();
        let tol = timing_tolerance(epr);
        let ms = |d: Duration| d.total_micros() as f64 / 1000.0;
        let ack_timer =
            Duration::from_millis(u64::from(conn.summary.ack_timer_ms.unwrap_or(DEFAULT_ACK_TIMER_MS)));
        // A re-send: the same data again sooner than any trigger could bring it (§II.2.4).
        let window = {
            let w = ack_timer + Duration::from_millis(50);
            let half = Duration::from_micros(epr.total_micros() / 2);
            if w < half {
                w
            } else {
                half
            }
        };
        if let Some((prev, prev_data, acked_at)) = conn.last.clone() {
            // Only an acknowledgement missed or later than the timer explains a re-send: after a
            // timely one the same data again is a production of its own (a COS trigger with
            // unchanged data), judged below.
            let late = acked_at.map(|a| a - prev);
            let missed = late.is_none_or(|l| l >= ack_timer);
            if conn.acked() && missed && prev_data == data && start - prev < window {
                conn.summary.re_sent += 1;
                let why = match late {
                    Some(l) => format!(
                        "the master acknowledged {:.1} ms after it, past the {:.0} ms acknowledge timer",
                        ms(l),
                        ms(ack_timer)
                    ),
                    None => "not acknowledged".to_string(),
                };
                let note = format!(
                    "the production sent again {:.1} ms after the first ({why}, notes II.2.4)",
                    ms(start - prev)
                );
                return (v.noted(&note), true);
            }
        }
        conn.summary.productions += 1;
        let (interval, since) = match (&conn.last, conn.resumed) {
            (Some((prev, _, _)), _) => (start - *prev, "the previous production"),
            (None, Some(back)) => (start - back, "the master took the connection back"),
            (None, None) => (start - conn.established_at, "the Set EPR (established)"),
        };
        let first = conn.last.is_none();
        if !first {
            conn.note_interval(ms(interval));
        }
        let mut timing = Vec::new();
        match conn.options.kind {
            IoKind::Cyclic if !first => {
                let off = Duration::from_micros(interval.total_micros().abs_diff(epr.total_micros()));
                if off > tol {
                    timing.push(format!(
                        "{:.1} ms after {since}: a cyclic connection produces every EPR ({} ms, tolerance {:.0} ms)",
                        ms(interval),
                        conn.epr_ms,
                        ms(tol)
                    ));
                }
            }
            _ => {
                if interval > epr + tol {
                    timing.push(format!(
                        "{:.1} ms after {since}: {} (EPR {} ms, tolerance {:.0} ms)",
                        ms(interval),
                        if conn.options.kind == IoKind::Cyclic {
                            "the first cyclic production comes at the latest one EPR after it is established"
                        } else {
                            "a change-of-state connection produces at the latest every EPR"
                        },
                        conn.epr_ms,
                        ms(tol)
                    ));
                }
                if let (IoKind::ChangeOfState, Some(pit), false) =
                    (conn.options.kind, conn.summary.inhibit_time_ms, first)
                {
                    let pit_d = Duration::from_millis(u64::from(pit));
                    if pit > 0 && interval + Duration::from_millis(2) < pit_d {
                        timing.push(format!(
                            "{:.1} ms after the previous production, inside the {pit} ms production inhibit time",
                            ms(interval)
                        ));
                    }
                }
            }
        }
        let note = format!("{:.1} ms after {since}", ms(interval));
        let v = if conn.options.judge_timing {
            v.with_failures(timing).noted(&note)
        } else if timing.is_empty() {
            v.noted(&note)
        } else {
            v.noted(&format!("{note}; timing not judged on this bus: {}", timing.join("; ")))
        };
        (v, false)
    }
}

impl Verdict {
    /// Adds `note` to an ok verdict (a failure keeps its reasons).
    pub fn noted(self, note: &str) -> Verdict {
        match self {
            Verdict::Ok(n) => Verdict::Ok(format!("{n}; {note}")),
            other => other,
        }
    }
}

#[cfg(test)]
mod tests;
