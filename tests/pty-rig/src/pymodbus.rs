//! A pymodbus server (the independent Modbus implementation) as the soft slave's or the board's
//! instrument, and the monitor run that reads the gateway's poll data, for the Modbus system tests
//! (RTU, ASCII and TCP framing).
//!
//! The server serves unit 1 from the tables it is given ([`Registers`]), answers other addresses
//! with exception 02, prints `ready` once it serves, `connected`/`disconnected` per TCP client, and
//! one line per write, flushed at once:
//!
//! ```text
//! write unit=1 function=16 address=16 values=0x2211,0x4433
//! ```

use crate::{bin, Proc};
use serde_json::{json, Value};
use std::path::Path;
use std::time::Duration;

/// The server: one JSON argument, `{"link": "rtu" | "ascii" | "tcp", "port": PTY or TCP port,
/// "holding": [[ADDRESS, [VALUES]]], "inputs": [[ADDRESS, [VALUES]]]}`. Serial links run at 19200
/// baud, 8N1 (a pty carries bytes, so the character format is not modelled).
const SERVER: &str = r#"
import asyncio, json, sys
from pymodbus.framer import FramerType
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

spec = json.loads(sys.argv[1])

async def on_access(function_code, _start, address, _count, _registers, set_values):
    if set_values is not None:
        values = ",".join(f"0x{int(v):04X}" for v in set_values)
        print(f"write unit=1 function={function_code} address={address} values={values}", flush=True)
    return None

def trace_connect(connected):
    print("connected" if connected else "disconnected", flush=True)

def table(entries):
    return [SimData(address=a, values=list(v), datatype=DataType.REGISTERS) for a, v in entries]

async def main():
    bits = [SimData(address=0, values=[False], datatype=DataType.BITS)]
    device = SimDevice(id=1, simdata=(bits, list(bits), table(spec["holding"]), table(spec["inputs"])),
                       action=on_access)
    if spec["link"] == "tcp":
        server = ModbusTcpServer(device, framer=FramerType.SOCKET, address=("127.0.0.1", int(spec["port"])),
                                 trace_connect=trace_connect)
    else:
        framer = {"rtu": FramerType.RTU, "ascii": FramerType.ASCII}[spec["link"]]
        server = ModbusSerialServer(device, framer=framer, port=spec["port"], baudrate=19200,
                                    bytesize=8, parity="N", stopbits=1)
    await server.serve_forever(background=True)
    print("ready", flush=True)
    await asyncio.Event().wait()

asyncio.run(main())
"#;

/// Where the server listens, and how it frames.
#[derive(Debug, Clone, Copy)]
pub enum Link<'a> {
    /// Modbus RTU on a serial port (a pty end).
    Rtu(&'a str),
    /// Modbus ASCII on a serial port (a pty end).
    Ascii(&'a str),
    /// Modbus TCP (MBAP) on `127.0.0.1:PORT`.
    Tcp(u16),
}

/// Unit 1's register tables: each entry a start address and the values from there.
#[derive(Debug, Clone, Copy)]
pub struct Registers<'a> {
    /// Holding registers (functions 3, 6, 16).
    pub holding: &'a [(u16, &'a [u16])],
    /// Input registers (function 4).
    pub inputs: &'a [(u16, &'a [u16])],
}

/// The registers the gateway descriptions read and write: input registers 0..3 = 0x0102, 0x0304,
/// 0x0506, 0x0708; holding registers 16..17 = 0, 0 (the gateway writes here) and 100..101 =
/// 0xABCD, 0x1234.
pub const GATEWAY_REGISTERS: Registers<'static> = Registers {
    holding: &[(16, &[0, 0]), (100, &[0xABCD, 0x1234])],
    inputs: &[(0, &[0x0102, 0x0304, 0x0506, 0x0708])],
};

/// Starts the server with `python` (see [`crate::require_pymodbus`]) and waits (20 s at most)
/// until it serves; panics with its output when it does not.
pub fn server(python: &Path, link: Link<'_>, registers: &Registers<'_>) -> Proc {
    let (kind, port) = match link {
        Link::Rtu(pty) => ("rtu", json!(pty)),
        Link::Ascii(pty) => ("ascii", json!(pty)),
        Link::Tcp(port) => ("tcp", json!(port)),
    };
    let spec = json!({"link": kind, "port": port, "holding": registers.holding, "inputs": registers.inputs})
        .to_string();
    let server = Proc::spawn(python, &["-c", SERVER, &spec]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());
    server
}

