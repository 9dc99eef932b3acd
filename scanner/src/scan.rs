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
use devicenet::explicit::{BodyFormat, GeneralStatus, Request, ServiceCode};
use devicenet::messages::{AllocateRequest, AllocationChoice, ReleaseRequest};
use devicenet::objects::class;
use devicenet::{Duration, Group2Message, Identifier, Instant, MacId};
use harness_common::console::Progress;
use harness_common::error::HarnessError;
use master_core::client::{ClientError, Handled, Port, ReplyBody, Transaction};
use master_core::decode;
use master_core::master::Master;
use std::collections::VecDeque;

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

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    Allocate(AllocationChoice),
    Get(u16, u16, u8),
    Release,
    /// Release through the Group 2 Only port: a set an earlier run of this master kept.
    ReleaseKept(AllocationChoice),
}

struct Node {
    mac: MacId,
    steps: VecDeque<Step>,
    tx: Option<Transaction>,
    allocated: AllocationChoice,
    found: bool,
    /// The set was still allocated to this master and has been released and allocated again.
    reallocated: bool,
    device: ScannedDevice,
}

fn request_for(
    step: Step,
    master: MacId,
    allocated: AllocationChoice,
    buf: &mut Vec<u8>,
) -> (Port, ServiceCode, u16, u16) {
    buf.clear();
    match step {
        Step::Allocate(choice) => {
            buf.extend_from_slice(&AllocateRequest { choice, allocator: master }.emit());
            (Port::Group2Only, ServiceCode::AllocateMasterSlave, class::DEVICENET, 1)
        }
        Step::Get(c, i, a) => {
            buf.push(a);
            (Port::Explicit, ServiceCode::GetAttributeSingle, c, i)
        }
        Step::Release => {
            buf.extend_from_slice(&ReleaseRequest { choice: allocated }.emit());
            (Port::Explicit, ServiceCode::ReleaseMasterSlave, class::DEVICENET, 1)
        }
        Step::ReleaseKept(choice) => {
            buf.extend_from_slice(&ReleaseRequest { choice }.emit());
            (Port::Group2Only, ServiceCode::ReleaseMasterSlave, class::DEVICENET, 1)
        }
    }
}

impl Node {
    fn start_next(&mut self, master: &Master<'_, '_>, now: Instant) -> Result<(), HarnessError> {
        let Some(&step) = self.steps.front() else {
            self.tx = None;
            return Ok(());
        };
        let mut data = Vec::new();
        let (port, service, c, i) = request_for(step, master.config.mac, self.allocated, &mut data);
        let req = Request { service, class: c, instance: i, data: &data };
        let mut tx = Transaction::new(
            self.mac,
            master.config.mac,
            port,
            false,
            &req,
            BodyFormat::Class8Instance8,
            master.config.response_timeout,
        )?;
        tx.start(now);
        self.tx = Some(tx);
        Ok(())
    }

