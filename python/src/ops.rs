//! What each call of `dnet.Master` does on the bus thread, in Rust terms: plain functions of the
//! master and the thread's [`State`], their results plain serde values (the Python side turns them
//! into dicts).

use crate::error::CallError;
use crate::worker::{IoSetup, State};
use devicenet::messages::AllocationChoice;
use devicenet::{Duration, Instant, MacId};
use dnet_scanner::monitor::{InputLayout, Sample};
use dnet_scanner::scan::{self, ScanReport};
use harness_common::console::Progress;
use master_core::error::MasterError;
use master_core::io::{IoKind, IoOptions};
use master_core::master::{ConnectOptions, DeviceSummary, Master, MIN_POLL_TIMEOUT};
use master_core::session::{Record, Verdict};
use serde::Serialize;

/// One frame of a call's transcript, with its verdict.
#[derive(Clone, Debug, Serialize)]
pub struct FrameRow {
    /// Position in the master's session.
    pub index: usize,
    /// Bus time, microseconds.
    pub time_us: u64,
    /// `M->` (the master), `S->` (the device), `?->` (another node).
    pub direction: &'static str,
    /// The frame, candump style (`405#...`).
    pub frame: String,
    /// Its DeviceNet meaning.
    pub meaning: String,
    /// `sent`, `ok`, `fail` or `info`.
    pub verdict: &'static str,
    /// What was checked (ok), or the reasons (fail), or why not checked.
    pub notes: Vec<String>,
}

impl FrameRow {
    fn of(r: &Record, device: MacId) -> FrameRow {
        let (verdict, notes) = match &r.verdict {
            Verdict::Sent => ("sent", Vec::new()),
            Verdict::Ok(n) => ("ok", vec![n.clone()]),
            Verdict::Fail(reasons) => ("fail", reasons.clone()),
            Verdict::Info(n) => ("info", vec![n.clone()]),
            Verdict::Unchecked => ("unchecked", Vec::new()),
        };
        FrameRow {
            index: r.index,
            time_us: r.at.total_micros(),
            direction: r.direction(Some(device)),
            frame: r.frame.to_string(),
            meaning: r.meaning.clone(),
            verdict,
            notes,
        }
    }
}

/// What `connect` returns: the device's summary and every frame of the bring-up with its verdict.
#[derive(Clone, Debug, Serialize)]
pub struct ConnectReport {
    /// No frame check failed.
    pub ok: bool,
    /// Frames whose check failed.
    pub failures: usize,
    /// The device as the bring-up found it.
    pub device: DeviceSummary,
    /// Every frame of the bring-up.
    pub frames: Vec<FrameRow>,
}

/// The frames of the session from index `from` on.
fn frames_since(master: &Master<'_, '_>, from: usize, device: MacId) -> Vec<FrameRow> {
    master.session.records().iter().filter(|r| r.index >= from).map(|r| FrameRow::of(r, device)).collect()
}

/// The bring-up of protocol §2 with the I/O connection `kind` at `epr_ms`; the connection stays
/// established for [`io_cycle`] and the monitor.
pub fn connect(
    master: &mut Master<'_, '_>,
    state: &mut State,
    mac: MacId,
    kind: IoKind,
    epr_ms: u16,
) -> Result<ConnectReport, CallError> {
    let from = master.session.next_index();
    let opts = ConnectOptions { target: mac, epr_ms, polls: 1, output: None, verify_state: false };
    let io = IoOptions { judge_timing: state.judge_timing, ..IoOptions::of(kind) };
    let summary = master.connect_io(&opts, &io)?;
    let epr = summary.expected_packet_rate_ms.unwrap_or(epr_ms).max(1);
    state.io.insert(
        mac.as_raw(),
        IoSetup {
            kind,
            produced: summary.produced_size.unwrap_or(0),
            consumed: summary.consumed_size.unwrap_or(0),
            epr: Duration::from_millis(u64::from(epr)),
            due: master.session.now(),
        },
    );
    let frames = frames_since(master, from, mac);
    let failures = frames.iter().filter(|f| f.verdict == "fail").count();
    Ok(ConnectReport { ok: failures == 0, failures, device: summary, frames })
}

/// The explicit connection to `mac`, allocated unless the master holds it already.
fn explicit(master: &mut Master<'_, '_>, mac: MacId) -> Result<(), MasterError> {
    if master.held(mac).contains(AllocationChoice::EXPLICIT) {
        Ok(())
    } else {
        master.open_explicit(mac)
    }
}

/// Get_Attribute_Single: the value's bytes.
pub fn get(
    master: &mut Master<'_, '_>,
    mac: MacId,
    class: u16,
    instance: u16,
    attribute: u8,
) -> Result<Vec<u8>, CallError> {
    explicit(master, mac)?;
    Ok(master.get(mac, class, instance, attribute)?.0)
}

/// Set_Attribute_Single: the response's data (usually none).
pub fn set(
    master: &mut Master<'_, '_>,
    mac: MacId,
    class: u16,
    instance: u16,
    attribute: u8,
    value: &[u8],
) -> Result<Vec<u8>, CallError> {
    explicit(master, mac)?;
    Ok(master.set(mac, class, instance, attribute, value)?.0)
}

