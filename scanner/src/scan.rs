//! `scan`: find every device on the network and read its identity and I/O sizes — a network
//! "who" for group-2-only devices.
//!
//! The requests to all MAC IDs overlap: the master sends Allocate (explicit and poll) through the
//! Group 2 Only port to every MAC in the range back to back, so that absent nodes cost one shared
//! response timeout, not one each. Each device that answers then runs its own sequence — Identity
//! attributes 1, 2, 3, 4, 6, 7 (the product name comes fragmented), Connection 2 attributes 7 and
//! 8 when poll was allocated, Release — while the others run theirs: one outstanding request per
//! device, all devices in parallel, the bus arbitrating between them.
//!
//! A device that refuses poll (0x02 resource unavailable) is allocated explicit only; a device
//! owned by another master (0x0C / 0x01) is reported as such; a device still allocated to this
//! master (0x0B: an earlier run kept it) is released through the Group 2 Only port and allocated
//! again, and its row says so.

use crate::model::Identity;
use can_io::bus::Origin;
use devicenet::explicit::GeneralStatus;
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::{Duration, Group2Message, Identifier, Instant, MacId};
use harness_common::console::Progress;
use harness_common::error::HarnessError;
use master_core::bring_up::{BringUp, Event, NodeError, Refusal, Step};
use master_core::client::{Handled, Port, ReplyBody};
use master_core::decode;
use master_core::master::Master;

/// One device found.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ScannedDevice {
    /// MAC ID.
    pub mac: u8,
    /// `ok`, or why it could not be read fully.
    pub status: String,
    /// What else happened (a set of this master's released and allocated again).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
    /// Identity attributes 1-4, 6 and 7 (in the JSON as fields of the device).
    #[serde(flatten)]
    pub identity: Identity,
    /// Connection 2 attribute 7 (poll response size).
    pub produced_size: Option<u16>,
    /// Connection 2 attribute 8 (poll command size).
    pub consumed_size: Option<u16>,
}

/// The result of a scan.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ScanReport {
    /// Devices found, by MAC.
    pub devices: Vec<ScannedDevice>,
    /// MACs asked.
    pub asked: usize,
    /// Bus time from the first request to the last answer (or timeout), microseconds.
    pub scan_micros: u64,
    /// Bus time of the whole command (network access included), microseconds.
    pub total_micros: u64,
}

/// One MAC being asked: its bring-up engine and what it found.
struct Node {
    engine: BringUp,
    device: ScannedDevice,
}

impl Node {
    /// Takes an event of the engine at `now`: what was read, and the steps that follow.
    fn take(&mut self, event: Event, now: Instant) {
        let reply = match event {
            Event::Answered { step, body } => (step, body),
            Event::Reallocated { .. } => {
                self.device.note =
                    Some("was still allocated to this master: released and allocated again".into());
                return;
            }
            Event::Failed(NodeError::Timeout { timeout, .. }) => {
                if self.engine.answered() {
                    self.device.status = format!("stopped answering ({timeout})");
                }
                return;
            }
            Event::Failed(NodeError::Aborted { reason, .. }) => {
                self.device.status = reason;
                return;
            }
            Event::Failed(other) => {
                self.device.status = other.to_string();
                return;
            }
        };
        let e = &mut self.engine;
        match reply {
            (Step::Allocate { choice, .. }, ReplyBody::Success(_)) => {
                for a in [1u8, 2, 3, 4, 6, 7] {
                    e.get(now, class::IDENTITY, 1, a, Refusal::Report);
                }
                if choice.contains(AllocationChoice::POLL) {
                    e.get(now, class::CONNECTION, 2, 7, Refusal::Report);
                    e.get(now, class::CONNECTION, 2, 8, Refusal::Report);
                }
                e.push(now, Step::Release { port: Port::Explicit, choice }, Refusal::Report);
            }
            (
                Step::Allocate { choice, .. },
                ReplyBody::Error { general: GeneralStatus::ResourceUnavailable, .. },
            ) if choice.contains(AllocationChoice::POLL) => {
                // No poll connection: identity only.
                e.push(
                    now,
                    Step::Allocate { port: Port::Group2Only, choice: AllocationChoice::EXPLICIT },
                    Refusal::Report,
                );
            }
            (Step::Allocate { .. }, ReplyBody::Error { general, additional }) => {
                self.device.status = if general == GeneralStatus::ObjectStateConflict && additional == 0x01 {
                    "allocated by another master".into()
                } else {
                    format!("allocation refused: {}", decode::error_text(general, additional))
                };
            }
            (Step::Get { class: c, instance: i, attribute: a }, ReplyBody::Success(data)) => {
                let d = &mut self.device;
                match (c, i, a) {
                    (class::IDENTITY, 1, a) => {
                        d.identity.take_attribute(a, &data);
                    }
                    (class::CONNECTION, 2, 7) => d.produced_size = decode::u16_of(&data),
                    (class::CONNECTION, 2, 8) => d.consumed_size = decode::u16_of(&data),
                    _ => {}
                }
            }
            (Step::Get { class: c, instance: i, attribute: a }, ReplyBody::Error { general, additional }) => {
                if self.device.status == "ok" {
                    self.device.status = format!(
                        "{} {}: {}",
                        decode::class_text(c),
                        decode::attribute_text(c, i, a),
                        decode::error_text(general, additional)
                    );
                }
            }
            // A release refused leaves the set with the master, which gives back what it holds.
            (Step::Release { .. } | Step::Set { .. }, _) => {}
        }
    }
}

