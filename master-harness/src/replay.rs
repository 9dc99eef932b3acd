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
//! Where the replay begins ([`ReplayOptions::from_online`], `--from-online`):
//!
//! - from the first frame (the default): a transcript that begins with the device's power-up
//!   (its duplicate MAC ID check) needs the device powered on in step with it, its first request
//!   within `tolerance` of the recorded time ([`power_on_window`] says when);
//! - [`FromOnline::Now`]: the device is on-line already; the transcript's start-up, every frame
//!   before the device's recorded on-line instant (one interval after its last duplicate MAC ID
//!   request, protocol §7.1), is skipped;
//! - [`FromOnline::Wait`]: the replay first waits, as long as it takes, for the device's own
//!   duplicate MAC ID check (it is powered on after the start). When the transcript has the
//!   device's check, its first request is compared with the transcript's and the replay goes on
//!   from there, timed from the moment it came; otherwise the replay waits until the device is
//!   on-line and starts at the transcript's first frame.
//!
//! With [`ReplayOptions::ignore_io_data`] (`--ignore-data io`) the data of the device's I/O
//! messages (Group 1 messages 12-15: poll, bit-strobe, change-of-state/cyclic and multicast poll
//! responses), which legitimately differ from a recording (live measurements), is not compared:
//! the identifier and the length still are, and the frame is reported as *not compared*, never as
//! passed.
//!
//! On the simulated bus the device is attached as [`sim_start`] says: powered on at the recorded
//! time of its first duplicate MAC ID request; on-line before the first frame when the transcript
//! has no such request (a capture of a running network) or with `--from-online`; at the start
//! with `--from-online=wait`.
//!
//! A replay that would compare nothing of the device (the transcript has no frame from MAC N: the
//! wrong `--mac`) fails before it starts, naming the transcript's device: the master would
//! otherwise transmit the device's recorded answers itself and call that a pass.
//!
//! On the first divergence the replay stops with a [`Divergence`]: expected and actual frames, both
//! decoded, and the frames before it.

use can_io::bus::Origin;
use can_io::log::{format_line, LogEntry};
use devicenet::explicit::ServiceCode;
use devicenet::id::Group1MessageId;
use devicenet::messages::{AllocationChoice, DuplicateMacCheck};
use devicenet::slave::DUP_MAC_INTERVAL;
use devicenet::{CanFrame, Duration, Group2Message, Identifier, Instant, MacId};
use harness_common::error::{Divergence, HarnessError, ShownFrame};
use master_core::decode::Decoder;
use master_core::session::{is_from_device, Session, Verdict};

/// Frames of the transcript shown before a divergence.
pub const CONTEXT_FRAMES: usize = 8;

/// Where a replay begins when the transcript's start-up is not replayed in step (`--from-online`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum FromOnline {
    /// The device is on-line already: skip the transcript's start-up.
    Now,
    /// Wait for the device's own duplicate MAC ID check (it is powered on after the start).
    Wait,
}

/// Options of `replay`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplayOptions {
    /// The device under test.
    pub device: MacId,
    /// How late an expected frame may be, after its recorded time (`--tolerance`, default 1 s).
    pub tolerance: Duration,
    /// How long to watch for extra device frames after the transcript ends (`--settle`, 500 ms).
    pub settle: Duration,
    /// Begin where the device is on-line (`--from-online`); `None`: at the first frame.
    pub from_online: Option<FromOnline>,
    /// Do not compare the data of the device's I/O messages (`--ignore-data io`).
    pub ignore_io_data: bool,
}

impl ReplayOptions {
    /// Defaults for `device`.
    #[must_use]
    pub fn new(device: MacId) -> ReplayOptions {
        ReplayOptions {
            device,
            tolerance: Duration::from_secs(1),
            settle: Duration::from_millis(500),
            from_online: None,
            ignore_io_data: false,
        }
    }
}

/// A replay that held.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ReplaySummary {
    /// Transcript frames.
    pub frames: usize,
    /// Device frames compared byte for byte.
    pub expected: usize,
    /// Device I/O frames whose data was not compared (`--ignore-data io`): identifier and length
    /// only.
    pub not_compared: usize,
    /// Stimulus frames transmitted.
    pub stimulus: usize,
    /// Transcript frames of the start-up not replayed (`--from-online`).
    pub skipped: usize,
}

