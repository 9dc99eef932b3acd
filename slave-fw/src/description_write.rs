//! Writing a device description: the TOML form of a [`DeviceDescription`], which
//! [`DeviceDescription::parse`] reads back to the same converter configuration. `dnet-master
//! configure --read` uses it to give back what a device runs as a file the user can edit.
//!
//! The layout is the one of `slave-fw/descriptions/`: `[identity]`, `[network]`, `[io]`,
//! `[profile]`. A framed-serial profile that is the breaker preset with other serial, health or
//! sequencer settings is written as `kind = "breaker"` with those three tables; any other framed
//! profile as `kind = "framed"` with its whole `[profile.framed]` table; Modbus with every key of
//! `[profile.modbus]` written out. Sizes that follow from the profile (`io.produced_size`,
//! `io.consumed_size`) are left out, as are the switch readings, which belong to the hardware.

use crate::converter::InputAssembly;
use crate::description::DeviceDescription;
use crate::serial::modbus::{ByteOrder, Framing, ScanEntry};
use crate::serial::{
    FramedProfileConfig, HealthConfig, IdleAction, ProfileConfig, SequencerConfig, SerialSettings,
};
use devicenet::slave::BaudRate;
use serde::Serialize;

#[derive(Serialize)]
struct File<'a> {
    identity: Identity<'a>,
    network: Network,
    io: Io,
    profile: Profile<'a>,
}

#[derive(Serialize)]
struct Identity<'a> {
    vendor_id: u16,
    vendor_name: &'a str,
    device_type: u16,
    product_code: u16,
    major_revision: u8,
    minor_revision: u8,
    serial_number: u32,
    product_name: &'a str,
    catalog: &'a str,
}

#[derive(Serialize)]
struct Network {
    mac_id: u8,
    baud_rate: &'static str,
    bus_off_interrupt: bool,
    epr_resolution_ms: u16,
    programmable: bool,
}

#[derive(Serialize)]
struct Io {
    input_assembly: InputAssembly,
}

#[derive(Serialize)]
struct Profile<'a> {
    kind: &'static str,
    #[serde(skip_serializing_if = "Option::is_none")]
    serial: Option<&'a SerialSettings>,
    #[serde(skip_serializing_if = "Option::is_none")]
    health: Option<&'a HealthConfig>,
    #[serde(skip_serializing_if = "Option::is_none")]
    sequencer: Option<&'a SequencerConfig>,
    #[serde(skip_serializing_if = "Option::is_none")]
    framed: Option<&'a FramedProfileConfig>,
    #[serde(skip_serializing_if = "Option::is_none")]
    modbus: Option<Modbus<'a>>,
}

#[derive(Serialize)]
struct Modbus<'a> {
    serial: &'a SerialSettings,
    /// Left out for RTU, the default, so that RTU descriptions read as before the key existed.
    #[serde(skip_serializing_if = "Option::is_none")]
    framing: Option<Framing>,
    response_timeout_ms: u32,
    retries: u8,
    poll_period_ms: u32,
    byte_order: ByteOrder,
    health: &'a HealthConfig,
    on_idle: &'a IdleAction,
    on_fault: &'a IdleAction,
    /// Left out when there are no data-valid bits.
    #[serde(skip_serializing_if = "Option::is_none")]
    valid_bits_offset: Option<u16>,
    scan: &'a [ScanEntry],
}

fn baud_text(baud: BaudRate) -> &'static str {
    match baud {
        BaudRate::Kbps125 => "125k",
        BaudRate::Kbps250 => "250k",
        BaudRate::Kbps500 => "500k",
    }
}

/// `true` when `c` is the breaker preset apart from what `kind = "breaker"` may override.
fn is_breaker(c: &FramedProfileConfig) -> bool {
    let mut preset = FramedProfileConfig::breaker();
    preset.serial = c.serial;
    preset.health = c.health;
    preset.sequencer = c.sequencer.clone();
    preset == *c
}

