//! One node's bring-up, as the scanner runs it on master-core's bring-up engine: the allocation,
//! the reads, the check against the scan list, the EPR that establishes the connection (the
//! scanner's docs, "A node's life").

use super::Scanner;
use crate::model::{Identity, NodeState, NodeStatus, ScanEntry};
use devicenet::explicit::GeneralStatus;
use devicenet::fragment::IoReassembler;
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::{Instant, MacId};
use master_core::bring_up::{BringUp, Event, NodeError, Refusal, Step};
use master_core::client::{Port, ReplyBody};
use master_core::decode;
use master_core::master::io::IoKind;
use master_core::master::Master;

/// The detail of a disabled node.
pub(super) const DISABLED: &str = "disabled in the scan list (maintenance): not scanned";

pub(super) struct Node {
    pub(super) entry: ScanEntry,
    /// The connection type of the entry.
    pub(super) kind: IoKind,
    /// Strobe: Connection 3 attribute 8 as read (8, the strobe command).
    pub(super) strobe_consumed: Option<u16>,
    /// COS/cyclic: the scanner's data last sent (`None`: not yet since established).
    pub(super) output_sent: Option<Vec<u8>>,
    /// Cyclic: when the scanner's data goes next.
    pub(super) next_output: Instant,
    /// COS/cyclic: when the scanner's data went out, while its acknowledgement is awaited.
    pub(super) output_ack: Option<Instant>,
    pub(super) state: NodeState,
    /// The bring-up running or last run (`None`: none since the scanner started or stopped).
    pub(super) engine: Option<BringUp>,
    pub(super) allocated: AllocationChoice,
    pub(super) in_io: bool,
    pub(super) in_io_since: Instant,
    pub(super) last_exchange: Option<Instant>,
    pub(super) awaiting: bool,
    pub(super) rx: Box<IoReassembler<{ decode::MAX_IO_MESSAGE }>>,
    /// A second device was seen at this MAC (Communication Faulted), and what showed it.
    pub(super) duplicate: Option<String>,
    /// The last duplicate MAC ID request seen at this MAC: serial, time.
    pub(super) announced: Option<(u32, Instant)>,
}

impl Node {
    /// A node for scan-list entry `e`, not yet brought up (disabled when the entry says so).
    pub(super) fn new(e: &ScanEntry) -> Node {
        let mut n = Node {
            entry: e.clone(),
            kind: e.io_kind(),
            strobe_consumed: None,
            output_sent: None,
            next_output: Instant::ZERO,
            output_ack: None,
            state: NodeState {
                mac: e.mac,
                name: e.name.clone(),
                connection: e.io_kind().name().into(),
                ack_suppression: e.ack_suppression,
                status: NodeStatus::Initializing,
                code: NodeStatus::Initializing.code(),
                detail: None,
                identity: Identity::default(),
                input_size: None,
                output_size: None,
                input: Vec::new(),
                output: vec![0; if e.io_kind() == IoKind::Strobe { 1 } else { usize::from(e.output_size) }],
                exchanges: 0,
                last_exchange_us: None,
            },
            engine: None,
            allocated: AllocationChoice::empty(),
            in_io: false,
            in_io_since: Instant::ZERO,
            last_exchange: None,
            awaiting: false,
            rx: Box::new(IoReassembler::new()),
            duplicate: None,
            announced: None,
        };
        if !e.enabled {
            n.set(NodeStatus::Disabled, Some(DISABLED.into()));
        }
        n
    }

    pub(super) fn set(&mut self, status: NodeStatus, detail: Option<String>) {
        self.state.status = status;
        self.state.code = status.code();
        self.state.detail = detail;
    }

    /// The node cannot be brought into I/O: `status` with `detail`, then its connections released.
    pub(super) fn give_up(&mut self, status: NodeStatus, detail: String, now: Instant) {
        self.set(status, Some(detail));
        if let Some(e) = &mut self.engine {
            e.give_back(now);
        }
    }

    /// `true` while a bring-up step runs or is queued.
    pub(super) fn busy(&self) -> bool {
        self.engine.as_ref().is_some_and(|e| !e.is_idle())
    }

    pub(super) fn produced(&self) -> u16 {
        self.state.input_size.unwrap_or(self.entry.input_size)
    }

    pub(super) fn consumed(&self) -> u16 {
        self.state.output_size.unwrap_or(self.entry.output_size)
    }

    /// The size of the node's output image: its consumed size, 1 byte for a strobed node (bit 0:
    /// its strobe bit).
    pub(super) fn output_len(&self) -> usize {
        match self.kind {
            IoKind::Strobe => 1,
            _ => usize::from(self.consumed()),
        }
    }

