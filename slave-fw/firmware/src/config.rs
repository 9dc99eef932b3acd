//! The converter's configuration at reset: the stored configuration image or the factory
//! default ([`boot`]), the MAC ID and data rate from the switches or the stored settings (board
//! crate), and in the emulated build the build-time MAC ID.
//!
//! ## Which configuration runs
//!
//! 1. The stored settings' configuration image (`Settings::image`, written when a tool downloads
//!    one over the bus, `slave_fw::image`), when it decodes, the converter accepts it and the
//!    USART makes its serial line: [`ConfigOrigin::Stored`].
//! 2. No image stored: the factory default, the reference breaker converter
//!    ([`ConverterConfig::breaker_reference`]): [`ConfigOrigin::FactoryDefault`].
//! 3. An image that cannot be used (corrupt, another format version, values refused, a line the
//!    USART cannot make): the factory default with a **configuration fault**, a minor recoverable
//!    fault in the Identity status, Module Status flashing red (protocol §6.2, §7.3), the
//!    reason in the configuration object: [`ConfigOrigin::Fault`]. Any image bytes boot.
//!
//! The same rule for the serial line ([`usart_makes_the_line`]) refuses a download at
//! Commit_Download, so an image the board cannot run is never stored.
//!
//! Whatever runs, the MAC ID and data rate come from the switches or the stored settings (the
//! image's own are the soft slave's), and so does the bus-off interrupt setting.
//!
//! ## The serial number
//!
//! The board's own, never the image's (a description configures many boards, and two devices on
//! one network must not share vendor and serial): `serial_number`, folded from the MCU's unique
//! ID ([`board::uid`]). QEMU's `netduinoplus2` models no unique ID (nothing is mapped at
//! 0x1FFF_7A10, a read is a bus fault), so the emulated board does not read it and keeps the
//! reference device's serial number, [`EMULATED_SERIAL`], which the reference sequence of
//! protocol §2 carries in its duplicate MAC ID checks.

use board::clocks::INSTRUMENT_UART_HZ;
use board::settings::Settings;
use board::switches::{self, SwitchReading};
use board::uart::{self, LineFormat};
use board::Resolved;
use devicenet::slave::BaudRate;
use devicenet::Instant;
#[cfg(feature = "emulated")]
use devicenet::MacId;
use slave_fw::converter::{BoardFacts, ConfigOrigin, Converter, ConverterConfig, InvalidConfig};
use slave_fw::image::{self, ImageError};
use slave_fw::serial::modbus::Framing;
use slave_fw::serial::{
    ConfigError, Conflict, DataBits, Field, Parity, ProfileConfig, SerialSettings, StopBits,
};

/// The stored image is at most what a settings record holds.
const _: () = assert!(image::MAX_IMAGE <= board::settings::IMAGE_CAPACITY);

/// A short name of `origin` for the log.
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
pub const fn origin_name(origin: &ConfigOrigin) -> &'static str {
    match origin {
        ConfigOrigin::FactoryDefault => "factory default",
        ConfigOrigin::Stored => "stored image",
        ConfigOrigin::Fault(_) => "factory default, stored image refused",
    }
}

/// The emulated board's serial number: the reference device's (module docs).
#[cfg_attr(not(feature = "emulated"), allow(dead_code))]
pub const EMULATED_SERIAL: u32 = 0x1234_5678;

/// The board's serial number (module docs): the real board's from its MCU's unique ID, the
/// emulated board's [`EMULATED_SERIAL`].
#[cfg(target_os = "none")]
pub fn serial_number() -> u32 {
    #[cfg(not(feature = "emulated"))]
    let serial = board::uid::serial_number(board::hw::unique_id());
    #[cfg(feature = "emulated")]
    let serial = EMULATED_SERIAL;
    serial
}

/// What runs after a reset.
pub struct Boot {
    /// The converter, powered off, built with [`Boot::origin`] (a fault shows in its status).
    pub converter: Converter,
    /// Its serial line, one the USART makes.
    pub line: LineFormat,
    /// Where the configuration came from.
    pub origin: ConfigOrigin,
}

