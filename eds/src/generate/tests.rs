use super::*;
use rstest::rstest;
use slave_fw::converter::SETTINGS_CLASS;
use slave_fw::serial::modbus::WriteMode;

#[rstest]
#[case::adapter(0x0C, "Communications Adapter")]
#[case::generic(0x00, "Generic Device")]
#[case::vendor(0x64, "Vendor Specific")]
#[case::unknown(0x0D, "Device Type 0x0D")]
#[case::wide(0x1234, "Device Type 0x1234")]
fn device_type_names(#[case] code: u16, #[case] name: &str) {
    assert_eq!(device_type_name(code), name);
}

#[rstest]
#[case::one(12, 1, "byte 12")]
#[case::many(0, 8, "bytes 0-7")]
fn byte_ranges(#[case] start: usize, #[case] len: usize, #[case] text: &str) {
    assert_eq!(bytes(start, len), text);
}

#[test]
fn reference_description_checks_clean() {
    let text = generate_text(&DeviceDescription::reference(), &GenerateOptions::default());
    let report = crate::check_str(&text);
    assert!(report.diagnostics.is_empty(), "{report}");
}

/// The reference (framed) description producing `status_len` bytes (plain input assembly).
fn framed_producing(status_len: u8) -> DeviceDescription {
    let mut description = DeviceDescription::reference();
    if let ProfileConfig::Framed(c) = &mut description.converter.profile {
        c.status_len = status_len;
    }
    description.converter.input = InputAssembly::Plain;
    description
}

/// The strobe response is min(P, 8) bytes of the input assembly: its own `Input2` above 8
/// bytes, `Input1` itself up to 8 (docs/src/reference/io-connections.md).
#[rstest]
#[case::breaker(18, 18, Some(8))]
#[case::nine(9, 9, Some(8))]
#[case::eight(8, 8, None)]
#[case::small(3, 3, None)]
fn the_strobe_input_is_min_p_8(#[case] status_len: u8, #[case] p: u32, #[case] second: Option<u32>) {
    let eds = generate(&framed_producing(status_len), &GenerateOptions::default());
    let io = eds.io_info.unwrap();
    let input1 = &io.inputs[&1];
    assert_eq!(input1.size, Some(p));
    let strobe = io.strobe.as_ref().unwrap();
    assert_eq!(strobe.default_output, Some(0), "the strobe command is not an output assembly");
    match second {
        Some(size) => {
            let input2 = &io.inputs[&2];
            assert_eq!((input2.size, input2.bits), (Some(size), Some(size * 8)));
            assert_eq!(input2.mask, Some(ConnectionMask(ConnectionMask::STROBE)));
            assert_eq!(input2.path, input1.path, "the first bytes of the same assembly");
            assert_eq!(input1.mask, Some(OUTPUT_CONNECTIONS), "Input1 is too large for a strobe");
            assert_eq!(strobe.default_input, Some(2));
        }
        None => {
            assert_eq!(io.inputs.len(), 1);
            assert_eq!(input1.mask, Some(POLL_STROBE_COMPATIBLE));
            assert_eq!(strobe.default_input, Some(1));
        }
    }
    let text = generate_text(&framed_producing(status_len), &GenerateOptions::default());
    let report = crate::check_str(&text);
    assert!(report.diagnostics.is_empty(), "{report}");
}

#[test]
fn every_offered_connection_is_announced_poll_by_default() {
    let io = generate(&DeviceDescription::reference(), &GenerateOptions::default()).io_info.unwrap();
    assert_eq!(io.default, Some(ConnectionMask(ConnectionMask::POLL)));
    let masks =
        [&io.poll, &io.strobe, &io.cos, &io.cyclic].map(|i| i.as_ref().unwrap().compatible.unwrap().0);
    assert_eq!(masks, [0x000F, 0x000F, 0x0007, 0x000B], "as the Hilscher files of the corpus");
    assert_eq!(io.outputs[&1].mask, Some(ConnectionMask(0x000D)));
    for info in [&io.poll, &io.cos, &io.cyclic] {
        let info = info.as_ref().unwrap();
        assert_eq!((info.default_input, info.default_output), (Some(1), Some(1)));
    }
    assert!(eds_has_no_connection_manager(&DeviceDescription::reference()));
}

