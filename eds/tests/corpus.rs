//! The EDS corpus written for this test suite (`tests/corpus/*.eds`): one file per dialect point,
//! each parsed and its facts asserted.

use eds::model::EnumDialect;
use eds::text::Encoding;
use eds::value::{ConnectionMask, DataType, Date, Revision, Time};
use eds::{check, parse, read_file, Eds, FieldValue, Rule, Severity, Span, SyntaxError, Value};
use rstest::rstest;
use std::path::PathBuf;

fn path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/corpus").join(name)
}

fn bytes(name: &str) -> Vec<u8> {
    std::fs::read(path(name)).unwrap()
}

fn load(name: &str) -> Eds {
    read_file(path(name)).unwrap()
}

#[rstest]
#[case::full_devicenet("full_devicenet.eds")]
#[case::comments_and_strings("comments_and_strings.eds")]
#[case::case_insensitive("case_insensitive.eds")]
#[case::multiline_and_empty_fields("multiline_and_empty_fields.eds")]
#[case::vendor_and_unknown("vendor_and_unknown.eds")]
#[case::enum_legacy("enum_legacy.eds")]
#[case::latin1("latin1.eds")]
fn clean_files_check_without_findings(#[case] name: &str) {
    let report = check(&bytes(name));
    assert!(report.diagnostics.is_empty(), "{report}");
}

#[test]
fn full_file_types_every_section() {
    let eds = load("full_devicenet.eds");
    let file = eds.file.as_ref().unwrap();
    assert_eq!(file.create_date, Some(Date { year: 2024, month: 5, day: 14 }));
    assert_eq!(file.mod_time, Some(Time { hour: 17, minute: 45, second: 10 }));
    assert_eq!(file.revision, Some(Revision { major: 1, minor: 2 }));
    let device = eds.device.as_ref().unwrap();
    assert_eq!(device.vend_code, Some(0x0457));
    assert_eq!(device.catalog.as_deref(), Some("SDN-1"));
    assert_eq!(eds.classification.as_ref().unwrap().classes[&1], ["DeviceNet"]);
    let io = eds.io_info.as_ref().unwrap();
    assert_eq!(io.cos.as_ref().unwrap().default_output, Some(0));
    assert_eq!(io.outputs[&1].mask, Some(ConnectionMask(ConnectionMask::POLL)));
    let class = eds.param_class.as_ref().unwrap();
    assert_eq!((class.max_inst, class.descriptor, class.cfg_assembly), (Some(4), Some(9), Some(0)));
    assert_eq!(eds.param_count(), 4);
    let gain = eds.param(3).unwrap();
    assert_eq!(gain.data_type, Some(DataType::Real));
    assert_eq!((gain.min.clone(), gain.default.clone()), (Some(Value::Real(0.5)), Some(Value::Real(1.0))));
    assert_eq!(gain.decimal_places, Some(2));
    assert_eq!(eds.param(2).unwrap().units, "ms");
    let baud = eds.enum_strings(1).unwrap();
    assert_eq!(baud.dialect, EnumDialect::Params);
    assert_eq!(
        baud.entries.iter().map(|e| e.text.as_str()).collect::<Vec<_>>(),
        ["9600", "19200", "38400", "115200"]
    );
    assert_eq!(eds.groups().map(|(_, g)| g.params.clone()).collect::<Vec<_>>(), [vec![1, 2], vec![3, 4]]);
}

#[test]
fn comments_and_strings() {
    let eds = load("comments_and_strings.eds");
    let file = eds.file.as_ref().unwrap();
    assert_eq!(file.desc_text.as_deref(), Some("Comment markers $ inside strings are text"));
    assert!(file.create_time.is_some(), "two entries on one line");
    let device = eds.device.as_ref().unwrap();
    assert_eq!(device.vend_name.as_deref(), Some("Vendor Name Continued"), "adjacent strings are joined");
    assert_eq!(device.prod_type_str.as_deref(), Some("Communications\nAdapter"), "a string spans lines");
    assert_eq!(device.prod_name.as_deref(), Some("Quote \"inside\" and back\\slash"));
    assert_eq!(device.catalog.as_deref(), Some(""));
}

#[test]
fn sections_and_keywords_ignore_case() {
    let eds = load("case_insensitive.eds");
    let device = eds.device.as_ref().unwrap();
    assert_eq!((device.vend_code, device.prod_type, device.prod_code), (Some(283), Some(12), Some(0x22)));
    assert_eq!(eds.file.as_ref().unwrap().revision, Some(Revision { major: 2, minor: 10 }));
    assert!(eds.classification.is_some());
    assert_eq!(eds.io_info.as_ref().unwrap().inputs[&1].size, Some(2));
    assert_eq!(eds.enum_strings(1).unwrap().entries.len(), 2);
    assert_eq!(eds.groups().count(), 1);
}

#[test]
fn entries_span_lines_and_fields_may_be_empty() {
    let eds = load("multiline_and_empty_fields.eds");
    assert_eq!(eds.io_info.as_ref().unwrap().default, Some(ConnectionMask(1)));
    let p = eds.param(1).unwrap();
    assert_eq!((p.link_path_size, &p.link_path), (None, &None));
    assert_eq!(p.data_type, Some(DataType::Int));
    assert_eq!(p.min, Some(Value::Int(-100)));
    assert_eq!((p.scaling.multiplier, p.links.offset, p.decimal_places), (None, None, None));
}

