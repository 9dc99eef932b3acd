//! CAN acceptance filtering: only this node's Group 2 traffic reaches the core (notes §8).
//!
//! A group-2-only slave consumes four identifiers, all carrying **its own** MAC ID in the Group 2
//! MAC field: the master's explicit request (message 4), the poll command (5), the Group 2 Only
//! Unconnected Explicit Request port (6) and the duplicate MAC ID check (7). Another node's
//! duplicate MAC check for our MAC uses our MAC in the identifier, so the same list catches it.
//! Group 1 and Group 3 (UCMM) frames never reach the core; neither do other nodes' Group 2 frames.
//!
//! For MAC 5 the list is 0x42C, 0x42D, 0x42E, 0x42F. On the bxCAN the four identifiers fill one
//! filter bank in 16-bit list mode, routed to FIFO 0 so that frames keep their bus order; the
//! emulated board applies [`accepts`] in software to the SLCAN frames it receives.

use devicenet::MacId;

/// Group 2 message IDs the slave consumes: explicit request, poll command, Group 2 Only
/// unconnected explicit request, duplicate MAC ID check (notes §1.2).
pub const CONSUMED_GROUP2_MESSAGES: [u8; 4] = [4, 5, 6, 7];

/// The filter bank holding the list.
pub const FILTER_BANK: u8 = 0;

/// The 11-bit identifiers the node with `mac` accepts: `0x400 | mac << 3 | message`.
pub const fn acceptance_list(mac: MacId) -> [u16; 4] {
    let base = 0x400 | ((mac.as_raw() as u16) << 3);
    [
        base | CONSUMED_GROUP2_MESSAGES[0] as u16,
        base | CONSUMED_GROUP2_MESSAGES[1] as u16,
        base | CONSUMED_GROUP2_MESSAGES[2] as u16,
        base | CONSUMED_GROUP2_MESSAGES[3] as u16,
    ]
}

/// Whether a standard identifier passes the node's acceptance filter (what the bxCAN bank does
/// in hardware).
pub const fn accepts(mac: MacId, id: u16) -> bool {
    let list = acceptance_list(mac);
    id == list[0] || id == list[1] || id == list[2] || id == list[3]
}

#[cfg(test)]
mod tests {
    use super::*;
    use devicenet::{CanId, Group2Message, Identifier};
    use rstest::rstest;

    #[test]
    fn mac_5_list_of_notes_8() {
        assert_eq!(acceptance_list(MacId::new(5).unwrap()), [0x42C, 0x42D, 0x42E, 0x42F]);
    }

    #[rstest]
    #[case::mac0(0)]
    #[case::mac5(5)]
    #[case::mac42(42)]
    #[case::mac63(63)]
    fn filter_is_exactly_own_group2_consumed(#[case] mac: u8) {
        let mac = MacId::new(mac).unwrap();
        let mut accepted = 0;
        for raw in 0..=0x7FFu16 {
            let wanted = matches!(
                Identifier::decode(CanId::new(raw).unwrap()),
                Identifier::Group2 {
                    mac: m,
                    message: Group2Message::ExplicitRequest
                        | Group2Message::PollCommand
                        | Group2Message::UnconnectedExplicitRequest
                        | Group2Message::DuplicateMacCheck
                } if m == mac
            );
            assert_eq!(accepts(mac, raw), wanted, "identifier {raw:03X}");
            accepted += usize::from(wanted);
        }
        assert_eq!(accepted, 4);
    }

    #[rstest]
    #[case::other_nodes_dup_check_for_our_mac(0x42F, true)]
    #[case::our_own_explicit_response(0x42B, false)]
    #[case::our_poll_response_group1(0x3C5, false)]
    #[case::ucmm_request_group3(0x780, false)]
    #[case::another_slaves_poll(0x435, false)]
    #[case::offline_connection_set_group4(0x7EF, false)]
    fn examples(#[case] id: u16, #[case] accepted: bool) {
        assert_eq!(accepts(MacId::new(5).unwrap(), id), accepted);
    }
}
