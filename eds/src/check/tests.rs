use super::*;
use rstest::rstest;

const HEADER: &str =
    "[File]\nDescText = \"t\"; CreateDate = 01-01-2024; CreateTime = 00:00:00; Revision = 1.0;\n\
    [Device]\nVendCode = 1; VendName = \"v\"; ProdType = 12; ProdTypeStr = \"a\"; ProdCode = 2;\n\
    MajRev = 1; MinRev = 1; ProdName = \"p\";\n\
    [IO_Info]\nDefault = 0x0001; PollInfo = 0x0001, 1, 1;\n\
    Input1 = 1, 8, 0x0001, \"i\", 6, \"20 04 24 64 30 03\", \"\";\n\
    Output1 = 1, 8, 0x0001, \"o\", 6, \"20 04 24 65 30 03\", \"\";\n";

/// A USINT parameter with the given min, max, default.
fn param(n: u32, min: &str, max: &str, default: &str) -> String {
    format!("Param{n} = 0, 6, \"20 0F 24 {n:02X} 30 01\", 0x0000, 0xC6, 1, \"p{n}\", \"\", \"\", {min}, {max}, {default}, 1,1,1,0, 0,0,0,0, 0;\n")
}

fn check_with(body: &str) -> Report {
    check_str(&format!("{HEADER}{body}"))
}

#[test]
fn minimal_file_is_clean() {
    let report = check_with(&format!("[Params]\n{}", param(1, "0", "10", "5")));
    assert!(report.diagnostics.is_empty(), "{report}");
}

#[rstest]
#[case::default_above_max(param(1, "0", "10", "11"), Rule::DefaultOutOfRange, Severity::Error)]
#[case::default_below_min(param(1, "5", "10", "4"), Rule::DefaultOutOfRange, Severity::Error)]
#[case::min_above_max(param(1, "10", "0", "5"), Rule::RangeOrder, Severity::Error)]
#[case::max_above_usint(param(1, "0", "300", "5"), Rule::TypeRange, Severity::Error)]
#[case::negative_usint(param(1, "-1", "10", "5"), Rule::TypeRange, Severity::Error)]
#[case::text_minimum(param(1, "low", "10", "5"), Rule::InvalidValue, Severity::Error)]
#[case::real_for_usint(param(1, "0.5", "10", "5"), Rule::TypeRange, Severity::Error)]
#[case::size_mismatch(
    "Param1 = 0, 6, \"20 0F 24 01 30 01\", 0, 0xC7, 1, \"p\", \"\", \"\", 0, 10, 5, 1,1,1,0, 0,0,0,0, 0;\n".to_string(),
    Rule::DataSize, Severity::Error)]
#[case::unknown_type(
    "Param1 = 0, 6, \"20 0F 24 01 30 01\", 0, 0x42, 1, \"p\", \"\", \"\", 0, 10, 5, 1,1,1,0, 0,0,0,0, 0;\n".to_string(),
    Rule::UnknownDataType, Severity::Warning)]
#[case::path_size(
    "Param1 = 0, 4, \"20 0F 24 01 30 01\", 0, 0xC6, 1, \"p\", \"\", \"\", 0, 10, 5, 1,1,1,0, 0,0,0,0, 0;\n".to_string(),
    Rule::PathSize, Severity::Error)]
#[case::reserved(
    "Param1 = 1, 6, \"20 0F 24 01 30 01\", 0, 0xC6, 1, \"p\", \"\", \"\", 0, 10, 5, 1,1,1,0, 0,0,0,0, 0;\n".to_string(),
    Rule::Reserved, Severity::Warning)]
#[case::divisor_zero_with_scaling(
    "Param1 = 0, 6, \"20 0F 24 01 30 01\", 0x0004, 0xC6, 1, \"p\", \"\", \"\", 0, 10, 5, 1,0,1,0, 0,0,0,0, 0;\n".to_string(),
    Rule::Scaling, Severity::Error)]
#[case::link_to_nothing(
    "Param1 = 0, 6, \"20 0F 24 01 30 01\", 0x0008, 0xC6, 1, \"p\", \"\", \"\", 0, 10, 5, 1,1,1,0, 9,0,0,0, 0;\n".to_string(),
    Rule::UndefinedParam, Severity::Error)]
#[case::enum_descriptor_without_strings(
    "Param1 = 0, 6, \"20 0F 24 01 30 01\", 0x0002, 0xC6, 1, \"p\", \"\", \"\", 0, 10, 5, 1,1,1,0, 0,0,0,0, 0;\n".to_string(),
    Rule::EnumDescriptor, Severity::Warning)]
#[case::enum_out_of_range(param(1, "0", "1", "0") + "Enum1 = 0, \"off\", 1, \"on\", 2, \"auto\";\n",
    Rule::EnumOutOfRange, Severity::Warning)]
#[case::enum_for_missing_param("Enum4 = 0, \"off\";\n".to_string(), Rule::UndefinedParam, Severity::Error)]
fn param_rules(#[case] params: String, #[case] rule: Rule, #[case] severity: Severity) {
    let report = check_with(&format!("[Params]\n{params}"));
    let found = report.diagnostics.iter().find(|d| d.rule == rule);
    assert_eq!(found.map(|d| d.severity), Some(severity), "{report}");
}

