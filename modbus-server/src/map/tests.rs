use super::*;
use dnet_scanner::model::Identity;
use proptest::prelude::*;
use rstest::rstest;

fn node(mac: u8, status: NodeStatus, input: &[u8], output: &[u8]) -> NodeState {
    NodeState {
        mac,
        name: None,
        connection: "poll".into(),
        ack_suppression: false,
        status,
        code: status.code(),
        detail: None,
        identity: Identity::default(),
        input_size: Some(input.len() as u16),
        output_size: Some(output.len() as u16),
        input: input.to_vec(),
        output: output.to_vec(),
        exchanges: 0x0001_0002_0003,
        last_exchange_us: None,
    }
}

fn state(nodes: Vec<NodeState>) -> ScannerState {
    ScannerState {
        mac: 0,
        status: ScannerStatus::Running,
        cycles: 0x0012_3456_789A,
        cycle_ms: 12.34,
        bus_load: 0.4567,
        interscan_delay_ms: 10,
        expected_packet_rate_ms: 100,
        nodes,
    }
}

fn plant() -> ScannerState {
    state(vec![
        node(1, NodeStatus::Ok, &[0x34, 0x12, 0xAB], &[0x01]),
        node(17, NodeStatus::Idle, &[], &[0, 0]),
        node(33, NodeStatus::KeyingMismatch, &[], &[]),
        node(63, NodeStatus::NotPresent, &[], &[]),
    ])
}

fn one(state: &ScannerState, address: u16) -> u16 {
    read_registers(state, address, 1).unwrap()[0]
}

#[test]
fn status_table_holds_the_counter_and_the_node_tables() {
    let s = plant();
    let regs = read_registers(&s, 0, 23).unwrap();
    // Low word first, the counter's low 32 bits.
    assert_eq!(&regs[0..2], &[0x789A, 0x3456]);
    // Active: 1, 17, 33, 63.
    assert_eq!(&regs[2..6], &[1 << 1, 1 << 1, 1 << 1, 1 << 15]);
    // Faulted: 33 (keying) and 63 (not present); idle is not a fault.
    assert_eq!(&regs[6..10], &[0, 0, 1 << 1, 1 << 15]);
    // Idle: 17.
    assert_eq!(&regs[10..14], &[0, 1 << 1, 0, 0]);
    // Verify error: 33.
    assert_eq!(&regs[14..18], &[0, 0, 1 << 1, 0]);
    assert_eq!(regs[18], STATUS_RUN | STATUS_NODE_FAULT | STATUS_VERIFY_FAULT);
    assert_eq!(regs[19], 0);
    assert_eq!(regs[20], 4);
    assert_eq!(regs[21], 123);
    assert_eq!(regs[22], 457);
}

#[rstest]
#[case::ok(1, 0)]
#[case::idle(17, 86)]
#[case::keying(33, 73)]
#[case::not_present(63, 78)]
#[case::not_in_list(5, 0)]
fn node_status_table_has_the_code_per_mac(#[case] mac: u16, #[case] code: u16) {
    assert_eq!(one(&plant(), NODE_STATUS_TABLE + mac), code);
    let block = NODE_BLOCK_BASE + mac * NODE_BLOCK_LEN;
    assert_eq!(one(&plant(), block + NODE_STATUS), code);
}

#[rstest]
#[case::duplicate(ScannerStatus::DuplicateMac, 70, STATUS_FAULTED | STATUS_DUPLICATE_MAC)]
#[case::bus_off(ScannerStatus::BusOff, 91, STATUS_FAULTED | STATUS_BUS_OFF)]
#[case::warning(ScannerStatus::BusWarning, 0, STATUS_RUN | STATUS_BUS_WARNING)]
#[case::starting(ScannerStatus::Starting, 0, STATUS_STARTING)]
#[case::stopped(ScannerStatus::Stopped, 0, STATUS_STOPPED)]
fn the_scanners_own_status(#[case] status: ScannerStatus, #[case] code: u16, #[case] bits: u16) {
    let mut s = state(vec![node(1, NodeStatus::Ok, &[1], &[])]);
    s.mac = 9;
    s.status = status;
    assert_eq!(one(&s, NODE_STATUS_TABLE + 9), code);
    assert_eq!(one(&s, SCANNER_STATUS), bits);
    assert_eq!(one(&s, SCANNER_MAC), 9);
}

