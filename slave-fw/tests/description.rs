//! The device description file: the shipped examples parse, the reference equals the built-in
//! default, and every kind of mistake gets a precise error (file, key, allowed range).

use rstest::rstest;
use slave_fw::converter::{ConverterConfig, InputAssembly};
use slave_fw::description::DeviceDescription;
use slave_fw::serial::ProfileConfig;
use std::path::Path;

fn example(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("descriptions").join(name)
}

fn reference_text() -> String {
    std::fs::read_to_string(example("breaker.toml")).unwrap()
}

#[test]
fn breaker_example_is_the_built_in_reference() {
    let d = DeviceDescription::load(&example("breaker.toml")).unwrap();
    assert_eq!(d, DeviceDescription::reference());
    assert_eq!(d.converter, ConverterConfig::breaker_reference());
    let device = d.converter.device_config();
    assert_eq!((device.produced_size, device.consumed_size), (18, 8));
}

#[test]
fn modbus_example() {
    let d = DeviceDescription::load(&example("modbus-meter.toml")).unwrap();
    assert_eq!(d.converter.input, InputAssembly::WithStatus);
    let device = d.converter.device_config();
    assert_eq!((device.produced_size, device.consumed_size, device.input_assembly), (14, 4, 101));
    assert_eq!(device.mac_id.as_raw(), 7);
    let ProfileConfig::Modbus(m) = &d.converter.profile else { panic!("modbus profile") };
    assert_eq!(m.scan.len(), 3);
    assert_eq!(m.serial.baud, 19200);
}

#[test]
fn minimal_description_uses_the_presets() {
    let text = r#"
[identity]
vendor_id = 1
device_type = 12
product_code = 9
major_revision = 2
minor_revision = 0
serial_number = 1
product_name = "X"
[network]
mac_id = 63
baud_rate = "125k"
[profile]
kind = "breaker"
"#;
    let d = DeviceDescription::parse(text).unwrap();
    assert_eq!(d.converter.device_config().produced_size, 18);
    assert_eq!(d.converter.device.mac_id.as_raw(), 63);
}

#[rstest]
#[case::mac_out_of_range("mac_id = 5", "mac_id = 64", "network.mac_id: 64 is outside 0..=63")]
#[case::baud("baud_rate = \"250k\"", "baud_rate = \"1M\"", "network.baud_rate: \"1m\" is not one of")]
#[case::vendor_too_big("vendor_id = 0x1234 ", "vendor_id = 0x12345 ", "vendor_id")]
#[case::unknown_key("catalog = \"SDN-1\"", "catalogue = \"SDN-1\"", "unknown field `catalogue`")]
#[case::name_too_long(
    "product_name = \"Serial-DeviceNet Bridge\"",
    "product_name = \"Serial-DeviceNet Bridge with a very long name\"",
    "identity.product_name: 45 characters, allowed 1..=32"
)]
#[case::major_zero(
    "major_revision = 1 ",
    "major_revision = 0 ",
    "identity.major_revision: 0 is outside 1..=127"
)]
#[case::produced_mismatch(
    "produced_size = 18",
    "produced_size = 20",
    "io.produced_size: 20 disagrees with the profile and assembly, which produce 18"
)]
#[case::consumed_mismatch("consumed_size = 8 ", "consumed_size = 4 ", "io.consumed_size: 4 disagrees")]
#[case::stale_timeout(
    "stale_timeout_ms = 3000",
    "stale_timeout_ms = 0",
    "profile.health.stale_timeout_ms: 0 is outside the allowed range 1..=3600000"
)]
#[case::retries("retries = 2", "retries = 11", "retries: 11 is outside the allowed range 0..=10")]
#[case::policy("stale_policy = \"hold_last_value\"", "stale_policy = \"freeze\"", "unknown variant `freeze`")]
#[case::kind("kind = \"breaker\"", "kind = \"profibus\"", "unknown variant `profibus`")]
#[case::syntax("[network]", "[network", "line")]
fn precise_errors(#[case] find: &str, #[case] replace: &str, #[case] expected: &str) {
    let text = reference_text();
    assert!(text.contains(find), "test setup: {find}");
    let err = DeviceDescription::parse(&text.replacen(find, replace, 1)).unwrap_err().to_string();
    assert!(err.contains(expected), "error {err:?} should contain {expected:?}");
}

#[test]
fn modbus_scan_errors_name_the_entry() {
    let text = std::fs::read_to_string(example("modbus-meter.toml")).unwrap();
    let bad = text.replacen("count = 2\noffset = 8", "count = 2\noffset = 6", 1);
    let err = DeviceDescription::parse(&bad).unwrap_err().to_string();
    assert!(err.contains("profile.modbus.scan[1].offset"), "{err}");
    let none = DeviceDescription::parse(&text.replace("[[profile.modbus.scan]]", "[[profile.modbus.other]]"));
    assert!(none.is_err());
}

#[test]
fn missing_file_names_the_file() {
    let err = DeviceDescription::load(Path::new("/nonexistent/device.toml")).unwrap_err().to_string();
    assert!(err.starts_with("/nonexistent/device.toml: cannot read"), "{err}");
}