/// Why an I/O exchange cannot start.
#[derive(Debug, thiserror::Error)]
pub enum IoUsage {
    /// No connect first.
    #[error("MAC {0} has no I/O connection: call connect({0}) first")]
    NotConnected(MacId),
    /// The output does not fit the connection.
    #[error("output: {given} bytes, MAC {mac}'s connection consumes {consumed}")]
    OutputSize {
        /// The device.
        mac: MacId,
        /// Bytes given.
        given: usize,
        /// Bytes the device consumes.
        consumed: u16,
    },
}

/// One I/O cycle on the connection `connect` left to `mac`, `output` sent (`None`: zeros of the
/// consumed size): the poll (or bit-strobe) and its response, no sooner than one EPR after the
/// previous one (the rate the device expects, protocol §5.4); for COS and cyclic the device's
/// next production, then the master's data. Returns when the cycle started and the input data.
pub fn io_cycle(
    master: &mut Master<'_, '_>,
    state: &mut State,
    mac: MacId,
    output: Option<&[u8]>,
) -> Result<(Instant, Vec<u8>), CallError> {
    let Some(setup) = state.io.get(&mac.as_raw()).copied() else {
        return Err(CallError::Usage(format!(
            "mac: MAC {mac} has no I/O connection: call connect({mac}) first"
        )));
    };
    let output = match output {
        None => vec![0; usize::from(setup.consumed)],
        Some(o) if o.len() == usize::from(setup.consumed) => o.to_vec(),
        Some(o) => {
            return Err(CallError::Usage(format!(
                "output: {} bytes, MAC {mac}'s connection consumes {}",
                o.len(),
                setup.consumed
            )))
        }
    };
    let timeout = if setup.epr > MIN_POLL_TIMEOUT { setup.epr } else { MIN_POLL_TIMEOUT };
    let paced = matches!(setup.kind, IoKind::Poll | IoKind::Strobe);
    if paced {
        master.idle_until(setup.due)?;
    }
    let at = master.session.now();
    if let Some(s) = state.io.get_mut(&mac.as_raw()) {
        s.due = at + setup.epr;
    }
    let input = match setup.kind {
        IoKind::Poll => master.poll(mac, &output, setup.produced, setup.consumed, timeout)?,
        IoKind::Strobe => master.strobe()?,
        IoKind::ChangeOfState | IoKind::Cyclic => {
            let input = master.await_production()?;
            if setup.consumed > 0 {
                master.send_output(&output)?;
            }
            input
        }
    };
    Ok((at, input))
}

/// The devices of MAC IDs `from..=to` ([`dnet_scanner::scan::scan`]); the I/O connections it
/// released forgotten.
pub fn scan(
    master: &mut Master<'_, '_>,
    state: &mut State,
    from: u8,
    to: u8,
) -> Result<ScanReport, CallError> {
    let report = scan::scan(master, from, to, &mut Progress::off());
    // The scan releases what it allocated, also a set a connect() left: those I/O connections
    // are gone.
    state.io.retain(|&mac, s| master.held(MacId::from_low_bits(mac)).contains(s.kind.choice()));
    Ok(report?)
}

/// A monitor in progress: how it connects, and how the run ends.
#[derive(Clone, Debug)]
pub struct Monitor {
    /// The device.
    pub mac: MacId,
    /// The output sent each cycle (`None`: zeros of the consumed size).
    pub output: Option<Vec<u8>>,
    /// The EPR to connect with when the device has no connection yet.
    pub epr_ms: u16,
    /// The connection's kind when the monitor connects.
    pub kind: IoKind,
    /// Samples still to take (`None`: no limit).
    pub remaining: Option<u64>,
    /// How long to monitor (bus time, from the first sample).
    pub duration: Option<Duration>,
    /// When the run ends (set at the first sample).
    pub end: Option<Instant>,
    /// The decoding (`None`: the master's default).
    pub layout: Option<InputLayout>,
}

/// The next sample of `m`, or `None` when its count or duration is reached. The first call
/// brings the device up when it has no I/O connection yet; then one cycle every EPR
/// ([`io_cycle`]).
pub fn monitor_next(
    master: &mut Master<'_, '_>,
    state: &mut State,
    m: &mut Monitor,
) -> Result<Option<Sample>, CallError> {
    if m.remaining == Some(0) {
        return Ok(None);
    }
    if !state.io.contains_key(&m.mac.as_raw()) {
        connect(master, state, m.mac, m.kind, m.epr_ms)?;
    }
    let now = master.session.now();
    let end = *m.end.get_or_insert_with(|| m.duration.map_or(Instant::MAX, |d| now + d));
    let due = state.io.get(&m.mac.as_raw()).map_or(now, |s| s.due);
    if due.max(now) > end {
        return Ok(None);
    }
    let (at, raw) = io_cycle(master, state, m.mac, m.output.as_deref())?;
    if let Some(r) = &mut m.remaining {
        *r = r.saturating_sub(1);
    }
    let strobe = state.io.get(&m.mac.as_raw()).is_some_and(|s| s.kind == IoKind::Strobe);
    let sample = match &m.layout {
        Some(layout) => Sample::new(at.total_micros(), raw, layout),
        // A bit-strobe response carries the first 8 input bytes only: raw, as dnet-master
        // monitor shows it.
        None if strobe => Sample::new(at.total_micros(), raw, &InputLayout::raw()),
        None => Sample::new(at.total_micros(), raw, &state.layout),
    };
    Ok(Some(sample))
}
