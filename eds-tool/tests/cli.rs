//! The `dnet-eds` binary, run as a user would.

use std::path::PathBuf;
use std::process::{Command, Output};

const EXTENDED: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_dns_v5_extended.eds");
const NETX90: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/eds-corpus/hilscher_netx90_dns.eds");

fn corpus(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../eds/tests/corpus").join(name).display().to_string()
}

fn description(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../slave-fw/descriptions")
        .join(format!("{name}.toml"))
        .display()
        .to_string()
}

fn golden(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../eds/tests/golden")
        .join(format!("{name}.eds"))
        .display()
        .to_string()
}

/// A fresh directory for one test's files.
fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-eds-cli-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
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
    for args in [
        &["--help"][..],
        &["parse", "--help"],
        &["check", "--help"],
        &["format", "--help"],
        &["generate", "--help"],
        &["check-device", "--help"],
        &["help"],
    ] {
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
        stderr(&output).contains("syntax_error.eds:2:40: missing ';' after entry `DescText`"),
        "{}",
        stderr(&output)
    );
}

#[test]
fn check_clean_file_exits_0() {
    let output = run(&["check", NETX90]);
    assert_eq!(output.status.code(), Some(0));
    assert!(stdout(&output).ends_with("0 errors, 0 warnings\n"));
}

/// The DNS V5 demo names its 10-byte Input1 for the bit-strobe: a warning at the field, exit 0.
#[test]
fn check_a_strobe_input_over_8_bytes_warns_at_the_field() {
    let output = run(&["check", EXTENDED]);
    assert_eq!(output.status.code(), Some(0));
    let text = stdout(&output);
    assert!(
        text.contains(&format!(
            "{EXTENDED}:51:17: warning[strobe-size]: `StrobeInfo` uses Input1 (10 bytes) by default, but a \
             bit-strobe response carries at most 8 bytes and is never fragmented"
        )),
        "{text}"
    );
    assert!(text.ends_with("0 errors, 1 warning\n"), "{text}");
}