/// One `[[profile.modbus.scan]]` entry of unit 1.
#[derive(Debug, Clone, Copy)]
pub struct Scan<'a> {
    /// The Modbus function (3, 4: read into the input image; 6, 16: write from the output image).
    pub function: u8,
    /// The first register.
    pub address: u16,
    /// How many registers.
    pub count: u16,
    /// The byte offset in the image.
    pub offset: u16,
    /// `word_order` of 32-bit values (`"cdab"`, ...), when not the default.
    pub word_order: Option<&'a str>,
}

impl Scan<'_> {
    /// An entry in the default word order.
    pub const fn new(function: u8, address: u16, count: u16, offset: u16) -> Scan<'static> {
        Scan { function, address, count, offset, word_order: None }
    }
}

/// The scan list of the gateway of [`gateway_description`].
const GATEWAY_SCANS: [Scan<'static>; 4] =
    [Scan::new(4, 0, 4, 0), Scan::new(3, 100, 2, 8), Scan::new(3, 16, 2, 12), Scan::new(16, 16, 2, 0)];

/// A Modbus gateway's description: MAC ID 5 at 250 kbit/s, the status assembly of
/// `produced_size` bytes, 4 output bytes, `modbus` as the body of its `[profile.modbus]` table
/// (framing, timing, and any sub-tables such as `[profile.modbus.serial]`), and `scans`.
pub fn description(produced_size: u16, modbus: &str, scans: &[Scan<'_>]) -> String {
    let mut text = format!(
        r#"[identity]
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
produced_size = {produced_size}
consumed_size = 4

[profile]
kind = "modbus"

[profile.modbus]
{modbus}"#
    );
    for s in scans {
        text += &format!(
            "\n[[profile.modbus.scan]]\nunit = 1\nfunction = {}\naddress = {}\ncount = {}\noffset = {}\n",
            s.function, s.address, s.count, s.offset
        );
        if let Some(order) = s.word_order {
            text += &format!("word_order = \"{order}\"\n");
        }
    }
    text
}

/// The gateway that maps [`GATEWAY_REGISTERS`] (input registers 0..3 to input bytes 0..7, holding
/// 100..101 to 8..11, holding 16..17 read back to 12..15, output bytes 0..3 written to holding
/// 16..17; 18 bytes with status and freshness; stale after 1 s, cleared): [`description`] with
/// `modbus` and the health table.
pub fn gateway_description(modbus: &str) -> String {
    let health = "\n[profile.modbus.health]\nstale_timeout_ms = 1000\nstale_policy = \"clear\"\n";
    description(18, &format!("{modbus}{health}"), &GATEWAY_SCANS)
}

/// `dnet-master --bus MASTER_BUS --json monitor --mac 5 --epr 100 --count 30 --output OUTPUT`
/// (`OUTPUT` in hexadecimal): the last sample's input bytes. Panics, with `others`' output, when
/// the run fails or reports no sample.
pub fn last_poll(master_bus: &str, output: &str, others: &[&Proc]) -> Vec<u8> {
    let args = [
        "--bus", master_bus, "--json", "monitor", "--mac", "5", "--epr", "100", "--count", "30", "--output",
        output,
    ];
    let mut monitor = Proc::spawn(bin("dnet-master"), &args);
    let status = monitor.wait(Duration::from_secs(60));
    let context = || others.iter().map(|p| p.dump()).collect::<Vec<_>>().join("\n");
    assert_eq!(status.and_then(|s| s.code()), Some(0), "monitor\n{}\n{}", monitor.dump(), context());
    last_sample(&monitor.stdout.text())
}

/// The last sample's input bytes in the JSON report of `dnet-master --json monitor`; panics when
/// there is none.
pub fn last_sample(report: &str) -> Vec<u8> {
    let json: Value =
        serde_json::from_str(report.trim()).unwrap_or_else(|e| panic!("monitor's JSON: {e}\n{report}"));
    let list = json["samples"].as_array().unwrap_or_else(|| panic!("no samples in {json}"));
    let last = list.last().unwrap_or_else(|| panic!("no sample: {json}"));
    let raw = last["raw"].as_array().unwrap_or_else(|| panic!("no raw bytes in {last}"));
    raw.iter()
        .map(|b| b.as_u64().and_then(|b| u8::try_from(b).ok()).unwrap_or_else(|| panic!("not a byte: {b}")))
        .collect()
}

/// Stops `slave` with SIGTERM: it must exit 0. Its report (standard error).
pub fn stop(slave: &mut Proc) -> String {
    let status = slave.terminate();
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{}", slave.dump());
    slave.stderr.text()
}
