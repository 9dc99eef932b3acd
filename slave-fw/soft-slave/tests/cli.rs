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
    assert!(stderr(&o).contains("--serial <PATH>"), "{}", stderr(&o));
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
    assert!(err.contains("bad.toml: network.mac_id: 70 is outside 0..=63"), "{err}");
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
