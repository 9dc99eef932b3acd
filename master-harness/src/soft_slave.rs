//! The soft slave of the simulated bus: the core's [`SlaveNode`] plus a simple built-in instrument
//! model that writes the produced assembly directly.
//!
//! The instrument is a circuit breaker reduced to what the polled data shows (the breaker profile's
//! 18-byte status; the serial framing comes with the converter, which will replace this model
//! behind the same [`SimDevice`] trait):
//!
//! | input byte | content |
//! |---|---|
//! | 0–3 | phase A, B, C and neutral current (A) |
//! | 9 | switch state: `0x0F` open, `0xF0` closed |
//!
//! It starts open with zero currents, which is exactly the reference input image of notes §2
//! ([`devicenet::reference::INPUT_IMAGE`]). The poll command's byte 0 is a command (1 open, 2 close)
//! and byte 1 a sequence number; a command is executed when either byte changes. While closed, the
//! currents follow a fixed slow pattern, refreshed once a second like the breaker's status frame.

use crate::bus::sim::SimDevice;
use devicenet::slave::ConfigError;
use devicenet::{CanFrame, DeviceConfig, Duration, Event, Instant, MacId, SlaveNode};

/// Input byte of the switch state.
pub const SWITCH_BYTE: usize = 9;
/// Switch state: open.
pub const SWITCH_OPEN: u8 = 0x0F;
/// Switch state: closed.
pub const SWITCH_CLOSED: u8 = 0xF0;
/// Output command: open.
pub const COMMAND_OPEN: u8 = 1;
/// Output command: close.
pub const COMMAND_CLOSE: u8 = 2;
/// How often the instrument refreshes its status.
pub const STATUS_PERIOD: Duration = Duration::from_secs(1);
/// The delay between an Identity Reset response and the simulated power cycle.
pub const RESET_DELAY: Duration = Duration::from_millis(10);

/// The built-in breaker model: switch state and phase currents, written into the input image.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BreakerModel {
    closed: bool,
    /// Seconds of status refreshes since the last close (drives the current pattern).
    ticks: u32,
    /// The last (command, sequence) pair seen in the output data.
    last_command: (u8, u8),
}

impl BreakerModel {
    /// An open breaker with zero currents.
    pub fn new() -> BreakerModel {
        BreakerModel::default()
    }

    /// `true` while closed.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Takes the poll command (output data); executes its command when byte 0 or byte 1 changed.
    pub fn command(&mut self, output: &[u8]) {
        let pair = (output.first().copied().unwrap_or(0), output.get(1).copied().unwrap_or(0));
        if pair == self.last_command {
            return;
        }
        self.last_command = pair;
        match pair.0 {
            COMMAND_OPEN => self.closed = false,
            COMMAND_CLOSE if !self.closed => {
                self.closed = true;
                self.ticks = 0;
            }
            _ => {}
        }
    }

    /// One status refresh (once per [`STATUS_PERIOD`]).
    pub fn tick(&mut self) {
        self.ticks = self.ticks.wrapping_add(1);
    }

    /// Phase A, B, C and neutral currents.
    pub fn currents(&self) -> [u8; 4] {
        if !self.closed {
            return [0; 4];
        }
        // A slow triangle of ±4 A around 120 A, phases offset; a few amps on the neutral.
        let wave = |offset: u32| -> u8 {
            let t = (self.ticks + offset) % 8;
            let tri = if t < 4 { t } else { 8 - t };
            (118 + tri) as u8
        };
        [wave(0), wave(3), wave(5), 3]
    }

    /// Writes the status into `image` (as much of it as fits).
    pub fn fill(&self, image: &mut [u8]) {
        for (dst, src) in image.iter_mut().zip(self.currents()) {
            *dst = src;
        }
        if let Some(b) = image.get_mut(SWITCH_BYTE) {
            *b = if self.closed { SWITCH_CLOSED } else { SWITCH_OPEN };
        }
    }
}

/// The soft slave: a [`SlaveNode`] with the built-in [`BreakerModel`].
pub struct SoftSlave {
    node: SlaveNode,
    model: BreakerModel,
    image: Vec<u8>,
    next_tick: Option<Instant>,
    reset_at: Option<Instant>,
}

