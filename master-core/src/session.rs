//! A session on a bus: every frame seen is recorded with its time, direction, decoded meaning and
//! verdict, and written to the `--log` file as it comes.

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

    /// Removes the stop request watch (to release the device and flush after an interruption);
    /// returns it.
    pub fn take_stop(&mut self) -> Option<Stop> {
        self.stop.take()
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

    /// Queues a frame; it is recorded when it comes back from the bus.
    pub fn send(&mut self, frame: &CanFrame) -> Result<(), MasterError> {
        self.bus.send(frame)?;
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