/// The converter the stored `settings` and the switches (`resolved`) make at `now` with the
/// board's `serial` number: the stored image if it can run, the factory default otherwise
/// (module docs). Never fails.
pub fn boot(resolved: &Resolved, stored: &Settings, serial: u32, now: Instant) -> Boot {
    let board = BoardFacts {
        mac_id: resolved.mac_id,
        baud_rate: resolved.baud_rate,
        switches: resolved.switches,
        bus_off_interrupt: stored.bus_off_interrupt,
        serial_number: serial,
    };
    let origin = if stored.image.is_empty() {
        ConfigOrigin::FactoryDefault
    } else {
        match start(&stored.image, ConfigOrigin::Stored, &board, now) {
            Ok(boot) => return boot,
            Err(e) => ConfigOrigin::Fault(e),
        }
    };
    // The factory default is the reference converter, which always starts (a host test proves it).
    match start(&image::BREAKER_REFERENCE, origin, &board, now) {
        Ok(boot) => boot,
        Err(_) => panic!("factory configuration refused"),
    }
}

/// A converter for the configuration in `image` from `origin` with the `board`'s own values,
/// and its serial line, if the image decodes and both the converter and the USART take it. The
/// image in force is `image` as it is.
fn start(image: &[u8], origin: ConfigOrigin, board: &BoardFacts, now: Instant) -> Result<Boot, ImageError> {
    // A download this board cannot run is refused at once, not found out at the next reset.
    let converter = Converter::boot(image, origin, board, usart_makes_the_line, now)?;
    let line = line_format(converter.profile().serial_settings());
    Ok(Boot { converter, line, origin })
}

