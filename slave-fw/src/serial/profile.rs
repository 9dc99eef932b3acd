//! [`Profile`]: the one concrete type the converter drives, whatever the instrument.

use super::error::ConfigError;
use super::framed_profile::{FramedProfile, FramedProfileConfig};
use super::health::{Counter, LinkStatus, Stats};
use super::line::SerialSettings;
use super::modbus::{ModbusConfig, ModbusMaster};
use devicenet::Instant;

/// The instrument description: which profile, and its settings.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
#[allow(clippy::large_enum_variant)] // Configurations are built once; no allocation by design.
pub enum ProfileConfig {
    /// A framed-serial instrument (the breaker and similar).
    Framed(FramedProfileConfig),
    /// A Modbus RTU gateway.
    Modbus(ModbusConfig),
}

impl ProfileConfig {
    /// The breaker of the source paper.
    pub fn breaker() -> Self {
        ProfileConfig::Framed(FramedProfileConfig::breaker())
    }

    /// Checks the configuration (see each profile's `validate`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        match self {
            ProfileConfig::Framed(c) => c.validate(),
            ProfileConfig::Modbus(c) => c.validate(),
        }
    }

    /// The serial line settings, for whoever opens the port.
    pub fn serial(&self) -> &SerialSettings {
        match self {
            ProfileConfig::Framed(c) => &c.serial,
            ProfileConfig::Modbus(c) => &c.serial,
        }
    }

    /// The length of the input image this configuration produces.
    pub fn input_len(&self) -> usize {
        match self {
            ProfileConfig::Framed(c) => usize::from(c.status_len),
            ProfileConfig::Modbus(c) => usize::from(c.input_len),
        }
    }
}

/// A serial instrument profile: a sans-IO state machine between the UART and the I/O images.
///
/// Contract (quinn-proto style):
///
/// * inputs — [`on_bytes`](Self::on_bytes) for every chunk read from the UART,
///   [`set_outputs`](Self::set_outputs) for every consumed poll (empty = idle),
///   [`connection_fault`](Self::connection_fault) when the poll connection times out;
/// * outputs — after any input and whenever `now >= poll_at()`, call
///   [`poll_transmit`](Self::poll_transmit) until it returns `None` and write each frame to the
///   UART in order; then sleep until [`poll_at`](Self::poll_at);
/// * state — [`input_image`](Self::input_image), [`status`](Self::status) and
///   [`stats`](Self::stats) may be read at any time and never block; a poll is answered from them
///   at once.
///
/// `now` must not go backwards between calls.
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)] // Lives in a static or a task's local resource; no allocation by design.
pub enum Profile {
    /// A framed-serial instrument.
    Framed(FramedProfile),
    /// A Modbus RTU master.
    Modbus(ModbusMaster),
}

