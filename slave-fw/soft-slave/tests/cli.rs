//! The two command lines: help everywhere, and precise errors with the documented exit status
//! (2 usage or configuration, 1 hardware), without any serial port or CAN adapter.

use std::process::{Command, Output};

fn run(bin: &str, args: &[&str]) -> Output {
    Command::new(bin).args(args).output().expect("run the binary")
}

fn soft(args: &[&str]) -> Output {
    run(env!("CARGO_BIN_EXE_dnet-soft-slave"), args)
}

fn breaker(args: &[&str]) -> Output {
    run(env!("CARGO_BIN_EXE_dnet-sim-breaker"), args)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn help_everywhere() {
    let o = soft(&["--help"]);
    assert_eq!(o.status.code(), Some(0));
    let text = String::from_utf8_lossy(&o.stdout);
    for option in ["--bus", "--serial", "--config", "--mac", "--log", "--duration", "SIGTERM"] {
        assert!(text.contains(option), "{option} in\n{text}");
    }
    let o = breaker(&["--help"]);
    assert_eq!(o.status.code(), Some(0));
    let text = String::from_utf8_lossy(&o.stdout);
    for option in ["--serial", "--silent-after", "--garbage-every", "--log", "--closed", "--load"] {
        assert!(text.contains(option), "{option} in\n{text}");
    }
    for o in [soft(&["--version"]), breaker(&["--version"])] {
        assert_eq!(o.status.code(), Some(0));
        // The package version and the git commit it was built from.
        let text = String::from_utf8_lossy(&o.stdout).into_owned();
        assert!(text.contains(concat!(" ", env!("CARGO_PKG_VERSION"), " (")), "{text}");
    }
}

#[test]
fn the_simulated_bus_is_refused_with_a_reason() {
    let o = soft(&["--bus", "sim", "--serial", "/dev/null"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("the soft slave needs a real bus"), "{}", stderr(&o));
}

#[test]
fn missing_arguments_are_usage_errors() {
    let o = soft(&["--bus", "socketcan:can0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--serial <PORT>"), "{}", stderr(&o));
    let o = breaker(&["--serial", "/dev/null", "--load", "1,2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("expected four currents"), "{}", stderr(&o));
    let o = breaker(&["--serial", "/dev/null", "--garbage-every", "0"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("at least 0.001 s"), "{}", stderr(&o));
}

#[test]
fn a_bad_description_names_the_file_and_the_key() {
    let dir = std::env::temp_dir().join(format!("soft-slave-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.toml");
    let good = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../descriptions/breaker.toml"))
        .unwrap();
    std::fs::write(&path, good.replace("mac_id = 5", "mac_id = 70")).unwrap();
    let o = soft(&["--bus", "socketcan:can0", "--serial", "/dev/null", "--config", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(err.contains("bad.toml: line 17: network.mac_id: 70 is outside 0..=63"), "{err}");
}

/// Issue 33: `parityy = "even"` in `[profile.serial]` used to be ignored and the soft slave ran.
/// A misspelt key in a nested table is refused before anything is opened, with the file, the
/// line and the dotted key (exit 2).
#[test]
fn a_misspelt_key_in_a_nested_table_is_refused_with_file_line_and_key() {
    let dir = std::env::temp_dir().join(format!("soft-slave-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("typo.toml");
    let good = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../descriptions/breaker.toml"))
        .unwrap();
    let bad = good.replacen("parity = \"none\"", "parity = \"none\"\nparityy = \"even\"", 1);
    let line = bad.lines().position(|l| l.starts_with("parityy")).unwrap() + 1;
    std::fs::write(&path, bad).unwrap();
    let o = soft(&["--bus", "socketcan:can0", "--serial", "/dev/null", "--config", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    let expected =
        format!("typo.toml: TOML parse error at line {line}, column 1: profile.serial.parityy: unknown key");
    assert!(err.contains(&expected), "{err}");
}

#[test]
fn a_missing_serial_port_is_named_with_its_settings() {
    let o = soft(&["--bus", "socketcan:can0", "--serial", "/dev/no-such-port", "--quiet"]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(err.contains("cannot open the serial port '/dev/no-such-port' (9600 8N1)"), "{err}");
    let modbus = concat!(env!("CARGO_MANIFEST_DIR"), "/../descriptions/modbus-meter.toml");
    let o = soft(&["--bus", "socketcan:can0", "--serial", "/dev/no-such-port", "--config", modbus]);
    assert!(stderr(&o).contains("(19200 8E1)"), "{}", stderr(&o));
    let o = breaker(&["--serial", "/dev/no-such-port"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("cannot open the serial port '/dev/no-such-port' (9600 8N1)"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn an_unknown_mutant_is_refused_with_the_list_of_mutants() {
    let out = soft(&["--bus", "slcan:/dev/null", "--serial", "/dev/null", "--mutant", "nonsense"]);
    assert_eq!(out.status.code(), Some(2));
    let err = stderr(&out);
    assert!(err.contains("no mutant \"nonsense\"") && err.contains("answers-ucmm"), "{err}");
}

/// A scratch folder of this test process.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("soft-slave-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Issue 33: an unwritable `--log` made both programs exit 1; it is an output file that cannot be
/// written, a usage error (guide, "Exit status": 2), named, and found before the serial port or
/// the bus is opened (their paths here do not exist: those would fail with 1).
#[test]
fn an_unwritable_log_is_a_usage_error_naming_the_file() {
    let o = soft(&[
        "--bus",
        "socketcan:nonexistent0",
        "--serial",
        "/dev/no-such-port",
        "--log",
        "/nonexistent/bus.log",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("log file '/nonexistent/bus.log'"), "{}", stderr(&o));
    let o = breaker(&["--serial", "/dev/no-such-port", "--log", "/nonexistent/events.log"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("log file '/nonexistent/events.log'"), "{}", stderr(&o));
}

/// `--log` named for a format that is not written, or `--format` naming one, is refused before
/// anything is opened; `--format` without `--log` is a usage error.
#[test]
fn a_log_format_that_is_not_written_is_a_usage_error() {
    let dir = scratch("log-format");
    let pcap = dir.join("bus.pcap");
    let o = soft(&[
        "--bus",
        "socketcan:nonexistent0",
        "--serial",
        "/dev/no-such-port",
        "--log",
        pcap.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("the extension names pcap, which --log does not write"), "{}", stderr(&o));
    assert!(!pcap.exists());
    let log = dir.join("bus.log");
    let args =
        ["--bus", "socketcan:nonexistent0", "--serial", "/dev/no-such-port", "--log", log.to_str().unwrap()];
    let o = soft(&[&args[..], &["--format", "blf"]].concat());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--format blf: --log writes candump, trc, asc or csv"), "{}", stderr(&o));
    let o = soft(&["--bus", "socketcan:nonexistent0", "--serial", "/dev/null", "--format", "asc"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--log <FILE>"), "{}", stderr(&o));
}

/// Issue 33: `--state` in a folder that cannot be written went on-line and quit (exit 2) only
/// when a master allocated the device. It is refused at start, before the serial port and the bus
/// are opened (their paths here do not exist: either would fail with 1), and nothing is left.
#[test]
fn an_unwritable_state_file_is_refused_at_start() {
    let o = soft(&[
        "--bus",
        "socketcan:nonexistent0",
        "--serial",
        "/dev/no-such-port",
        "--state",
        "/nonexistent/s.json",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("state file /nonexistent/s.json: cannot write"), "{}", stderr(&o));
    // A folder that exists but is not writable (unless the tests run as root, who may write it).
    let dir = scratch("read-only");
    let mut perms = std::fs::metadata(&dir).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perms, 0o555);
    std::fs::set_permissions(&dir, perms).unwrap();
    let probe = std::fs::File::create(dir.join("probe"));
    let root = probe.is_ok();
    let _ = std::fs::remove_file(dir.join("probe"));
    if !root {
        let state = dir.join("s.json");
        let o = soft(&[
            "--bus",
            "socketcan:nonexistent0",
            "--serial",
            "/dev/no-such-port",
            "--state",
            state.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!("state file {}: cannot write", state.display())),
            "{}",
            stderr(&o)
        );
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "nothing left in the folder");
    }
}
