//! The generator on the shipped device descriptions: golden files compared byte for byte, the
//! round trip generate -> parse -> model against what the description says, and `check`.
//!
//! `UPDATE_GOLDEN=1 cargo test -p eds --test generate` rewrites the golden files in
//! `tests/golden/` from the current generator; review the diff before committing it.

use eds::generate::{
    generate, generate_text, GenerateOptions, DEFAULT_DATE, FIRST_DEVICENET_PARAM, FIRST_LINK_PARAM,
    FIRST_UNIT_PARAM, PARAMS_PER_UNIT,
};
use eds::model::Eds;
use eds::value::{ConnectionMask, DataType, Date, Descriptor, LinkPath, Revision, Value};
use rstest::rstest;
use slave_fw::converter::{PARAMETER_CLASS, SERIAL_LINK_CLASS, SETTINGS_CLASS, UNITS_CLASS};
use slave_fw::description::DeviceDescription;
use slave_fw::serial::{IdleAction, Parity, ProfileConfig, StalePolicy, StopBits};
use std::path::PathBuf;

fn description_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../slave-fw/descriptions").join(format!("{name}.toml"))
}

fn golden_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden").join(format!("{name}.eds"))
}

fn description(name: &str) -> DeviceDescription {
    DeviceDescription::load(&description_path(name)).unwrap()
}

fn options(name: &str) -> GenerateOptions {
    GenerateOptions { source: Some(format!("{name}.toml")), ..GenerateOptions::default() }
}

fn text(name: &str) -> String {
    generate_text(&description(name), &options(name))
}

#[rstest]
#[case::breaker("breaker")]
#[case::modbus_meter("modbus-meter")]
fn matches_the_golden_file(#[case] name: &str) {
    let generated = text(name);
    let path = golden_path(name);
    if std::env::var_os("UPDATE_GOLDEN").is_some_and(|v| v == "1") {
        std::fs::write(&path, &generated).unwrap();
        return;
    }
    let golden = std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (UPDATE_GOLDEN=1 writes it)", path.display()));
    if generated != golden {
        let line = generated.lines().zip(golden.lines()).position(|(a, b)| a != b);
        let line = line.unwrap_or_else(|| generated.lines().count().min(golden.lines().count()));
        panic!(
            "{} differs from the generator's output at line {}:\n  golden:    {:?}\n  generated: {:?}\n\
             (UPDATE_GOLDEN=1 cargo test -p eds --test generate rewrites it)",
            path.display(),
            line + 1,
            golden.lines().nth(line),
            generated.lines().nth(line),
        );
    }
}

#[rstest]
#[case::breaker("breaker")]
#[case::modbus_meter("modbus-meter")]
fn checks_without_diagnostics(#[case] name: &str) {
    let report = eds::check_str(&text(name));
    assert!(report.diagnostics.is_empty(), "{report}");
}

#[rstest]
#[case::breaker("breaker")]
#[case::modbus_meter("modbus-meter")]
fn reads_back_as_the_generated_model(#[case] name: &str) {
    let model = generate(&description(name), &options(name));
    assert_eq!(eds::parse_str(&text(name)).unwrap(), model);
}

/// Parameter `n`'s default, as an integer.
fn default(eds: &Eds, n: u32) -> i128 {
    eds.param(n).and_then(|p| p.default.as_ref()).and_then(Value::as_int).unwrap()
}

