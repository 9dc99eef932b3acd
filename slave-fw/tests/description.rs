//! The device description file: the shipped examples parse, the reference equals the built-in
//! default, and every kind of mistake gets a precise error (file, key, allowed range).

use rstest::rstest;
use slave_fw::converter::{ConverterConfig, InputAssembly};
use slave_fw::description::DeviceDescription;
use slave_fw::serial::modbus::{Framing, WordOrder, WriteMode};
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
#[case::unknown_key(
    "catalog = \"SDN-1\"",
    "catalogue = \"SDN-1\"",
    "identity.catalogue: unknown key `catalogue`"
)]
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
#[case::inline_table_extra_key(
    "on_idle = \"nothing\"",
    "on_idle = { send = [4], sned = [5] }",
    "profile.sequencer.on_idle: wanted exactly 1 element"
)]
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

/// `framing`: an unknown value names the file, the line and the key; each known value round-trips
/// through the description writer (RTU, the default, is not written).
#[test]
fn modbus_framing_key() {
    let text = std::fs::read_to_string(example("modbus-meter.toml")).unwrap();
    let find = "[profile.modbus]\n";
    let (err, path, bad) =
        load_error("framing.toml", &text, find, "[profile.modbus]\nframing = \"rtu-over-tcp\"\n");
    let line = line_of(&bad, "framing");
    assert!(err.starts_with(&format!("{}: ", path.display())), "{err}");
    assert!(err.contains(&format!("line {line},")), "{err}");
    assert!(
        err.contains("profile.modbus.framing") && err.contains("unknown variant `rtu-over-tcp`"),
        "{err}"
    );
    for (value, framing) in [("rtu", Framing::Rtu), ("ascii", Framing::Ascii), ("tcp", Framing::Tcp)] {
        let d = DeviceDescription::parse(&text.replacen(find, &format!("{find}framing = \"{value}\"\n"), 1))
            .unwrap();
        let ProfileConfig::Modbus(m) = &d.converter.profile else { panic!("not Modbus") };
        assert_eq!(m.framing, framing);
        let written = d.to_toml().unwrap();
        assert_eq!(written.contains("framing = "), framing != Framing::Rtu, "{written}");
        assert_eq!(DeviceDescription::parse(&written).unwrap().converter, d.converter);
    }
}

/// `word_order` on a scan entry: each value reads and round-trips through the writer (the
/// default is not written, so older files read and write as before); on an odd register count
/// the error names the file, the line of the key and the key.
#[test]
fn modbus_word_order_key() {
    let text = std::fs::read_to_string(example("modbus-meter.toml")).unwrap();
    let find = "function = 3\naddress = 100\ncount = 2\n";
    let old = DeviceDescription::parse(&text).unwrap();
    let ProfileConfig::Modbus(m) = &old.converter.profile else { panic!("not Modbus") };
    assert!(m.scan.iter().all(|e| e.word_order == WordOrder::Registers));
    assert!(!old.to_toml().unwrap().contains("word_order"));
    for (value, order) in [
        ("abcd", WordOrder::Abcd),
        ("badc", WordOrder::Badc),
        ("cdab", WordOrder::Cdab),
        ("dcba", WordOrder::Dcba),
        ("registers", WordOrder::Registers),
    ] {
        let d =
            DeviceDescription::parse(&text.replacen(find, &format!("{find}word_order = \"{value}\"\n"), 1))
                .unwrap();
        let ProfileConfig::Modbus(m) = &d.converter.profile else { panic!("not Modbus") };
        assert_eq!(m.scan[1].word_order, order);
        let written = d.to_toml().unwrap();
        assert_eq!(written.contains(&format!("word_order = \"{value}\"")), order != WordOrder::Registers);
        assert_eq!(DeviceDescription::parse(&written).unwrap().converter, d.converter);
    }
    let odd = "function = 3\naddress = 100\ncount = 1\nword_order = \"cdab\"\n";
    let (err, path, bad) = load_error("word-order.toml", &text, find, odd);
    let line = line_of(&bad, "word_order");
    assert_eq!(
        err,
        format!(
            "{}: line {line}: profile.modbus.scan[1].word_order: a 32-bit word order needs function 3, 4 \
             or 16 and an even register count",
            path.display()
        )
    );
    let coils = "function = 1\naddress = 100\ncount = 2\nword_order = \"abcd\"\n";
    let (err, _, _) = load_error("word-order-coils.toml", &text, find, coils);
    assert!(err.contains("profile.modbus.scan[1].word_order: a 32-bit word order needs"), "{err}");
    let (err, _, bad) =
        load_error("word-order-bad.toml", &text, find, &format!("{find}word_order = \"abdc\"\n"));
    let line = line_of(&bad, "word_order");
    assert!(err.contains(&format!("line {line},")) && err.contains("unknown variant `abdc`"), "{err}");
}

