//! The soft slave of the simulated bus: the real converter ([`slave_fw::converter::Converter`]:
//! the core's slave node plus the breaker's serial profile) wired to a simulated breaker over a
//! simulated serial line ([`slave_fw::soft::SoftSlave`]), on the bus's virtual clock.
//!
//! The breaker sends its 18-byte status frame every second (notes: the source paper) and obeys the
//! open/close/set-parameter/refresh commands the converter derives from the poll command:
//!
//! | input byte | content |
//! |---|---|
//! | 0–3 | phase A, B, C and neutral current (A) |
//! | 9 | switch state: `0x0F` open, `0xF0` closed |
//!
//! It starts open with zero currents, which is exactly the reference input image of notes §2
//! ([`devicenet::reference::INPUT_IMAGE`]). Poll command byte 0 is the command (1 open, 2 close,
//! 3 set parameter, 4 refresh), byte 1 a sequence number; a command is executed exactly once when
//! either changes. A device description file (`--slave-config`) replaces the reference device.

use crate::bus::sim::SimDevice;
use devicenet::{CanFrame, Instant, MacId, SlaveNode};
use slave_fw::converter::{ConverterConfig, ConverterConfigError};
use slave_fw::sim::SimulatedBreaker;

pub use slave_fw::serial::breaker::{SWITCH_CLOSED, SWITCH_OPEN};

/// Input byte of the switch state.
pub const SWITCH_BYTE: usize = 9;
/// Output command: open.
pub const COMMAND_OPEN: u8 = 1;
/// Output command: close.
pub const COMMAND_CLOSE: u8 = 2;
/// The currents the simulated breaker reports while closed (A, B, C, N).
pub const LOAD: [u8; 4] = [120, 118, 121, 3];

/// The soft slave: converter + simulated breaker.
pub struct SoftSlave {
    inner: slave_fw::soft::SoftSlave,
}

impl SoftSlave {
    /// A soft slave running `config`.
    pub fn new(config: ConverterConfig) -> Result<SoftSlave, ConverterConfigError> {
        let mut inner = slave_fw::soft::SoftSlave::new(config, Instant::ZERO)?;
        inner.breaker_mut().set_load(LOAD);
        Ok(SoftSlave { inner })
    }

    /// The reference converter ([`ConverterConfig::breaker_reference`]) at `mac`. MAC 5 keeps the
    /// reference serial number 0x12345678; other MACs get 0x12345678 + (MAC − 5), so that every
    /// simulated device has its own.
    pub fn reference(mac: MacId) -> SoftSlave {
        let mut config = ConverterConfig::breaker_reference();
        config.device.mac_id = mac;
        config.device.identity.serial_number =
            config.device.identity.serial_number.wrapping_add(u32::from(mac.as_raw())).wrapping_sub(5);
        // The reference configuration is valid whatever the MAC.
        match SoftSlave::new(config) {
            Ok(slave) => slave,
            Err(e) => unreachable!("the reference configuration is valid: {e}"),
        }
    }

    /// The slave node.
    pub fn node(&self) -> &SlaveNode {
        self.inner.converter().node()
    }

    /// The simulated breaker.
    pub fn breaker(&self) -> &SimulatedBreaker {
        self.inner.breaker()
    }

    /// The simulated breaker, to inject faults.
    pub fn breaker_mut(&mut self) -> &mut SimulatedBreaker {
        self.inner.breaker_mut()
    }

    /// The converter and its serial side.
    pub fn converter(&self) -> &slave_fw::converter::Converter {
        self.inner.converter()
    }
}

impl SimDevice for SoftSlave {
    fn mac(&self) -> MacId {
        self.node().mac_id()
    }

    fn power_on(&mut self, now: Instant) {
        self.inner.power_on(now);
    }

    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.inner.handle_frame(frame, now);
        while self.inner.poll_event().is_some() {}
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.inner.handle_timeout(now);
        while self.inner.poll_event().is_some() {}
    }

    fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.inner.poll_transmit()
    }

    fn poll_at(&self) -> Option<Instant> {
        self.inner.poll_at()
    }

    fn handle_bus_off(&mut self, now: Instant) {
        self.inner.handle_bus_off(now);
        while self.inner.poll_event().is_some() {}
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