    /// Takes the outcome of the current step; returns whether the node goes on.
    fn finish_step(&mut self, outcome: Result<master_core::client::Reply, ClientError>) {
        let Some(step) = self.steps.pop_front() else { return };
        let reply = match outcome {
            Ok(r) => r,
            Err(ClientError::Timeout { name, .. }) => {
                if self.found {
                    self.device.status = format!("stopped answering ({name})");
                }
                self.steps.clear();
                return;
            }
            Err(ClientError::RequestAborted(r)) => {
                self.device.status = r;
                self.steps.clear();
                return;
            }
        };
        self.found = true;
        match (step, reply.body) {
            (Step::Allocate(choice), ReplyBody::Success(_)) => {
                self.allocated = choice;
                let mut steps: Vec<Step> =
                    [1u8, 2, 3, 4, 6, 7].iter().map(|&a| Step::Get(class::IDENTITY, 1, a)).collect();
                if choice.contains(AllocationChoice::POLL) {
                    steps.push(Step::Get(class::CONNECTION, 2, 7));
                    steps.push(Step::Get(class::CONNECTION, 2, 8));
                }
                steps.push(Step::Release);
                self.steps = steps.into();
            }
            (
                Step::Allocate(choice),
                ReplyBody::Error { general: GeneralStatus::AlreadyInRequestedState, .. },
            ) if !self.reallocated => {
                // Still allocated to this master (an earlier run kept it): release what it
                // holds of the choice (explicit alone when poll is gone), allocate again.
                self.reallocated = true;
                self.device.note =
                    Some("was still allocated to this master: released and allocated again".into());
                self.steps.push_front(Step::Allocate(choice));
                self.steps.push_front(Step::ReleaseKept(AllocationChoice::EXPLICIT));
                if choice.contains(AllocationChoice::POLL) {
                    self.steps.push_front(Step::ReleaseKept(AllocationChoice::POLL));
                }
            }
            (
                Step::Allocate(choice),
                ReplyBody::Error { general: GeneralStatus::ResourceUnavailable, .. },
            ) if choice.contains(AllocationChoice::POLL) => {
                // No poll connection: identity only.
                self.steps.push_front(Step::Allocate(AllocationChoice::EXPLICIT));
            }
            (Step::Allocate(_), ReplyBody::Error { general, additional }) => {
                self.device.status = if general == GeneralStatus::ObjectStateConflict && additional == 0x01 {
                    "allocated by another master".into()
                } else {
                    format!("allocation refused: {}", decode::error_text(general, additional))
                };
                self.steps.clear();
            }
            (Step::Get(c, i, a), ReplyBody::Success(data)) => {
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
            (Step::Get(c, i, a), ReplyBody::Error { general, additional }) => {
                if self.device.status == "ok" {
                    self.device.status = format!(
                        "{} {}: {}",
                        decode::class_text(c),
                        decode::attribute_text(c, i, a),
                        decode::error_text(general, additional)
                    );
                }
            }
            (Step::Release, ReplyBody::Success(_)) => self.allocated = AllocationChoice::empty(),
            (Step::Release, ReplyBody::Error { .. }) => {}
            // A kept poll connection may be gone already (its watchdog fired): 0x0B is fine.
            (Step::ReleaseKept(_), _) => {}
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
        .map(|&mac| Node {
            mac,
            steps: VecDeque::from([Step::Allocate(AllocationChoice::EXPLICIT | AllocationChoice::POLL)]),
            tx: None,
            allocated: AllocationChoice::empty(),
            found: false,
            reallocated: false,
            device: ScannedDevice { mac: mac.as_raw(), status: "ok".into(), ..ScannedDevice::default() },
        })
        .collect();
    for n in &mut nodes {
        n.start_next(master, scan_start)?;
    }
    let mut last_answer = scan_start;
    loop {
        for n in &mut nodes {
            if let Some(tx) = &mut n.tx {
                while let Some(f) = tx.poll_transmit() {
                    master.session.send(&f)?;
                }
            }
        }
        let now = master.session.now();
        // Steps whose transaction ended: take the outcome, start the next.
        for n in &mut nodes {
            if let Some(outcome) = n.tx.as_mut().filter(|t| t.is_done()).and_then(|t| t.take_outcome()) {
                n.finish_step(outcome);
                // The master knows what each device holds, so an interrupted scan gives it back.
                master.set_held(n.mac, n.allocated);
                n.start_next(master, now)?;
                if let Some(tx) = &mut n.tx {
                    while let Some(f) = tx.poll_transmit() {
                        master.session.send(&f)?;
                    }
                }
            }
        }
        let Some(deadline) = nodes.iter().filter_map(|n| n.tx.as_ref().and_then(|t| t.poll_at())).min()
        else {
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
                        nodes.iter_mut().find(|n| n.mac == mac && n.tx.is_some())
                    }
                    _ => None,
                };
                match owner.and_then(|n| n.tx.as_mut()).map(|tx| tx.handle_frame(&rec.frame, rec.at)) {
                    Some(Handled::Frame(v)) => {
                        master.session.set_verdict(i, v);
                        last_answer = rec.at;
                    }
                    _ => master.other(i)?,
                }
            }
            None => {
                let now = master.session.now();
                for n in &mut nodes {
                    if let Some(tx) = &mut n.tx {
                        tx.handle_timeout(now);
                    }
                }
            }
        }
    }
    let end = master.session.now();
    let _ = last_answer;
    let devices: Vec<ScannedDevice> = nodes.into_iter().filter(|n| n.found).map(|n| n.device).collect();
    Ok(ScanReport {
        devices,
        asked: macs.len(),
        scan_micros: (end - scan_start).total_micros(),
        total_micros: (end - begin).total_micros(),
    })
}

/// The scan duration as a [`Duration`].
pub fn scan_duration(report: &ScanReport) -> Duration {
    Duration::from_micros(report.scan_micros)
}
