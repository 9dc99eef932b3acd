//! The per-unit health scenario shared by the pty test (`modbus_units.rs`, the soft slave) and
//! the QEMU test (`qemu_modbus_units.rs`, the real firmware): pymodbus's RTU server with units 1
//! and 2 and a switch that silences unit 2, the gateway description, and the runs of
//! `dnet-master` and `dnet-eds` with their checks.

use pty_rig::{bin, pymodbus, Proc};
use serde_json::Value;
use slave_fw::serial::StatusByte;
use std::path::Path;
use std::time::Duration;

/// The server: `PTY MUTE_FILE`. Units 1 and 2, holding register 0 = 0x1111 and 0x2222; while
/// `MUTE_FILE` exists, requests to unit 2 are dropped unanswered (pymodbus's `trace_pdu` hook
/// returning no request). Prints `ready` once it serves.
pub const SERVER: &str = r#"
import asyncio, os, sys
from pymodbus.framer import FramerType
from pymodbus.server import ModbusSerialServer
from pymodbus.simulator import DataType, SimData, SimDevice

port, mute = sys.argv[1], sys.argv[2]

def device(unit, value):
    bits = [SimData(address=0, values=[False], datatype=DataType.BITS)]
    regs = [SimData(address=0, values=[value], datatype=DataType.REGISTERS)]
    return SimDevice(id=unit, simdata=(bits, list(bits), regs, list(regs)))

def trace_pdu(sending, pdu):
    if not sending and pdu.dev_id == 2 and os.path.exists(mute):
        return None
    return pdu

async def main():
    server = ModbusSerialServer([device(1, 0x1111), device(2, 0x2222)], framer=FramerType.RTU, port=port,
                                baudrate=19200, bytesize=8, parity="N", stopbits=1, trace_pdu=trace_pdu)
    await server.serve_forever(background=True)
    print("ready", flush=True)
    await asyncio.Event().wait()

asyncio.run(main())
"#;

/// The gateway: unit 1 holding 0 → input bytes 0..1, unit 2 holding 0 → 2..3, the data-valid bits
/// at byte 4; with the status assembly 7 bytes. Two retries of 100 ms each.
pub const DESCRIPTION: &str = r#"[identity]
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

[profile]
kind = "modbus"

[profile.modbus]
response_timeout_ms = 100
retries = 2
poll_period_ms = 50
valid_bits_offset = 4

[profile.modbus.serial]
baud = 19200
data_bits = "eight"
parity = "none"
stop_bits = "one"

[profile.modbus.health]
stale_timeout_ms = 1000
stale_policy = "hold_last_value"

[[profile.modbus.scan]]
unit = 1
function = 3
address = 0
count = 1
offset = 0

[[profile.modbus.scan]]
unit = 2
function = 3
address = 0
count = 1
offset = 2
"#;

/// `dnet-master --json ARGS` on `bus`: its JSON report; panics with `others`' output unless it
/// exits 0.
fn master_json(bus: &str, args: &[&str], others: &[&Proc]) -> Value {
    let mut all = vec!["--bus", bus, "--json"];
    all.extend_from_slice(args);
    let mut run = Proc::spawn(bin("dnet-master"), &all);
    let status = run.wait(Duration::from_secs(30));
    let context = || others.iter().map(|p| p.dump()).collect::<Vec<_>>().join("\n");
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{args:?}\n{}\n{}", run.dump(), context());
    let text = run.stdout.text();
    serde_json::from_str(text.trim()).unwrap_or_else(|e| panic!("{args:?}: {e}\n{text}"))
}

/// The last poll sample's input bytes (10 polls at 100 ms).
fn last_poll(bus: &str, others: &[&Proc]) -> Vec<u8> {
    let report = master_json(bus, &["monitor", "--mac", "5", "--epr", "100", "--count", "10"], others);
    pymodbus::last_sample(&report.to_string())
}

/// `dnet-master units --mac 5 --json`: per unit (address, state, lost data, retries).
fn units(bus: &str, others: &[&Proc]) -> Vec<(u64, String, u64, u64)> {
    let report = master_json(bus, &["units", "--mac", "5"], others);
    let list = report["units"].as_array().unwrap_or_else(|| panic!("no units in {report}"));
    list.iter()
        .map(|u| {
            let n = |k: &str| u[k].as_u64().unwrap_or_else(|| panic!("no {k} in {u}"));
            (n("unit"), u["state"].as_str().unwrap_or_default().to_string(), n("lost_data"), n("retries"))
        })
        .collect()
}

