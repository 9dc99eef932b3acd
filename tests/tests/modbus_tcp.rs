//! `dnet-master ui --modbus-tcp` as a process, read by an independent Modbus client: pymodbus
//! (`tests/python/modbus_tcp_client.py`) reads the status tables and every node's block and
//! compares each value with the console's `GET /api/state` and `GET /api/node/MAC`, checks that
//! writes and bad reads are refused with the documented exceptions, and sends hostile bytes over
//! raw TCP while the server keeps answering. Once on the simulated bus (a node in I/O and one
//! absent, so the faulted table is not empty), once on the real SLCAN path (the soft slave on a
//! socat pty pair, pty-rig). And the refusal of a non-loopback address (exit 2, before the bus).
//!
//! Needs the built `dnet-master` (and `dnet-soft-slave`, `dnet-sim-breaker` for the pty test),
//! the pymodbus virtual environment (`DNET_PYTHON`) and socat: ignored in the plain host-test run,
//! run by `scripts/check` with `-- --ignored`.

use pty_rig::console::{console_url, stop_ui};
use pty_rig::{bin, require_pymodbus, require_socat, scratch, workspace_dir, Proc, PtyRig};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

/// Connections allowed in the tests (the flood opens more).
const CONNECTIONS: &str = "4";

/// Starts `dnet-master BUS ui ...` with a Modbus TCP server on a free loopback port; the console's
/// URL and the Modbus address.
fn start_ui(bus: &str, extra: &[&str]) -> (Proc, String, String) {
    let mut args = vec![
        "--bus",
        bus,
        "ui",
        "--listen",
        "127.0.0.1:0",
        "--no-history",
        "--modbus-tcp",
        "127.0.0.1:0",
        "--modbus-tcp-connections",
        CONNECTIONS,
    ];
    args.extend_from_slice(extra);
    let p = Proc::spawn(bin("dnet-master"), &args);
    let modbus = p
        .wait_stdout("modbus tcp at ", Duration::from_secs(30))
        .unwrap_or_else(|| panic!("no Modbus TCP address\n{}", p.dump()));
    let console = console_url(&p, Duration::from_secs(30));
    let modbus = modbus.trim_start_matches("modbus tcp at ").trim().to_string();
    (p, console, modbus)
}

/// Waits until every node the console shows has left `initializing` (at most `limit`).
fn wait_scanning(console: &str, limit: Duration, python: &Path) {
    let script = "import json,sys,time,urllib.request\n\
        end=time.time()+float(sys.argv[2])\n\
        while time.time()<end:\n\
        \x20   s=json.load(urllib.request.urlopen(sys.argv[1]+'api/state'))\n\
        \x20   if s['nodes'] and s['cycles']>2 and all(n['status']!='initializing' for n in s['nodes']): sys.exit(0)\n\
        \x20   time.sleep(0.2)\n\
        sys.exit(1)\n";
    let ok = Command::new(python)
        .args(["-c", script, console, &limit.as_secs().to_string()])
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "the scanner never brought its nodes up within {limit:?}");
}

/// Runs the client against the server; its `compared:` line, after checking that it passed and
/// compared something.
fn run_client(python: &Path, console: &str, modbus: &str, min_nodes: usize, p: &Proc) -> String {
    let script = workspace_dir().join("tests/python/modbus_tcp_client.py");
    let out = Command::new(python)
        .arg(&script)
        .args(["--modbus", modbus, "--console", console, "--connections", CONNECTIONS])
        .args(["--min-nodes", &min_nodes.to_string()])
        .output()
        .expect("the Python client runs");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "client failed:\n{stdout}\n{stderr}\n{}", p.dump());
    let line = stdout.lines().find(|l| l.starts_with("compared: ")).unwrap_or_default().to_string();
    let values: usize =
        line.split_whitespace().nth(1).and_then(|n| n.parse().ok()).unwrap_or_else(|| panic!("{stdout}"));
    assert!(values >= 64 + 10 * min_nodes, "too little compared: {line}");
    line
}

#[test]
#[ignore = "needs the built dnet-master and the pymodbus venv: run by scripts/check"]
fn pymodbus_reads_the_tables_as_the_console_shows_them_on_the_simulated_bus() {
    let Some(python) = require_pymodbus() else { return };
    let dir = scratch("modbus-tcp-sim");
    // MAC 5 is the simulated device (18 bytes in, 8 out); nothing answers at MAC 20.
    let list = dir.join("plant.toml");
    std::fs::write(
        &list,
        "[[node]]\nmac = 5\ninput_size = 18\noutput_size = 8\n\n[[node]]\nmac = 20\ninput_size = 4\noutput_size = 2\n",
    )
    .unwrap();
    let (mut p, console, modbus) = start_ui("sim", &["--scanlist", list.to_str().unwrap()]);
    wait_scanning(&console, Duration::from_secs(60), &python);
    let line = run_client(&python, &console, &modbus, 2, &p);
    eprintln!("{line}");
    assert!(p.running(), "dnet-master still runs\n{}", p.dump());
    stop_ui(&mut p, Duration::from_secs(20), "");
}

#[test]
#[ignore = "needs socat, the built programs and the pymodbus venv: run by scripts/check"]
fn pymodbus_reads_the_soft_slave_over_slcan() {
    let Some(python) = require_pymodbus() else { return };
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("modbus-tcp", &["--period", "0.3"], None);
    let bus = rig.master_bus_arg();
    let (mut p, console, modbus) = start_ui(&bus, &[]);
    wait_scanning(&console, Duration::from_secs(90), &python);
    let line = run_client(&python, &console, &modbus, 1, &p);
    eprintln!("{line}");
    stop_ui(&mut p, Duration::from_secs(30), &rig.dump());
}

#[test]
#[ignore = "needs the built dnet-master: run by scripts/check"]
fn a_non_loopback_address_is_refused_before_the_bus() {
    // Any address but loopback without --modbus-tcp-public, a name instead of an address, and
    // --modbus-tcp-public alone (clap: it requires --modbus-tcp).
    for args in
        [&["--modbus-tcp", "0.0.0.0:0"][..], &["--modbus-tcp", "localhost:5020"], &["--modbus-tcp-public"]]
    {
        let out = Command::new(bin("dnet-master"))
            .args(["--bus", "sim", "ui", "--listen", "127.0.0.1:0", "--no-history", "--cycles", "1"])
            .args(args)
            .output()
            .expect("dnet-master runs");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stdout}\n{stderr}");
        assert!(!stdout.contains("console at"), "{args:?}: the console started: {stdout}");
        assert!(stderr.contains("--modbus-tcp"), "{args:?}: {stderr}");
    }
}
