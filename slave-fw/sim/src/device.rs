//! The converter as a simulated device: the real [`Converter`] (the core's slave node plus the
//! instrument profile) wired to a [`SimulatedBreaker`] over a simulated serial line, on one virtual
//! clock, with serial bytes crossing the "wire" in their transmission time at the configured baud
//! rate. The simulated CAN bus drives it through [`SimDevice`]; tests may drive it directly.
//!
//! The breaker sends its 18-byte status frame every second (the source paper) and obeys the
//! open/close/set-parameter/refresh commands the converter derives from the poll command:
//!
//! | input byte | content |
//! |---|---|
//! | 0–3 | phase A, B, C and neutral current (A) |
//! | 9 | switch state: `0x0F` open, `0xF0` closed |
//!
//! It starts open with zero currents, which is exactly the reference input image of protocol §2
//! ([`devicenet::reference::INPUT_IMAGE`]). Poll command byte 0 is the command (1 open, 2 close,
//! 3 set parameter, 4 refresh), byte 1 a sequence number; a command is executed exactly once when
//! either changes. A device description (`--slave-config`) replaces the reference device; whatever
//! the profile, the simulated instrument on the line is the breaker.

use crate::breaker::SimulatedBreaker;
use can_io::sim::SimDevice;
use devicenet::slave::SettingChanged;
use devicenet::{CanFrame, Duration, Event, Instant, MacId, SlaveNode};
use slave_fw::converter::{ConfigOrigin, Converter, ConverterConfig, ConverterConfigError};
use std::collections::VecDeque;

pub use slave_fw::serial::breaker::{SWITCH_CLOSED, SWITCH_OPEN};

/// Input byte of the switch state.
pub const SWITCH_BYTE: usize = 9;
/// Output command: open.
pub const COMMAND_OPEN: u8 = 1;
/// Output command: close.
pub const COMMAND_CLOSE: u8 = 2;
/// The currents the simulated breaker reports while closed (A, B, C, N).
pub const LOAD: [u8; 4] = [120, 118, 121, 3];

/// The delay between an Identity Reset response and the simulated power cycle: the converter's
/// own ([`Converter::poll_reset`] says when), the same as the board's.
pub use slave_fw::converter::RESET_DELAY;

/// The converter as a simulated device: a [`Converter`] and its [`SimulatedBreaker`] on one
/// virtual clock. See the [module docs](self).
pub struct SoftSlave {
    /// The factory configuration; what runs after a reset is the stored image when there is one.
    config: ConverterConfig,
    /// The configuration image stored over the network (the board's settings journal).
    stored: Option<Vec<u8>>,
    converter: Converter,
    events: VecDeque<Event>,
    breaker: SimulatedBreaker,
    /// Bytes on the serial wire towards the breaker / the converter, with arrival times.
    to_breaker: VecDeque<(Instant, Vec<u8>)>,
    to_converter: VecDeque<(Instant, Vec<u8>)>,
    char_time: Duration,
    powered: bool,
    /// The MAC ID set over the network (DeviceNet object attribute 1), kept across resets as the
    /// board's settings journal and the soft slave's state file keep it.
    set_mac: Option<MacId>,
}

impl SoftSlave {
    /// A powered-off soft slave for `config`, its breaker reporting [`LOAD`] while closed and
    /// sending its first status frame at time zero.
    pub fn new(config: ConverterConfig) -> Result<SoftSlave, ConverterConfigError> {
        let now = Instant::ZERO;
        let char_time = config.profile.serial().char_time();
        let mut breaker = SimulatedBreaker::new(now);
        breaker.set_load(LOAD);
        Ok(SoftSlave {
            converter: Converter::new(config.clone(), now)?,
            config,
            stored: None,
            events: VecDeque::new(),
            breaker,
            to_breaker: VecDeque::new(),
            to_converter: VecDeque::new(),
            char_time,
            powered: false,
            set_mac: None,
        })
    }

    /// The reference converter ([`ConverterConfig::breaker_reference`]: the protocol §2
    /// device, breaker profile) at `mac`. MAC 5 keeps the reference serial number 0x12345678; other
    /// MACs get 0x12345678 + (MAC − 5), so that every simulated device has its own.
    pub fn reference(mac: MacId) -> SoftSlave {
        let mut config = ConverterConfig::breaker_reference();
        config.device.mac_id = mac;
        config.device.identity.serial_number =
            config.device.identity.serial_number.wrapping_add(u32::from(mac.as_raw())).wrapping_sub(5);
        // The reference configuration is valid whatever the MAC (tested).
        match SoftSlave::new(config) {
            Ok(slave) => slave,
            Err(e) => unreachable!("the reference configuration is valid: {e}"),
        }
    }

