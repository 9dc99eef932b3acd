//! The converter's configuration at reset: which instrument preset ([`Preset`]), the MAC ID and
//! data rate from the switches or the stored settings (board crate), and in the emulated build the
//! build-time MAC ID.
//!
//! ## Choosing the preset
//!
//! The firmware carries both instrument profiles, and picks one at run time:
//!
//! 1. the stored settings' configuration image, when its first byte is a preset code ([`Preset::code`]);
//! 2. otherwise the build-time default, `DNET_PROFILE` (`breaker`, the default, or `modbus`).
//!
//! Nothing writes the image yet (the settings object is read-only over the network); reading it
//! at run time is what puts both profiles in every image, so the size budget measures the full
//! converter.

use crate::presets;
use board::settings::Settings;
use board::switches::{self, SwitchReading};
use board::uart::{self, LineFormat};
use board::Resolved;
#[cfg(feature = "emulated")]
use devicenet::MacId;
use slave_fw::converter::ConverterConfig;
use slave_fw::serial::{DataBits, Parity, SerialSettings, StopBits};

/// The instrument configurations this firmware carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(all(feature = "defmt", target_os = "none"), derive(defmt::Format))]
pub enum Preset {
    /// The reference converter: the intelligent circuit breaker ([`presets::breaker`]).
    Breaker,
    /// The Modbus RTU energy-meter gateway ([`presets::modbus_meter`]).
    ModbusMeter,
}

impl Preset {
    /// The build-time default: `DNET_PROFILE`, `breaker` when unset.
    pub const BUILD_DEFAULT: Preset = parse_preset(option_env!("DNET_PROFILE"));

    /// The preset's code in the first byte of the stored configuration image (until
    /// `slave_fw::image` replaces the presets with decoded images).
    pub const fn code(self) -> u8 {
        match self {
            Preset::Breaker => 1,
            Preset::ModbusMeter => 2,
        }
    }

    /// The preset a stored configuration image selects, if any.
    pub fn from_stored(image: &[u8]) -> Option<Preset> {
        let code = *image.first()?;
        [Preset::Breaker, Preset::ModbusMeter].into_iter().find(|p| p.code() == code)
    }

    /// The preset's converter configuration (MAC ID and data rate still to be set).
    pub fn config(self) -> ConverterConfig {
        match self {
            Preset::Breaker => presets::breaker(),
            Preset::ModbusMeter => presets::modbus_meter(),
        }
    }
}

/// Parses `DNET_PROFILE` at compile time; anything but `breaker` or `modbus` fails the build.
const fn parse_preset(text: Option<&str>) -> Preset {
    let bytes = match text {
        Some(t) => t.as_bytes(),
        None => return Preset::Breaker,
    };
    if eq(bytes, b"breaker") {
        Preset::Breaker
    } else if eq(bytes, b"modbus") {
        Preset::ModbusMeter
    } else {
        panic!("DNET_PROFILE must be breaker or modbus")
    }
}

const fn eq(a: &[u8], b: &[u8]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

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

/// The preset the stored settings select, else the build default.
pub fn preset(stored: &Settings) -> Preset {
    Preset::from_stored(&stored.image).unwrap_or(Preset::BUILD_DEFAULT)
}

/// The converter configuration for `preset` with the MAC ID, data rate and switches `resolved`
/// decided and the stored bus-off interrupt setting.
pub fn converter_config(preset: Preset, resolved: &Resolved, stored: &Settings) -> ConverterConfig {
    let mut config = preset.config();
    config.device.mac_id = resolved.mac_id;
    config.device.baud_rate = resolved.baud_rate;
    config.device.switches = resolved.switches;
    config.device.bus_off_interrupt = stored.bus_off_interrupt;
    config
}

/// The profile's serial settings as the board's USART takes them.
pub fn line_format(serial: &SerialSettings) -> LineFormat {
    LineFormat {
        baud: serial.baud,
        data_bits: match serial.data_bits {
            DataBits::Seven => 7,
            DataBits::Eight => 8,
        },
        parity: match serial.parity {
            Parity::None => uart::Parity::None,
            Parity::Even => uart::Parity::Even,
            Parity::Odd => uart::Parity::Odd,
        },
        stop_bits: match serial.stop_bits {
            StopBits::One => uart::StopBits::One,
            StopBits::Two => uart::StopBits::Two,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use board::uart::WordLength;
    use devicenet::slave::BaudRate;
    use devicenet::MacId;

    #[test]
    fn default_preset_is_the_breaker() {
        assert_eq!(parse_preset(None), Preset::Breaker);
        assert_eq!(parse_preset(Some("breaker")), Preset::Breaker);
        assert_eq!(parse_preset(Some("modbus")), Preset::ModbusMeter);
    }

    #[test]
    fn switches_decide_the_mac_id_except_in_the_emulated_build() {
        // Switches 1-6 = 12, switch 7 on: 250 kbit/s.
        let resolved = resolve(SwitchReading::from_bits(12 | 1 << 6), &Settings::default());
        #[cfg(not(feature = "emulated"))]
        assert_eq!(resolved.mac_id.as_raw(), 12);
        #[cfg(feature = "emulated")]
        assert_eq!(resolved.mac_id, EMULATED_MAC);
        assert_eq!(resolved.baud_rate, BaudRate::Kbps250);
    }

    #[test]
    fn stored_image_selects_the_preset() {
        for p in [Preset::Breaker, Preset::ModbusMeter] {
            assert_eq!(Preset::from_stored(&[p.code(), 0xAA]), Some(p));
        }
        assert_eq!(Preset::from_stored(&[]), None);
        assert_eq!(Preset::from_stored(&[0]), None);
        assert_eq!(Preset::from_stored(&[0xFF]), None);
        let mut stored = Settings::default();
        assert_eq!(preset(&stored), Preset::BUILD_DEFAULT);
        stored.image.extend_from_slice(&[Preset::ModbusMeter.code()]).unwrap();
        assert_eq!(preset(&stored), Preset::ModbusMeter);
    }

    #[test]
    fn switches_and_settings_override_the_preset() {
        let resolved = Resolved {
            mac_id: MacId::new(12).unwrap(),
            baud_rate: BaudRate::Kbps500,
            switches: devicenet::slave::Switches {
                mac_id: Some(12),
                programmable: false,
                ..Default::default()
            },
            store_reading: false,
        };
        let stored = Settings { bus_off_interrupt: true, ..Settings::default() };
        for preset in [Preset::Breaker, Preset::ModbusMeter] {
            let c = converter_config(preset, &resolved, &stored);
            assert_eq!((c.device.mac_id, c.device.baud_rate), (resolved.mac_id, BaudRate::Kbps500));
            assert_eq!(c.device.switches, resolved.switches);
            assert!(c.device.bus_off_interrupt);
            c.validate().unwrap();
            // Every preset's line is one the USART makes.
            assert!(line_format(c.profile.serial()).word_length().is_ok());
        }
    }

    #[test]
    fn line_formats() {
        let breaker = line_format(presets::breaker().profile.serial());
        assert_eq!(breaker, LineFormat::new_8n1(9600));
        let meter = line_format(presets::modbus_meter().profile.serial());
        assert_eq!(
            (meter.baud, meter.parity, meter.word_length()),
            (19200, uart::Parity::Even, Ok(WordLength::Nine))
        );
    }
}