impl ReplaySummary {
    /// The one-line result: `replay held: ...`.
    #[must_use]
    pub fn text(&self) -> String {
        let mut text = format!(
            "replay held: {} frames, {} from the device compared byte for byte",
            self.frames, self.expected
        );
        if self.not_compared > 0 {
            text += &format!(
                ", {} I/O frames from the device not compared (data ignored: --ignore-data io; identifier and length matched)",
                self.not_compared
            );
        }
        text += &format!(", {} stimulus frames sent", self.stimulus);
        if self.skipped > 0 {
            text += &format!(", {} start-up frames skipped (--from-online)", self.skipped);
        }
        text
    }
}

fn time_text(at: Instant) -> String {
    let us = at.total_micros();
    format!("{}.{:06}s", us / 1_000_000, us % 1_000_000)
}

fn seconds(d: Duration) -> String {
    format!("{:.1} s", d.total_micros() as f64 / 1e6)
}

/// The index of the transcript's first duplicate MAC ID request from `device`.
fn first_check(entries: &[LogEntry], device: MacId) -> Option<usize> {
    entries.iter().position(|e| DuplicateMacCheck::request_in(&e.frame) == Some(device))
}

/// The index of the first transcript frame after the device's start-up: the first one recorded
/// at or after its on-line instant, one interval after its last duplicate MAC ID request (notes
/// §7.1); 0 when the transcript has no request from it (the device was on-line throughout).
#[must_use]
pub fn online_index(entries: &[LogEntry], device: MacId) -> usize {
    let Some(last) = entries.iter().rposition(|e| DuplicateMacCheck::request_in(&e.frame) == Some(device))
    else {
        return 0;
    };
    let online = entries[last].at + DUP_MAC_INTERVAL;
    entries.iter().skip(last + 1).position(|e| e.at >= online).map_or(entries.len(), |i| last + 1 + i)
}

/// How a simulated device meets a replay (what the command line gives the simulated bus).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimStart {
    /// Power on this long after the start: the recorded time of its first duplicate MAC ID
    /// request.
    PowerOnAt(Duration),
    /// On-line before the first frame (no duplicate MAC ID check on the caller's bus).
    OnlineBeforeStart,
    /// Power on at the start (`--from-online=wait` waits for its check).
    PowerOnAtStart,
}

/// How the simulated device at `device` is attached for a replay of `entries` beginning as
/// `from_online` says (see the [module docs](self)).
#[must_use]
pub fn sim_start(entries: &[LogEntry], device: MacId, from_online: Option<FromOnline>) -> SimStart {
    match (from_online, first_check(entries, device), entries.first()) {
        (Some(FromOnline::Wait), _, _) => SimStart::PowerOnAtStart,
        (None, Some(i), Some(first)) => SimStart::PowerOnAt(entries[i].at - first.at),
        _ => SimStart::OnlineBeforeStart,
    }
}

/// When a real device must be powered on for a replay from the first frame of a transcript that
/// begins with its power-up: `(earliest, latest)` after the start. Its first duplicate MAC ID
/// request must come after the stimulus recorded before it and no later than `tolerance` after
/// its own recorded time. `None` when the transcript has no duplicate MAC ID request from it.
#[must_use]
pub fn power_on_window(
    entries: &[LogEntry],
    device: MacId,
    tolerance: Duration,
) -> Option<(Duration, Duration)> {
    let first = entries.first()?;
    let i = first_check(entries, device)?;
    let earliest = entries[..i]
        .iter()
        .rev()
        .find(|e| !is_from_device(&e.frame, device))
        .map_or(Duration::ZERO, |e| e.at - first.at);
    Some((earliest, entries[i].at - first.at + tolerance))
}

/// The note `replay` prints before a replay from the first frame against a real device whose
/// power-up the transcript holds: when to power it on, and the alternative.
#[must_use]
pub fn power_on_note(entries: &[LogEntry], device: MacId, tolerance: Duration) -> Option<String> {
    let (earliest, latest) = power_on_window(entries, device, tolerance)?;
    Some(format!(
        "note: the transcript begins with MAC {device}'s power-up: power it on between {} and {} after the replay starts (its first duplicate MAC ID request is due then, --tolerance {}); a device already on-line: --from-online; powered on later: --from-online=wait",
        seconds(earliest),
        seconds(latest),
        seconds(tolerance)
    ))
}

