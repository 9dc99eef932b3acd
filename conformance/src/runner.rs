//! The machinery the checks share: a [`Runner`] owns the [`Master`] and the device facts learned
//! on the way, runs each check with its frames kept, and offers the raw exchanges the protocol
//! checks need (frames sent as built, answers collected and judged by the check) next to the
//! master's own checked exchanges.

use super::{Basis, CheckResult, Expectation, Grade, Measurement, SuiteOptions};
use super::{Category, DeviceIdentity, HarnessError, Observer, Timestamps};
use can_io::bus::Origin;
use devicenet::explicit::{BodyFormat, GeneralStatus, Header, Request, ServiceCode};
use devicenet::fragment::{next_count, FragmentByte, FragmentKind, IoReassembler};
use devicenet::id::Group1MessageId;
use devicenet::messages::{AllocateRequest, AllocationChoice, ReleaseRequest};
use devicenet::objects::class;
use devicenet::{CanFrame, CanId, Duration, Group2Message, Identifier, Instant, MacId};
use master_core::client::{ClientError, Port, Reply, ReplyBody, Transaction};
use master_core::decode::{self, hex};
use master_core::error::MasterError;
use master_core::master::{Answer, Master, MasterConfig};
use master_core::session::{is_from_device, Session, Verdict};

/// A value read, with the record of the response that carried it.
pub(crate) type Value = Option<(Vec<u8>, Option<usize>)>;

/// The outcome of an exchange (a timeout included) and the record that completed it.
pub(crate) type Outcome = (Result<Reply, ClientError>, Option<usize>);

/// What the suite learned about the device so far.
#[derive(Clone, Debug, Default)]
pub(crate) struct Facts {
    /// Vendor and serial from its duplicate MAC ID check, and its port.
    pub announced: Option<(u16, u32, u8)>,
    /// Poll connection produced / consumed sizes.
    pub produced: Option<u16>,
    pub consumed: Option<u16>,
    /// Connection 1 attribute 8: the longest explicit request it takes.
    pub explicit_consumed: Option<u16>,
    /// The output assembly instance (Connection 2 attribute 16).
    pub output_assembly: Option<u16>,
    /// A connection type the device lacks (for the release row of §3.4).
    pub lacking: Option<AllocationChoice>,
    /// The EPR the device applies for the suite's EPR.
    pub applied_epr: Option<u16>,
    /// The step between the EPRs applied for the suite's EPR and for 3 ms more (epr-round-trip):
    /// the device's timer resolution, as far as the rounding shows it (protocol §5.3).
    pub epr_step: Option<u16>,
}

/// A check being run: its expectations and measurements.
pub(crate) struct Check {
    expectations: Vec<Expectation>,
    measurements: Vec<Measurement>,
    start: usize,
    /// Why the frames' times cannot be judged on this transport, if they cannot.
    untimed: Option<&'static str>,
}

impl Check {
    /// Records an expectation: `ok` passes, otherwise it fails or, when the rule is not firm
    /// (`basis`), is advisory.
    pub fn expect(&mut self, basis: Basis, ok: bool, text: impl Into<String>, frame: Option<usize>) -> bool {
        let grade = match (ok, basis) {
            (true, _) => Grade::Pass,
            (false, Basis::Normative) => Grade::Fail,
            (false, Basis::Unconfirmed | Basis::Free) => Grade::Advisory,
        };
        self.expectations.push(Expectation { text: text.into(), grade, basis, frame });
        ok
    }

    /// A normative expectation.
    pub fn firm(&mut self, ok: bool, text: impl Into<String>, frame: Option<usize>) -> bool {
        self.expect(Basis::Normative, ok, text, frame)
    }

    /// Something that could not be exercised, or is worth a look: advisory.
    pub fn advise(&mut self, basis: Basis, text: impl Into<String>) {
        self.expectations.push(Expectation { text: text.into(), grade: Grade::Advisory, basis, frame: None });
    }

    /// An expectation on timing (an interval between frames, a latency, a watchdog's expiry):
    /// graded as [`Check::expect`] where the transport's timestamps show the device's timing;
    /// where they do not (SLCAN), advisory whatever the value, with the reason.
    pub fn timed(&mut self, basis: Basis, ok: bool, text: impl Into<String>, frame: Option<usize>) -> bool {
        match self.untimed {
            None => self.expect(basis, ok, text, frame),
            Some(why) => {
                let text = format!("{} (not judged: {why})", text.into());
                self.expectations.push(Expectation { text, grade: Grade::Advisory, basis, frame });
                ok
            }
        }
    }

