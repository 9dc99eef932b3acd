//! The vendor-written EDS files in `../shared/eds-corpus/` (Hilscher netX DeviceNet slave
//! demos), read in place: each parses without error, checks without errors (the two DNS V5 demos
//! with one warning: a 10-byte bit-strobe input), and its facts are asserted.

use eds::model::EnumDialect;
use eds::{check_file, read_file, AttributePath, DataType, Eds, Rule, Span, Summary, Writer};

const NETX90: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_netx90_dns.eds");
const SIMPLE: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_dns_v5_simple.eds");
const EXTENDED: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_dns_v5_extended.eds");

fn identity(eds: &Eds) -> (u16, u16, u16, u8, u8, &str) {
    let d = eds.device.as_ref().unwrap();
    (
        d.vend_code.unwrap(),
        d.prod_type.unwrap(),
        d.prod_code.unwrap(),
        d.maj_rev.unwrap(),
        d.min_rev.unwrap(),
        d.prod_name.as_deref().unwrap(),
    )
}

/// No errors. The netX 90 file is clean; the DNS V5 demos name their 10-byte `Input1` as the
/// bit-strobe's default input (`StrobeInfo = 0x000F, 1, 0;`), one warning each, at that field.
#[test]
fn all_three_check_without_errors() {
    let expected: [(&str, &[(Rule, Span)]); 3] = [
        (NETX90, &[]),
        (SIMPLE, &[(Rule::StrobeSize, Span::new(51, 17))]),
        (EXTENDED, &[(Rule::StrobeSize, Span::new(51, 17))]),
    ];
    for (path, findings) in expected {
        let report = check_file(path).unwrap();
        assert!(!report.has_errors(), "{report}");
        let found: Vec<(Rule, Span)> = report.warnings().map(|d| (d.rule, d.span)).collect();
        assert_eq!(found, findings, "{report}");
    }
}

/// The connection entries the generator follows: every file announces the four types with the
/// same masks, poll by default, and no default output for the bit-strobe.
#[test]
fn all_three_announce_the_four_connections_alike() {
    for path in [NETX90, SIMPLE, EXTENDED] {
        let eds = read_file(path).unwrap();
        let io = eds.io_info.as_ref().unwrap();
        assert_eq!(io.default.map(|m| m.0), Some(0x0001), "{path}");
        let masks =
            [&io.poll, &io.strobe, &io.cos, &io.cyclic].map(|i| i.as_ref().unwrap().compatible.unwrap().0);
        assert_eq!(masks, [0x000F, 0x000F, 0x0007, 0x000B], "{path}");
        assert_eq!(io.strobe.as_ref().unwrap().default_output, Some(0), "{path}");
        assert!(io.outputs.values().all(|o| o.mask.map(|m| m.0) == Some(0x000D)), "{path}");
        assert!(io.inputs.values().all(|i| i.mask.map(|m| m.0) == Some(0x000F)), "{path}");
        assert!(eds.other_sections.is_empty(), "{path}: no [Connection Manager], no other section");
    }
}

#[test]
fn netx90_dns() {
    let eds = read_file(NETX90).unwrap();
    assert_eq!(identity(&eds), (283, 12, 62, 5, 4, "NETX 90-DN/DNS"));
    assert_eq!(eds.device.as_ref().unwrap().vend_name.as_deref(), Some("Hilscher GmbH"));
    assert!(eds.classification.is_none(), "no [Device Classification]");
    assert_eq!(eds.param_count(), 0);
    assert!(eds.enum_par.is_none() && eds.enums().is_empty(), "this file has no enums in either dialect");
    let io = eds.io_info.as_ref().unwrap();
    assert_eq!((io.inputs.len(), io.outputs.len()), (9, 9));
    let poll = io.poll.as_ref().unwrap();
    assert_eq!((poll.default_input, poll.default_output), (Some(4), Some(4)));
    assert_eq!(io.inputs[&4].size, Some(8));
    assert_eq!(io.inputs[&9].size, Some(255));
    assert_eq!(io.outputs[&9].bits, Some(2040));
    assert_eq!(io.strobe.as_ref().unwrap().default_output, Some(0));
    let assembly = io.inputs[&1].path.as_ref().unwrap().attribute();
    assert_eq!(assembly, Some(AttributePath { class: 4, instance: 0x65, attribute: Some(3) }));
}

