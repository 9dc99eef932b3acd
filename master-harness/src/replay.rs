//! `replay TRANSCRIPT --mac N`: a recorded exchange becomes a regression test.
//!
//! Every transcript frame the device at MAC N would produce ([`is_from_device`]: its Group 1
//! messages, its Group 2 message 3 responses and message 7 duplicate MAC ID checks, its Group 3
//! messages) is *expected*: the device must send exactly it, next, within `tolerance` of its
//! recorded time. Every other frame is *stimulus*: the harness transmits it at its recorded time
//! relative to the first frame (so a transcript may hold several masters). A device frame the
//! transcript does not have at that point, including after its end (within `settle`), is a
//! divergence too.
//!
//! On the simulated bus the device is attached to power on at the recorded time of its first
//! duplicate MAC ID request in the transcript, or at the start when there is none
//! ([`device_power_on`], used by the command line when it builds the simulated bus).
//!
//! A replay that would compare nothing of the device (the transcript has no frame from MAC N: the
//! wrong `--mac`) fails before it starts, naming the transcript's device: the master would
//! otherwise transmit the device's recorded answers itself and call that a pass.
//!
//! On the first divergence the replay stops with a [`Divergence`]: expected and actual frames, both
//! decoded, and the transcript frames before it.

use crate::error::{Divergence, HarnessError, ShownFrame};
use can_io::bus::Origin;
use can_io::log::{format_line, LogEntry};
use devicenet::explicit::ServiceCode;
use devicenet::messages::{AllocationChoice, DuplicateMacCheck};
use devicenet::{CanFrame, Duration, Group2Message, Identifier, Instant, MacId};
use master_core::decode::Decoder;
use master_core::session::{is_from_device, Session, Verdict};

/// Frames of the transcript shown before a divergence.
pub const CONTEXT_FRAMES: usize = 8;

/// Options of `replay`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplayOptions {
    /// The device under test.
    pub device: MacId,
    /// How late an expected frame may be, after its recorded time (`--tolerance`, default 1 s).
    pub tolerance: Duration,
    /// How long to watch for extra device frames after the transcript ends (`--settle`, 500 ms).
    pub settle: Duration,
}

impl ReplayOptions {
    /// Defaults for `device`.
    pub fn new(device: MacId) -> ReplayOptions {
        ReplayOptions { device, tolerance: Duration::from_secs(1), settle: Duration::from_millis(500) }
    }
}

/// A replay that held.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ReplaySummary {
    /// Transcript frames.
    pub frames: usize,
    /// Device frames compared.
    pub expected: usize,
    /// Stimulus frames transmitted.
    pub stimulus: usize,
}

fn time_text(at: Instant) -> String {
    let us = at.total_micros();
    format!("{}.{:06}s", us / 1_000_000, us % 1_000_000)
}

/// When, after the transcript's first frame, the device at `device` powered on: the recorded time
/// of its first duplicate MAC ID request, or zero when the transcript has none. A simulated device
/// replayed from the start of a fresh bus is attached with this instant.
pub fn device_power_on(entries: &[LogEntry], device: MacId) -> Duration {
    let Some(first) = entries.first() else { return Duration::ZERO };
    entries
        .iter()
        .find(|e| DuplicateMacCheck::request_in(&e.frame) == Some(device))
        .map_or(Duration::ZERO, |e| e.at - first.at)
}

/// The devices of a transcript: the MACs that sent a device's frames (Group 1 messages, explicit
/// responses, Group 2 message 3), in order of first appearance. Duplicate MAC ID checks are left
/// out: masters send them too.
pub fn transcript_devices(entries: &[LogEntry]) -> Vec<MacId> {
    let mut macs: Vec<MacId> = Vec::new();
    for e in entries {
        let mac = match Identifier::decode(e.frame.id()) {
            Identifier::Group1 { source, .. } => Some(source),
            Identifier::Group2 { mac, message: Group2Message::ExplicitResponse } => Some(mac),
            _ => None,
        };
        if let Some(m) = mac.filter(|m| !macs.contains(m)) {
            macs.push(m);
        }
    }
    macs
}

