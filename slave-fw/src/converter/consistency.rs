//! Identity attribute 9, the configuration consistency value (CCV, protocol §II.5.3): a UINT
//! that changes whenever the stored configuration changes, so that a scanner with automatic
//! device replacement can tell, by one read, whether a device holds the configuration it saved.
//!
//! The converter's whole configuration is its image ([`super::image`]), so the CCV is a CRC of
//! the image: **CRC-16/MODBUS** ([`crate::serial::checksum::crc16_modbus`], already in the
//! firmware for Modbus RTU) over the image's header and body (not its CRC-32 trailer), with the
//! values that are not the configuration's read as 0 ([`masked`]):
//!
//! - the serial number: the device's own, never taken from an image
//!   ([`super::ConfigOrigin::resolve`]);
//! - the MAC ID, the data rate and the bus-off interrupt bit of the network flags: what a master
//!   sets through the DeviceNet object (attributes 1–3), which the board keeps beside the image
//!   in its settings and puts over the image's values at start ([`super::BoardFacts`]); moving a
//!   device to another MAC ID, as address recovery does, must not change its CCV.
//!
//! So
//!
//! - equal configurations give equal CCVs, whatever device holds them and at whatever address;
//! - the factory default has one fixed CCV, [`FACTORY_CCV`] on every board (the image
//!   [`super::image::BREAKER_REFERENCE`]) and on a soft slave run from the reference description;
//! - any change of one byte, or of up to 16 adjacent bits, of the rest of the image changes it
//!   (a CRC-16 detects every burst of up to 16 bits); two different configurations share a CCV
//!   with a chance of 1 in 65 536.
//!
//! The converter sets the node's attribute from the image in force when it is built, and from a
//! new image when it hands it over for storage ([`super::Converter::poll_new_image`]): the CCV
//! is that of the stored configuration, the one the next reset runs, from the moment it is
//! stored. Being a function of the stored bytes, it survives every reset.

use crate::serial::checksum::{crc16_modbus_step, CRC16_MODBUS_INIT};
use core::ops::Range;

/// Where the serial number lies in an image of format version 1: after the 7-byte header,
/// vendor ID, device type and product code (2 bytes each), major and minor revision.
pub const SERIAL_NUMBER_AT: Range<usize> = 15..19;
/// Where the product name's length byte lies (version 1); the network section follows the name:
/// MAC ID, data rate, port, flags (bit 0 bus-off interrupt).
const PRODUCT_NAME_AT: usize = 19;

/// The CCV of the factory default ([`super::image::BREAKER_REFERENCE`]).
pub const FACTORY_CCV: u16 = 0x3554;

/// Byte `at` of an image whose network section starts at `network`, as the CCV covers it: the
/// values that are not the configuration's read as 0 (module docs).
pub fn masked(at: usize, b: u8, network: usize) -> u8 {
    match at.wrapping_sub(network) {
        _ if SERIAL_NUMBER_AT.contains(&at) => 0,
        // MAC ID and data rate.
        0 | 1 => 0,
        // The flags without the bus-off interrupt bit.
        3 => b & !1,
        _ => b,
    }
}

