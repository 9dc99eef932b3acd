//! The converter application: the DeviceNet slave node and a serial instrument profile, joined.
//!
//! [`Converter`] is sans-IO like its two halves: CAN frames, serial bytes and `now` go in; CAN
//! frames, serial bytes, events and the next deadline come out. The RTIC firmware and the soft
//! slave on Linux drive the same type.
//!
//! - Every poll is answered at once by the node from the buffered input image; the image is
//!   refreshed whenever the instrument side changes, never inside a poll.
//! - Consumed poll data goes to [`Profile::set_outputs`]: for a framed instrument (the breaker)
//!   the 8 bytes are a command (code, sequence, arguments) executed exactly once; for Modbus they
//!   are the output image. A zero-length (idle) poll never triggers a command, nor does a poll
//!   connection timeout; the profile's idle/fault actions say what the instrument is told.
//! - Input assembly 100 is the instrument's image as it is (the plain 18 bytes of the breaker);
//!   assembly 101 appends the status byte and the freshness counter
//!   ([`LinkStatus::to_bytes`](crate::serial::LinkStatus::to_bytes)). The description chooses which one the poll connection produces.
//! - While the instrument is silent the Identity status reports a minor recoverable fault and the
//!   Module Status LED flashes red (protocol §6.2, §7.3); so does a configuration fault
//!   (built [`Converter::with_origin`] [`ConfigOrigin::Fault`]: the stored image was refused, the
//!   factory default runs).
//! - Two vendor-specific objects serve the serial side over explicit messaging:
//!   [`SERIAL_LINK_CLASS`] (statistics and link status) and [`SETTINGS_CLASS`] (the
//!   configuration in force, which the EDS parameters point at). Their attributes are described
//!   once, in [`objects`], for the object handler and the EDS generator alike.
//! - The configuration object [`CONFIG_CLASS`] (0x66, [`config_object`]) serves the
//!   configuration image in force ([`crate::image`]) and takes a new one by download; an accepted
//!   image is handed to the application ([`Converter::poll_new_image`]) and applies at the next
//!   reset.
//! - The Parameter object [`PARAMETER_CLASS`] (0x0F, [`parameters`]) serves the settings a
//!   commissioning tool edits one by one; a Set changes the pending configuration and hands the
//!   new image over as a download does, so it too applies at the next reset.
//! - An Identity Reset is carried out [`RESET_DELAY`] after the request, so that the response has
//!   left; the converter keeps the deadline and says when the reset is due
//!   ([`Converter::poll_reset`]). The firmware resets the chip then, a host power-cycles its
//!   simulated device; neither keeps a delay of its own.
//!
//! ## Driving it
//!
//! Like the node's (`devicenet::slave`), the contract is: after **every** input
//! ([`Converter::handle_can_frame`], [`Converter::handle_serial`], [`Converter::handle_bus_off`],
//! [`Converter::handle_timeout`], [`Converter::power_on`]) drain, in this order,
//!
//! 1. [`Converter::poll_can_transmit`] until `None` (frames for the bus);
//! 2. [`Converter::poll_serial_transmit`] until `None` (bytes for the instrument's UART);
//! 3. [`Converter::poll_event`] until `None` (what the application acts on), and
//!    [`Converter::poll_new_image`] (a downloaded configuration image to store);
//! 4. [`Converter::poll_reset`]: when it returns a [`ResetKind`], reset now;
//!
//! and call [`Converter::handle_timeout`] at [`Converter::poll_at`] at the latest. The queues
//! behind the first and third are small (the node's 16 frames, 8 events): a caller that hands
//! several inputs over before draining loses frames and events.

use crate::serial::trace::{Trace, TraceKind};
use crate::serial::{ConfigError, Counter, LinkState, Profile, ProfileConfig};
use devicenet::led::Leds;
use devicenet::slave::{
    ApplicationStatus, BaudRate, ConfigError as NodeConfigError, ConnectionKind, ConnectionState,
    DeviceConfig, Event, Switches,
};
use devicenet::{CanFrame, Duration, Instant, MacId, SlaveNode};
use heapless::Deque;
use image::ImageError;

