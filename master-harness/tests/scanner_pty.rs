//! `dnet-master scanner` on the real SLCAN path: the program against `dnet-soft-slave` on SLCAN
//! over a socat pty pair, with `dnet-sim-breaker` as its instrument. The scan list is built by a
//! network scan, node 5 is kept in I/O for a few cycles and ends ok with the breaker's product
//! name; the `--json` summary parses.
//!
//! Needs socat and the soft slave's binaries (`cargo build -p soft-slave`): ignored in the plain
//! host-test run, run by `scripts/check`; skips with a message without socat.

use pty_rig::{require_socat, Proc, PtyRig};
use std::time::Duration;

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn scanner_keeps_the_soft_slave_in_io_over_slcan() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("scanner", &["--period", "0.3"], None);
    let bus = rig.master_bus_arg();
    let list = pty_rig::scratch("scanner-list").join("scanlist.toml");
    let list_arg = list.to_str().unwrap().to_string();
    let args =
        ["--bus", bus.as_str(), "--json", "scanner", "--cycles", "20", "--write-scanlist", list_arg.as_str()];
    let mut p = Proc::spawn(env!("CARGO_BIN_EXE_dnet-master"), &args);
    let status = p.wait(Duration::from_secs(90)).unwrap_or_else(|| panic!("scanner hangs\n{}", p.dump()));
    let out = p.stdout.text();
    assert_eq!(status.code(), Some(0), "{out}\n{}\n{}", p.stderr.text(), rig.dump());
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"));
    let nodes = v["nodes"].as_array().unwrap();
    let n5 = nodes.iter().find(|n| n["mac"] == 5).unwrap_or_else(|| panic!("no MAC 5: {v}"));
    assert_eq!(n5["status"], "ok", "{n5}");
    assert_eq!(n5["code"], 0);
    assert_eq!(n5["product_name"], "Serial-DeviceNet Bridge");
    assert_eq!((n5["input_size"].as_u64(), n5["output_size"].as_u64()), (Some(18), Some(8)));
    assert!(n5["exchanges"].as_u64().unwrap() >= 20, "{n5}");
    assert!(v["cycle_ms"].as_f64().unwrap() > 0.0, "{v}");
    assert!(std::fs::read_to_string(&list).unwrap().contains("mac = 5"));
    // The scan list written is read back by the next run.
    let args = ["--bus", bus.as_str(), "--json", "scanner", "--cycles", "5", "--scanlist", list_arg.as_str()];
    let mut p = Proc::spawn(env!("CARGO_BIN_EXE_dnet-master"), &args);
    let status = p.wait(Duration::from_secs(60)).unwrap_or_else(|| panic!("scanner hangs\n{}", p.dump()));
    assert_eq!(status.code(), Some(0), "{}\n{}", p.stdout.text(), p.stderr.text());
}