    /// The output image as sent now: the node's while it is ok, zeros otherwise.
    pub(super) fn output_now(&self) -> Vec<u8> {
        if self.state.status == NodeStatus::Ok && self.state.output.len() == self.output_len() {
            self.state.output.clone()
        } else {
            vec![0; self.output_len()]
        }
    }

    /// What the scanner waits for from the node, in words.
    pub(super) fn input_name(&self) -> &'static str {
        match self.kind {
            IoKind::Poll => "poll response",
            IoKind::Strobe => "strobe response",
            IoKind::ChangeOfState => "change-of-state production",
            IoKind::Cyclic => "cyclic production",
        }
    }

    /// The allocation choice of the node's set (explicit + its connection), without acknowledge
    /// suppression (which is requested, never held or released, protocol §II.2.5).
    pub(super) fn choice(&self) -> AllocationChoice {
        AllocationChoice::EXPLICIT | self.kind.choice()
    }
}

impl Scanner {
    pub(super) fn begin_bringup(&mut self, i: usize, master: &Master<'_, '_>, now: Instant) {
        let Some(n) = self.nodes.get_mut(i) else { return };
        let Some(mac) = MacId::new(n.entry.mac) else { return };
        let mut choice = n.choice();
        if n.entry.ack_suppression && n.kind.is_cos_cyclic() {
            choice |= AllocationChoice::ACK_SUPPRESSION;
        }
        let mut engine = master.bring_up(mac);
        engine.push(now, Step::Allocate { port: Port::Group2Only, choice }, Refusal::Report);
        n.engine = Some(engine);
        *n.rx = IoReassembler::new();
    }

    /// Electronic key and sizes against the scan list (after the identity and sizes were read).
    pub(super) fn check(n: &mut Node, now: Instant) -> bool {
        let e = &n.entry;
        let keying: Vec<String> =
            crate::keying::mismatches(e.keying, &e.electronic_key(), &n.state.identity.electronic_key())
                .iter()
                .map(ToString::to_string)
                .collect();
        if !keying.is_empty() {
            n.give_up(NodeStatus::KeyingMismatch, keying.join("; "), now);
            return false;
        }
        let mut sizes = Vec::new();
        if n.state.input_size != Some(e.input_size) {
            sizes.push(format!(
                "input (produced) size {} bytes, scan list {}",
                n.state.input_size.map_or("?".into(), |v| v.to_string()),
                e.input_size
            ));
        }
        if n.kind == IoKind::Strobe && n.strobe_consumed != Some(8) {
            sizes.push(format!(
                "strobe consumed size (Connection 3 attribute 8) {} bytes, a strobe command has 8",
                n.strobe_consumed.map_or("?".into(), |v| v.to_string())
            ));
        } else if n.state.output_size != Some(e.output_size) {
            sizes.push(format!(
                "output (consumed) size {} bytes, scan list {}",
                n.state.output_size.map_or("?".into(), |v| v.to_string()),
                e.output_size
            ));
        }
        if !sizes.is_empty() {
            n.give_up(NodeStatus::SizeMismatch, sizes.join("; "), now);
            return false;
        }
        true
    }