pub mod analyzer_object;
pub mod check;
pub mod config_object;
pub mod consistency;
pub mod image;
pub mod objects;
pub mod parameters;
pub mod units_object;
mod vendor;

pub use check::{InvalidConfig, KeyCode};
use config_object::ConfigObject;
pub use config_object::{ConfigOrigin, ConfigState, PlatformCheck, CONFIG_CLASS};

pub use objects::{SERIAL_LINK_CLASS, SETTINGS_CLASS};
pub use parameters::PARAMETER_CLASS;
pub use units_object::UNITS_CLASS;
use vendor::VendorObjects;

/// An object the application serves beside the converter's own, over the same explicit
/// connection (so only the master that owns it reaches the object): the firmware update object
/// ([`crate::update`]), which needs the board's flash. Requests to a class that neither the node
/// nor the converter serves go to it ([`Converter::handle_can_frame_with`]).
pub trait ApplicationObject {
    /// Serves `req` when its class is the object's, `None` otherwise. `io_established`: an I/O
    /// connection is established.
    fn handle(
        &mut self,
        req: &devicenet::explicit::Request<'_>,
        reply: &mut devicenet::slave::Reply<'_>,
        io_established: bool,
        now: Instant,
    ) -> Option<Result<(), devicenet::slave::ServiceError>>;

    /// As [`devicenet::slave::ObjectHandler::class_revision`].
    fn class_revision(&self, class: u16) -> Option<u16>;
}

/// Input assembly instance with the instrument's image only.
pub const PLAIN_INPUT_ASSEMBLY: u8 = 100;
/// Input assembly instance with the image, the status byte and the freshness counter.
pub const STATUS_INPUT_ASSEMBLY: u8 = 101;
/// Output assembly instance (the poll command).
pub const OUTPUT_ASSEMBLY: u8 = 150;
/// The consumed size for a framed (command) instrument: code, sequence, six argument bytes.
pub const COMMAND_SIZE: u16 = 8;
/// The time from an Identity Reset request to the reset ([`Converter::poll_reset`]).
///
/// The node queues the success response when it takes the request (protocol §3.2: respond
/// before resetting); the reset must wait until that frame has left the CAN controller, or the
/// master sees a timeout instead of a response. One frame takes under 1.1 ms at 125 kbit/s, but it
/// may wait behind queued frames, lose arbitration and be retransmitted after errors; 100 ms
/// covers that with a wide margin (the adapter board has always waited this long), and is short
/// against the master's explicit message timeout and a power cycle's own duplicate MAC ID check
/// (2 s, protocol §7.1).
pub const RESET_DELAY: Duration = Duration::from_millis(100);

/// What an Identity Reset asks for (the Reset service's type byte, protocol §3.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ResetKind {
    /// Type 0 (or no type byte): emulate a power cycle.
    PowerCycle,
    /// Type 1: return to the out-of-box configuration, then power cycle.
    OutOfBox,
    /// Another type byte (the node refuses these, so a converter never reports one).
    Unknown(u8),
}

impl ResetKind {
    /// The kind the Reset service's type byte selects.
    pub const fn from_raw(raw: u8) -> ResetKind {
        match raw {
            0 => ResetKind::PowerCycle,
            1 => ResetKind::OutOfBox,
            other => ResetKind::Unknown(other),
        }
    }

    /// The type byte.
    pub const fn as_raw(self) -> u8 {
        match self {
            ResetKind::PowerCycle => 0,
            ResetKind::OutOfBox => 1,
            ResetKind::Unknown(raw) => raw,
        }
    }
}

/// Which input assembly the poll connection produces.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum InputAssembly {
    /// Instance 100: the instrument's image (the source paper's 18 bytes for the breaker).
    #[default]
    Plain,
    /// Instance 101: the image followed by the status byte and the freshness counter.
    WithStatus,
}

impl InputAssembly {
    /// The Assembly object instance.
    pub const fn instance(self) -> u8 {
        match self {
            InputAssembly::Plain => PLAIN_INPUT_ASSEMBLY,
            InputAssembly::WithStatus => STATUS_INPUT_ASSEMBLY,
        }
    }

