//! Unit tests of the slave node: network access, the validation tables of protocol §3.4 and §5,
//! objects, connections and fragmentation, driven on a virtual clock.

use super::*;
use crate::explicit::ServiceCode;
use crate::led;
use crate::reference::INPUT_IMAGE;
use crate::time::Duration;
use rstest::rstest;
use std::vec::Vec;

type Tx = Vec<(u16, Vec<u8>)>;

struct Rig {
    node: SlaveNode,
    now: Instant,
}

impl Rig {
    fn new(config: DeviceConfig) -> Rig {
        let mut node = SlaveNode::new(config).unwrap();
        // The reference image wherever the produced size is the reference one.
        let _ = node.set_input(&INPUT_IMAGE);
        Rig { node, now: Instant::ZERO }
    }

    /// Powered on at t = 0 and on-line at t = 2 s.
    fn online() -> Rig {
        let mut rig = Rig::new(DeviceConfig::reference());
        rig.node.power_on(rig.now);
        rig.advance(Duration::from_secs(2));
        assert_eq!(rig.node.network_state(), NetworkState::Online);
        rig.events();
        rig
    }

    /// On-line with explicit allocated by master 0.
    fn explicit() -> Rig {
        let mut rig = Rig::online();
        assert_eq!(rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]), tx(0x42B, &[0x00, 0xCB, 0x00]));
        rig.events();
        rig
    }

    /// Explicit and poll established (EPR 100 ms).
    fn established() -> Rig {
        let mut rig = Rig::explicit();
        assert_eq!(rig.send(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00]), tx(0x42B, &[0x00, 0xCB, 0x00]));
        assert_eq!(
            rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]),
            tx(0x42B, &[0x00, 0x90, 0x64, 0x00])
        );
        rig.events();
        rig
    }

    fn drain(&mut self) -> Tx {
        let mut out = Vec::new();
        while let Some(f) = self.node.poll_transmit() {
            out.push((f.id().as_raw(), f.data().to_vec()));
        }
        out
    }

    fn events(&mut self) -> Vec<Event> {
        let mut out = Vec::new();
        while let Some(e) = self.node.poll_event() {
            out.push(e);
        }
        out
    }

    /// Runs every timer up to `now + d`, returning what was sent.
    fn advance(&mut self, d: Duration) -> Tx {
        let end = self.now + d;
        let mut out = self.drain();
        while let Some(at) = self.node.poll_at() {
            if at > end {
                break;
            }
            self.now = at.max(self.now);
            self.node.handle_timeout(self.now);
            out.extend(self.drain());
        }
        self.now = end;
        self.node.handle_timeout(end);
        out.extend(self.drain());
        out
    }

    fn send(&mut self, id: u16, data: &[u8]) -> Tx {
        let frame = CanFrame::from_raw(id, data).unwrap();
        self.node.handle_frame(&frame, self.now);
        self.drain()
    }
}

fn tx(id: u16, data: &[u8]) -> Tx {
    std::vec![(id, data.to_vec())]
}

// ----- network access (protocol §7.1) -------------------------------------------------------------

#[test]
fn duplicate_mac_check_two_requests_one_second_apart() {
    let mut rig = Rig::new(DeviceConfig::reference());
    rig.node.power_on(Instant::ZERO);
    let req = [0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12];
    assert_eq!(rig.drain(), tx(0x42F, &req));
    assert_eq!(rig.node.poll_at(), Some(Instant::from_secs(1)));
    assert_eq!(rig.advance(Duration::from_millis(999)), Tx::new());
    assert_eq!(rig.advance(Duration::from_millis(1)), tx(0x42F, &req));
    assert!(matches!(rig.node.network_state(), NetworkState::DuplicateMacCheck { requests_sent: 2, .. }));
    assert_eq!(rig.advance(Duration::from_millis(999)), Tx::new());
    assert_eq!(rig.events(), Vec::<Event>::new());
    rig.advance(Duration::from_millis(1));
    assert_eq!(rig.node.network_state(), NetworkState::Online);
    assert_eq!(rig.events(), std::vec![Event::Online]);
}

#[rstest]
#[case::request_during_check(&[0x00, 0x99, 0x00, 1, 2, 3, 4])]
#[case::response_during_check(&[0x80, 0x99, 0x00, 1, 2, 3, 4])]
fn duplicate_during_check_faults(#[case] data: &[u8]) {
    let mut rig = Rig::new(DeviceConfig::reference());
    rig.node.power_on(Instant::ZERO);
    rig.drain();
    rig.advance(Duration::from_millis(500));
    assert_eq!(rig.send(0x42F, data), Tx::new());
    assert_eq!(rig.node.network_state(), NetworkState::CommunicationFaulted(FaultReason::DuplicateMacId));
    assert_eq!(rig.events(), std::vec![Event::CommunicationFaulted(FaultReason::DuplicateMacId)]);
    // Faulted: silent, no second request, no answer to anything.
    assert_eq!(rig.advance(Duration::from_secs(5)), Tx::new());
    assert_eq!(rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]), Tx::new());
    assert_eq!(rig.node.network_indication(), Indication::Red);
}

#[test]
fn online_node_answers_a_newcomer_with_a_response() {
    let mut rig = Rig::online();
    assert_eq!(
        rig.send(0x42F, &[0x00, 0x99, 0x00, 1, 2, 3, 4]),
        tx(0x42F, &[0x80, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12])
    );
    assert_eq!(rig.node.network_state(), NetworkState::Online);
}

#[test]
fn online_node_faults_on_a_response_for_its_mac() {
    let mut rig = Rig::online();
    assert_eq!(rig.send(0x42F, &[0x80, 0x99, 0x00, 1, 2, 3, 4]), Tx::new());
    assert_eq!(rig.node.network_state(), NetworkState::CommunicationFaulted(FaultReason::DuplicateMacId));
}

#[rstest]
#[case::other_mac_dup_check(0x407, &[0x00, 0x01, 0x00, 4, 3, 2, 1])]
#[case::ucmm_open(0x780, &[0x05, 0x4B, 0x00, 0x34])]
#[case::ucmm_to_us_from_mac_7(0x787, &[0x05, 0x4B, 0x00, 0x34])]
#[case::group1(0x3C6, &[1, 2, 3])]
#[case::group4_who(0x7ED, &[0x3F, 0x4B, 0x02])]
#[case::invalid_range(0x7F5, &[])]
#[case::other_slave_explicit(0x434, &[0x00, 0x0E, 0x01, 0x01, 0x01])]
#[case::malformed_dup_mac(0x42F, &[0x00, 0x01])]
fn ignored_traffic(#[case] id: u16, #[case] data: &[u8]) {
    let mut rig = Rig::online();
    assert_eq!(rig.send(id, data), Tx::new());
    assert_eq!(rig.node.network_state(), NetworkState::Online);
}

#[test]
fn nothing_but_dup_mac_before_online() {
    let mut rig = Rig::new(DeviceConfig::reference());
    assert_eq!(rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]), Tx::new());
    rig.node.power_on(rig.now);
    rig.drain();
    assert_eq!(rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]), Tx::new());
}

// ----- Predefined Master/Slave Connection Set (protocol §3.4) -------------------------------------

