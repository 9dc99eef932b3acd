//! The console's Serial line panel: the converter's serial-line analyzer (vendor class 0x68,
//! Read_Trace, `slave_fw::converter::analyzer_object`) read over the scanner's explicit connection
//! and decoded by the device's profile ([`crate::serial_trace`]), as `dnet-master serial-trace`
//! prints it.
//!
//! | request | answer |
//! |---|---|
//! | `GET /api/node/MAC/serial-trace?since=N` | `{"ok", "converter": true, "profile", "next", "lines": [{n, seq, time_ms, kind, hex, decoded}], "dropped", "entries", "missed"}`: the decoded lines numbered after `N` (default 0: every line kept); `next` is the `N` to ask with next time; `dropped` the lines after `N` no longer kept; `entries` and `missed` the trace entries read and overwritten before they were read since the console started. A node without the analyzer: `{"ok", "converter": false, "note"}` |
//!
//! One poll reads the trace from where the last read of that node ended, until it reaches the
//! device's next sequence number (at most [`READS_PER_POLL`] Read_Trace requests): a poll costs one
//! request when nothing is new. The first poll of a node also reads its profile from the settings
//! object (class 0x65 attributes 11 and 12). The lines are kept per node (the newest
//! [`LINES_KEPT`]), so several pages share one read of the device, and a line that completes a
//! frame begun in an earlier poll is decoded whole. A ring overrun is a line of kind `missed`
//! ("N entries missed"), a converter restart one of kind `restart`.
//!
//! Reading changes nothing on the device: a viewer may read it. A node in the scan list without
//! the analyzer (an error response to Read_Trace) is answered `200` with `converter: false` and the
//! reason, for the panel to show; a MAC outside the scan list is `404`, a node without an explicit
//! connection or an unanswered request `409`.

use super::http::Response;
use super::COMMAND_TIMEOUT;
use crate::model::{ConsoleCommand, Shared};
use crate::serial_trace::{parse_reply, Decoder, Gap, LineProfile, TraceLine};
use master_core::client::ReplyBody;
use master_core::decode;
use serde_json::json;
use slave_fw::converter::analyzer_object::{ANALYZER_CLASS, READ_TRACE};
use slave_fw::converter::objects::{SettingsAttribute, SETTINGS_CLASS};
use std::collections::{BTreeMap, VecDeque};
use std::sync::{mpsc, Arc, Mutex};

/// Decoded lines kept per node (the newest).
pub const LINES_KEPT: usize = 500;
/// Read_Trace requests at most in one poll: the analyzer's ring (32 entries) read from its
/// oldest entry takes 16 replies of at least two entries each.
pub const READS_PER_POLL: usize = 20;

/// Service code of Get_Attribute_Single.
const GET_ATTRIBUTE_SINGLE: u8 = 0x0E;

/// Why a poll gave no lines.
#[derive(Debug, thiserror::Error)]
enum TraceApiError {
    /// The MAC is not in the scan list.
    #[error("MAC {0} is not in the scan list")]
    UnknownNode(u8),
    /// The scanner could not be asked.
    #[error("the scanner is not running")]
    NotRunning,
    /// No answer from the scanner in time.
    #[error("no answer from the scanner within {} s", COMMAND_TIMEOUT.as_secs())]
    Timeout,
    /// The scanner or the device gave no reply (a node that is not ok, a bus timeout).
    #[error("{0}")]
    NoReply(String),
    /// A Read_Trace reply that does not parse.
    #[error("MAC {mac}: Read_Trace reply: {reason}")]
    BadReply {
        /// The node.
        mac: u8,
        /// Why.
        reason: String,
    },
    /// A lock was poisoned by a panicked handler.
    #[error("the serial trace of MAC {0} is unavailable")]
    Unavailable(u8),
}

impl TraceApiError {
    fn status(&self) -> u16 {
        match self {
            TraceApiError::UnknownNode(_) => 404,
            TraceApiError::NotRunning => 503,
            TraceApiError::Timeout => 504,
            TraceApiError::NoReply(_) | TraceApiError::BadReply { .. } => 409,
            TraceApiError::Unavailable(_) => 500,
        }
    }
}

