use super::*;
use rstest::rstest;

fn lower(src: &str) -> (Eds, Vec<Diagnostic>) {
    Eds::from_raw(&RawEds::parse(src).unwrap())
}

fn rules(diagnostics: &[Diagnostic]) -> Vec<Rule> {
    diagnostics.iter().map(|d| d.rule).collect()
}

#[rstest]
#[case::param("Param07", Some(("param".to_string(), 7)))]
#[case::upper("INPUT1", Some(("input".to_string(), 1)))]
#[case::no_number("Default", None)]
#[case::vendor("1_Param3", None)]
#[case::too_long("Param1234567890", None)]
fn splits_numbered_keywords(#[case] keyword: &str, #[case] expected: Option<(String, u32)>) {
    assert_eq!(numbered(keyword), expected);
}

#[test]
fn lowers_identity_case_insensitively() {
    let (eds, diagnostics) = lower(
        "[device]\nvendcode = 0x011B;\nVENDNAME = \"Hilscher\";\nProdType = 12;\nMajRev = 5; MinRev = 4;",
    );
    assert!(diagnostics.is_empty(), "{diagnostics:?}");
    let device = eds.device.unwrap();
    assert_eq!(device.vend_code, Some(283));
    assert_eq!(device.vend_name.as_deref(), Some("Hilscher"));
    assert_eq!((device.maj_rev, device.min_rev), (Some(5), Some(4)));
}

#[rstest]
#[case::not_a_number("[Device]\nVendCode = abc;", Rule::InvalidValue)]
#[case::too_big("[Device]\nVendCode = 70000;", Rule::InvalidValue)]
#[case::two_values("[Device]\nVendCode = 1, 2;", Rule::FieldCount)]
#[case::bad_date("[File]\nCreateDate = 2020-01-01;", Rule::InvalidValue)]
fn keeps_untypeable_entries(#[case] src: &str, #[case] rule: Rule) {
    let (eds, diagnostics) = lower(src);
    assert_eq!(rules(&diagnostics), vec![rule]);
    let kept = eds.other_entries();
    assert_eq!(kept.len(), 1);
}

#[test]
fn keeps_vendor_keywords_silently_and_warns_on_unknown_ones() {
    let (eds, diagnostics) = lower("[Device]\n1_VendorKeyword = 5;\nColour = \"red\";");
    assert_eq!(rules(&diagnostics), vec![Rule::UnknownKeyword]);
    let kept: Vec<&str> = eds.other_entries().iter().map(|(_, e)| e.keyword.as_str()).collect();
    assert_eq!(kept, ["1_VendorKeyword", "Colour"]);
}

#[test]
fn merges_repeated_sections_and_reports_duplicates() {
    let (eds, diagnostics) = lower("[Device]\nVendCode = 1;\n[Device]\nVendCode = 2;\nProdCode = 3;");
    assert_eq!(rules(&diagnostics), vec![Rule::DuplicateSection, Rule::DuplicateEntry]);
    let device = eds.device.unwrap();
    assert_eq!((device.vend_code, device.prod_code), (Some(1), Some(3)));
}

#[test]
fn param_fields_in_order() {
    let (eds, diagnostics) = lower(
        "[Params]\nParam1 = 0, 6, \"20 05 24 02 30 64\", 0x002E, 0xC6, 1, \"Name\", \"ms\", \"Help\",\n\
         1, 10, 5, 2, 3, 4, 5, 6, 7, 8, 9, 2, \"extra\";",
    );
    assert!(diagnostics.is_empty(), "{diagnostics:?}");
    let p = eds.param(1).unwrap();
    assert_eq!(p.reserved, Some(0));
    assert_eq!(p.link_path_size, Some(6));
    assert_eq!(p.link_path.as_ref().and_then(LinkPath::attribute).map(|a| a.attribute), Some(Some(100)));
    assert_eq!(p.descriptor, Some(Descriptor(0x2E)));
    assert_eq!(p.data_type, Some(DataType::Usint));
    assert_eq!(p.data_size, Some(1));
    assert_eq!((p.name.as_str(), p.units.as_str(), p.help.as_str()), ("Name", "ms", "Help"));
    assert_eq!(
        (p.min.clone(), p.max.clone(), p.default.clone()),
        (Some(Value::Int(1)), Some(Value::Int(10)), Some(Value::Int(5)))
    );
    assert_eq!(p.scaling, Scaling { multiplier: Some(2), divisor: Some(3), base: Some(4), offset: Some(5) });
    assert_eq!(
        p.links,
        ScalingLinks { multiplier: Some(6), divisor: Some(7), base: Some(8), offset: Some(9) }
    );
    assert_eq!(p.decimal_places, Some(2));
    assert_eq!(p.extra, vec![FieldValue::Str("extra".into())]);
}

