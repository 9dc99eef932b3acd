//! The generated EDS against the soft slave on the simulated bus: what the EDS says (identity,
//! sizes, parameters) is what the device running the same description reports, and
//! `check_device` names every field an edited EDS gets wrong.

use can_io::bus::{Bitrate, BusSpec};
use can_io::sim::{PowerOn, SimBus};
use converter_sim::device::SoftSlave;
use devicenet::MacId;
use eds::generate::{generate_text, GenerateOptions};
use eds::Eds;
use eds_tool::device::DeviceError;
use eds_tool::device::{check_device, check_on_bus, BusOptions, CheckOptions, Verdict};
use master_core::error::MasterError;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use rstest::rstest;
use slave_fw::description::DeviceDescription;
use std::path::PathBuf;

fn description_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../slave-fw/descriptions").join(format!("{name}.toml"))
}

fn description(name: &str) -> DeviceDescription {
    DeviceDescription::load(&description_path(name)).unwrap()
}

/// The generated EDS text of a shipped description.
fn eds_text(name: &str) -> String {
    generate_text(&description(name), &GenerateOptions::default())
}

/// The simulated bus with the soft slave running description `name` at its own MAC ID.
fn sim(name: &str) -> BusOptions {
    BusOptions {
        bus: BusSpec::Sim,
        bitrate: None,
        mac: description(name).converter.device.mac_id,
        slave_config: Some(description_path(name)),
    }
}

fn check(eds: &Eds, name: &str, params: bool) -> eds_tool::DeviceReport {
    let options = CheckOptions { params, ..CheckOptions::default() };
    check_on_bus(eds, &sim(name), &options, None).unwrap()
}

/// The bring-up of `dnet-master connect` (not the check's code) against the soft slave: the
/// identity and sizes the device reports.
#[rstest]
#[case::breaker("breaker")]
#[case::modbus_meter("modbus-meter")]
fn generated_identity_and_sizes_equal_what_the_soft_slave_reports(#[case] name: &str) {
    let d = description(name);
    let mac = d.converter.device.mac_id;
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(SoftSlave::new(d.converter.clone()).unwrap()), PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let summary = Master::new(&mut session, MasterConfig::default())
        .connect(&ConnectOptions { target: mac, polls: 1, ..ConnectOptions::default() })
        .unwrap();
    assert_eq!(session.failures(), 0);

    let eds = eds::parse_str(&eds_text(name)).unwrap();
    let device = eds.device.as_ref().unwrap();
    let io = eds.io_info.as_ref().unwrap();
    assert_eq!(summary.vendor_id, device.vend_code);
    assert_eq!(summary.device_type, device.prod_type);
    assert_eq!(summary.product_code, device.prod_code);
    assert_eq!(summary.produced_size.map(u32::from), io.inputs[&1].size);
    assert_eq!(summary.consumed_size.map(u32::from), io.outputs[&1].size);
    assert_eq!(
        summary.last_input.map(|i| i.len() as u32),
        io.inputs[&1].size,
        "the poll response has the EDS size"
    );
}

#[rstest]
#[case::breaker("breaker")]
#[case::modbus_meter("modbus-meter")]
fn check_device_agrees_with_the_generated_eds(#[case] name: &str) {
    let eds = eds::parse_str(&eds_text(name)).unwrap();
    let report = check(&eds, name, false);
    for f in &report.findings {
        assert_eq!(f.verdict, Verdict::Agree, "not even a note:\n{report}");
    }
    assert!(report.agrees(), "{report}");
    for what in [
        "vendor ID",
        "device type",
        "product code",
        "major revision",
        "produced size",
        "consumed size",
        "bit-strobe connection",
        "bit-strobe produced size",
        "change-of-state connection",
        "change-of-state produced size",
        "cyclic connection",
        "cyclic produced size",
    ] {
        assert!(report.finding(what).is_some(), "{what} is checked:\n{report}");
    }
    let strobe = report.finding("bit-strobe connection").unwrap();
    assert_eq!(
        (strobe.eds.as_str(), strobe.device.as_str()),
        ("announced (StrobeInfo, PollInfo mask, COSInfo mask, CyclicInfo mask, Input2 mask)", "accepts")
    );
    for kind in ["change-of-state", "cyclic"] {
        let f = report.finding(&format!("{kind} connection")).unwrap();
        assert_eq!(f.device, "accepts", "{report}");
    }
    // The strobe response carries min(P, 8) bytes (Input2), COS and cyclic the whole input (Input1).
    let input1 = eds.io_info.as_ref().unwrap().inputs[&1].size.unwrap();
    let sizes = [
        ("bit-strobe produced size (Input2)", 8.min(input1)),
        ("change-of-state produced size (Input1)", input1),
        ("cyclic produced size (Input1)", input1),
    ];
    for (what, size) in sizes {
        let f = report.finding(what).unwrap_or_else(|| panic!("{what}:\n{report}"));
        assert_eq!((f.eds.clone(), f.device.clone()), (size.to_string(), size.to_string()), "{report}");
    }
}