    /// The converter a reset starts: the stored configuration image, else the factory
    /// configuration ([`ConfigOrigin::resolve`], as the board does: the device keeps its own
    /// serial number). A stored image in force is the bytes downloaded, as on the board.
    fn fresh(&self, now: Instant) -> Result<Converter, ConverterConfigError> {
        let (mut config, origin) = ConfigOrigin::resolve(&self.config, self.stored.as_deref());
        if let Some(mac) = self.set_mac {
            config.device.mac_id = mac;
        }
        match (origin, self.stored.as_deref()) {
            (ConfigOrigin::Stored, Some(image)) => Converter::with_image(config, origin, image, now),
            _ => Converter::with_origin(config, origin, now),
        }
    }

    /// The configuration image stored over the network, if one was.
    pub fn stored_image(&self) -> Option<&[u8]> {
        self.stored.as_deref()
    }

    /// The slave node.
    pub fn node(&self) -> &SlaveNode {
        self.converter.node()
    }

    /// Power-on: the node starts its duplicate MAC ID check.
    pub fn power_on(&mut self, now: Instant) {
        if self.powered {
            // A second power-on is a power cycle: the converter starts afresh.
            if let Ok(fresh) = self.fresh(now) {
                self.converter = fresh;
            }
        }
        self.powered = true;
        self.converter.power_on(now);
    }

    /// `true` after [`SoftSlave::power_on`].
    pub fn is_powered(&self) -> bool {
        self.powered
    }