/// The board's own rule for a configuration ([`slave_fw::converter::PlatformCheck`]): no Modbus
/// TCP framing (the board has no TCP), and the instrument USART makes its serial line (7 data
/// bits only with parity; the baud rate within the divider's range, [`LineFormat::baud_range`]).
pub fn usart_makes_the_line(config: &ConverterConfig) -> Result<(), InvalidConfig> {
    // The board has no network port: Modbus TCP is for the soft slave's TCP serial port.
    if let ProfileConfig::Modbus(m) = &config.profile {
        if m.framing == Framing::Tcp {
            let error = ConfigError::conflict(Field::ModbusFraming, Conflict::NoTcpPort);
            return Err(InvalidConfig::Profile { modbus: true, error });
        }
    }
    let line = line_format(config.profile.serial());
    if line.check(INSTRUMENT_UART_HZ).is_ok() {
        return Ok(());
    }
    let range = LineFormat::baud_range(INSTRUMENT_UART_HZ);
    let error = if line.word_length().is_err() {
        ConfigError::conflict(Field::SerialParity, Conflict::SevenBitsNeedParity)
    } else {
        ConfigError::out_of_range(Field::SerialBaud, line.baud, *range.start(), *range.end())
    };
    Err(InvalidConfig::Profile { modbus: matches!(config.profile, ProfileConfig::Modbus(_)), error })
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

/// What the switches (`None` on a board without them: the stored values) and settings decide,
/// with the emulated build's MAC override. `stored` is the settings journal's newest record,
/// `None` when it holds none: a board without switches then starts at MAC ID 63 and autobauds
/// ([`board::switches::resolve_stored`]); one with switches runs on the defaults.
pub fn resolve(reading: Option<SwitchReading>, stored: Option<&Settings>) -> Resolved {
    #[allow(unused_mut)]
    let mut resolved = match reading {
        Some(reading) => switches::resolve(reading, stored.unwrap_or(&Settings::default())),
        None => switches::resolve_stored(stored),
    };
    #[cfg(feature = "emulated")]
    {
        resolved.mac_id = EMULATED_MAC;
    }
    resolved
}

/// The node joins at `rate`: the rate autobaud found, or the one it was set up at. With no record
/// stored (autobaud ran), the in-memory settings take it too, so that the record the first
/// network-set MAC ID writes keeps the network's rate, not the default 125 kbit/s the search
/// started at: after a power cycle the node comes up at the rate it joined at. Nothing is stored
/// here ([`board::autobaud`]'s rule 4).
#[cfg_attr(feature = "emulated", allow(dead_code))] // the emulated board has no bxCAN
pub fn joined_at(resolved: &mut Resolved, settings: &mut Settings, rate: BaudRate) {
    resolved.baud_rate = rate;
    if resolved.autobaud {
        settings.baud_rate = rate;
    }
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
    use devicenet::led::Indication;
    use devicenet::MacId;
    use slave_fw::converter::ConfigState;
    use slave_fw::description::DeviceDescription;
    use slave_fw::serial::Problem;
    use std::path::Path;

    /// The board's serial number in these tests.
    const SERIAL: u32 = 0x3A5C_0F17;

    /// The switches in the program position with MAC ID 12 at 500 kbit/s, from the settings.
    fn resolved() -> Resolved {
        Resolved {
            mac_id: MacId::new(12).unwrap(),
            baud_rate: BaudRate::Kbps500,
            switches: devicenet::slave::Switches {
                mac_id: Some(12),
                programmable: true,
                ..Default::default()
            },
            store_reading: false,
            autobaud: false,
        }
    }

    fn described(file: &str) -> ConverterConfig {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../descriptions").join(file);
        DeviceDescription::load(&path).unwrap().converter
    }

    fn settings_with(image: &[u8]) -> Settings {
        let mut settings = Settings { bus_off_interrupt: true, ..Settings::default() };
        settings.image.extend_from_slice(image).unwrap();
        settings
    }

    fn encoded(config: &ConverterConfig) -> Vec<u8> {
        let mut out = [0; image::MAX_IMAGE];
        let len = image::encode(config, &mut out).unwrap();
        out[..len].to_vec()
    }

    /// The Module Status indication just after power-on (before the instrument could be late).
    fn module_status(boot: &mut Boot) -> Indication {
        boot.converter.power_on(Instant::ZERO);
        boot.converter.handle_timeout(Instant::from_millis(10));
        boot.converter.node().module_indication()
    }

    #[test]
    fn switches_decide_the_mac_id_except_in_the_emulated_build() {
        // Switches 1-6 = 12, switch 7 on: 250 kbit/s.
        let resolved = resolve(Some(SwitchReading::from_bits(12 | 1 << 6)), Some(&Settings::default()));
        #[cfg(not(feature = "emulated"))]
        assert_eq!(resolved.mac_id.as_raw(), 12);
        #[cfg(feature = "emulated")]
        assert_eq!(resolved.mac_id, EMULATED_MAC);
        assert_eq!(resolved.baud_rate, BaudRate::Kbps250);
    }

    #[test]
    fn a_board_without_switches_starts_at_mac_63_and_autobauds_when_nothing_is_stored() {
        let resolved = resolve(None, None);
        #[cfg(not(feature = "emulated"))]
        assert_eq!(resolved.mac_id.as_raw(), 63);
        assert!(resolved.autobaud);
        let boot = boot(&resolved, &Settings::default(), SERIAL, Instant::ZERO);
        let node = boot.converter.node().config();
        #[cfg(not(feature = "emulated"))]
        assert_eq!(node.mac_id.as_raw(), 63, "the converter's DeviceNet object says 63");
        assert!(node.switches.programmable, "settable over the network");
        // With a record, the stored values and no autobaud.
        let stored = Settings { mac_id: MacId::new(9).unwrap(), ..Settings::default() };
        let resolved = resolve(None, Some(&stored));
        assert!(!resolved.autobaud);
    }

    #[test]
    fn no_image_runs_the_factory_default() {
        let mut boot = boot(&resolved(), &settings_with(&[]), SERIAL, Instant::ZERO);
        assert_eq!(boot.origin, ConfigOrigin::FactoryDefault);
        assert_eq!(boot.line, LineFormat::new_8n1(9600));
        let mut identity = ConverterConfig::breaker_reference().device.identity;
        identity.serial_number = SERIAL;
        assert_eq!(boot.converter.node().config().identity, identity);
        assert_eq!(module_status(&mut boot), Indication::Green);
    }

    #[test]
    fn a_stored_image_runs_with_the_switches_network_settings() {
        let meter = described("modbus-meter.toml");
        let mut boot = boot(&resolved(), &settings_with(&encoded(&meter)), SERIAL, Instant::ZERO);
        assert_eq!(boot.origin, ConfigOrigin::Stored);
        assert!(matches!(boot.converter.profile(), slave_fw::serial::Profile::Modbus(_)));
        let node = boot.converter.node().config();
        let mut identity = meter.device.identity.clone();
        identity.serial_number = SERIAL;
        assert_eq!(node.identity, identity, "the image's identity with the board's serial number");
        assert_eq!((node.mac_id, node.baud_rate), (resolved().mac_id, BaudRate::Kbps500));
        assert_eq!(node.switches, resolved().switches);
        assert!(node.bus_off_interrupt, "the stored setting");
        assert_eq!((node.produced_size, node.consumed_size), (14, 4));
        assert_eq!(
            (boot.line.baud, boot.line.parity, boot.line.word_length()),
            (19200, uart::Parity::Even, Ok(WordLength::Nine))
        );
        assert_eq!(module_status(&mut boot), Indication::Green);
        assert_eq!(boot.converter.image_in_force(), encoded(&meter), "the bytes stored, as downloaded");
    }

    #[test]
    fn an_unusable_image_runs_the_factory_default_with_a_configuration_fault() {
        let good = encoded(&described("modbus-meter.toml"));
        let mut corrupt = good.clone();
        corrupt[20] ^= 0x01;
        let mut newer = good.clone();
        newer[4] = image::IMAGE_VERSION + 1;
        for (name, bytes) in
            [("corrupt", &corrupt[..]), ("newer version", &newer[..]), ("garbage", &[0xFF; 40][..])]
        {
            let mut boot = boot(&resolved(), &settings_with(bytes), SERIAL, Instant::ZERO);
            assert!(matches!(boot.origin, ConfigOrigin::Fault(_)), "{name}: {:?}", boot.origin);
            assert_eq!(boot.converter.config_state(), ConfigState::Fault, "{name}");
            assert_eq!(boot.line, LineFormat::new_8n1(9600), "{name}");
            assert_eq!(module_status(&mut boot), Indication::FlashingRed, "{name}");
        }
    }

    #[test]
    fn an_image_whose_line_the_usart_cannot_make_is_refused() {
        let mut meter = described("modbus-meter.toml");
        let ProfileConfig::Modbus(modbus) = &mut meter.profile else { unreachable!() };
        // Valid for the converter (300..=4_000_000), beyond the USART's divider.
        modbus.serial.baud = if cfg!(feature = "emulated") { 4_000_000 } else { 300 };
        let mut boot = boot(&resolved(), &settings_with(&encoded(&meter)), SERIAL, Instant::ZERO);
        let ConfigOrigin::Fault(ImageError::Invalid(InvalidConfig::Profile { error, .. })) = boot.origin
        else {
            panic!("{:?}", boot.origin);
        };
        assert_eq!(error.field, Field::SerialBaud);
        assert_eq!(module_status(&mut boot), Indication::FlashingRed);
        // The same rule refuses the download (the converter's Commit_Download).
        assert_eq!(
            usart_makes_the_line(&meter).map_err(|e| e.key().to_string()),
            Err("profile.modbus.serial.baud".into())
        );
        assert_eq!(usart_makes_the_line(&described("modbus-meter.toml")), Ok(()));
    }

    #[test]
    fn a_modbus_tcp_image_is_refused_and_ascii_runs() {
        let mut meter = described("modbus-meter.toml");
        let ProfileConfig::Modbus(modbus) = &mut meter.profile else { unreachable!() };
        modbus.framing = Framing::Tcp;
        let mut boot = boot(&resolved(), &settings_with(&encoded(&meter)), SERIAL, Instant::ZERO);
        let ConfigOrigin::Fault(ImageError::Invalid(InvalidConfig::Profile { error, .. })) = boot.origin
        else {
            panic!("{:?}", boot.origin);
        };
        assert_eq!(
            (error.field, error.problem),
            (Field::ModbusFraming, Problem::Conflict(Conflict::NoTcpPort))
        );
        // The converter keeps working, on the factory default.
        assert!(matches!(boot.converter.profile(), slave_fw::serial::Profile::Framed(_)));
        assert_eq!(module_status(&mut boot), Indication::FlashingRed);
        assert_eq!(
            usart_makes_the_line(&meter).map_err(|e| e.key().to_string()),
            Err("profile.modbus.framing".into())
        );
        let ProfileConfig::Modbus(modbus) = &mut meter.profile else { unreachable!() };
        modbus.framing = Framing::Ascii;
        let ascii = super::boot(&resolved(), &settings_with(&encoded(&meter)), SERIAL, Instant::ZERO);
        assert_eq!(ascii.origin, ConfigOrigin::Stored);
        let slave_fw::serial::Profile::Modbus(m) = ascii.converter.profile() else { panic!("not Modbus") };
        assert_eq!(m.config().framing, Framing::Ascii);
    }

    /// Any image bytes boot: every truncation and every single-bit flip of a valid image.
    #[test]
    fn any_image_bytes_boot() {
        let good = encoded(&described("modbus-meter.toml"));
        for len in 0..good.len() {
            let b = boot(&resolved(), &settings_with(&good[..len]), SERIAL, Instant::ZERO);
            assert_ne!(b.origin, ConfigOrigin::Stored, "truncated to {len}");
        }
        for byte in 0..good.len() {
            for bit in 0..8 {
                let mut bytes = good.clone();
                bytes[byte] ^= 1 << bit;
                let b = boot(&resolved(), &settings_with(&bytes), SERIAL, Instant::ZERO);
                assert!(matches!(b.origin, ConfigOrigin::Fault(_)), "byte {byte} bit {bit}");
            }
        }
    }

    #[test]
    fn the_emulated_board_keeps_the_reference_serial_number() {
        assert_eq!(EMULATED_SERIAL, devicenet::slave::DeviceConfig::reference().identity.serial_number);
        // The meter's description carries another one; a board running it keeps its own.
        let meter = described("modbus-meter.toml");
        assert_ne!(meter.device.identity.serial_number, EMULATED_SERIAL);
        let boot = boot(&resolved(), &settings_with(&encoded(&meter)), EMULATED_SERIAL, Instant::ZERO);
        assert_eq!(boot.origin, ConfigOrigin::Stored);
        assert_eq!(boot.converter.node().config().identity.serial_number, EMULATED_SERIAL);
    }

    #[test]
    fn the_factory_default_matches_its_description() {
        let breaker = described("breaker.toml");
        let factory = ConverterConfig::breaker_reference();
        assert_eq!(factory.profile, breaker.profile);
        assert_eq!(factory.input, breaker.input);
        assert_eq!(factory.device.identity, breaker.device.identity);
    }

    #[test]
    fn an_autobauded_rate_is_the_one_a_later_record_keeps() {
        let mut searched = Resolved { autobaud: true, baud_rate: BaudRate::Kbps125, ..resolved() };
        let mut settings = Settings::default();
        joined_at(&mut searched, &mut settings, BaudRate::Kbps500);
        assert_eq!((searched.baud_rate, settings.baud_rate), (BaudRate::Kbps500, BaudRate::Kbps500));

        // A rate from the switches or a record is in force but not copied into the record.
        let mut fixed = resolved();
        let mut stored = Settings { baud_rate: BaudRate::Kbps250, ..Settings::default() };
        joined_at(&mut fixed, &mut stored, BaudRate::Kbps500);
        assert_eq!((fixed.baud_rate, stored.baud_rate), (BaudRate::Kbps500, BaudRate::Kbps250));
    }
}