/// Every parameter's link path is an attribute the device serves, of the parameter's size, and
/// holds the parameter's default (the description's value): the EDS and the device agree.
#[rstest]
#[case::breaker("breaker")]
#[case::modbus_meter("modbus-meter")]
fn every_parameter_is_served_with_its_default(#[case] name: &str) {
    let eds = eds::parse_str(&eds_text(name)).unwrap();
    let report = check(&eds, name, true);
    for (n, _) in eds.params() {
        let finding =
            report.finding(&format!("Param{n} ")).unwrap_or_else(|| panic!("Param{n} read:\n{report}"));
        assert_eq!(finding.verdict, Verdict::Agree, "Param{n}:\n{report}");
    }
    assert!(report.agrees(), "{report}");
}

#[rstest]
#[case::product_code("        ProdCode = 1;", "        ProdCode = 7;", &["product code (ProdCode)"], "7", "1")]
#[case::vendor(
    "        VendCode = 4660;",
    "        VendCode = 283;",
    &["vendor ID (VendCode)"],
    "0x011B",
    "0x1234"
)]
#[case::device_type("        ProdType = 12;", "        ProdType = 0;", &["device type (ProdType)"], "0", "12")]
#[case::major_revision("        MajRev = 1;", "        MajRev = 2;", &["major revision (MajRev)"], "2", "1")]
#[case::produced_size(
    "                18,                       $ size in bytes",
    "                20,                       $ size in bytes",
    // Input1 is also the default input of COSInfo and CyclicInfo: Connection 4 produces it.
    &["produced size (Input1)", "change-of-state produced size (Input1)", "cyclic produced size (Input1)"],
    "20",
    "18"
)]
#[case::consumed_size(
    "        Output1 =\n                8,",
    "        Output1 =\n                6,",
    &["consumed size (Output1)"],
    "6",
    "8"
)]
#[case::produced_path(
    "\"20 04 24 64 30 03\",      $ path\n                \"bytes 0-17",
    "\"20 04 24 65 30 03\",      $ path\n                \"bytes 0-17",
    &["produced path (Input1)"],
    "\"20 04 24 65 30 03\" (assembly 101)",
    "\"20 04 24 64 30 03\" (assembly 100)"
)]
#[case::strobe_produced_size(
    "                8,                        $ size in bytes\n                64,                       $ bits used\n                0x0002,",
    "                6,                        $ size in bytes\n                64,                       $ bits used\n                0x0002,",
    &["bit-strobe produced size (Input2)"],
    "6",
    "8"
)]
fn an_edited_eds_fails_naming_the_field(
    #[case] find: &str,
    #[case] replace: &str,
    #[case] what: &[&str],
    #[case] eds_value: &str,
    #[case] device_value: &str,
) {
    let text = eds_text("breaker");
    assert_eq!(text.matches(find).count(), 1, "{find:?} is in the generated EDS once");
    let eds = eds::parse_str(&text.replacen(find, replace, 1)).unwrap();
    let report = check(&eds, "breaker", false);
    assert!(!report.agrees());
    let wrong: Vec<String> = report.disagreements().map(|f| f.what.clone()).collect();
    assert_eq!(wrong, what, "{report}");
    for what in what {
        let finding = report.findings.iter().find(|f| f.what == *what).unwrap();
        assert_eq!((finding.eds.as_str(), finding.device.as_str()), (eds_value, device_value));
        assert!(
            report
                .to_string()
                .contains(&format!("disagreement: {what}: EDS {eds_value}, device {device_value}")),
            "{report}"
        );
    }
}

#[test]
fn a_missing_key_disagrees() {
    let text = eds_text("breaker").replacen("        ProdCode = 1;\n", "", 1);
    let report = check(&eds::parse_str(&text).unwrap(), "breaker", false);
    let finding = report.finding("product code").unwrap();
    assert_eq!((finding.eds.as_str(), finding.verdict), ("(missing)", Verdict::Disagree));
}