    /// A measured value.
    pub fn measure(&mut self, name: impl Into<String>, value: f64, unit: &'static str) {
        self.measurements.push(Measurement { name: name.into(), value, unit });
    }
}

/// The suite's master and what it knows.
pub(crate) struct Runner<'s, 'b> {
    pub m: Master<'s, 'b>,
    /// Told about each check.
    observer: &'s mut dyn Observer,
    /// Why timing cannot be judged on this transport, if it cannot.
    untimed: Option<&'static str>,
    /// The device's identity as read.
    identity: DeviceIdentity,
    pub opts: SuiteOptions,
    pub facts: Facts,
    /// A strobe, COS or cyclic connection may be allocated: [`Runner::release_all`] releases them.
    pub io_allocated: bool,
    /// A MAC the suite uses as a second master.
    pub second: MacId,
    /// A MAC nobody should use (traffic to other nodes).
    pub bystander: MacId,
    results: Vec<CheckResult>,
}

/// The identifier of Group 2 message `message` of `mac`.
pub(crate) fn g2(mac: MacId, message: Group2Message) -> CanId {
    Identifier::group2(mac, message)
}

/// The first MAC not in `taken`, counting up from `from`.
fn free_mac(from: u8, taken: &[MacId]) -> MacId {
    (0..64u8)
        .map(|k| MacId::from_low_bits(from.wrapping_add(k)))
        .find(|m| !taken.contains(m))
        .unwrap_or(MacId::MAX)
}

impl<'s, 'b> Runner<'s, 'b> {
    pub fn new(
        session: &'s mut Session<'b>,
        config: MasterConfig,
        opts: SuiteOptions,
        timestamps: Timestamps,
        observer: &'s mut dyn Observer,
    ) -> Self {
        let second = free_mac(config.mac.as_raw().wrapping_add(1), &[config.mac, opts.target]);
        let bystander = free_mac(opts.target.as_raw().wrapping_add(1), &[config.mac, opts.target, second]);
        let mut m = Master::new(session, config);
        m.set_device(opts.target);
        Runner {
            m,
            observer,
            untimed: timestamps.timing_advisory(),
            identity: DeviceIdentity::default(),
            opts,
            facts: Facts::default(),
            io_allocated: false,
            second,
            bystander,
            results: Vec::new(),
        }
    }

    /// `true` where the transport's timestamps show the device's timing (not SLCAN).
    pub fn timing_judged(&self) -> bool {
        self.untimed.is_none()
    }

    /// The device under test.
    pub fn dut(&self) -> MacId {
        self.opts.target
    }

    /// The master's MAC.
    pub fn master_mac(&self) -> MacId {
        self.m.config.mac
    }

    pub fn second_master(&self) -> MacId {
        self.second
    }

    /// The device's identity as read so far.
    pub fn identity(&self) -> DeviceIdentity {
        self.identity.clone()
    }

    /// Notes identity values the bring-up read.
    pub fn note_identity(&mut self, attr: u8, value: Option<u16>) {
        if let Some(v) = value {
            self.identity.note(attr, &v.to_le_bytes());
        }
    }

    /// Whether the device sent anything at all in this run (its duplicate MAC ID check, any
    /// answer): the criterion for "no device answers at the MAC".
    pub fn device_heard(&self) -> bool {
        let dut = self.dut();
        self.m.session.records().iter().any(|r| r.origin == Origin::Remote && is_from_device(&r.frame, dut))
    }

    /// Tells the observer the current check waits on the bus (`what`).
    pub fn waiting(&mut self, what: &str) {
        self.observer.wait(what);
    }

    /// The end of a run, a complete or an early one: releases the connections (as the master, and
    /// as the second master when the device belongs to it) through the Group 2 Only port, unless
    /// `keep`. The session's stop watch is removed first, so an interrupted run still gives the
    /// device back. Nothing is released when the device was never heard. Returns what was done,
    /// in words.
    pub fn finish(&mut self, keep: bool, early: bool) -> Result<String, HarnessError> {
        // The stop is taken off the session, so the release below runs to its end.
        let _ = self.m.session.take_stop();
        let dut = self.dut();
        if keep {
            return Ok(format!("connections of MAC {dut} kept allocated (--keep)"));
        }
        if !self.device_heard() {
            return Ok("nothing to release: the device never answered".into());
        }
        if early {
            self.observer.wait("releasing the device");
        }
        self.release_all()?;
        Ok(format!("poll and explicit connections of MAC {dut} released through the Group 2 Only port"))
    }