/// The schedule keys of a scan entry: they read, round-trip through the writer (defaults are
/// not written), grow the output image to hold a trigger byte, and a key that does not apply is
/// an error naming the file, the line and the key.
#[test]
fn modbus_schedule_keys() {
    let text = std::fs::read_to_string(example("modbus-meter.toml")).unwrap();
    let read = "function = 3\naddress = 100\ncount = 2\n";
    let write = "function = 16\naddress = 16\ncount = 2\n";
    assert!(!DeviceDescription::parse(&text).unwrap().to_toml().unwrap().contains("\nperiod_ms"));
    let scheduled = text.replacen(read, &format!("{read}period_ms = 5000\n"), 1).replacen(
        write,
        &format!("{write}write = \"trigger\"\ntrigger_offset = 6\n"),
        1,
    );
    let d = DeviceDescription::parse(&scheduled).unwrap();
    let ProfileConfig::Modbus(m) = &d.converter.profile else { panic!("not Modbus") };
    assert_eq!(m.scan[1].period_ms, Some(5000));
    assert_eq!((m.scan[2].write, m.scan[2].trigger_offset), (WriteMode::Trigger, Some(6)));
    assert_eq!(m.output_len, 7, "the output image holds the trigger byte");
    let written = d.to_toml().unwrap();
    assert!(written.contains("write = \"trigger\"") && written.contains("trigger_offset = 6"), "{written}");
    assert_eq!(DeviceDescription::parse(&written).unwrap().converter, d.converter);
    let (err, path, bad) = load_error("schedule.toml", &text, read, &format!("{read}write = \"cyclic\"\n"));
    let line = line_of(&bad, "write");
    assert_eq!(
        err,
        format!(
            "{}: line {line}: profile.modbus.scan[1].write: applies to write entries (functions 5, 6, 15, 16) only",
            path.display()
        )
    );
    let (err, _, bad) = load_error(
        "schedule-trigger.toml",
        &text,
        write,
        &format!("{write}write = \"trigger\"\ntrigger_offset = 1\n"),
    );
    let line = line_of(&bad, "trigger_offset");
    assert!(
        err.contains(&format!(
            "line {line}: profile.modbus.scan[2].trigger_offset: overlaps the image bytes of entry 2"
        )),
        "{err}"
    );
    let (err, _, _) = load_error("schedule-period.toml", &text, read, &format!("{read}period_ms = 0\n"));
    assert!(
        err.contains("profile.modbus.scan[1].period_ms: 0 is outside the allowed range 1..=3600000"),
        "{err}"
    );
}

#[test]
fn missing_file_names_the_file() {
    let err = DeviceDescription::load(Path::new("/nonexistent/device.toml")).unwrap_err().to_string();
    assert!(err.starts_with("/nonexistent/device.toml: cannot read"), "{err}");
}

