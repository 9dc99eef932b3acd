//! The instrument configurations built into the firmware, in Rust: the board has no file system,
//! and a `const`-like builder costs no parser in flash. Each is the device description file of the
//! same name in `slave-fw/descriptions/`, and a host test proves the two agree (the description
//! files stay the one source of truth; the EDS generator and the soft slave read them).
//!
//! The descriptions' `[network]` MAC ID and data rate are the soft slave's; on the board they come
//! from the switches or the stored settings ([`crate::config::converter_config`]).

use devicenet::slave::{DeviceConfig, Identity};
use slave_fw::converter::{ConverterConfig, InputAssembly};
use slave_fw::serial::modbus::{ByteOrder, Function, ModbusConfig, ScanEntry};
use slave_fw::serial::{HealthConfig, IdleAction, ProfileConfig, SerialSettings, StalePolicy};

/// `descriptions/breaker.toml`: the reference converter, the intelligent circuit breaker of the
/// source paper on 9600 8N1, the reference device of devicenet-notes §2.
pub fn breaker() -> ConverterConfig {
    ConverterConfig::breaker_reference()
}

/// `descriptions/modbus-meter.toml`: a Modbus RTU gateway to an energy meter on 19200 8E1.
/// Input registers 0–3 and holding registers 100–101 fill input bytes 0–11; output bytes 0–3 go to
/// holding registers 16–17; the poll produces assembly 101 (image, status byte, freshness counter,
/// 14 bytes). On a poll connection fault register 16 is written 0.
pub fn modbus_meter() -> ConverterConfig {
    let entry = |function, address, count, offset| ScanEntry { unit: 1, function, address, count, offset };
    let mut scan = heapless::Vec::new();
    for e in [
        entry(Function::ReadInputRegisters, 0, 4, 0),
        entry(Function::ReadHoldingRegisters, 100, 2, 8),
        entry(Function::WriteMultipleRegisters, 16, 2, 0),
    ] {
        // Three entries; the scan list holds sixteen.
        let _ = scan.push(e);
    }
    let mut modbus = ModbusConfig::new(scan);
    modbus.serial = SerialSettings::new_8e1(19200);
    modbus.response_timeout_ms = 200;
    modbus.retries = 1;
    modbus.poll_period_ms = 100;
    modbus.byte_order = ByteOrder::LittleEndian;
    modbus.health = HealthConfig { stale_timeout_ms: 1000, stale_policy: StalePolicy::Clear };
    modbus.on_fault = IdleAction::send(&[0x01, 0x06, 0x00, 0x10, 0x00, 0x00]).unwrap_or_default();

    let mut product_name = heapless::String::new();
    // 24 characters; the Identity holds 32.
    let _ = product_name.push_str("Modbus-DeviceNet Gateway");
    let reference = DeviceConfig::reference();
    ConverterConfig {
        device: DeviceConfig {
            identity: Identity {
                vendor_id: 0x1234,
                device_type: 0x000C,
                product_code: 2,
                major_revision: 1,
                minor_revision: 0,
                serial_number: 0x00C0_FFEE,
                product_name,
            },
            epr_resolution_ms: 1,
            port: 0,
            bus_off_interrupt: false,
            switches: Default::default(),
            ..reference
        },
        profile: ProfileConfig::Modbus(modbus),
        input: InputAssembly::WithStatus,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slave_fw::description::DeviceDescription;
    use std::path::Path;

    /// The description file's configuration, with the MAC ID and data rate of `preset`.
    fn agree(preset: ConverterConfig, file: &str) {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../descriptions").join(file);
        let described = DeviceDescription::load(&path).unwrap().converter;
        let mut preset = preset;
        preset.validate().unwrap();
        preset.device.mac_id = described.device.mac_id;
        preset.device.baud_rate = described.device.baud_rate;
        assert_eq!(preset.profile, described.profile, "{file}: profile");
        assert_eq!(preset.input, described.input, "{file}: input assembly");
        assert_eq!(preset.device_config(), described.device_config(), "{file}: device");
    }

    #[test]
    fn breaker_matches_its_description() {
        agree(breaker(), "breaker.toml");
    }

    #[test]
    fn modbus_meter_matches_its_description() {
        agree(modbus_meter(), "modbus-meter.toml");
    }

    #[test]
    fn sizes() {
        let meter = modbus_meter().device_config();
        assert_eq!((meter.produced_size, meter.consumed_size), (14, 4));
        let breaker = breaker().device_config();
        assert_eq!((breaker.produced_size, breaker.consumed_size), (18, 8));
    }
}