    /// The results so far, handed over at the end.
    pub fn take_results(&mut self) -> Vec<CheckResult> {
        std::mem::take(&mut self.results)
    }

    /// The number of records so far.
    pub fn mark(&self) -> usize {
        self.m.session.records().len()
    }

    /// The bus clock.
    pub fn now(&mut self) -> Instant {
        self.m.session.now()
    }

    /// Runs one check. Errors other than a failing bus end the check as a finding (a firm
    /// failure: the device did not answer where it must); frames judged failures by the harness
    /// are findings too.
    pub fn run(
        &mut self,
        id: &'static str,
        title: &'static str,
        category: Category,
        section: &'static str,
        body: impl FnOnce(&mut Self, &mut Check) -> Result<(), HarnessError>,
    ) -> Result<(), HarnessError> {
        // A stop asked for between two checks ends the run before the next one.
        if let Some(signal) = self.m.session.stop_requested() {
            return Err(MasterError::Interrupted { signal }.into());
        }
        self.observer.start(self.results.len() + 1, id, title);
        let mut c = Check {
            expectations: Vec::new(),
            measurements: Vec::new(),
            start: self.mark(),
            untimed: self.untimed,
        };
        match body(self, &mut c) {
            Ok(()) => {}
            Err(HarnessError::Master(MasterError::Bus(e))) => return Err(e.into()),
            // Interrupted: the check did not complete and is not reported.
            Err(e @ HarnessError::Master(MasterError::Interrupted { .. })) => return Err(e),
            Err(e) => {
                c.firm(false, format!("stopped: {e}"), None);
            }
        }
        let end = self.mark();
        let records = self.m.session.records();
        for r in records.get(c.start..end).unwrap_or(&[]) {
            if let Verdict::Fail(reasons) = &r.verdict {
                let already = c.expectations.iter().any(|e| e.frame == Some(r.index));
                if !already {
                    c.expectations.push(Expectation {
                        text: format!("frame #{} {}: {}", r.index, r.frame, reasons.join("; ")),
                        grade: Grade::Fail,
                        basis: Basis::Normative,
                        frame: Some(r.index),
                    });
                }
            }
        }
        let grade = c.expectations.iter().map(|e| e.grade).max().unwrap_or(Grade::Pass);
        self.results.push(CheckResult {
            id,
            title,
            category,
            section,
            grade,
            expectations: c.expectations,
            measurements: c.measurements,
            frames: c.start..end,
        });
        if let Some(done) = self.results.last() {
            let frames = self.m.session.records().get(c.start..end).unwrap_or(&[]);
            self.observer.judged(done, frames);
        }
        Ok(())
    }

    // ----- frames -------------------------------------------------------------------------------

    /// Sends a frame as built.
    pub fn send(&mut self, id: CanId, data: &[u8]) -> Result<(), HarnessError> {
        let f = CanFrame::new(id, data).map_err(HarnessError::Frame)?;
        Ok(self.m.session.send(&f)?)
    }

    /// Collects the frames the device sends until `until`, for the caller to judge; other nodes'
    /// frames are judged as other traffic, the master's own are kept as sent.
    pub fn collect(&mut self, until: Instant) -> Result<Vec<usize>, HarnessError> {
        let dut = self.dut();
        let mut out = Vec::new();
        while let Some(i) = self.m.session.next(until)? {
            let rec = self.m.session.record(i);
            if rec.origin == Origin::Local {
                continue;
            }
            if is_from_device(&rec.frame, dut) {
                out.push(i);
            } else {
                self.m.session.set_verdict(i, Verdict::Info("other traffic".into()));
            }
        }
        Ok(out)
    }