/// The scenario against the gateway at MAC 5 on `bus`, described by `config` (in `dir`), whose
/// instrument is the [`SERVER`] silencing unit 2 while `mute` exists; `others` are dumped when a
/// run fails. With `readers`, the counters are also read with `dnet-master get` and through the
/// generated EDS (`dnet-eds generate`, `check`, `dnet-master params --eds`): two runs of 2 s
/// more, host code that the firmware does not change. Returns unit 2's lost data as `dnet-master
/// units` read it.
pub fn exercise(bus: &str, config: &Path, dir: &Path, mute: &Path, others: &[&Proc], readers: bool) -> u64 {
    let bus = bus.to_string();
    let poll = last_poll(&bus, others);
    assert_eq!(poll.len(), 7, "{poll:02X?}");
    assert_eq!(&poll[..4], &[0x11, 0x11, 0x22, 0x22], "both units' registers");
    assert_eq!(poll[4], 0b11, "both data-valid bits");
    assert_eq!(poll[5] & 0x0F, StatusByte::LINK_OK, "{:#04X}", poll[5]);

    // Unit 2 falls silent: after its next transaction's retries its bit is 0.
    std::fs::write(mute, b"").unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let poll = last_poll(&bus, others);
    assert_eq!(poll[4], 0b01, "unit 2's bit cleared, unit 1's kept: {poll:02X?}");
    assert_eq!(&poll[..2], &[0x11, 0x11]);
    let table = units(&bus, others);
    assert_eq!((table[0].0, table[0].1.as_str(), table[0].2, table[0].3), (1, "ok", 0, 0), "{table:?}");
    let (unit, state, lost, retries) = &table[1];
    assert_eq!((*unit, state.as_str()), (2, "lost"), "{table:?}");
    assert!(*lost >= 1 && *retries >= 2 * *lost, "each lost transaction took 2 retries: {table:?}");

    if !readers {
        return *lost;
    }
    // The same counter through the generic Get_Attribute_Single: class 0x69 instance 2 attr 3.
    let get = master_json(&bus, &["get", "5", "0x69", "2", "3"], others);
    let hex = get["hex"].as_str().unwrap_or_else(|| panic!("no hex in {get}"));
    let bytes: Vec<u8> =
        (0..hex.len()).step_by(2).map(|i| u8::from_str_radix(&hex[i..i + 2], 16).unwrap()).collect();
    let counted = u32::from_le_bytes(bytes.as_slice().try_into().unwrap_or_else(|_| panic!("{get}")));
    assert!(u64::from(counted) >= *lost, "lost data still counting up: {get}");

    // The EDS of the same description names the unit parameters, passes the checker, and its
    // link paths read the same counters from the device (`dnet-master params --eds`).
    let eds = dir.join("modbus-units.eds");
    let mut generate =
        Proc::spawn(bin("dnet-eds"), &["generate", config.to_str().unwrap(), "-o", eds.to_str().unwrap()]);
    assert_eq!(generate.wait(Duration::from_secs(10)).and_then(|s| s.code()), Some(0), "{}", generate.dump());
    let mut check = Proc::spawn(bin("dnet-eds"), &["check", eds.to_str().unwrap()]);
    assert_eq!(check.wait(Duration::from_secs(10)).and_then(|s| s.code()), Some(0), "{}", check.dump());
    let params = master_json(&bus, &["params", "--mac", "5", "--eds", eds.to_str().unwrap()], others);
    let list = params["params"].as_array().unwrap_or_else(|| panic!("no params in {params}"));
    let value = |name: &str| {
        let p = list.iter().find(|p| p["name"] == name).unwrap_or_else(|| panic!("no {name} in {params}"));
        p["value"].as_u64().unwrap_or_else(|| panic!("no value in {p}"))
    };
    assert_eq!((value("Unit 1 state"), value("Unit 1 lost data"), value("Unit 1 retries")), (1, 0, 0));
    assert_eq!(value("Unit 2 state"), 2, "lost");
    assert!(value("Unit 2 lost data") >= *lost && value("Unit 2 retries") >= *retries, "{params}");

    *lost
}
