//! The server on loopback, spoken to in raw MBAP bytes.

use super::*;
use crate::map::{NODE_BLOCK_BASE, NODE_BLOCK_LEN, NODE_INPUT, SCAN_COUNTER};
use dnet_scanner::model::{Identity, NodeState, NodeStatus, ScannerState, ScannerStatus};
use std::collections::VecDeque;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::sync::Mutex;
use std::time::Instant;

fn shared() -> Arc<Shared> {
    let node = NodeState {
        mac: 3,
        name: None,
        connection: "poll".into(),
        ack_suppression: false,
        status: NodeStatus::Ok,
        code: 0,
        detail: None,
        identity: Identity::default(),
        input_size: Some(4),
        output_size: Some(1),
        input: vec![0x11, 0x22, 0x33, 0x44],
        output: vec![1],
        exchanges: 5,
        last_exchange_us: None,
    };
    let state = ScannerState {
        mac: 0,
        status: ScannerStatus::Running,
        cycles: 42,
        cycle_ms: 10.0,
        bus_load: 0.1,
        interscan_delay_ms: 10,
        expected_packet_rate_ms: 100,
        nodes: vec![node],
    };
    let (commands, _) = std::sync::mpsc::channel();
    Arc::new(Shared {
        state: Mutex::new(state),
        frames: Mutex::new(VecDeque::new()),
        commands: Mutex::new(commands),
        history: None,
        record_dir: ".".into(),
        mqtt: Mutex::new(None),
        audit: Arc::new(dnet_scanner::audit::MemoryAudit::default()),
    })
}

fn start(config: ServerConfig) -> ModbusServer {
    ModbusServer::start("127.0.0.1:0".parse().unwrap(), config, shared()).unwrap()
}

fn connect(server: &ModbusServer) -> TcpStream {
    let s = TcpStream::connect(server.local_addr()).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s
}

/// An MBAP frame: transaction 0x1234, protocol 0, the length, the unit, the PDU.
fn frame(unit: u8, pdu: &[u8]) -> Vec<u8> {
    let mut f = vec![0x12, 0x34, 0, 0];
    f.extend_from_slice(&(pdu.len() as u16 + 1).to_be_bytes());
    f.push(unit);
    f.extend_from_slice(pdu);
    f
}

/// Sends `request` and reads one answer's PDU (after checking its header), `None` when the
/// server closed the connection instead.
fn exchange(stream: &mut TcpStream, request: &[u8]) -> Option<Vec<u8>> {
    stream.write_all(request).ok()?;
    let mut header = [0u8; 7];
    stream.read_exact(&mut header).ok()?;
    assert_eq!(&header[..4], &[0x12, 0x34, 0, 0], "transaction and protocol echoed");
    assert_eq!(header[6], request[6], "unit echoed");
    let len = usize::from(u16::from_be_bytes([header[4], header[5]])) - 1;
    let mut pdu = vec![0u8; len];
    stream.read_exact(&mut pdu).ok()?;
    Some(pdu)
}

fn read(function: u8, address: u16, quantity: u16) -> Vec<u8> {
    let mut pdu = vec![function];
    pdu.extend_from_slice(&address.to_be_bytes());
    pdu.extend_from_slice(&quantity.to_be_bytes());
    pdu
}

/// The connection was closed by the server: a read gives end of file (or a reset).
fn closed(stream: &mut TcpStream) -> bool {
    let mut b = [0u8; 1];
    matches!(stream.read(&mut b), Ok(0) | Err(_))
}

#[test]
fn reads_answer_from_the_map_with_either_function() {
    let server = start(ServerConfig::default());
    let mut s = connect(&server);
    let block = NODE_BLOCK_BASE + 3 * NODE_BLOCK_LEN + NODE_INPUT;
    let input = exchange(&mut s, &frame(1, &read(0x04, block, 2))).unwrap();
    assert_eq!(input, [0x04, 4, 0x22, 0x11, 0x44, 0x33]);
    let holding = exchange(&mut s, &frame(255, &read(0x03, SCAN_COUNTER, 2))).unwrap();
    assert_eq!(holding, [0x03, 4, 0, 42, 0, 0]);
    let unit0 = exchange(&mut s, &frame(0, &read(0x04, SCAN_COUNTER, 1))).unwrap();
    assert_eq!(unit0, [0x04, 2, 0, 42]);
}

