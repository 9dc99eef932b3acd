//! `[profile.modbus] valid_bits_offset`: read from the description, written back, carried by the
//! configuration image (and so by the consistency value), and refused with the key named.

use slave_fw::converter::consistency;
use slave_fw::converter::image;
use slave_fw::description::DeviceDescription;
use slave_fw::serial::ProfileConfig;

fn meter() -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("descriptions/modbus-meter.toml");
    std::fs::read_to_string(path).unwrap()
}

fn with_bits(offset: &str) -> String {
    meter().replacen("[profile.modbus]\n", &format!("[profile.modbus]\nvalid_bits_offset = {offset}\n"), 1)
}

#[test]
fn the_key_grows_the_input_image_and_round_trips() {
    let d = DeviceDescription::parse(&with_bits("12")).unwrap();
    let ProfileConfig::Modbus(m) = &d.converter.profile else { panic!("modbus profile") };
    assert_eq!((m.valid_bits_offset, m.input_len), (Some(12), 13));
    // 13 data bytes, then the status byte and the freshness counter.
    assert_eq!(d.converter.device_config().produced_size, 15);
    let written = d.to_toml().unwrap();
    assert!(written.contains("valid_bits_offset = 12"), "{written}");
    assert_eq!(DeviceDescription::parse(&written).unwrap().converter, d.converter);
    let old = DeviceDescription::parse(&meter()).unwrap();
    assert!(!old.to_toml().unwrap().contains("valid_bits_offset"));
}

#[test]
fn the_image_carries_the_key_and_the_consistency_value_sees_it() {
    let with = DeviceDescription::parse(&with_bits("12")).unwrap().converter;
    let bytes = image::encode_to_vec(&with).unwrap();
    assert_eq!(image::decode(&bytes).unwrap(), with);
    let moved = DeviceDescription::parse(&with_bits("13")).unwrap().converter;
    let moved_bytes = image::encode_to_vec(&moved).unwrap();
    assert_eq!(image::decode(&moved_bytes).unwrap(), moved);
    assert_ne!(consistency::consistency_value(&bytes), consistency::consistency_value(&moved_bytes));
    // An image from before the key reads without bits.
    let old = DeviceDescription::parse(&meter()).unwrap().converter;
    let ProfileConfig::Modbus(m) = image::decode(&image::encode_to_vec(&old).unwrap()).unwrap().profile
    else {
        panic!("modbus profile")
    };
    assert_eq!(m.valid_bits_offset, None);
}

#[test]
fn bits_over_a_read_entry_name_the_key_and_line() {
    let err = DeviceDescription::parse(&with_bits("8")).unwrap_err().to_string();
    assert!(
        err.contains("line 26: profile.modbus.valid_bits_offset: overlaps the image bytes of entry 1"),
        "{err}"
    );
    let err = DeviceDescription::parse(&with_bits("70")).unwrap_err().to_string();
    assert!(
        err.contains("profile.modbus.valid_bits_offset: 70 is outside the allowed range 0..=11"),
        "{err}"
    );
}

/// A downloaded image with bits over a read entry is refused, the key named as the device's
/// refusal record carries it.
#[test]
fn an_image_with_overlapping_bits_is_refused_naming_the_key() {
    let mut config = DeviceDescription::parse(&with_bits("12")).unwrap().converter;
    let ProfileConfig::Modbus(m) = &mut config.profile else { panic!("modbus profile") };
    m.valid_bits_offset = Some(8);
    let bytes = image::encode_to_vec(&config).unwrap();
    let err = image::decode(&bytes).unwrap_err();
    let image::ImageError::Invalid(invalid) = err else { panic!("{err:?}") };
    assert_eq!(
        invalid.to_string(),
        "profile.modbus.valid_bits_offset: overlaps the image bytes of entry 1",
        "{invalid:?}"
    );
}
