//! The one way every host program opens a bus: [`open_bus`] attaches the simulated converters to
//! a fresh simulated bus for `sim`, and opens a real bus through [`BusSpec::open`] otherwise.

use crate::device::SoftSlave;
use can_io::bus::{Bitrate, Bus, BusError, BusSpec};
use can_io::sim::{PowerOn, SimBus};
use devicenet::slave::DUP_MAC_INTERVAL;
use devicenet::{Duration, Instant, MacId};
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
    /// The devices are on-line when the bus is handed over: they power on at the start (or as
    /// `power_on` says) and [`open_bus`] runs the simulation until their duplicate MAC ID checks
    /// are over, unseen by the caller. A replayed capture of a running network has no check, so
    /// its device must be on-line before the first frame.
    pub online_before_start: bool,
    /// `--sim-replace`: the device at each MAC goes silent at the instant, and a factory-fresh
    /// replacement powers on at MAC 63 then ([`crate::replace`]).
    pub replace: Vec<(MacId, Instant)>,
    /// The replacements' configuration (`None`: the failed device's, [`crate::replace::replacement`]
    /// makes it factory-fresh at MAC 63 either way); tests give another kind, or one whose MAC is
    /// set by switches.
    pub replacement: Option<ConverterConfig>,
}

impl SimSetup {
    /// One reference converter at its MAC (5), powered on when the master is on-line.
    pub fn reference() -> SimSetup {
        SimSetup {
            config: ConverterConfig::breaker_reference(),
            macs: Vec::new(),
            power_on: PowerOn::WhenMasterOnline,
            realtime: false,
            online_before_start: false,
            replace: Vec::new(),
            replacement: None,
        }
    }

    /// One device running `config` at its own MAC, powered on when the master is on-line.
    pub fn described(config: ConverterConfig) -> SimSetup {
        SimSetup { config, ..SimSetup::reference() }
    }

    /// The simulated devices, each with its power-on policy. A single device keeps the
    /// configuration's identity (serial number included) at whatever MAC it is placed; when
    /// several share the bus, each gets the configuration's serial number + (its MAC − the
    /// configuration's MAC), so that every one has its own.
    ///
    /// A MAC given again puts another device there (`--slave-mac 5,5`): the n-th repeat gets
    /// 0x10000 × n more on its serial number and powers on [`DUPLICATE_DELAY`] × n after the
    /// first, which is on-line by then, defends its MAC and leaves the newcomer Communication
    /// Faulted (protocol §7.1): a faulted node for the Offline Connection Set (§II.6).
    ///
    /// # Errors
    ///
    /// A configuration the converter refuses (the message names the key).
    pub fn devices(&self) -> Result<Vec<(SoftSlave, PowerOn)>, String> {
        let own = self.config.device.mac_id;
        let macs = if self.macs.is_empty() { vec![own] } else { self.macs.clone() };
        let mut devices = Vec::with_capacity(macs.len());
        for (i, &mac) in macs.iter().enumerate() {
            let repeat = macs[..i].iter().filter(|&&m| m == mac).count() as u32;
            let mut config = self.config.clone();
            config.device.mac_id = mac;
            if macs.len() > 1 {
                let id = &mut config.device.identity;
                id.serial_number = id
                    .serial_number
                    .wrapping_add(u32::from(mac.as_raw()))
                    .wrapping_sub(u32::from(own.as_raw()))
                    .wrapping_add(repeat << 16);
            }
            let delay = Duration::from_millis(DUPLICATE_DELAY.total_millis() * u64::from(repeat));
            let power = match self.power_on {
                PowerOn::WhenMasterOnline if repeat > 0 => PowerOn::AfterMasterOnline(delay),
                PowerOn::AfterMasterOnline(d) => PowerOn::AfterMasterOnline(d + delay),
                PowerOn::AtStart if repeat > 0 => PowerOn::At(Instant::ZERO + delay),
                PowerOn::At(t) => PowerOn::At(t + delay),
                other => other,
            };
            let device =
                SoftSlave::new(config).map_err(|e| format!("the simulated device's configuration: {e}"))?;
            devices.push((device, power));
        }
        Ok(devices)
    }
}