/// `text` with `find` replaced by `replace`, written to a file of its own and loaded: the error,
/// the file and the text written.
fn load_error(name: &str, text: &str, find: &str, replace: &str) -> (String, std::path::PathBuf, String) {
    assert!(text.contains(find), "test setup: {find:?}");
    let bad = text.replacen(find, replace, 1);
    let dir = std::env::temp_dir().join(format!("slave-fw-description-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, &bad).unwrap();
    let err = DeviceDescription::load(&path).map(|_| ()).unwrap_err().to_string();
    (err, path, bad)
}

/// The 1-based line of `text` that sets `key`.
fn line_of(text: &str, key: &str) -> usize {
    let at = text.lines().position(|l| l.starts_with(&format!("{key} ="))).expect("the key is in the text");
    at + 1
}

/// A misspelt key in any table of either shipped description is refused, with the file, the line
/// and the dotted key (issue 33: these tables used to ignore unknown keys).
#[rstest]
#[case::serial(
    "breaker.toml",
    "parity = \"none\"",
    "parity = \"none\"\nparityy = \"even\"",
    "profile.serial.parityy"
)]
#[case::health(
    "breaker.toml",
    "stale_policy = \"hold_last_value\"",
    "stale_policy = \"hold_last_value\"\nstale_polcy = \"clear\"",
    "profile.health.stale_polcy"
)]
#[case::sequencer(
    "breaker.toml",
    "execute_first = true",
    "execute_first = true\nexecute_frist = false",
    "profile.sequencer.execute_frist"
)]
#[case::modbus_serial(
    "modbus-meter.toml",
    "parity = \"even\"",
    "parity = \"even\"\nstopbits = \"two\"",
    "profile.modbus.serial.stopbits"
)]
#[case::modbus_health(
    "modbus-meter.toml",
    "stale_policy = \"clear\"",
    "stale_policy = \"clear\"\nstale_timeout = 5",
    "profile.modbus.health.stale_timeout"
)]
#[case::modbus_scan(
    "modbus-meter.toml",
    "function = 3",
    "function = 3\nfunctions = 4",
    "profile.modbus.scan[1].functions"
)]
#[case::modbus("modbus-meter.toml", "retries = 1", "retry = 1", "profile.modbus.retry")]
#[case::identity("breaker.toml", "catalog = \"SDN-1\"", "catalogue = \"SDN-1\"", "identity.catalogue")]
#[case::top_level("breaker.toml", "[identity]", "vendor = 1\n[identity]", "vendor")]
fn unknown_keys_are_refused_with_file_line_and_key(
    #[case] file: &str,
    #[case] find: &str,
    #[case] replace: &str,
    #[case] key: &str,
) {
    let text = std::fs::read_to_string(example(file)).unwrap();
    // A file of its own per case: the cases run in parallel.
    let name = format!("{}-{file}", key.replace(['.', '[', ']'], "-"));
    let (err, path, bad) = load_error(&name, &text, find, replace);
    let unknown = key.rsplit('.').next().unwrap();
    let line = line_of(&bad, unknown);
    let expected = format!(
        "{}: TOML parse error at line {line}, column 1: {key}: unknown key `{unknown}`",
        path.display()
    );
    assert!(err.starts_with(&expected), "error {err:?} should start with {expected:?}");
}

/// The dotted path of every table header in `text` (`profile.modbus.scan[2]` for the third
/// `[[profile.modbus.scan]]`), with the line it is on (1-based); the top level first, as line 0.
fn tables(text: &str) -> Vec<(String, usize)> {
    let mut found = vec![(String::new(), 0)];
    let mut arrays: std::collections::HashMap<String, usize> = Default::default();
    for (i, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap().trim();
        if let Some(name) = line.strip_prefix("[[").and_then(|l| l.strip_suffix("]]")) {
            let n = arrays.entry(name.to_string()).or_default();
            found.push((format!("{name}[{n}]"), i + 1));
            *n += 1;
        } else if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            found.push((name.to_string(), i + 1));
        }
    }
    found
}

/// A framed description (not the breaker preset): every table of `[profile.framed]` written out.
fn framed_text() -> String {
    let mut d = DeviceDescription::reference();
    let ProfileConfig::Framed(c) = &mut d.converter.profile else { panic!("the reference is framed") };
    c.framing.start = 0x67;
    let text = d.to_toml().unwrap();
    assert!(text.contains("[profile.framed.framing]"), "{text}");
    DeviceDescription::parse(&text).unwrap();
    text
}

/// Every table, at every depth, of every kind of description refuses a key it does not know:
/// an unknown key is put into each table in turn (table headers found in the text, so a table
/// added later is covered too), and the error names the line it is on and its dotted key.
#[test]
fn every_table_at_every_depth_refuses_unknown_keys() {
    let texts = [
        ("breaker.toml", reference_text()),
        ("modbus-meter.toml", std::fs::read_to_string(example("modbus-meter.toml")).unwrap()),
        ("framed.toml", framed_text()),
    ];
    let mut checked = 0;
    for (name, text) in &texts {
        for (table, header_line) in tables(text) {
            let mut lines: Vec<&str> = text.lines().collect();
            lines.insert(header_line, "misspelt_key = 1");
            let bad = lines.join("\n");
            let Err(err) = DeviceDescription::parse(&bad).map(|_| ()) else {
                panic!("{name}: an unknown key in [{table}] was accepted");
            };
            let err = err.to_string();
            let key =
                if table.is_empty() { "misspelt_key".to_string() } else { format!("{table}.misspelt_key") };
            let expected = format!(
                "TOML parse error at line {}, column 1: {key}: unknown key `misspelt_key`",
                header_line + 1
            );
            assert!(err.starts_with(&expected), "{name}: error {err:?} should start with {expected:?}");
            checked += 1;
        }
    }
    // breaker: 7 tables and the top level; modbus: 9 and the top level; framed: at least 8.
    assert!(checked >= 25, "only {checked} tables found");
}