/// The master of a transcript: the source MAC in the header of its first request through the
/// Group 2 Only port or an explicit connection (notes §3.1: a request's header carries the
/// requester's MAC).
pub fn transcript_master(entries: &[LogEntry]) -> Option<MacId> {
    entries.iter().find_map(|e| match Identifier::decode(e.frame.id()) {
        Identifier::Group2 {
            message: Group2Message::ExplicitRequest | Group2Message::UnconnectedExplicitRequest,
            ..
        } => e.frame.data().first().map(|h| MacId::from_low_bits(h & 0x3F)),
        _ => None,
    })
}

/// What the transcript leaves allocated at `device`: the choices of its Allocate requests the
/// device answered with success, less those of its successful Releases (notes §3.4). A replay
/// releases this when it ends, as every command does.
pub fn held_after(entries: &[LogEntry], device: MacId) -> AllocationChoice {
    let mut held = AllocationChoice::empty();
    let mut pending: Option<(ServiceCode, AllocationChoice)> = None;
    for e in entries {
        let data = e.frame.data();
        match Identifier::decode(e.frame.id()) {
            Identifier::Group2 {
                mac,
                message: Group2Message::ExplicitRequest | Group2Message::UnconnectedExplicitRequest,
            } if mac == device => {
                // Unfragmented [hdr] service class instance choice ... (8/8 body, notes §3.4).
                pending = match data {
                    [h, service, 0x03, 0x01, choice, ..] if h & 0x80 == 0 => {
                        let service = ServiceCode::from(*service);
                        matches!(service, ServiceCode::AllocateMasterSlave | ServiceCode::ReleaseMasterSlave)
                            .then(|| (service, AllocationChoice::from_bits(*choice)))
                    }
                    _ => None,
                };
            }
            Identifier::Group2 { mac, message: Group2Message::ExplicitResponse } if mac == device => {
                if let (Some((service, choice)), [_, reply, ..]) = (pending.take(), data) {
                    if *reply == 0x80 | service.as_raw() {
                        held = match service {
                            ServiceCode::AllocateMasterSlave => held.union(choice),
                            _ => held.difference(choice),
                        };
                    }
                }
            }
            _ => {}
        }
    }
    held
}

