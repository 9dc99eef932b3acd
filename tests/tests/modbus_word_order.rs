//! A scan entry's 32-bit `word_order` the way it is used: pymodbus's serial server (RTU, the
//! independent implementation) holds the REAL 123.45 (`0x42F6E666`) word-swapped (CDAB: registers
//! `0xE666 0x42F6`) and little-endian (DCBA: `0x66E6 0xF642`) on one end of a socat pty pair,
//! `dnet-soft-slave` is the master on the other, and `dnet-master monitor` polls the soft slave
//! over SLCAN. With `byte_order = "big_endian"` the poll data must carry each value as `42 F6 E6
//! 66`, and a CDAB write entry must put the output value into the registers word-swapped. (Big-
//! endian images, because there each order differs from the default of registers one by one: in a
//! little-endian image CDAB is what the default gives.)
//!
//! Needs socat, the test virtual environment (pymodbus) and the built `dnet-soft-slave` and
//! `dnet-master`: ignored in the plain host-test run, run by `scripts/check` with `-- --ignored`.

use pty_rig::pymodbus::{self, Link, Registers, Scan};
use pty_rig::{require_pymodbus, require_socat, scratch, soft_slave, PtyPair};
use slave_fw::serial::StatusByte;
use std::time::Duration;

/// Unit 1 of pymodbus's RTU server: holding registers 100..101 = 0xE666, 0x42F6 (123.45 CDAB),
/// 16..17 = 0, 0 (written by the gateway); input registers 0..1 = 0x66E6, 0xF642 (123.45 DCBA).
const REGISTERS: Registers<'static> =
    Registers { holding: &[(16, &[0, 0]), (100, &[0xE666, 0x42F6])], inputs: &[(0, &[0x66E6, 0xF642])] };

/// The gateway's `[profile.modbus]` table: RTU at 19200 8N1, big-endian images.
const MODBUS: &str = r#"response_timeout_ms = 300
retries = 1
poll_period_ms = 50
byte_order = "big_endian"

[profile.modbus.serial]
baud = 19200
data_bits = "eight"
parity = "none"
stop_bits = "one"
"#;

/// The gateway's scans: holding 100..101 (CDAB) to input bytes 0..3, input 0..1 (DCBA) to 4..7,
/// holding 16..17 (CDAB) read back to 8..11, output bytes 0..3 written to holding 16..17 (CDAB).
const SCANS: [Scan<'static>; 4] = [
    Scan { word_order: Some("cdab"), ..Scan::new(3, 100, 2, 0) },
    Scan { word_order: Some("dcba"), ..Scan::new(4, 0, 2, 4) },
    Scan { word_order: Some("cdab"), ..Scan::new(3, 16, 2, 8) },
    Scan { word_order: Some("cdab"), ..Scan::new(16, 16, 2, 0) },
];

/// 123.45 as a big-endian REAL.
const REAL: [u8; 4] = [0x42, 0xF6, 0xE6, 0x66];

#[test]
#[ignore = "needs socat, pymodbus and the built programs: run by scripts/check"]
fn register_pairs_reach_the_poll_data_and_the_instrument_in_their_word_order() {
    assert_eq!(f32::from_be_bytes(REAL), 123.45, "test setup: the REAL");
    if !require_socat() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("modbus-word-order");
    let serial = PtyPair::new();
    let server = pymodbus::server(&python, Link::Rtu(&serial.a), &REGISTERS);
    let config = dir.join("modbus-word-order.toml");
    std::fs::write(&config, pymodbus::description(14, MODBUS, &SCANS)).unwrap();
    let can = PtyPair::new();
    let mut slave = soft_slave(&can, &serial.b, &config);

    // The output REAL 123.45: holding registers 16..17 must become 0xE666, 0x42F6 (CDAB).
    let output: String = REAL.iter().map(|b| format!("{b:02X}")).collect();
    let last = pymodbus::last_poll(&format!("slcan:{}", can.b), &output, &[&slave, &server]);
    assert_eq!(last.len(), 14, "{last:02X?}");
    assert_eq!(&last[..4], &REAL, "holding registers 100..101, CDAB");
    assert_eq!(&last[4..8], &REAL, "input registers 0..1, DCBA");
    assert_eq!(&last[8..12], &REAL, "holding registers 16..17 read back after the CDAB write");
    assert_eq!(last[12] & 0x0F, StatusByte::LINK_OK, "link ok, no errors: {:#04X}", last[12]);
    let write = "write unit=1 function=16 address=16 values=0xE666,0x42F6";
    assert!(
        server.wait_stdout(write, Duration::from_secs(2)).is_some(),
        "the server saw {write}\n{}",
        server.dump()
    );

    let report = pymodbus::stop(&mut slave);
    assert!(report.contains("0 checksum and 0 framing errors, 0 timeouts"), "{report}");
    drop(server);
}
