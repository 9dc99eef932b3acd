//! A session on a bus: every frame seen is recorded with its time, direction, decoded meaning and
//! verdict, and written to the `--log` file as it comes.
//!
//! ## Frames that are not judged
//!
//! A frame from the device that nothing in the session expects is a failure, but for two stretches
//! of the session where such a frame can only be recognised by its time, not by its content:
//!
//! - before the session sent its first request (any frame but a duplicate MAC ID check): the frame
//!   cannot answer anything this session asked; it answers a request made before the command
//!   started (a previous run that was interrupted);
//! - once the session winds down ([`Session::wind_down`]: a stop was seen, or the command took its
//!   stop watch away to give the device back): an answer to the request the stop cut short, or
//!   to one the command no longer waits for.
//!
//! [`Session::not_judged`] says which stretch a record falls in; the verdict is then
//! [`Verdict::Info`] `not judged: WHY` instead of a failure ([`crate::client::judge_other`]).

use crate::decode::Decoder;
use crate::error::MasterError;
use crate::stop::Stop;
use can_io::bus::{Bus, Origin};
use can_io::log::LogWriter;
use can_io::trace::Direction;
use devicenet::{CanFrame, Duration, Identifier, Instant, MacId};

/// How long the session waits on the bus at a time while a [`Stop`] is set, so a stop is seen
/// within this time even in a long wait.
pub const STOP_CHECK: Duration = Duration::from_millis(50);

/// The verdict on one frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Sent by this program.
    Sent,
    /// Checked and as the protocol requires; the note says what was verified.
    Ok(String),
    /// Checked and wrong: each reason.
    Fail(Vec<String>),
    /// Not part of the exchange under test (other traffic); not checked.
    Info(String),
    /// Not looked at (yet).
    Unchecked,
}

impl Verdict {
    /// A failure with one reason.
    pub fn fail(reason: impl Into<String>) -> Verdict {
        Verdict::Fail(vec![reason.into()])
    }

    /// Adds `reasons`: an empty list keeps the verdict, otherwise it becomes (or stays) a failure.
    pub fn with_failures(self, reasons: Vec<String>) -> Verdict {
        if reasons.is_empty() {
            return self;
        }
        match self {
            Verdict::Fail(mut r) => {
                r.extend(reasons);
                Verdict::Fail(r)
            }
            _ => Verdict::Fail(reasons),
        }
    }

    /// `true` for [`Verdict::Fail`].
    pub fn is_failure(&self) -> bool {
        matches!(self, Verdict::Fail(_))
    }

    /// The short form shown in the table's verdict column.
    pub fn label(&self) -> String {
        match self {
            Verdict::Sent => "sent".into(),
            Verdict::Ok(_) => "ok".into(),
            Verdict::Fail(r) => format!("FAIL: {}", r.join("; ")),
            Verdict::Info(_) => "-".into(),
            Verdict::Unchecked => "-".into(),
        }
    }
}

/// One frame seen on the bus.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Record {
    /// 0-based position in the session.
    pub index: usize,
    /// When it completed on the bus.
    pub at: Instant,
    /// Who sent it.
    pub origin: Origin,
    /// The frame.
    pub frame: CanFrame,
    /// Its DeviceNet meaning.
    pub meaning: String,
    /// The verdict.
    pub verdict: Verdict,
}

impl Record {
    /// `M->` for this program's frames, `S->` for frames of `device`, `?->` for anyone else.
    pub fn direction(&self, device: Option<MacId>) -> &'static str {
        match self.origin {
            Origin::Local => "M->",
            Origin::Remote if device.is_some_and(|d| is_from_device(&self.frame, d)) => "S->",
            Origin::Remote => "?->",
        }
    }
}

/// `true` for frames only device `mac` produces: its Group 1 messages, its Group 2 message 3
/// (explicit/unconnected responses) and 7 (duplicate MAC ID checks), and Group 3 messages with it
/// as the source.
pub fn is_from_device(frame: &CanFrame, mac: MacId) -> bool {
    match Identifier::decode(frame.id()) {
        Identifier::Group1 { source, .. } | Identifier::Group3 { source, .. } => source == mac,
        Identifier::Group2 { mac: m, message } => {
            m == mac
                && matches!(
                    message,
                    devicenet::Group2Message::ExplicitResponse | devicenet::Group2Message::DuplicateMacCheck
                )
        }
        Identifier::Group4 { .. } | Identifier::Invalid(_) => false,
    }
}