    /// Waits `d`, expecting nothing from the device: every frame it sends fails. Returns how many.
    pub fn expect_silence(&mut self, c: &mut Check, d: Duration, what: &str) -> Result<usize, HarnessError> {
        if d >= Duration::from_secs(1) {
            self.waiting(&format!("listening {d} for silence"));
        }
        let until = self.now() + d;
        let got = self.collect(until)?;
        for &i in &got {
            self.m.session.set_verdict(i, Verdict::fail(format!("the device answered {what}")));
        }
        c.firm(
            got.is_empty(),
            if got.is_empty() {
                format!("silent to {what} for {d}")
            } else {
                format!("answered {what} ({} frame(s))", got.len())
            },
            got.first().copied(),
        );
        Ok(got.len())
    }

    /// Sets the verdict of record `i`.
    pub fn verdict(&mut self, i: usize, v: Verdict) {
        self.m.session.set_verdict(i, v);
    }

    /// Record `i`'s time and data.
    pub fn rec(&self, i: usize) -> (Instant, CanFrame) {
        let r = self.m.session.record(i);
        (r.at, r.frame)
    }

    /// The most recent record sent by the master with identifier `id`, at or after `from`.
    pub fn last_sent(&self, id: CanId, from: usize) -> Option<usize> {
        let records = self.m.session.records();
        records
            .get(from..)?
            .iter()
            .rev()
            .find(|r| r.origin == Origin::Local && r.frame.id() == id)
            .map(|r| r.index)
    }

    // ----- explicit messaging ------------------------------------------------------------------

    /// A request through the master (every response frame checked); an error response is an answer.
    pub fn request(
        &mut self,
        port: Port,
        service: ServiceCode,
        class_id: u16,
        instance: u16,
        data: &[u8],
    ) -> Result<Answer, HarnessError> {
        let req = Request { service, class: class_id, instance, data };
        Ok(self.m.request(self.dut(), port, &req)?)
    }

    /// Get_Attribute_Single through the explicit connection. Identity values read are kept for
    /// the report.
    pub fn get(&mut self, class_id: u16, instance: u16, attribute: u8) -> Result<Answer, HarnessError> {
        let a =
            self.request(Port::Explicit, ServiceCode::GetAttributeSingle, class_id, instance, &[attribute])?;
        if let (class::IDENTITY, 1, ReplyBody::Success(d)) = (class_id, instance, &a.reply.body) {
            self.identity.note(attribute, d);
        }
        Ok(a)
    }

    /// Set_Attribute_Single through the explicit connection.
    pub fn set(
        &mut self,
        class_id: u16,
        instance: u16,
        attribute: u8,
        value: &[u8],
    ) -> Result<Answer, HarnessError> {
        let mut data = vec![attribute];
        data.extend_from_slice(value);
        self.request(Port::Explicit, ServiceCode::SetAttributeSingle, class_id, instance, &data)
    }

    /// A request sent as another master would (`master` in the header), checked the same way;
    /// returns the outcome (a timeout is an outcome here) and the completing record.
    pub fn request_as(
        &mut self,
        master: MacId,
        port: Port,
        req: &Request<'_>,
    ) -> Result<Outcome, HarnessError> {
        let mut tx = Transaction::new(
            self.dut(),
            master,
            port,
            false,
            req,
            BodyFormat::Class8Instance8,
            self.m.config.response_timeout,
        )?;
        Ok(self.m.run(&mut tx)?)
    }

    /// Allocate_Master/Slave_Connection_Set of `choice` with `allocator`, as `allocator` (its MAC
    /// in the header), through `port`.
    pub fn allocate_as(
        &mut self,
        allocator: MacId,
        port: Port,
        choice: AllocationChoice,
    ) -> Result<Outcome, HarnessError> {
        if choice.intersects(AllocationChoice::from_bits(0x34)) {
            self.io_allocated = true;
        }
        let data = AllocateRequest { choice, allocator }.emit();
        let req = Request {
            service: ServiceCode::AllocateMasterSlave,
            class: class::DEVICENET,
            instance: 1,
            data: &data,
        };
        self.request_as(allocator, port, &req)
    }

    /// Release_Master/Slave_Connection_Set of `choice` as `requester`, through `port`.
    pub fn release_as(
        &mut self,
        requester: MacId,
        port: Port,
        choice: AllocationChoice,
    ) -> Result<Outcome, HarnessError> {
        let data = ReleaseRequest { choice }.emit();
        let req = Request {
            service: ServiceCode::ReleaseMasterSlave,
            class: class::DEVICENET,
            instance: 1,
            data: &data,
        };
        self.request_as(requester, port, &req)
    }

