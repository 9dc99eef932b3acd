//! The Modbus RTU profile against a real Modbus slave: pymodbus (`tests/modbus/server.py`) on one
//! end of a socat pty pair, `dnet-soft-slave` as the RTU master on the other, its CAN side SLCAN
//! on a second pty pair with the master harness at the far end.
//!
//! These need socat and the test virtual environment (`.venv` with pymodbus and pyserial, or
//! `DNET_PYTHON`), so they are ignored in the plain host-test run and run by the `scripts/check`
//! stage "serial bridge on ptys (socat, pymodbus)". Without the tools they skip with a message,
//! except in CI (`CI=true`), where they fail.

mod common;

use common::{bring_up, link_attribute, poll_until, require_pymodbus, require_socat, PtyRig};
use devicenet::Duration;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use slave_fw::serial::StatusByte;

/// Input registers 0..3 of the server, little-endian in the image.
const INPUT_REGISTERS: [u8; 8] = [0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07];
/// Holding registers 100..101 (0xABCD, 0x1234).
const HOLDING_100: [u8; 4] = [0xCD, 0xAB, 0x34, 0x12];

#[test]
#[ignore = "needs socat and pymodbus: run by scripts/check"]
fn reads_land_in_the_poll_response_and_writes_reach_the_registers() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let rig = PtyRig::modbus("modbus-ok", &python, &common::description("modbus-gateway.toml"));
    let mut bus = common::master_bus(&rig);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let summary = bring_up(&mut master);
    assert_eq!((summary.produced_size, summary.consumed_size), (Some(18), Some(4)));

    // The output bytes go to holding registers 16..17 (function 16); the scan list reads them back.
    for output in [[0x11, 0x22, 0x33, 0x44], [0x55, 0x66, 0x77, 0x88]] {
        let (input, _) =
            poll_until(&mut master, &summary, &output, Duration::from_secs(5), |i| i[12..16] == output);
        assert_eq!(&input[..8], &INPUT_REGISTERS, "input registers 0..3\n{}", rig.dump());
        assert_eq!(&input[8..12], &HOLDING_100, "holding registers 100..101");
        let status = input[16];
        assert_eq!(status & 0x0F, StatusByte::LINK_OK, "link ok, no errors: {status:#04X}");
        assert_eq!(StatusByte::from_raw(status).command_code(), 2, "last write ok: {status:#04X}");
        assert_eq!(status & StatusByte::REQUEST_TIMEOUT, 0);
        let registers = format!(
            "write unit=1 function=16 address=16 values=0x{:02X}{:02X},0x{:02X}{:02X}",
            output[1], output[0], output[3], output[2]
        );
        assert!(
            rig.instrument.wait_stdout(&registers, std::time::Duration::from_secs(2)).is_some(),
            "the server saw {registers}\n{}",
            rig.dump()
        );
    }
    assert_eq!(link_attribute(&mut master, 9), 0, "no Modbus exceptions (0x64/1/9)");
    assert_eq!(link_attribute(&mut master, 4), 0, "no timeouts (0x64/1/4)");
    assert_eq!(link_attribute(&mut master, 5), 2, "two writes of changed outputs (0x64/1/5)");
    assert!(link_attribute(&mut master, 1) >= 6, "responses received (0x64/1/1)");
    let (profile, _) = master.get(common::mac(), 0x65, 1, 11).unwrap();
    assert_eq!(profile, vec![1], "the settings object says Modbus (0x65/1/11)");
    assert_eq!(master.session.failures(), 0);
}

#[test]
#[ignore = "needs socat and pymodbus: run by scripts/check"]
fn an_exception_and_a_timeout_are_reported() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    // Scan list: a good read, holding register 2000 (not on the server: exception 02), unit 9 (no
    // such slave: no answer), and a write of output bytes 0..1 to holding register 16.
    let rig = PtyRig::modbus("modbus-faults", &python, &common::description("modbus-faults.toml"));
    let mut bus = common::master_bus(&rig);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let summary = bring_up(&mut master);
    assert_eq!(summary.produced_size, Some(14));

    let both = StatusByte::EXCEPTION | StatusByte::REQUEST_TIMEOUT;
    let (input, _) =
        poll_until(&mut master, &summary, &[0x34, 0x12], Duration::from_secs(5), |i| i[12] & both == both);
    assert_eq!(&input[..8], &INPUT_REGISTERS, "the good read still lands\n{}", rig.dump());
    assert_eq!(&input[8..12], &[0; 4], "nothing for the failed reads");
    assert_ne!(input[12] & StatusByte::LINK_OK, 0, "the line itself is alive: {:#04X}", input[12]);
    assert!(
        rig.instrument
            .wait_stdout(
                "write unit=1 function=6 address=16 values=0x1234",
                std::time::Duration::from_secs(2)
            )
            .is_some(),
        "{}",
        rig.dump()
    );
    let exceptions = link_attribute(&mut master, 9);
    let timeouts = link_attribute(&mut master, 4);
    assert!(exceptions >= 1, "Modbus exceptions (0x64/1/9): {exceptions}");
    assert!(timeouts >= 2, "every attempt to unit 9 times out (0x64/1/4): {timeouts}");
    assert_eq!(link_attribute(&mut master, 7), 0, "the write did not fail (0x64/1/7)");
    assert_eq!(master.session.failures(), 0);
}