fn eds_has_no_connection_manager(description: &DeviceDescription) -> bool {
    let text = generate_text(description, &GenerateOptions::default());
    !text.to_ascii_lowercase().contains("[connection manager]")
}

#[test]
fn parameter_numbers_and_groups_cover_each_other() {
    let eds = generate(&DeviceDescription::reference(), &GenerateOptions::default());
    let params: Vec<u32> = eds.params().map(|(n, _)| n).collect();
    let total = FIRST_LINK_PARAM - 1 + LINK_PARAM_COUNT;
    assert_eq!(params, (1..=total).collect::<Vec<_>>());
    let mut grouped: Vec<u32> = eds.groups().flat_map(|(_, g)| g.params.clone()).collect();
    grouped.sort_unstable();
    assert_eq!(grouped, params, "every parameter is in exactly one group");
}

#[rstest]
#[case::rtu(Framing::Rtu, None)]
#[case::ascii(Framing::Ascii, Some("; Modbus ASCII"))]
#[case::tcp(Framing::Tcp, Some("; Modbus TCP"))]
fn the_assembly_help_names_the_framing(#[case] framing: Framing, #[case] named: Option<&str>) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../slave-fw/descriptions/modbus-meter.toml");
    let mut description = DeviceDescription::load(&path).unwrap();
    let ProfileConfig::Modbus(m) = &mut description.converter.profile else { panic!("not Modbus") };
    m.framing = framing;
    let help = input_help(&description);
    match named {
        Some(text) => assert!(help.contains(text), "{help}"),
        None => assert!(!help.contains("Modbus ASCII") && !help.contains("Modbus TCP"), "{help}"),
    }
}

#[rstest]
#[case::registers(WordOrder::Registers, None)]
#[case::abcd(WordOrder::Abcd, Some("(function 3, 32-bit values sent ABCD)"))]
#[case::badc(WordOrder::Badc, Some("(function 3, 32-bit values sent BADC)"))]
#[case::cdab(WordOrder::Cdab, Some("(function 3, 32-bit values sent CDAB)"))]
#[case::dcba(WordOrder::Dcba, Some("(function 3, 32-bit values sent DCBA)"))]
fn the_assembly_help_names_the_word_order(#[case] order: WordOrder, #[case] named: Option<&str>) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../slave-fw/descriptions/modbus-meter.toml");
    let mut description = DeviceDescription::load(&path).unwrap();
    let ProfileConfig::Modbus(m) = &mut description.converter.profile else { panic!("not Modbus") };
    // Entry 1 reads holding registers 100-101 into input bytes 8-11.
    m.scan[1].word_order = order;
    let help = input_help(&description);
    match named {
        Some(text) => {
            assert!(help.contains(&format!("unit 1 holding registers 100-101 {text}")), "{help}")
        }
        None => assert!(!help.contains("32-bit"), "{help}"),
    }
}

#[test]
fn the_assembly_help_names_each_entry_schedule() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../slave-fw/descriptions/modbus-meter.toml");
    let mut description = DeviceDescription::load(&path).unwrap();
    assert!(output_help(&description).ends_with("; written when they change"));
    let ProfileConfig::Modbus(m) = &mut description.converter.profile else { panic!("not Modbus") };
    // Entry 1 reads holding registers 100-101; entry 2 writes holding registers 16-17 from
    // output bytes 0-3.
    m.scan[1].period_ms = Some(5000);
    m.scan[2].write = WriteMode::Trigger;
    m.scan[2].trigger_offset = Some(4);
    m.output_len = 5;
    description.converter.profile.validate().unwrap();
    let input = input_help(&description);
    assert!(input.contains("unit 1 holding registers 100-101 (function 3, read every 5000 ms)"), "{input}");
    let output = output_help(&description);
    assert!(
        output
            .contains("unit 1 holding registers 16-17 (function 16, sent once per change of output byte 4)"),
        "{output}"
    );
    assert!(!output.contains("written when they change"), "{output}");
    assert!(output.ends_with("; byte 4: trigger byte, each change of value sends the entries it names"));
}

