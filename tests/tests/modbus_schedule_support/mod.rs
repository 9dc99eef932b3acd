//! The scheduling scenario shared by the pty test (`modbus_schedule.rs`, the soft slave) and the
//! QEMU test (`qemu_modbus_schedule.rs`, the real firmware): pymodbus's logging RTU server, the
//! gateway description, and the three monitor runs with their checks.

use pty_rig::{bin, Proc};
use std::time::{Duration, Instant};

/// The server: unit 1, holding registers 0, 16..17 and 100; prints `ready`, then one line per
/// request served: `t=SECONDS function=F address=A` and, for a write, ` values=0x....,0x....`.
pub const SERVER: &str = r#"
import asyncio, sys, time
from pymodbus.framer import FramerType
from pymodbus.server import ModbusSerialServer
from pymodbus.simulator import DataType, SimData, SimDevice

async def on_access(function_code, _start, address, _count, _registers, set_values):
    line = f"t={time.monotonic():.3f} function={function_code} address={address}"
    if set_values is not None:
        line += " values=" + ",".join(f"0x{int(v):04X}" for v in set_values)
    print(line, flush=True)
    return None

async def main():
    bits = [SimData(address=0, values=[False], datatype=DataType.BITS)]
    holding = [SimData(address=a, values=v, datatype=DataType.REGISTERS)
               for a, v in ((0, [0x1111]), (16, [0, 0]), (100, [0x2222]))]
    device = SimDevice(id=1, simdata=(bits, list(bits), holding, list(holding)), action=on_access)
    server = ModbusSerialServer(device, framer=FramerType.RTU, port=sys.argv[1], baudrate=19200,
                                bytesize=8, parity="N", stopbits=1)
    await server.serve_forever(background=True)
    print("ready", flush=True)
    await asyncio.Event().wait()

asyncio.run(main())
"#;

/// The gateway: input bytes 0..1 holding register 0 every cycle, 2..3 holding register 100 every
/// second; output bytes 0..3 written to holding 16..17 when output byte 4 changes; 4 input bytes
/// and the status pair, 5 output bytes.
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
produced_size = 6
consumed_size = 5

[profile]
kind = "modbus"

[profile.modbus]
response_timeout_ms = 300
retries = 1
poll_period_ms = 50

[profile.modbus.serial]
baud = 19200
data_bits = "eight"
parity = "none"
stop_bits = "one"

[[profile.modbus.scan]]
unit = 1
function = 3
address = 0
count = 1
offset = 0

[[profile.modbus.scan]]
unit = 1
function = 3
address = 100
count = 1
offset = 2
period_ms = 1000

[[profile.modbus.scan]]
unit = 1
function = 16
address = 16
count = 2
offset = 0
write = "trigger"
trigger_offset = 4
"#;

/// One request in the server's log: seconds, function, address, the values of a write.
#[derive(Debug)]
pub struct Served {
    pub t: f64,
    pub function: u8,
    pub address: u16,
    pub values: Option<String>,
}

pub fn served(server: &Proc) -> Vec<Served> {
    let parse = |line: &str| {
        let mut s = Served { t: -1.0, function: 0, address: u16::MAX, values: None };
        for field in line.split(' ') {
            match field.split_once('=') {
                Some(("t", v)) => s.t = v.parse().ok()?,
                Some(("function", v)) => s.function = v.parse().ok()?,
                Some(("address", v)) => s.address = v.parse().ok()?,
                Some(("values", v)) => s.values = Some(v.to_string()),
                _ => return None,
            }
        }
        (s.t >= 0.0).then_some(s)
    };
    server.stdout.lines().iter().filter_map(|l| parse(l)).collect()
}

/// Polls the soft slave (MAC 5) for 10 polls at a 100 ms EPR with output image `output` (hex).
pub fn monitor(master_bus: &str, output: &str, others: &[&Proc]) {
    let args = [
        "--bus", master_bus, "--json", "monitor", "--mac", "5", "--epr", "100", "--count", "10", "--output",
        output,
    ];
    let mut run = Proc::spawn(bin("dnet-master"), &args);
    let status = run.wait(Duration::from_secs(30));
    let context = || others.iter().map(|p| p.dump()).collect::<Vec<_>>().join("\n");
    assert_eq!(status.and_then(|s| s.code()), Some(0), "monitor {output}\n{}\n{}", run.dump(), context());
}

pub fn writes(server: &Proc) -> Vec<Served> {
    served(server).into_iter().filter(|s| s.function == 16).collect()
}

/// Polls the gateway (MAC 5) on `bus` with three output images in turn and checks `server`'s log:
/// the triggered write only after its trigger byte changed, the slow entry about once a second
/// while the cycle's read goes some twenty times as often. `gap` is the range allowed between two
/// slow reads, in seconds of the server's clock (wider on QEMU, whose clock runs slow). `others`' output is shown on a failure.
pub fn exercise(bus: &str, server: &Proc, others: &[&Proc], gap: std::ops::Range<f64>) {
    let mut all = others.to_vec();
    all.push(server);
    let others = all.as_slice();
    let started = Instant::now();

    // Data 01 02 03 04, trigger 0: the first image arms the trigger and writes nothing.
    monitor(bus, "0102030400", others);
    // Only the data bytes change: still nothing.
    monitor(bus, "0506070800", others);
    assert!(writes(server).is_empty(), "written before the trigger byte changed: {:?}", writes(server));
    // The trigger byte changes: written once, with the data of now (registers low byte first).
    let before_trigger = served(server).last().map_or(0.0, |s| s.t);
    monitor(bus, "0506070801", others);
    let written = writes(server);
    assert_eq!(written.len(), 1, "{written:?}\n{}", server.dump());
    assert_eq!(written[0].address, 16);
    assert_eq!(written[0].values.as_deref(), Some("0x0605,0x0807"), "{written:?}");
    assert!(written[0].t > before_trigger, "{written:?} before {before_trigger}");

    // The read rates over the whole run (some 4 s at least): the slow entry about once a second,
    // the cycle's read about every 50 ms.
    let log = served(server);
    let times = |address: u16| -> Vec<f64> {
        log.iter().filter(|s| s.function == 3 && s.address == address).map(|s| s.t).collect()
    };
    let (fast, slow) = (times(0), times(100));
    let span = slow.last().unwrap_or(&0.0) - slow.first().unwrap_or(&0.0);
    assert!(slow.len() >= 4, "slow reads {slow:?} in {:?}", started.elapsed());
    for pair in slow.windows(2) {
        assert!(gap.contains(&(pair[1] - pair[0])), "slow reads {:.3} s apart: {slow:?}", pair[1] - pair[0]);
    }
    let fast_in_span = fast.iter().filter(|&&t| t >= slow[0] && t <= slow[slow.len() - 1]).count();
    assert!(
        fast_in_span as f64 >= 10.0 * span,
        "the cycle's read went {fast_in_span} times in {span:.3} s (50 ms cycle): {fast:?}"
    );
    // Whatever the gateway's clock rate (QEMU's runs slow), the slow entry goes once for some 20
    // of the cycle's reads (1000 ms against 50 ms).
    let ratio = fast_in_span as f64 / (slow.len() - 1) as f64;
    assert!((16.0..24.0).contains(&ratio), "{ratio:.1} cycle reads per slow read: {slow:?}\n{fast:?}");
    eprintln!(
        "{} slow reads, {} fast reads in {span:.3} s ({ratio:.1} per slow read); the three polls {:?}",
        slow.len(),
        fast_in_span,
        started.elapsed()
    );
}