/// `true` for the device's I/O messages whose data `--ignore-data io` leaves out: Group 1
/// messages 12-15 with data (protocol §1.3).
fn is_io_data(frame: &CanFrame) -> bool {
    let io = [
        Group1MessageId::MULTICAST_POLL_RESPONSE,
        Group1MessageId::COS_CYCLIC,
        Group1MessageId::BIT_STROBE_RESPONSE,
        Group1MessageId::POLL_RESPONSE,
    ];
    matches!(Identifier::decode(frame.id()), Identifier::Group1 { message, .. } if io.contains(&message))
        && !frame.data().is_empty()
}

/// The devices of a transcript: the MACs that sent a device's frames (Group 1 messages, explicit
/// responses, Group 2 message 3), in order of first appearance. Duplicate MAC ID checks are left
/// out: masters send them too.
#[must_use]
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
/// Group 2 Only port or an explicit connection (protocol §3.1: a request's header carries the
/// requester's MAC).
#[must_use]
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
/// device answered with success, less those of its successful Releases (protocol §3.4). A replay
/// releases this when it ends, as every command does.
#[must_use]
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
                // Unfragmented [hdr] service class instance choice ... (8/8 body, protocol §3.4).
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
    if entries.is_empty() {
        return Err(HarnessError::EmptyTranscript);
    }
    let from_device = entries.iter().filter(|e| is_from_device(&e.frame, device)).count();
    if from_device == 0 {
        return Err(nothing_from(entries, device));
    }
    let start = match opts.from_online {
        Some(FromOnline::Now) => online_index(entries, device),
        Some(FromOnline::Wait) | None => 0,
    };
    if !entries[start..].iter().any(|e| is_from_device(&e.frame, device)) {
        return Err(HarnessError::NothingCompared(format!(
            "--from-online skips the transcript's start-up (its first {start} frames, up to MAC {device}'s on-line instant), and nothing from MAC {device} is left to compare"
        )));
    }
    let mut run = Run::new(session, entries, opts);
    let start = match opts.from_online {
        Some(FromOnline::Wait) => run.wait_for_power_up()?,
        _ => {
            run.skip(start);
            run.anchor = Some((run.session.now(), entries[start].at));
            start
        }
    };
    for (k, e) in entries.iter().enumerate().skip(start) {
        if is_from_device(&e.frame, device) {
            run.expect(k)?;
        } else {
            run.stimulus(k)?;
        }
    }
    run.settle()?;
    let summary = run.summary;
    if summary.expected + summary.not_compared == 0 {
        return Err(HarnessError::NothingCompared(format!("no frame from MAC {device} was compared")));
    }
    Ok(summary)
}

/// The error of a transcript with no frame from `device`, naming the transcript's devices.
fn nothing_from(entries: &[LogEntry], device: MacId) -> HarnessError {
    let devices = transcript_devices(entries);
    let whose = match devices.as_slice() {
        [] => "the transcript has no device frames at all".to_string(),
        [one] => format!("the transcript's device is MAC {one} (--mac {one})"),
        many => format!(
            "the transcript's devices are MAC {}",
            many.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
        ),
    };
    HarnessError::NothingCompared(format!(
        "the transcript has no frame from MAC {device}, so replaying it would compare nothing of the device under test: {whose}"
    ))
}

/// A replay in progress.
struct Run<'s, 'b, 'e> {
    session: &'s mut Session<'b>,
    entries: &'e [LogEntry],
    opts: &'e ReplayOptions,
    /// The transcript read up to the frame being replayed (for the meaning of the next).
    expected_decoder: Decoder,
    /// (bus instant, transcript instant) that coincide: where the transcript's clock is pinned.
    anchor: Option<(Instant, Instant)>,
    summary: ReplaySummary,
}

