//! The [`BringUp`] engine driven on the master's session: the blocking driver `connect` and
//! `check-device` use (a program that brings up several devices at once, `scan` and the
//! scanner, drives one engine per device on the bus itself).

use super::Master;
use crate::bring_up::{BringUp, Event, NodeError, Refusal, Step};
use crate::client::{self, Handled, ReplyBody};
use crate::decode;
use crate::error::MasterError;
use crate::session::Verdict;
use can_io::bus::Origin;
use devicenet::explicit::{additional, GeneralStatus};
use devicenet::MacId;

/// An event of the engine, with the record of the frame that completed it.
pub type NodeEvent = (Event, Option<usize>);

impl Master<'_, '_> {
    /// A bring-up engine for `target` with this master's MAC ID and response timeout.
    #[must_use]
    pub fn bring_up(&self, target: devicenet::MacId) -> BringUp {
        BringUp::new(target, self.config.mac, self.config.response_timeout)
    }

    /// Runs `node` on the session until its next event: its frames sent, the device's answers
    /// handed to it (with their verdicts recorded), every other frame judged
    /// ([`Master::other`]). `None` when the engine is idle with nothing to say.
    ///
    /// # Errors
    ///
    /// The bus's, or what judging other traffic finds ([`MasterError::DuplicateMac`]).
    pub fn next_event(&mut self, node: &mut BringUp) -> Result<Option<NodeEvent>, MasterError> {
        let mut last = None;
        // Own frames sent and not yet seen back from the bus.
        let mut in_flight = 0usize;
        loop {
            while let Some(frame) = node.poll_transmit() {
                self.session.send(&frame)?;
                in_flight += 1;
            }
            if let Some(event) = node.poll_event() {
                // Record the master's last frames (the final fragment acknowledge) first.
                let until = self.session.now() + client::ECHO_WAIT;
                while in_flight > 0 {
                    let Some(i) = self.session.next(until)? else { break };
                    if !self.take_frame(node, i, &mut last)? {
                        in_flight -= 1;
                    }
                }
                if last.is_some() {
                    self.last_record = last;
                }
                return Ok(Some((event, last)));
            }
            let Some(deadline) = node.poll_at() else { return Ok(None) };
            match self.session.next(deadline)? {
                Some(i) => {
                    if !self.take_frame(node, i, &mut last)? {
                        in_flight = in_flight.saturating_sub(1);
                    }
                }
                None => node.handle_timeout(self.session.now()),
            }
        }
    }

    /// Hands record `i` to `node` (its verdict recorded, `last` set when it answers the step) or
    /// to [`Master::other`]; `false` for the master's own frame coming back from the bus.
    fn take_frame(
        &mut self,
        node: &mut BringUp,
        i: usize,
        last: &mut Option<usize>,
    ) -> Result<bool, MasterError> {
        let rec = self.session.record(i).clone();
        if rec.origin == Origin::Local {
            return Ok(false);
        }
        match node.handle_frame(&rec.frame, rec.at) {
            Handled::Frame(verdict) => {
                self.session.set_verdict(i, verdict);
                *last = Some(i);
            }
            Handled::NotMine => self.other(i)?,
        }
        Ok(true)
    }