/// One line as the API gives it: its number in the node's kept lines and the decoded line.
#[derive(Clone, Debug, serde::Serialize)]
struct Row {
    n: u64,
    #[serde(flatten)]
    line: TraceLine,
}

/// What the console keeps of one node's trace.
struct NodeTrace {
    /// The decoder, made once the profile is read.
    decoder: Option<Decoder>,
    /// The sequence number the next read asks from.
    from: u32,
    /// The newest lines.
    lines: VecDeque<Row>,
    /// The number the next line gets (from 1).
    next_n: u64,
    entries: u64,
    missed: u64,
}

impl NodeTrace {
    fn new() -> NodeTrace {
        NodeTrace { decoder: None, from: 0, lines: VecDeque::new(), next_n: 1, entries: 0, missed: 0 }
    }

    fn keep(&mut self, line: TraceLine) {
        if self.lines.len() == LINES_KEPT {
            self.lines.pop_front();
        }
        self.lines.push_back(Row { n: self.next_n, line });
        self.next_n += 1;
    }
}

/// Every node's kept trace: at most one per MAC (64), each at most [`LINES_KEPT`] lines.
#[derive(Default)]
pub(crate) struct Traces {
    nodes: Mutex<BTreeMap<u8, Arc<Mutex<NodeTrace>>>>,
}

/// Sends `make`'s command to the scanner's loop and waits for its answer.
fn ask<T>(shared: &Shared, make: impl FnOnce(mpsc::Sender<T>) -> ConsoleCommand) -> Result<T, TraceApiError> {
    let (tx, rx) = mpsc::channel();
    shared
        .commands
        .lock()
        .map_err(|_| TraceApiError::NotRunning)?
        .send(make(tx))
        .map_err(|_| TraceApiError::NotRunning)?;
    rx.recv_timeout(COMMAND_TIMEOUT).map_err(|e| match e {
        mpsc::RecvTimeoutError::Timeout => TraceApiError::Timeout,
        mpsc::RecvTimeoutError::Disconnected => TraceApiError::NotRunning,
    })
}

/// `service` with `data` to `class` instance 1 of `mac`: the device's reply.
fn request(
    shared: &Shared,
    mac: u8,
    service: u8,
    class: u16,
    data: Vec<u8>,
) -> Result<ReplyBody, TraceApiError> {
    ask(shared, |reply| ConsoleCommand::Request { mac, service, class, instance: 1, data, reply })?
        .map_err(TraceApiError::NoReply)
}

/// A settings object attribute; `None` when the device answers with an error.
fn setting(shared: &Shared, mac: u8, attribute: SettingsAttribute) -> Result<Option<Vec<u8>>, TraceApiError> {
    Ok(match request(shared, mac, GET_ATTRIBUTE_SINGLE, SETTINGS_CLASS, vec![attribute.id()])? {
        ReplyBody::Success(bytes) => Some(bytes),
        ReplyBody::Error { .. } => None,
    })
}

/// The profile of `mac`, read from its settings object.
fn profile(shared: &Shared, mac: u8) -> Result<LineProfile, TraceApiError> {
    let serial_profile = setting(shared, mac, SettingsAttribute::SerialProfile)?;
    let framing = match serial_profile.as_deref() {
        Some([1]) => setting(shared, mac, SettingsAttribute::ModbusFraming)?,
        _ => None,
    };
    Ok(LineProfile::from_settings(serial_profile.as_deref(), framing.as_deref()))
}

