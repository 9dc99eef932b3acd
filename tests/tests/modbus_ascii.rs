//! The Modbus profile with `framing = "ascii"` the way it is used: pymodbus's ASCII framer
//! (`FramerType.ASCII`, the independent implementation) serves unit 1 on one end of a socat pty
//! pair, `dnet-soft-slave` is the ASCII master on the other, and `dnet-master monitor` polls the
//! soft slave over SLCAN on a second pty pair. The poll data must carry the registers read, the
//! output must reach the holding registers, and the soft slave must count no LRC, framing or
//! timeout errors.
//!
//! The pty carries bytes, not characters: the 7-bit character format of §2.5.2.1 is not modelled
//! here (8N1 on both ends); the LRC, the hexadecimal encoding and the `:` … CR LF framing are.
//!
//! Needs socat, the test virtual environment (pymodbus) and the built `dnet-soft-slave` and
//! `dnet-master`: ignored in the plain host-test run, run by `scripts/check` with `-- --ignored`.

use pty_rig::pymodbus::{self, Link, GATEWAY_REGISTERS};
use pty_rig::{require_pymodbus, require_socat, scratch, soft_slave, PtyPair};
use slave_fw::serial::StatusByte;
use std::time::Duration;

/// The gateway's `[profile.modbus]` table: Modbus ASCII at 19200 8N1.
const MODBUS_ASCII: &str = r#"framing = "ascii"
response_timeout_ms = 300
retries = 1
poll_period_ms = 50

[profile.modbus.serial]
baud = 19200
data_bits = "eight"
parity = "none"
stop_bits = "one"
"#;

#[test]
#[ignore = "needs socat, pymodbus and the built programs: run by scripts/check"]
fn a_modbus_ascii_instrument_fills_the_poll_data_and_takes_the_written_output() {
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("modbus-ascii");
    let serial = PtyPair::new();
    let server = pymodbus::server(&python, Link::Ascii(&serial.a), &GATEWAY_REGISTERS);
    let config = dir.join("modbus-ascii-gateway.toml");
    std::fs::write(&config, pymodbus::gateway_description(MODBUS_ASCII)).unwrap();
    let can = PtyPair::new();
    let mut slave = soft_slave(&can, &serial.b, &config);

    // Output bytes 11 22 33 44: holding registers 16..17 = 0x2211, 0x4433 (little-endian image).
    let last = pymodbus::last_poll(&format!("slcan:{}", can.b), "11223344", &[&slave, &server]);
    assert_eq!(last.len(), 18, "{last:02X?}");
    assert_eq!(&last[..8], &[0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07], "input registers 0..3");
    assert_eq!(&last[8..12], &[0xCD, 0xAB, 0x34, 0x12], "holding registers 100..101");
    assert_eq!(
        &last[12..16],
        &[0x11, 0x22, 0x33, 0x44],
        "holding registers 16..17 read back after the write"
    );
    assert_eq!(last[16] & 0x0F, StatusByte::LINK_OK, "link ok, no errors: {:#04X}", last[16]);
    let write = "write unit=1 function=16 address=16 values=0x2211,0x4433";
    assert!(
        server.wait_stdout(write, Duration::from_secs(2)).is_some(),
        "the server saw {write}\n{}",
        server.dump()
    );

    let report = pymodbus::stop(&mut slave);
    assert!(report.contains("0 checksum and 0 framing errors, 0 timeouts"), "{report}");
    drop(server);
}