#[rstest]
#[case::allocate_explicit(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00], &[0x00, 0xCB, 0x00])]
#[case::allocate_explicit_and_poll(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00], &[0x00, 0xCB, 0x00])]
#[case::xid_echoed(&[], 0x42E, &[0x40, 0x4B, 0x03, 0x01, 0x01, 0x00], &[0x40, 0xCB, 0x00])]
#[case::conflict_second_master(&[0x01], 0x42E, &[0x01, 0x4B, 0x03, 0x01, 0x01, 0x01], &[0x01, 0x94, 0x0C, 0x01])]
#[case::choice_zero(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x00, 0x00], &[0x00, 0x94, 0x09, 0x02])]
#[case::ack_suppression_alone(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x41, 0x00], &[0x00, 0x94, 0x09, 0x02])]
#[case::bit_strobe(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x05, 0x00], &[0x00, 0xCB, 0x00])]
#[case::cos(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x11, 0x00], &[0x00, 0xCB, 0x00])]
#[case::cyclic_suppressed(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x61, 0x00], &[0x00, 0xCB, 0x00])]
#[case::every_type_but_multicast(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x57, 0x00], &[0x00, 0xCB, 0x00])]
#[case::cos_and_cyclic(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x31, 0x00], &[0x00, 0x94, 0x09, 0x02])]
#[case::cyclic_on_cos(&[0x11], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x20, 0x00], &[0x00, 0x94, 0x09, 0x02])]
#[case::cos_twice(&[0x11], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x10, 0x00], &[0x00, 0x94, 0x0B, 0x02])]
#[case::ack_suppression_later(&[0x11], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x40, 0x00], &[0x00, 0x94, 0x09, 0x02])]
#[case::strobe_without_explicit(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x04, 0x00], &[0x00, 0x94, 0x09, 0x02])]
#[case::multicast_with_strobe(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x0D, 0x00], &[0x00, 0x94, 0x02, 0x02])]
#[case::multicast_poll_lacking(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x09, 0x00], &[0x00, 0x94, 0x02, 0x02])]
#[case::reserved_bit_lacking(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x81, 0x00], &[0x00, 0x94, 0x02, 0x02])]
#[case::poll_without_explicit(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00], &[0x00, 0x94, 0x09, 0x02])]
#[case::double_allocation(&[0x01], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00], &[0x00, 0x94, 0x0B, 0x02])]
#[case::release_choice_zero(&[0x01], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x00], &[0x00, 0x94, 0x09, 0x02])]
#[case::release_lacking_type(&[0x01], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x08], &[0x00, 0x94, 0x02, 0x02])]
#[case::release_strobe_not_allocated(&[0x01], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x04], &[0x00, 0x94, 0x0B, 0x02])]
#[case::release_cyclic_when_cos(&[0x11], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x20], &[0x00, 0x94, 0x0B, 0x02])]
#[case::release_cos(&[0x11], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x10], &[0x00, 0xCC])]
#[case::release_cos_with_suppression_bit(&[0x51], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x50], &[0x00, 0x94, 0x09, 0x02])]
#[case::release_nonexistent(&[0x01], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x02], &[0x00, 0x94, 0x0B, 0x02])]
#[case::release_ack_suppression(&[0x01], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x41], &[0x00, 0x94, 0x09, 0x02])]
#[case::release_other_master(&[0x01], 0x42E, &[0x01, 0x4C, 0x03, 0x01, 0x01], &[0x01, 0x94, 0x0C, 0x01])]
#[case::release_explicit(&[0x01], 0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x01], &[0x00, 0xCC])]
#[case::get_on_group2_only_port(&[], 0x42E, &[0x00, 0x0E, 0x03, 0x01, 0x01], &[0x00, 0x94, 0x02, 0x03])]
#[case::set_on_group2_only_port(&[0x01], 0x42E, &[0x00, 0x10, 0x03, 0x01, 0x03, 0x01], &[0x00, 0x94, 0x02, 0x03])]
#[case::allocate_wrong_class(&[], 0x42E, &[0x00, 0x4B, 0x01, 0x01, 0x01, 0x00], &[0x00, 0x94, 0x16, 0xFF])]
#[case::allocate_short(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01], &[0x00, 0x94, 0x13, 0xFF])]
#[case::allocate_long(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00, 0x00], &[0x00, 0x94, 0x15, 0xFF])]
#[case::allocate_without_instance(&[], 0x42E, &[0x00, 0x4B, 0x03], &[0x00, 0x94, 0x13, 0xFF])]
#[case::release_without_instance(&[0x01], 0x42E, &[0x00, 0x4C, 0x03], &[0x00, 0x94, 0x13, 0xFF])]
#[case::allocator_reserved_bits(&[], 0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x40], &[0x00, 0x94, 0x09, 0x02])]
#[case::allocate_poll_through_explicit(&[0x01], 0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00], &[0x00, 0xCB, 0x00])]
#[case::double_allocation_through_explicit(&[0x03], 0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00], &[0x00, 0x94, 0x0B, 0x02])]
#[case::release_poll_through_explicit(&[0x03], 0x42C, &[0x00, 0x4C, 0x03, 0x01, 0x02], &[0x00, 0xCC])]
fn predefined_set_validation(
    #[case] allocated_first: &[u8],
    #[case] id: u16,
    #[case] request: &[u8],
    #[case] response: &[u8],
) {
    let mut rig = Rig::online();
    if let Some(&choice) = allocated_first.first() {
        let resp = rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, choice, 0x00]);
        assert_eq!(resp, tx(0x42B, &[0x00, 0xCB, 0x00]));
    }
    assert_eq!(rig.send(id, request), tx(0x42B, response));
}

#[test]
fn ownership_and_allocation_information() {
    let mut rig = Rig::explicit();
    assert_eq!(rig.node.allocation(), (AllocationChoice::EXPLICIT, Some(MacId::new(0).unwrap())));
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x05]), tx(0x42B, &[0x00, 0x8E, 0x01, 0x00]));
    assert_eq!(rig.node.identity_status() & 1, 1);
    // Releasing everything drops ownership (JB): master MAC 255.
    assert_eq!(rig.send(0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x01]), tx(0x42B, &[0x00, 0xCC]));
    assert_eq!(rig.node.allocation(), (AllocationChoice::empty(), None));
    assert_eq!(rig.node.identity_status() & 1, 0);
    // A second master may now allocate.
    assert_eq!(rig.send(0x42E, &[0x07, 0x4B, 0x03, 0x01, 0x01, 0x07]), tx(0x42B, &[0x07, 0xCB, 0x00]));
    assert_eq!(rig.node.allocation().1, MacId::new(7));
}

#[test]
fn explicit_requests_only_from_the_owner() {
    let mut rig = Rig::explicit();
    assert_eq!(rig.send(0x42C, &[0x01, 0x0E, 0x01, 0x01, 0x01]), Tx::new());
    assert_eq!(rig.node.stats().explicit_ignored, 1);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x34, 0x12]));
}

#[test]
fn explicit_request_without_connection_is_ignored() {
    let mut rig = Rig::online();
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]), Tx::new());
}

#[test]
fn group2_only_port_ignores_fragmented_frames() {
    // Unconnected messages are never fragmented (protocol §3.1, §3.4): a Frag bit means no request.
    let mut rig = Rig::online();
    assert_eq!(rig.send(0x42E, &[0x80, 0x4B, 0x03, 0x01, 0x01, 0x00]), Tx::new());
    assert_eq!(rig.node.allocation(), (AllocationChoice::empty(), None));
}

#[test]
fn header_only_explicit_frame_is_ignored_and_does_not_feed_the_watchdog() {
    let mut rig = Rig::explicit();
    rig.advance(Duration::from_secs(9));
    assert_eq!(rig.send(0x42C, &[0x00]), Tx::new());
    assert_eq!(rig.node.stats().explicit_ignored, 1);
    // Only a message consumed restarts the inactivity timer (protocol §5.3): 10 s after allocation.
    rig.advance(Duration::from_secs(1));
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::NonExistent);
}

#[test]
fn request_of_header_and_service_only_is_answered_not_enough_data() {
    let mut rig = Rig::explicit();
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E]), tx(0x42B, &[0x00, 0x94, 0x13, 0xFF]));
}

// ----- objects ---------------------------------------------------------------------------------

#[rstest]
#[case::vendor(&[0x0E, 0x01, 0x01, 0x01], &[0x8E, 0x34, 0x12])]
#[case::device_type(&[0x0E, 0x01, 0x01, 0x02], &[0x8E, 0x0C, 0x00])]
#[case::product_code(&[0x0E, 0x01, 0x01, 0x03], &[0x8E, 0x01, 0x00])]
#[case::revision(&[0x0E, 0x01, 0x01, 0x04], &[0x8E, 0x01, 0x01])]
#[case::status_owned_no_io(&[0x0E, 0x01, 0x01, 0x05], &[0x8E, 0x31, 0x00])]
#[case::serial(&[0x0E, 0x01, 0x01, 0x06], &[0x8E, 0x78, 0x56, 0x34, 0x12])]
#[case::state(&[0x0E, 0x01, 0x01, 0x08], &[0x8E, 0x03])]
#[case::identity_class_revision(&[0x0E, 0x01, 0x00, 0x01], &[0x8E, 0x01, 0x00])]
#[case::identity_class_attr_2(&[0x0E, 0x01, 0x00, 0x02], &[0x94, 0x14, 0xFF])]
#[case::identity_unknown_attr(&[0x0E, 0x01, 0x01, 0x63], &[0x94, 0x14, 0xFF])]
#[case::identity_set_vendor(&[0x10, 0x01, 0x01, 0x01, 0x00, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::identity_instance_2(&[0x0E, 0x01, 0x02, 0x01], &[0x94, 0x16, 0xFF])]
#[case::identity_reset_bad_type(&[0x05, 0x01, 0x01, 0x02], &[0x94, 0x20, 0xFF])]
#[case::identity_unsupported_service(&[0x06, 0x01, 0x01], &[0x94, 0x08, 0xFF])]
#[case::get_without_attribute(&[0x0E, 0x01, 0x01], &[0x94, 0x13, 0xFF])]
#[case::router_class_revision(&[0x0E, 0x02, 0x00, 0x01], &[0x8E, 0x01, 0x00])]
#[case::router_instance_attr(&[0x0E, 0x02, 0x01, 0x01], &[0x94, 0x14, 0xFF])]
#[case::router_instance_set(&[0x10, 0x02, 0x01, 0x01, 0x00], &[0x94, 0x08, 0xFF])]
#[case::unknown_class(&[0x0E, 0x64, 0x01, 0x01], &[0x94, 0x16, 0xFF])]
#[case::dnet_mac(&[0x0E, 0x03, 0x01, 0x01], &[0x8E, 0x05])]
#[case::dnet_baud(&[0x0E, 0x03, 0x01, 0x02], &[0x8E, 0x01])]
#[case::dnet_boi(&[0x0E, 0x03, 0x01, 0x03], &[0x8E, 0x00])]
#[case::dnet_bus_off_counter(&[0x0E, 0x03, 0x01, 0x04], &[0x8E, 0x00])]
#[case::dnet_allocation(&[0x0E, 0x03, 0x01, 0x05], &[0x8E, 0x01, 0x00])]
#[case::dnet_mac_switch_changed(&[0x0E, 0x03, 0x01, 0x06], &[0x8E, 0x00])]
#[case::dnet_baud_switch_changed(&[0x0E, 0x03, 0x01, 0x07], &[0x8E, 0x00])]
#[case::dnet_no_mac_switch(&[0x0E, 0x03, 0x01, 0x08], &[0x94, 0x14, 0xFF])]
#[case::dnet_class_revision(&[0x0E, 0x03, 0x00, 0x01], &[0x8E, 0x02, 0x00])]
#[case::dnet_set_mac_not_programmable(&[0x10, 0x03, 0x01, 0x01, 0x07], &[0x94, 0x0E, 0xFF])]
#[case::dnet_set_boi(&[0x10, 0x03, 0x01, 0x03, 0x01], &[0x90])]
#[case::dnet_clear_boi(&[0x10, 0x03, 0x01, 0x03, 0x00], &[0x90])]
#[case::dnet_set_boi_invalid(&[0x10, 0x03, 0x01, 0x03, 0x02], &[0x94, 0x09, 0xFF])]
#[case::dnet_clear_bus_off_counter(&[0x10, 0x03, 0x01, 0x04, 0x00], &[0x90])]
#[case::dnet_bus_off_counter_nonzero(&[0x10, 0x03, 0x01, 0x04, 0x05], &[0x94, 0x09, 0xFF])]
#[case::dnet_set_allocation_info(&[0x10, 0x03, 0x01, 0x05, 0x01, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::dnet_set_boi_too_long(&[0x10, 0x03, 0x01, 0x03, 0x01, 0x00], &[0x94, 0x15, 0xFF])]
#[case::dnet_unsupported_service(&[0x05, 0x03, 0x01], &[0x94, 0x08, 0xFF])]
#[case::assembly_input_size(&[0x0E, 0x04, 0x64, 0x04], &[0x8E, 0x12, 0x00])]
#[case::assembly_set_input(&[0x10, 0x04, 0x64, 0x03, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::assembly_set_size(&[0x10, 0x04, 0x96, 0x04, 0x08, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::assembly_unknown_instance(&[0x0E, 0x04, 0x01, 0x03], &[0x94, 0x16, 0xFF])]
#[case::assembly_set_output_short(&[0x10, 0x04, 0x96, 0x03, 0x01], &[0x94, 0x13, 0xFF])]
#[case::connection_class_revision(&[0x0E, 0x05, 0x00, 0x01], &[0x8E, 0x01, 0x00])]
#[case::poll_not_allocated(&[0x0E, 0x05, 0x02, 0x01], &[0x94, 0x16, 0xFF])]
#[case::bit_strobe_instance(&[0x0E, 0x05, 0x03, 0x01], &[0x94, 0x16, 0xFF])]
fn explicit_services(#[case] body: &[u8], #[case] response: &[u8]) {
    let mut rig = Rig::explicit();
    let mut request = std::vec![0x00];
    request.extend_from_slice(body);
    let mut expected = std::vec![0x00];
    expected.extend_from_slice(response);
    assert_eq!(rig.send(0x42C, &request), tx(0x42B, &expected));
}

