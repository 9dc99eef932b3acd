//! The [`BringUp`] engine driven on the master's session: the blocking driver `connect` and
//! `check-device` use (a program that brings up several devices at once, `scan` and the
//! scanner, drives one engine per device on the bus itself).

use super::Master;
use crate::bring_up::{BringUp, Event, Refusal, Step};
use crate::client::{Handled, ReplyBody};
use crate::error::MasterError;
use can_io::bus::Origin;

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
    /// ([`Master::other`]). `None` when the engine is idle with nothing to say. What the device
    /// holds is kept up to date for [`Master::release_held`].
    ///
    /// # Errors
    ///
    /// The bus's, or what judging other traffic finds ([`MasterError::DuplicateMac`]).
    pub fn next_event(&mut self, node: &mut BringUp) -> Result<Option<NodeEvent>, MasterError> {
        let mut last = None;
        loop {
            while let Some(frame) = node.poll_transmit() {
                self.session.send(&frame)?;
            }
            if let Some(event) = node.poll_event() {
                self.set_held(node.mac(), node.held());
                if last.is_some() {
                    self.last_record = last;
                }
                return Ok(Some((event, last)));
            }
            let Some(deadline) = node.poll_at() else {
                self.set_held(node.mac(), node.held());
                return Ok(None);
            };
            match self.session.next(deadline)? {
                Some(i) => {
                    let rec = self.session.record(i).clone();
                    if rec.origin == Origin::Local {
                        continue;
                    }
                    match node.handle_frame(&rec.frame, rec.at) {
                        Handled::Frame(verdict) => {
                            self.session.set_verdict(i, verdict);
                            last = Some(i);
                        }
                        Handled::NotMine => self.other(i)?,
                    }
                }
                None => node.handle_timeout(self.session.now()),
            }
        }
    }

    /// Queues `step` on `node` and runs it to its answer: the answer with the record that
    /// completed it. A set still allocated to this master is released and allocated again on the
    /// way (a [notice](Master::notices) says so).
    ///
    /// # Errors
    ///
    /// [`MasterError::Node`] when the step times out, is aborted, or is refused with
    /// [`Refusal::Stop`]; those of [`Master::next_event`].
    pub fn run_step(
        &mut self,
        node: &mut BringUp,
        step: Step,
        refusal: Refusal,
    ) -> Result<(ReplyBody, Option<usize>), MasterError> {
        let now = self.session.now();
        node.push(now, step, refusal);
        loop {
            match self.next_event(node)? {
                Some((Event::Answered { body, .. }, record)) => return Ok((body, record)),
                Some((Event::Failed(error), _)) => return Err(error.into()),
                Some((Event::Reallocated { choice }, _)) => self.notices.push(format!(
                    "MAC {}: {choice} was still allocated to this master (an earlier run kept it): released and allocated again",
                    node.mac()
                )),
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
}