    /// Queues `step` on `node` and runs it to its answer: the answer with the record that
    /// completed it. A set still allocated to this master is released and allocated again on the
    /// way (a [notice](Master::notices) says so, and the 0x0B answer's record).
    ///
    /// # Errors
    ///
    /// When the step times out [`MasterError::Timeout`], when it is refused with
    /// [`Refusal::Stop`] [`MasterError::ErrorResponse`] (the record's verdict a failure naming it)
    /// or [`MasterError::AllocationConflict`], [`MasterError::Protocol`] when its request is
    /// aborted; those of [`Master::next_event`].
    pub fn run_step(
        &mut self,
        node: &mut BringUp,
        step: Step,
        refusal: Refusal,
    ) -> Result<(ReplyBody, Option<usize>), MasterError> {
        node.set_response_timeout(self.config.response_timeout);
        let now = self.session.now();
        node.push(now, step, refusal);
        loop {
            match self.next_event(node)? {
                Some((Event::Answered { body, .. }, record)) => return Ok((body, record)),
                Some((Event::Failed(error), record)) => return Err(self.node_error(error, record)),
                Some((Event::Reallocated { choice }, record)) => {
                    if let Some(i) = record {
                        let note = format!(
                            "{choice} already allocated to this master: released and allocated again"
                        );
                        self.session.set_verdict(i, Verdict::Ok(note));
                    }
                    self.notices.push(format!(
                        "MAC {}: {choice} was still allocated to this master (an earlier run kept it): released and allocated again",
                        node.mac()
                    ));
                }
                // A queued step always ends in an answer or a failure.
                None => {
                    return Err(MasterError::Protocol {
                        what: format!("MAC {}", node.mac()),
                        reason: "the bring-up engine went idle without answering its step".into(),
                    })
                }
            }
        }
    }

    /// [`Master::run_step`] on the master's own engine for `target` (one per device, kept
    /// between steps: what the device announced, such as its body format, holds for the next).
    ///
    /// # Errors
    ///
    /// Those of [`Master::run_step`].
    pub fn step(
        &mut self,
        target: MacId,
        step: Step,
        refusal: Refusal,
    ) -> Result<(ReplyBody, Option<usize>), MasterError> {
        let mut node = self.nodes.remove(&target.as_raw()).unwrap_or_else(|| self.bring_up(target));
        let result = self.run_step(&mut node, step, refusal);
        self.nodes.insert(target.as_raw(), node);
        result
    }

    /// [`Master::step`] for a step whose answer must be a success: its data.
    pub(super) fn step_ok(
        &mut self,
        target: MacId,
        step: Step,
    ) -> Result<(Vec<u8>, Option<usize>), MasterError> {
        match self.step(target, step, Refusal::Stop)? {
            (ReplyBody::Success(data), record) => Ok((data, record)),
            // Refusal::Stop turns every error response into an error.
            (ReplyBody::Error { general, additional }, _) => Err(MasterError::ErrorResponse {
                what: format!("MAC {target}"),
                mac: target.as_raw(),
                general,
                additional,
                text: decode::error_text(general, additional),
            }),
        }
    }

    /// The master's error for an engine's: the same variants the master's own requests give.
    fn node_error(&mut self, error: NodeError, record: Option<usize>) -> MasterError {
        match error {
            NodeError::Timeout { mac, step, timeout, after } => {
                MasterError::Timeout { what: step.to_string(), mac: mac.as_raw(), after, timeout }
            }
            NodeError::Refused { mac, step, general, additional } => {
                let text = decode::error_text(general, additional);
                self.mark_error_response(record, &text);
                MasterError::ErrorResponse {
                    what: step.to_string(),
                    mac: mac.as_raw(),
                    general,
                    additional,
                    text,
                }
            }
            NodeError::AllocationConflict { mac, .. } => {
                let text =
                    decode::error_text(GeneralStatus::ObjectStateConflict, additional::ALLOCATION_CONFLICT);
                self.mark_error_response(record, &text);
                MasterError::AllocationConflict { mac: mac.as_raw(), owner: self.owner_seen(mac) }
            }
            NodeError::Aborted { step, reason, .. } => {
                MasterError::Protocol { what: step.to_string(), reason }
            }
            NodeError::Request { source, .. } => MasterError::Request(source),
        }
    }

    /// The record of an error response nobody allowed: its verdict a failure naming it.
    fn mark_error_response(&mut self, record: Option<usize>, text: &str) {
        if let Some(i) = record {
            let v = self.session.record(i).verdict.clone();
            self.session.set_verdict(i, v.with_failures(vec![format!("error response: {text}")]));
        }
    }
}