#[rstest]
// Explicit (instance 1), protocol §5.1.
#[case::e_state(1, 1, &[0x03])]
#[case::e_instance_type(1, 2, &[0x00])]
#[case::e_transport(1, 3, &[0x83])]
#[case::e_produced_id(1, 4, &[0x2B, 0x04])]
#[case::e_consumed_id(1, 5, &[0x2C, 0x04])]
#[case::e_comm_characteristics(1, 6, &[0x21])]
#[case::e_produced_size(1, 7, &[0x40, 0x00])]
#[case::e_consumed_size(1, 8, &[0x40, 0x00])]
#[case::e_epr(1, 9, &[0xC4, 0x09])]
#[case::e_watchdog(1, 12, &[0x01])]
#[case::e_produced_path_len(1, 13, &[0x00, 0x00])]
#[case::e_produced_path(1, 14, &[])]
#[case::e_consumed_path_len(1, 15, &[0x00, 0x00])]
#[case::e_consumed_path(1, 16, &[])]
#[case::e_inhibit(1, 17, &[0x00, 0x00])]
// Poll (instance 2), after EPR set.
#[case::p_state(2, 1, &[0x03])]
#[case::p_instance_type(2, 2, &[0x01])]
#[case::p_transport(2, 3, &[0x82])]
#[case::p_produced_id(2, 4, &[0xC5, 0x03])]
#[case::p_consumed_id(2, 5, &[0x2D, 0x04])]
#[case::p_comm_characteristics(2, 6, &[0x01])]
#[case::p_produced_size(2, 7, &[0x12, 0x00])]
#[case::p_consumed_size(2, 8, &[0x08, 0x00])]
#[case::p_epr(2, 9, &[0x64, 0x00])]
#[case::p_watchdog(2, 12, &[0x00])]
#[case::p_produced_path_len(2, 13, &[0x06, 0x00])]
#[case::p_produced_path(2, 14, &[0x20, 0x04, 0x24, 0x64, 0x30, 0x03])]
#[case::p_consumed_path(2, 16, &[0x20, 0x04, 0x24, 0x96, 0x30, 0x03])]
#[case::p_inhibit(2, 17, &[0x00, 0x00])]
fn connection_attributes(#[case] instance: u8, #[case] attr: u8, #[case] value: &[u8]) {
    let mut rig = Rig::established();
    let resp = rig.send(0x42C, &[0x00, 0x0E, 0x05, instance, attr]);
    let mut expected = std::vec![0x00, 0x8E];
    expected.extend_from_slice(value);
    assert_eq!(resp, tx(0x42B, &expected));
}

#[rstest]
#[case::explicit_deferred_delete(1, 3, &[0x90])]
#[case::explicit_auto_delete(1, 1, &[0x90])]
#[case::explicit_timed_out_invalid(1, 0, &[0x94, 0x09, 0xFF])]
#[case::explicit_auto_reset_invalid(1, 2, &[0x94, 0x09, 0xFF])]
#[case::poll_timed_out(2, 0, &[0x90])]
#[case::poll_auto_delete(2, 1, &[0x90])]
#[case::poll_auto_reset(2, 2, &[0x90])]
#[case::poll_deferred_invalid(2, 3, &[0x94, 0x09, 0xFF])]
#[case::out_of_range(2, 9, &[0x94, 0x09, 0xFF])]
fn watchdog_action_values(#[case] instance: u8, #[case] value: u8, #[case] response: &[u8]) {
    let mut rig = Rig::established();
    let mut expected = std::vec![0x00];
    expected.extend_from_slice(response);
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x05, instance, 0x0C, value]), tx(0x42B, &expected));
}

#[rstest]
#[case::state(1, &[0x03], &[0x94, 0x0E, 0xFF])]
#[case::produced_size(7, &[0x12, 0x00], &[0x94, 0x0E, 0xFF])]
#[case::path(14, &[0x00], &[0x94, 0x0E, 0xFF])]
#[case::cip_connection_id(10, &[0, 0], &[0x94, 0x14, 0xFF])]
#[case::unknown(40, &[0x00], &[0x94, 0x14, 0xFF])]
#[case::epr_too_short(9, &[0x64], &[0x94, 0x13, 0xFF])]
#[case::epr_too_long(9, &[0x64, 0x00, 0x00], &[0x94, 0x15, 0xFF])]
#[case::epr_above_65000(9, &[0xE9, 0xFD], &[0x94, 0x09, 0xFF])]
#[case::epr_max(9, &[0xE8, 0xFD], &[0x90, 0xE8, 0xFD])]
fn connection_set_rules(#[case] attr: u8, #[case] value: &[u8], #[case] response: &[u8]) {
    let mut rig = Rig::established();
    let mut req = std::vec![0x00, 0x10, 0x05, 0x02, attr];
    req.extend_from_slice(value);
    let mut expected = std::vec![0x00];
    expected.extend_from_slice(response);
    assert_eq!(rig.send(0x42C, &req), tx(0x42B, &expected));
}

#[rstest]
#[case::exact(10, 100, 100)]
#[case::rounded_up(10, 95, 100)]
#[case::icp_example(100, 3594, 3600)]
#[case::one_ms(1, 3594, 3594)]
#[case::zero_disables(10, 0, 0)]
fn expected_packet_rate_rounding(#[case] resolution: u16, #[case] requested: u16, #[case] applied: u16) {
    let mut config = DeviceConfig::reference();
    config.epr_resolution_ms = resolution;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    let [lo, hi] = requested.to_le_bytes();
    let [alo, ahi] = applied.to_le_bytes();
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, lo, hi]), tx(0x42B, &[0x00, 0x90, alo, ahi]));
    assert_eq!(rig.node.poll_connection().state, ConnectionState::Established);
}

#[rstest]
#[case::configured(ApplicationStatus { configured: true, ..ApplicationStatus::default() }, [0x35, 0x00])]
#[case::minor_recoverable(ApplicationStatus { minor_recoverable_fault: true, ..ApplicationStatus::default() }, [0x31, 0x01])]
#[case::minor_unrecoverable(ApplicationStatus { minor_unrecoverable_fault: true, ..ApplicationStatus::default() }, [0x31, 0x02])]
#[case::major_recoverable(ApplicationStatus { major_recoverable_fault: true, ..ApplicationStatus::default() }, [0x31, 0x04])]
#[case::major_unrecoverable(ApplicationStatus { major_unrecoverable_fault: true, ..ApplicationStatus::default() }, [0x31, 0x08])]
fn identity_status_carries_each_application_flag_in_its_bit(
    #[case] status: ApplicationStatus,
    #[case] word: [u8; 2],
) {
    // Identity attribute 5 (protocol §6.2): owned (bit 0), configured (bit 2), extended status
    // 0b0011 "no I/O connection established" (bits 4–7), faults in bits 8–11.
    let mut rig = Rig::explicit();
    rig.node.set_application_status(status, rig.now);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x05]), tx(0x42B, &[0x00, 0x8E, word[0], word[1]]));
}