/// Scans MAC IDs `from..=to` (the master's own MAC excluded). See the [module docs](self).
pub fn scan(
    master: &mut Master<'_, '_>,
    from: u8,
    to: u8,
    progress: &mut Progress<'_>,
) -> Result<ScanReport, HarnessError> {
    if from > to || to > 63 {
        return Err(HarnessError::MacRange { from, to });
    }
    let begin = master.session.now();
    let macs: Vec<MacId> = (from..=to).filter_map(MacId::new).filter(|&m| m != master.config.mac).collect();
    progress.show("scan: network access (duplicate MAC ID check, 2 s) ...");
    master.network_access()?;
    progress.show("scan: waiting for devices to come on-line ...");
    master.await_online(&macs)?;
    progress.show(&format!("scan: asking MAC {from}..={to} ..."));
    let scan_start = master.session.now();
    let mut nodes: Vec<Node> = macs
        .iter()
        .map(|&mac| {
            let mut engine = master.bring_up(mac);
            engine.push(
                scan_start,
                Step::Allocate {
                    port: Port::Group2Only,
                    choice: AllocationChoice::EXPLICIT | AllocationChoice::POLL,
                },
                Refusal::Report,
            );
            Node {
                engine,
                device: ScannedDevice { mac: mac.as_raw(), status: "ok".into(), ..ScannedDevice::default() },
            }
        })
        .collect();
    loop {
        let now = master.session.now();
        for n in &mut nodes {
            // Events start the next steps; their frames go out at once.
            loop {
                while let Some(f) = n.engine.poll_transmit() {
                    master.session.send(&f)?;
                }
                let Some(event) = n.engine.poll_event() else { break };
                n.take(event, now);
            }
            // The master knows what each device holds, so an interrupted scan gives it back.
            master.set_held(n.engine.mac(), n.engine.held());
        }
        let Some(deadline) = nodes.iter().filter_map(|n| n.engine.poll_at()).min() else {
            break;
        };
        match master.session.next(deadline)? {
            Some(i) => {
                let rec = master.session.record(i).clone();
                if rec.origin == Origin::Local {
                    continue;
                }
                let owner = match Identifier::decode(rec.frame.id()) {
                    Identifier::Group2 { mac, message: Group2Message::ExplicitResponse } => {
                        nodes.iter_mut().find(|n| n.engine.mac() == mac && n.engine.current().is_some())
                    }
                    _ => None,
                };
                match owner.map(|n| n.engine.handle_frame(&rec.frame, rec.at)) {
                    Some(Handled::Frame(v)) => master.session.set_verdict(i, v),
                    _ => master.other(i)?,
                }
            }
            None => {
                let now = master.session.now();
                for n in &mut nodes {
                    n.engine.handle_timeout(now);
                }
            }
        }
    }
    let end = master.session.now();
    let devices: Vec<ScannedDevice> =
        nodes.into_iter().filter(|n| n.engine.answered()).map(|n| n.device).collect();
    Ok(ScanReport {
        devices,
        asked: macs.len(),
        scan_micros: (end - scan_start).total_micros(),
        total_micros: (end - begin).total_micros(),
    })
}

/// The scan duration as a [`Duration`].
#[must_use]
pub fn scan_duration(report: &ScanReport) -> Duration {
    Duration::from_micros(report.scan_micros)
}
