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
//!   ([`LinkStatus::to_bytes`]). The description chooses which one the poll connection produces.
//! - While the instrument is silent the Identity status reports a minor recoverable fault and the
//!   Module Status LED flashes red (devicenet-notes §6.2, §7.3).
//! - Two vendor-specific objects serve the serial side over explicit messaging:
//!   [`SERIAL_LINK_CLASS`] (statistics and link status) and [`SETTINGS_CLASS`] (the
//!   configuration in force, which the EDS parameters point at).
//!
//! Drain order after any input: [`Converter::poll_can_transmit`], then
//! [`Converter::poll_serial_transmit`], then [`Converter::poll_event`]; call
//! [`Converter::handle_timeout`] at [`Converter::poll_at`] at the latest.

use crate::serial::{
    ConfigError, IdleAction, LinkState, Parity, Profile, ProfileConfig, StalePolicy, StopBits, IMAGE_CAPACITY,
};
use devicenet::explicit::{Request, ServiceCode};
use devicenet::led::Leds;
use devicenet::slave::{
    ApplicationStatus, ConfigError as NodeConfigError, ConnectionKind, DeviceConfig, Event, ObjectHandler,
    Reply, ServiceError,
};
use devicenet::{CanFrame, Instant, SlaveNode};
use heapless::Deque;

/// Input assembly instance with the instrument's image only.
pub const PLAIN_INPUT_ASSEMBLY: u8 = 100;
/// Input assembly instance with the image, the status byte and the freshness counter.
pub const STATUS_INPUT_ASSEMBLY: u8 = 101;
/// Output assembly instance (the poll command).
pub const OUTPUT_ASSEMBLY: u8 = 150;
/// The consumed size for a framed (command) instrument: code, sequence, six argument bytes.
pub const COMMAND_SIZE: u16 = 8;
/// Vendor-specific class of the serial link object: statistics and status, instance 1.
pub const SERIAL_LINK_CLASS: u16 = 0x64;
/// Vendor-specific class of the settings object: the configuration in force, instance 1.
pub const SETTINGS_CLASS: u16 = 0x65;

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
    /// The reference converter: the reference device of devicenet-notes §2 and the breaker.
    pub fn breaker_reference() -> ConverterConfig {
        ConverterConfig {
            device: DeviceConfig::reference(),
            profile: ProfileConfig::breaker(),
            input: InputAssembly::Plain,
        }
    }

    /// The poll command size the profile consumes.
    pub fn consumed_size(&self) -> u16 {
        match &self.profile {
            ProfileConfig::Framed(_) => COMMAND_SIZE,
            ProfileConfig::Modbus(m) => m.output_len,
        }
    }

    /// The node configuration with sizes and assembly instances derived from the profile.
    pub fn device_config(&self) -> DeviceConfig {
        let mut device = self.device.clone();
        let produced = self.input.produced_size(self.profile.input_len());
        device.produced_size = u16::try_from(produced).unwrap_or(u16::MAX);
        device.consumed_size = self.consumed_size();
        device.input_assembly = self.input.instance();
        device.output_assembly = OUTPUT_ASSEMBLY;
        device
    }

    /// Checks both halves.
    pub fn validate(&self) -> Result<(), ConverterConfigError> {
        self.profile.validate().map_err(ConverterConfigError::Profile)?;
        self.device_config().validate().map_err(ConverterConfigError::Device)
    }
}

/// A serial-to-DeviceNet converter. See the [module docs](self).
pub struct Converter {
    node: SlaveNode,
    profile: Profile,
    input: InputAssembly,
    events: Deque<Event, 8>,
    last_image: heapless::Vec<u8, { IMAGE_CAPACITY + 2 }>,
}

impl Converter {
    /// A powered-off converter; call [`Converter::power_on`] to start.
    pub fn new(config: ConverterConfig, now: Instant) -> Result<Converter, ConverterConfigError> {
        config.validate()?;
        let node = SlaveNode::new(config.device_config()).map_err(ConverterConfigError::Device)?;
        let profile = Profile::new(config.profile, now).map_err(ConverterConfigError::Profile)?;
        let mut converter = Converter {
            node,
            profile,
            input: config.input,
            events: Deque::new(),
            last_image: heapless::Vec::new(),
        };
        converter.refresh_image(now);
        Ok(converter)
    }

    /// Power-on: the node starts its duplicate MAC ID check.
    pub fn power_on(&mut self, now: Instant) {
        self.node.power_on(now);
    }

    /// A CAN frame was received.
    pub fn handle_can_frame(&mut self, frame: &CanFrame, now: Instant) {
        let mut objects = VendorObjects { profile: &self.profile, input: self.input };
        self.node.handle_frame_with(frame, now, &mut objects);
        self.sync(now);
    }