impl<'s, 'b, 'e> Run<'s, 'b, 'e> {
    fn new(session: &'s mut Session<'b>, entries: &'e [LogEntry], opts: &'e ReplayOptions) -> Self {
        Run {
            session,
            entries,
            opts,
            expected_decoder: Decoder::new(),
            anchor: None,
            summary: ReplaySummary {
                frames: entries.len(),
                expected: 0,
                not_compared: 0,
                stimulus: 0,
                skipped: 0,
            },
        }
    }

    /// Skips the transcript's first `n` frames (read for the meaning of the later ones).
    fn skip(&mut self, n: usize) {
        for e in &self.entries[..n] {
            self.expected_decoder.decode(&e.frame);
        }
        self.summary.skipped = n;
    }

    /// The bus instant of transcript instant `at`.
    fn due(&mut self, at: Instant) -> Instant {
        let (bus, transcript) = match self.anchor {
            Some(a) => a,
            None => (self.session.now(), at),
        };
        bus + (at - transcript)
    }

    fn shown_entry(&self, k: usize) -> ShownFrame {
        let e = &self.entries[k];
        ShownFrame {
            line: Some(e.line),
            time: time_text(e.at),
            frame: e.frame.to_string(),
            meaning: self.expected_decoder.clone().decode(&e.frame).text(),
        }
    }

    fn actual(&self, i: usize) -> ShownFrame {
        let r = self.session.record(i);
        ShownFrame {
            line: None,
            time: time_text(r.at),
            frame: r.frame.to_string(),
            meaning: r.meaning.clone(),
        }
    }