    /// Judges an answer that must be the error `general`/`additional`. Returns whether it was.
    pub fn expect_error(
        &mut self,
        c: &mut Check,
        basis: Basis,
        outcome: &Outcome,
        general: GeneralStatus,
        additional: u8,
        what: &str,
    ) -> bool {
        let want = decode::error_text(general, additional);
        let (text, ok) = match &outcome.0 {
            Ok(Reply { body: ReplyBody::Error { general: g, additional: a }, .. }) => {
                if *g == general && *a == additional {
                    (format!("{what}: {want}"), true)
                } else {
                    (format!("{what}: {} (expected {want})", decode::error_text(*g, *a)), false)
                }
            }
            Ok(Reply { body: ReplyBody::Success(d), .. }) => {
                (format!("{what}: accepted ({}), expected the error {want}", data_text(d)), false)
            }
            Err(e) => {
                (format!("{what}: no answer ({}), expected the error {want}", client_error_text(e)), false)
            }
        };
        self.mark_record(outcome.1, ok, &text);
        c.expect(basis, ok, text, outcome.1)
    }

    /// Judges an answer that must be a success; returns its data.
    pub fn expect_success(
        &mut self,
        c: &mut Check,
        basis: Basis,
        outcome: &Outcome,
        what: &str,
    ) -> Option<Vec<u8>> {
        let (text, data) = match &outcome.0 {
            Ok(Reply { body: ReplyBody::Success(d), .. }) => (format!("{what}: success"), Some(d.clone())),
            Ok(Reply { body: ReplyBody::Error { general, additional }, .. }) => {
                (format!("{what}: refused with {}", decode::error_text(*general, *additional)), None)
            }
            Err(e) => (format!("{what}: no answer ({})", client_error_text(e)), None),
        };
        self.mark_record(outcome.1, data.is_some(), &text);
        c.expect(basis, data.is_some(), text, outcome.1);
        data
    }

    /// Adds the judgement to the completing record of an exchange.
    fn mark_record(&mut self, record: Option<usize>, ok: bool, text: &str) {
        if let Some(i) = record {
            let v = self.m.session.record(i).verdict.clone();
            let v = if ok {
                match v {
                    Verdict::Ok(n) => Verdict::Ok(format!("{n}; {text}")),
                    other => other,
                }
            } else {
                v.with_failures(vec![text.to_string()])
            };
            self.m.session.set_verdict(i, v);
        }
    }

    /// An [`Answer`] as the outcome form of [`Runner::request_as`].
    pub fn outcome(r: Result<Answer, HarnessError>) -> Result<Outcome, HarnessError> {
        match r {
            Ok(a) => Ok((Ok(a.reply), a.record)),
            Err(HarnessError::Master(MasterError::Timeout { timeout, after, .. })) => {
                Ok((Err(ClientError::Timeout { name: timeout, after }), None))
            }
            Err(HarnessError::Master(MasterError::Protocol { reason, .. })) => {
                Ok((Err(ClientError::RequestAborted(reason)), None))
            }
            Err(e) => Err(e),
        }
    }

    /// Reads a value; `None` (and a finding with `basis`) if it cannot be read.
    pub fn read(
        &mut self,
        c: &mut Check,
        basis: Basis,
        class_id: u16,
        instance: u16,
        attr: u8,
    ) -> Result<Value, HarnessError> {
        let outcome = Self::outcome(self.get(class_id, instance, attr))?;
        let what = format!(
            "{} inst {instance} {}",
            decode::class_text(class_id),
            decode::attribute_text(class_id, instance, attr)
        );
        match &outcome.0 {
            Ok(Reply { body: ReplyBody::Success(d), .. }) => Ok(Some((d.clone(), outcome.1))),
            _ => {
                self.expect_success(c, basis, &outcome, &format!("Get {what}"));
                Ok(None)
            }
        }
    }

    /// Reads a USINT, `None` when not readable or not 1 byte.
    pub fn read_u8(&mut self, class_id: u16, instance: u16, attr: u8) -> Result<Option<u8>, HarnessError> {
        let a = Self::outcome(self.get(class_id, instance, attr))?;
        Ok(match a.0 {
            Ok(Reply { body: ReplyBody::Success(d), .. }) if d.len() == 1 => Some(d[0]),
            _ => None,
        })
    }

