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

use pty_rig::{bin, require_pymodbus, require_socat, scratch, Proc, PtyPair};
use serde_json::Value;
use slave_fw::serial::StatusByte;
use std::time::Duration;

/// pymodbus's serial server with the ASCII framer on the pty `argv[1]`, unit 1: input registers
/// 0..3 = 0x0102, 0x0304, 0x0506, 0x0708; holding registers 16..17 = 0, 0 (the gateway writes
/// here); 100..101 = 0xABCD, 0x1234. Prints `ready`, and one line per write.
const MODBUS_ASCII_SERVER: &str = r#"
import asyncio, sys
from pymodbus.framer import FramerType
from pymodbus.server import ModbusSerialServer
from pymodbus.simulator import DataType, SimData, SimDevice

async def on_access(function_code, _start, address, _count, _registers, set_values):
    if set_values is not None:
        values = ",".join(f"0x{int(v):04X}" for v in set_values)
        print(f"write unit=1 function={function_code} address={address} values={values}", flush=True)
    return None

async def main():
    bits = [SimData(address=0, values=[False], datatype=DataType.BITS)]
    holding = [SimData(address=16, values=[0, 0], datatype=DataType.REGISTERS),
               SimData(address=100, values=[0xABCD, 0x1234], datatype=DataType.REGISTERS)]
    inputs = [SimData(address=0, values=[0x0102, 0x0304, 0x0506, 0x0708], datatype=DataType.REGISTERS)]
    device = SimDevice(id=1, simdata=(bits, list(bits), holding, inputs), action=on_access)
    server = ModbusSerialServer(device, framer=FramerType.ASCII, port=sys.argv[1], baudrate=19200,
                                bytesize=8, parity="N", stopbits=1)
    await server.serve_forever(background=True)
    print("ready", flush=True)
    await asyncio.Event().wait()

asyncio.run(main())
"#;

/// The gateway: input registers 0..3 to input bytes 0..7, holding 100..101 to 8..11, holding
/// 16..17 read back to 12..15, output bytes 0..3 written to holding 16..17; over Modbus ASCII.
const MODBUS_ASCII_GATEWAY: &str = r#"
[identity]
vendor_id = 0x1234
device_type = 0x000C
product_code = 2
major_revision = 1
minor_revision = 0
serial_number = 0x00C0FFEE
product_name = "Modbus-DeviceNet Gateway"

[network]
mac_id = 5
baud_rate = "250k"

[io]
input_assembly = "with_status"
produced_size = 18
consumed_size = 4

[profile]
kind = "modbus"

[profile.modbus]
framing = "ascii"
response_timeout_ms = 300
retries = 1
poll_period_ms = 50

[profile.modbus.serial]
baud = 19200
data_bits = "eight"
parity = "none"
stop_bits = "one"

[profile.modbus.health]
stale_timeout_ms = 1000
stale_policy = "clear"

[[profile.modbus.scan]]
unit = 1
function = 4
address = 0
count = 4
offset = 0

[[profile.modbus.scan]]
unit = 1
function = 3
address = 100
count = 2
offset = 8

[[profile.modbus.scan]]
unit = 1
function = 3
address = 16
count = 2
offset = 12

[[profile.modbus.scan]]
unit = 1
function = 16
address = 16
count = 2
offset = 0
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
    let server = Proc::spawn(&python, &["-c", MODBUS_ASCII_SERVER, &serial.a]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());
    let config = dir.join("modbus-ascii-gateway.toml");
    std::fs::write(&config, MODBUS_ASCII_GATEWAY).unwrap();
    let can = PtyPair::new();
    let bus = format!("slcan:{}", can.a);
    let mut slave = Proc::spawn(
        bin("dnet-soft-slave"),
        &["--bus", &bus, "--serial", &serial.b, "--config", config.to_str().unwrap()],
    );

    // Output bytes 11 22 33 44: holding registers 16..17 = 0x2211, 0x4433 (little-endian image).
    let master_bus = format!("slcan:{}", can.b);
    let mut monitor = Proc::spawn(
        bin("dnet-master"),
        &[
            "--bus",
            &master_bus,
            "--json",
            "monitor",
            "--mac",
            "5",
            "--epr",
            "100",
            "--count",
            "30",
            "--output",
            "11223344",
        ],
    );
    let status = monitor.wait(Duration::from_secs(60));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "monitor\n{}\n{}", monitor.dump(), slave.dump());
    let json: Value = serde_json::from_str(monitor.stdout.text().trim())
        .unwrap_or_else(|e| panic!("monitor's JSON: {e}\n{}", monitor.dump()));
    let list = json["samples"].as_array().unwrap_or_else(|| panic!("no samples in {json}"));
    let last: Vec<u8> = list.last().unwrap_or_else(|| panic!("no sample: {json}"))["raw"]
        .as_array()
        .unwrap()
        .iter()
        .map(|b| u8::try_from(b.as_u64().unwrap()).unwrap())
        .collect();
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

    let status = slave.terminate();
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{}", slave.dump());
    let report = slave.stderr.text();
    assert!(report.contains("0 checksum and 0 framing errors, 0 timeouts"), "{report}");
    drop(server);
}