    /// A CAN frame reached the node.
    pub fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.run_serial(now);
        if self.powered {
            self.converter.handle_can_frame(frame, now);
        }
        self.run_serial(now);
    }

    /// The CAN controller went bus-off at `now` (protocol §7.2): the node applies its bus-off
    /// interrupt setting (BOI 0: Communication Faulted; 1: restart the duplicate MAC ID check).
    pub fn handle_bus_off(&mut self, now: Instant) {
        self.run_serial(now);
        if self.powered {
            self.converter.handle_bus_off(now);
        }
        self.run_serial(now);
    }

    /// Runs both sides' timers and the serial wire up to `now`. An Identity Reset power-cycles
    /// the converter when it says the reset is due ([`RESET_DELAY`] after its response; the
    /// breaker keeps running).
    pub fn handle_timeout(&mut self, now: Instant) {
        self.run_serial(now);
    }

    /// The configuration the converter runs with.
    pub fn config(&self) -> &ConverterConfig {
        &self.config
    }

    /// The converter's events (settings changed, reset requested, connection faults), oldest
    /// first; at most the last 64 are kept.
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// The next CAN frame the node transmits.
    pub fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.converter.poll_can_transmit()
    }

    /// The earliest instant anything happens: node, profile, breaker or a byte arriving.
    pub fn poll_at(&self) -> Option<Instant> {
        let node = if self.powered { self.converter.poll_at() } else { None };
        [
            node,
            self.breaker.poll_at(),
            self.to_breaker.front().map(|(at, _)| *at),
            self.to_converter.front().map(|(at, _)| *at),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// The converter.
    pub fn converter(&self) -> &Converter {
        &self.converter
    }

    /// The breaker.
    pub fn breaker(&self) -> &SimulatedBreaker {
        &self.breaker
    }

    /// The breaker, to inject faults (silence, garbage, rejections).
    pub fn breaker_mut(&mut self) -> &mut SimulatedBreaker {
        &mut self.breaker
    }

    fn wire_time(&self, len: usize) -> Duration {
        Duration::from_micros(self.char_time.total_micros().saturating_mul(len as u64))
    }

    /// Moves everything due by `now`, in time order, until both sides are quiet.
    fn run_serial(&mut self, now: Instant) {
        for _ in 0..10_000 {
            let mut moved = false;
            if self.powered {
                if self.converter.poll_at().is_some_and(|at| at <= now) {
                    self.converter.handle_timeout(now);
                }
                while let Some(bytes) = self.converter.poll_serial_transmit(now) {
                    let bytes = bytes.to_vec();
                    let at = now + self.wire_time(bytes.len());
                    self.to_breaker.push_back((at, bytes));
                    moved = true;
                }
            }
            while let Some(bytes) = self.breaker.poll_transmit(now) {
                let at = now + self.wire_time(bytes.len());
                self.to_converter.push_back((at, bytes));
                moved = true;
            }
            while self.to_breaker.front().is_some_and(|(at, _)| *at <= now) {
                if let Some((at, bytes)) = self.to_breaker.pop_front() {
                    self.breaker.on_bytes(&bytes, at);
                    moved = true;
                }
            }
            while self.to_converter.front().is_some_and(|(at, _)| *at <= now) {
                if let Some((at, bytes)) = self.to_converter.pop_front() {
                    if self.powered {
                        self.converter.handle_serial(&bytes, at);
                    }
                    moved = true;
                }
            }
            while let Some(event) = self.converter.poll_event() {
                if let Event::SettingChanged(SettingChanged::MacId(mac)) = event {
                    self.set_mac = Some(mac);
                }
                if self.events.len() == 64 {
                    self.events.pop_front();
                }
                self.events.push_back(event);
            }
            if let Some(image) = self.converter.poll_new_image() {
                self.stored = Some(image.to_vec());
            }
            if self.powered && self.converter.poll_reset(now).is_some() {
                if let Ok(fresh) = self.fresh(now) {
                    self.converter = fresh;
                    self.converter.power_on(now);
                    moved = true;
                }
            }
            if !moved {
                return;
            }
        }
    }
}

/// On the simulated bus the device is driven through [`SimDevice`]; the events it keeps stay
/// readable with [`SoftSlave::poll_event`] (the last 64).
impl SimDevice for SoftSlave {
    fn mac(&self) -> MacId {
        self.node().mac_id()
    }

    fn power_on(&mut self, now: Instant) {
        SoftSlave::power_on(self, now);
    }

    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        SoftSlave::handle_frame(self, frame, now);
    }

    fn handle_timeout(&mut self, now: Instant) {
        SoftSlave::handle_timeout(self, now);
    }

    fn poll_transmit(&mut self) -> Option<CanFrame> {
        SoftSlave::poll_transmit(self)
    }

    fn poll_at(&self) -> Option<Instant> {
        SoftSlave::poll_at(self)
    }

    fn handle_bus_off(&mut self, now: Instant) {
        SoftSlave::handle_bus_off(self, now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use devicenet::reference::INPUT_IMAGE;
    use devicenet::Duration;

    fn run(slave: &mut SoftSlave, until: Instant) {
        while let Some(at) = slave.poll_at().filter(|&at| at <= until) {
            slave.handle_timeout(at);
            while slave.poll_transmit().is_some() {}
        }
    }

    #[test]
    fn serial_numbers_follow_the_mac() {
        let slave = SoftSlave::reference(MacId::new(5).unwrap());
        assert_eq!(slave.node().config().identity.serial_number, 0x1234_5678);
        let other = SoftSlave::reference(MacId::new(9).unwrap());
        assert_eq!(other.node().config().identity.serial_number, 0x1234_567C);
    }

    #[test]
    fn the_breakers_first_status_frame_gives_the_reference_image() {
        let mut slave = SoftSlave::reference(MacId::new(5).unwrap());
        slave.power_on(Instant::ZERO);
        run(&mut slave, Instant::ZERO + Duration::from_millis(100));
        assert_eq!(slave.node().input(), &INPUT_IMAGE);
        assert!(slave.converter().profile().stats().frames_received >= 1);
    }

    #[test]
    fn bus_off_applies_the_bus_off_interrupt_setting() {
        use devicenet::slave::{FaultReason, NetworkState};
        let mut slave = SoftSlave::reference(MacId::new(5).unwrap());
        slave.power_on(Instant::ZERO);
        run(&mut slave, Instant::from_secs(3));
        assert_eq!(slave.node().network_state(), NetworkState::Online);
        slave.handle_bus_off(Instant::from_secs(3));
        let expected = if slave.node().config().bus_off_interrupt {
            matches!(slave.node().network_state(), NetworkState::DuplicateMacCheck { .. })
        } else {
            slave.node().network_state() == NetworkState::CommunicationFaulted(FaultReason::BusOff)
        };
        assert!(expected, "{:?}", slave.node().network_state());
        assert_eq!(slave.node().bus_off_counter(), 1);
    }

    #[test]
    fn closed_breaker_reports_its_load() {
        let mut slave = SoftSlave::reference(MacId::new(5).unwrap());
        slave.breaker_mut().set_switch(slave_fw::serial::breaker::SwitchState::Closed);
        slave.power_on(Instant::ZERO);
        run(&mut slave, Instant::ZERO + Duration::from_millis(100));
        assert_eq!(&slave.node().input()[..4], &LOAD);
        assert_eq!(slave.node().input()[SWITCH_BYTE], SWITCH_CLOSED);
    }
}