    // ----- fixtures ----------------------------------------------------------------------------

    /// Releases the poll and explicit connections through the Group 2 Only port (as the master,
    /// then, if the device is owned by the second master, as that one). Errors are expected
    /// (nothing allocated) and not judged.
    pub fn release_all(&mut self) -> Result<(), HarnessError> {
        let me = self.master_mac();
        let mut conflict = false;
        // The strobe, COS and cyclic connections once a check may have allocated them (each
        // alone: a release naming a connection that does not exist is refused whole). The master
        // forgets its connection only once they are released: until the device has the Release,
        // it produces, and those productions are the connection's, not unexpected frames.
        if std::mem::take(&mut self.io_allocated) {
            for choice in
                [AllocationChoice::BIT_STROBE, AllocationChoice::CHANGE_OF_STATE, AllocationChoice::CYCLIC]
            {
                let _ = self.release_as(me, Port::Group2Only, choice)?;
            }
            self.m.end_io();
        }
        for choice in [AllocationChoice::POLL, AllocationChoice::EXPLICIT] {
            let (r, _) = self.release_as(me, Port::Group2Only, choice)?;
            conflict |= matches!(
                r,
                Ok(Reply { body: ReplyBody::Error { general: GeneralStatus::ObjectStateConflict, .. }, .. })
            );
        }
        if conflict {
            let other = self.second;
            for choice in [AllocationChoice::POLL, AllocationChoice::EXPLICIT] {
                let _ = self.release_as(other, Port::Group2Only, choice)?;
            }
        }
        Ok(())
    }

    /// A fresh explicit connection: everything released, explicit allocated through the Group 2
    /// Only port (checked).
    pub fn fresh_explicit(&mut self) -> Result<(), HarnessError> {
        self.release_all()?;
        self.m.allocate(self.dut(), Port::Group2Only, AllocationChoice::EXPLICIT)?;
        Ok(())
    }

    /// A fresh poll connection: explicit and poll allocated, the poll connection's watchdog action
    /// set when given, its EPR set to `epr_ms`; returns the EPR applied.
    pub fn fresh_poll(&mut self, epr_ms: u16, action: Option<u8>) -> Result<u16, HarnessError> {
        self.fresh_explicit()?;
        let dut = self.dut();
        self.m.allocate(dut, Port::Explicit, AllocationChoice::POLL)?;
        if self.facts.produced.is_none() || self.facts.consumed.is_none() {
            self.facts.produced = self.m.get_u16(dut, class::CONNECTION, 2, 7)?;
            self.facts.consumed = self.m.get_u16(dut, class::CONNECTION, 2, 8)?;
        }
        if let Some(a) = action {
            self.m.set(dut, class::CONNECTION, 2, 12, &[a])?;
        }
        let (data, _) = self.m.set(dut, class::CONNECTION, 2, 9, &epr_ms.to_le_bytes())?;
        let applied = match data.as_slice() {
            [a, b] => u16::from_le_bytes([*a, *b]),
            _ => epr_ms,
        };
        Ok(applied)
    }

    /// The poll output the suite sends: zeros of the consumed size.
    pub fn output(&self) -> Vec<u8> {
        vec![0; usize::from(self.facts.consumed.unwrap_or(0))]
    }

    /// One poll cycle through the master (every response fragment checked).
    pub fn poll(&mut self, output: &[u8], timeout: Duration) -> Result<Vec<u8>, HarnessError> {
        let (p, c) = (self.facts.produced.unwrap_or(0), self.facts.consumed.unwrap_or(0));
        let dut = self.dut();
        Ok(self.m.poll(dut, output, p, c, timeout)?)
    }

    /// The poll command frames for `output`.
    pub fn poll_frames(&self, output: &[u8]) -> Vec<Vec<u8>> {
        if self.facts.consumed.unwrap_or(0) > 8 {
            devicenet::fragment::io_fragments(output).map(|p| p.to_vec()).collect()
        } else {
            vec![output.to_vec()]
        }
    }

    /// The poll response identifier of the device.
    pub fn poll_response_id(&self) -> CanId {
        Identifier::group1(Group1MessageId::POLL_RESPONSE, self.dut())
    }