#[test]
fn vendor_keywords_and_unknown_sections_are_kept_with_positions() {
    let eds = load("vendor_and_unknown.eds");
    let kept: Vec<(&str, &str, Span)> =
        eds.other_entries().into_iter().map(|(section, e)| (section, e.keyword.as_str(), e.span)).collect();
    assert_eq!(
        kept,
        [("File", "1_VendorKeyword", Span::new(7, 9)), ("Device", "283_Firmware", Span::new(18, 9))]
    );
    let firmware = eds.other_entries()[1].1;
    assert_eq!(firmware.vendor_prefix(), Some((283, "Firmware")));
    assert_eq!(firmware.fields[1].value, FieldValue::Text("0x0504".into()));
    let names: Vec<&str> = eds.other_sections.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["283_Diagnostics", "Assembly"]);
    let counter = &eds.other_sections[0].entries[0];
    assert!(matches!(&counter.fields[2].value, FieldValue::List(items) if items.len() == 2));
    assert_eq!(eds.other_sections[1].entries[0].fields.len(), 8, "empty fields are kept");
}

#[test]
fn legacy_enum_par_is_mapped_from_the_minimum() {
    let eds = load("enum_legacy.eds");
    let assembly = eds.enum_strings(1).unwrap();
    assert_eq!(assembly.dialect, EnumDialect::EnumPar);
    let pairs: Vec<(i128, &str)> = assembly.entries.iter().map(|e| (e.value, e.text.as_str())).collect();
    assert_eq!(pairs, [(100, "Assembly 100"), (101, "Assembly 101"), (102, "Assembly 102")]);
    let mode = eds.enum_strings(2).unwrap();
    assert_eq!(mode.entries[1].value, 1);
    assert_eq!(eds.enums().len(), 2);
}

#[test]
fn optional_sections_may_be_missing() {
    let eds = load("minimal.eds");
    assert!(eds.classification.is_none() && eds.io_info.is_none() && eds.params.is_none());
    assert!(eds.enum_par.is_none() && eds.groups.is_none() && eds.param_class.is_none());
    assert_eq!(eds.param_count(), 0);
    let report = check(&bytes("minimal.eds"));
    assert!(!report.has_errors(), "{report}");
    assert_eq!(report.rules(), [Rule::MissingSection], "only the [IO_Info] warning");
}

#[test]
fn latin1_bytes_are_decoded() {
    let raw = bytes("latin1.eds");
    assert!(std::str::from_utf8(&raw).is_err(), "the file must not be valid UTF-8");
    let eds = parse(&raw).unwrap();
    let device = eds.device.as_ref().unwrap();
    assert_eq!(device.vend_name.as_deref(), Some("Müller Messtechnik"));
    assert_eq!(device.prod_name.as_deref(), Some("Témp µs"));
    assert_eq!(eds.io_info.as_ref().unwrap().inputs[&1].name, "°C x 10");
    assert_eq!(check(&raw).encoding, Some(Encoding::Latin1));
}

#[test]
fn crlf_line_ends_and_dos_eof_give_the_same_model() {
    let unix = bytes("full_devicenet.eds");
    let mut dos: Vec<u8> = String::from_utf8(unix.clone()).unwrap().replace('\n', "\r\n").into_bytes();
    dos.push(0x1A);
    assert_eq!(parse(&dos).unwrap(), parse(&unix).unwrap());
    assert!(check(&dos).diagnostics.is_empty());
}

#[test]
fn check_reports_every_content_problem_with_its_position() {
    let report = check(&bytes("check_errors.eds"));
    let found: Vec<(u32, Rule, Severity)> =
        report.diagnostics.iter().map(|d| (d.span.line, d.rule, d.severity)).collect();
    let e = Severity::Error;
    assert_eq!(
        found,
        [
            (2, Rule::MissingKey, e),
            (4, Rule::InvalidValue, e),
            (8, Rule::InvalidValue, e),
            (16, Rule::DuplicateEntry, e),
            (20, Rule::IoReference, e),
            (21, Rule::IoSize, e),
            (25, Rule::DataSize, e),
            (25, Rule::DefaultOutOfRange, e),
            (27, Rule::RangeOrder, e),
            (32, Rule::GroupCount, Severity::Warning),
            (32, Rule::UndefinedParam, e),
        ],
        "{report}"
    );
}

#[test]
fn syntax_errors_carry_file_line_and_column() {
    let error = match read_file(path("syntax_error.eds")) {
        Err(eds::EdsError::Parse(error)) => error,
        other => panic!("expected a parse error, got {other:?}"),
    };
    assert_eq!(error.span, Span::new(2, 40));
    assert_eq!(error.kind, SyntaxError::MissingSemicolon("DescText".into()));
    let text = error.to_string();
    assert!(text.ends_with("syntax_error.eds:2:40: missing ';' after entry `DescText`"), "{text}");
    let report = check(&bytes("syntax_error.eds"));
    let syntax: Vec<Span> =
        report.diagnostics.iter().filter(|d| d.rule == Rule::Syntax).map(|d| d.span).collect();
    // The unterminated string of line 7 is reported once, at its quote, with no follow-up error.
    assert_eq!(syntax, [Span::new(2, 40), Span::new(7, 20)]);
}