    /// The transcript frames before `k` (at most [`CONTEXT_FRAMES`]), decoded in order.
    fn context(&self, k: usize) -> Vec<ShownFrame> {
        let mut dec = Decoder::new();
        let from = k.saturating_sub(CONTEXT_FRAMES);
        let mut shown = Vec::new();
        for (j, e) in self.entries[..k].iter().enumerate() {
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
    }

    fn diverge(
        &self,
        k: usize,
        reason: String,
        expected: Option<ShownFrame>,
        actual: Option<usize>,
    ) -> HarnessError {
        let mut reason = reason;
        if let Some(i) = actual.filter(|_| self.opts.from_online != Some(FromOnline::Wait)) {
            if DuplicateMacCheck::request_in(&self.session.record(i).frame) == Some(self.opts.device) {
                reason.push_str(
                    "; the device is running its duplicate MAC ID check: it was powered on at another moment than the transcript's (power it on at the recorded time, or replay with --from-online=wait; --from-online for a device already on-line)",
                );
            }
        }
        HarnessError::Divergence(Box::new(Divergence {
            index: k,
            total: self.entries.len(),
            reason,
            expected,
            actual: actual.map(|i| self.actual(i)),
            before: self.context(k),
        }))
    }

    /// Transcript frame `k` is the device's: the next device frame must be it.
    fn expect(&mut self, k: usize) -> Result<(), HarnessError> {
        let device = self.opts.device;
        let entries = self.entries;
        let e = &entries[k];
        let due = self.due(e.at);
        let deadline = due.max(self.session.now()) + self.opts.tolerance;
        loop {
            let Some(i) = self.session.next(deadline)? else {
                let reason =
                    format!("the device sent nothing within {} of the recorded time", self.opts.tolerance);
                return Err(self.diverge(k, reason, Some(self.shown_entry(k)), None));
            };
            let rec = self.session.record(i).clone();
            if rec.origin == Origin::Local {
                continue;
            }
            if !is_from_device(&rec.frame, device) {
                self.session.set_verdict(i, Verdict::Info("other traffic, not compared".into()));
                continue;
            }
            let masked = self.opts.ignore_io_data && is_io_data(&e.frame);
            if masked && rec.frame.id() == e.frame.id() && rec.frame.data().len() == e.frame.data().len() {
                let note = format!(
                    "not compared: I/O data ignored (--ignore-data io); identifier and length as transcript line {}, which has {}",
                    e.line, e.frame
                );
                self.session.set_verdict(i, Verdict::Info(note));
                self.expected_decoder.decode(&e.frame);
                self.summary.not_compared += 1;
                return Ok(());
            }
            if rec.frame == e.frame {
                self.expected_decoder.decode(&e.frame);
                self.session.set_verdict(i, Verdict::Ok(format!("as transcript line {}", e.line)));
                self.summary.expected += 1;
                return Ok(());
            }
            self.session.set_verdict(i, Verdict::fail(format!("transcript line {} has {}", e.line, e.frame)));
            let reason = if masked {
                "the device sent a different identifier or length (its I/O data is not compared)".to_string()
            } else {
                "the device sent a different frame".to_string()
            };
            return Err(self.diverge(k, reason, Some(self.shown_entry(k)), Some(i)));
        }
    }

    /// Transcript frame `k` is stimulus: sent at its time, after checking nothing of the device
    /// came before it.
    fn stimulus(&mut self, k: usize) -> Result<(), HarnessError> {
        let entries = self.entries;
        let e = &entries[k];
        let due = self.due(e.at);
        while let Some(i) = self.session.next(due)? {
            let rec = self.session.record(i).clone();
            if rec.origin == Origin::Local {
                continue;
            }
            if is_from_device(&rec.frame, self.opts.device) {
                self.session.set_verdict(i, Verdict::fail("not in the transcript at this point"));
                let reason = "the device sent a frame the transcript does not have here (next in the transcript is stimulus)";
                return Err(self.diverge(k, reason.into(), Some(self.shown_entry(k)), Some(i)));
            }
            self.session.set_verdict(i, Verdict::Info("other traffic, not compared".into()));
        }
        self.session.send(&e.frame)?;
        self.expected_decoder.decode(&e.frame);
        self.summary.stimulus += 1;
        Ok(())
    }

    /// Watches `settle` after the last frame: nothing more may come from the device.
    fn settle(&mut self) -> Result<(), HarnessError> {
        let end = self.session.now() + self.opts.settle;
        while let Some(i) = self.session.next(end)? {
            let rec = self.session.record(i).clone();
            if rec.origin == Origin::Remote && is_from_device(&rec.frame, self.opts.device) {
                self.session.set_verdict(i, Verdict::fail("after the end of the transcript"));
                let reason = format!(
                    "the device sent a frame after the transcript's last one (within {})",
                    self.opts.settle
                );
                return Err(self.diverge(self.entries.len(), reason, None, Some(i)));
            }
            if rec.origin == Origin::Remote {
                self.session.set_verdict(i, Verdict::Info("other traffic, not compared".into()));
            }
        }
        Ok(())
    }

    /// `--from-online=wait`: waits for the device's first duplicate MAC ID request, however long
    /// it takes (a stop request ends the wait). With the device's check in the transcript, that
    /// request is compared with the transcript's first one and the replay goes on after it, timed
    /// from it; otherwise the replay waits until the device is on-line (two intervals after its
    /// first request, protocol §7.1) and starts at the first frame. Returns the index to go on from.
    fn wait_for_power_up(&mut self) -> Result<usize, HarnessError> {
        let device = self.opts.device;
        let recorded = first_check(self.entries, device);
        let seen = loop {
            let until = self.session.now() + Duration::from_secs(3600);
            let Some(i) = self.session.next(until)? else { continue };
            let rec = self.session.record(i).clone();
            if rec.origin == Origin::Local {
                continue;
            }
            if DuplicateMacCheck::request_in(&rec.frame) == Some(device) {
                break (i, rec);
            }
            self.session.set_verdict(
                i,
                Verdict::Info("before the device's power-up (--from-online=wait), not compared".into()),
            );
        };
        let (i, rec) = seen;
        if let Some(r) = recorded {
            self.skip(r);
            let entries = self.entries;
            let e = &entries[r];
            if rec.frame != e.frame {
                self.session
                    .set_verdict(i, Verdict::fail(format!("transcript line {} has {}", e.line, e.frame)));
                let reason = "the device's duplicate MAC ID check is not the transcript's (another vendor ID or serial number: another device)";
                return Err(self.diverge(r, reason.into(), Some(self.shown_entry(r)), Some(i)));
            }
            self.session.set_verdict(
                i,
                Verdict::Ok(format!("as transcript line {} (the device's power-up)", e.line)),
            );
            self.expected_decoder.decode(&e.frame);
            self.summary.expected += 1;
            self.anchor = Some((rec.at, e.at));
            return Ok(r + 1);
        }
        self.session.set_verdict(i, Verdict::Info("the device's power-up, not in the transcript".into()));
        let online = rec.at + DUP_MAC_INTERVAL + DUP_MAC_INTERVAL;
        while let Some(j) = self.session.next(online)? {
            if self.session.record(j).origin == Origin::Remote {
                self.session
                    .set_verdict(j, Verdict::Info("during the device's power-up, not compared".into()));
            }
        }
        let first = self.entries[0].at;
        self.anchor = Some((self.session.now(), first));
        Ok(0)
    }
}

/// The log line of a transcript entry (for reports).
#[must_use]
pub fn entry_line(e: &LogEntry) -> String {
    format_line(e.at, &e.iface, &e.frame)
}

/// `true` when `frame` is one the device at `mac` produces (expected in a replay).
#[must_use]
pub fn is_expected(frame: &CanFrame, mac: MacId) -> bool {
    is_from_device(frame, mac)
}

#[cfg(test)]
mod tests {
    use super::*;
    use can_io::log::parse_log;