    /// The produced size for an instrument image of `image_len` bytes.
    pub const fn produced_size(self, image_len: usize) -> usize {
        match self {
            InputAssembly::Plain => image_len,
            InputAssembly::WithStatus => image_len + 2,
        }
    }
}

/// Everything the converter runs with. Build the node's [`DeviceConfig`] from it with
/// [`ConverterConfig::device_config`]: sizes and assembly instances follow from the profile, so
/// they cannot disagree with it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConverterConfig {
    /// Identity, MAC ID, baud rate, switches. Its I/O sizes and assembly instances are replaced
    /// by the ones the profile implies.
    pub device: DeviceConfig,
    /// The instrument.
    pub profile: ProfileConfig,
    /// The produced assembly.
    pub input: InputAssembly,
}

/// Why a converter configuration was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConverterConfigError {
    /// The DeviceNet side.
    Device(NodeConfigError),
    /// The serial side.
    Profile(ConfigError),
}

impl core::fmt::Display for ConverterConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConverterConfigError::Device(e) => write!(f, "device: {e}"),
            ConverterConfigError::Profile(e) => write!(f, "profile: {e}"),
        }
    }
}

impl core::error::Error for ConverterConfigError {}

impl ConverterConfig {
    /// The reference converter: the reference device of protocol §2 and the breaker.
    pub fn breaker_reference() -> ConverterConfig {
        ConverterConfig {
            device: DeviceConfig::reference(),
            profile: ProfileConfig::breaker(),
            input: InputAssembly::Plain,
        }
    }

    /// The poll command size the profile consumes.
    pub fn consumed_size(&self) -> u16 {
        consumed_size(&self.profile)
    }

    /// The node configuration with sizes and assembly instances derived from the profile.
    pub fn device_config(&self) -> DeviceConfig {
        let mut device = self.device.clone();
        derive_io(&mut device, &self.profile, self.input);
        device
    }

    /// Checks both halves.
    pub fn validate(&self) -> Result<(), ConverterConfigError> {
        self.profile.validate().map_err(ConverterConfigError::Profile)?;
        self.device_config().validate().map_err(ConverterConfigError::Device)
    }
}

/// The poll command size `profile` consumes ([`ConverterConfig::consumed_size`]).
fn consumed_size(profile: &ProfileConfig) -> u16 {
    match profile {
        ProfileConfig::Framed(_) => COMMAND_SIZE,
        ProfileConfig::Modbus(m) => m.output_len,
    }
}

/// Sets the I/O sizes and assembly instances of `device` that `profile` and `input` imply
/// ([`ConverterConfig::device_config`]; the image decoder sets them while it builds the
/// configuration, without a second copy of the device half).
pub(crate) fn derive_io(device: &mut DeviceConfig, profile: &ProfileConfig, input: InputAssembly) {
    let produced = input.produced_size(profile.input_len());
    device.produced_size = u16::try_from(produced).unwrap_or(u16::MAX);
    device.consumed_size = consumed_size(profile);
    device.input_assembly = input.instance();
    device.output_assembly = OUTPUT_ASSEMBLY;
}

/// What the board decides at reset over a stored configuration ([`Converter::boot`]): the MAC
/// ID and data rate its switches select, the switch attributes, the bus-off setting kept in its
/// settings, and its own serial number (the image's is a description's, shared by every device
/// configured from it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardFacts {
    /// The MAC ID in use.
    pub mac_id: MacId,
    /// The data rate in use.
    pub baud_rate: BaudRate,
    /// The DeviceNet object's switch attributes.
    pub switches: Switches,
    /// The DeviceNet object's BOI attribute, as stored.
    pub bus_off_interrupt: bool,
    /// Identity attribute 6, the board's own (derived from the MCU's unique ID).
    pub serial_number: u32,
}

impl BoardFacts {
    /// Puts the board's values into `device`.
    fn apply(&self, device: &mut DeviceConfig) {
        device.mac_id = self.mac_id;
        device.baud_rate = self.baud_rate;
        device.switches = self.switches;
        device.bus_off_interrupt = self.bus_off_interrupt;
        device.identity.serial_number = self.serial_number;
    }
}