    /// Sends a poll raw and collects until `until`: `Some(data)` when a complete response came
    /// (its frames judged), `None` otherwise; other device frames are returned for judging.
    pub fn poll_raw(
        &mut self,
        output: &[u8],
        until: Instant,
    ) -> Result<(Option<Vec<u8>>, Vec<usize>), HarnessError> {
        let id = g2(self.dut(), Group2Message::PollCommand);
        for f in self.poll_frames(output) {
            self.send(id, &f)?;
        }
        let frames = self.collect(until)?;
        let produced = usize::from(self.facts.produced.unwrap_or(0));
        let response_id = self.poll_response_id();
        let mut rx: Box<IoReassembler<{ decode::MAX_IO_MESSAGE }>> = Box::new(IoReassembler::new());
        let mut whole = None;
        let mut others = Vec::new();
        for i in frames {
            let (_, f) = self.rec(i);
            if f.id() != response_id || whole.is_some() {
                others.push(i);
                continue;
            }
            if produced <= 8 {
                self.verdict(i, Verdict::Ok(format!("poll response, {} bytes", f.data().len())));
                whole = Some(f.data().to_vec());
            } else {
                match rx.receive(f.data()) {
                    Ok(Some(w)) => {
                        whole = Some(w.to_vec());
                        self.verdict(i, Verdict::Ok("last poll response fragment".into()));
                    }
                    Ok(None) => self.verdict(i, Verdict::Ok("poll response fragment".into())),
                    Err(e) => self.verdict(i, Verdict::fail(format!("poll response fragment rejected: {e}"))),
                }
            }
        }
        Ok((whole, others))
    }

    // ----- explicit fragments, raw -------------------------------------------------------------

    /// The whole explicit message `[header, body…]` of `req` from the master (8/8).
    pub fn message(&self, req: &Request<'_>) -> Vec<u8> {
        let len = req.buffer_len(BodyFormat::Class8Instance8).unwrap_or(0);
        let mut m = vec![0u8; 1 + len];
        m[0] = Header::new(false, self.master_mac()).to_byte();
        let _ = req.emit(BodyFormat::Class8Instance8, &mut m[1..]);
        m
    }

    /// The fragment frames of `message` (protocol §4.1): 6 body bytes each, counts from 0.
    pub fn fragments(message: &[u8]) -> Vec<Vec<u8>> {
        let Some((&h, body)) = message.split_first() else { return Vec::new() };
        let header = h | 0x80;
        let chunks: Vec<&[u8]> = body.chunks(6).collect();
        let mut count = 0u8;
        let mut out = Vec::new();
        for (k, chunk) in chunks.iter().enumerate() {
            let kind = if k == 0 {
                FragmentKind::First
            } else if k + 1 == chunks.len() {
                FragmentKind::Last
            } else {
                FragmentKind::Middle
            };
            let byte = FragmentByte::new(kind, count).map_or(0, FragmentByte::to_byte);
            let mut f = vec![header, byte];
            f.extend_from_slice(chunk);
            out.push(f);
            count = next_count(count);
        }
        out
    }

    /// The explicit request identifier of the device.
    pub fn explicit_request_id(&self) -> CanId {
        g2(self.dut(), Group2Message::ExplicitRequest)
    }

    /// The explicit response identifier of the device.
    pub fn explicit_response_id(&self) -> CanId {
        g2(self.dut(), Group2Message::ExplicitResponse)
    }

    /// Sends `frame` on the explicit request identifier and collects the device's frames until
    /// `wait` has passed.
    pub fn send_collect(&mut self, frame: &[u8], wait: Duration) -> Result<Vec<usize>, HarnessError> {
        let id = self.explicit_request_id();
        if wait >= Duration::from_secs(1) {
            self.waiting(&format!("collecting the device's frames for {wait}"));
        }
        self.send(id, frame)?;
        let until = self.now() + wait;
        self.collect(until)
    }
}

/// Response data in words: its bytes in hex, or "no data".
pub(crate) fn data_text(data: &[u8]) -> String {
    if data.is_empty() {
        "no data".to_string()
    } else {
        format!("data {}", hex(data))
    }
}

/// A client error in words.
pub(crate) fn client_error_text(e: &ClientError) -> String {
    match e {
        ClientError::Timeout { name, after } => format!("{name} after {after}"),
        ClientError::RequestAborted(r) => r.clone(),
    }
}

