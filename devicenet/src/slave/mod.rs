//! The group-2-only slave node (protocol §3–§8).
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
//!   bus-off interrupt setting and counter (protocol §7.1, §7.2); the Offline Connection Set (Group
//!   4) through which a tool finds a faulted node and gives it a new MAC ID (§II.6);
//! - the Predefined Master/Slave Connection Set through the Group 2 Only Unconnected Explicit
//!   Request port and through the explicit connection, with the validation of protocol §3.4; every
//!   Group 3 (UCMM) frame is ignored;
//! - Identity, Message Router, DeviceNet, Assembly and Connection objects (protocol §5, §6), with
//!   explicit fragmentation both ways (protocol §4.1); application objects through [`ObjectHandler`];
//! - the explicit (instance 1), poll (instance 2), bit-strobe (instance 3) and change-of-state or
//!   cyclic (instance 4) connections with their watchdogs (protocol §5, §II.1, §II.2); poll and strobe
//!   responses are sent at once from the input image, poll responses and COS/cyclic productions
//!   fragmented above 8 bytes (protocol §4.2); the Acknowledge Handler (class 0x2B) for
//!   acknowledged COS/cyclic productions;
//! - the device heartbeat (Identity attribute 10) and the shutdown message before an Identity
//!   Reset (§II.5).
//!
//! Multicast poll is not offered: allocating it is answered with 0x02 resource unavailable / 0x02
//! (protocol §3.4, "asks for a connection type the device lacks"; §II.3). What the node does where the
//! notes are UNCONFIRMED is recorded in `docs/src/reference/io-connections.md`.
//!
//! ## Where each part lives
//!
//! | file | what it holds |
//! |---|---|
//! | `mod.rs` | [`SlaveNode`]: its state, the `handle_*` inputs and `poll_*` outputs, [`Event`] |
//! | `network.rs` | network access: duplicate MAC ID check, Communication Faulted ([`NetworkState`], [`FaultReason`]) |
//! | `allocation.rs` | Allocate/Release of the Predefined Master/Slave Connection Set, the Group 2 Only port |
//! | `explicit_messaging.rs` | the explicit connection: ownership, fragmentation, serving a whole request |
//! | `polled_io.rs` | poll commands and poll responses |
//! | `strobe.rs` | bit-strobe commands and responses |
//! | `change_of_state.rs` | change-of-state and cyclic production, acknowledgements, the master's COS/cyclic data |
//! | `heartbeat.rs` | the device heartbeat and shutdown messages |
//! | `offline.rs` | the Offline Connection Set of a Communication Faulted node |
//! | `objects/` | Message Router, Identity, DeviceNet, Assembly and Connection objects, one file each |
//! | `indications.rs` | Module and Network Status LEDs |
//! | [`config`] | [`DeviceConfig`]: what the application tells the node about the device |
//! | [`connection`] | one Connection object instance: state, expected packet rate, watchdog |
//! | [`reply`] | [`Reply`] (response data under construction) and [`ServiceError`] |

pub mod config;
pub mod connection;
pub mod reply;

mod allocation;
mod change_of_state;
mod explicit_messaging;
mod heartbeat;
mod indications;
mod network;
mod objects;
mod offline;
mod polled_io;
mod strobe;

pub use change_of_state::AckHandler;
pub use config::{
    strobe_produced_size, BaudRate, ConfigError, DeviceConfig, Identity, Switches, MAX_EXPLICIT_SIZE,
    MAX_IO_SIZE, STROBE_MAX_SIZE,
};
pub use connection::{Connection, ConnectionKind, ConnectionState, WatchdogAction};
pub use network::{FaultReason, NetworkState, DUP_MAC_INTERVAL};
pub use objects::SettingChanged;
pub use reply::{Reply, ServiceError};

use crate::explicit::Request;
use crate::fragment::{ExplicitReassembler, ExplicitTransmitter, IoReassembler, TransmitEvent};
use crate::frame::{CanFrame, CanId};
use crate::id::{Group1MessageId, Group2Message, Identifier, MacId};
use crate::led::Indication;
use crate::messages::AllocationChoice;
use crate::time::Instant;
use heapless::Deque;

