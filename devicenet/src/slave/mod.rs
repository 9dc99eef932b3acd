//! The group-2-only slave node (devicenet-notes §3–§8).
//!
//! [`SlaveNode`] is a pure state machine in the style of quinn-proto: inputs are the `handle_*`
//! methods, outputs are drained with the `poll_*` methods. After any input, drain in this order:
//!
//! 1. [`SlaveNode::poll_transmit`] until `None` (frames to put on the bus, in order);
//! 2. [`SlaveNode::poll_event`] until `None` (what the application must act on);
//! 3. [`SlaveNode::poll_at`]: call [`SlaveNode::handle_timeout`] at that instant at the latest.
//!
//! What it does:
//! - network access: duplicate MAC ID check (two requests 1 s apart, on-line 1 s after the second),
//!   answering other nodes' checks for our MAC, Communication Faulted on conflict, bus-off with the
//!   bus-off interrupt setting and counter (notes §7.1, §7.2);
//! - the Predefined Master/Slave Connection Set through the Group 2 Only Unconnected Explicit
//!   Request port and through the explicit connection, with the validation of notes §3.4; every
//!   Group 3 (UCMM) frame is ignored;
//! - Identity, Message Router, DeviceNet, Assembly and Connection objects (notes §5, §6), with
//!   explicit fragmentation both ways (notes §4.1); application objects through [`ObjectHandler`];
//! - the explicit (instance 1) and poll (instance 2) connections with their watchdogs (notes §5);
//!   poll responses are sent at once from the input image, fragmented above 8 bytes (notes §4.2).
//!
//! Bit-strobe, multicast poll, change-of-state and cyclic connections are not offered: allocating
//! them is answered with 0x02 resource unavailable / 0x02 (notes §3.4, "asks for a connection type
//! the device lacks").

pub mod config;
pub mod connection;
pub mod reply;

pub use config::{BaudRate, ConfigError, DeviceConfig, Identity, Switches, MAX_EXPLICIT_SIZE, MAX_IO_SIZE};
pub use connection::{Connection, ConnectionKind, ConnectionState, WatchdogAction};
pub use reply::{Reply, ServiceError};

use crate::explicit::{
    additional, split_message, BodyFormat, GeneralStatus, Header, Request, Response, ServiceCode,
};
use crate::fragment::{
    io_fragments, ExplicitReassembler, ExplicitReceive, ExplicitTransmitter, FragmentByte, FragmentKind,
    IoReassembler, TransmitEvent,
};
use crate::frame::{CanFrame, CanId};
use crate::id::{Group1MessageId, Group2Message, Identifier, MacId};
use crate::led::{self, Indication, Leds};
use crate::messages::{AllocateRequest, AllocationChoice, DuplicateMacCheck, ReleaseRequest};
use crate::time::{Duration, Instant};
use connection::{Expiry, MAX_EPR_MS};
use heapless::Deque;

/// Frames the node can hold for transmission.
pub const TX_QUEUE_LEN: usize = 16;
/// Events the node can hold for the application.
pub const EVENT_QUEUE_LEN: usize = 16;
/// Time between the two duplicate MAC ID requests, and from the second to on-line (notes §7.1).
pub const DUP_MAC_INTERVAL: Duration = Duration::from_secs(1);

/// The connection types this node offers.
const SUPPORTED: AllocationChoice = AllocationChoice::EXPLICIT.union(AllocationChoice::POLL);

// Object classes (notes §6, §5).
const CLASS_IDENTITY: u16 = 0x01;
const CLASS_MESSAGE_ROUTER: u16 = 0x02;
const CLASS_DEVICENET: u16 = 0x03;
const CLASS_ASSEMBLY: u16 = 0x04;
const CLASS_CONNECTION: u16 = 0x05;

/// Why the node is in the Communication Faulted state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FaultReason {
    /// Another node uses our MAC ID (notes §7.1).
    DuplicateMacId,
    /// The CAN controller went bus-off with BOI = 0 (notes §7.2).
    BusOff,
}

/// Network access state (notes §7.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NetworkState {
    /// Before [`SlaveNode::power_on`]: the node neither sends nor receives.
    PoweredOff,
    /// Duplicate MAC ID check in progress: `requests_sent` of 2 sent, next step at `deadline`.
    DuplicateMacCheck {
        /// Requests sent so far (1 or 2).
        requests_sent: u8,
        /// When the next request is sent, or the node goes on-line.
        deadline: Instant,
    },
    /// On-line.
    Online,
    /// Communication Faulted: silent until reset (notes §7.4).
    CommunicationFaulted(FaultReason),
}

/// A DeviceNet object attribute the master changed, which the application should store
/// (non-volatile) and apply as the attribute says.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SettingChanged {
    /// DeviceNet attribute 1; takes effect after a reset.
    MacId(MacId),
    /// DeviceNet attribute 2; takes effect after a reset.
    BaudRate(BaudRate),
    /// DeviceNet attribute 3; takes effect at once.
    BusOffInterrupt(bool),
}

/// What the application must know about or act on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// The duplicate MAC ID check passed; the node is on-line.
    Online,
    /// The node entered Communication Faulted.
    CommunicationFaulted(FaultReason),
    /// Bus-off with BOI = 1: reset the CAN controller; the node restarts its duplicate MAC check.
    ResetCanController,
    /// Connections were allocated by `master`.
    Allocated {
        /// The connections allocated by this request.
        choice: AllocationChoice,
        /// The owning master.
        master: MacId,
    },
    /// Connections were released; `owned` tells whether the master still owns the set.
    Released {
        /// The connections released.
        choice: AllocationChoice,
        /// Whether any connection is still allocated.
        owned: bool,
    },
    /// The connection went to Established (poll: its EPR was set).
    ConnectionEstablished(ConnectionKind),
    /// The connection's watchdog expired and it went to Timed Out (the application applies its
    /// fault behaviour).
    ConnectionTimedOut(ConnectionKind),
    /// The connection was deleted by its watchdog (not by a release).
    ConnectionDeleted(ConnectionKind),
    /// New output data arrived (poll command or Assembly set); read it with
    /// [`SlaveNode::output`].
    OutputReceived,
    /// A zero-length poll command: the master is idle. The output image is unchanged.
    Idle,
    /// Identity Reset was requested (type 0: power cycle, 1: out-of-box); the response has been
    /// queued. Reset once it is on the bus.
    ResetRequested(u8),
    /// A setting was changed over the network.
    SettingChanged(SettingChanged),
    /// A fragmented explicit response was abandoned (ack timeout or rejection).
    ExplicitTransferAborted,
}