impl SoftSlave {
    /// A soft slave for `config` (its MAC, identity and sizes).
    pub fn new(config: DeviceConfig) -> Result<SoftSlave, ConfigError> {
        let image = vec![0; usize::from(config.produced_size)];
        let node = SlaveNode::new(config)?;
        let mut slave =
            SoftSlave { node, model: BreakerModel::new(), image, next_tick: None, reset_at: None };
        slave.refresh();
        Ok(slave)
    }

    /// The reference device ([`DeviceConfig::reference`]) at `mac`. MAC 5 keeps the reference
    /// serial number 0x12345678; other MACs get 0x12345678 + (MAC − 5), so that every simulated
    /// device has its own.
    pub fn reference(mac: MacId) -> SoftSlave {
        let mut config = DeviceConfig::reference();
        config.mac_id = mac;
        config.identity.serial_number =
            config.identity.serial_number.wrapping_add(u32::from(mac.as_raw())).wrapping_sub(5);
        // The reference configuration is valid whatever the MAC.
        match SoftSlave::new(config) {
            Ok(slave) => slave,
            Err(e) => unreachable!("the reference configuration is valid: {e}"),
        }
    }

    /// The node.
    pub fn node(&self) -> &SlaveNode {
        &self.node
    }

    /// The instrument model.
    pub fn model(&self) -> &BreakerModel {
        &self.model
    }

    fn refresh(&mut self) {
        self.model.fill(&mut self.image);
        // The image has the produced size by construction.
        let _ = self.node.set_input(&self.image);
    }

    fn after_input(&mut self, now: Instant) {
        while let Some(event) = self.node.poll_event() {
            match event {
                Event::OutputReceived => {
                    let output = self.node.output().to_vec();
                    self.model.command(&output);
                    self.refresh();
                }
                Event::ResetRequested(_) => self.reset_at = Some(now + RESET_DELAY),
                _ => {}
            }
        }
    }
}

impl SimDevice for SoftSlave {
    fn mac(&self) -> MacId {
        self.node.mac_id()
    }

    fn power_on(&mut self, now: Instant) {
        self.model = BreakerModel::new();
        self.refresh();
        self.node.power_on(now);
        self.next_tick = Some(now + STATUS_PERIOD);
        self.reset_at = None;
        self.after_input(now);
    }

    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.node.handle_frame(frame, now);
        self.after_input(now);
    }

    fn handle_timeout(&mut self, now: Instant) {
        if self.reset_at.is_some_and(|at| at <= now) {
            self.power_on(now);
            return;
        }
        while let Some(at) = self.next_tick.filter(|&at| at <= now) {
            self.model.tick();
            self.refresh();
            self.next_tick = Some(at + STATUS_PERIOD);
        }
        self.node.handle_timeout(now);
        self.after_input(now);
    }

    fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.node.poll_transmit()
    }

    fn poll_at(&self) -> Option<Instant> {
        [self.node.poll_at(), self.next_tick, self.reset_at].into_iter().flatten().min()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use devicenet::reference::INPUT_IMAGE;

    #[test]
    fn starts_with_the_reference_image() {
        let slave = SoftSlave::reference(MacId::new(5).unwrap());
        assert_eq!(slave.node().input(), &INPUT_IMAGE);
        assert_eq!(slave.node().config().identity.serial_number, 0x1234_5678);
        let other = SoftSlave::reference(MacId::new(9).unwrap());
        assert_eq!(other.node().config().identity.serial_number, 0x1234_567C);
    }

    #[test]
    fn commands_execute_on_change_of_command_or_sequence() {
        let mut m = BreakerModel::new();
        m.command(&[0; 8]);
        assert!(!m.is_closed());
        m.command(&[COMMAND_CLOSE, 1]);
        assert!(m.is_closed());
        let mut image = [0u8; 18];
        m.fill(&mut image);
        assert_eq!(image[SWITCH_BYTE], SWITCH_CLOSED);
        assert!(image[0] > 100);
        m.command(&[COMMAND_OPEN, 1]);
        assert!(!m.is_closed());
        // Same pair again: nothing happens even if the state was changed since.
        m.command(&[COMMAND_OPEN, 1]);
        m.fill(&mut image);
        assert_eq!(image[..4], [0; 4]);
        assert_eq!(image[SWITCH_BYTE], SWITCH_OPEN);
    }

    #[test]
    fn currents_move_while_closed() {
        let mut m = BreakerModel::new();
        m.command(&[COMMAND_CLOSE, 7]);
        let first = m.currents();
        m.tick();
        m.tick();
        assert_ne!(m.currents(), first);
        assert_eq!(m.currents()[3], 3);
    }
}