/// Frames the node can hold for transmission.
pub const TX_QUEUE_LEN: usize = 16;
/// Events the node can hold for the application.
pub const EVENT_QUEUE_LEN: usize = 16;

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
    /// A change-of-state or cyclic production went unacknowledged through the Acknowledge
    /// Handler's retry limit (protocol §II.2.4). The connection stays; production goes on at the next
    /// trigger.
    RetryLimitReached,
    /// The node took a new MAC ID through the Offline Connection Set (protocol §II.6) and restarted its
    /// duplicate MAC ID check there: store it like a network-set MAC ID, and receive for it.
    MacIdChanged(MacId),
}

/// Serves requests for object classes the core does not implement (vendor objects, the Parameter
/// object). `None` means "no such class": the node answers 0x16 object does not exist.
pub trait ObjectHandler {
    /// Serves `request`, writing response data into `reply`.
    fn handle(&mut self, request: &Request<'_>, reply: &mut Reply<'_>) -> Option<Result<(), ServiceError>>;

    /// The revision of `class` when it is one of the handler's classes whose class instance (0)
    /// serves its revision (attribute 1) and nothing else, as the core's own classes do: the node
    /// then serves that instance itself, with the core's answers, and [`handle`](Self::handle)
    /// sees only the other instances of the class. `None` (the default): every request to
    /// `class` goes to [`handle`](Self::handle).
    fn class_revision(&self, class: u16) -> Option<u16> {
        let _ = class;
        None
    }
}

/// An [`ObjectHandler`] with no objects.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoObjects;

impl ObjectHandler for NoObjects {
    fn handle(&mut self, _: &Request<'_>, _: &mut Reply<'_>) -> Option<Result<(), ServiceError>> {
        None
    }
}

/// Fault and status flags the application reports through the Identity object (protocol §6.2).
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
    strobe: Connection,
    cos: Connection,
    strobe_bit: bool,
    production: change_of_state::Production,
    ack_handler: AckHandler,
    heartbeat: heartbeat::Heartbeat,
    offline: offline::Offline,
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
    /// Identity attribute 9, the configuration consistency value; `None`: not supported.
    configuration_consistency: Option<u16>,
    network_indication: (Indication, Instant),
    module_indication: (Indication, Instant),
    stats: NodeStats,
}

impl SlaveNode {
    /// A powered-off node for `config`. The input and output images start as zeros of the
    /// produced and consumed sizes, so the Assembly data reads with its size before any output
    /// arrived (Connection 2 attribute 8 and the EDS say so).
    pub fn new(config: DeviceConfig) -> Result<SlaveNode, ConfigError> {
        config.validate()?;
        Ok(SlaveNode::build(config))
    }