#[rstest]
#[case::breaker("breaker")]
#[case::modbus_meter("modbus-meter")]
fn settings_parameters_point_at_the_parameter_object(#[case] name: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(format!("../slave-fw/descriptions/{name}.toml"));
    let description = DeviceDescription::load(&path).unwrap();
    let eds = generate(&description, &GenerateOptions::default());
    let class = eds.param_class.as_ref().unwrap();
    assert_eq!((class.max_inst, class.descriptor, class.cfg_assembly), (Some(9), Some(0x0B), Some(0)));
    let modbus = matches!(description.converter.profile, ProfileConfig::Modbus(_));
    for d in &PARAMETERS {
        let n = u32::from(d.parameter.instance());
        let param = eds.param(n).unwrap();
        // protocol §II.4.4: `6,"20 0F 24 NN 30 01"`.
        assert_eq!(param.link_path_size, Some(6));
        assert_eq!(param.link_path, Some(LinkPath::Bytes(vec![0x20, 0x0F, 0x24, n as u8, 0x30, 0x01])));
        assert_eq!(
            (param.name.as_str(), param.units.as_str(), param.help.as_str()),
            (d.name, d.units, d.help)
        );
        assert_eq!(param.data_type, Some(data_type(d.data_type)), "Param{n}");
        assert_eq!(param.data_size, Some(d.data_type.size() as u32), "Param{n}");
        assert_eq!(param.min, Some(Value::Int(d.min.into())), "Param{n}");
        assert_eq!(param.max, Some(Value::Int(d.max.into())), "Param{n}");
        let default = d.parameter.read(&description.converter);
        assert_eq!(param.default, Some(Value::Int(default.into())), "Param{n}");
        let read_only = d.parameter == Parameter::PollPeriod && !modbus;
        assert_eq!(param.descriptor.unwrap().read_only(), read_only, "Param{n}");
        assert_eq!(eds.enum_strings(n).is_some(), !matches!(n, 1 | 4 | 7 | 8 | 9), "Param{n}");
    }
    for (a, n) in SETTINGS_PARAMS.into_iter().zip(FIRST_SETTINGS_PARAM..) {
        let path = eds.param(n).and_then(|p| p.link_path.as_ref()).and_then(LinkPath::attribute).unwrap();
        assert_eq!((path.class, path.instance, path.attribute), (SETTINGS_CLASS, 1, Some(u16::from(a.id()))));
        assert!(eds.param(n).unwrap().descriptor.unwrap().read_only());
    }
}

#[test]
fn programmable_switches_make_the_mac_id_settable() {
    let mut description = DeviceDescription::reference();
    description.converter.device.switches.programmable = true;
    let eds = generate(&description, &GenerateOptions::default());
    let mac = eds.param(FIRST_DEVICENET_PARAM).unwrap();
    assert!(!mac.descriptor.unwrap().read_only());
    assert!(mac.help.contains("program position"));
}

#[test]
fn vendor_parameters_are_the_attribute_tables() {
    let eds = generate(&DeviceDescription::reference(), &GenerateOptions::default());
    let settings = SETTINGS_PARAMS.into_iter().zip(FIRST_SETTINGS_PARAM..).map(|(a, n)| (n, a.spec()));
    let link = LinkAttribute::ALL.map(|a| (FIRST_LINK_PARAM + u32::from(a.id()) - 1, a.spec()));
    for (n, spec) in settings.chain(link) {
        let param = eds.param(n).unwrap();
        assert_eq!((param.name.as_str(), param.units.as_str()), (spec.name, spec.units), "Param{n}");
        let path = param.link_path.as_ref().and_then(LinkPath::attribute).unwrap();
        assert_eq!((path.class, path.attribute), (spec.class, Some(u16::from(spec.id))));
        assert_eq!(param.data_size, Some(spec.data_type.size() as u32), "Param{n}");
        let monitor = param.descriptor.unwrap().0 & Descriptor::MONITOR != 0;
        assert_eq!(monitor, spec.access == Access::GetMonitor, "Param{n}");
    }
}
