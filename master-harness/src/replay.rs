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
//! On the first divergence the replay stops with a [`Divergence`]: expected and actual frames, both
//! decoded, and the transcript frames before it.

use crate::error::{Divergence, HarnessError, ShownFrame};
use can_io::bus::Origin;
use can_io::log::{format_line, LogEntry};
use devicenet::messages::DuplicateMacCheck;
use devicenet::{CanFrame, Duration, Instant, MacId};
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
