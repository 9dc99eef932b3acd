//! `dnet-master ui --sim-unpaced`, through the program: refused with a real bus (exit 2, before the
//! port is opened or the console listens, on the real SLCAN path too) and with `--plant`; on the
//! simulated bus an unpaced run with `--cycles N` brings its nodes into I/O, runs to the end and
//! prints its table. How fast it runs is a figure (`scripts/soak-sparkplug`), not a test: on a
//! loaded machine the unpaced simulation may run slower than real time.

use pty_rig::{require_socat, PtyRig};
use std::process::{Command, Output};

fn dnet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dnet-master")).args(args).output().expect("run dnet-master")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// Refused, exit 2, the option and the bus named, and nothing served.
fn assert_refused(o: &Output, bus: &str) {
    assert_eq!(o.status.code(), Some(2), "{}", text(o));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("--sim-unpaced") && stderr.contains("--bus sim"), "{}", text(o));
    assert!(stderr.contains(bus), "the bus given is named: {}", text(o));
    assert!(!text(o).contains("console at"), "refused before the console listens: {}", text(o));
}

#[test]
fn refused_with_a_real_bus_before_its_port_is_opened() {
    // A missing port would be refused where it is opened, naming the port: the option's refusal
    // comes first.
    let bus = "slcan:/nonexistent/ttyACM9";
    let o = dnet(&["--bus", bus, "ui", "--sim-unpaced", "--listen", "127.0.0.1:0", "--no-history"]);
    assert_refused(&o, bus);
    assert!(!text(&o).contains("No such file"), "{}", text(&o));
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn refused_on_the_real_slcan_path() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("ui-sim-unpaced", &[], None);
    let bus = rig.master_bus_arg();
    let o = dnet(&[
        "--bus",
        &bus,
        "ui",
        "--sim-unpaced",
        "--listen",
        "127.0.0.1:0",
        "--no-history",
        "--cycles",
        "5",
    ]);
    assert_refused(&o, &bus);
}

#[test]
fn refused_with_a_plant_file() {
    let o =
        dnet(&["--bus", "sim", "ui", "--sim-unpaced", "--plant", "plant.toml", "--listen", "127.0.0.1:0"]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("--plant"), "{}", text(&o));
}

#[test]
fn an_unpaced_run_reaches_its_cycles_and_prints_its_table() {
    let o = dnet(&[
        "--bus",
        "sim",
        "--slave-mac",
        "5,6",
        "ui",
        "--sim-unpaced",
        "--listen",
        "127.0.0.1:0",
        "--no-history",
        "--cycles",
        "200",
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.lines().next().is_some_and(|l| l.starts_with("console at http://127.0.0.1:")), "{out}");
    for mac in ["  5  ok", "  6  ok"] {
        assert!(out.lines().any(|l| l.starts_with(mac)), "node{mac}: {out}");
    }
    assert!(out.contains("200 cycle(s)"), "{out}");
}