/// A bus with its transcript. See the [module docs](self).
pub struct Session<'b> {
    bus: &'b mut dyn Bus,
    decoder: Decoder,
    records: Vec<Record>,
    /// The index of `records[0]`: records before it were forgotten ([`Session::forget_records_before`]).
    base: usize,
    /// Failures among the forgotten records.
    forgotten_failures: usize,
    log: Option<LogWriter>,
    stop: Option<Stop>,
    /// The index of the first record after the session's first request; `None` before it.
    asked_from: Option<usize>,
    /// From which record on, and why, the session winds down.
    wind_down: Option<(usize, String)>,
}

impl<'b> Session<'b> {
    /// A session on `bus`, without a log file.
    pub fn new(bus: &'b mut dyn Bus) -> Session<'b> {
        Session {
            bus,
            decoder: Decoder::new(),
            records: Vec::new(),
            base: 0,
            forgotten_failures: 0,
            log: None,
            stop: None,
            asked_from: None,
            wind_down: None,
        }
    }

    /// Writes every frame to `log` as it is seen.
    pub fn set_log(&mut self, log: LogWriter) {
        self.log = Some(log);
    }

    /// Ends every wait on the bus with [`MasterError::Interrupted`] once `stop` is requested.
    pub fn set_stop(&mut self, stop: Stop) {
        self.stop = Some(stop);
    }

    /// Removes the stop request watch (to release the device and flush at the end of a command,
    /// interrupted or not); returns it. The session winds down from here ([`Session::wind_down`]).
    pub fn take_stop(&mut self) -> Option<Stop> {
        let reason = match self.stop_requested() {
            Some(signal) => format!("stopped by {}", crate::stop::signal_name(signal)),
            None => "the command ends and gives the device back".to_string(),
        };
        self.wind_down(reason);
        self.stop.take()
    }

    /// Marks the session as winding down from the next record on, for `reason` (the first reason
    /// given is kept): frames nothing expects are no longer judged (see the [module docs](self)).
    pub fn wind_down(&mut self, reason: impl Into<String>) {
        if self.wind_down.is_none() {
            self.wind_down = Some((self.next_index(), reason.into()));
        }
    }

    /// Why record `i` is not judged when nothing expects it: it arrived before the session's first
    /// request, or while the session wound down; `None` when it must be judged (or is this
    /// program's own frame). See the [module docs](self).
    pub fn not_judged(&self, i: usize) -> Option<String> {
        if self.get(i).is_some_and(|r| r.origin == Origin::Local) {
            return None;
        }
        if self.asked_from.is_none_or(|from| i < from) {
            return Some(
                "it came before this program asked anything: the answer to a request made before the command started"
                    .into(),
            );
        }
        match &self.wind_down {
            Some((from, reason)) if i >= *from => {
                Some(format!("it came while the command wound down ({reason})"))
            }
            _ => None,
        }
    }

    /// The signal that asked this session to stop, if one did.
    pub fn stop_requested(&self) -> Option<i32> {
        self.stop.as_ref().and_then(Stop::requested)
    }

    /// The bus's clock.
    pub fn now(&mut self) -> Instant {
        self.bus.now()
    }

    /// The bus interface name.
    pub fn bus_name(&self) -> &str {
        self.bus.name()
    }

    /// The bus controller's error state, where the bus can tell it ([`Bus::error_state`]).
    pub fn error_state(&mut self) -> Option<can_io::bus::health::ErrorReport> {
        self.bus.error_state()
    }

    /// Queues a frame; it is recorded when it comes back from the bus. The first frame that is not
    /// a duplicate MAC ID check is the session's first request ([`Session::not_judged`]).
    pub fn send(&mut self, frame: &CanFrame) -> Result<(), MasterError> {
        self.bus.send(frame)?;
        let check = matches!(
            Identifier::decode(frame.id()),
            Identifier::Group2 { message: devicenet::Group2Message::DuplicateMacCheck, .. }
        );
        if !check && self.asked_from.is_none() {
            self.asked_from = Some(self.next_index());
        }
        Ok(())
    }

    /// Waits for the next frame until `deadline`, records it and returns its index; `None` at the
    /// deadline. This program's own frames are recorded with [`Verdict::Sent`].
    /// With a [`Stop`] set, the wait is cut in [`STOP_CHECK`] slices and ends with
    /// [`MasterError::Interrupted`] when a stop is requested.
    pub fn next(&mut self, deadline: Instant) -> Result<Option<usize>, MasterError> {
        let ev = loop {
            let Some(stop) = &self.stop else {
                match self.bus.recv(deadline)? {
                    Some(ev) => break ev,
                    None => return Ok(None),
                }
            };
            if let Some(signal) = stop.requested() {
                self.wind_down(format!("stopped by {}", crate::stop::signal_name(signal)));
                return Err(MasterError::Interrupted { signal });
            }
            let slice = (self.bus.now() + STOP_CHECK).min(deadline);
            match self.bus.recv(slice)? {
                Some(ev) => break ev,
                None if slice >= deadline => return Ok(None),
                None => {}
            }
        };
        let meaning = self.decoder.decode(&ev.frame).text();
        if let Some(log) = &mut self.log {
            let direction = if ev.origin == Origin::Local { Direction::Tx } else { Direction::Rx };
            log.write_dir(ev.at, self.bus.name(), direction, &ev.frame)
                .map_err(|source| MasterError::LogWrite { source })?;
        }
        let index = self.base + self.records.len();
        let verdict = if ev.origin == Origin::Local { Verdict::Sent } else { Verdict::Unchecked };
        self.records.push(Record { index, at: ev.at, origin: ev.origin, frame: ev.frame, meaning, verdict });
        Ok(Some(index))
    }

    /// Waits until `deadline`, recording everything; frames not from this program are passed to
    /// `other` to be judged.
    pub fn idle_until(
        &mut self,
        deadline: Instant,
        mut other: impl FnMut(&mut Session<'b>, usize) -> Result<(), MasterError>,
    ) -> Result<(), MasterError> {
        while let Some(i) = self.next(deadline)? {
            if self.record(i).origin == Origin::Remote {
                other(self, i)?;
            }
        }
        Ok(())
    }

    /// Record `i`.
    ///
    /// # Panics
    ///
    /// When `i` was never returned by [`Session::next`] or was forgotten
    /// ([`Session::forget_records_before`]); [`Session::get`] is the checked form.
    pub fn record(&self, i: usize) -> &Record {
        &self.records[i - self.base]
    }

    /// Record `i`, if it is kept.
    pub fn get(&self, i: usize) -> Option<&Record> {
        i.checked_sub(self.base).and_then(|k| self.records.get(k))
    }

    /// Sets the verdict of record `i` (nothing for a record not kept).
    pub fn set_verdict(&mut self, i: usize, verdict: Verdict) {
        if let Some(r) = i.checked_sub(self.base).and_then(|k| self.records.get_mut(k)) {
            r.verdict = verdict;
        }
    }

    /// Every frame seen so far and still kept (all of them unless
    /// [`Session::forget_records_before`] was used); `records()[k].index` is `k` plus
    /// [`Session::first_kept`].
    pub fn records(&self) -> &[Record] {
        &self.records
    }

    /// The index of the first record kept (0 unless records were forgotten).
    pub fn first_kept(&self) -> usize {
        self.base
    }

    /// The index the next record will get.
    pub fn next_index(&self) -> usize {
        self.base + self.records.len()
    }

    /// Drops the records before index `n` (a long-running scanner keeps its memory bounded);
    /// indices of the records kept do not change, and failures among the dropped ones still count
    /// in [`Session::failures`]. The log file has every frame regardless.
    pub fn forget_records_before(&mut self, n: usize) {
        let drop = n.saturating_sub(self.base).min(self.records.len());
        if drop == 0 {
            return;
        }
        self.forgotten_failures += self.records[..drop].iter().filter(|r| r.verdict.is_failure()).count();
        self.records.drain(..drop);
        self.base += drop;
    }

    /// Frames whose verdict is a failure (the forgotten ones included).
    pub fn failures(&self) -> usize {
        self.forgotten_failures + self.records.iter().filter(|r| r.verdict.is_failure()).count()
    }

    /// The decoder (what it learned: connection sizes).
    pub fn decoder(&mut self) -> &mut Decoder {
        &mut self.decoder
    }

    /// Flushes the log file.
    pub fn flush(&mut self) -> Result<(), MasterError> {
        if let Some(log) = &mut self.log {
            log.flush().map_err(|source| MasterError::LogWrite { source })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use can_io::bus::Bitrate;

    use can_io::sim::SimBus;

    /// A bus that echoes what is sent and delivers the frames a test puts on it (through a
    /// [`Feed`]) as another node's.
    struct Script {
        now: Instant,
        queue: Feed,
    }

    type Feed = std::rc::Rc<std::cell::RefCell<std::collections::VecDeque<can_io::bus::BusEvent>>>;

    fn script() -> (Script, Feed) {
        let feed = Feed::default();
        (Script { now: Instant::ZERO, queue: feed.clone() }, feed)
    }

    fn from_device(feed: &Feed, frame: CanFrame) {
        feed.borrow_mut().push_back(can_io::bus::BusEvent {
            at: Instant::ZERO,
            frame,
            origin: Origin::Remote,
        });
    }

    impl Bus for Script {
        fn name(&self) -> &str {
            "script"
        }
        fn now(&mut self) -> Instant {
            self.now
        }
        fn send(&mut self, frame: &CanFrame) -> Result<(), can_io::bus::BusError> {
            let ev = can_io::bus::BusEvent { at: self.now, frame: *frame, origin: Origin::Local };
            self.queue.borrow_mut().push_back(ev);
            Ok(())
        }
        fn recv(
            &mut self,
            deadline: Instant,
        ) -> Result<Option<can_io::bus::BusEvent>, can_io::bus::BusError> {
            let ev = self.queue.borrow_mut().pop_front();
            match ev {
                Some(ev) => Ok(Some(can_io::bus::BusEvent { at: self.now, ..ev })),
                None => {
                    self.now = self.now.max(deadline);
                    Ok(None)
                }
            }
        }
    }

    /// MAC 5's Release response to master 0: what a request of an earlier run is answered with.
    fn release_answer() -> CanFrame {
        CanFrame::from_raw(0x42B, &[0x00, 0xCC]).unwrap()
    }

    /// The master's duplicate MAC ID check (it asks nothing of any device).
    fn dup_mac_check() -> CanFrame {
        CanFrame::from_raw(0x407, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]).unwrap()
    }

    /// Get_Attribute_Single Identity 1 / 7 to MAC 5.
    fn request() -> CanFrame {
        CanFrame::from_raw(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x07]).unwrap()
    }

    /// Records everything queued, judging the device's frames as nothing expects them; their
    /// verdicts.
    fn judge_all(s: &mut Session<'_>) -> Vec<Verdict> {
        let mut verdicts = Vec::new();
        loop {
            let until = s.now() + Duration::from_millis(10);
            let Some(i) = s.next(until).unwrap() else { break };
            if s.record(i).origin == Origin::Remote {
                crate::client::judge_other(s, i, MacId::from_low_bits(5));
                verdicts.push(s.record(i).verdict.clone());
            }
        }
        verdicts
    }

    fn not_judged(v: &Verdict, why: &str) -> bool {
        matches!(v, Verdict::Info(n) if n.starts_with("not judged: ") && n.contains(why))
    }

    #[test]
    fn an_unexpected_frame_while_the_command_runs_fails() {
        let (mut bus, feed) = script();
        let mut s = Session::new(&mut bus);
        s.send(&request()).unwrap();
        judge_all(&mut s);
        from_device(&feed, release_answer());
        assert_eq!(judge_all(&mut s), [Verdict::fail("unexpected frame from the device at this point")]);
        assert_eq!(s.failures(), 1);
    }

    #[test]
    fn a_frame_before_the_first_request_is_not_judged() {
        let (mut bus, feed) = script();
        let mut s = Session::new(&mut bus);
        // Waiting in the buffer when the command starts, and during its network access.
        from_device(&feed, release_answer());
        s.send(&dup_mac_check()).unwrap();
        from_device(&feed, release_answer());
        let v = judge_all(&mut s);
        assert_eq!(v.len(), 2);
        assert!(v.iter().all(|v| not_judged(v, "before this program asked anything")), "{v:?}");
        assert_eq!(s.failures(), 0);
    }

    #[rstest::rstest]
    #[case::stop_seen(true)]
    #[case::stop_taken_at_the_end(false)]
    fn a_frame_while_the_session_winds_down_is_not_judged(#[case] seen: bool) {
        let (mut bus, feed) = script();
        let mut s = Session::new(&mut bus);
        let stop = Stop::new();
        s.set_stop(stop.clone());
        s.send(&request()).unwrap();
        judge_all(&mut s);
        stop.request(crate::stop::SIGINT);
        if seen {
            let until = s.now() + Duration::from_millis(10);
            let e = s.next(until).unwrap_err();
            assert!(matches!(e, MasterError::Interrupted { .. }), "{e}");
        }
        s.take_stop();
        // The answer to the poll the Ctrl-C cut short, during the Release.
        from_device(&feed, release_answer());
        let v = judge_all(&mut s);
        assert!(not_judged(&v[0], "while the command wound down (stopped by SIGINT)"), "{v:?}");
        assert_eq!(s.failures(), 0);
    }

    #[test]
    fn forgotten_records_keep_the_indices_and_the_failure_count() {
        let mut bus = SimBus::new(Bitrate::K500);
        let mut s = Session::new(&mut bus);
        for i in 0..5u8 {
            s.send(&CanFrame::from_raw(0x400 + u16::from(i), &[i]).unwrap()).unwrap();
            let at = s.now() + Duration::from_millis(10);
            s.next(at).unwrap();
        }
        s.set_verdict(1, Verdict::fail("bad"));
        s.forget_records_before(3);
        assert_eq!(s.first_kept(), 3);
        assert_eq!(s.records().len(), 2);
        assert_eq!(s.record(4).index, 4);
        assert!(s.get(2).is_none());
        assert_eq!(s.failures(), 1);
        s.forget_records_before(2);
        assert_eq!(s.first_kept(), 3);
        s.forget_records_before(100);
        assert_eq!((s.records().len(), s.next_index()), (0, 5));
    }
}
