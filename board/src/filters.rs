//! CAN acceptance filtering: only the frames a group-2-only slave consumes reach the core
//! (protocol §8, docs/src/reference/io-connections.md).
//!
//! - Every Group 2 message carrying **its own** MAC ID in the MAC field (`0x400 | mac << 3 |
//!   message`): the COS/cyclic acknowledge (message 2), the explicit request (4), the poll command
//!   or the master's COS/cyclic data (5), the Group 2 Only port (6) and the duplicate MAC ID check
//!   (7; another node's check for our MAC carries our MAC too). Messages 0, 1 and 3 with our MAC
//!   pass as well (one mask covers the eight); the core ignores them.
//! - Every bit-strobe command (Group 2 message 0): it carries the **master's** MAC, which is not
//!   known before allocation (§II.1.2); the core keeps the owner's.
//! - The Offline Connection Set's requests, 0x7ED and 0x7EF (§II.6), for a faulted node.
//!
//! Group 1, Group 3 (UCMM), other nodes' Group 2 traffic and Group 4 responses never reach the
//! core. For MAC 5: 0x428-0x42F, 0x400 | n << 3 for every n, 0x7ED, 0x7EF. On the bxCAN, filter
//! bank 0 holds the two Group 2 masks and bank 1 the Group 4 mask (the two requests differ in one
//! bit, [`OFFLINE_MASK`]), all in 16-bit mask mode and routed to FIFO 0 so that frames keep their
//! bus order; a MAC ID taken through the Offline Connection Set rewrites bank 0. The emulated board applies [`accepts`] in software
//! to the SLCAN frames it receives.

use devicenet::MacId;

/// The filter bank holding the two Group 2 masks.
pub const FILTER_BANK: u8 = 0;
/// The filter bank holding the Group 4 list.
pub const OFFLINE_FILTER_BANK: u8 = 1;

/// The mask of a Group 2 identifier's group and MAC bits: every message of one MAC.
pub const OWN_MASK: u16 = if cfg!(feature = "fault-filter") { NOTHING } else { 0x7F8 };
/// The mask of a Group 2 identifier's group and message bits: one message of every MAC.
pub const STROBE_MASK: u16 = if cfg!(feature = "fault-filter") { NOTHING } else { 0x607 };
/// The bit-strobe command of any master (Group 2 message 0).
pub const STROBE_ID: u16 = if cfg!(feature = "fault-filter") { NOTHING } else { 0x400 };
/// The self-test's `fault-filter` identifier and mask of the Group 2 bank: 0x7FF exactly, which
/// CAN 2.0A forbids (the seven most significant bits recessive), so the bank matches nothing (the
/// Offline Connection Set's bank is left as it is).
const NOTHING: u16 = 0x7FF;
/// The Offline Connection Set's request identifiers: Communication Faulted request and offline
/// ownership request (protocol §1.4).
pub const OFFLINE_REQUESTS: [u16; 2] = [0x7ED, 0x7EF];
/// The mask of every bit but the one in which the two [`OFFLINE_REQUESTS`] differ: with the first
/// of them it passes both and nothing else.
pub const OFFLINE_MASK: u16 = 0x7FF & !(OFFLINE_REQUESTS[0] ^ OFFLINE_REQUESTS[1]);

/// The identifier of Group 2 message 0 for `mac`; with [`OWN_MASK`], all its Group 2 messages.
pub const fn own_group2(mac: MacId) -> u16 {
    if cfg!(feature = "fault-filter") {
        return NOTHING;
    }
    0x400 | ((mac.as_raw() as u16) << 3)
}

/// Whether a standard identifier passes the node's acceptance filter (what the bxCAN banks do
/// in hardware).
pub const fn accepts(mac: MacId, id: u16) -> bool {
    id & OWN_MASK == own_group2(mac)
        || id & STROBE_MASK == STROBE_ID
        || id & OFFLINE_MASK == OFFLINE_REQUESTS[0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use devicenet::id::Group4MessageId;
    use devicenet::{CanId, Group2Message, Identifier};
    use rstest::rstest;

    #[test]
    fn offline_mask_passes_both_requests() {
        assert_eq!(OFFLINE_MASK, 0x7FD);
        assert!(OFFLINE_REQUESTS.iter().all(|id| id & OFFLINE_MASK == OFFLINE_REQUESTS[0]));
    }

    #[test]
    fn mac_5_own_identifiers() {
        assert_eq!(own_group2(MacId::new(5).unwrap()), 0x428);
    }

    #[rstest]
    #[case::mac0(0)]
    #[case::mac5(5)]
    #[case::mac42(42)]
    #[case::mac63(63)]
    fn filter_is_exactly_what_the_node_consumes(#[case] mac: u8) {
        let mac = MacId::new(mac).unwrap();
        let mut accepted = 0;
        for raw in 0..=0x7FFu16 {
            let wanted = match Identifier::decode(CanId::new(raw).unwrap()) {
                Identifier::Group2 { message: Group2Message::BitStrobeCommand, .. } => true,
                Identifier::Group2 { mac: m, .. } => m == mac,
                Identifier::Group4 { message } => {
                    message == Group4MessageId::COMM_FAULTED_REQUEST
                        || message == Group4MessageId::OFFLINE_OWNERSHIP_REQUEST
                }
                _ => false,
            };
            assert_eq!(accepts(mac, raw), wanted, "identifier {raw:03X}");
            accepted += usize::from(wanted);
        }
        // Eight messages of our MAC, the other 63 masters' strobes, two Group 4 requests.
        assert_eq!(accepted, 8 + 63 + 2);
    }

    #[rstest]
    #[case::other_nodes_dup_check_for_our_mac(0x42F, true)]
    #[case::our_own_explicit_response_passes_the_mask(0x42B, true)]
    #[case::our_poll_response_group1(0x3C5, false)]
    #[case::ucmm_request_group3(0x780, false)]
    #[case::another_slaves_poll(0x435, false)]
    #[case::offline_ownership_request(0x7EF, true)]
    #[case::who_request(0x7ED, true)]
    #[case::who_response(0x7EC, false)]
    #[case::cos_ack(0x42A, true)]
    #[case::strobe_from_master_0(0x400, true)]
    #[case::strobe_from_master_62(0x5F0, true)]
    #[case::another_slaves_cos_ack(0x432, false)]
    fn examples(#[case] id: u16, #[case] accepted: bool) {
        assert_eq!(accepts(MacId::new(5).unwrap(), id), accepted);
    }
}