    /// The start of a `connect` transcript (protocol §2 frames 0-7): the master's and the device's
    /// duplicate MAC ID checks, 1 s apart, then the UCMM probe and the Allocate.
    const BRING_UP: &str = "\
(0.000) sim 407#00010004030201
(1.000) sim 407#00010004030201
(2.000) sim 42F#00341278563412
(3.000) sim 42F#00341278563412
(4.000) sim 780#054B0034
(4.500) sim 780#054B0034
(5.000) sim 42E#004B03010100
(5.001) sim 42B#00CB00
";

    fn entries(text: &str) -> Vec<LogEntry> {
        parse_log(text, "t.log").unwrap()
    }

    fn mac(n: u8) -> MacId {
        MacId::new(n).unwrap()
    }

    #[test]
    fn the_start_up_ends_one_interval_after_the_devices_last_request() {
        let e = entries(BRING_UP);
        assert_eq!(online_index(&e, mac(5)), 4, "the UCMM open at 4 s, 1 s after the second request");
        // A transcript without the device's check has no start-up.
        assert_eq!(online_index(&e[4..], mac(5)), 0);
        // One that ends before the device is on-line is all start-up.
        assert_eq!(online_index(&e[..4], mac(5)), 4);
    }

    #[test]
    fn the_power_on_window_runs_from_the_stimulus_before_the_check_to_its_tolerance() {
        let e = entries(BRING_UP);
        let window = power_on_window(&e, mac(5), Duration::from_secs(1));
        assert_eq!(window, Some((Duration::from_secs(1), Duration::from_secs(3))));
        assert_eq!(power_on_window(&e[4..], mac(5), Duration::from_secs(1)), None);
    }

    #[test]
    fn the_simulated_device_meets_the_transcript_as_it_begins() {
        let e = entries(BRING_UP);
        assert_eq!(sim_start(&e, mac(5), None), SimStart::PowerOnAt(Duration::from_secs(2)));
        assert_eq!(sim_start(&e[4..], mac(5), None), SimStart::OnlineBeforeStart);
        assert_eq!(sim_start(&e, mac(5), Some(FromOnline::Now)), SimStart::OnlineBeforeStart);
        assert_eq!(sim_start(&e, mac(5), Some(FromOnline::Wait)), SimStart::PowerOnAtStart);
    }

    #[test]
    fn io_data_is_group_1_messages_12_to_15_with_data() {
        let f = |id, data: &[u8]| CanFrame::from_raw(id, data).unwrap();
        assert!(is_io_data(&f(0x3C5, &[0x00, 1, 2])), "poll response");
        assert!(is_io_data(&f(0x345, &[1])), "change of state");
        assert!(is_io_data(&f(0x385, &[1])), "bit-strobe response");
        assert!(is_io_data(&f(0x305, &[1])), "multicast poll response");
        assert!(!is_io_data(&f(0x3C5, &[])), "an acknowledgement has no data to ignore");
        assert!(!is_io_data(&f(0x42B, &[0x00, 0x8E, 0x34, 0x12])), "explicit response");
        assert!(!is_io_data(&f(0x2C5, &[1])), "a dynamic connection's message 11");
    }
}