/// The configuration consistency value of `image` (module docs). Any bytes are accepted: a
/// shorter image is covered as far as it goes.
pub fn consistency_value(image: &[u8]) -> u16 {
    let covered = image.len().saturating_sub(super::image::CRC_LEN);
    let name_len = image.get(PRODUCT_NAME_AT).map_or(0, |&n| usize::from(n));
    let network = PRODUCT_NAME_AT + 1 + name_len;
    image
        .iter()
        .take(covered)
        .enumerate()
        .fold(CRC16_MODBUS_INIT, |crc, (at, &b)| crc16_modbus_step(crc, masked(at, b, network)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::converter::image::{self, BREAKER_REFERENCE};
    use crate::converter::{ConfigOrigin, Converter, ConverterConfig, InputAssembly};
    use devicenet::{CanFrame, Duration, Instant};
    use rstest::rstest;

    /// CRC-16/MODBUS by the `crc` crate's catalogue: an implementation independent of ours.
    fn crc16_reference(data: &[u8]) -> u16 {
        crc::Crc::<u16>::new(&crc::CRC_16_MODBUS).checksum(data)
    }

    fn encoded(config: &ConverterConfig) -> std::vec::Vec<u8> {
        image::encode_to_vec(config).unwrap()
    }

    #[test]
    fn the_factory_value_is_the_crc_of_the_reference_image_without_serial_address_and_trailer() {
        let mut bytes = BREAKER_REFERENCE[..BREAKER_REFERENCE.len() - 4].to_vec();
        bytes[SERIAL_NUMBER_AT].fill(0);
        // Product name of 23 bytes: the network section at 43 (MAC 5, 250k, port 0, flags 0).
        assert_eq!(&bytes[43..47], [5, 1, 0, 0]);
        bytes[43..45].fill(0);
        assert_eq!(consistency_value(&BREAKER_REFERENCE), crc16_reference(&bytes));
        assert_eq!(consistency_value(&BREAKER_REFERENCE), FACTORY_CCV);
    }

    #[test]
    fn the_serial_number_field_is_where_the_encoder_writes_it() {
        let mut config = ConverterConfig::breaker_reference();
        config.device.identity.serial_number = 0xA1B2_C3D4;
        assert_eq!(encoded(&config)[SERIAL_NUMBER_AT], [0xD4, 0xC3, 0xB2, 0xA1]);
    }

    #[rstest]
    #[case::serial_number(|c: &mut ConverterConfig| c.device.identity.serial_number = 0x0BAD_F00D)]
    #[case::mac_id(|c: &mut ConverterConfig| c.device.mac_id = devicenet::MacId::new(63).unwrap())]
    #[case::data_rate(|c: &mut ConverterConfig| c.device.baud_rate = devicenet::slave::BaudRate::Kbps500)]
    #[case::bus_off_interrupt(|c: &mut ConverterConfig| c.device.bus_off_interrupt = true)]
    #[case::nothing(|_: &mut ConverterConfig| {})]
    fn equal_configurations_give_equal_values(#[case] change: fn(&mut ConverterConfig)) {
        let mut config = ConverterConfig::breaker_reference();
        change(&mut config);
        assert_eq!(consistency_value(&encoded(&config)), FACTORY_CCV);
    }

    #[rstest]
    #[case::product_name(|c: &mut ConverterConfig| c.device.identity.product_name = "Other".try_into().unwrap())]
    #[case::programmable(|c: &mut ConverterConfig| c.device.switches.programmable = true)]
    #[case::port(|c: &mut ConverterConfig| c.device.port = 1)]
    #[case::input_assembly(|c: &mut ConverterConfig| c.input = InputAssembly::WithStatus)]
    fn a_changed_configuration_changes_the_value(#[case] change: fn(&mut ConverterConfig)) {
        let mut config = ConverterConfig::breaker_reference();
        change(&mut config);
        assert_ne!(consistency_value(&encoded(&config)), FACTORY_CCV);
    }

    #[test]
    fn every_single_byte_change_of_the_configuration_changes_the_value() {
        let covered = BREAKER_REFERENCE.len() - 4;
        // Serial number 15..19, MAC ID 43, data rate 44 (the network section after the name).
        let not_configuration = |at: usize| SERIAL_NUMBER_AT.contains(&at) || at == 43 || at == 44;
        // The name's length byte moves the network section: changing it is changing the
        // configuration, but the masked bytes move too, so it is left to the cases above.
        for at in (0..covered).filter(|&at| !not_configuration(at) && at != 19) {
            for flip in [0x01, 0x80, 0xFF] {
                let mut bytes = BREAKER_REFERENCE;
                bytes[at] ^= flip;
                if at == 46 && flip == 0x01 {
                    // The bus-off interrupt bit of the flags.
                    assert_eq!(consistency_value(&bytes), FACTORY_CCV);
                } else {
                    assert_ne!(consistency_value(&bytes), FACTORY_CCV, "byte {at} ^ {flip:#04X}");
                }
            }
        }
        // The serial number, MAC ID, data rate and the trailer are not configuration.
        let mut bytes = BREAKER_REFERENCE;
        for at in [16, 43, 44, covered] {
            bytes[at] ^= 0xFF;
        }
        assert_eq!(consistency_value(&bytes), FACTORY_CCV);
    }

    /// A converter on `image` (as a reset builds it), on-line with the explicit connection
    /// allocated by master 0, at the time it returns.
    fn explicit_converter(
        config: ConverterConfig,
        origin: ConfigOrigin,
        image: &[u8],
    ) -> (Converter, Instant) {
        let mut c = Converter::with_image(config, origin, image, Instant::ZERO).unwrap();
        let mut now = Instant::ZERO;
        c.power_on(now);
        let end = now + Duration::from_secs(3);
        while let Some(at) = c.poll_at().filter(|&at| at <= end) {
            now = at.max(now);
            c.handle_timeout(now);
            while c.poll_can_transmit().is_some() {}
        }
        // Allocate the explicit connection (DeviceNet object, protocol §3.4).
        let reply = request(&mut c, now, 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
        assert_eq!(reply, [0x00, 0xCB, 0x00], "allocated");
        (c, now)
    }

    /// The reply on the node's explicit response identifier (MAC 5) to one request frame.
    fn request(c: &mut Converter, now: Instant, id: u16, data: &[u8]) -> std::vec::Vec<u8> {
        c.handle_can_frame(&CanFrame::from_raw(id, data).unwrap(), now);
        let frames: std::vec::Vec<_> = std::iter::from_fn(|| c.poll_can_transmit())
            .filter(|f| f.id().as_raw() == 0x42B)
            .map(|f| f.data().to_vec())
            .collect();
        let [reply] = frames.as_slice() else { panic!("one reply: {frames:02X?}") };
        reply.clone()
    }

    /// Identity attribute 9 read over the bus.
    fn get_ccv(c: &mut Converter, now: Instant) -> u16 {
        let reply = request(c, now, 0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x09]);
        let [0x00, 0x8E, lo, hi] = reply.as_slice() else { panic!("Get attribute 9: {reply:02X?}") };
        u16::from_le_bytes([*lo, *hi])
    }

    /// Downloads `image` through the configuration object (class 0x66) and takes it for storage.
    fn download(c: &mut Converter, now: Instant, image: &[u8]) -> std::vec::Vec<u8> {
        let size = (image.len() as u16).to_le_bytes();
        assert_eq!(request(c, now, 0x42C, &[0x00, 0x4C, 0x66, 0x01, size[0], size[1]]), [0x00, 0xCC]);
        for (k, chunk) in image.chunks(2).enumerate() {
            let offset = ((k * 2) as u16).to_le_bytes();
            let mut req = std::vec![0x00, 0x4D, 0x66, 0x01, offset[0], offset[1]];
            req.extend_from_slice(chunk);
            assert_eq!(request(c, now, 0x42C, &req), [0x00, 0xCD], "chunk {k}");
        }
        assert_eq!(request(c, now, 0x42C, &[0x00, 0x4E, 0x66, 0x01]), [0x00, 0xCE]);
        c.poll_new_image().expect("an accepted image is handed over").to_vec()
    }

    fn other_configuration() -> ConverterConfig {
        let mut config = ConverterConfig::breaker_reference();
        config.input = InputAssembly::WithStatus;
        config
    }

    #[test]
    fn a_download_changes_the_value_at_once_and_a_reset_keeps_it() {
        let factory = ConverterConfig::breaker_reference();
        let (mut c, now) = explicit_converter(factory, ConfigOrigin::FactoryDefault, &BREAKER_REFERENCE);
        assert_eq!(get_ccv(&mut c, now), FACTORY_CCV);

        let image = encoded(&other_configuration());
        let stored = download(&mut c, now, &image);
        assert_eq!(stored, image);
        let changed = get_ccv(&mut c, now);
        assert_ne!(changed, FACTORY_CCV, "the stored configuration changed");
        assert_eq!(changed, consistency_value(&image));
        assert_eq!(c.node().configuration_consistency(), Some(changed));

        // The next reset runs the stored image: the same value.
        let (config, origin) = ConfigOrigin::resolve(&ConverterConfig::breaker_reference(), Some(&stored));
        assert_eq!(origin, ConfigOrigin::Stored);
        let (mut after, now) = explicit_converter(config, origin, &stored);
        assert_eq!(get_ccv(&mut after, now), changed);

        // The same configuration downloaded again: the same value.
        assert_eq!(download(&mut after, now, &stored), stored);
        assert_eq!(get_ccv(&mut after, now), changed);
    }

    #[test]
    fn a_parameter_set_changes_the_value_as_a_download_does() {
        let factory = ConverterConfig::breaker_reference();
        let (mut c, now) = explicit_converter(factory, ConfigOrigin::FactoryDefault, &BREAKER_REFERENCE);
        // Parameter instance 2 (serial parity) := even (protocol §II.4).
        assert_eq!(request(&mut c, now, 0x42C, &[0x00, 0x10, 0x0F, 0x02, 0x01, 2]), [0x00, 0x90]);
        let image = c.poll_new_image().expect("handed over").to_vec();
        assert_eq!(get_ccv(&mut c, now), consistency_value(&image));
        assert_ne!(get_ccv(&mut c, now), FACTORY_CCV);
    }

    #[test]
    fn the_value_is_the_stored_configurations_whatever_the_device_serial_number() {
        // Two devices (own serial numbers) holding the same downloaded image: one value.
        let image = encoded(&other_configuration());
        let values: std::vec::Vec<u16> = [0x0000_0001, 0x7777_0002]
            .into_iter()
            .map(|serial| {
                let (mut config, origin) =
                    ConfigOrigin::resolve(&ConverterConfig::breaker_reference(), Some(&image));
                config.device.identity.serial_number = serial;
                let (mut c, now) = explicit_converter(config, origin, &image);
                get_ccv(&mut c, now)
            })
            .collect();
        assert_eq!(values, [consistency_value(&image); 2]);
    }

    #[rstest]
    #[case::empty(&[])]
    #[case::shorter_than_a_trailer(&[1, 2, 3])]
    #[case::header_only(b"DNCI\x01\x00\x00")]
    fn any_bytes_give_a_value_without_panic(#[case] bytes: &[u8]) {
        let covered = bytes.len().saturating_sub(4);
        assert_eq!(consistency_value(bytes), crc16_reference(&bytes[..covered]));
    }
}