/// Replays `entries` on `session`. See the [module docs](self).
pub fn replay(
    session: &mut Session<'_>,
    entries: &[LogEntry],
    opts: &ReplayOptions,
) -> Result<ReplaySummary, HarnessError> {
    let device = opts.device;
    let Some(first) = entries.first() else {
        return Err(HarnessError::Usage("the transcript holds no frame".into()));
    };
    let from_device = entries.iter().filter(|e| is_from_device(&e.frame, device)).count();
    if from_device == 0 {
        let devices = transcript_devices(entries);
        let whose = match devices.as_slice() {
            [] => "the transcript has no device frames at all".to_string(),
            [one] => format!("the transcript's device is MAC {one} (--mac {one})"),
            many => format!(
                "the transcript's devices are MAC {}",
                many.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
            ),
        };
        return Err(HarnessError::NothingCompared(format!(
            "the transcript has no frame from MAC {device}, so replaying it would compare nothing of the device under test: {whose}"
        )));
    }
    let t0 = first.at;
    let start = session.now();
    let rel = |at: Instant| start + (at - t0);

    let mut expected_decoder = Decoder::new();
    let shown_entry = |dec: &mut Decoder, e: &LogEntry| ShownFrame {
        line: Some(e.line),
        time: time_text(e.at),
        frame: e.frame.to_string(),
        meaning: dec.clone().decode(&e.frame).text(),
    };
    let context = |k: usize| -> Vec<ShownFrame> {
        let mut dec = Decoder::new();
        let from = k.saturating_sub(CONTEXT_FRAMES);
        let mut shown = Vec::new();
        for (j, e) in entries[..k].iter().enumerate() {
            let meaning = dec.decode(&e.frame).text();
            if j >= from {
                shown.push(ShownFrame {
                    line: Some(e.line),
                    time: time_text(e.at),
                    frame: e.frame.to_string(),
                    meaning,
                });
            }
        }
        shown
    };
    let actual = |session: &Session<'_>, i: usize| {
        let r = session.record(i);
        ShownFrame {
            line: None,
            time: time_text(r.at),
            frame: r.frame.to_string(),
            meaning: r.meaning.clone(),
        }
    };
    let diverge = |k: usize, reason: String, expected: Option<ShownFrame>, actual: Option<ShownFrame>| {
        HarnessError::Divergence(Box::new(Divergence {
            index: k,
            total: entries.len(),
            reason,
            expected,
            actual,
            before: context(k),
        }))
    };

    let mut summary = ReplaySummary { frames: entries.len(), expected: 0, stimulus: 0 };
    for (k, e) in entries.iter().enumerate() {
        let due = rel(e.at);
        if is_from_device(&e.frame, device) {
            let deadline = due.max(session.now()) + opts.tolerance;
            loop {
                let Some(i) = session.next(deadline)? else {
                    let shown = shown_entry(&mut expected_decoder, e);
                    return Err(diverge(
                        k,
                        format!("the device sent nothing within {} of the recorded time", opts.tolerance),
                        Some(shown),
                        None,
                    ));
                };
                let rec = session.record(i).clone();
                if rec.origin == Origin::Local {
                    continue;
                }
                if !is_from_device(&rec.frame, device) {
                    session.set_verdict(i, Verdict::Info("other traffic, not compared".into()));
                    continue;
                }
                if rec.frame == e.frame {
                    expected_decoder.decode(&e.frame);
                    session.set_verdict(i, Verdict::Ok(format!("as transcript line {}", e.line)));
                    summary.expected += 1;
                    break;
                }
                let shown = shown_entry(&mut expected_decoder, e);
                session.set_verdict(i, Verdict::fail(format!("transcript line {} has {}", e.line, e.frame)));
                return Err(diverge(
                    k,
                    "the device sent a different frame".into(),
                    Some(shown),
                    Some(actual(session, i)),
                ));
            }
        } else {
            while let Some(i) = session.next(due)? {
                let rec = session.record(i).clone();
                if rec.origin == Origin::Local {
                    continue;
                }
                if is_from_device(&rec.frame, device) {
                    let shown = shown_entry(&mut expected_decoder, e);
                    session.set_verdict(i, Verdict::fail("not in the transcript at this point"));
                    return Err(diverge(
                        k,
                        "the device sent a frame the transcript does not have here (next in the transcript is stimulus)".into(),
                        Some(shown),
                        Some(actual(session, i)),
                    ));
                }
                session.set_verdict(i, Verdict::Info("other traffic, not compared".into()));
            }
            session.send(&e.frame)?;
            expected_decoder.decode(&e.frame);
            summary.stimulus += 1;
        }
    }
    let end = session.now() + opts.settle;
    while let Some(i) = session.next(end)? {
        let rec = session.record(i).clone();
        if rec.origin == Origin::Remote && is_from_device(&rec.frame, device) {
            session.set_verdict(i, Verdict::fail("after the end of the transcript"));
            return Err(diverge(
                entries.len(),
                format!("the device sent a frame after the transcript's last one (within {})", opts.settle),
                None,
                Some(actual(session, i)),
            ));
        }
        if rec.origin == Origin::Remote {
            session.set_verdict(i, Verdict::Info("other traffic, not compared".into()));
        }
    }
    if summary.expected == 0 {
        return Err(HarnessError::NothingCompared(format!("no frame from MAC {device} was compared")));
    }
    Ok(summary)
}

/// The log line of a transcript entry (for reports).
pub fn entry_line(e: &LogEntry) -> String {
    format_line(e.at, &e.iface, &e.frame)
}

/// `true` when `frame` is one the device at `mac` produces (expected in a replay).
pub fn is_expected(frame: &CanFrame, mac: MacId) -> bool {
    is_from_device(frame, mac)
}