    /// The node for `config`, which [`DeviceConfig::validate`] has accepted. Out of line: the
    /// large node is built in its return slot, not moved through the caller's `Result`
    /// (firmware size budget).
    #[inline(never)]
    fn build(config: DeviceConfig) -> SlaveNode {
        let mut input = heapless::Vec::new();
        // validate() bounds the produced size by MAX_IO_SIZE, so this cannot fail.
        let _ = input.resize(usize::from(config.produced_size), 0);
        let mut output = heapless::Vec::new();
        let _ = output.resize(usize::from(config.consumed_size), 0);
        SlaveNode {
            network: NetworkState::PoweredOff,
            powered_on_at: None,
            explicit: Connection::new(ConnectionKind::Explicit),
            poll: Connection::new(ConnectionKind::Poll),
            strobe: Connection::new(ConnectionKind::Strobe),
            cos: Connection::new(ConnectionKind::ChangeOfState),
            strobe_bit: false,
            production: change_of_state::Production::new(),
            ack_handler: AckHandler::DEFAULT,
            heartbeat: heartbeat::Heartbeat::new(),
            offline: offline::Offline::new(),
            allocation: AllocationChoice::empty(),
            master: None,
            input,
            output,
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
            configuration_consistency: None,
            network_indication: (Indication::Off, Instant::ZERO),
            module_indication: (Indication::Off, Instant::ZERO),
            stats: NodeStats::default(),
            config,
        }
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

    /// The bit-strobe connection (instance 3).
    pub fn strobe_connection(&self) -> &Connection {
        &self.strobe
    }

    /// The change-of-state / cyclic connection (instance 4).
    pub fn cos_connection(&self) -> &Connection {
        &self.cos
    }

    /// This node's bit of the last bit-strobe command consumed (protocol §II.1.2).
    pub fn strobe_bit(&self) -> bool {
        self.strobe_bit
    }

    /// The Acknowledge Handler's settings (class 0x2B instance 1, protocol §II.2.4).
    pub fn ack_handler(&self) -> AckHandler {
        self.ack_handler
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

    /// The input image to write in place, exactly the produced size: for an application that
    /// assembles it from parts, without a copy to hand to [`set_input`](Self::set_input).
    pub fn input_mut(&mut self) -> &mut [u8] {
        &mut self.input
    }

    /// Sets the fault and status flags reported through the Identity object and the Module LED.
    pub fn set_application_status(&mut self, status: ApplicationStatus, now: Instant) {
        self.app_status = status;
        self.update_indications(now);
    }

    /// Sets Identity attribute 9, the configuration consistency value (protocol §II.5.3): a
    /// value of the stored configuration that changes whenever it changes. Until it is set the
    /// node does not support the attribute (Get answers 0x14) and its heartbeat carries 0.
    pub fn set_configuration_consistency(&mut self, value: u16) {
        self.configuration_consistency = Some(value);
    }

    /// Identity attribute 9 as set ([`SlaveNode::set_configuration_consistency`]), `None` when
    /// the node does not support it.
    pub fn configuration_consistency(&self) -> Option<u16> {
        self.configuration_consistency
    }

    /// Power-on (or reset): starts the duplicate MAC ID check by queueing the first request
    /// (protocol §7.1). The power-up LED test runs alongside it for 1.5 s.
    pub fn power_on(&mut self, now: Instant) {
        self.reset_connections();
        self.tx.clear();
        self.powered_on_at = Some(now);
        self.start_duplicate_mac_check(now);
        self.update_indications(now);
    }

    /// Handles a received frame at `now`, with no application objects.
    pub fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.handle_frame_with(frame, now, &mut NoObjects);
    }

    /// Handles a received frame at `now`; requests for classes the core does not implement go to
    /// `objects`.
    // Out of line: inlined into the firmware's async CAN task, its state and spills cost some 260
    // bytes of flash.
    #[inline(never)]
    pub fn handle_frame_with<H: ObjectHandler>(&mut self, frame: &CanFrame, now: Instant, objects: &mut H) {
        self.handle_timeout(now);
        self.stats.frames_received = self.stats.frames_received.wrapping_add(1);
        // Group 1 is produced by slaves and Group 3 is UCMM (never answered, protocol §3.4); Group 2
        // carries the Predefined Master/Slave Connection Set, Group 4 the Offline Connection Set.
        let data = frame.data();
        match Identifier::decode(frame.id()) {
            // The strobe carries the owning master's MAC, not ours (protocol §II.1.2).
            Identifier::Group2 { mac, message: Group2Message::BitStrobeCommand }
                if matches!(self.network, NetworkState::Online) && Some(mac) == self.master =>
            {
                self.on_strobe(data, now);
            }
            Identifier::Group2 { mac, message } if mac == self.config.mac_id => match message {
                Group2Message::DuplicateMacCheck => self.on_duplicate_mac(data),
                _ if !matches!(self.network, NetworkState::Online) => {}
                Group2Message::UnconnectedExplicitRequest => self.on_group2_only::<H>(data, now),
                Group2Message::ExplicitRequest => self.on_explicit(data, now, objects),
                Group2Message::PollCommand => self.on_poll(data, now),
                Group2Message::CosCyclicAck => self.on_cos_ack(data, now),
                _ => {}
            },
            Identifier::Group4 { message } => self.on_offline(message, data, now),
            _ => {}
        }
        self.update_indications(now);
    }

    /// The CAN controller reports bus-off (protocol §7.2): the bus-off counter increments; with
    /// BOI = 0 the node enters Communication Faulted, with BOI = 1 the application resets the
    /// controller and the node restarts its duplicate MAC check (protocol §9.9: GC's behaviour).
    pub fn handle_bus_off(&mut self, now: Instant) {
        if matches!(self.network, NetworkState::PoweredOff) {
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
        self.step_duplicate_mac_check(now);
        self.run_watchdogs(now);
        self.step_production(now);
        self.step_heartbeat(now);
        self.step_offline(now);
        self.pump_explicit(now);
        // A transfer ends once: one event at most (firmware size: no loop).
        if let Some(TransmitEvent::Aborted(_)) = self.explicit_tx.poll_event(now) {
            self.push_event(Event::ExplicitTransferAborted);
        }
        self.update_indications(now);
    }

    /// The next frame to transmit, if any.
    #[must_use = "the frame is handed out once: a dropped one is never sent"]
    pub fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.tx.pop_front()
    }

    /// The next event for the application, if any.
    #[must_use = "an event is handed out once: a dropped one is lost"]
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// When [`SlaveNode::handle_timeout`] must be called next, if any timer is armed.
    // Out of line: nine deadlines inlined into the firmware's converter task cost more flash.
    #[inline(never)]
    pub fn poll_at(&self) -> Option<Instant> {
        // Chained rather than over an array: no copy of the nine to the stack (firmware size).
        let at = self
            .duplicate_mac_deadline()
            .min(self.explicit.deadline)
            .min(self.poll.deadline)
            .min(self.strobe.deadline)
            .min(self.cos.deadline)
            .min(self.production_at())
            .min(self.heartbeat.at)
            .min(self.offline.answer_at)
            .min(self.explicit_tx.poll_at().unwrap_or(Instant::MAX));
        (at != Instant::MAX).then_some(at)
    }

    // ----- outputs -------------------------------------------------------------------------

    /// Queues a frame of `data` (at most 8 bytes) on `id`.
    fn queue_data(&mut self, id: CanId, data: &[u8]) {
        queue_into(&mut self.tx, &mut self.stats, id, data);
    }

    /// Queues `ev` for the application, counting an overflow.
    fn push_event(&mut self, ev: Event) {
        if self.events.push_back(ev).is_err() {
            self.stats.event_overflows = self.stats.event_overflows.wrapping_add(1);
        }
    }

    /// Our explicit response identifier (Group 2 message 3).
    fn response_id(&self) -> CanId {
        Identifier::group2(self.config.mac_id, Group2Message::ExplicitResponse)
    }

    /// Our poll response identifier (Group 1 message 15).
    fn poll_response_id(&self) -> CanId {
        Identifier::group1(Group1MessageId::POLL_RESPONSE, self.config.mac_id)
    }

    /// Communication Faulted: silent, every connection gone, until reset (protocol §7.4). Here, not in
    /// `network.rs`, because it resets the Offline Connection Set too (`offline.rs`, which reads
    /// the network state).
    // Always inlined: the reason is a constant at each call site (some 15 bytes of flash).
    #[inline(always)]
    fn fault(&mut self, reason: FaultReason) {
        self.network = NetworkState::CommunicationFaulted(reason);
        self.reset_connections();
        self.offline = offline::Offline::new();
        self.push_event(Event::CommunicationFaulted(reason));
    }

    /// Back to no connection and no owner (power-on, bus-off, Communication Faulted).
    fn reset_connections(&mut self) {
        // Deleting every connection also ends the master's ownership (`delete_connection`).
        self.delete_connection(ConnectionKind::ChangeOfState);
        self.delete_connection(ConnectionKind::Strobe);
        self.delete_connection(ConnectionKind::Poll);
        self.delete_connection(ConnectionKind::Explicit);
    }

    /// `true` while an I/O connection (poll, strobe, COS/cyclic) is established.
    fn io_established(&self) -> bool {
        self.poll.is_established() || self.strobe.is_established() || self.cos.is_established()
    }

    /// `true` while an I/O connection is timed out.
    fn io_timed_out(&self) -> bool {
        let timed_out = |c: &Connection| matches!(c.state, ConnectionState::TimedOut);
        timed_out(&self.poll) || timed_out(&self.strobe) || timed_out(&self.cos)
    }
}

/// Queues a frame of `data` (at most 8 bytes) on `id` into `tx`, counting it or the overflow in
/// `stats`: [`SlaveNode::queue_data`] for a caller that reads the input image meanwhile.
fn queue_into(tx: &mut Deque<CanFrame, TX_QUEUE_LEN>, stats: &mut NodeStats, id: CanId, data: &[u8]) {
    let Ok(frame) = CanFrame::new(id, data) else { return };
    if tx.push_back(frame).is_err() {
        stats.tx_overflows = stats.tx_overflows.wrapping_add(1);
    } else {
        stats.frames_queued = stats.frames_queued.wrapping_add(1);
    }
}

#[cfg(test)]
mod tests;
