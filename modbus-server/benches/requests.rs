//! What the Modbus TCP server costs, with 63 nodes in the scan list (the reference breaker: 18-byte
//! input, 8-byte output). Reported, not asserted:
//! - the register map alone: a read of the status table (23 registers), of the node status table
//!   (64), of a node block (125), time per read;
//! - the server over loopback: sequential FC 04 reads of 125 registers by one client (round trip
//!   median and 99th percentile, reads per second), then by 4 clients at once (reads per second).
//!
//! `cargo bench -p dnet-modbus-tcp --bench requests`

use dnet_modbus_tcp::map::{read_registers, NODE_BLOCK_BASE, NODE_BLOCK_LEN, NODE_STATUS_TABLE};
use dnet_modbus_tcp::{ModbusServer, ServerConfig};
use dnet_scanner::audit::MemoryAudit;
use dnet_scanner::model::{Identity, NodeState, NodeStatus, ScannerState, ScannerStatus, Shared};
use std::collections::VecDeque;
use std::hint::black_box;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

fn state() -> ScannerState {
    let nodes = (1..=63)
        .map(|mac| NodeState {
            mac,
            name: None,
            connection: "poll".into(),
            ack_suppression: false,
            status: NodeStatus::Ok,
            code: 0,
            detail: None,
            identity: Identity::default(),
            input_size: Some(18),
            output_size: Some(8),
            input: (0..18).collect(),
            output: vec![0; 8],
            exchanges: 1000,
            last_exchange_us: None,
        })
        .collect();
    ScannerState {
        mac: 0,
        status: ScannerStatus::Running,
        cycles: 1000,
        cycle_ms: 60.0,
        bus_load: 0.8,
        interscan_delay_ms: 10,
        expected_packet_rate_ms: 100,
        nodes,
    }
}

fn per_read(what: &str, address: u16, quantity: u16, s: &ScannerState) {
    const N: u32 = 20_000;
    let start = Instant::now();
    for _ in 0..N {
        black_box(read_registers(black_box(s), address, quantity).ok());
    }
    println!(
        "map: {what} ({quantity} registers): {:.2} µs a read",
        start.elapsed().as_secs_f64() * 1e6 / f64::from(N)
    );
}

fn request(mac: u8) -> Vec<u8> {
    let address = NODE_BLOCK_BASE + u16::from(mac) * NODE_BLOCK_LEN;
    let mut f = vec![0, 1, 0, 0, 0, 6, 1, 0x04];
    f.extend_from_slice(&address.to_be_bytes());
    f.extend_from_slice(&125u16.to_be_bytes());
    f
}

/// `n` sequential reads on one connection; the round trip of each.
fn client(address: std::net::SocketAddr, n: usize) -> Vec<Duration> {
    let mut s = TcpStream::connect(address).expect("connect");
    s.set_nodelay(true).expect("nodelay");
    let mut answer = vec![0u8; 9 + 250];
    (0..n)
        .map(|i| {
            let start = Instant::now();
            s.write_all(&request((i % 63 + 1) as u8)).expect("send");
            s.read_exact(&mut answer).expect("answer");
            assert_eq!(answer[7], 0x04, "an answer, not an exception");
            start.elapsed()
        })
        .collect()
}

fn main() {
    let s = state();
    per_read("status table", 0, 23, &s);
    per_read("node status table", NODE_STATUS_TABLE, 64, &s);
    per_read("node block of MAC 63", NODE_BLOCK_BASE + 63 * NODE_BLOCK_LEN, 125, &s);

    let (commands, _) = std::sync::mpsc::channel();
    let shared = Arc::new(Shared {
        state: Mutex::new(s),
        frames: Mutex::new(VecDeque::new()),
        commands: Mutex::new(commands),
        history: None,
        record_dir: ".".into(),
        mqtt: Mutex::new(None),
        audit: Arc::new(MemoryAudit::default()),
    });
    let server =
        ModbusServer::start("127.0.0.1:0".parse().expect("address"), ServerConfig::default(), shared)
            .expect("the server starts");
    let address = server.local_addr();
    const N: usize = 20_000;
    let start = Instant::now();
    let mut rtt = client(address, N);
    let elapsed = start.elapsed();
    rtt.sort();
    println!(
        "server, 1 client: {:.0} reads/s of 125 registers, round trip median {:.0} µs, p99 {:.0} µs",
        N as f64 / elapsed.as_secs_f64(),
        rtt[N / 2].as_secs_f64() * 1e6,
        rtt[N * 99 / 100].as_secs_f64() * 1e6
    );
    let start = Instant::now();
    let clients: Vec<_> = (0..4).map(|_| std::thread::spawn(move || client(address, N / 4))).collect();
    for c in clients {
        c.join().expect("a client");
    }
    println!("server, 4 clients: {:.0} reads/s of 125 registers", N as f64 / start.elapsed().as_secs_f64());
    server.stop();
}