#[test]
fn node_block_holds_sizes_counter_and_images_low_byte_first() {
    let s = plant();
    let block = NODE_BLOCK_BASE + NODE_BLOCK_LEN;
    let regs = read_registers(&s, block, 10).unwrap();
    assert_eq!(regs[..8], [0, FLAG_IN_SCAN_LIST | FLAG_OK, 3, 1, 0x0003, 0x0002, 0, 0]);
    assert_eq!(regs[8..], [0x1234, 0x00AB]);
    assert_eq!(one(&s, block + NODE_OUTPUT), 0x0001);
    assert_eq!(one(&s, block + NODE_OUTPUT + 1), 0);
    // A MAC not in the scan list: a block of zeros, its flag off.
    assert!(read_registers(&s, NODE_BLOCK_BASE + 5 * NODE_BLOCK_LEN, 125).unwrap().iter().all(|&r| r == 0));
}

#[test]
fn a_long_image_is_cut_and_flagged() {
    let long: Vec<u8> = (0..=255).collect();
    let s = state(vec![node(2, NodeStatus::Ok, &long, &long)]);
    let block = NODE_BLOCK_BASE + 2 * NODE_BLOCK_LEN;
    let flags = one(&s, block + NODE_FLAGS);
    assert_eq!(flags & (FLAG_INPUT_CUT | FLAG_OUTPUT_CUT), FLAG_INPUT_CUT | FLAG_OUTPUT_CUT);
    assert_eq!(one(&s, block + NODE_INPUT + IMAGE_REGISTERS - 1), u16::from_le_bytes([238, 239]));
    // The gap after the input image is not the rest of it.
    assert_eq!(one(&s, block + NODE_INPUT + IMAGE_REGISTERS), 0);
    assert_eq!(one(&s, block + NODE_OUTPUT + IMAGE_REGISTERS - 1), u16::from_le_bytes([238, 239]));
}

#[rstest]
#[case::zero(0, 0, MapError::Quantity { quantity: 0 })]
#[case::too_many(0, 126, MapError::Quantity { quantity: 126 })]
#[case::past_the_end(u16::MAX, 1, MapError::Address { address: u16::MAX, end: 65536 })]
#[case::straddles_the_end(16600, 41, MapError::Address { address: 16600, end: 16641 })]
fn refusals(#[case] address: u16, #[case] quantity: u16, #[case] error: MapError) {
    assert_eq!(read_registers(&plant(), address, quantity), Err(error));
}

#[test]
fn the_last_register_and_the_exception_codes() {
    assert_eq!(read_registers(&plant(), (MAP_END - 125) as u16, 125).map(|r| r.len()), Ok(125));
    assert_eq!(MapError::Quantity { quantity: 0 }.exception_code(), 3);
    assert_eq!(MapError::Address { address: 0, end: 0 }.exception_code(), 2);
}

proptest! {
    /// Any request: the values or a refusal, never a panic, and exactly `quantity` values.
    #[test]
    fn any_request_is_answered(address: u16, quantity: u16, cycle_ms: f64, load: f64) {
        let mut s = plant();
        s.cycle_ms = cycle_ms;
        s.bus_load = load;
        match read_registers(&s, address, quantity) {
            Ok(regs) => prop_assert_eq!(regs.len(), usize::from(quantity)),
            Err(MapError::Quantity { .. }) => prop_assert!(quantity == 0 || quantity > MAX_READ),
            Err(MapError::Address { .. }) => prop_assert!(u32::from(address) + u32::from(quantity) > MAP_END),
        }
    }
}
