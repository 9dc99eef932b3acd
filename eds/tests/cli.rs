//! The `dnet-eds` binary, run as a user would.

use std::path::PathBuf;
use std::process::{Command, Output};

const EXTENDED: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_dns_v5_extended.eds");

fn corpus(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/corpus").join(name).display().to_string()
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dnet-eds")).args(args).output().unwrap()
}

fn stdout(output: &Output) -> String {
    String::from_utf8(output.stdout.clone()).unwrap()
}

fn stderr(output: &Output) -> String {
    String::from_utf8(output.stderr.clone()).unwrap()
}

#[test]
fn help_everywhere() {
    for args in
        [&["--help"][..], &["parse", "--help"], &["check", "--help"], &["format", "--help"], &["help"]]
    {
        let output = run(args);
        assert_eq!(output.status.code(), Some(0), "{args:?}");
        assert!(stdout(&output).contains("Usage: dnet-eds"), "{args:?}: {}", stdout(&output));
    }
    assert!(stdout(&run(&["check", "--help"])).contains("Exit status 0 without errors"));
}

#[test]
fn usage_errors_exit_2() {
    assert_eq!(run(&[]).status.code(), Some(2));
    assert_eq!(run(&["parse"]).status.code(), Some(2));
    assert_eq!(run(&["frobnicate"]).status.code(), Some(2));
}

#[test]
fn parse_prints_a_summary() {
    let output = run(&["parse", EXTENDED]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let text = stdout(&output);
    for expected in [
        "vendor 283 \"Hilscher GmbH\"",
        "product code 34 \"DNS_V5_EXTENDED_CONFIG_DEMO\", revision 5.4",
        "parameters:     8",
        "class 0x05 instance 2 attribute 100",
        "enums:          8 (0 EnumN, 8 [EnumPar])",
        "100 \"Assembly Object 100\"",
        "Group1     \"Assemblies\": Param1, Param2, Param3, Param4",
        "kept:           0 unknown sections, 0 unknown entries",
    ] {
        assert!(text.contains(expected), "missing {expected:?} in\n{text}");
    }
}

#[test]
fn parse_json() {
    let output = run(&["parse", "--json", EXTENDED]);
    assert_eq!(output.status.code(), Some(0));
    let json: serde_json::Value = serde_json::from_str(&stdout(&output)).unwrap();
    assert_eq!(json["identity"]["vend_code"], 283);
    assert_eq!(json["param_count"], 8);
    assert_eq!(json["params"][0]["attribute"]["attribute"], 100);
    assert_eq!(json["params"][0]["link_path"], "20 05 24 02 30 64");
    assert_eq!(json["params"][0]["data_type"], "USINT");
    assert_eq!(json["enums"][0]["dialect"], "enum-par");
    assert_eq!(json["enums"][0]["entries"][0]["value"], 100);
    assert_eq!(json["groups"][2]["name"], "Acuator settings");
}

#[test]
fn parse_lists_what_was_kept() {
    let output = run(&["parse", &corpus("vendor_and_unknown.eds")]);
    let text = stdout(&output);
    assert!(text.contains("kept:           2 unknown sections, 2 unknown entries"), "{text}");
    assert!(text.contains("[File] 1_VendorKeyword line 7"), "{text}");
    assert!(text.contains("[283_Diagnostics] line 26, 1 entries"), "{text}");
}

#[test]
fn parse_syntax_error_exits_1_with_position() {
    let output = run(&["parse", &corpus("syntax_error.eds")]);
    assert_eq!(output.status.code(), Some(1));
    assert!(
        stderr(&output).contains("syntax_error.eds:3:9: entry `DescText` is not terminated by ';'"),
        "{}",
        stderr(&output)
    );
}

#[test]
fn check_clean_file_exits_0() {
    let output = run(&["check", EXTENDED]);
    assert_eq!(output.status.code(), Some(0));
    assert!(stdout(&output).ends_with("0 errors, 0 warnings\n"));
}

#[test]
fn check_warnings_only_exits_0() {
    let output = run(&["check", &corpus("minimal.eds")]);
    assert_eq!(output.status.code(), Some(0));
    let text = stdout(&output);
    assert!(text.contains("minimal.eds:1:1: warning[missing-section]: no [IO_Info] section"), "{text}");
    assert!(text.ends_with("0 errors, 1 warning\n"), "{text}");
}

#[test]
fn check_errors_exit_1_with_positions() {
    let output = run(&["check", &corpus("check_errors.eds")]);
    assert_eq!(output.status.code(), Some(1));
    let text = stdout(&output);
    assert!(
        text.contains(
            "check_errors.eds:25:91: error[default-out-of-range]: `Param1` default 20 is outside 0..=10"
        ),
        "{text}"
    );
    assert!(text.contains("check_errors.eds:32:39: error[undefined-param]"), "{text}");
    assert!(text.ends_with("10 errors, 1 warning\n"), "{text}");
}

#[test]
fn check_json() {
    let output = run(&["check", "--json", &corpus("check_errors.eds")]);
    assert_eq!(output.status.code(), Some(1));
    let json: serde_json::Value = serde_json::from_str(&stdout(&output)).unwrap();
    let first = &json["diagnostics"][0];
    assert_eq!(first["severity"], "error");
    assert_eq!(first["rule"], "missing-key");
    assert_eq!(first["span"]["line"], 2);
}

#[test]
fn missing_file_is_a_clear_error() {
    for command in ["parse", "check", "format"] {
        let output = run(&[command, "/nonexistent/device.eds"]);
        assert_eq!(output.status.code(), Some(2), "{command}");
        let text = stderr(&output);
        assert!(text.starts_with("dnet-eds: cannot read /nonexistent/device.eds:"), "{command}: {text}");
        assert!(!text.contains("panicked"));
    }
}

#[test]
fn format_writes_canonical_text() {
    let output = run(&["format", &corpus("case_insensitive.eds")]);
    assert_eq!(output.status.code(), Some(0));
    let text = stdout(&output);
    assert!(text.starts_with("[File]\n        DescText = \"lower case keywords\";\n"), "{text}");
    assert_eq!(eds::parse_str(&text).unwrap(), eds::read_file(corpus("case_insensitive.eds")).unwrap());

    let dir = std::env::temp_dir().join(format!("dnet-eds-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out.eds");
    let output = run(&["format", &corpus("case_insensitive.eds"), "-o", out.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(0));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), text);
    std::fs::remove_dir_all(&dir).unwrap();
}