/// How much later a second device at one MAC ID powers on: after the first's duplicate MAC ID
/// check (2 s, protocol §7.1) with room to spare.
pub const DUPLICATE_DELAY: Duration = Duration::from_secs(3);

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
            let mut online_at = Instant::ZERO;
            let devices = sim.devices().map_err(OpenError::Setup)?;
            if let Some((mac, _)) =
                sim.replace.iter().find(|(m, _)| !devices.iter().any(|(d, _)| d.node().mac_id() == *m))
            {
                return Err(OpenError::Setup(format!(
                    "--sim-replace {mac}: no simulated device at MAC {mac}"
                )));
            }
            for (device, power) in devices {
                let power = match power {
                    // Nothing on the bus tells a device when to power on before the caller's
                    // first frame: at the start, or at the instant given.
                    PowerOn::WhenMasterOnline if sim.online_before_start => PowerOn::AtStart,
                    PowerOn::AfterMasterOnline(d) if sim.online_before_start => {
                        PowerOn::At(Instant::ZERO + d)
                    }
                    other => other,
                };
                if let PowerOn::At(at) = power {
                    online_at = online_at.max(at);
                }
                let mac = device.node().mac_id();
                match sim.replace.iter().find(|(m, _)| *m == mac) {
                    Some(&(_, at)) => {
                        let fresh =
                            crate::replace::replacement(&sim.replacement.clone().unwrap_or_else(|| {
                                // Factory-fresh, no switches: its MAC is set over the network.
                                let mut c = device.config().clone();
                                c.device.switches.programmable = true;
                                c
                            }))
                            .map_err(OpenError::Setup)?;
                        bus.attach(Box::new(crate::replace::Failing::new(device, at)), power);
                        bus.attach(Box::new(fresh), crate::replace::power_at(at));
                    }
                    None => bus.attach(Box::new(device), power),
                }
            }

            bus.set_realtime(sim.realtime);
            if sim.online_before_start {
                // Two requests one interval apart, on-line one interval after the second (notes
                // §7.1); the frames of the checks are the past of the caller's bus.
                let deadline = online_at + DUP_MAC_INTERVAL + DUP_MAC_INTERVAL + Duration::from_millis(1);
                while bus.recv(deadline)?.is_some() {}
            }
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
            assert_eq!(devices[0].0.node().config().mac_id, mac(at));
            assert_eq!(devices[0].0.node().config().identity.serial_number, 0x1234_5678, "at MAC {at}");
        }
    }

    #[test]
    fn several_devices_get_their_own_serial_numbers() {
        let mut setup = SimSetup::reference();
        setup.macs = vec![mac(3), mac(5), mac(12)];
        let serials: Vec<u32> =
            setup.devices().unwrap().iter().map(|d| d.0.node().config().identity.serial_number).collect();
        assert_eq!(serials, [0x1234_5676, 0x1234_5678, 0x1234_567F]);
    }

    #[test]
    fn a_mac_given_again_is_a_second_device_powered_on_later() {
        let mut setup = SimSetup::reference();
        setup.macs = vec![mac(5), mac(5), mac(5)];
        let devices = setup.devices().unwrap();
        let seen: Vec<(u8, u32, PowerOn)> = devices
            .iter()
            .map(|(d, p)| (d.node().config().mac_id.as_raw(), d.node().config().identity.serial_number, *p))
            .collect();
        assert_eq!(
            seen,
            [
                (5, 0x1234_5678, PowerOn::WhenMasterOnline),
                (5, 0x1235_5678, PowerOn::AfterMasterOnline(Duration::from_secs(3))),
                (5, 0x1236_5678, PowerOn::AfterMasterOnline(Duration::from_secs(6))),
            ]
        );
    }

    /// On the bus the later device finds the MAC taken and faults; the first defends it.
    #[test]
    fn the_later_device_at_a_taken_mac_ends_communication_faulted() {
        let mut setup = SimSetup::reference();
        setup.macs = vec![mac(5), mac(5)];
        setup.power_on = PowerOn::AtStart;
        let mut bus = open_bus(&BusSpec::Sim, Bitrate::K250, &setup).unwrap();
        let mut frames = Vec::new();
        while let Some(event) = bus.recv(Instant::from_secs(10)).unwrap() {
            frames.push((event.frame.id().as_raw(), event.frame.data().to_vec()));
        }
        let first = [0x34, 0x12, 0x78, 0x56, 0x34, 0x12];
        let second = [0x34, 0x12, 0x78, 0x56, 0x35, 0x12];
        let check = |response: u8, key: &[u8]| (0x42F, [&[response][..], key].concat());
        assert_eq!(
            frames,
            [
                // The first device's two requests, then it is on-line.
                check(0x00, &first),
                check(0x00, &first),
                // The second's first request at 3 s, answered: the MAC is taken, it faults.
                check(0x00, &second),
                check(0x80, &first),
            ]
        );
    }

    /// A device brought on-line before the start answers at once and sends nothing of its own:
    /// its duplicate MAC ID check is over when the bus is handed over.
    #[test]
    fn devices_online_before_start_answer_the_first_frame() {
        let mut setup = SimSetup::reference();
        setup.online_before_start = true;
        let mut bus = open_bus(&BusSpec::Sim, Bitrate::K250, &setup).unwrap();
        let start = bus.now();
        // Allocate explicit through the Group 2 Only port (protocol §2 frame 6).
        let allocate = devicenet::CanFrame::from_raw(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]).unwrap();
        bus.send(&allocate).unwrap();
        let mut frames = Vec::new();
        while let Some(event) = bus.recv(start + Duration::from_secs(3)).unwrap() {
            frames.push((event.frame.id().as_raw(), event.frame.data().to_vec()));
        }
        assert_eq!(frames, [(0x42E, allocate.data().to_vec()), (0x42B, vec![0x00, 0xCB, 0x00])]);
    }

    #[test]
    fn real_buses_are_opened_by_can_io() {
        let spec = BusSpec::Slcan { path: "/nonexistent/tty".into(), baud: 115_200 };
        let err = open_bus(&spec, Bitrate::K250, &SimSetup::reference()).err().unwrap();
        assert!(err.to_string().contains("/nonexistent/tty"), "{err}");
    }
}