/// A serial-to-DeviceNet converter. See the [module docs](self).
pub struct Converter {
    node: SlaveNode,
    profile: Profile,
    input: InputAssembly,
    events: Deque<Event, 8>,
    /// An accepted Identity Reset: when it is due, and its kind.
    reset: Option<(Instant, ResetKind)>,
    /// The configuration object (class 0x66): the image in force, downloads.
    config: ConfigObject,
    /// The stored image was refused ([`ConfigOrigin::Fault`]): ORed into the Identity status.
    configuration_fault: bool,
    /// The board found its hardware faulty ([`Converter::set_major_unrecoverable_fault`]).
    major_unrecoverable_fault: bool,
    /// The status byte and freshness last seen: a change is new instrument data or a new status,
    /// what a change-of-state connection produces (docs/src/reference/io-connections.md).
    last_status: [u8; 2],
    /// The serial-line analyzer's ring (class 0x68, [`analyzer_object`]).
    trace: Trace,
}

impl Converter {
    /// A powered-off converter running the factory default configuration; call
    /// [`Converter::power_on`] to start. Same as [`Converter::with_origin`] with
    /// [`ConfigOrigin::FactoryDefault`].
    pub fn new(config: ConverterConfig, now: Instant) -> Result<Converter, ConverterConfigError> {
        Converter::with_origin(config, ConfigOrigin::FactoryDefault, now)
    }

    /// A powered-off converter running `config`, which came from `origin`: the factory default,
    /// the stored image ([`image::decode`] accepted it), or the factory default because the
    /// stored image was refused ([`ConfigOrigin::Fault`], reported by the configuration object,
    /// [`CONFIG_CLASS`] attributes 3 and 5). The image in force is `image::encode(&config)`.
    pub fn with_origin(
        config: ConverterConfig,
        origin: ConfigOrigin,
        now: Instant,
    ) -> Result<Converter, ConverterConfigError> {
        let mut image = [0u8; image::MAX_IMAGE];
        let len = image::encode(&config, &mut image).unwrap_or(0);
        Converter::with_image(config, origin, image.get(..len).unwrap_or_default(), now)
    }

    /// [`Converter::with_origin`] for a configuration read from `image`, which is the image in
    /// force as a tool reads it back (Read_Chunk, attributes 2 and 4): the firmware runs its
    /// stored image, or [`image::BREAKER_REFERENCE`], with the
    /// MAC ID and data rate of its switches, and carries no encoder.
    // Out of line: the converter is built in the caller's return slot, not moved through it
    // (firmware size budget).
    #[inline(never)]
    pub fn with_image(
        config: ConverterConfig,
        origin: ConfigOrigin,
        image: &[u8],
        now: Instant,
    ) -> Result<Converter, ConverterConfigError> {
        // No `config.validate()` first: `SlaveNode::new` and `Profile::new` check their halves
        // (the node's first), and a refused configuration builds nothing.
        let config_object = ConfigObject::new(image, origin);
        // Matches rather than `?` and `map_err`: the node is not moved through the `Try` machinery
        // (firmware size: 96 bytes).
        let node = match SlaveNode::new(config.device_config()) {
            Ok(node) => node,
            Err(e) => return Err(ConverterConfigError::Device(e)),
        };
        if let Err(e) = config.profile.validate() {
            return Err(ConverterConfigError::Profile(e));
        }
        Ok(Converter::build(node, config.profile, config.input, config_object, origin, now))
    }