/// Serves requests for object classes the core does not implement (vendor objects, the Parameter
/// object). `None` means "no such class": the node answers 0x16 object does not exist.
pub trait ObjectHandler {
    /// Serves `request`, writing response data into `reply`.
    fn handle(&mut self, request: &Request<'_>, reply: &mut Reply<'_>) -> Option<Result<(), ServiceError>>;
}

/// An [`ObjectHandler`] with no objects.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoObjects;

impl ObjectHandler for NoObjects {
    fn handle(&mut self, _: &Request<'_>, _: &mut Reply<'_>) -> Option<Result<(), ServiceError>> {
        None
    }
}

/// Fault and status flags the application reports through the Identity object (notes §6.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ApplicationStatus {
    /// Identity status bit 2.
    pub configured: bool,
    /// Bit 8: minor recoverable fault (e.g. the serial instrument is silent).
    pub minor_recoverable_fault: bool,
    /// Bit 9.
    pub minor_unrecoverable_fault: bool,
    /// Bit 10.
    pub major_recoverable_fault: bool,
    /// Bit 11.
    pub major_unrecoverable_fault: bool,
    /// Module Status flashes green (standby: configuration missing or incomplete).
    pub standby: bool,
}

/// Counters for diagnostics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeStats {
    /// Frames handed to [`SlaveNode::handle_frame`].
    pub frames_received: u32,
    /// Frames queued for transmission.
    pub frames_queued: u32,
    /// Frames dropped because the transmit queue was full.
    pub tx_overflows: u32,
    /// Events dropped because the event queue was full.
    pub event_overflows: u32,
    /// Poll commands ignored (connection not established, too long, bad fragments).
    pub polls_ignored: u32,
    /// Explicit requests ignored (not from the owner, no connection, malformed).
    pub explicit_ignored: u32,
}

/// A group-2-only DeviceNet slave node. See the [module docs](self) for the contract.
pub struct SlaveNode {
    config: DeviceConfig,
    network: NetworkState,
    powered_on_at: Option<Instant>,
    explicit: Connection,
    poll: Connection,
    allocation: AllocationChoice,
    master: Option<MacId>,
    input: heapless::Vec<u8, MAX_IO_SIZE>,
    output: heapless::Vec<u8, MAX_IO_SIZE>,
    io_idle: bool,
    poll_rx: IoReassembler<MAX_IO_SIZE>,
    explicit_rx: ExplicitReassembler<MAX_EXPLICIT_SIZE>,
    explicit_tx: ExplicitTransmitter<MAX_EXPLICIT_SIZE>,
    tx: Deque<CanFrame, TX_QUEUE_LEN>,
    events: Deque<Event, EVENT_QUEUE_LEN>,
    bus_off_counter: u8,
    bus_off_interrupt: bool,
    pending_mac: MacId,
    pending_baud: BaudRate,
    app_status: ApplicationStatus,
    network_indication: (Indication, Instant),
    module_indication: (Indication, Instant),
    stats: NodeStats,
}

impl SlaveNode {
    /// A powered-off node for `config`. The input image starts as zeros.
    pub fn new(config: DeviceConfig) -> Result<SlaveNode, ConfigError> {
        config.validate()?;
        let mut input = heapless::Vec::new();
        // validate() bounds the produced size by MAX_IO_SIZE, so this cannot fail.
        let _ = input.resize(usize::from(config.produced_size), 0);
        Ok(SlaveNode {
            network: NetworkState::PoweredOff,
            powered_on_at: None,
            explicit: Connection::new(ConnectionKind::Explicit),
            poll: Connection::new(ConnectionKind::Poll),
            allocation: AllocationChoice::empty(),
            master: None,
            input,
            output: heapless::Vec::new(),
            io_idle: false,
            poll_rx: IoReassembler::new(),
            explicit_rx: ExplicitReassembler::new(),
            explicit_tx: ExplicitTransmitter::new(),
            tx: Deque::new(),
            events: Deque::new(),
            bus_off_counter: 0,
            bus_off_interrupt: config.bus_off_interrupt,
            pending_mac: config.mac_id,
            pending_baud: config.baud_rate,
            app_status: ApplicationStatus::default(),
            network_indication: (Indication::Off, Instant::ZERO),
            module_indication: (Indication::Off, Instant::ZERO),
            stats: NodeStats::default(),
            config,
        })
    }

    /// The configuration the node runs with.
    pub fn config(&self) -> &DeviceConfig {
        &self.config
    }

    /// This node's MAC ID.
    pub fn mac_id(&self) -> MacId {
        self.config.mac_id
    }

    /// Network access state.
    pub fn network_state(&self) -> NetworkState {
        self.network
    }

    /// The explicit connection (instance 1).
    pub fn explicit_connection(&self) -> &Connection {
        &self.explicit
    }

    /// The poll connection (instance 2).
    pub fn poll_connection(&self) -> &Connection {
        &self.poll
    }

    /// The allocated connections and the owning master (DeviceNet attribute 5).
    pub fn allocation(&self) -> (AllocationChoice, Option<MacId>) {
        (self.allocation, self.master)
    }

    /// The last output data consumed (poll command or Assembly set).
    pub fn output(&self) -> &[u8] {
        &self.output
    }

    /// The input image sent in every poll response.
    pub fn input(&self) -> &[u8] {
        &self.input
    }

    /// `true` while the last poll command was zero-length (master idle).
    pub fn is_idle(&self) -> bool {
        self.io_idle
    }

    /// Diagnostic counters.
    pub fn stats(&self) -> &NodeStats {
        &self.stats
    }

    /// The bus-off counter (DeviceNet attribute 4).
    pub fn bus_off_counter(&self) -> u8 {
        self.bus_off_counter
    }