#[test]
fn identity_get_attributes_all_answers_attributes_1_to_7_in_fragments() {
    // Get_Attributes_All (protocol §3.2): the reply exceeds one frame, so it goes out in acknowledged
    // fragments (protocol §4.1); the master reassembles and acks each one.
    let mut rig = Rig::explicit();
    let mut master = crate::fragment::ExplicitReassembler::<MAX_EXPLICIT_SIZE>::new();
    let mut frames = rig.send(0x42C, &[0x00, 0x01, 0x01, 0x01]);
    // Header and 39 body bytes: 7 fragments of up to 6 body bytes.
    for _ in 0..7 {
        let [(0x42B, frame)] = frames.as_slice() else { panic!("one response fragment: {frames:02X?}") };
        match master.receive(frame) {
            crate::fragment::ExplicitReceive::Ack(ack) => frames = rig.send(0x42C, &ack),
            crate::fragment::ExplicitReceive::Complete(ack) => {
                assert_eq!(rig.send(0x42C, &ack), Tx::new());
                break;
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    let mut expected = std::vec![0x00, 0x81, 0x34, 0x12, 0x0C, 0x00, 0x01, 0x00, 0x01, 0x01, 0x31, 0x00];
    expected.extend_from_slice(&[0x78, 0x56, 0x34, 0x12, 23]);
    expected.extend_from_slice(b"Serial-DeviceNet Bridge");
    assert_eq!(master.message(), expected);
}

#[rstest]
#[case::power_cycle(&[0x00, 0x05, 0x01, 0x01], 0)]
#[case::out_of_box(&[0x00, 0x05, 0x01, 0x01, 0x01], 1)]
fn identity_reset_reports_an_event_after_queueing_the_response(#[case] request: &[u8], #[case] kind: u8) {
    let mut rig = Rig::explicit();
    // The response, then the shutdown message: class 1, instance 1, code 4 (LIM, §II.5.2).
    assert_eq!(
        rig.send(0x42C, request),
        std::vec![
            (0x42B, std::vec![0x00, 0x85]),
            (0x42B, std::vec![0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00])
        ]
    );
    assert_eq!(rig.events(), std::vec![Event::ResetRequested(kind)]);
}

#[test]
fn programmable_mac_and_baud() {
    let mut config = DeviceConfig::reference();
    config.switches.programmable = true;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
    rig.events();
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x01, 0x40]), tx(0x42B, &[0x00, 0x94, 0x09, 0xFF]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x01, 0x07]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x02, 0x02]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x02, 0x03]), tx(0x42B, &[0x00, 0x94, 0x09, 0xFF]));
    assert_eq!(
        rig.events(),
        std::vec![
            Event::SettingChanged(SettingChanged::MacId(MacId::new(7).unwrap())),
            Event::SettingChanged(SettingChanged::BaudRate(BaudRate::Kbps500)),
        ]
    );
    // The stored values are reported; the node keeps running at MAC 5 until reset.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x07]));
    assert_eq!(rig.node.mac_id().as_raw(), 5);
}

#[test]
fn switch_attributes() {
    let mut config = DeviceConfig::reference();
    config.switches = Switches {
        mac_id: Some(5),
        baud_rate: Some(1),
        mac_id_changed: true,
        baud_rate_changed: false,
        programmable: false,
    };
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x06]), tx(0x42B, &[0x00, 0x8E, 0x01]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x08]), tx(0x42B, &[0x00, 0x8E, 0x05]));
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x09]), tx(0x42B, &[0x00, 0x8E, 0x01]));
}

// ----- explicit fragmentation (protocol §4.1) ------------------------------------------------------

#[test]
fn output_assembly_reads_the_consumed_size_of_zeros_before_any_output() {
    // Connection 2 attribute 8 and the EDS say 8 bytes: the data reads as 8 bytes from the start
    // (9 body bytes with the service, so fragmented, protocol §4.1).
    let mut rig = Rig::explicit();
    let first = rig.send(0x42C, &[0x00, 0x0E, 0x04, 0x96, 0x03]);
    assert_eq!(first, tx(0x42B, &[0x80, 0x00, 0x8E, 0, 0, 0, 0, 0]));
    let last = rig.send(0x42C, &[0x80, 0xC0, 0x00]);
    assert_eq!(last, tx(0x42B, &[0x80, 0x81, 0, 0, 0]));
    assert_eq!(rig.node.output(), &[0; 8]);
}

#[test]
fn product_name_is_sent_fragmented_with_acks() {
    let mut rig = Rig::explicit();
    // "Serial-DeviceNet Bridge": 23 characters; body 8E 17 <23 bytes> = 25 bytes.
    let first = rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x07]);
    assert_eq!(first, tx(0x42B, &[0x80, 0x00, 0x8E, 0x17, b'S', b'e', b'r', b'i']));
    let mut body = first[0].1[2..].to_vec();
    let mut count = 0u8;
    loop {
        let next = rig.send(0x42C, &[0x80, 0xC0 | count, 0x00]);
        if next.is_empty() {
            break;
        }
        assert_eq!(next.len(), 1);
        let frame = &next[0].1;
        assert_eq!(frame[0], 0x80);
        count += 1;
        let kind = frame[1] >> 6;
        assert_eq!(frame[1] & 0x3F, count);
        body.extend_from_slice(&frame[2..]);
        assert!(kind == 1 || kind == 2, "middle or last fragment");
    }
    assert_eq!(count, 4, "25 body bytes = 5 fragments of up to 6");
    assert_eq!(&body[..2], &[0x8E, 23]);
    assert_eq!(&body[2..], b"Serial-DeviceNet Bridge");
}

#[test]
fn missing_ack_retries_once_then_aborts() {
    let mut rig = Rig::explicit();
    let first = rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x07]);
    assert_eq!(first.len(), 1);
    // One re-send after 1 s, then the transfer is abandoned after another second.
    assert_eq!(rig.advance(Duration::from_millis(1000)), first);
    assert_eq!(rig.advance(Duration::from_millis(1000)), Tx::new());
    assert!(rig.events().contains(&Event::ExplicitTransferAborted));
    assert_eq!(rig.advance(Duration::from_secs(3)), Tx::new());
    // The connection still serves requests.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x34, 0x12]));
}

#[test]
fn fragmented_request_is_acked_and_served() {
    let mut rig = Rig::explicit();
    // Set Assembly 150 attribute 3 = 8 bytes: body 10 04 96 03 + 8 bytes = 12 bytes, 2 fragments.
    let out = [1u8, 2, 3, 4, 5, 6, 7, 8];
    let r1 = rig.send(0x42C, &[0x80, 0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]);
    assert_eq!(r1, tx(0x42B, &[0x80, 0xC0, 0x00]));
    // A duplicate of the first fragment is re-acked, not appended.
    let dup = rig.send(0x42C, &[0x80, 0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]);
    assert_eq!(dup, tx(0x42B, &[0x80, 0xC0, 0x00]));
    let r2 = rig.send(0x42C, &[0x80, 0x81, 3, 4, 5, 6, 7, 8]);
    assert_eq!(r2, std::vec![(0x42B, std::vec![0x80, 0xC1, 0x00]), (0x42B, std::vec![0x00, 0x90])]);
    assert_eq!(rig.node.output(), &out);
    assert!(rig.events().contains(&Event::OutputReceived));
}

#[test]
fn repeated_last_fragment_is_acked_again_and_not_served_twice() {
    let mut rig = Rig::explicit();
    rig.send(0x42C, &[0x80, 0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]);
    let last = [0x80, 0x81, 3, 4, 5, 6, 7, 8];
    let r = rig.send(0x42C, &last);
    assert_eq!(r, std::vec![(0x42B, std::vec![0x80, 0xC1, 0x00]), (0x42B, std::vec![0x00, 0x90])]);
    let served = rig.events().iter().filter(|e| **e == Event::OutputReceived).count();
    // The master missed the ack and sends the last fragment again: acked, not served again.
    assert_eq!(rig.send(0x42C, &last), tx(0x42B, &[0x80, 0xC1, 0x00]));
    assert!(!rig.events().contains(&Event::OutputReceived), "served once ({served})");
    // The next request starts afresh.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x34, 0x12]));
}

#[test]
fn oversized_fragmented_request_is_rejected_with_too_much_data() {
    let mut rig = Rig::explicit();
    let mut acks = Vec::new();
    acks.extend(rig.send(0x42C, &[0x80, 0x00, 0x10, 0x04, 0x96, 0x03, 0, 0]));
    for count in 1..=12u8 {
        acks.extend(rig.send(0x42C, &[0x80, 0x40 | count, 0, 0, 0, 0, 0, 0]));
    }
    assert!(acks.iter().any(|(_, d)| d.len() == 3 && d[2] == 0x01), "an ack with status 1: {acks:02X?}");
}

// ----- polled I/O (protocol §4.2, §5) ---------------------------------------------------------------

#[test]
fn poll_ignored_until_epr_is_set() {
    let mut rig = Rig::explicit();
    rig.send(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00]);
    assert_eq!(rig.node.poll_connection().state, ConnectionState::Configuring);
    assert_eq!(rig.send(0x42D, &[0; 8]), Tx::new());
    assert_eq!(rig.node.stats().polls_ignored, 1);
}