    /// Boots from a stored `image` (or the factory default's): decodes it ([`image::decode`]
    /// checks every value, as the description loader does), puts in the `board`'s own values,
    /// applies the platform's `check` ([`Converter::set_platform_check`], kept for downloads)
    /// and builds the converter, powered off. Every refusal is an [`ImageError`], as a download's
    /// would be.
    ///
    /// [`image::decode`]: image::decode
    // One step from image to converter, out of line: the decoded configuration is not checked a
    // second time nor moved into another builder, and no [`ConverterConfigError`] is mapped to
    // an [`ImageError`] by the caller (firmware size).
    #[inline(never)]
    pub fn boot(
        image: &[u8],
        origin: ConfigOrigin,
        board: &BoardFacts,
        check: PlatformCheck,
        now: Instant,
    ) -> Result<Converter, ImageError> {
        // `decode_with_layout`, the firmware's one decoder (`ConfigObject::check`, the Parameter
        // object), rather than `decode`. The board's values are put in and the platform's check
        // made where the configuration was decoded, and only then is it taken out of the `Result`
        // (no `Try` moves of the large value, no copy before the changes; firmware size).
        let mut decoded = image::decode_with_layout(image);
        if let Ok((config, _)) = &mut decoded {
            board.apply(&mut config.device);
            if let Err(e) = check(config) {
                return Err(ImageError::Invalid(e));
            }
        }
        #[allow(clippy::question_mark)]
        let config = match decoded {
            Ok((config, _)) => config,
            Err(e) => return Err(e),
        };
        // The decoder checked the node's half too (`ConverterConfig::check`), and the board's
        // values are typed: the node's own check passes, and its error is mapped only for
        // completeness. The device half is moved in as it is: the decoder derived its I/O values,
        // and the board's values are not among them (firmware size: no `device_config` copy).
        let node = match SlaveNode::new(config.device) {
            Ok(node) => node,
            Err(e) => return Err(ImageError::Invalid(InvalidConfig::Io(e))),
        };
        let mut config_object = ConfigObject::new(image, origin);
        config_object.set_platform_check(check);
        Ok(Converter::build(node, config.profile, config.input, config_object, origin, now))
    }

    /// The converter for a configuration whose halves were checked: the node built from its
    /// device half, the profile built from the other.
    // Out of line, the platform check set on the configuration object before: the converter is
    // built in the caller's return slot, not moved through it (firmware size).
    #[inline(never)]
    fn build(
        node: SlaveNode,
        profile: ProfileConfig,
        input: InputAssembly,
        config_object: ConfigObject,
        origin: ConfigOrigin,
        now: Instant,
    ) -> Converter {
        let mut converter = Converter {
            node,
            profile: Profile::build(profile, now),
            input,
            events: Deque::new(),
            reset: None,
            config: config_object,
            configuration_fault: matches!(origin, ConfigOrigin::Fault(_)),
            major_unrecoverable_fault: false,
            last_status: [0; 2],
            trace: Trace::new(),
        };
        converter.refresh_image(now);
        // Identity attribute 9: the CCV of the configuration in force, the stored one.
        let ccv = consistency::consistency_value(converter.config.in_force());
        converter.node.set_configuration_consistency(ccv);
        converter
    }

    /// Power-on: the node starts its duplicate MAC ID check.
    pub fn power_on(&mut self, now: Instant) {
        self.node.power_on(now);
    }

    /// The board's power-up self-test failed (e.g. its CAN controller, `board::self_test`): a
    /// major unrecoverable fault, for good. The Identity status reports it (bit 11, state 5) and
    /// Module Status shows solid red (protocol §6.2, §7.3). Keeping the node off the bus is
    /// the board's part: its CAN driver sends nothing.
    pub fn set_major_unrecoverable_fault(&mut self, now: Instant) {
        self.major_unrecoverable_fault = true;
        self.refresh_image(now);
    }

    /// Whether [`Converter::set_major_unrecoverable_fault`] was called.
    pub fn major_unrecoverable_fault(&self) -> bool {
        self.major_unrecoverable_fault
    }