#[rstest]
#[case::group_to_missing_param(
    "[Groups]\nGroup1 = \"G\", 2, 1, 7;",
    Rule::UndefinedParam,
    Severity::Error,
    Span::new(14, 21)
)]
#[case::legacy_enum_count(
    "[EnumPar]\nParam1 = \"a\", \"b\";",
    Rule::EnumCount,
    Severity::Warning,
    Span::new(14, 1)
)]
#[case::legacy_for_missing_param(
    "[EnumPar]\nParam9 = \"a\";",
    Rule::UndefinedParam,
    Severity::Error,
    Span::new(14, 1)
)]
#[case::both_dialects("[EnumPar]\nParam1 = \"a\";", Rule::EnumConflict, Severity::Warning, Span::new(14, 1))]
fn cross_reference_rules(
    #[case] tail: &str,
    #[case] rule: Rule,
    #[case] severity: Severity,
    #[case] span: Span,
) {
    let params = param(1, "0", "2", "0") + "Enum1 = 0, \"a\";\n";
    let params = if rule == Rule::EnumCount {
        param(1, "0", "2", "0") + "Param2 = 0,,,0x0002,0xC6,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;\n"
    } else {
        params
    };
    let report = check_with(&format!("[Params]\n{params}{tail}"));
    let found = report.diagnostics.iter().find(|d| d.rule == rule);
    assert_eq!(found.map(|d| (d.severity, d.span)), Some((severity, span)), "{report}");
}

#[rstest]
#[case::missing_file("[Device]\nVendCode = 1;", Rule::MissingSection)]
#[case::missing_key("[File]\nDescText = \"x\";", Rule::MissingKey)]
#[case::no_io_info("[File]\n", Rule::MissingSection)]
#[case::not_devicenet("[Device Classification]\nClass1 = EtherNetIP;", Rule::Classification)]
fn file_level_rules(#[case] src: &str, #[case] rule: Rule) {
    assert!(check_str(src).rules().contains(&rule));
}

#[rstest]
#[case::default_input_missing("PollInfo = 0x0001, 3, 1;", Rule::IoReference)]
#[case::bits_exceed_size("Input2 = 1, 9, 0x0001, \"i\", 6, \"20 04 24 64 30 03\", \"\";", Rule::IoSize)]
#[case::input_mask_excludes_poll(
    "PollInfo = 0x0001, 2, 1;\nInput2 = 1, 8, 0x0004, \"i\", 6, \"20 04 24 64 30 03\", \"\";",
    Rule::ConnectionMask
)]
#[case::default_without_info("Default = 0x0005;", Rule::ConnectionMask)]
fn io_rules(#[case] extra: &str, #[case] rule: Rule) {
    // Later duplicates are ignored, so the extra entries go in a section of their own that
    // replaces the header's IO_Info.
    let src = HEADER.split("[IO_Info]").next().unwrap().to_string()
        + "[IO_Info]\n"
        + extra
        + "\nInput1 = 1, 8, 0x0001, \"i\", 6, \"20 04 24 64 30 03\", \"\";\nOutput1 = 1, 8, 0x0001, \"o\", 6, \"20 04 24 65 30 03\", \"\";\nPollInfo = 0x0001, 1, 1;\nDefault = 0x0001;";
    let report = check_str(&src);
    assert!(report.rules().contains(&rule), "{report}");
}

/// An `[IO_Info]` with every connection type, as the generator writes it for an 18-byte input.
const FOUR_CONNECTIONS: &str = "[IO_Info]\nDefault = 0x0001;\nPollInfo = 0x000F, 1, 1;\n\
    StrobeInfo = 0x000F, 2, 0;\nCOSInfo = 0x0007, 1, 1;\nCyclicInfo = 0x000B, 1, 1;\n\
    Input1 = 18, 144, 0x000D, \"i\", 6, \"20 04 24 64 30 03\", \"\";\n\
    Input2 = 8, 64, 0x0002, \"s\", 6, \"20 04 24 64 30 03\", \"\";\n\
    Output1 = 8, 64, 0x000D, \"o\", 6, \"20 04 24 96 30 03\", \"\";\n";

/// The header's identity with [`FOUR_CONNECTIONS`] edited by `edits`.
fn four_connections(edits: &[(&str, &str)]) -> Report {
    let mut io = FOUR_CONNECTIONS.to_string();
    for (find, replace) in edits {
        assert_eq!(io.matches(find).count(), 1, "{find:?}");
        io = io.replacen(find, replace, 1);
    }
    check_str(&(HEADER.split("[IO_Info]").next().unwrap().to_string() + &io))
}

#[test]
fn four_connections_are_clean() {
    let report = four_connections(&[]);
    assert!(report.diagnostics.is_empty(), "{report}");
}