/// Reads `mac`'s trace on from `t.from` into `t`; `Some(note)` when the node has no analyzer.
fn read_new(shared: &Shared, mac: u8, t: &mut NodeTrace) -> Result<Option<String>, TraceApiError> {
    for _ in 0..READS_PER_POLL {
        let bytes = match request(shared, mac, READ_TRACE, ANALYZER_CLASS, t.from.to_le_bytes().to_vec())? {
            ReplyBody::Success(bytes) => bytes,
            ReplyBody::Error { general, additional } => {
                return Ok(Some(format!(
                    "MAC {mac} has no serial-line analyzer (class 0x{ANALYZER_CLASS:02X}): it is not a \
                     serial converter ({})",
                    decode::error_text(general, additional)
                )));
            }
        };
        let reply =
            parse_reply(&bytes).map_err(|e| TraceApiError::BadReply { mac, reason: e.to_string() })?;
        let decoder = match &mut t.decoder {
            Some(d) => d,
            None => t.decoder.insert(Decoder::new(profile(shared, mac)?)),
        };
        let time_ms = reply.entries.first().map_or(0, |e| e.time_ms);
        let note = |kind, decoded| TraceLine { seq: reply.first, time_ms, kind, hex: String::new(), decoded };
        let gap = match Gap::between(t.from, reply.first) {
            Gap::None => None,
            Gap::Missed(n) => {
                t.missed += u64::from(n);
                Some(note("missed", format!("{n} entries missed")))
            }
            Gap::Restarted => {
                *decoder = Decoder::new(decoder.profile());
                Some(note(
                    "restart",
                    format!("the converter restarted: its trace starts again at #{}", reply.first),
                ))
            }
        };
        let mut lines: Vec<TraceLine> = gap.into_iter().collect();
        for (k, entry) in reply.entries.iter().enumerate() {
            lines.extend(decoder.push(reply.first.wrapping_add(k as u32), entry));
        }
        lines.into_iter().for_each(|l| t.keep(l));
        t.entries += reply.entries.len() as u64;
        t.from = reply.first.wrapping_add(reply.entries.len() as u32);
        if t.from == reply.next || reply.entries.is_empty() {
            break;
        }
    }
    Ok(None)
}

/// `GET /api/node/MAC/serial-trace?since=N`.
pub(super) fn poll(shared: &Shared, traces: &Traces, mac: u8, since: Option<u64>) -> Response {
    match answer(shared, traces, mac, since.unwrap_or(0)) {
        Ok(v) => Response::new(200, "application/json", v.to_string().into_bytes()),
        Err(e) => {
            let body = json!({"ok": false, "error": e.to_string()}).to_string();
            Response::new(e.status(), "application/json", body.into_bytes())
        }
    }
}

fn answer(shared: &Shared, traces: &Traces, mac: u8, since: u64) -> Result<serde_json::Value, TraceApiError> {
    let known =
        shared.state.lock().map_err(|_| TraceApiError::NotRunning)?.nodes.iter().any(|n| n.mac == mac);
    if !known {
        return Err(TraceApiError::UnknownNode(mac));
    }
    let node = {
        let mut nodes = traces.nodes.lock().map_err(|_| TraceApiError::Unavailable(mac))?;
        Arc::clone(nodes.entry(mac).or_insert_with(|| Arc::new(Mutex::new(NodeTrace::new()))))
    };
    let mut t = node.lock().map_err(|_| TraceApiError::Unavailable(mac))?;
    // A number from before the console started again: every line kept.
    let since = if since >= t.next_n { 0 } else { since };
    if let Some(note) = read_new(shared, mac, &mut t)? {
        return Ok(json!({"ok": true, "converter": false, "mac": mac, "note": note}));
    }
    let oldest = t.lines.front().map_or(t.next_n, |r| r.n);
    let rows: Vec<&Row> = t.lines.iter().filter(|r| r.n > since).collect();
    Ok(json!({
        "ok": true,
        "converter": true,
        "mac": mac,
        "profile": t.decoder.as_ref().map_or(LineProfile::Raw, Decoder::profile).name(),
        "next": t.next_n - 1,
        "lines": rows,
        "dropped": oldest.saturating_sub(since + 1),
        "entries": t.entries,
        "missed": t.missed,
    }))
}

#[cfg(test)]
mod tests;