    /// A CAN frame was received.
    pub fn handle_can_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.handle_can_frame_inner(frame, now, None);
    }

    /// [`Converter::handle_can_frame`] with an object the application serves beside the
    /// converter's own (the firmware update object, [`crate::update`]).
    pub fn handle_can_frame_with(
        &mut self,
        frame: &CanFrame,
        now: Instant,
        extra: &mut dyn ApplicationObject,
    ) {
        self.handle_can_frame_inner(frame, now, Some(extra));
    }

    fn handle_can_frame_inner(
        &mut self,
        frame: &CanFrame,
        now: Instant,
        extra: Option<&mut dyn ApplicationObject>,
    ) {
        let io_established = self.node.poll_connection().state == ConnectionState::Established;
        let mut objects = VendorObjects {
            profile: &self.profile,
            input: self.input,
            config: &mut self.config,
            io_established,
            trace: &mut self.trace,
            now,
            // The trait object's lifetime shortened to this call's (a reborrow).
            extra: match extra {
                Some(e) => Some(e),
                None => None,
            },
        };
        self.node.handle_frame_with(frame, now, &mut objects);
        self.sync(now);
    }

    /// Bytes were read from the instrument's UART at `now`.
    pub fn handle_serial(&mut self, bytes: &[u8], now: Instant) {
        self.trace.record_bytes(TraceKind::Receive, bytes, now);
        // The profile's checksum and framing errors, as the counters that moved (protocol-free).
        const ERRORS: [(Counter, TraceKind); 2] =
            [(Counter::ChecksumErrors, TraceKind::Checksum), (Counter::FramingErrors, TraceKind::Framing)];
        let count = |p: &Profile, c: Counter| p.counts().get(c as usize).copied();
        let before = ERRORS.map(|(c, _)| count(&self.profile, c));
        self.profile.on_bytes(bytes, now);
        for ((c, kind), before) in ERRORS.into_iter().zip(before) {
            if count(&self.profile, c) != before {
                self.trace.record_event(kind, now);
            }
        }
        self.sync(now);
    }

    /// A line event the UART's owner saw at `now` (RS-485 driver edges, UART errors), for the
    /// serial-line analyzer ([`analyzer_object`]).
    pub fn record_line_event(&mut self, kind: TraceKind, now: Instant) {
        self.trace.record_event(kind, now);
    }

    /// The serial-line analyzer's ring.
    pub fn trace(&self) -> &Trace {
        &self.trace
    }

    /// The CAN controller went bus-off.
    pub fn handle_bus_off(&mut self, now: Instant) {
        self.node.handle_bus_off(now);
        self.sync(now);
    }

    /// Runs every timer due at `now`, on both sides.
    pub fn handle_timeout(&mut self, now: Instant) {
        self.node.handle_timeout(now);
        self.sync(now);
    }

    /// The next CAN frame to transmit.
    #[must_use = "the frame is handed out once: a dropped one is never sent"]
    pub fn poll_can_transmit(&mut self) -> Option<CanFrame> {
        self.node.poll_transmit()
    }

    /// The next bytes to write to the instrument's UART.
    #[must_use = "the bytes are handed out once: dropped ones are never sent"]
    pub fn poll_serial_transmit(&mut self, now: Instant) -> Option<&[u8]> {
        let frame = self.profile.poll_transmit(now)?;
        self.trace.record_bytes(TraceKind::Transmit, frame, now);
        Some(frame)
    }

    /// Node events for the application: settings changed (store them), a CAN controller reset
    /// after bus-off, the reset request (for the log: [`Converter::poll_reset`] says when to
    /// reset), connections and faults. The converter consumes the per-poll events
    /// ([`Event::OutputReceived`], [`Event::Idle`]) and does not pass them on; connection faults
    /// it has acted on (the profile's fault action) are passed on for the application's log.
    ///
    /// At most 8 events wait; beyond that the oldest is dropped. Drained after every input, as
    /// the [module docs](self) say, the queue never fills.
    #[must_use = "an event is handed out once: a dropped one is lost"]
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// A new configuration image the configuration object accepted (a committed download,
    /// [`config_object`], or a Parameter object Set, [`parameters`]), once: the application stores it (firmware: the settings journal; soft
    /// slave: its state file) and builds the converter from it at the next reset
    /// ([`Converter::with_origin`] with [`ConfigOrigin::Stored`]). Nothing applies before then.
    /// Drain it with the events (step 3 of the [module docs](self)); a later download replaces an
    /// image not yet taken.
    #[must_use = "the new image is handed out once: a dropped one is never stored"]
    pub fn poll_new_image(&mut self) -> Option<&[u8]> {
        let image = self.config.take_new_image()?;
        // From now on the stored configuration is this one (protocol §II.5.3).
        self.node.set_configuration_consistency(consistency::consistency_value(image));
        Some(image)
    }

    /// The configuration image in force (the configuration object's Read_Chunk 0).
    pub fn image_in_force(&self) -> &[u8] {
        self.config.in_force()
    }

    /// Has Commit_Download also refuse what this platform cannot run (the firmware: a serial line
    /// its USART does not make), with the check's key and reason ([`PlatformCheck`]).
    pub fn set_platform_check(&mut self, check: PlatformCheck) {
        self.config.set_platform_check(check);
    }

    /// The configuration object's state (its attribute 3).
    pub fn config_state(&self) -> ConfigState {
        self.config.state()
    }

    /// The Identity Reset that is due at `now`, once: the caller resets at once (the firmware
    /// resets the chip; a host replaces the converter with a new one and powers it on). The
    /// converter schedules it [`RESET_DELAY`] after the request, and [`Converter::poll_at`]
    /// includes that deadline. A second request while one is pending does not postpone it.
    #[must_use = "a reset request is handed out once: a dropped one is never carried out"]
    pub fn poll_reset(&mut self, now: Instant) -> Option<ResetKind> {
        match self.reset {
            Some((at, kind)) if at <= now => {
                self.reset = None;
                Some(kind)
            }
            _ => None,
        }
    }

    /// The earliest instant [`Converter::handle_timeout`] (and [`Converter::poll_reset`]) must
    /// run: the node's and the profile's timers and a pending reset.
    pub fn poll_at(&self) -> Option<Instant> {
        earliest(earliest(self.node.poll_at(), self.profile.poll_at()), self.reset.map(|(at, _)| at))
    }

    /// The LEDs at `now`.
    pub fn leds(&self, now: Instant) -> Leds {
        self.node.leds(now)
    }

    /// The DeviceNet side.
    pub fn node(&self) -> &SlaveNode {
        &self.node
    }

    /// The serial side.
    pub fn profile(&self) -> &Profile {
        &self.profile
    }

    fn sync(&mut self, now: Instant) {
        while let Some(event) = self.node.poll_event() {
            // The per-poll events are the converter's alone; the rest go on to the application.
            match event {
                Event::OutputReceived | Event::Idle => {
                    // `matches!` rather than `==`: the derived `Event` comparison costs 20 bytes here.
                    let outputs = if matches!(event, Event::Idle) { &[] } else { self.node.output() };
                    self.profile.set_outputs(outputs, now);
                    continue;
                }
                // The connections that carry the master's outputs: poll, and change of state or
                // cyclic (whose Connection 2 consumes them when poll is not allocated).
                Event::ConnectionTimedOut(ConnectionKind::Poll | ConnectionKind::ChangeOfState)
                | Event::ConnectionDeleted(ConnectionKind::Poll | ConnectionKind::ChangeOfState)
                | Event::CommunicationFaulted(_) => self.profile.connection_fault(now),
                Event::ResetRequested(kind) if self.reset.is_none() => {
                    self.reset = Some((now + RESET_DELAY, ResetKind::from_raw(kind)));
                }
                _ => {}
            }
            if self.events.is_full() {
                self.events.pop_front();
            }
            let _ = self.events.push_back(event);
        }
        self.profile.poll(now);
        self.refresh_image(now);
    }

    /// Copies the instrument's image (and, for assembly 101, its status) into the node.
    fn refresh_image(&mut self, now: Instant) {
        let status = self.profile.status();
        let data = self.profile.input_image();
        let with_status = self.input == InputAssembly::WithStatus;
        // Written straight into the node's image, not assembled in a copy first (flash). Sizes
        // are fixed by the configuration, so this always matches the produced size. Set every
        // time: comparing with a copy of the last image first costs more flash and RAM than the
        // copy it saves.
        if let Some((head, tail)) = self.node.input_mut().split_at_mut_checked(data.len()) {
            let fits = match tail {
                [] => !with_status,
                [byte, freshness] if with_status => {
                    [*byte, *freshness] = status.to_bytes();
                    true
                }
                _ => false,
            };
            if fits {
                head.copy_from_slice(data);
            }
        }
        // Freshness counts the instrument's good frames: new data or a new status byte is a
        // change of state.
        let bytes = status.to_bytes();
        if bytes != self.last_status {
            self.last_status = bytes;
            self.node.input_changed(now);
        }
        let stale = status.state == LinkState::Timeout;
        let mut app = ApplicationStatus { configured: true, ..ApplicationStatus::default() };
        app.minor_recoverable_fault = stale || self.configuration_fault;
        app.major_unrecoverable_fault = self.major_unrecoverable_fault;
        self.node.set_application_status(app, now);
    }
}