#[rstest::rstest]
#[case::write_single_register(frame(1, &[0x06, 0, 8, 0, 1]), [0x86, 0x01])]
#[case::write_multiple_registers(frame(1, &[0x10, 0, 8, 0, 1, 2, 0, 1]), [0x90, 0x01])]
#[case::write_single_coil(frame(1, &[0x05, 0, 0, 0xFF, 0]), [0x85, 0x01])]
#[case::read_coils(frame(1, &read(0x01, 0, 8)), [0x81, 0x01])]
#[case::custom_function(frame(1, &[0x41, 1, 2, 3]), [0xC1, 0x01])]
#[case::too_many(frame(1, &read(0x04, 0, 126)), [0x84, 0x03])]
#[case::none(frame(1, &read(0x03, 0, 0)), [0x83, 0x03])]
#[case::past_the_end(frame(1, &read(0x04, 0xFFFF, 1)), [0x84, 0x02])]
#[case::other_unit(frame(7, &read(0x04, 0, 1)), [0x84, 0x0A])]
fn refusals_are_exceptions_and_the_connection_goes_on(#[case] request: Vec<u8>, #[case] answer: [u8; 2]) {
    let server = start(ServerConfig::default());
    let mut s = connect(&server);
    assert_eq!(exchange(&mut s, &request).unwrap(), answer);
    assert_eq!(exchange(&mut s, &frame(1, &read(0x04, 0, 1))).unwrap(), [0x04, 2, 0, 42]);
}

#[rstest::rstest]
#[case::protocol_id(vec![0, 1, 0, 1, 0, 6, 1, 4, 0, 0, 0, 1])]
#[case::length_zero(vec![0, 1, 0, 0, 0, 0, 1, 4, 0, 0, 0, 1])]
#[case::truncated_pdu(frame(1, &[0x04, 0]))]
#[case::exception_function(frame(1, &[0x84, 0, 0, 0, 1]))]
#[case::coils_count_past_the_frame(frame(1, &[0x0F, 0, 0, 0, 8, 200, 1]))]
#[case::registers_quantity_overflows(frame(1, &[0x10, 0, 0, 0x80, 0, 0]))]
fn an_undecodable_frame_closes_its_connection_only(#[case] request: Vec<u8>) {
    let server = start(ServerConfig::default());
    let mut other = connect(&server);
    let mut s = connect(&server);
    s.write_all(&request).unwrap();
    assert!(closed(&mut s), "the connection is closed");
    assert_eq!(exchange(&mut other, &frame(1, &read(0x04, 0, 1))).unwrap(), [0x04, 2, 0, 42]);
    let mut again = connect(&server);
    assert_eq!(exchange(&mut again, &frame(1, &read(0x04, 0, 1))).unwrap(), [0x04, 2, 0, 42]);
}

#[test]
fn connections_over_the_limit_are_closed_and_a_freed_place_is_reused() {
    let server = start(ServerConfig { max_connections: 2, ..ServerConfig::default() });
    let mut a = connect(&server);
    let mut b = connect(&server);
    assert!(exchange(&mut a, &frame(1, &read(0x04, 0, 1))).is_some());
    assert!(exchange(&mut b, &frame(1, &read(0x04, 0, 1))).is_some());
    let mut c = connect(&server);
    assert!(exchange(&mut c, &frame(1, &read(0x04, 0, 1))).is_none(), "a third connection is refused");
    drop(a);
    // The place comes back once the server has seen the close.
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        let mut d = connect(&server);
        if exchange(&mut d, &frame(1, &read(0x04, 0, 1))).is_some() {
            break;
        }
        assert!(Instant::now() < deadline, "the freed place was never given back");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_silent_connection_is_closed_after_the_idle_timeout() {
    let idle = Duration::from_millis(300);
    let server = start(ServerConfig { idle_timeout: idle, ..ServerConfig::default() });
    let mut s = connect(&server);
    assert!(exchange(&mut s, &frame(1, &read(0x04, 0, 1))).is_some());
    let since = Instant::now();
    assert!(closed(&mut s));
    assert!(since.elapsed() >= idle - Duration::from_millis(50), "closed after {:?}", since.elapsed());
}

#[test]
fn refused_configurations() {
    let taken = StdListener::bind("127.0.0.1:0").unwrap();
    let address = taken.local_addr().unwrap();
    assert!(matches!(
        ModbusServer::start(address, ServerConfig::default(), shared()),
        Err(ServerError::Listen { .. })
    ));
    for n in [0, CONNECTIONS_LIMIT + 1] {
        let config = ServerConfig { max_connections: n, ..ServerConfig::default() };
        assert!(matches!(
            ModbusServer::start("127.0.0.1:0".parse().unwrap(), config, shared()),
            Err(ServerError::Connections(m)) if m == n
        ));
    }
}

#[test]
fn stop_closes_the_listener() {
    let server = start(ServerConfig::default());
    let address = server.local_addr();
    let mut s = connect(&server);
    server.stop();
    assert!(closed(&mut s));
    assert!(TcpStream::connect(address).is_err());
}