impl DeviceDescription {
    /// The description as a TOML file (see the [module docs](crate::description_write)).
    ///
    /// # Errors
    ///
    /// Only when a value has no TOML form, which no valid configuration has: the message says
    /// which.
    pub fn to_toml(&self) -> Result<String, String> {
        let device = &self.converter.device;
        let id = &device.identity;
        let profile = match &self.converter.profile {
            ProfileConfig::Framed(c) if is_breaker(c) => Profile {
                kind: "breaker",
                serial: Some(&c.serial),
                health: Some(&c.health),
                sequencer: Some(&c.sequencer),
                framed: None,
                modbus: None,
            },
            ProfileConfig::Framed(c) => Profile {
                kind: "framed",
                serial: None,
                health: None,
                sequencer: None,
                framed: Some(c),
                modbus: None,
            },
            ProfileConfig::Modbus(m) => Profile {
                kind: "modbus",
                serial: None,
                health: None,
                sequencer: None,
                framed: None,
                modbus: Some(Modbus {
                    serial: &m.serial,
                    framing: (m.framing != Framing::Rtu).then_some(m.framing),
                    response_timeout_ms: m.response_timeout_ms,
                    retries: m.retries,
                    poll_period_ms: m.poll_period_ms,
                    byte_order: m.byte_order,
                    health: &m.health,
                    on_idle: &m.on_idle,
                    on_fault: &m.on_fault,
                    valid_bits_offset: m.valid_bits_offset,
                    scan: &m.scan,
                }),
            },
        };
        let file = File {
            identity: Identity {
                vendor_id: id.vendor_id,
                vendor_name: &self.vendor_name,
                device_type: id.device_type,
                product_code: id.product_code,
                major_revision: id.major_revision,
                minor_revision: id.minor_revision,
                serial_number: id.serial_number,
                product_name: &id.product_name,
                catalog: &self.catalog,
            },
            network: Network {
                mac_id: device.mac_id.as_raw(),
                baud_rate: baud_text(device.baud_rate),
                bus_off_interrupt: device.bus_off_interrupt,
                epr_resolution_ms: device.epr_resolution_ms,
                programmable: device.switches.programmable,
            },
            io: Io { input_assembly: self.converter.input },
            profile,
        };
        toml::to_string(&file).map_err(|e| format!("the description has no TOML form: {e}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn descriptions() -> Vec<PathBuf> {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("descriptions");
        let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        files
    }

    #[test]
    fn every_shipped_description_reads_back_the_same() {
        let files = descriptions();
        assert!(files.len() >= 2, "{files:?}");
        for path in files {
            let loaded = DeviceDescription::load(&path).unwrap();
            let text = loaded.to_toml().unwrap();
            let again = DeviceDescription::parse(&text).unwrap_or_else(|e| {
                panic!("{}: the written form does not read back: {e}\n{text}", path.display())
            });
            assert_eq!(again, loaded, "{}\n{text}", path.display());
        }
    }

    #[test]
    fn a_framed_profile_other_than_the_breaker_is_written_whole() {
        let mut d = DeviceDescription::reference();
        let ProfileConfig::Framed(c) = &mut d.converter.profile else { panic!("the reference is framed") };
        c.status_len = 12;
        let text = d.to_toml().unwrap();
        assert!(text.contains("kind = \"framed\"") && text.contains("[profile.framed]"), "{text}");
        let again = DeviceDescription::parse(&text).map(|a| a.converter.profile);
        // The shorter status frame must still be valid for the breaker's framing, or refused by
        // key; either way the text is the one the loader reads.
        match again {
            Ok(p) => assert_eq!(p, d.converter.profile),
            Err(e) => assert!(e.to_string().contains("profile.framed"), "{e}"),
        }
    }

    #[test]
    fn the_breaker_keeps_its_short_form() {
        let text = DeviceDescription::reference().to_toml().unwrap();
        assert!(text.contains("kind = \"breaker\""), "{text}");
        assert!(!text.contains("[profile.framed]"), "{text}");
    }
}
