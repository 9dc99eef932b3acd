//! The writer on the whole corpus: output is deterministic, reads back to the same model and
//! is a fixed point of parse-then-write.

use eds::{parse, parse_str, Writer};
use rstest::rstest;
use std::path::PathBuf;

fn bytes(name: &str) -> Vec<u8> {
    std::fs::read(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/corpus").join(name)).unwrap()
}

#[rstest]
#[case::full_devicenet("full_devicenet.eds", true)]
#[case::comments_and_strings("comments_and_strings.eds", true)]
#[case::case_insensitive("case_insensitive.eds", true)]
#[case::multiline_and_empty_fields("multiline_and_empty_fields.eds", true)]
#[case::enum_legacy("enum_legacy.eds", true)]
#[case::latin1("latin1.eds", true)]
#[case::minimal("minimal.eds", true)]
#[case::check_errors("check_errors.eds", false)]
#[case::vendor_and_unknown("vendor_and_unknown.eds", false)]
fn parse_write_parse(#[case] name: &str, #[case] same_model: bool) {
    let eds = parse(&bytes(name)).unwrap();
    let first = Writer::new().write(&eds);
    let again = parse_str(&first).unwrap();
    if same_model {
        assert_eq!(again, eds);
    }
    let second = Writer::new().write(&again);
    assert_eq!(first, second, "writing is a fixed point after one pass");
}

#[test]
fn kept_entries_are_written_back() {
    let text = Writer::new().write(&parse(&bytes("vendor_and_unknown.eds")).unwrap());
    for line in [
        "        1_VendorKeyword = \"kept\";",
        "        283_Firmware = \"V5.4.0\", 0x0504;",
        "[283_Diagnostics]",
        "        Counter1 = \"Frames\", 0x00C8, {1, 2};",
        "        Assem100 = \"Input\", \"20 04 24 64\", 8, 0x0000, , , 64, ;",
    ] {
        assert!(text.lines().any(|l| l == line), "missing {line:?} in\n{text}");
    }
}

#[test]
fn output_is_deterministic() {
    let eds = parse(&bytes("full_devicenet.eds")).unwrap();
    let writer = Writer::new().header_comment("dnet-eds test");
    assert_eq!(writer.write(&eds), writer.write(&eds.clone()));
    assert!(writer.write(&eds).starts_with("$ dnet-eds test\n\n[File]\n"));
}
