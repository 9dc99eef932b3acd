//! The node's configuration at reset: switches and stored settings (board crate), the device
//! description (for now the reference device of `DeviceConfig::reference`, which the placeholder
//! instrument matches), and in the emulated build the build-time MAC ID.

use board::settings::Settings;
use board::switches::{self, SwitchReading};
use board::Resolved;
use devicenet::DeviceConfig;
#[cfg(feature = "emulated")]
use devicenet::MacId;

/// Parses a decimal MAC ID at compile time.
#[cfg(feature = "emulated")]
const fn parse_mac(text: Option<&str>) -> MacId {
    let bytes = match text {
        Some(t) => t.as_bytes(),
        None => return MacId::from_low_bits(5),
    };
    let mut value: u32 = 0;
    let mut i = 0;
    if bytes.is_empty() {
        panic!("DNET_MAC is empty");
    }
    while i < bytes.len() {
        let d = bytes[i];
        if !d.is_ascii_digit() {
            panic!("DNET_MAC must be a decimal number 0-63");
        }
        value = value * 10 + (d - b'0') as u32;
        if value > 63 {
            panic!("DNET_MAC must be 0-63");
        }
        i += 1;
    }
    MacId::from_low_bits(value as u8)
}

/// The emulated board's MAC ID: `DNET_MAC` at build time, default 5 (QEMU reads the switches as
/// zeros, i.e. all on).
#[cfg(feature = "emulated")]
pub const EMULATED_MAC: MacId = parse_mac(option_env!("DNET_MAC"));

/// What the switches and settings decide, with the emulated build's MAC override.
pub fn resolve(reading: SwitchReading, stored: &Settings) -> Resolved {
    #[allow(unused_mut)]
    let mut resolved = switches::resolve(reading, stored);
    #[cfg(feature = "emulated")]
    {
        resolved.mac_id = EMULATED_MAC;
    }
    resolved
}

/// The node configuration for `resolved` and the stored settings.
pub fn device_config(resolved: &Resolved, stored: &Settings) -> DeviceConfig {
    let mut config = DeviceConfig::reference();
    config.mac_id = resolved.mac_id;
    config.baud_rate = resolved.baud_rate;
    config.switches = resolved.switches;
    config.bus_off_interrupt = stored.bus_off_interrupt;
    config
}
