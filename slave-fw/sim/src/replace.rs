//! `--sim-replace MAC@MS`: a failed device and its replacement on the simulated bus. The device
//! at MAC goes silent at MS ms of simulated time (it neither receives nor transmits again, as a
//! dead adapter), and a factory-fresh device of the same kind powers on then at MAC 63 (no stored
//! MAC, protocol §ADR), its MAC settable over the network, with a serial number of its own.

use crate::device::SoftSlave;
use can_io::sim::{PowerOn, SimDevice};
use devicenet::{CanFrame, Instant, MacId};
use slave_fw::converter::ConverterConfig;

/// The MAC a factory-fresh device comes up at.
pub const FRESH_MAC: u8 = 63;

/// What the replacement's serial number adds to the failed device's.
pub const SERIAL_OFFSET: u32 = 0x0100_0000;

/// A device that goes silent at an instant. See the [module docs](self).
pub struct Failing {
    inner: SoftSlave,
    silent_from: Instant,
    now: Instant,
}

impl Failing {
    /// `inner`, silent from `at`.
    pub fn new(inner: SoftSlave, at: Instant) -> Failing {
        Failing { inner, silent_from: at, now: Instant::ZERO }
    }

    fn alive(&self) -> bool {
        self.now < self.silent_from
    }
}

impl SimDevice for Failing {
    fn mac(&self) -> MacId {
        self.inner.node().mac_id()
    }

    fn power_on(&mut self, now: Instant) {
        self.now = now;
        if self.alive() {
            self.inner.power_on(now);
        }
    }

    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.now = now;
        if self.alive() {
            self.inner.handle_frame(frame, now);
        }
    }

    fn handle_timeout(&mut self, now: Instant) {
        self.now = now;
        if self.alive() {
            self.inner.handle_timeout(now);
        }
    }

    fn poll_transmit(&mut self) -> Option<CanFrame> {
        if self.alive() {
            self.inner.poll_transmit()
        } else {
            None
        }
    }

    fn poll_at(&self) -> Option<Instant> {
        // The instant it dies, so that nothing it queued goes out after.
        let next = self.inner.poll_at().filter(|_| self.alive())?;
        Some(next.min(self.silent_from).max(self.now))
    }

    fn handle_bus_off(&mut self, now: Instant) {
        self.now = now;
        if self.alive() {
            self.inner.handle_bus_off(now);
        }
    }
}

/// The factory-fresh replacement of a device running `config`: the same kind of device at MAC
/// 63, its serial number `config`'s + [`SERIAL_OFFSET`]; its MAC settable over the network as
/// `config.device.switches.programmable` says.
///
/// # Errors
///
/// A configuration the converter refuses.
pub fn replacement(config: &ConverterConfig) -> Result<SoftSlave, String> {
    let mut fresh = config.clone();
    fresh.device.mac_id = MacId::from_low_bits(FRESH_MAC);
    fresh.device.identity.serial_number = fresh.device.identity.serial_number.wrapping_add(SERIAL_OFFSET);
    SoftSlave::new(fresh).map_err(|e| format!("the replacement device's configuration: {e}"))
}

/// The power-on of a replacement at `at`.
#[must_use]
pub fn power_at(at: Instant) -> PowerOn {
    PowerOn::At(at)
}
