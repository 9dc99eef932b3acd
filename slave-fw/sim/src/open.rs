//! The one way every host program opens a bus: [`open_bus`] attaches the simulated converters to
//! a fresh simulated bus for `sim`, and opens a real bus through [`BusSpec::open`] otherwise.

use crate::device::SoftSlave;
use can_io::bus::{Bitrate, Bus, BusError, BusSpec};
use can_io::sim::{PowerOn, SimBus};
use devicenet::MacId;
use slave_fw::converter::ConverterConfig;

/// What runs on the simulated bus: one soft slave per MAC, each running `config`.
#[derive(Clone, Debug)]
pub struct SimSetup {
    /// The device configuration (from a description file, or the reference converter).
    pub config: ConverterConfig,
    /// The MAC IDs to place a device at; empty: one device at the configuration's own MAC.
    pub macs: Vec<MacId>,
    /// When the devices power on.
    pub power_on: PowerOn,
    /// Pace the simulation against the wall clock.
    pub realtime: bool,
}

impl SimSetup {
    /// One reference converter at its MAC (5), powered on when the master is on-line.
    pub fn reference() -> SimSetup {
        SimSetup {
            config: ConverterConfig::breaker_reference(),
            macs: Vec::new(),
            power_on: PowerOn::WhenMasterOnline,
            realtime: false,
        }
    }

    /// One device running `config` at its own MAC, powered on when the master is on-line.
    pub fn described(config: ConverterConfig) -> SimSetup {
        SimSetup { config, ..SimSetup::reference() }
    }

    /// The simulated devices. A single device keeps the configuration's identity (serial number
    /// included) at whatever MAC it is placed; when several share the bus, each gets the
    /// configuration's serial number + (its MAC − the configuration's MAC), so that every one has
    /// its own.
    ///
    /// # Errors
    ///
    /// A MAC given twice, or a configuration the converter refuses (the message names the key).
    pub fn devices(&self) -> Result<Vec<SoftSlave>, String> {
        let own = self.config.device.mac_id;
        let macs = if self.macs.is_empty() { vec![own] } else { self.macs.clone() };
        let mut devices = Vec::with_capacity(macs.len());
        for (i, &mac) in macs.iter().enumerate() {
            if macs[..i].contains(&mac) {
                return Err(format!("MAC {mac} is given twice for the simulated devices"));
            }
            let mut config = self.config.clone();
            config.device.mac_id = mac;
            if mac != own && macs.len() > 1 {
                config.device.identity.serial_number = config
                    .device
                    .identity
                    .serial_number
                    .wrapping_add(u32::from(mac.as_raw()))
                    .wrapping_sub(u32::from(own.as_raw()));
            }
            devices.push(
                SoftSlave::new(config).map_err(|e| format!("the simulated device's configuration: {e}"))?,
            );
        }
        Ok(devices)
    }
}

/// Why [`open_bus`] failed.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// The simulated devices cannot be set up (a usage or configuration error).
    #[error("{0}")]
    Setup(String),
    /// The real bus cannot be opened.
    #[error(transparent)]
    Bus(#[from] BusError),
}

/// Opens `spec` at `bitrate`: for `sim` a fresh simulated bus with the devices of `sim`
/// attached; otherwise the real bus ([`BusSpec::open`]; `sim` is then not used).
pub fn open_bus(spec: &BusSpec, bitrate: Bitrate, sim: &SimSetup) -> Result<Box<dyn Bus>, OpenError> {
    match spec {
        BusSpec::Sim => {
            let mut bus = SimBus::new(bitrate);
            for device in sim.devices().map_err(OpenError::Setup)? {
                bus.attach(Box::new(device), sim.power_on);
            }
            bus.set_realtime(sim.realtime);
            Ok(Box::new(bus))
        }
        real => Ok(real.open(bitrate)?),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mac(n: u8) -> MacId {
        MacId::new(n).unwrap()
    }

    #[test]
    fn one_device_keeps_the_configured_identity_at_any_mac() {
        let mut setup = SimSetup::reference();
        for at in [5, 0, 63] {
            setup.macs = vec![mac(at)];
            let devices = setup.devices().unwrap();
            assert_eq!(devices.len(), 1);
            assert_eq!(devices[0].node().config().mac_id, mac(at));
            assert_eq!(devices[0].node().config().identity.serial_number, 0x1234_5678, "at MAC {at}");
        }
    }

    #[test]
    fn several_devices_get_their_own_serial_numbers() {
        let mut setup = SimSetup::reference();
        setup.macs = vec![mac(3), mac(5), mac(12)];
        let serials: Vec<u32> =
            setup.devices().unwrap().iter().map(|d| d.node().config().identity.serial_number).collect();
        assert_eq!(serials, [0x1234_5676, 0x1234_5678, 0x1234_567F]);
    }

    #[test]
    fn a_mac_given_twice_is_refused() {
        let mut setup = SimSetup::reference();
        setup.macs = vec![mac(3), mac(3)];
        assert_eq!(setup.devices().err().unwrap(), "MAC 3 is given twice for the simulated devices");
    }

    #[test]
    fn real_buses_are_opened_by_can_io() {
        let spec = BusSpec::Slcan { path: "/nonexistent/tty".into(), baud: 115_200 };
        let err = open_bus(&spec, Bitrate::K250, &SimSetup::reference()).err().unwrap();
        assert!(err.to_string().contains("/nonexistent/tty"), "{err}");
    }
}
