//! Per-unit health the way it is used: pymodbus's RTU server (the independent implementation)
//! serves units 1 and 2 on one end of a socat pty pair, `dnet-soft-slave` is the Modbus master on
//! the other with a scan list over both units and `valid_bits_offset = 4`, and `dnet-master`
//! polls it over SLCAN. Both data-valid bits are 1; then the server stops answering unit 2 (its
//! request handler drops unit 2's requests, as a unit that lost power would): unit 2's bit goes
//! to 0, unit 1's stays 1, and the unit table read over DeviceNet (class 0x69, `dnet-master units
//! --json` and `dnet-master get`) shows lost data and retries for unit 2 only, as do the unit
//! parameters of the EDS `dnet-eds generate` makes from the same description (checked by `dnet-eds
//! check`, read with `dnet-master params --eds`). The scenario is `modbus_units_support`'s, which
//! the QEMU test runs against the real firmware. Each `dnet-master` run starts with its own
//! duplicate MAC ID check (2 s): five runs in all.
//!
//! Needs socat, the test virtual environment (pymodbus) and the built `dnet-soft-slave`,
//! `dnet-master` and `dnet-eds`: ignored in the plain host-test run, run by `scripts/check` with
//! `-- --ignored`.

mod modbus_units_support;

use modbus_units_support::{exercise, DESCRIPTION, SERVER};
use pty_rig::pymodbus;
use pty_rig::{require_pymodbus, require_socat, scratch, soft_slave, Proc, PtyPair};
use std::time::Duration;

#[test]
#[ignore = "needs socat, pymodbus and the built programs: run by scripts/check"]
fn a_silent_unit_clears_its_valid_bit_and_counts_alone() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("modbus-units");
    let mute = dir.join("mute-unit-2");
    let _ = std::fs::remove_file(&mute);
    let serial = PtyPair::new();
    let server = Proc::spawn(&python, &["-c", SERVER, &serial.a, mute.to_str().unwrap()]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());
    let config = dir.join("modbus-units.toml");
    std::fs::write(&config, DESCRIPTION).unwrap();
    let can = PtyPair::new();
    let mut slave = soft_slave(&can, &serial.b, &config);
    // Ready once it reports the start (its SLCAN set-up done): a master before that races it.
    let end = std::time::Instant::now() + Duration::from_secs(10);
    while !slave.stderr.text().contains("started on") && std::time::Instant::now() < end {
        std::thread::sleep(Duration::from_millis(10));
    }
    let bus = format!("slcan:{}", can.b);

    exercise(&bus, &config, &dir, &mute, &[&slave, &server], true);

    let report = pymodbus::stop(&mut slave);
    assert!(report.contains("0 checksum and 0 framing errors"), "{report}");
    drop(server);
    let _ = std::fs::remove_file(&mute);
}
