//! Per-entry scheduling the way it is used: pymodbus's RTU server (the independent
//! implementation) on one end of a socat pty pair logs every request it serves with its time;
//! `dnet-soft-slave` is the Modbus master on the other end with a scan list of a read every scan
//! cycle (50 ms), a read with `period_ms = 1000`, and a function-16 write with
//! `write = "trigger"` on output byte 4; `dnet-master monitor` polls the soft slave over SLCAN with
//! three output images in turn. The server's log must show the slow entry read about once a
//! second while the cycle's read goes about twenty times as often, and the triggered write
//! reaching the instrument exactly once, only after the trigger byte changed: not for the first
//! image, nor when only its data bytes changed.
//!
//! Needs socat, the test virtual environment (pymodbus) and the built `dnet-soft-slave` and
//! `dnet-master`: ignored in the plain host-test run, run by `scripts/check` with `-- --ignored`.

mod modbus_schedule_support;

use modbus_schedule_support::{exercise, DESCRIPTION, SERVER};
use pty_rig::{require_pymodbus, require_socat, scratch, soft_slave, Proc, PtyPair};
use std::time::Duration;

#[test]
#[ignore = "needs socat, pymodbus and the built programs: run by scripts/check"]
fn a_slow_entry_is_read_less_often_and_a_triggered_write_waits_for_its_trigger_byte() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("modbus-schedule");
    let serial = PtyPair::new();
    let server = Proc::spawn(&python, &["-c", SERVER, &serial.a]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());
    let config = dir.join("modbus-schedule.toml");
    std::fs::write(&config, DESCRIPTION).unwrap();
    let can = PtyPair::new();
    let slave = soft_slave(&can, &serial.b, &config);
    let bus = format!("slcan:{}", can.b);
    exercise(&bus, &server, &[&slave], 0.9..1.2);
}