/// Bad masks and a missing input in a generated EDS: errors and warnings with positions, exit 1.
#[test]
fn check_bad_io_connections_in_an_edited_eds() {
    let dir = temp_dir("check-io");
    let bad = dir.join("bad.eds");
    let text = std::fs::read_to_string(golden("breaker"))
        .unwrap()
        .replacen(
            "        COSInfo =\n                0x0007,",
            "        COSInfo =\n                0x001F,",
            1,
        )
        .replacen(
            "                2,                        $ default input",
            "                3,                        $ default input",
            1,
        );
    std::fs::write(&bad, text).unwrap();
    let output = run(&["check", bad.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(1));
    let text = stdout(&output);
    let at = bad.display();
    for line in [
        format!("{at}:34:17: error[io-reference]: `StrobeInfo` names Input3 as its default, but there is no `Input3`"),
        format!("{at}:37:17: warning[connection-mask]: `COSInfo` mask 0x001F (poll, strobe, cos, cyclic, bit4) sets reserved bits 0x0010"),
        format!("{at}:37:17: warning[connection-mask]: `COSInfo` mask 0x001F (poll, strobe, cos, cyclic, bit4) combines cos and cyclic"),
    ] {
        assert!(text.contains(&line), "{line}\n{text}");
    }
    assert!(text.ends_with("1 error, 2 warnings\n"), "{text}");
    std::fs::remove_dir_all(&dir).unwrap();
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
    assert!(
        text.starts_with(
            "$ Section names and keywords in any case.\n[File]\n        DescText = \"lower case keywords\";\n"
        ),
        "{text}"
    );
    assert_eq!(eds::parse_str(&text).unwrap(), eds::read_file(corpus("case_insensitive.eds")).unwrap());

    let dir = std::env::temp_dir().join(format!("dnet-eds-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("out.eds");
    let output = run(&["format", &corpus("case_insensitive.eds"), "-o", out.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(0));
    assert_eq!(std::fs::read_to_string(&out).unwrap(), text);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn generate_prints_the_golden_file() {
    for name in ["breaker", "modbus-meter"] {
        let output = run(&["generate", &description(name)]);
        assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
        assert_eq!(stdout(&output), std::fs::read_to_string(golden(name)).unwrap(), "{name}");
    }
}

#[test]
fn generate_writes_a_file_that_checks_clean() {
    let dir = temp_dir("generate");
    let out = dir.join("bridge.eds");
    let output =
        run(&["generate", &description("breaker"), "-o", out.to_str().unwrap(), "--date", "03-14-2026"]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert!(stdout(&output).is_empty());
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("CreateDate = 03-14-2026;") && text.contains("ModDate = 03-14-2026;"), "{text}");
    let output = run(&["check", out.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(0));
    assert!(stdout(&output).ends_with("0 errors, 0 warnings\n"), "{}", stdout(&output));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn generate_refuses_bad_input_with_exit_2() {
    let output = run(&["generate", "/nonexistent/device.toml"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(
        stderr(&output).starts_with("dnet-eds: /nonexistent/device.toml: cannot read the device description")
    );

    let dir = temp_dir("generate-bad");
    let bad = dir.join("bad.toml");
    let text = std::fs::read_to_string(description("breaker")).unwrap().replace("mac_id = 5", "mac_id = 64");
    std::fs::write(&bad, text).unwrap();
    let output = run(&["generate", bad.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("network.mac_id: 64 is outside 0..=63"), "{}", stderr(&output));

    let output = run(&["generate", &description("breaker"), "--date", "2026-03-14"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("'2026-03-14' is not a date MM-DD-YYYY"), "{}", stderr(&output));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The findings that disagree in `check-device --json` output.
fn disagreements(json: &serde_json::Value) -> Vec<String> {
    json["report"]["findings"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["verdict"] == "disagree")
        .map(|f| f["what"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn check_device_agrees_on_the_simulated_bus() {
    let output = run(&["check-device", "--eds", &golden("breaker"), "--mac", "5"]);
    let text = stdout(&output);
    assert_eq!(output.status.code(), Some(0), "{text}{}", stderr(&output));
    assert!(text.contains("product code (ProdCode)"), "{text}");
    assert!(text.contains("bit-strobe produced size (Input2)"), "{text}");
    assert!(!text.contains("DISAGREES"), "{text}");
    assert!(text.ends_with("MAC 5: the device agrees with the EDS\n"), "{text}");

    let output = run(&[
        "check-device",
        "--eds",
        &golden("modbus-meter"),
        "--mac",
        "7",
        "--slave-config",
        &description("modbus-meter"),
        "--params",
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_str(&stdout(&output)).unwrap();
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    assert_eq!(json["ok"], true);
    assert_eq!(disagreements(&json), Vec::<String>::new());
    assert_eq!(json["report"]["mac"], 7);
    let findings = json["report"]["findings"].as_array().unwrap();
    for kind in ["bit-strobe", "change-of-state", "cyclic"] {
        let connection = findings.iter().find(|f| f["what"] == format!("{kind} connection")).unwrap();
        assert_eq!((&connection["device"], &connection["verdict"]), (&"accepts".into(), &"agree".into()));
    }
    assert!(findings.iter().any(|f| f["what"] == "Param1 \"Serial baud rate\"" && f["device"] == "19200"));
}

/// `--log` follows the file's extension, as every program's does: an `.asc` name gets a Vector
/// ASCII trace, not candump text; a `.pcap` name (read, not written) is a usage error.
#[test]
fn check_device_log_is_written_in_the_format_its_extension_names() {
    let dir = temp_dir("check-device-log");
    let asc = dir.join("run.asc");
    let output =
        run(&["check-device", "--eds", &golden("breaker"), "--mac", "5", "--log", asc.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(0), "{}", stderr(&output));
    let text = std::fs::read_to_string(&asc).unwrap();
    assert_eq!(can_io::trace::detect(text.as_bytes()), Some(can_io::trace::TraceFormat::Asc), "{text}");
    assert!(text.trim_end().ends_with("End TriggerBlock"), "{text}");

    let pcap = dir.join("run.pcap");
    let output =
        run(&["check-device", "--eds", &golden("breaker"), "--mac", "5", "--log", pcap.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(2), "{}", stderr(&output));
    assert!(stderr(&output).contains("pcap"), "{}", stderr(&output));
    assert!(!pcap.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn check_device_disagreement_exits_1_naming_the_field() {
    let dir = temp_dir("check-device");
    let wrong = dir.join("wrong.eds");
    let text = std::fs::read_to_string(golden("breaker")).unwrap().replace("ProdCode = 1;", "ProdCode = 7;");
    std::fs::write(&wrong, text).unwrap();
    let output = run(&["check-device", "--eds", wrong.to_str().unwrap(), "--mac", "5"]);
    assert_eq!(output.status.code(), Some(1));
    let text = stdout(&output);
    assert!(text.contains("disagreement: product code (ProdCode): EDS 7, device 1"), "{text}");
    assert!(text.ends_with("MAC 5: 1 disagreement with the EDS\n"), "{text}");

    // The modbus meter's EDS against the breaker: sizes and path too (the strobe's 8 bytes agree).
    let output = run(&["check-device", "--eds", &golden("modbus-meter"), "--mac", "5", "--json"]);
    assert_eq!(output.status.code(), Some(1));
    let json: serde_json::Value = serde_json::from_str(&stdout(&output)).unwrap();
    assert_eq!(json["ok"], false);
    let expected = [
        "product code (ProdCode)",
        "produced size (Input1)",
        "produced path (Input1)",
        "consumed size (Output1)",
        "change-of-state produced size (Input1)",
        "cyclic produced size (Input1)",
    ];
    assert_eq!(disagreements(&json), expected);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn check_device_usage_and_file_errors_exit_2() {
    let cases: [(&[&str], &str); 6] = [
        (&["check-device", "--mac", "5"], "--eds <EDS>"),
        (&["check-device", "--eds", "/nonexistent/x.eds", "--mac", "5"], "cannot read /nonexistent/x.eds"),
        (&["check-device", "--eds", &corpus("syntax_error.eds"), "--mac", "5"], "syntax_error.eds:2:40"),
        (&["check-device", "--eds", EXTENDED, "--mac", "64"], "MAC ID 64 is out of range 0..=63"),
        (&["check-device", "--eds", EXTENDED, "--mac", "5", "--bus", "can0"], "unknown bus 'can0'"),
        (
            &[
                "check-device",
                "--eds",
                EXTENDED,
                "--mac",
                "5",
                "--bus",
                "socketcan:can0",
                "--slave-config",
                "x.toml",
            ],
            "needs --bus sim",
        ),
    ];
    for (args, message) in cases {
        let output = run(args);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {}", stderr(&output));
        assert!(stderr(&output).contains(message), "{args:?}: {}", stderr(&output));
        assert!(!stderr(&output).contains("panicked"));
    }
}

#[test]
fn check_device_refuses_a_clash_or_a_bad_description_with_exit_2() {
    // (A device that does not answer exits 1; the library test `no_device_is_an_error_not_a_
    // disagreement` covers it, since the simulated bus always has the device at --mac.)
    let output = run(&["check-device", "--eds", &golden("breaker"), "--mac", "5", "--master-mac", "5"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(stderr(&output).contains("the device's MAC 5 is the master's own MAC"), "{}", stderr(&output));

    let dir = temp_dir("bad-description");
    let empty = dir.join("empty.toml");
    std::fs::write(&empty, "").unwrap();
    let output = run(&[
        "check-device",
        "--eds",
        &golden("breaker"),
        "--mac",
        "5",
        "--slave-config",
        empty.to_str().unwrap(),
    ]);
    assert_eq!(output.status.code(), Some(2));
    let text = stderr(&output);
    assert!(
        text.contains("empty.toml: TOML parse error") && text.contains("missing field `identity`"),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn version_names_the_package_version_and_the_commit() {
    let output = run(&["--version"]);
    assert_eq!(output.status.code(), Some(0));
    let text = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(text.starts_with(concat!("dnet-eds ", env!("CARGO_PKG_VERSION"), " (")), "{text}");
}

#[test]
fn a_bus_that_cannot_be_opened_is_a_bus_error_exit_1() {
    let dir = temp_dir("bus-open");
    let eds = dir.join("breaker.eds");
    let output = run(&["generate", &description("breaker"), "-o", eds.to_str().unwrap()]);
    assert_eq!(output.status.code(), Some(0));
    let output = run(&[
        "check-device",
        "--eds",
        eds.to_str().unwrap(),
        "--mac",
        "5",
        "--bus",
        "slcan:/nonexistent/ttyACM9",
    ]);
    assert_eq!(output.status.code(), Some(1), "{}", stderr(&output));
    assert!(stderr(&output).contains("/nonexistent/ttyACM9"), "{}", stderr(&output));
    std::fs::remove_dir_all(&dir).unwrap();
}