    /// Bytes were read from the instrument's UART at `now`.
    pub fn handle_serial(&mut self, bytes: &[u8], now: Instant) {
        self.profile.on_bytes(bytes, now);
        self.sync(now);
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
    pub fn poll_can_transmit(&mut self) -> Option<CanFrame> {
        self.node.poll_transmit()
    }

    /// The next bytes to write to the instrument's UART.
    pub fn poll_serial_transmit(&mut self, now: Instant) -> Option<&[u8]> {
        self.profile.poll_transmit(now)
    }

    /// Node events the application acts on (reset requested, settings changed, …). Poll data,
    /// idle and connection faults are already handled by the converter and are passed on too.
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// The earliest instant [`Converter::handle_timeout`] must run.
    pub fn poll_at(&self) -> Option<Instant> {
        match (self.node.poll_at(), self.profile.poll_at()) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
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
            match event {
                Event::OutputReceived => self.profile.set_outputs(self.node.output(), now),
                Event::Idle => self.profile.set_outputs(&[], now),
                Event::ConnectionTimedOut(ConnectionKind::Poll)
                | Event::ConnectionDeleted(ConnectionKind::Poll)
                | Event::CommunicationFaulted(_) => self.profile.connection_fault(now),
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
        let mut image: heapless::Vec<u8, { IMAGE_CAPACITY + 2 }> = heapless::Vec::new();
        let _ = image.extend_from_slice(self.profile.input_image());
        let status = self.profile.status();
        if self.input == InputAssembly::WithStatus {
            let _ = image.extend_from_slice(&status.to_bytes());
        }
        if image != self.last_image {
            // Sizes are fixed by the configuration, so this always matches the produced size.
            let _ = self.node.set_input(&image);
            self.last_image = image;
        }
        let stale = status.state == LinkState::Timeout;
        let mut app = ApplicationStatus { configured: true, ..ApplicationStatus::default() };
        app.minor_recoverable_fault = stale;
        self.node.set_application_status(app, now);
    }
}

/// The vendor-specific objects, borrowing the serial side while the node serves a request.
struct VendorObjects<'a> {
    profile: &'a Profile,
    input: InputAssembly,
}

impl ObjectHandler for VendorObjects<'_> {
    fn handle(&mut self, req: &Request<'_>, reply: &mut Reply<'_>) -> Option<Result<(), ServiceError>> {
        let serve: fn(&Self, u8, &mut Reply<'_>) -> Result<(), ServiceError> = match req.class {
            SERIAL_LINK_CLASS => Self::link_attribute,
            SETTINGS_CLASS => Self::settings_attribute,
            _ => return None,
        };
        Some(match (req.instance, req.service, req.data) {
            (0, ServiceCode::GetAttributeSingle, [1]) => reply.u16(1),
            (0, ServiceCode::GetAttributeSingle, [_]) => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
            (0 | 1, ServiceCode::GetAttributeSingle, []) => Err(ServiceError::NOT_ENOUGH_DATA),
            (0 | 1, ServiceCode::GetAttributeSingle, [_, _, ..]) => Err(ServiceError::TOO_MUCH_DATA),
            (1, ServiceCode::GetAttributeSingle, [attr]) => serve(self, *attr, reply),
            (1, ServiceCode::SetAttributeSingle, [attr, ..]) => {
                // Probe the attribute: known ones are read-only (configuration comes from the
                // description and the non-volatile settings), unknown ones are not supported.
                let mut scratch = [0u8; 8];
                match serve(self, *attr, &mut Reply::new(&mut scratch)) {
                    Ok(()) => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
                    Err(e) => Err(e),
                }
            }
            (1, ServiceCode::SetAttributeSingle, []) => Err(ServiceError::NOT_ENOUGH_DATA),
            (0 | 1, _, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        })
    }
}

impl VendorObjects<'_> {
    /// Serial link object (class 0x64) instance 1 attributes.
    fn link_attribute(&self, attr: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let s = self.profile.stats();
        let status = self.profile.status();
        match attr {
            1 => reply.u32(s.frames_received),
            2 => reply.u32(s.checksum_errors),
            3 => reply.u32(s.framing_errors),
            4 => reply.u32(s.timeouts),
            5 => reply.u32(s.commands_sent),
            6 => reply.u32(s.commands_retried),
            7 => reply.u32(s.commands_failed),
            8 => reply.u32(s.commands_rejected),
            9 => reply.u32(s.modbus_exceptions),
            10 => reply.u32(s.frames_sent),
            11 => reply.u32(s.discarded_bytes),
            12 => reply.u32(s.link_timeouts),
            13 => reply.u8(status.to_bytes()[0]),
            14 => reply.u8(status.freshness),
            15 => reply.u8(match status.state {
                LinkState::Starting => 0,
                LinkState::Ok => 1,
                LinkState::Timeout => 2,
            }),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }

    /// Settings object (class 0x65) instance 1 attributes: the configuration in force.
    fn settings_attribute(&self, attr: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        let (health, response_timeout_ms, retries, on_idle, on_fault) = match self.profile {
            Profile::Framed(p) => {
                let c = p.config();
                (
                    c.health,
                    c.sequencer.response_timeout_ms,
                    c.sequencer.retries,
                    &c.sequencer.on_idle,
                    &c.sequencer.on_fault,
                )
            }
            Profile::Modbus(p) => {
                let c = p.config();
                (c.health, c.response_timeout_ms, c.retries, &c.on_idle, &c.on_fault)
            }
        };
        let serial = self.profile.serial_settings();
        let action = |a: &IdleAction| u8::from(matches!(a, IdleAction::Send(_)));
        match attr {
            1 => reply.u32(serial.baud),
            2 => reply.u8(match serial.parity {
                Parity::None => 0,
                Parity::Odd => 1,
                Parity::Even => 2,
            }),
            3 => reply.u8(match serial.stop_bits {
                StopBits::One => 1,
                StopBits::Two => 2,
            }),
            4 => reply.u32(health.stale_timeout_ms),
            5 => reply.u8(match health.stale_policy {
                StalePolicy::HoldLastValue => 0,
                StalePolicy::Clear => 1,
            }),
            6 => reply.u8(self.input.instance()),
            7 => reply.u32(response_timeout_ms),
            8 => reply.u8(retries),
            9 => reply.u8(action(on_idle)),
            10 => reply.u8(action(on_fault)),
            11 => reply.u8(match self.profile {
                Profile::Framed(_) => 0,
                Profile::Modbus(_) => 1,
            }),
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }
}