/// The earlier of two optional deadlines.
fn earliest(a: Option<Instant>, b: Option<Instant>) -> Option<Instant> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::Conflict;
    use image::BREAKER_REFERENCE;

    fn board() -> BoardFacts {
        BoardFacts {
            mac_id: MacId::new(9).unwrap(),
            baud_rate: BaudRate::Kbps500,
            switches: Switches { mac_id: Some(9), baud_rate: Some(2), ..Switches::default() },
            bus_off_interrupt: true,
            serial_number: 0x3A5C_0F17,
        }
    }

    fn accept(_: &ConverterConfig) -> Result<(), InvalidConfig> {
        Ok(())
    }

    fn refuse(_: &ConverterConfig) -> Result<(), InvalidConfig> {
        let error = ConfigError::conflict(crate::serial::Field::SerialParity, Conflict::SevenBitsNeedParity);
        Err(InvalidConfig::Profile { modbus: false, error })
    }

    #[test]
    fn boot_puts_in_the_board_values() {
        let converter =
            Converter::boot(&BREAKER_REFERENCE, ConfigOrigin::Stored, &board(), accept, Instant::ZERO)
                .unwrap();
        let device = converter.node().config();
        assert_eq!(device.mac_id, board().mac_id);
        assert_eq!(device.baud_rate, BaudRate::Kbps500);
        assert_eq!(device.switches, board().switches);
        assert!(device.bus_off_interrupt);
        assert_eq!(device.identity.serial_number, 0x3A5C_0F17, "the board's, not the image's");
        assert_eq!(converter.config_state(), ConfigState::Stored);
    }

    #[test]
    fn a_major_unrecoverable_fault_shows_in_identity_status_and_module_status() {
        let mut converter =
            Converter::boot(&BREAKER_REFERENCE, ConfigOrigin::Stored, &board(), accept, Instant::ZERO)
                .unwrap();
        assert_eq!(converter.node().identity_status() & 1 << 11, 0);
        converter.set_major_unrecoverable_fault(Instant::ZERO);
        converter.power_on(Instant::ZERO);
        converter.handle_timeout(Instant::from_millis(10));
        assert!(converter.major_unrecoverable_fault());
        assert_ne!(converter.node().identity_status() & 1 << 11, 0, "Identity status bit 11");
        assert_eq!(converter.node().module_indication(), devicenet::led::Indication::Red);
        // Instrument traffic refreshes the status; the fault stays.
        converter.handle_serial(&[0x00], Instant::from_millis(20));
        assert_ne!(converter.node().identity_status() & 1 << 11, 0);
    }

    #[test]
    fn boot_refuses_a_damaged_image() {
        let mut image = BREAKER_REFERENCE;
        image[10] ^= 1;
        let refused = Converter::boot(&image, ConfigOrigin::Stored, &board(), accept, Instant::ZERO);
        assert!(matches!(refused, Err(ImageError::CrcMismatch { .. })));
    }

    #[test]
    fn boot_refuses_what_the_platform_cannot_run() {
        let refused =
            Converter::boot(&BREAKER_REFERENCE, ConfigOrigin::Stored, &board(), refuse, Instant::ZERO);
        assert_eq!(
            refused.err(),
            Some(ImageError::Invalid(refuse(&ConverterConfig::breaker_reference()).unwrap_err()))
        );
    }
}