#[rstest]
#[case::reserved_default_bit(&[("Default = 0x0001", "Default = 0x0011")], Rule::ConnectionMask, Severity::Warning, "`Default` mask 0x0011 (poll, bit4) sets reserved bits 0x0010")]
#[case::reserved_input_bit(&[("0x000D, \"i\"", "0x800D, \"i\"")], Rule::ConnectionMask, Severity::Warning, "`Input1` mask 0x800D (poll, cos, cyclic, bit15) sets reserved bits 0x8000")]
#[case::reserved_info_bit(&[("PollInfo = 0x000F", "PollInfo = 0x002F")], Rule::ConnectionMask, Severity::Warning, "`PollInfo` mask 0x002F")]
#[case::mask_over_16_bits(&[("PollInfo = 0x000F", "PollInfo = 0x1000F")], Rule::InvalidValue, Severity::Error, "`PollInfo` mask: 65551 is out of range")]
#[case::cos_with_cyclic(&[("COSInfo = 0x0007", "COSInfo = 0x000F")], Rule::ConnectionMask, Severity::Warning, "`COSInfo` mask 0x000F (poll, strobe, cos, cyclic) combines cos and cyclic")]
#[case::default_cos_and_cyclic(&[("Default = 0x0001", "Default = 0x000C")], Rule::ConnectionMask, Severity::Warning, "`Default` mask 0x000C (cos, cyclic) combines cos and cyclic")]
#[case::masks_disagree(&[("StrobeInfo = 0x000F", "StrobeInfo = 0x000E")], Rule::ConnectionMask, Severity::Warning, "`PollInfo` says poll and strobe combine but `StrobeInfo` says they do not")]
#[case::missing_strobe_input(&[("StrobeInfo = 0x000F, 2", "StrobeInfo = 0x000F, 3")], Rule::IoReference, Severity::Error, "`StrobeInfo` names Input3 as its default, but there is no `Input3`")]
#[case::missing_cos_output(&[("COSInfo = 0x0007, 1, 1", "COSInfo = 0x0007, 1, 2")], Rule::IoReference, Severity::Error, "`COSInfo` names Output2 as its default, but there is no `Output2`")]
#[case::no_strobe_input_at_all(
    &[("StrobeInfo = 0x000F, 2", "StrobeInfo = 0x000F, 0"), ("0x0002, \"s\"", "0x0001, \"s\"")],
    Rule::IoReference, Severity::Warning, "`StrobeInfo` names no default input and no InputN's mask includes strobe")]
#[case::strobe_too_large(&[("StrobeInfo = 0x000F, 2", "StrobeInfo = 0x000F, 1"), ("0x000D, \"i\"", "0x000F, \"i\"")],
    Rule::StrobeSize, Severity::Warning, "`StrobeInfo` uses Input1 (18 bytes) by default, but a bit-strobe response carries at most 8 bytes")]
fn io_connection_rules(
    #[case] edits: &[(&str, &str)],
    #[case] rule: Rule,
    #[case] severity: Severity,
    #[case] message: &str,
) {
    let report = four_connections(edits);
    let found: Vec<&Diagnostic> = report.diagnostics.iter().filter(|d| d.rule == rule).collect();
    assert_eq!(found.len(), 1, "{report}");
    assert_eq!(found[0].severity, severity, "{report}");
    assert!(found[0].message.contains(message), "{report}");
    assert_eq!(report.diagnostics.len(), 1, "one finding only:\n{report}");
}

#[test]
fn a_strobe_input_over_8_bytes_is_named_by_file_line_and_key() {
    let mut report = four_connections(&[("StrobeInfo = 0x000F, 2", "StrobeInfo = 0x000F, 1")]);
    report.file = Some(PathBuf::from("big.eds"));
    let text = report.to_string();
    // StrobeInfo is on line 9; its default input is the second field, at column 22.
    assert!(
        text.contains(
            "big.eds:9:22: warning[strobe-size]: `StrobeInfo` uses Input1 (18 bytes) by default, but a \
             bit-strobe response carries at most 8 bytes and is never fragmented"
        ),
        "{text}"
    );
    // Input1 is not for bit-strobe: its mask says so too.
    assert!(text.contains("9:22: warning[connection-mask]: `StrobeInfo` uses Input1 by default"), "{text}");
}

#[test]
fn syntax_errors_are_all_reported_with_positions() {
    let report = check_str("[File]\nDescText = \"x\"\nRevision = 1.0;\n[Device\nVendCode = 1;");
    let syntax: Vec<Span> =
        report.diagnostics.iter().filter(|d| d.rule == Rule::Syntax).map(|d| d.span).collect();
    assert_eq!(syntax, vec![Span::new(2, 15), Span::new(4, 1)]);
    assert!(report.has_errors());
}

#[test]
fn report_display_has_file_position_and_rule() {
    let mut report = check_str("[Device]\nVendCode = x;");
    report.file = Some(PathBuf::from("dev.eds"));
    let text = report.to_string();
    assert!(text.contains("dev.eds:2:12: error[invalid-value]: `VendCode`: expected a vendor ID"), "{text}");
    assert!(text.ends_with("errors, 1 warning"), "{text}");
}