impl Profile {
    /// The profile for `config`, started at `now`.
    pub fn new(config: ProfileConfig, now: Instant) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Profile::build(config, now))
    }

    /// The profile for `config`, which [`ProfileConfig::validate`] has accepted: the large
    /// profile is built where it stays, not passed through a `Result`.
    pub(crate) fn build(config: ProfileConfig, now: Instant) -> Self {
        match config {
            ProfileConfig::Framed(c) => Profile::Framed(FramedProfile::build(c, now)),
            ProfileConfig::Modbus(c) => Profile::Modbus(ModbusMaster::build(c, now)),
        }
    }

    /// Takes bytes read from the UART at `now`.
    pub fn on_bytes(&mut self, bytes: &[u8], now: Instant) {
        match self {
            Profile::Framed(p) => p.on_bytes(bytes, now),
            Profile::Modbus(p) => p.on_bytes(bytes, now),
        }
    }

    /// Takes the consumed poll data received at `now`; an empty slice is an idle poll. Framed:
    /// the 8 command bytes ([`Command`](super::Command)). Modbus: the output image.
    pub fn set_outputs(&mut self, outputs: &[u8], now: Instant) {
        match self {
            Profile::Framed(p) => p.set_outputs(outputs, now),
            Profile::Modbus(p) => p.set_outputs(outputs, now),
        }
    }

    /// The poll connection timed out at `now`.
    pub fn connection_fault(&mut self, now: Instant) {
        match self {
            Profile::Framed(p) => p.connection_fault(now),
            Profile::Modbus(p) => p.connection_fault(now),
        }
    }

    /// Advances timers to `now` without transmitting (also done by
    /// [`poll_transmit`](Self::poll_transmit)).
    pub fn poll(&mut self, now: Instant) {
        match self {
            Profile::Framed(p) => p.poll(now),
            Profile::Modbus(p) => p.poll(now),
        }
    }

    /// Advances to `now` and returns the next frame to write to the UART, if any.
    #[must_use = "the bytes are handed out once: dropped ones are never sent"]
    pub fn poll_transmit(&mut self, now: Instant) -> Option<&[u8]> {
        match self {
            Profile::Framed(p) => p.poll_transmit(now),
            Profile::Modbus(p) => p.poll_transmit(now),
        }
    }

    /// When to call [`poll_transmit`](Self::poll_transmit) next (`None`: only after input).
    pub fn poll_at(&self) -> Option<Instant> {
        match self {
            Profile::Framed(p) => p.poll_at(),
            Profile::Modbus(p) => p.poll_at(),
        }
    }

    /// The input image: the produced data before the optional status bytes.
    pub fn input_image(&self) -> &[u8] {
        match self {
            Profile::Framed(p) => p.input_image(),
            Profile::Modbus(p) => p.input_image(),
        }
    }

    /// The link status (status byte and freshness counter via [`LinkStatus::to_bytes`]).
    pub fn status(&self) -> LinkStatus {
        match self {
            Profile::Framed(p) => p.status(),
            Profile::Modbus(p) => p.status(),
        }
    }

    /// The statistics.
    pub fn stats(&self) -> Stats {
        Stats::from_counts(self.counts())
    }

    /// The statistics as a table indexed by [`Counter`].
    pub fn counts(&self) -> &[u32; Counter::COUNT] {
        match self {
            Profile::Framed(p) => p.counts(),
            Profile::Modbus(p) => p.counts(),
        }
    }

    /// The serial line settings.
    pub fn serial_settings(&self) -> &SerialSettings {
        match self {
            Profile::Framed(p) => &p.config().serial,
            Profile::Modbus(p) => &p.config().serial,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::breaker::{self, StatusData, SwitchState};
    use crate::serial::modbus::{Function, ScanEntry};
    use crate::serial::{CommandOutcome, LinkState};
    use heapless::Vec;

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    #[test]
    fn breaker_profile_uniformly() {
        let config = ProfileConfig::breaker();
        assert_eq!(config.input_len(), 18);
        assert_eq!(config.serial().baud, 9600);
        let mut p = Profile::new(config, ms(0)).unwrap();
        let mut wire = [0u8; 32];
        let n = breaker::FRAMING
            .encode(StatusData::new([1, 2, 3, 4], SwitchState::Open).as_bytes(), &mut wire)
            .unwrap();
        p.on_bytes(&wire[..n], ms(10));
        assert_eq!(&p.input_image()[..4], &[1, 2, 3, 4]);
        p.set_outputs(&[2, 1, 0, 0, 0, 0, 0, 0], ms(20));
        assert_eq!(p.poll_transmit(ms(20)), Some(&[0x68, 0x01, 0x02, 0x02, 0x16][..]));
        assert_eq!(p.poll_transmit(ms(20)), None);
        assert_eq!(p.status().command, CommandOutcome::Pending);
        assert_eq!(p.status().to_bytes(), [0x11, 1]);
        assert!(p.poll_at().is_some());
        p.connection_fault(ms(30));
        for t in (30..10_000).step_by(100) {
            while p.poll_transmit(ms(t)).is_some() {}
        }
        p.poll(ms(10_000));
        assert_eq!(p.status().state, LinkState::Timeout);
        assert_eq!(p.stats().commands_failed, 1);
        assert_eq!(p.serial_settings().baud, 9600);
    }

    #[test]
    fn modbus_profile_uniformly() {
        let scan = Vec::from_slice(&[ScanEntry {
            unit: 1,
            function: Function::ReadInputRegisters,
            address: 0,
            count: 1,
            offset: 0,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        }])
        .unwrap();
        let config = ProfileConfig::Modbus(crate::serial::modbus::ModbusConfig::new(scan));
        config.validate().unwrap();
        assert_eq!(config.input_len(), 2);
        let mut p = Profile::new(config, ms(0)).unwrap();
        assert_eq!(p.poll_transmit(ms(0)).map(|f| f.len()), Some(8));
        p.on_bytes(&[0x01, 0x04, 0x02, 0xFF, 0xFF, 0xB8, 0x80], ms(5));
        assert_eq!(p.input_image(), &[0xFF, 0xFF]);
        p.set_outputs(&[], ms(6));
        assert_eq!(p.status().state, LinkState::Ok);
        assert_eq!(p.stats().frames_received, 1);
        assert_eq!(p.serial_settings().baud, 19200);
    }
}