    /// Replaces the input image. It must be exactly the produced size; otherwise the image is
    /// left unchanged and the expected size is returned as the error.
    pub fn set_input(&mut self, data: &[u8]) -> Result<(), usize> {
        if data.len() != self.input.len() {
            return Err(self.input.len());
        }
        self.input.copy_from_slice(data);
        Ok(())
    }

    /// Sets the fault and status flags reported through the Identity object and the Module LED.
    pub fn set_application_status(&mut self, status: ApplicationStatus, now: Instant) {
        self.app_status = status;
        self.update_indications(now);
    }

    /// Power-on (or reset): starts the duplicate MAC ID check by queueing the first request
    /// (notes §7.1). The power-up LED test runs alongside it for 1.5 s.
    pub fn power_on(&mut self, now: Instant) {
        self.reset_connections();
        self.tx.clear();
        self.powered_on_at = Some(now);
        self.start_duplicate_mac_check(now);
        self.update_indications(now);
    }

    fn start_duplicate_mac_check(&mut self, now: Instant) {
        self.send_duplicate_mac(false);
        self.network = NetworkState::DuplicateMacCheck { requests_sent: 1, deadline: now + DUP_MAC_INTERVAL };
    }

    /// Handles a received frame at `now`, with no application objects.
    pub fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.handle_frame_with(frame, now, &mut NoObjects);
    }

    /// Handles a received frame at `now`; requests for classes the core does not implement go to
    /// `objects`.
    pub fn handle_frame_with<H: ObjectHandler>(&mut self, frame: &CanFrame, now: Instant, objects: &mut H) {
        self.handle_timeout(now);
        self.stats.frames_received = self.stats.frames_received.wrapping_add(1);
        // Only Group 2 concerns a group-2-only slave: Group 1 is produced by slaves, Group 3 is UCMM
        // (never answered, notes §3.4), Group 4 is the optional Offline Connection Set.
        if let Identifier::Group2 { mac, message } = Identifier::decode(frame.id()) {
            if mac == self.config.mac_id {
                match message {
                    Group2Message::DuplicateMacCheck => self.on_duplicate_mac(frame.data(), now),
                    _ if self.network != NetworkState::Online => {}
                    Group2Message::UnconnectedExplicitRequest => self.on_group2_only(frame.data(), now),
                    Group2Message::ExplicitRequest => self.on_explicit(frame.data(), now, objects),
                    Group2Message::PollCommand => self.on_poll(frame.data(), now),
                    _ => {}
                }
            }
        }
        self.update_indications(now);
    }

    /// The CAN controller reports bus-off (notes §7.2): the bus-off counter increments; with
    /// BOI = 0 the node enters Communication Faulted, with BOI = 1 the application resets the
    /// controller and the node restarts its duplicate MAC check (notes §9.9: GC's behaviour).
    pub fn handle_bus_off(&mut self, now: Instant) {
        if self.network == NetworkState::PoweredOff {
            return;
        }
        self.bus_off_counter = self.bus_off_counter.saturating_add(1);
        self.reset_connections();
        self.tx.clear();
        if self.bus_off_interrupt {
            self.push_event(Event::ResetCanController);
            self.start_duplicate_mac_check(now);
        } else {
            self.fault(FaultReason::BusOff);
        }
        self.update_indications(now);
    }

    /// Runs every timer due at `now`: duplicate MAC steps, connection watchdogs, explicit
    /// fragment acknowledgement timeouts.
    pub fn handle_timeout(&mut self, now: Instant) {
        if let NetworkState::DuplicateMacCheck { requests_sent, deadline } = self.network {
            if now >= deadline {
                if requests_sent < 2 {
                    self.send_duplicate_mac(false);
                    self.network = NetworkState::DuplicateMacCheck {
                        requests_sent: 2,
                        deadline: deadline + DUP_MAC_INTERVAL,
                    };
                } else {
                    self.network = NetworkState::Online;
                    self.push_event(Event::Online);
                }
            }
        }
        self.run_watchdogs(now);
        self.pump_explicit(now);
        while let Some(ev) = self.explicit_tx.poll_event(now) {
            if let TransmitEvent::Aborted(_) = ev {
                self.push_event(Event::ExplicitTransferAborted);
            }
        }
        self.update_indications(now);
    }

    /// The next frame to transmit, if any.
    pub fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.tx.pop_front()
    }

    /// The next event for the application, if any.
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// When [`SlaveNode::handle_timeout`] must be called next, if any timer is armed.
    pub fn poll_at(&self) -> Option<Instant> {
        let dup = match self.network {
            NetworkState::DuplicateMacCheck { deadline, .. } => Some(deadline),
            _ => None,
        };
        [dup, self.explicit.deadline, self.poll.deadline, self.explicit_tx.poll_at()]
            .into_iter()
            .flatten()
            .min()
    }

    /// What the Module and Network Status LEDs show now, including the power-up test
    /// (notes §7.3).
    pub fn leds(&self, now: Instant) -> Leds {
        if let Some(on) = self.powered_on_at {
            if let Some(test) = led::self_test(now - on) {
                return test;
            }
        }
        Leds {
            module: self.module_indication.0.lit(self.module_indication.1, now),
            network: self.network_indication.0.lit(self.network_indication.1, now),
        }
    }

    /// The Network Status indication (notes §7.3).
    pub fn network_indication(&self) -> Indication {
        match self.network {
            NetworkState::PoweredOff | NetworkState::DuplicateMacCheck { .. } => Indication::Off,
            NetworkState::CommunicationFaulted(_) => Indication::Red,
            NetworkState::Online if self.poll.state == ConnectionState::TimedOut => Indication::FlashingRed,
            NetworkState::Online if self.master.is_some() => Indication::Green,
            NetworkState::Online => Indication::FlashingGreen,
        }
    }

    /// The Module Status indication (notes §7.3).
    pub fn module_indication(&self) -> Indication {
        let s = &self.app_status;
        if self.network == NetworkState::PoweredOff {
            Indication::Off
        } else if s.major_unrecoverable_fault || s.major_recoverable_fault {
            Indication::Red
        } else if s.minor_recoverable_fault || s.minor_unrecoverable_fault {
            Indication::FlashingRed
        } else if s.standby {
            Indication::FlashingGreen
        } else {
            Indication::Green
        }
    }

    /// The Identity status word, attribute 5 (notes §6.2).
    pub fn identity_status(&self) -> u16 {
        let s = &self.app_status;
        let extended: u16 = if self.poll.state == ConnectionState::TimedOut {
            0b0010 // at least one faulted I/O connection
        } else if !self.poll.is_established() {
            0b0011 // no I/O connection established
        } else if self.io_idle {
            0b0111 // I/O connection established, all idle
        } else {
            0b0110 // at least one I/O connection in run mode
        };
        u16::from(self.master.is_some())
            | u16::from(s.configured) << 2
            | extended << 4
            | u16::from(s.minor_recoverable_fault) << 8
            | u16::from(s.minor_unrecoverable_fault) << 9
            | u16::from(s.major_recoverable_fault) << 10
            | u16::from(s.major_unrecoverable_fault) << 11
    }

    /// Identity state, attribute 8.
    fn identity_state(&self) -> u8 {
        if self.app_status.major_unrecoverable_fault {
            5
        } else if self.app_status.major_recoverable_fault {
            4
        } else {
            3
        }
    }

    // ----- outputs -------------------------------------------------------------------------

    fn queue(&mut self, frame: CanFrame) {
        if self.tx.push_back(frame).is_err() {
            self.stats.tx_overflows = self.stats.tx_overflows.wrapping_add(1);
        } else {
            self.stats.frames_queued = self.stats.frames_queued.wrapping_add(1);
        }
    }

    fn queue_data(&mut self, id: CanId, data: &[u8]) {
        if let Ok(frame) = CanFrame::new(id, data) {
            self.queue(frame);
        }
    }

    fn push_event(&mut self, ev: Event) {
        if self.events.push_back(ev).is_err() {
            self.stats.event_overflows = self.stats.event_overflows.wrapping_add(1);
        }
    }

    fn response_id(&self) -> CanId {
        Identifier::group2(self.config.mac_id, Group2Message::ExplicitResponse)
    }

    fn poll_response_id(&self) -> CanId {
        Identifier::group1(Group1MessageId::POLL_RESPONSE, self.config.mac_id)
    }

    fn send_duplicate_mac(&mut self, response: bool) {
        let msg = DuplicateMacCheck {
            response,
            port: self.config.port,
            vendor_id: self.config.identity.vendor_id,
            serial_number: self.config.identity.serial_number,
        };
        let id = Identifier::group2(self.config.mac_id, Group2Message::DuplicateMacCheck);
        self.queue_data(id, &msg.emit());
    }

    fn pump_explicit(&mut self, now: Instant) {
        let id = self.response_id();
        while let Some(payload) = self.explicit_tx.poll_transmit(now) {
            self.queue_data(id, &payload);
        }
    }

    fn update_indications(&mut self, now: Instant) {
        let net = self.network_indication();
        if net != self.network_indication.0 {
            self.network_indication = (net, now);
        }
        let module = self.module_indication();
        if module != self.module_indication.0 {
            self.module_indication = (module, now);
        }
    }

    fn fault(&mut self, reason: FaultReason) {
        self.network = NetworkState::CommunicationFaulted(reason);
        self.reset_connections();
        self.push_event(Event::CommunicationFaulted(reason));
    }

    fn reset_connections(&mut self) {
        self.explicit.delete();
        self.poll.delete();
        self.allocation = AllocationChoice::empty();
        self.master = None;
        self.io_idle = false;
        self.explicit_rx.reset();
        self.explicit_tx.reset();
        self.poll_rx.reset();
    }

    // ----- network access (notes §7.1) -------------------------------------------------------

    fn on_duplicate_mac(&mut self, data: &[u8], _now: Instant) {
        let Ok(check) = DuplicateMacCheck::parse(data) else { return };
        match self.network {
            // Any request or response for our MAC during our own check: someone else has it.
            NetworkState::DuplicateMacCheck { .. } => self.fault(FaultReason::DuplicateMacId),
            NetworkState::Online if !check.response => self.send_duplicate_mac(true),
            NetworkState::Online => self.fault(FaultReason::DuplicateMacId),
            NetworkState::PoweredOff | NetworkState::CommunicationFaulted(_) => {}
        }
    }

    // ----- connections -----------------------------------------------------------------------

    fn run_watchdogs(&mut self, now: Instant) {
        match self.poll.expire(now) {
            Expiry::TimedOut => {
                self.push_event(Event::ConnectionTimedOut(ConnectionKind::Poll));
                self.after_io_lost();
            }
            Expiry::Delete => {
                self.delete_connection(ConnectionKind::Poll);
                self.push_event(Event::ConnectionDeleted(ConnectionKind::Poll));
                self.after_io_lost();
            }
            Expiry::Reset | Expiry::None | Expiry::DeferredDelete => {}
        }
        match self.explicit.expire(now) {
            Expiry::Delete => self.delete_by_watchdog(ConnectionKind::Explicit),
            Expiry::DeferredDelete if self.poll.is_established() => {
                self.explicit.state = ConnectionState::DeferredDelete;
            }
            Expiry::DeferredDelete => self.delete_by_watchdog(ConnectionKind::Explicit),
            Expiry::TimedOut | Expiry::Reset | Expiry::None => {}
        }
    }

    /// An I/O connection timed out or was deleted: an explicit connection in deferred delete
    /// goes with it (notes §5.2).
    fn after_io_lost(&mut self) {
        if self.explicit.state == ConnectionState::DeferredDelete {
            self.delete_by_watchdog(ConnectionKind::Explicit);
        }
    }

    fn delete_by_watchdog(&mut self, kind: ConnectionKind) {
        self.delete_connection(kind);
        self.push_event(Event::ConnectionDeleted(kind));
    }

    fn delete_connection(&mut self, kind: ConnectionKind) {
        match kind {
            ConnectionKind::Explicit => {
                self.explicit.delete();
                self.explicit_rx.reset();
                self.explicit_tx.reset();
                self.allocation = self.allocation.difference(AllocationChoice::EXPLICIT);
            }
            ConnectionKind::Poll => {
                self.poll.delete();
                self.poll_rx.reset();
                self.io_idle = false;
                self.allocation = self.allocation.difference(AllocationChoice::POLL);
            }
        }
        // With no connection left the master's ownership ends (JB, notes §3.4).
        if self.allocation.difference(AllocationChoice::ACK_SUPPRESSION).is_empty() {
            self.allocation = AllocationChoice::empty();
            self.master = None;
        }
    }

    fn connection_mut(&mut self, instance: u16) -> Option<&mut Connection> {
        match instance {
            1 => Some(&mut self.explicit),
            2 => Some(&mut self.poll),
            _ => None,
        }
    }

    // ----- Group 2 Only Unconnected Explicit Request port (notes §3.4) -------------------------

    fn on_group2_only(&mut self, data: &[u8], now: Instant) {
        let Ok((header, body)) = split_message(data) else { return };
        if header.fragmented || body[0] & 0x80 != 0 {
            return; // unconnected messages are never fragmented; responses are not for us
        }
        let result = match Request::parse(body, BodyFormat::Class8Instance8) {
            Ok(req) => match req.service {
                ServiceCode::AllocateMasterSlave | ServiceCode::ReleaseMasterSlave
                    if (req.class, req.instance) != (CLASS_DEVICENET, 1) =>
                {
                    Err(ServiceError::OBJECT_DOES_NOT_EXIST)
                }
                ServiceCode::AllocateMasterSlave => self.allocate(req.data, now),
                ServiceCode::ReleaseMasterSlave => self.release(header.mac, req.data),
                _ => Err(invalid_group2_only_request()),
            },
            Err(_) => match ServiceCode::from(body[0]) {
                ServiceCode::AllocateMasterSlave | ServiceCode::ReleaseMasterSlave => {
                    Err(ServiceError::NOT_ENOUGH_DATA)
                }
                _ => Err(invalid_group2_only_request()),
            },
        };
        let service = ServiceCode::from(body[0]);
        let mut buf = [0u8; 4];
        let n = match result {
            Ok(body_format) => {
                buf[1] = 0x80 | service.as_raw();
                match body_format {
                    Some(fmt) => {
                        buf[2] = fmt;
                        3
                    }
                    None => 2,
                }
            }
            Err(e) => {
                let resp = Response::Error { general: e.general, additional: e.additional };
                let _ = resp.emit(&mut buf[1..]);
                4
            }
        };
        buf[0] = Header::new(header.xid, header.mac).to_byte();
        let id = self.response_id();
        self.queue_data(id, &buf[..n]);
    }

    /// Allocate_Master/Slave_Connection_Set (notes §3.4), validation in JB's order. Returns the
    /// body format byte of the success response.
    fn allocate(&mut self, data: &[u8], now: Instant) -> Result<Option<u8>, ServiceError> {
        ServiceError::expect_len(data, 2)?;
        let req = AllocateRequest::parse(data).map_err(|_| invalid_choice())?;
        let choice = req.choice;
        if self.master.is_some_and(|m| m != req.allocator) {
            return Err(ServiceError::with_additional(
                GeneralStatus::ObjectStateConflict,
                additional::ALLOCATION_CONFLICT,
            ));
        }
        if choice.is_empty() {
            return Err(invalid_choice());
        }
        let cos_or_cyclic = AllocationChoice::CHANGE_OF_STATE.union(AllocationChoice::CYCLIC);
        if choice.contains(AllocationChoice::ACK_SUPPRESSION) && !choice.intersects(cos_or_cyclic) {
            return Err(invalid_choice());
        }
        if !SUPPORTED.contains(choice) {
            return Err(ServiceError::with_additional(
                GeneralStatus::ResourceUnavailable,
                additional::INVALID_CHOICE,
            ));
        }
        if !choice.contains(AllocationChoice::EXPLICIT) && !self.explicit.exists() {
            return Err(invalid_choice());
        }
        if choice.intersects(self.allocation) {
            return Err(ServiceError::with_additional(
                GeneralStatus::AlreadyInRequestedState,
                additional::INVALID_CHOICE,
            ));
        }
        self.master = Some(req.allocator);
        self.allocation = self.allocation.union(choice);
        if choice.contains(AllocationChoice::EXPLICIT) {
            self.explicit.allocate(now);
            self.push_event(Event::ConnectionEstablished(ConnectionKind::Explicit));
        }
        if choice.contains(AllocationChoice::POLL) {
            self.poll.allocate(now);
        }
        self.push_event(Event::Allocated { choice, master: req.allocator });
        // Our explicit connection uses message body format 0 (8/8).
        Ok(Some(BodyFormat::Class8Instance8.code()))
    }

    /// Release_Master/Slave_Connection_Set (notes §3.4).
    fn release(&mut self, requester: MacId, data: &[u8]) -> Result<Option<u8>, ServiceError> {
        ServiceError::expect_len(data, 1)?;
        let req = ReleaseRequest::parse(data).map_err(|_| invalid_choice())?;
        let choice = req.choice;
        if self.master.is_some_and(|m| m != requester) {
            return Err(ServiceError::with_additional(
                GeneralStatus::ObjectStateConflict,
                additional::ALLOCATION_CONFLICT,
            ));
        }
        if choice.is_empty() || choice.contains(AllocationChoice::ACK_SUPPRESSION) {
            return Err(invalid_choice());
        }
        if !SUPPORTED.contains(choice) {
            return Err(ServiceError::with_additional(
                GeneralStatus::ResourceUnavailable,
                additional::INVALID_CHOICE,
            ));
        }
        if !self.allocation.contains(choice) {
            return Err(ServiceError::with_additional(
                GeneralStatus::AlreadyInRequestedState,
                additional::INVALID_CHOICE,
            ));
        }
        if choice.contains(AllocationChoice::POLL) {
            self.delete_connection(ConnectionKind::Poll);
        }
        if choice.contains(AllocationChoice::EXPLICIT) {
            self.delete_connection(ConnectionKind::Explicit);
        }
        self.push_event(Event::Released { choice, owned: self.master.is_some() });
        Ok(None)
    }

    // ----- explicit connection (notes §3.1, §4.1) ----------------------------------------------

    fn on_explicit<H: ObjectHandler>(&mut self, data: &[u8], now: Instant, objects: &mut H) {
        let Some(&first) = data.first() else { return };
        let header = Header::from_byte(first);
        let live =
            matches!(self.explicit.state, ConnectionState::Established | ConnectionState::DeferredDelete);
        // Only the owning master may use the explicit connection (notes §8, JB).
        if !live || Some(header.mac) != self.master || data.len() < 2 {
            self.stats.explicit_ignored = self.stats.explicit_ignored.wrapping_add(1);
            return;
        }
        // Any message consumed restarts the inactivity timer; deferred delete -> established.
        self.explicit.state = ConnectionState::Established;
        self.explicit.restart_timer(now);
        let id = self.response_id();
        if header.fragmented {
            if FragmentByte::from_byte(data[1]).kind == FragmentKind::Ack {
                self.explicit_tx.handle_ack(data, now);
                self.pump_explicit(now);
                return;
            }
            match self.explicit_rx.receive(data) {
                ExplicitReceive::Ack(ack)
                | ExplicitReceive::Duplicate(ack)
                | ExplicitReceive::Rejected(ack) => {
                    self.queue_data(id, &ack);
                }
                ExplicitReceive::Complete(ack) => {
                    self.queue_data(id, &ack);
                    let mut message = [0u8; MAX_EXPLICIT_SIZE];
                    let whole = self.explicit_rx.message();
                    let n = whole.len().min(MAX_EXPLICIT_SIZE);
                    message[..n].copy_from_slice(&whole[..n]);
                    // The reassembler keeps its last answer (not reset here): a repeat of the last
                    // fragment, whose ack the master missed, is acknowledged again and the request
                    // is not served twice (notes §4.1, JB; found by the conformance suite).
                    self.serve(&message[..n], now, objects);
                }
                ExplicitReceive::Ignored(_) => {
                    self.stats.explicit_ignored = self.stats.explicit_ignored.wrapping_add(1);
                }
            }
        } else {
            // An unfragmented request resets both directions' fragmentation (JB, notes §4.1).
            self.explicit_rx.reset();
            self.explicit_tx.reset();
            self.serve(data, now, objects);
        }
    }

    /// Serves one whole explicit request message (header + body) and queues the response.
    fn serve<H: ObjectHandler>(&mut self, message: &[u8], now: Instant, objects: &mut H) {
        let Ok((header, body)) = split_message(message) else { return };
        let mut out = [0u8; MAX_EXPLICIT_SIZE];
        out[0] = Header::new(header.xid, header.mac).to_byte();
        let (result, service) = match Request::parse(body, BodyFormat::Class8Instance8) {
            Ok(req) => {
                let mut reply = Reply::new(&mut out[2..]);
                let r = self.dispatch(&req, &mut reply, now, objects).map(|()| reply.len());
                (r, req.service)
            }
            Err(crate::explicit::ExplicitError::NotARequest) => {
                self.stats.explicit_ignored = self.stats.explicit_ignored.wrapping_add(1);
                return;
            }
            Err(_) => (Err(ServiceError::NOT_ENOUGH_DATA), ServiceCode::from(body[0])),
        };
        let len = match result {
            Ok(n) => {
                out[1] = 0x80 | service.as_raw();
                2 + n
            }
            Err(e) => {
                out[1] = 0x80 | ServiceCode::ErrorResponse.as_raw();
                out[2] = e.general.as_raw();
                out[3] = e.additional;
                4
            }
        };
        if len <= 8 {
            let id = self.response_id();
            self.queue_data(id, &out[..len]);
        } else if self.explicit_tx.start(&out[..len], now).is_ok() {
            self.pump_explicit(now);
        }
    }

    fn dispatch<H: ObjectHandler>(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        now: Instant,
        objects: &mut H,
    ) -> Result<(), ServiceError> {
        match req.class {
            CLASS_IDENTITY => self.identity_service(req, reply),
            CLASS_MESSAGE_ROUTER => self.router_service(req, reply),
            CLASS_DEVICENET => self.devicenet_service(req, reply, now),
            CLASS_ASSEMBLY => self.assembly_service(req, reply),
            CLASS_CONNECTION => self.connection_service(req, reply, now),
            _ => objects.handle(req, reply).unwrap_or(Err(ServiceError::OBJECT_DOES_NOT_EXIST)),
        }
    }

    // ----- Identity object (class 1, notes §6.2) ------------------------------------------------

    fn identity_service(&mut self, req: &Request<'_>, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        match (req.instance, req.service) {
            (0, ServiceCode::GetAttributeSingle) => class_revision(req.data, 1, reply),
            (0, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            (1, ServiceCode::GetAttributeSingle) => {
                ServiceError::expect_len(req.data, 1)?;
                self.identity_attribute(req.data[0], reply)
            }
            (1, ServiceCode::GetAttributesAll) => {
                for attr in 1..=7 {
                    self.identity_attribute(attr, reply)?;
                }
                Ok(())
            }
            (1, ServiceCode::SetAttributeSingle) => {
                let (&attr, _) = req.data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
                match attr {
                    1..=8 => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
                    _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
                }
            }
            (1, ServiceCode::Reset) => {
                let kind = match req.data {
                    [] => 0,
                    [k @ (0 | 1)] => *k,
                    [_] => return Err(ServiceError::INVALID_PARAMETER),
                    _ => return Err(ServiceError::TOO_MUCH_DATA),
                };
                self.push_event(Event::ResetRequested(kind));
                Ok(())
            }
            (1, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        }
    }

    fn identity_attribute(&self, attr: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let id = &self.config.identity;
        match attr {
            1 => reply.u16(id.vendor_id),
            2 => reply.u16(id.device_type),
            3 => reply.u16(id.product_code),
            4 => reply.bytes(&[id.major_revision, id.minor_revision]),
            5 => reply.u16(self.identity_status()),
            6 => reply.u32(id.serial_number),
            7 => reply.short_string(&id.product_name),
            8 => reply.u8(self.identity_state()),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    // ----- Message Router (class 2) -------------------------------------------------------------

    fn router_service(&mut self, req: &Request<'_>, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        match (req.instance, req.service) {
            (0, ServiceCode::GetAttributeSingle) => class_revision(req.data, 1, reply),
            (1, ServiceCode::GetAttributeSingle) => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
            (0 | 1, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        }
    }

    // ----- DeviceNet object (class 3, notes §6.1) -----------------------------------------------

    fn devicenet_service(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        now: Instant,
    ) -> Result<(), ServiceError> {
        match (req.instance, req.service) {
            (0, ServiceCode::GetAttributeSingle) => class_revision(req.data, 2, reply),
            (0, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            (1, ServiceCode::GetAttributeSingle) => {
                ServiceError::expect_len(req.data, 1)?;
                self.devicenet_attribute(req.data[0], reply)
            }
            (1, ServiceCode::SetAttributeSingle) => self.set_devicenet_attribute(req.data),
            (1, ServiceCode::AllocateMasterSlave) => match self.allocate(req.data, now)? {
                Some(fmt) => reply.u8(fmt),
                None => Ok(()),
            },
            (1, ServiceCode::ReleaseMasterSlave) => {
                // Through the explicit connection the requester is the owner (checked on entry).
                let owner = self.master.unwrap_or(MacId::MAX);
                self.release(owner, req.data).map(|_| ())
            }
            (1, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        }
    }

    fn devicenet_attribute(&self, attr: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let sw = &self.config.switches;
        match attr {
            1 => reply.u8(self.pending_mac.as_raw()),
            2 => reply.u8(self.pending_baud.attribute_value()),
            3 => reply.u8(u8::from(self.bus_off_interrupt)),
            4 => reply.u8(self.bus_off_counter),
            5 => {
                reply.u8(self.allocation.bits())?;
                reply.u8(self.master.map_or(0xFF, MacId::as_raw))
            }
            6 => reply.u8(u8::from(sw.mac_id_changed)),
            7 => reply.u8(u8::from(sw.baud_rate_changed)),
            8 => reply.u8(sw.mac_id.ok_or(ServiceError::ATTRIBUTE_NOT_SUPPORTED)?),
            9 => reply.u8(sw.baud_rate.ok_or(ServiceError::ATTRIBUTE_NOT_SUPPORTED)?),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    fn set_devicenet_attribute(&mut self, data: &[u8]) -> Result<(), ServiceError> {
        let (&attr, value) = data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
        let programmable = self.config.switches.programmable;
        let changed = match attr {
            1 | 2 if !programmable => return Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
            1..=4 => {
                ServiceError::expect_len(value, 1)?;
                let v = value[0];
                match attr {
                    1 => {
                        let mac = MacId::new(v).ok_or(ServiceError::INVALID_ATTRIBUTE_VALUE)?;
                        self.pending_mac = mac;
                        Some(SettingChanged::MacId(mac))
                    }
                    2 => {
                        let baud =
                            BaudRate::from_attribute_value(v).ok_or(ServiceError::INVALID_ATTRIBUTE_VALUE)?;
                        self.pending_baud = baud;
                        Some(SettingChanged::BaudRate(baud))
                    }
                    3 => {
                        let boi = match v {
                            0 => false,
                            1 => true,
                            _ => return Err(ServiceError::INVALID_ATTRIBUTE_VALUE),
                        };
                        self.bus_off_interrupt = boi;
                        Some(SettingChanged::BusOffInterrupt(boi))
                    }
                    _ => {
                        // The bus-off counter can only be cleared.
                        if v != 0 {
                            return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
                        }
                        self.bus_off_counter = 0;
                        None
                    }
                }
            }
            5..=9 => return Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
            _ => return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        };
        if let Some(c) = changed {
            self.push_event(Event::SettingChanged(c));
        }
        Ok(())
    }

    // ----- Assembly object (class 4) ------------------------------------------------------------

    fn assembly_service(&mut self, req: &Request<'_>, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let input = u16::from(self.config.input_assembly);
        let output = u16::from(self.config.output_assembly);
        if req.instance == 0 {
            return match req.service {
                ServiceCode::GetAttributeSingle => class_revision(req.data, 2, reply),
                _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            };
        }
        if req.instance != input && req.instance != output {
            return Err(ServiceError::OBJECT_DOES_NOT_EXIST);
        }
        let is_input = req.instance == input;
        match req.service {
            ServiceCode::GetAttributeSingle => {
                ServiceError::expect_len(req.data, 1)?;
                let data: &[u8] = if is_input { &self.input } else { &self.output };
                match req.data[0] {
                    3 => reply.bytes(data),
                    4 => {
                        let size =
                            if is_input { self.config.produced_size } else { self.config.consumed_size };
                        reply.u16(size)
                    }
                    _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
                }
            }
            ServiceCode::SetAttributeSingle => {
                let (&attr, value) = req.data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
                match attr {
                    3 if is_input => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
                    // The poll connection owns the outputs while it is established.
                    3 if self.poll.is_established() => Err(ServiceError::DEVICE_STATE_CONFLICT),
                    3 => {
                        ServiceError::expect_len(value, usize::from(self.config.consumed_size))?;
                        self.output.clear();
                        let _ = self.output.extend_from_slice(value);
                        self.push_event(Event::OutputReceived);
                        Ok(())
                    }
                    4 => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
                    _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
                }
            }
            _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
        }
    }

    // ----- Connection object (class 5, notes §5) -------------------------------------------------

    fn connection_service(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        now: Instant,
    ) -> Result<(), ServiceError> {
        if req.instance == 0 {
            return match req.service {
                ServiceCode::GetAttributeSingle => class_revision(req.data, 1, reply),
                _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            };
        }
        let conn = match self.connection_mut(req.instance) {
            Some(c) if c.exists() => *c,
            _ => return Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        };
        match req.service {
            ServiceCode::GetAttributeSingle => {
                ServiceError::expect_len(req.data, 1)?;
                self.connection_attribute(&conn, req.data[0], reply)
            }
            ServiceCode::SetAttributeSingle => {
                let (&attr, value) = req.data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
                self.set_connection_attribute(conn.kind, attr, value, reply, now)
            }
            ServiceCode::Reset => {
                // Restart the watchdog; deferred delete and timed out return to established
                // (notes §3.2 Westlock; §9.8 for timed-out I/O, UNCONFIRMED).
                let was_timed_out = conn.state == ConnectionState::TimedOut;
                if let Some(c) = self.connection_mut(req.instance) {
                    if matches!(c.state, ConnectionState::DeferredDelete | ConnectionState::TimedOut) {
                        c.state = ConnectionState::Established;
                    }
                    c.restart_timer(now);
                }
                if was_timed_out {
                    self.push_event(Event::ConnectionEstablished(conn.kind));
                }
                Ok(())
            }
            _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
        }
    }

    fn connection_attribute(
        &self,
        conn: &Connection,
        attr: u8,
        reply: &mut Reply<'_>,
    ) -> Result<(), ServiceError> {
        let mac = self.config.mac_id;
        let explicit = conn.kind == ConnectionKind::Explicit;
        let path = |asm: u8| [0x20, 0x04, 0x24, asm, 0x30, 0x03];
        match attr {
            1 => reply.u8(conn.state.attribute_value()),
            2 => reply.u8(if explicit { 0 } else { 1 }),
            3 => reply.u8(if explicit { 0x83 } else { 0x82 }),
            4 => reply.u16(if explicit {
                Identifier::group2(mac, Group2Message::ExplicitResponse).as_raw()
            } else {
                Identifier::group1(Group1MessageId::POLL_RESPONSE, mac).as_raw()
            }),
            5 => reply.u16(if explicit {
                Identifier::group2(mac, Group2Message::ExplicitRequest).as_raw()
            } else {
                Identifier::group2(mac, Group2Message::PollCommand).as_raw()
            }),
            6 => reply.u8(if explicit { 0x21 } else { 0x01 }),
            7 => reply.u16(if explicit { MAX_EXPLICIT_SIZE as u16 } else { self.config.produced_size }),
            8 => reply.u16(if explicit { MAX_EXPLICIT_SIZE as u16 } else { self.config.consumed_size }),
            9 => reply.u16(conn.expected_packet_rate),
            12 => reply.u8(conn.watchdog_action.attribute_value()),
            13 | 15 => reply.u16(if explicit { 0 } else { 6 }),
            14 if explicit => Ok(()),
            14 => reply.bytes(&path(self.config.input_assembly)),
            16 if explicit => Ok(()),
            16 => reply.bytes(&path(self.config.output_assembly)),
            17 => reply.u16(0),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    fn set_connection_attribute(
        &mut self,
        kind: ConnectionKind,
        attr: u8,
        value: &[u8],
        reply: &mut Reply<'_>,
        now: Instant,
    ) -> Result<(), ServiceError> {
        let resolution = self.config.epr_resolution_ms;
        match attr {
            9 => {
                ServiceError::expect_len(value, 2)?;
                let requested = u16::from_le_bytes([value[0], value[1]]);
                if requested > MAX_EPR_MS {
                    return Err(ServiceError::INVALID_ATTRIBUTE_VALUE);
                }
                // Rounded up to the timer resolution; the response carries the value in use
                // (notes §5.3).
                let applied = requested.div_ceil(resolution).saturating_mul(resolution);
                let conn = if kind == ConnectionKind::Explicit { &mut self.explicit } else { &mut self.poll };
                let was_configuring = conn.state == ConnectionState::Configuring;
                conn.set_expected_packet_rate(applied, now);
                if was_configuring {
                    self.push_event(Event::ConnectionEstablished(kind));
                }
                reply.u16(applied)
            }
            12 => {
                ServiceError::expect_len(value, 1)?;
                let action = kind.parse_action(value[0]).ok_or(ServiceError::INVALID_ATTRIBUTE_VALUE)?;
                let conn = if kind == ConnectionKind::Explicit { &mut self.explicit } else { &mut self.poll };
                conn.watchdog_action = action;
                Ok(())
            }
            1..=8 | 13..=17 => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    // ----- polled I/O (notes §4.2, §5.2) ---------------------------------------------------------

    fn on_poll(&mut self, data: &[u8], now: Instant) {
        // A poll command in any state other than established is ignored (JB).
        if !self.poll.is_established() {
            self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
            return;
        }
        let consumed = usize::from(self.config.consumed_size);
        let mut command = [0u8; MAX_IO_SIZE];
        let len = if consumed > 8 {
            match self.poll_rx.receive(data) {
                Ok(Some(whole)) if whole.len() <= consumed => {
                    command[..whole.len()].copy_from_slice(whole);
                    whole.len()
                }
                Ok(None) => {
                    self.poll.restart_timer(now);
                    return;
                }
                Ok(Some(_)) | Err(_) => {
                    self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
                    return;
                }
            }
        } else if data.len() <= consumed {
            command[..data.len()].copy_from_slice(data);
            data.len()
        } else {
            self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
            return;
        };
        self.poll.restart_timer(now);
        if len == 0 {
            self.io_idle = true;
            self.push_event(Event::Idle);
        } else {
            self.io_idle = false;
            self.output.clear();
            let _ = self.output.extend_from_slice(&command[..len]);
            self.push_event(Event::OutputReceived);
        }
        self.send_poll_response();
    }

    /// Answers at once from the input image, fragmented when the produced size exceeds 8.
    fn send_poll_response(&mut self) {
        let id = self.poll_response_id();
        let input = self.input.clone();
        if input.len() > 8 {
            for payload in io_fragments(&input) {
                self.queue_data(id, &payload);
            }
        } else {
            self.queue_data(id, &input);
        }
    }
}

fn invalid_choice() -> ServiceError {
    ServiceError::with_additional(GeneralStatus::InvalidAttributeValue, additional::INVALID_CHOICE)
}

/// Any service but Allocate/Release on the Group 2 Only port: 0x02 / 0x03 (JB, notes §3.4 and
/// §9.6).
fn invalid_group2_only_request() -> ServiceError {
    ServiceError::with_additional(GeneralStatus::ResourceUnavailable, additional::INVALID_GROUP2_ONLY_REQUEST)
}

/// Class attribute 1 (revision), the only class attribute served.
fn class_revision(data: &[u8], revision: u16, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
    ServiceError::expect_len(data, 1)?;
    match data[0] {
        1 => reply.u16(revision),
        _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
    }
}

#[cfg(test)]
mod tests;
