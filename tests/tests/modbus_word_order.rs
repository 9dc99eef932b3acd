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

use pty_rig::{bin, require_pymodbus, require_socat, scratch, Proc, PtyPair};
use serde_json::Value;
use slave_fw::serial::StatusByte;
use std::time::Duration;

/// pymodbus's RTU server on the pty `argv[1]`, unit 1: holding registers 100..101 = 0xE666,
/// 0x42F6 (123.45 CDAB), 16..17 = 0, 0 (written by the gateway); input registers 0..1 = 0x66E6,
/// 0xF642 (123.45 DCBA). Prints `ready`, and one line per write.
const SERVER: &str = r#"
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
               SimData(address=100, values=[0xE666, 0x42F6], datatype=DataType.REGISTERS)]
    inputs = [SimData(address=0, values=[0x66E6, 0xF642], datatype=DataType.REGISTERS)]
    device = SimDevice(id=1, simdata=(bits, list(bits), holding, inputs), action=on_access)
    server = ModbusSerialServer(device, framer=FramerType.RTU, port=sys.argv[1], baudrate=19200,
                                bytesize=8, parity="N", stopbits=1)
    await server.serve_forever(background=True)
    print("ready", flush=True)
    await asyncio.Event().wait()

asyncio.run(main())
"#;

/// The gateway: holding 100..101 (CDAB) to input bytes 0..3, input 0..1 (DCBA) to 4..7, holding
/// 16..17 (CDAB) read back to 8..11, output bytes 0..3 written to holding 16..17 (CDAB).
const GATEWAY: &str = r#"
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
produced_size = 14
consumed_size = 4

[profile]
kind = "modbus"

[profile.modbus]
response_timeout_ms = 300
retries = 1
poll_period_ms = 50
byte_order = "big_endian"

[profile.modbus.serial]
baud = 19200
data_bits = "eight"
parity = "none"
stop_bits = "one"

[[profile.modbus.scan]]
unit = 1
function = 3
address = 100
count = 2
offset = 0
word_order = "cdab"

[[profile.modbus.scan]]
unit = 1
function = 4
address = 0
count = 2
offset = 4
word_order = "dcba"

[[profile.modbus.scan]]
unit = 1
function = 3
address = 16
count = 2
offset = 8
word_order = "cdab"

[[profile.modbus.scan]]
unit = 1
function = 16
address = 16
count = 2
offset = 0
word_order = "cdab"
"#;

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
    let server = Proc::spawn(&python, &["-c", SERVER, &serial.a]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());
    let config = dir.join("modbus-word-order.toml");
    std::fs::write(&config, GATEWAY).unwrap();
    let can = PtyPair::new();
    let bus = format!("slcan:{}", can.a);
    let mut slave = Proc::spawn(
        bin("dnet-soft-slave"),
        &["--bus", &bus, "--serial", &serial.b, "--config", config.to_str().unwrap()],
    );

    // The output REAL 123.45: holding registers 16..17 must become 0xE666, 0x42F6 (CDAB).
    let master_bus = format!("slcan:{}", can.b);
    let output: String = REAL.iter().map(|b| format!("{b:02X}")).collect();
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
            &output,
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

    let status = slave.terminate();
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{}", slave.dump());
    let report = slave.stderr.text();
    assert!(report.contains("0 checksum and 0 framing errors, 0 timeouts"), "{report}");
    drop(server);
}