    /// Takes an event of node `n`'s bring-up engine at `now`: what was read, the statuses, and the
    /// steps that follow.
    pub(super) fn take_event(n: &mut Node, event: Event, now: Instant, epr_ms: u16) {
        let answered = n.engine.as_ref().is_some_and(BringUp::answered);
        let (step, body) = match event {
            Event::Answered { step, body } => (step, body),
            // Still allocated to this master (an earlier run, or a connection the device still
            // holds): released and allocated again by the engine.
            Event::Reallocated { .. } => return,
            Event::Failed(NodeError::Timeout { step, timeout, .. }) => {
                if matches!(step, Step::Release { .. }) {
                    return;
                }
                let status = if n.duplicate.is_some() {
                    NodeStatus::CommunicationFaulted
                } else {
                    NodeStatus::NotPresent
                };
                if answered {
                    n.set(
                        NodeStatus::TimedOut,
                        Some(format!("stopped answering during its bring-up ({timeout})")),
                    );
                } else {
                    n.set(status, n.duplicate.clone().or_else(|| Some("nothing answers at this MAC".into())));
                }
                return;
            }
            Event::Failed(NodeError::Aborted { reason, .. }) => {
                n.set(NodeStatus::ErrorResponse, Some(reason));
                return;
            }
            Event::Failed(other) => {
                n.set(NodeStatus::ErrorResponse, Some(other.to_string()));
                return;
            }
        };
        // The input is the connection's produced size; the output what Connection 2 consumes
        // (poll commands, or the scanner's COS/cyclic data, §II.2.5), for a strobe the strobe
        // command (Connection 3 attribute 8).
        let output_instance = if n.kind == IoKind::Strobe { 3 } else { 2 };
        match (step, body) {
            (Step::Allocate { .. }, ReplyBody::Success(_)) => {
                n.allocated = n.choice();
                if let Some(e) = &mut n.engine {
                    for a in [1u8, 2, 3, 4, 6, 7] {
                        e.get(now, class::IDENTITY, 1, a, Refusal::Report);
                    }
                    e.get(now, class::CONNECTION, n.kind.instance(), 7, Refusal::Report);
                    e.get(now, class::CONNECTION, output_instance, 8, Refusal::Report);
                }
            }
            (Step::Allocate { .. }, ReplyBody::Error { general, additional }) => {
                let why = if general == GeneralStatus::ObjectStateConflict && additional == 0x01 {
                    "allocated by another master".to_string()
                } else {
                    format!("allocation refused: {}", decode::error_text(general, additional))
                };
                n.set(NodeStatus::ErrorResponse, Some(why));
            }
            (Step::Release { .. }, _) => n.allocated = AllocationChoice::empty(),
            (Step::Get { class: c, instance: i, attribute: a }, ReplyBody::Success(data)) => {
                match (c, i, a) {
                    (class::IDENTITY, 1, a) => {
                        n.state.identity.take_attribute(a, &data);
                    }
                    (class::CONNECTION, i, 7) if i == n.kind.instance() => {
                        n.state.input_size = decode::u16_of(&data)
                    }
                    (class::CONNECTION, 2, 8) => n.state.output_size = decode::u16_of(&data),
                    (class::CONNECTION, 3, 8) => {
                        // The node's output is its bit of the strobe command: no output data.
                        n.strobe_consumed = decode::u16_of(&data);
                        n.state.output_size = Some(0);
                    }
                    _ => {}
                }
                // The last read: the key and sizes against the scan list, then establish.
                if (c, i, a) == (class::CONNECTION, output_instance, 8) && Self::check(n, now) {
                    if let Some(e) = &mut n.engine {
                        if let (IoKind::ChangeOfState, Some(ms)) = (n.kind, n.entry.inhibit_ms) {
                            e.set(now, (class::CONNECTION, 4, 17), &ms.to_le_bytes(), Refusal::Report);
                        }
                        let epr = epr_ms.to_le_bytes();
                        e.set(now, (class::CONNECTION, n.kind.instance(), 9), &epr, Refusal::Report);
                    }
                }
            }
            (Step::Get { class: c, instance: i, attribute: a }, ReplyBody::Error { general, additional }) => {
                // Identity attributes are optional to read (the key then compares "nothing");
                // the connection sizes are not.
                if c == class::CONNECTION {
                    let why = format!(
                        "{} {}: {}",
                        decode::class_text(c),
                        decode::attribute_text(c, i, a),
                        decode::error_text(general, additional)
                    );
                    n.give_up(NodeStatus::ErrorResponse, why, now);
                }
            }
            (Step::Set { attribute: 17, value, .. }, ReplyBody::Error { general, additional }) => {
                let ms = match value.as_slice() {
                    [lo, hi] => u16::from_le_bytes([*lo, *hi]),
                    _ => 0,
                };
                let why = format!(
                    "production inhibit time {ms} ms refused: {}",
                    decode::error_text(general, additional)
                );
                n.give_up(NodeStatus::ErrorResponse, why, now);
            }
            (Step::Set { attribute: 9, .. }, ReplyBody::Success(_)) => {
                n.in_io = true;
                n.in_io_since = now;
                n.last_exchange = None;
                n.awaiting = false;
                n.output_sent = None;
                n.output_ack = None;
                n.next_output = now;
                *n.rx = IoReassembler::new();
                let what = n.input_name();
                n.set(NodeStatus::Initializing, Some(format!("in I/O, waiting for the first {what}")));
                if n.state.output.len() != n.output_len() {
                    n.state.output = vec![0; n.output_len()];
                }
            }
            (Step::Set { attribute: 9, .. }, ReplyBody::Error { general, additional }) => {
                let why =
                    format!("expected packet rate refused: {}", decode::error_text(general, additional));
                n.give_up(NodeStatus::ErrorResponse, why, now);
            }
            (Step::Set { .. }, _) => {}
        }
    }
}