/// `[header, fragment byte, …]` of an ack from the device: `(count, status)` when `data` is one.
pub(crate) fn parse_ack(data: &[u8]) -> Option<(u8, u8)> {
    match data {
        [h, f, status] if h & 0x80 != 0 && FragmentByte::from_byte(*f).kind == FragmentKind::Ack => {
            Some((FragmentByte::from_byte(*f).count, *status))
        }
        _ => None,
    }
}

/// Percentile `p` (0–100) of sorted `values` (nearest rank).
pub(crate) fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let rank = ((p / 100.0) * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

#[cfg(test)]
mod tests {
    use super::*;
    use can_io::bus::Bitrate;
    use can_io::sim::{PowerOn, SimBus};
    use converter_sim::device::SoftSlave;
    use master_core::io::{IoKind, IoOptions};
    use master_core::master::ConnectOptions;

    /// A cyclic connection producing every 10 ms, released by [`Runner::release_all`] at every
    /// phase of its period: the productions that come while the Releases are under way belong to
    /// the connection and none is judged unexpected. `taken`: before the release, a check takes
    /// the connection and watches its frames itself (as `ack-handler` does), then gives it back,
    /// sometimes in the middle of a production. Some releases must meet a production, or the test
    /// compared nothing.
    #[rstest::rstest]
    #[case::followed(false)]
    #[case::taken_and_given_back(true)]
    fn productions_during_the_release_belong_to_the_connection(#[case] taken: bool) {
        let dut = MacId::from_low_bits(5);
        let mut bus = SimBus::new(Bitrate::K250);
        bus.attach(Box::new(SoftSlave::reference(dut)), PowerOn::WhenMasterOnline);
        let mut session = Session::new(&mut bus);
        let mut observer = ();
        let opts = SuiteOptions::new(dut);
        let mut r = Runner::new(
            &mut session,
            MasterConfig::default(),
            opts,
            Timestamps::of_transport("sim"),
            &mut observer,
        );
        r.m.connect(&ConnectOptions { target: dut, ..ConnectOptions::default() }).unwrap();
        let production = Identifier::group1(Group1MessageId::COS_CYCLIC, dut);
        let mut met = 0;
        for offset_us in (0..10_000).step_by(500) {
            r.fresh_explicit().unwrap();
            r.io_allocated = true;
            r.m.establish_io(dut, 10, &IoOptions::of(IoKind::Cyclic)).unwrap();
            r.m.await_production().unwrap();
            let then = r.now() + Duration::from_micros(offset_us);
            if taken {
                let conn = r.m.end_io().unwrap();
                for i in r.collect(then).unwrap() {
                    r.verdict(i, Verdict::Ok("watched by the test".into()));
                }
                r.m.resume_io(conn);
            } else {
                r.m.idle_until(then).unwrap();
            }
            let from = r.mark();
            r.release_all().unwrap();
            met += r.m.session.records()[from..].iter().filter(|rec| rec.frame.id() == production).count();
        }
        let failed: Vec<String> =
            r.m.session
                .records()
                .iter()
                .filter(|rec| rec.verdict.is_failure())
                .map(|rec| format!("#{} {}: {}", rec.index, rec.frame, rec.verdict.label()))
                .collect();
        assert!(failed.is_empty(), "{failed:#?}");
        assert!(met > 0, "no release met a production: nothing was compared");
    }

    #[test]
    fn fragments_of_a_message() {
        let msg: Vec<u8> = (0..14).collect(); // header 0 + 13 body bytes -> 3 fragments
        let f = Runner::fragments(&msg);
        assert_eq!(f.len(), 3);
        assert_eq!(f[0][..2], [0x80, 0x00]);
        assert_eq!(f[1][..2], [0x80, 0x41]);
        assert_eq!(f[2], vec![0x80, 0x82, 13]);
    }

    #[test]
    fn percentiles() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(percentile(&v, 50.0), 50.0);
        assert_eq!(percentile(&v, 99.0), 99.0);
        assert_eq!(percentile(&v, 0.0), 1.0);
        assert_eq!(percentile(&[], 50.0), 0.0);
    }

    #[test]
    fn acks() {
        assert_eq!(parse_ack(&[0x80, 0xC1, 0x00]), Some((1, 0)));
        assert_eq!(parse_ack(&[0x00, 0xC1, 0x00]), None);
        assert_eq!(parse_ack(&[0x80, 0x41, 0x00]), None);
    }
}