#[test]
fn poll_answered_at_once_with_three_fragments() {
    let mut rig = Rig::established();
    let resp = rig.send(0x42D, &[1, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(
        resp,
        std::vec![
            (0x3C5, std::vec![0x00, 0, 0, 0, 0, 0, 0, 0]),
            (0x3C5, std::vec![0x41, 0, 0, 0x0F, 0, 0, 0, 0]),
            (0x3C5, std::vec![0x82, 0, 0, 0, 0]),
        ]
    );
    assert_eq!(rig.node.output(), &[1, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(rig.events(), std::vec![Event::OutputReceived]);
    assert_eq!(rig.node.identity_status() >> 4 & 0xF, 0b0110);
}

#[test]
fn fragments_as_io_fragments() {
    // Every fragmented produced size: the poll response is the frames of `io_fragments` (the
    // transmit queue holds the first TX_QUEUE_LEN of them).
    for size in 9..=MAX_IO_SIZE as u16 {
        let mut config = DeviceConfig::reference();
        config.produced_size = size;
        let mut rig = Rig::new(config);
        let input: Vec<u8> = (0..size).map(|i| i as u8 ^ 0xA5).collect();
        rig.node.set_input(&input).unwrap();
        rig.node.power_on(Instant::ZERO);
        rig.advance(Duration::from_secs(2));
        rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
        rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
        let expected: Tx =
            crate::fragment::io_fragments(&input).take(TX_QUEUE_LEN).map(|p| (0x3C5, p.to_vec())).collect();
        assert_eq!(rig.send(0x42D, &[0; 8]), expected, "produced size {size}");
    }
}

#[test]
fn idle_poll_is_reported_and_answered() {
    let mut rig = Rig::established();
    rig.send(0x42D, &[9; 8]);
    rig.events();
    assert_eq!(rig.send(0x42D, &[]).len(), 3);
    assert_eq!(rig.events(), std::vec![Event::Idle]);
    assert!(rig.node.is_idle());
    assert_eq!(rig.node.output(), &[9; 8], "idle keeps the last outputs");
    assert_eq!(rig.node.identity_status() >> 4 & 0xF, 0b0111);
}

#[test]
fn short_poll_accepted_long_poll_ignored() {
    let mut config = DeviceConfig::reference();
    config.consumed_size = 4;
    config.produced_size = 2;
    let mut rig = Rig::new(config);
    rig.node.set_input(&[0xAA, 0xBB]).unwrap();
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    assert_eq!(rig.send(0x42D, &[1, 2]), tx(0x3C5, &[0xAA, 0xBB]), "produced size <= 8: not fragmented");
    assert_eq!(rig.send(0x42D, &[1, 2, 3, 4, 5]), Tx::new());
}

#[test]
fn poll_with_data_after_an_idle_poll_ends_idle() {
    let mut rig = Rig::established();
    assert!(!rig.node.is_idle());
    rig.send(0x42D, &[]);
    assert!(rig.node.is_idle());
    rig.send(0x42D, &[3; 8]);
    assert!(!rig.node.is_idle());
    assert_eq!(rig.events(), std::vec![Event::Idle, Event::OutputReceived]);
}

#[test]
fn eight_byte_poll_response_is_one_unfragmented_frame() {
    // I/O fragmentation starts above 8 bytes (protocol §4.2).
    let mut config = DeviceConfig::reference();
    config.produced_size = 8;
    let mut rig = Rig::new(config);
    rig.node.set_input(&[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    assert_eq!(rig.send(0x42D, &[0; 8]), tx(0x3C5, &[1, 2, 3, 4, 5, 6, 7, 8]));
}

#[test]
fn fragmented_poll_command_up_to_the_consumed_size_is_accepted() {
    // Consumed size 10: the command comes in I/O fragments (protocol §4.2); a longer one is ignored.
    let mut config = DeviceConfig::reference();
    config.consumed_size = 10;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    rig.events();
    assert_eq!(rig.send(0x42D, &[0x00, 1, 2, 3, 4, 5, 6, 7]), Tx::new());
    assert_eq!(rig.send(0x42D, &[0x81, 8, 9, 10]).len(), 3, "answered with the 18-byte input");
    assert_eq!(rig.node.output(), &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
    assert_eq!(rig.events(), std::vec![Event::OutputReceived]);
    // 14 bytes: one fragment more than the consumed size allows.
    assert_eq!(rig.send(0x42D, &[0x00, 9, 9, 9, 9, 9, 9, 9]), Tx::new());
    assert_eq!(rig.send(0x42D, &[0x81, 9, 9, 9, 9, 9, 9, 9]), Tx::new());
    assert_eq!(rig.node.output(), &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
    assert_eq!(rig.node.stats().polls_ignored, 1);
    assert_eq!(rig.events(), Vec::<Event>::new());
}

#[test]
fn set_input_checks_the_size() {
    let mut rig = Rig::established();
    assert_eq!(rig.node.set_input(&[0; 3]), Err(18));
    let mut image = [0u8; 18];
    image[0] = 0x42;
    rig.node.set_input(&image).unwrap();
    assert_eq!(rig.send(0x42D, &[0; 8])[0].1, std::vec![0x00, 0x42, 0, 0, 0, 0, 0, 0]);
}

#[test]
fn input_mut_writes_the_image_in_place() {
    let mut rig = Rig::established();
    assert_eq!(rig.node.input_mut().len(), 18, "exactly the produced size");
    rig.node.input_mut()[1] = 0x42;
    assert_eq!(rig.node.input()[..3], [0, 0x42, 0]);
    assert_eq!(rig.send(0x42D, &[0; 8])[0].1, std::vec![0x00, 0, 0x42, 0, 0, 0, 0, 0]);
}

#[test]
fn assembly_output_set_refused_while_polling() {
    let mut config = DeviceConfig::reference();
    config.consumed_size = 2;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    // Configuring: the outputs may be set explicitly.
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]), tx(0x42B, &[0x00, 0x90]));
    assert_eq!(rig.node.output(), &[1, 2]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    // Established: the poll connection owns them.
    assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]), tx(0x42B, &[0x00, 0x94, 0x10, 0xFF]));
}

#[test]
fn setting_the_poll_epr_establishes_it_once() {
    let mut rig = Rig::explicit();
    rig.send(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00]);
    rig.events();
    // Configuring -> Established when the EPR is set (protocol §5.2); a second Set changes nothing.
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
    assert_eq!(rig.events(), std::vec![Event::ConnectionEstablished(ConnectionKind::Poll)]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0xC8, 0x00]);
    assert_eq!(rig.events(), Vec::<Event>::new());
}

// ----- watchdogs (protocol §5.2–§5.4) ---------------------------------------------------------------

#[test]
fn explicit_inactivity_deletes_after_ten_seconds() {
    let mut rig = Rig::explicit();
    assert_eq!(rig.node.explicit_connection().deadline, rig.now + Duration::from_secs(10));
    rig.advance(Duration::from_millis(9_999));
    assert!(rig.node.explicit_connection().is_established());
    rig.advance(Duration::from_millis(1));
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::NonExistent);
    assert_eq!(rig.events(), std::vec![Event::ConnectionDeleted(ConnectionKind::Explicit)]);
    assert_eq!(rig.node.allocation(), (AllocationChoice::empty(), None));
}

#[test]
fn explicit_traffic_restarts_the_watchdog() {
    let mut rig = Rig::explicit();
    for _ in 0..5 {
        rig.advance(Duration::from_secs(9));
        rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]);
    }
    assert!(rig.node.explicit_connection().is_established());
}

#[test]
fn poll_timeout_with_transition_to_timed_out() {
    let mut rig = Rig::established();
    rig.advance(Duration::from_millis(399));
    assert!(rig.node.poll_connection().is_established());
    rig.advance(Duration::from_millis(1));
    assert_eq!(rig.node.poll_connection().state, ConnectionState::TimedOut);
    assert_eq!(rig.events(), std::vec![Event::ConnectionTimedOut(ConnectionKind::Poll)]);
    assert_eq!(rig.node.network_indication(), Indication::FlashingRed);
    assert_eq!(rig.node.identity_status() >> 4 & 0xF, 0b0010);
    // Polls are ignored in the timed-out state; a Connection Reset brings it back.
    assert_eq!(rig.send(0x42D, &[0; 8]), Tx::new());
    assert_eq!(rig.send(0x42C, &[0x00, 0x05, 0x05, 0x02]), tx(0x42B, &[0x00, 0x85]));
    assert_eq!(rig.send(0x42D, &[0; 8]).len(), 3);
}

#[test]
fn connection_reset_reports_a_timed_out_poll_established_again() {
    let mut rig = Rig::established();
    // Reset of an established connection only restarts its timer: no event.
    assert_eq!(rig.send(0x42C, &[0x00, 0x05, 0x05, 0x02]), tx(0x42B, &[0x00, 0x85]));
    assert_eq!(rig.events(), Vec::<Event>::new());
    rig.advance(Duration::from_millis(400));
    assert_eq!(rig.events(), std::vec![Event::ConnectionTimedOut(ConnectionKind::Poll)]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x05, 0x05, 0x02]), tx(0x42B, &[0x00, 0x85]));
    assert_eq!(rig.events(), std::vec![Event::ConnectionEstablished(ConnectionKind::Poll)]);
}

#[test]
fn poll_auto_delete_and_auto_reset() {
    let mut rig = Rig::established();
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x0C, 0x02]);
    rig.advance(Duration::from_millis(1000));
    assert!(rig.node.poll_connection().is_established(), "auto reset keeps it established");
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x0C, 0x01]);
    rig.events();
    rig.advance(Duration::from_millis(400));
    assert_eq!(rig.node.poll_connection().state, ConnectionState::NonExistent);
    assert_eq!(rig.node.allocation().0, AllocationChoice::EXPLICIT);
}

#[test]
fn deferred_delete_waits_for_the_io_connection() {
    let mut rig = Rig::established();
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x01, 0x0C, 0x03]);
    // Keep polling for 12 s: the explicit watchdog (10 s) expires into deferred delete.
    for _ in 0..120 {
        rig.advance(Duration::from_millis(100));
        rig.send(0x42D, &[0; 8]);
    }
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::DeferredDelete);
    // Explicit traffic brings it back to established.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x05, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x03]));
    for _ in 0..120 {
        rig.advance(Duration::from_millis(100));
        rig.send(0x42D, &[0; 8]);
    }
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::DeferredDelete);
    // Polling stops: the poll times out and the explicit connection is deleted with it (JB).
    rig.events();
    rig.advance(Duration::from_millis(400));
    assert_eq!(rig.node.poll_connection().state, ConnectionState::TimedOut);
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::NonExistent);
    assert_eq!(
        rig.events(),
        std::vec![
            Event::ConnectionTimedOut(ConnectionKind::Poll),
            Event::ConnectionDeleted(ConnectionKind::Explicit)
        ]
    );
}