#[rstest]
#[case::breaker("breaker")]
#[case::modbus_meter("modbus-meter")]
fn model_equals_the_description(#[case] name: &str) {
    let d = description(name);
    let eds = eds::parse_str(&text(name)).unwrap();
    let config = d.converter.device_config();
    let id = &config.identity;

    let device = eds.device.as_ref().unwrap();
    assert_eq!(device.vend_code, Some(id.vendor_id));
    assert_eq!(device.vend_name.as_deref(), Some(d.vendor_name.as_str()));
    assert_eq!(device.prod_type, Some(id.device_type));
    assert_eq!(device.prod_code, Some(id.product_code));
    assert_eq!((device.maj_rev, device.min_rev), (Some(id.major_revision), Some(id.minor_revision)));
    assert_eq!(device.prod_name.as_deref(), Some(id.product_name.as_str()));
    assert_eq!(device.catalog.as_deref(), Some(d.catalog.as_str()));

    // Poll, bit-strobe, COS and cyclic, as the node offers them (docs/src/reference/io-connections.md).
    let io = eds.io_info.as_ref().unwrap();
    assert_eq!(io.default, Some(ConnectionMask(ConnectionMask::POLL)));
    let poll = io.poll.as_ref().unwrap();
    assert_eq!(
        (poll.compatible, poll.default_input, poll.default_output),
        (Some(ConnectionMask(0x000F)), Some(1), Some(1))
    );
    let (input, output) = (&io.inputs[&1], &io.outputs[&1]);
    assert_eq!(input.size, Some(u32::from(config.produced_size)));
    assert_eq!(output.size, Some(u32::from(config.consumed_size)));
    // Both descriptions produce more than 8 bytes: the strobe response is Input2, the first 8.
    let strobe = io.strobe.as_ref().unwrap();
    let strobe_input = &io.inputs[&strobe.default_input.unwrap()];
    let strobe_size = devicenet::slave::strobe_produced_size(config.produced_size);
    assert_eq!(
        (strobe_input.size, strobe_input.path.clone()),
        (Some(u32::from(strobe_size)), input.path.clone())
    );
    for (info, n) in [(&io.cos, 1), (&io.cyclic, 1)] {
        let info = info.as_ref().unwrap();
        assert_eq!((info.default_input, info.default_output), (Some(n), Some(n)));
    }
    assert_eq!((input.mask, output.mask), (Some(ConnectionMask(0x000D)), Some(ConnectionMask(0x000D))));
    let assembly = |e: &eds::model::IoEntry| {
        e.path.as_ref().and_then(LinkPath::attribute).map(|a| (a.class, a.instance, a.attribute))
    };
    assert_eq!(assembly(input), Some((4, u16::from(config.input_assembly), Some(3))));
    assert_eq!(assembly(output), Some((4, 150, Some(3))));

    // Parameters 1-9: Parameter instances 1-9; 10-12: the settings object's attributes 9-11;
    // defaults from the description.
    let (serial, health, timeout, retries, period, on_idle, on_fault, kind) = match &d.converter.profile {
        ProfileConfig::Framed(c) => (
            c.serial,
            c.health,
            c.sequencer.response_timeout_ms,
            c.sequencer.retries,
            0,
            &c.sequencer.on_idle,
            &c.sequencer.on_fault,
            0,
        ),
        ProfileConfig::Modbus(c) => (
            c.serial,
            c.health,
            c.response_timeout_ms,
            c.retries,
            c.poll_period_ms,
            &c.on_idle,
            &c.on_fault,
            1,
        ),
    };
    let sends = |a: &IdleAction| i128::from(matches!(a, IdleAction::Send(_)));
    let expected: [i128; 12] = [
        serial.baud.into(),
        match serial.parity {
            Parity::None => 0,
            Parity::Odd => 1,
            Parity::Even => 2,
        },
        match serial.stop_bits {
            StopBits::One => 1,
            StopBits::Two => 2,
        },
        health.stale_timeout_ms.into(),
        match health.stale_policy {
            StalePolicy::HoldLastValue => 0,
            StalePolicy::Clear => 1,
        },
        config.input_assembly.into(),
        timeout.into(),
        retries.into(),
        period.into(),
        sends(on_idle),
        sends(on_fault),
        kind,
    ];
    for (n, want) in (1..).zip(expected) {
        assert_eq!(default(&eds, n), want, "Param{n} default");
        let path = eds.param(n).unwrap().link_path.as_ref().and_then(LinkPath::attribute).unwrap();
        let expected = if n <= 9 {
            (PARAMETER_CLASS, n as u16, Some(1))
        } else {
            (SETTINGS_CLASS, 1, Some(n as u16 - 1))
        };
        assert_eq!((path.class, path.instance, path.attribute), expected, "Param{n}");
    }
    assert_eq!(default(&eds, FIRST_DEVICENET_PARAM), i128::from(config.mac_id.as_raw()));
    assert_eq!(default(&eds, FIRST_DEVICENET_PARAM + 1), i128::from(config.baud_rate.attribute_value()));
    assert_eq!(default(&eds, FIRST_DEVICENET_PARAM + 2), i128::from(config.bus_off_interrupt));

    // Every parameter: sized by its type, within its range, read-only unless it is a Parameter
    // object instance (the poll period of a framed instrument excepted) or the bus-off interrupt;
    // the statistics are monitor parameters of the serial link object.
    for (n, p) in eds.params() {
        assert_eq!(p.data_size, p.data_type.and_then(DataType::fixed_size), "Param{n}");
        let (min, max) = (
            p.min.as_ref().and_then(Value::as_int).unwrap(),
            p.max.as_ref().and_then(Value::as_int).unwrap(),
        );
        assert!((min..=max).contains(&default(&eds, n)), "Param{n}");
        let descriptor = p.descriptor.unwrap();
        assert_eq!(
            descriptor.read_only(),
            n != FIRST_DEVICENET_PARAM + 2 && (n > 9 || (n == 9 && kind == 0)),
            "Param{n} descriptor {descriptor:?}"
        );
        assert_eq!(descriptor.has(Descriptor::ENUMERATED_STRINGS), eds.enum_strings(n).is_some(), "Param{n}");
        let path = p.link_path.as_ref().and_then(LinkPath::attribute).unwrap();
        if n >= FIRST_UNIT_PARAM {
            // The Modbus unit table: instance k + 1 for the k-th unit, attributes 2-5.
            let k = n - FIRST_UNIT_PARAM;
            assert!(descriptor.monitor(), "Param{n}");
            assert_eq!(
                (path.class, path.instance, path.attribute),
                (UNITS_CLASS, (k / PARAMS_PER_UNIT + 1) as u16, Some((k % PARAMS_PER_UNIT + 2) as u16)),
                "Param{n}"
            );
        } else if n >= FIRST_LINK_PARAM {
            assert!(descriptor.monitor(), "Param{n}");
            assert_eq!(
                (path.class, path.attribute),
                (SERIAL_LINK_CLASS, Some((n - FIRST_LINK_PARAM + 1) as u16))
            );
        }
    }
    // One state and three counters per distinct unit of a Modbus scan list; none for a framed
    // instrument.
    let units = match &d.converter.profile {
        ProfileConfig::Framed(_) => 0,
        ProfileConfig::Modbus(m) => {
            let mut distinct: Vec<u8> = m.scan.iter().map(|e| e.unit).collect();
            distinct.sort_unstable();
            distinct.dedup();
            distinct.len() as u32
        }
    };
    let last = eds.params().map(|(n, _)| n).max().unwrap();
    assert_eq!(last, FIRST_UNIT_PARAM + units * PARAMS_PER_UNIT - 1, "the last parameter");
    assert!(eds.enum_par.is_none(), "one enum dialect: EnumN in [Params]");
}

#[test]
fn output_is_deterministic_and_dated_by_the_options() {
    let d = description("breaker");
    let first = generate_text(&d, &GenerateOptions::default());
    assert_eq!(first, generate_text(&d.clone(), &GenerateOptions::default()));
    assert!(first.contains(&format!("CreateDate = {DEFAULT_DATE};")));

    let options = GenerateOptions {
        date: Date { year: 2026, month: 3, day: 14 },
        revision: Revision { major: 2, minor: 1 },
        source: None,
    };
    let dated = generate_text(&d, &options);
    assert!(dated.contains("CreateDate = 03-14-2026;") && dated.contains("ModDate = 03-14-2026;"));
    assert!(dated.contains("Revision = 2.1;"));
    let strip = |t: &str| {
        t.lines()
            .filter(|l| !l.contains("Date =") && !l.contains("Revision =") && !l.starts_with('$'))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(strip(&first), strip(&dated), "only the dates, revision and header change");
}

#[test]
fn the_built_in_reference_is_the_breaker_description() {
    let reference = generate_text(&DeviceDescription::reference(), &options("breaker"));
    assert_eq!(reference, text("breaker"));
}