#[test]
fn dns_v5_simple() {
    let eds = read_file(SIMPLE).unwrap();
    assert_eq!(identity(&eds), (283, 12, 34, 5, 1, "DNS_V5_SIMPLE_CONFIG_DEMO"));
    assert_eq!(eds.param_count(), 0);
    assert!(eds.params.is_none() && eds.groups.is_none() && eds.enum_par.is_none());
    let io = eds.io_info.as_ref().unwrap();
    assert_eq!((io.inputs[&1].size, io.outputs[&1].size), (Some(10), Some(6)));
    assert_eq!(io.cos.as_ref().unwrap().compatible.map(|m| m.0), Some(0x0007));
}

#[test]
fn dns_v5_extended() {
    let eds = read_file(EXTENDED).unwrap();
    assert_eq!(identity(&eds), (283, 12, 34, 5, 4, "DNS_V5_EXTENDED_CONFIG_DEMO"));
    assert_eq!(eds.param_count(), 8);
    for (_, p) in eds.params() {
        assert_eq!((p.data_type, p.data_size), (Some(DataType::Usint), Some(1)));
        assert_eq!(p.descriptor.map(|d| d.0), Some(0x002E));
    }

    // Params 1-4 select assemblies through attributes 100/101 of the Connection object (class
    // 5), instances 2 (poll), 3 (bit-strobe) and 4 (COS/cyclic).
    let targets: Vec<AttributePath> =
        (1..=4).map(|n| eds.param(n).unwrap().link_path.as_ref().unwrap().attribute().unwrap()).collect();
    let at = |instance, attribute| AttributePath { class: 0x05, instance, attribute: Some(attribute) };
    assert_eq!(targets, [at(2, 100), at(2, 101), at(3, 101), at(4, 101)]);
    // Params 5-8 live in the vendor objects 0x64 and 0x65.
    let vendor = eds.param(7).unwrap().link_path.as_ref().unwrap().attribute().unwrap();
    assert_eq!(vendor, AttributePath { class: 0x65, instance: 1, attribute: Some(1) });

    // The legacy [EnumPar] section, mapped from each parameter's minimum.
    let enums = eds.enums();
    assert_eq!(enums.len(), 8);
    assert!(enums.iter().all(|e| e.dialect == EnumDialect::EnumPar));
    let output_assembly = eds.enum_strings(1).unwrap();
    let pairs: Vec<(i128, &str)> =
        output_assembly.entries.iter().map(|e| (e.value, e.text.as_str())).collect();
    assert_eq!(pairs, [(100, "Assembly Object 100"), (101, "n.a"), (102, "Assembly Object 102")]);
    assert_eq!(eds.enum_strings(3).unwrap().entries[1].text, "", "an empty enum string is kept");
    assert_eq!(eds.enum_strings(8).unwrap().entries[1].text, "Hold Last State");

    let groups: Vec<(&str, Vec<u32>)> =
        eds.groups().map(|(_, g)| (g.name.as_str(), g.params.clone())).collect();
    assert_eq!(
        groups,
        [("Assemblies", vec![1, 2, 3, 4]), ("Sensor Settings", vec![5, 6]), ("Acuator settings", vec![7, 8])]
    );
    let io = eds.io_info.as_ref().unwrap();
    assert_eq!((io.inputs[&2].size, io.inputs[&2].bits), (Some(6), Some(28)));
}

#[test]
fn nothing_is_left_unknown_in_the_real_files() {
    for path in [NETX90, SIMPLE, EXTENDED] {
        let summary = Summary::of(&read_file(path).unwrap());
        assert!(summary.kept_sections.is_empty() && summary.kept_entries.is_empty(), "{path}");
    }
}

#[test]
fn real_files_survive_the_writer() {
    for path in [NETX90, SIMPLE, EXTENDED] {
        let eds = read_file(path).unwrap();
        let text = Writer::new().write(&eds);
        assert_eq!(eds::parse_str(&text).unwrap(), eds, "{path}");
        let rules = |r: eds::Report| r.rules();
        assert_eq!(rules(eds::check_str(&text)), rules(check_file(path).unwrap()), "{path}");
    }
}