#[test]
fn deferred_delete_without_io_deletes() {
    let mut rig = Rig::explicit();
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x01, 0x0C, 0x03]);
    rig.advance(Duration::from_secs(10));
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::NonExistent);
}

// ----- bus-off (protocol §7.2) ------------------------------------------------------------------------

#[test]
fn bus_off_without_boi_faults() {
    let mut rig = Rig::established();
    rig.node.handle_bus_off(rig.now);
    assert_eq!(rig.node.network_state(), NetworkState::CommunicationFaulted(FaultReason::BusOff));
    assert_eq!(rig.node.bus_off_counter(), 1);
    assert_eq!(rig.node.allocation(), (AllocationChoice::empty(), None));
    assert_eq!(rig.node.network_indication(), Indication::Red);
    assert_eq!(rig.send(0x42D, &[0; 8]), Tx::new());
}

#[test]
fn bus_off_with_boi_restarts_the_duplicate_mac_check() {
    let mut config = DeviceConfig::reference();
    config.bus_off_interrupt = true;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.events();
    rig.node.handle_bus_off(rig.now);
    assert_eq!(rig.events(), std::vec![Event::ResetCanController]);
    assert_eq!(rig.drain(), tx(0x42F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]));
    rig.advance(Duration::from_secs(2));
    assert_eq!(rig.node.network_state(), NetworkState::Online);
    assert_eq!(rig.node.bus_off_counter(), 1);
}

#[test]
fn bus_off_counter_counts_every_bus_off() {
    let mut config = DeviceConfig::reference();
    config.bus_off_interrupt = true;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    assert_eq!(rig.node.bus_off_counter(), 0);
    for _ in 0..2 {
        rig.node.handle_bus_off(rig.now);
        rig.advance(Duration::from_secs(2));
    }
    assert_eq!(rig.node.bus_off_counter(), 2);
    // DeviceNet attribute 4 (protocol §6.1) reports the same count.
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x04]), tx(0x42B, &[0x00, 0x8E, 0x02]));
}

// ----- LEDs (protocol §7.3) ---------------------------------------------------------------------------

#[test]
fn led_indications_follow_the_state() {
    let mut rig = Rig::new(DeviceConfig::reference());
    rig.node.power_on(Instant::ZERO);
    assert_eq!(rig.node.leds(Instant::ZERO).module, led::Lit::Green, "self-test: MS green first");
    rig.advance(Duration::from_secs(2));
    assert_eq!(rig.node.network_indication(), Indication::FlashingGreen);
    assert_eq!(rig.node.module_indication(), Indication::Green);
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
    assert_eq!(rig.node.network_indication(), Indication::Green);
    let status = ApplicationStatus { minor_recoverable_fault: true, ..ApplicationStatus::default() };
    rig.node.set_application_status(status, rig.now);
    assert_eq!(rig.node.module_indication(), Indication::FlashingRed);
    assert_eq!(rig.node.identity_status() & 0x100, 0x100);
}

#[test]
fn leds_show_the_indications_once_the_power_up_test_is_over() {
    use led::{Leds, Lit};
    // Powered on at 0 s (test over at 1.5 s), on-line at 2 s: Module Status solid green,
    // Network Status flashing green in phase with going on-line, 0.5 s on / 0.5 s off (protocol §7.3).
    let rig = Rig::online();
    assert_eq!(rig.node.leds(Instant::from_millis(2000)), Leds { module: Lit::Green, network: Lit::Green });
    assert_eq!(rig.node.leds(Instant::from_millis(2500)), Leds { module: Lit::Green, network: Lit::Off });
    assert_eq!(rig.node.leds(Instant::from_millis(3000)), Leds { module: Lit::Green, network: Lit::Green });
}

#[test]
fn major_unrecoverable_fault_alone_shows_module_status_solid_red() {
    let mut rig = Rig::online();
    let status = ApplicationStatus { major_unrecoverable_fault: true, ..ApplicationStatus::default() };
    rig.node.set_application_status(status, rig.now);
    assert_eq!(rig.node.module_indication(), Indication::Red);
}

#[test]
fn application_objects_are_served() {
    struct Stats;
    impl ObjectHandler for Stats {
        fn handle(&mut self, req: &Request<'_>, reply: &mut Reply<'_>) -> Option<Result<(), ServiceError>> {
            (req.class == 0x64).then(|| match (req.service, req.data) {
                (ServiceCode::GetAttributeSingle, [1]) => reply.u32(0xDEAD_BEEF),
                _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
            })
        }
    }
    let mut rig = Rig::explicit();
    let frame = CanFrame::from_raw(0x42C, &[0x00, 0x0E, 0x64, 0x01, 0x01]).unwrap();
    rig.node.handle_frame_with(&frame, rig.now, &mut Stats);
    assert_eq!(rig.drain(), tx(0x42B, &[0x00, 0x8E, 0xEF, 0xBE, 0xAD, 0xDE]));
    let frame = CanFrame::from_raw(0x42C, &[0x00, 0x0E, 0x65, 0x01, 0x01]).unwrap();
    rig.node.handle_frame_with(&frame, rig.now, &mut Stats);
    assert_eq!(rig.drain(), tx(0x42B, &[0x00, 0x94, 0x16, 0xFF]));
}

// ----- bit-strobe, change of state, cyclic, heartbeat, offline set (docs/io-connections.md) ---

mod connection_types {
    use super::*;