/// An EDS that leaves a connection type out, which the device offers: its acceptance is a note,
/// and with no `...Info` entry there is no size to compare (the unit tests of `connection_finding`
/// cover a refusal).
#[rstest]
#[case::strobe("bit-strobe connection", "StrobeInfo", 0x0002)]
#[case::cos("change-of-state connection", "COSInfo", 0x0004)]
#[case::cyclic("cyclic connection", "CyclicInfo", 0x0008)]
fn connection_types_are_compared_with_the_allocation(
    #[case] what: &str,
    #[case] key: &str,
    #[case] bit: u16,
) {
    let mut eds = eds::parse_str(&eds_text("breaker")).unwrap();
    let io = eds.io_info.as_mut().unwrap();
    match key {
        "StrobeInfo" => io.strobe = None,
        "COSInfo" => io.cos = None,
        _ => io.cyclic = None,
    }
    let masks = [&mut io.poll, &mut io.strobe, &mut io.cos, &mut io.cyclic]
        .into_iter()
        .filter_map(|i| i.as_mut().and_then(|i| i.compatible.as_mut()))
        .chain(io.inputs.values_mut().chain(io.outputs.values_mut()).filter_map(|e| e.mask.as_mut()));
    for mask in masks {
        mask.0 &= !bit;
    }
    let report = check(&eds, "breaker", false);
    let finding = report.finding(what).unwrap();
    assert_eq!(finding.eds, "not announced");
    assert_eq!((finding.device.as_str(), finding.verdict), ("accepts", Verdict::Note), "{report}");
    let kind = what.trim_end_matches(" connection");
    assert!(report.finding(&format!("{kind} produced size")).is_none(), "{report}");
    assert!(report.agrees(), "{report}");
}

#[test]
fn a_vendor_eds_lists_every_disagreement() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_dns_v5_extended.eds");
    let eds = eds::read_file(path).unwrap();
    let report = check(&eds, "breaker", false);
    let wrong: Vec<String> = report.disagreements().map(|f| f.what.clone()).collect();
    assert_eq!(
        wrong,
        [
            "vendor ID (VendCode)",
            "product code (ProdCode)",
            "major revision (MajRev)",
            "produced size (Input1)",
            "produced path (Input1)",
            "consumed size (Output1)",
            "consumed path (Output1)",
            // StrobeInfo names the 10-byte Input1, which a strobe response cannot carry (8 bytes).
            "bit-strobe produced size (Input1)",
            "change-of-state produced size (Input1)",
            "cyclic produced size (Input1)",
        ]
        .iter()
        .map(|w| w.to_string())
        .collect::<Vec<_>>(),
        "{report}"
    );
}

#[test]
fn no_device_is_an_error_not_a_disagreement() {
    let eds = eds::parse_str(&eds_text("breaker")).unwrap();
    let mut bus = SimBus::new(Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let error =
        check_device(&mut master, MacId::new(5).unwrap(), &eds, &CheckOptions::default()).unwrap_err();
    assert!(matches!(error, MasterError::Timeout { mac: 5, .. }), "{error}");
}

#[test]
fn the_master_mac_cannot_be_the_device_mac() {
    let eds = Eds::default();
    let bus = BusOptions { mac: MacId::new(0).unwrap(), ..sim("breaker") };
    let error = check_on_bus(&eds, &bus, &CheckOptions::default(), None).unwrap_err();
    assert!(matches!(error, DeviceError::Usage(_)), "{error}");
}

#[test]
fn a_slave_config_needs_the_simulated_bus() {
    let bus = BusOptions { bus: BusSpec::SocketCan { iface: "can0".into() }, ..sim("breaker") };
    let error = check_on_bus(&Eds::default(), &bus, &CheckOptions::default(), None).unwrap_err();
    assert!(error.to_string().contains("needs --bus sim"), "{error}");
}

#[test]
fn the_log_records_every_frame() {
    let dir = std::env::temp_dir().join(format!("dnet-eds-device-log-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("check.log");
    let eds = eds::parse_str(&eds_text("breaker")).unwrap();
    check_on_bus(&eds, &sim("breaker"), &CheckOptions::default(), Some(&log)).unwrap();
    let lines = std::fs::read_to_string(&log).unwrap();
    let frames = can_io::log::read_log(&log).unwrap();
    assert!(frames.len() > 20, "{lines}");
    std::fs::remove_dir_all(&dir).unwrap();
}