#[test]
fn empty_param_fields_are_none() {
    let (eds, diagnostics) =
        lower("[Params]\nParam1 = 0, ,, 0x0012, 0xC7, 2, \"IO\", \"\", \"\", 0,2,0, ,,,, ,,,, ;\nEnum1 = 0,\"In\", 1,\"Out\";");
    assert!(diagnostics.is_empty(), "{diagnostics:?}");
    let p = eds.param(1).unwrap();
    assert_eq!((p.link_path_size, &p.link_path, p.decimal_places), (None, &None, None));
    assert_eq!(p.scaling, Scaling::default());
    let e = eds.enum_strings(1).unwrap();
    assert_eq!(e.dialect, EnumDialect::Params);
    assert_eq!(e.entries[1], EnumEntry { value: 1, text: "Out".into() });
}

#[test]
fn legacy_enums_are_numbered_from_the_minimum() {
    let (eds, _) = lower(
        "[Params]\nParam1 = 0,,,0x02,0xC6,1,\"A\",\"\",\"\",100,102,100,1,1,1,0,0,0,0,0,0;\n\
         [EnumPar]\nParam1 = \"a\", \"b\", \"c\";",
    );
    let e = eds.enum_strings(1).unwrap();
    assert_eq!(e.dialect, EnumDialect::EnumPar);
    let values: Vec<i128> = e.entries.iter().map(|e| e.value).collect();
    assert_eq!(values, [100, 101, 102]);
}

#[rstest]
#[case::short_param("[Params]\nParam1 = 0, 6;", Rule::FieldCount)]
#[case::odd_enum("[Params]\nEnum1 = 0, \"a\", 1;", Rule::FieldCount)]
#[case::duplicate_enum_value("[Params]\nEnum1 = 0, \"a\", 0, \"b\";", Rule::DuplicateEntry)]
#[case::bad_data_type("[Params]\nParam1 = 0,,,0,BOOL,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;", Rule::InvalidValue)]
#[case::group_count("[Groups]\nGroup1 = \"G\", 3, 1, 2;", Rule::GroupCount)]
#[case::group_member_twice("[Groups]\nGroup1 = \"G\", 2, 1, 1;", Rule::GroupCount)]
#[case::param_zero("[Params]\nParam0 = 0,,,0,0xC6,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;", Rule::InvalidValue)]
#[case::unquoted_name("[Device]\nProdName = Widget;", Rule::UnquotedString)]
#[case::duplicate_param("[Params]\nParam1 = 0,,,0,0xC6,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;\nParam01 = 0,,,0,0xC6,1,\"\",\"\",\"\",0,1,0,,,,,,,,,;", Rule::DuplicateEntry)]
#[case::unknown_section("[Colours]\nRed = 1;", Rule::UnknownSection)]
fn reports_lowering_problems(#[case] src: &str, #[case] rule: Rule) {
    let (_, diagnostics) = lower(src);
    assert!(rules(&diagnostics).contains(&rule), "{diagnostics:?}");
}

#[rstest]
#[case::vendor_section("[283_Private]\nA = 1;")]
#[case::cip_class_section("[Identity Class]\nRevision = 1;")]
#[case::assembly("[Assembly]\nAssem100 = \"x\", , 4, 0x0000, , , 32, Param1;")]
fn keeps_known_unmodelled_sections_silently(#[case] src: &str) {
    let (eds, diagnostics) = lower(src);
    assert!(diagnostics.is_empty(), "{diagnostics:?}");
    assert_eq!(eds.other_sections.len(), 1);
}

#[test]
fn groups_and_io_info() {
    let (eds, diagnostics) = lower(
        "[IO_Info]\nDefault = 0x0001;\nPollInfo = 0x000F, 1, 1;\n\
         Input1 = 10, 80, 0x000F, \"In\", 6, \"20 04 24 65 30 03\", \"help\";\n\
         [Groups]\nGroup1 = \"Assemblies\", 2, 1, 2;",
    );
    assert!(diagnostics.is_empty(), "{diagnostics:?}");
    let io = eds.io_info.unwrap();
    assert_eq!(io.default, Some(ConnectionMask(1)));
    assert_eq!(io.poll.unwrap().default_input, Some(1));
    let input = &io.inputs[&1];
    assert_eq!((input.size, input.bits, input.path_size), (Some(10), Some(80), Some(6)));
    assert_eq!(eds.groups.unwrap().groups[&1], Group { name: "Assemblies".into(), params: vec![1, 2] });
}