    /// An input image whose bytes tell where they come from.
    const INPUT: [u8; 18] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17];

    /// The 18-byte input as I/O fragments on `id` (protocol §4.2).
    fn fragments(id: u16) -> Tx {
        std::vec![
            (id, std::vec![0x00, 0, 1, 2, 3, 4, 5, 6]),
            (id, std::vec![0x41, 7, 8, 9, 10, 11, 12, 13]),
            (id, std::vec![0x82, 14, 15, 16, 17]),
        ]
    }

    /// On-line, `choice` allocated through the Group 2 Only port by master 0, and the EPR of
    /// `instance` set to `epr` ms.
    fn allocated(choice: u8, instance: u8, epr: u16) -> Rig {
        let mut rig = Rig::online();
        rig.node.set_input(&INPUT).unwrap();
        assert_eq!(rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, choice, 0x00]), tx(0x42B, &[0x00, 0xCB, 0x00]));
        let [lo, hi] = epr.to_le_bytes();
        assert_eq!(
            rig.send(0x42C, &[0x00, 0x10, 0x05, instance, 0x09, lo, hi]),
            tx(0x42B, &[0x00, 0x90, lo, hi])
        );
        rig.events();
        rig
    }

    fn get(rig: &mut Rig, class: u8, instance: u8, attr: u8) -> Vec<u8> {
        let frames = rig.send(0x42C, &[0x00, 0x0E, class, instance, attr]);
        assert_eq!(frames.len(), 1, "{frames:02X?}");
        frames[0].1[2..].to_vec()
    }

    #[test]
    fn strobe_answers_every_strobe_with_the_first_eight_input_bytes() {
        let mut rig = allocated(0x05, 3, 100);
        assert!(rig.node.strobe_connection().is_established());
        // Our bit (MAC 5 = byte 0 bit 5) set, then clear: answered both times (NI, §II.1.3).
        let response = tx(0x385, &[0, 1, 2, 3, 4, 5, 6, 7]);
        assert_eq!(rig.send(0x400, &[0x20, 0, 0, 0, 0, 0, 0, 0]), response);
        assert!(rig.node.strobe_bit());
        assert_eq!(rig.send(0x400, &[0xDF, 0xFF, 0, 0, 0, 0, 0, 0]), response);
        assert!(!rig.node.strobe_bit());
        // The output image is not touched by a strobe.
        assert_eq!(rig.node.output(), &[0; 8]);
    }

    #[rstest]
    #[case::short(0x400, &[0x20, 0, 0, 0, 0, 0, 0])]
    #[case::empty(0x400, &[])]
    #[case::another_master(0x408, &[0x20, 0, 0, 0, 0, 0, 0, 0])]
    fn strobe_ignores_what_is_not_the_owners_whole_command(#[case] id: u16, #[case] data: &[u8]) {
        let mut rig = allocated(0x05, 3, 100);
        assert_eq!(rig.send(id, data), Tx::new());
        assert!(!rig.node.strobe_bit());
    }

    #[test]
    fn strobe_is_not_answered_until_established() {
        let mut rig = Rig::explicit();
        assert_eq!(rig.send(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x04, 0x00]), tx(0x42B, &[0x00, 0xCB, 0x00]));
        assert_eq!(rig.node.strobe_connection().state, ConnectionState::Configuring);
        assert_eq!(rig.send(0x400, &[0x20, 0, 0, 0, 0, 0, 0, 0]), Tx::new());
    }

    #[test]
    fn strobe_watchdog_times_out_after_four_expected_packet_rates() {
        let mut rig = allocated(0x05, 3, 100);
        rig.send(0x400, &[0; 8]);
        rig.advance(Duration::from_millis(399));
        assert!(rig.events().is_empty());
        rig.advance(Duration::from_millis(1));
        assert_eq!(rig.events(), std::vec![Event::ConnectionTimedOut(ConnectionKind::Strobe)]);
        assert_eq!(rig.node.identity_status() >> 4 & 0xF, 0b0010);
        assert_eq!(rig.node.network_indication(), led::Indication::FlashingRed);
        // A timed-out strobe connection answers nothing.
        assert_eq!(rig.send(0x400, &[0; 8]), Tx::new());
    }

    #[rstest]
    // Strobe (§II.1.1): transport, produced 0x385, consumed the master's G2 msg 0, 0x02, sizes.
    #[case::strobe_transport(0x05, 3, 3, &[0x82])]
    #[case::strobe_produced_id(0x05, 3, 4, &[0x85, 0x03])]
    #[case::strobe_consumed_id(0x05, 3, 5, &[0x00, 0x04])]
    #[case::strobe_comm(0x05, 3, 6, &[0x02])]
    #[case::strobe_produced_size(0x05, 3, 7, &[0x08, 0x00])]
    #[case::strobe_consumed_size(0x05, 3, 8, &[0x08, 0x00])]
    #[case::strobe_produced_path(0x05, 3, 14, &[0x20, 0x04, 0x24, 0x64, 0x30, 0x03])]
    #[case::strobe_no_consumed_path(0x05, 3, 15, &[0x00, 0x00])]
    #[case::strobe_consumed_path_empty(0x05, 3, 16, &[])]
    // COS acknowledged (§II.2.2, RA tables).
    #[case::cos_transport(0x11, 4, 3, &[0x13])]
    #[case::cos_produced_id(0x11, 4, 4, &[0x45, 0x03])]
    #[case::cos_consumed_id(0x11, 4, 5, &[0x2A, 0x04])]
    #[case::cos_comm(0x11, 4, 6, &[0x01])]
    #[case::cos_produced_size(0x11, 4, 7, &[0x12, 0x00])]
    #[case::cos_consumed_size(0x11, 4, 8, &[0x00, 0x00])]
    #[case::cos_ack_handler_path(0x11, 4, 16, &[0x20, 0x2B, 0x24, 0x01, 0x30, 0x01])]
    #[case::cos_produced_path(0x11, 4, 14, &[0x20, 0x04, 0x24, 0x64, 0x30, 0x03])]
    #[case::cos_inhibit(0x11, 4, 17, &[0x00, 0x00])]
    // Cyclic and acknowledge suppression.
    #[case::cyclic_transport(0x21, 4, 3, &[0x03])]
    #[case::cos_suppressed_transport(0x51, 4, 3, &[0x10])]
    #[case::cyclic_suppressed_transport(0x61, 4, 3, &[0x00])]
    #[case::suppressed_consumed_id(0x51, 4, 5, &[0xFF, 0xFF])]
    #[case::suppressed_comm(0x51, 4, 6, &[0x0F])]
    #[case::suppressed_no_consumed_path(0x51, 4, 15, &[0x00, 0x00])]
    #[case::suppressed_consumed_path_empty(0x51, 4, 16, &[])]
    // Connection 2 created to consume the master's COS data (§II.2.5, EAT).
    #[case::consumer_transport(0x11, 2, 3, &[0x82])]
    #[case::consumer_produced_size(0x11, 2, 7, &[0x00, 0x00])]
    #[case::consumer_consumed_size(0x11, 2, 8, &[0x08, 0x00])]
    #[case::consumer_produced_path_empty(0x11, 2, 14, &[])]
    #[case::consumer_consumed_path(0x11, 2, 16, &[0x20, 0x04, 0x24, 0x96, 0x30, 0x03])]
    #[case::consumer_suppressed_transport(0x51, 2, 3, &[0x80])]
    #[case::consumer_suppressed_comm(0x51, 2, 6, &[0xF1])]
    #[case::consumer_state(0x11, 2, 1, &[0x03])]
    // With poll, Connection 2 is an ordinary poll connection.
    #[case::poll_with_cos(0x13, 2, 7, &[0x12, 0x00])]
    fn io_connection_attributes(
        #[case] choice: u8,
        #[case] instance: u8,
        #[case] attr: u8,
        #[case] value: &[u8],
    ) {
        let epr_instance = if instance == 2 {
            if choice & 0x02 != 0 {
                2
            } else {
                4
            }
        } else {
            instance
        };
        let mut rig = allocated(choice, epr_instance, 1000);
        rig.advance(Duration::from_millis(1));
        assert_eq!(get(&mut rig, 0x05, instance, attr), value);
    }

    #[test]
    fn acknowledged_cos_produces_at_once_then_on_change_and_every_epr() {
        let mut rig = allocated(0x11, 4, 1000);
        // The first production right after Established, then one acknowledgement.
        assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
        assert_eq!(rig.send(0x42A, &[]), Tx::new());
        // A change is produced at once.
        rig.advance(Duration::from_millis(100));
        rig.node.input_changed(rig.now);
        assert_eq!(rig.drain(), fragments(0x345));
        rig.send(0x42A, &[]);
        // Nothing changes: the next production one EPR after the last (the COS heartbeat).
        assert_eq!(rig.advance(Duration::from_millis(999)), Tx::new());
        assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345));
        rig.send(0x42A, &[]);
        assert!(rig.events().is_empty());
        assert!(rig.node.cos_connection().is_established());
    }

    #[test]
    fn production_inhibit_time_delays_a_change() {
        let mut rig = Rig::online();
        rig.node.set_input(&INPUT).unwrap();
        rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x51, 0x00]);
        // Inhibit time 50 ms, set while configuring (§II.2.3).
        assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x05, 0x04, 0x11, 0x32, 0x00]), tx(0x42B, &[0x00, 0x90]));
        rig.send(0x42C, &[0x00, 0x10, 0x05, 0x04, 0x09, 0xE8, 0x03]);
        assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
        rig.advance(Duration::from_millis(10));
        rig.node.input_changed(rig.now);
        assert_eq!(rig.drain(), Tx::new(), "inside the inhibit time");
        assert_eq!(rig.advance(Duration::from_millis(39)), Tx::new());
        assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345), "when it ends");
    }

    #[test]
    fn unacknowledged_production_is_sent_again_then_the_retry_limit_is_reported() {
        let mut rig = allocated(0x11, 4, 1000);
        assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
        // The acknowledge timer (16 ms by default, §II.2.4), then the whole series again.
        assert_eq!(rig.advance(Duration::from_millis(15)), Tx::new());
        assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345));
        // Retry limit 1: the next timeout is reported and nothing more is sent until the next trigger.
        assert_eq!(rig.advance(Duration::from_millis(16)), Tx::new());
        assert_eq!(rig.events(), std::vec![Event::RetryLimitReached]);
        assert!(rig.node.cos_connection().is_established(), "the connection stays");
    }

    #[test]
    fn acknowledge_handler_attributes_are_read_and_set() {
        let mut rig = allocated(0x11, 4, 1000);
        assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
        rig.send(0x42A, &[]);
        assert_eq!(get(&mut rig, 0x2B, 1, 1), &[0x10, 0x00]);
        assert_eq!(get(&mut rig, 0x2B, 1, 2), &[0x01]);
        assert_eq!(get(&mut rig, 0x2B, 1, 3), &[0x04, 0x00]);
        assert_eq!(get(&mut rig, 0x2B, 0, 1), &[0x01, 0x00]);
        assert_eq!(get(&mut rig, 0x2B, 0, 2), &[0x01, 0x00]);
        // The class instance has no attribute 3, and no Set.
        assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x2B, 0x00, 0x03]), tx(0x42B, &[0x00, 0x94, 0x14, 0xFF]));
        assert_eq!(
            rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x00, 0x01, 0x01]),
            tx(0x42B, &[0x00, 0x94, 0x08, 0xFF])
        );
        assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x01, 0x01, 0x28, 0x00]), tx(0x42B, &[0x00, 0x90]));
        assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x01, 0x02, 0x03]), tx(0x42B, &[0x00, 0x90]));
        assert_eq!(rig.node.ack_handler(), AckHandler { acknowledge_timer_ms: 40, retry_limit: 3 });
        // Timer 0 is invalid (U3K); attribute 3 is not settable; no attribute 8.
        assert_eq!(
            rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x01, 0x01, 0x00, 0x00]),
            tx(0x42B, &[0x00, 0x94, 0x09, 0xFF])
        );
        assert_eq!(
            rig.send(0x42C, &[0x00, 0x10, 0x2B, 0x01, 0x03, 0x04, 0x00]),
            tx(0x42B, &[0x00, 0x94, 0x0E, 0xFF])
        );
        assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x2B, 0x01, 0x08]), tx(0x42B, &[0x00, 0x94, 0x14, 0xFF]));
        assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x2B, 0x02, 0x01]), tx(0x42B, &[0x00, 0x94, 0x16, 0xFF]));
        // The new timer is used: 40 ms, then the retry.
        rig.node.input_changed(rig.now);
        assert_eq!(rig.drain(), fragments(0x345));
        assert_eq!(rig.advance(Duration::from_millis(39)), Tx::new());
        assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345));
    }

    #[test]
    fn cyclic_with_acknowledge_suppression_produces_every_epr_and_never_times_out() {
        let mut rig = allocated(0x61, 4, 100);
        assert_eq!(rig.advance(Duration::ZERO), fragments(0x345));
        assert_eq!(rig.advance(Duration::from_millis(99)), Tx::new());
        assert_eq!(rig.advance(Duration::from_millis(1)), fragments(0x345));
        // A change does not trigger a cyclic connection.
        rig.node.input_changed(rig.now);
        assert_eq!(rig.drain(), Tx::new());
        // No acknowledgement ever: no retry, no timeout.
        let sent = rig.advance(Duration::from_millis(1000));
        assert_eq!(sent.len(), 30, "ten productions of three fragments");
        assert!(rig.events().is_empty());
        assert!(rig.node.cos_connection().is_established());
        assert_eq!(rig.node.cos_connection().deadline, Instant::MAX);
    }

    #[test]
    fn master_cos_data_without_poll_is_consumed_and_acknowledged() {
        let mut rig = allocated(0x11, 4, 1000);
        rig.advance(Duration::ZERO);
        assert_eq!(rig.send(0x42D, &[1, 2, 3, 4, 5, 6, 7, 8]), tx(0x3C5, &[]));
        assert_eq!(rig.node.output(), &[1, 2, 3, 4, 5, 6, 7, 8]);
        assert_eq!(rig.events(), std::vec![Event::OutputReceived]);
        // Under acknowledge suppression it is consumed without an acknowledgement.
        let mut rig = allocated(0x51, 4, 1000);
        rig.advance(Duration::ZERO);
        assert_eq!(rig.send(0x42D, &[8, 7, 6, 5, 4, 3, 2, 1]), Tx::new());
        assert_eq!(rig.node.output(), &[8, 7, 6, 5, 4, 3, 2, 1]);
    }

    #[test]
    fn poll_and_cos_together_keep_poll_responses() {
        let mut rig = allocated(0x13, 4, 1000);
        rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]);
        rig.advance(Duration::ZERO);
        assert_eq!(rig.send(0x42D, &[0; 8]), fragments(0x3C5));
    }

    #[test]
    fn cos_watchdog_is_kept_alive_by_acknowledgements() {
        let mut rig = allocated(0x11, 4, 100);
        rig.advance(Duration::ZERO);
        rig.send(0x42A, &[]);
        for _ in 0..10 {
            rig.advance(Duration::from_millis(100));
            rig.send(0x42A, &[]);
        }
        assert!(rig.events().is_empty());
        // Without acknowledgements: 4 x EPR after the last one, timed out; production stops.
        rig.advance(Duration::from_millis(400));
        assert!(rig.events().contains(&Event::ConnectionTimedOut(ConnectionKind::ChangeOfState)));
        assert_eq!(rig.advance(Duration::from_millis(1000)), Tx::new());
    }

    #[test]
    fn cos_epr_zero_is_refused() {
        let mut rig = Rig::online();
        rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x11, 0x00]);
        assert_eq!(
            rig.send(0x42C, &[0x00, 0x10, 0x05, 0x04, 0x09, 0x00, 0x00]),
            tx(0x42B, &[0x00, 0x94, 0x09, 0xFF])
        );
    }

    #[test]
    fn releasing_cos_deletes_the_connection_it_created() {
        let mut rig = allocated(0x11, 4, 1000);
        rig.advance(Duration::ZERO);
        rig.send(0x42A, &[]);
        assert_eq!(rig.send(0x42C, &[0x00, 0x4C, 0x03, 0x01, 0x10]), tx(0x42B, &[0x00, 0xCC]));
        assert!(!rig.node.cos_connection().exists());
        assert!(!rig.node.poll_connection().exists());
        assert_eq!(rig.node.allocation().0, AllocationChoice::EXPLICIT);
        assert_eq!(rig.advance(Duration::from_millis(2000)), Tx::new());
    }

    #[test]
    fn heartbeat_every_interval_while_on_line() {
        let mut rig = Rig::explicit();
        assert_eq!(get(&mut rig, 0x01, 1, 10), &[0x00]);
        assert_eq!(rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x0A, 0x02]), tx(0x42B, &[0x00, 0x90]));
        assert_eq!(get(&mut rig, 0x01, 1, 10), &[0x02]);
        let heartbeat = tx(0x42B, &[0x05, 0xCD, 0x01, 0x00, 0x03, 0x00, 0x00, 0x00]);
        assert_eq!(rig.advance(Duration::from_millis(1999)), Tx::new());
        assert_eq!(rig.advance(Duration::from_millis(1)), heartbeat);
        assert_eq!(rig.advance(Duration::from_secs(2)), heartbeat);
        // Off again.
        rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x0A, 0x00]);
        assert_eq!(rig.advance(Duration::from_secs(10)), Tx::new());
    }

    #[test]
    fn heartbeat_flags_a_timed_out_connection() {
        let mut rig = allocated(0x03, 2, 100);
        rig.send(0x42C, &[0x00, 0x10, 0x01, 0x01, 0x0A, 0x01]);
        let sent = rig.advance(Duration::from_secs(1));
        // SF (bit 2): the poll connection timed out (LIM, §II.5.1).
        assert_eq!(sent, tx(0x42B, &[0x05, 0xCD, 0x01, 0x00, 0x03, 0x04, 0x00, 0x00]));
    }

    /// A node that found MAC 5 taken during its check: Communication Faulted.
    fn faulted() -> Rig {
        let mut rig = Rig::new(DeviceConfig::reference());
        rig.node.power_on(rig.now);
        rig.drain();
        rig.send(0x42F, &[0x80, 0x99, 0x00, 0x01, 0x00, 0x00, 0x00]);
        assert_eq!(rig.node.network_state(), NetworkState::CommunicationFaulted(FaultReason::DuplicateMacId));
        rig.events();
        rig
    }

    #[test]
    fn faulted_node_answers_who_after_its_time_delay() {
        let mut rig = faulted();
        // `3F 4B 02` (ICP): every faulted node; the delay is byte 2 of the answer, 0x12 = 18 ms.
        assert_eq!(rig.send(0x7ED, &[0x3F, 0x4B, 0x02]), Tx::new());
        assert_eq!(rig.advance(Duration::from_millis(17)), Tx::new());
        assert_eq!(
            rig.advance(Duration::from_millis(1)),
            tx(0x7EC, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12])
        );
        // Exact MAC match: 5 answers, 6 does not; mask 0x38 does not select MAC 5.
        rig.send(0x7ED, &[0x45, 0x4B, 0x00]);
        assert_eq!(rig.advance(Duration::ZERO), tx(0x7EC, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]));
        rig.send(0x7ED, &[0x46, 0x4B, 0x00]);
        rig.send(0x7ED, &[0x38, 0x4B, 0x00]);
        assert_eq!(rig.advance(Duration::from_millis(100)), Tx::new());
    }

    #[test]
    fn faulted_node_identifies_itself_and_takes_ownership() {
        let mut rig = faulted();
        assert_eq!(rig.node.network_indication(), led::Indication::Red);
        let key = [0x34, 0x12, 0x78, 0x56, 0x34, 0x12];
        let mut identify = std::vec![0x3F, 0x4C];
        identify.extend_from_slice(&key);
        assert_eq!(rig.send(0x7ED, &identify), tx(0x7EC, &[0x3F, 0xCC]));
        assert_eq!(rig.node.network_indication(), led::Indication::FlashingRedGreen);
        // Another device's key: no answer.
        assert_eq!(rig.send(0x7ED, &[0x3F, 0x4C, 0x34, 0x12, 0x79, 0x56, 0x34, 0x12]), Tx::new());
        // Ownership by tool 0x3E (its own key): echoed; a second tool is not answered.
        let ownership = [0x3E, 0x4B, 0x99, 0x00, 0x01, 0x00, 0x00, 0x00];
        assert_eq!(rig.send(0x7EF, &ownership), tx(0x7EE, &[0x3E, 0xCB, 0x99, 0x00, 0x01, 0x00, 0x00, 0x00]));
        assert_eq!(rig.send(0x7EF, &[0x3D, 0x4B, 0x98, 0x00, 0x01, 0x00, 0x00, 0x00]), Tx::new());
    }

    #[test]
    fn change_mac_id_restarts_the_duplicate_mac_check_at_the_new_mac() {
        let mut rig = faulted();
        // Not ours: ignored.
        assert_eq!(rig.send(0x7ED, &[0x09, 0x4D, 0x34, 0x12, 0x00, 0x00, 0x00, 0x00]), Tx::new());
        assert_eq!(rig.node.mac_id(), MacId::new(5).unwrap());
        let request = [0x09, 0x4D, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12];
        // The duplicate MAC ID request at MAC 9: 0x400 | 9 << 3 | 7.
        let check = tx(0x44F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]);
        assert_eq!(rig.send(0x7ED, &request), check);
        assert_eq!(rig.events(), std::vec![Event::MacIdChanged(MacId::new(9).unwrap())]);
        assert_eq!(rig.advance(Duration::from_secs(1)), check);
        rig.advance(Duration::from_secs(1));
        assert_eq!(rig.node.network_state(), NetworkState::Online);
        assert_eq!(rig.events(), std::vec![Event::Online]);
        // On-line at 9: answers an allocation there; DeviceNet attribute 1 reads 9.
        assert_eq!(rig.send(0x44E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]), tx(0x44B, &[0x00, 0xCB, 0x00]));
        assert_eq!(rig.send(0x44C, &[0x00, 0x0E, 0x03, 0x01, 0x01]), tx(0x44B, &[0x00, 0x8E, 0x09]));
        // An on-line node ignores Group 4.
        assert_eq!(rig.send(0x7ED, &[0x3F, 0x4B, 0x00]), Tx::new());
        assert_eq!(rig.advance(Duration::from_millis(100)), Tx::new());
    }

    #[test]
    fn bus_off_faulted_node_ignores_group_4() {
        let mut rig = Rig::online();
        rig.node.handle_bus_off(rig.now);
        assert_eq!(rig.node.network_state(), NetworkState::CommunicationFaulted(FaultReason::BusOff));
        rig.send(0x7ED, &[0x3F, 0x4B, 0x00]);
        assert_eq!(rig.advance(Duration::from_millis(100)), Tx::new());
    }
}
