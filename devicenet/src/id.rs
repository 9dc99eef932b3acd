//! The DeviceNet identifier codec: MAC IDs, the four message groups and their message IDs
//! (protocol §1).
//!
//! [`Identifier`] decodes every 11-bit CAN identifier into its message group and fields, and
//! encodes it back; every value decodes (0x7F0–0x7FF as [`Identifier::Invalid`]), so decoding
//! cannot fail and never loses information.

use crate::frame::CanId;
use core::fmt;

/// A DeviceNet node address, `0..=63`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct MacId(u8);

impl MacId {
    /// The highest MAC ID, 63 (the default of an unconfigured node).
    pub const MAX: MacId = MacId(63);

    /// `Some` when `raw` is `0..=63`.
    pub const fn new(raw: u8) -> Option<MacId> {
        if raw <= 63 {
            Some(MacId(raw))
        } else {
            None
        }
    }

    /// The low six bits of `raw`, as carried in identifiers and explicit headers.
    pub const fn from_low_bits(raw: u8) -> MacId {
        MacId(raw & 0x3F)
    }

    /// The MAC ID as a number.
    pub const fn as_raw(self) -> u8 {
        self.0
    }
}

impl fmt::Display for MacId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for MacId {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "{=u8}", self.0)
    }
}

/// A Group 1 message ID, `0..=15` (bits 9–6 of the identifier).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Group1MessageId(u8);

impl Group1MessageId {
    /// Slave's multicast-poll response (protocol §1.3).
    pub const MULTICAST_POLL_RESPONSE: Group1MessageId = Group1MessageId(12);
    /// Slave's change-of-state / cyclic message.
    pub const COS_CYCLIC: Group1MessageId = Group1MessageId(13);
    /// Slave's bit-strobe response.
    pub const BIT_STROBE_RESPONSE: Group1MessageId = Group1MessageId(14);
    /// Slave's poll response, or its acknowledgement of the master's COS/cyclic data.
    pub const POLL_RESPONSE: Group1MessageId = Group1MessageId(15);

    /// `Some` when `raw` is `0..=15`.
    pub const fn new(raw: u8) -> Option<Self> {
        if raw <= 15 {
            Some(Group1MessageId(raw))
        } else {
            None
        }
    }

    /// The message ID as a number.
    pub const fn as_raw(self) -> u8 {
        self.0
    }
}

/// The eight Group 2 message IDs of the Predefined Master/Slave Connection Set (protocol §1.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Group2Message {
    /// 0: master's bit-strobe command; the MAC field is the master's (source).
    BitStrobeCommand = 0,
    /// 1: master's multicast poll command.
    MulticastPollCommand = 1,
    /// 2: master's change-of-state / cyclic acknowledge; destination MAC.
    CosCyclicAck = 2,
    /// 3: slave's explicit / unconnected response; source MAC.
    ExplicitResponse = 3,
    /// 4: master's explicit request; destination MAC.
    ExplicitRequest = 4,
    /// 5: master's I/O poll command (or COS/cyclic data); destination MAC.
    PollCommand = 5,
    /// 6: Group 2 Only Unconnected Explicit Request (Allocate/Release only); destination MAC.
    UnconnectedExplicitRequest = 6,
    /// 7: duplicate MAC ID check request/response; the MAC being checked.
    DuplicateMacCheck = 7,
}

impl Group2Message {
    /// The message for a 3-bit message ID.
    pub const fn from_bits(bits: u8) -> Group2Message {
        match bits & 7 {
            0 => Group2Message::BitStrobeCommand,
            1 => Group2Message::MulticastPollCommand,
            2 => Group2Message::CosCyclicAck,
            3 => Group2Message::ExplicitResponse,
            4 => Group2Message::ExplicitRequest,
            5 => Group2Message::PollCommand,
            6 => Group2Message::UnconnectedExplicitRequest,
            _ => Group2Message::DuplicateMacCheck,
        }
    }
}

/// A Group 3 message ID, `0..=6` (7 would fall into Group 4 space).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Group3MessageId(u8);

impl Group3MessageId {
    /// Unconnected (UCMM) response.
    pub const UNCONNECTED_RESPONSE: Group3MessageId = Group3MessageId(5);
    /// Unconnected (UCMM) request.
    pub const UNCONNECTED_REQUEST: Group3MessageId = Group3MessageId(6);

    /// `Some` when `raw` is `0..=6`.
    pub const fn new(raw: u8) -> Option<Self> {
        if raw <= 6 {
            Some(Group3MessageId(raw))
        } else {
            None
        }
    }

    /// The message ID as a number.
    pub const fn as_raw(self) -> u8 {
        self.0
    }
}

/// A Group 4 message ID, `0x00..=0x2F` (protocol §1.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Group4MessageId(u8);

impl Group4MessageId {
    /// Communication-Faulted response (0x7EC).
    pub const COMM_FAULTED_RESPONSE: Group4MessageId = Group4MessageId(0x2C);
    /// Communication-Faulted request (0x7ED).
    pub const COMM_FAULTED_REQUEST: Group4MessageId = Group4MessageId(0x2D);
    /// Offline-Ownership response (0x7EE).
    pub const OFFLINE_OWNERSHIP_RESPONSE: Group4MessageId = Group4MessageId(0x2E);
    /// Offline-Ownership request (0x7EF).
    pub const OFFLINE_OWNERSHIP_REQUEST: Group4MessageId = Group4MessageId(0x2F);

    /// `Some` when `raw` is `0x00..=0x2F`.
    pub const fn new(raw: u8) -> Option<Self> {
        if raw <= 0x2F {
            Some(Group4MessageId(raw))
        } else {
            None
        }
    }

    /// The message ID as a number.
    pub const fn as_raw(self) -> u8 {
        self.0
    }
}

/// A decoded 11-bit identifier (protocol §1.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Identifier {
    /// `0 mmmm ssssss`: message ID and **source** MAC.
    Group1 {
        /// Message ID 0–15.
        message: Group1MessageId,
        /// The producing node.
        source: MacId,
    },
    /// `1 0 aaaaaa mmm`: MAC (source or destination, by message) and message.
    Group2 {
        /// Source or destination MAC, depending on the message.
        mac: MacId,
        /// The Group 2 message.
        message: Group2Message,
    },
    /// `1 1 mmm ssssss`: message ID 0–6 and **source** MAC.
    Group3 {
        /// Message ID 0–6.
        message: Group3MessageId,
        /// The sending node.
        source: MacId,
    },
    /// `1 1 1 1 1 mmmmmm`: message ID 0x00–0x2F, no MAC.
    Group4 {
        /// Message ID 0x00–0x2F.
        message: Group4MessageId,
    },
    /// 0x7F0–0x7FF: must not be used.
    Invalid(u16),
}

impl Identifier {
    /// Decodes any 11-bit identifier.
    pub const fn decode(id: CanId) -> Identifier {
        let raw = id.as_raw();
        if raw < 0x400 {
            Identifier::Group1 {
                message: Group1MessageId(((raw >> 6) & 0xF) as u8),
                source: MacId((raw & 0x3F) as u8),
            }
        } else if raw < 0x600 {
            Identifier::Group2 {
                mac: MacId(((raw >> 3) & 0x3F) as u8),
                message: Group2Message::from_bits((raw & 7) as u8),
            }
        } else if raw < 0x7C0 {
            Identifier::Group3 {
                message: Group3MessageId(((raw >> 6) & 7) as u8),
                source: MacId((raw & 0x3F) as u8),
            }
        } else if raw < 0x7F0 {
            Identifier::Group4 { message: Group4MessageId((raw & 0x3F) as u8) }
        } else {
            Identifier::Invalid(raw)
        }
    }

    /// Encodes back to the 11-bit identifier. An `Invalid` value keeps its raw number (masked to
    /// 11 bits).
    // Always inlined: its callers build one known variant (`group1`, `group2`), so the match folds
    // to a few instructions; out of line it costs some 130 bytes of the firmware's flash.
    #[inline(always)]
    pub const fn encode(self) -> CanId {
        let raw = match self {
            Identifier::Group1 { message, source } => ((message.0 as u16) << 6) | source.0 as u16,
            Identifier::Group2 { mac, message } => 0x400 | ((mac.0 as u16) << 3) | message as u16,
            Identifier::Group3 { message, source } => 0x600 | ((message.0 as u16) << 6) | source.0 as u16,
            Identifier::Group4 { message } => 0x7C0 | message.0 as u16,
            Identifier::Invalid(raw) => raw & 0x7FF,
        };
        CanId(raw)
    }

    /// The message group, 1–4, or `None` for the invalid range.
    pub const fn group(self) -> Option<u8> {
        match self {
            Identifier::Group1 { .. } => Some(1),
            Identifier::Group2 { .. } => Some(2),
            Identifier::Group3 { .. } => Some(3),
            Identifier::Group4 { .. } => Some(4),
            Identifier::Invalid(_) => None,
        }
    }

    /// A Group 2 identifier.
    pub const fn group2(mac: MacId, message: Group2Message) -> CanId {
        Identifier::Group2 { mac, message }.encode()
    }

    /// A Group 1 identifier.
    pub const fn group1(message: Group1MessageId, source: MacId) -> CanId {
        Identifier::Group1 { message, source }.encode()
    }
}

impl From<CanId> for Identifier {
    fn from(id: CanId) -> Identifier {
        Identifier::decode(id)
    }
}

impl From<Identifier> for CanId {
    fn from(id: Identifier) -> CanId {
        id.encode()
    }
}

impl fmt::Display for Identifier {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Identifier::Group1 { message, source } => {
                write!(f, "G1 msg {} from MAC {}", message.0, source)
            }
            Identifier::Group2 { mac, message } => write!(f, "G2 MAC {} {:?}", mac, message),
            Identifier::Group3 { message, source } => {
                write!(f, "G3 msg {} from MAC {}", message.0, source)
            }
            Identifier::Group4 { message } => write!(f, "G4 msg 0x{:02X}", message.0),
            Identifier::Invalid(raw) => write!(f, "invalid identifier 0x{raw:03X}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn mac(n: u8) -> MacId {
        MacId::new(n).unwrap()
    }

    #[rstest]
    #[case::master_dup_mac(0x407, Identifier::Group2 { mac: mac(0), message: Group2Message::DuplicateMacCheck })]
    #[case::slave_dup_mac(0x42F, Identifier::Group2 { mac: mac(5), message: Group2Message::DuplicateMacCheck })]
    #[case::explicit_response(0x42B, Identifier::Group2 { mac: mac(5), message: Group2Message::ExplicitResponse })]
    #[case::explicit_request(0x42C, Identifier::Group2 { mac: mac(5), message: Group2Message::ExplicitRequest })]
    #[case::poll_command(0x42D, Identifier::Group2 { mac: mac(5), message: Group2Message::PollCommand })]
    #[case::group2_only_port(0x42E, Identifier::Group2 { mac: mac(5), message: Group2Message::UnconnectedExplicitRequest })]
    #[case::bit_strobe(0x400, Identifier::Group2 { mac: mac(0), message: Group2Message::BitStrobeCommand })]
    #[case::poll_response(0x3C5, Identifier::Group1 { message: Group1MessageId::POLL_RESPONSE, source: mac(5) })]
    #[case::cos(0x345, Identifier::Group1 { message: Group1MessageId::COS_CYCLIC, source: mac(5) })]
    #[case::group1_lowest(0x000, Identifier::Group1 { message: Group1MessageId(0), source: mac(0) })]
    #[case::ucmm_request(0x780, Identifier::Group3 { message: Group3MessageId::UNCONNECTED_REQUEST, source: mac(0) })]
    #[case::ucmm_response(0x745, Identifier::Group3 { message: Group3MessageId::UNCONNECTED_RESPONSE, source: mac(5) })]
    #[case::comm_faulted_response(0x7EC, Identifier::Group4 { message: Group4MessageId::COMM_FAULTED_RESPONSE })]
    #[case::comm_faulted_request(0x7ED, Identifier::Group4 { message: Group4MessageId::COMM_FAULTED_REQUEST })]
    #[case::offline_ownership_request(0x7EF, Identifier::Group4 { message: Group4MessageId::OFFLINE_OWNERSHIP_REQUEST })]
    #[case::group4_lowest(0x7C0, Identifier::Group4 { message: Group4MessageId(0) })]
    #[case::invalid_lowest(0x7F0, Identifier::Invalid(0x7F0))]
    #[case::invalid_highest(0x7FF, Identifier::Invalid(0x7FF))]
    fn decode_and_encode(#[case] raw: u16, #[case] expected: Identifier) {
        let id = CanId::new(raw).unwrap();
        assert_eq!(Identifier::decode(id), expected);
        assert_eq!(expected.encode(), id);
    }

    #[test]
    fn every_identifier_round_trips() {
        for raw in 0..=0x7FFu16 {
            let id = CanId::new(raw).unwrap();
            assert_eq!(Identifier::decode(id).encode(), id, "0x{raw:03X}");
        }
    }

    #[rstest]
    #[case::zero(0, true)]
    #[case::max(63, true)]
    #[case::too_big(64, false)]
    #[case::broadcast_byte(255, false)]
    fn mac_range(#[case] raw: u8, #[case] ok: bool) {
        assert_eq!(MacId::new(raw).is_some(), ok);
    }

    #[test]
    fn message_id_ranges() {
        assert!(Group1MessageId::new(15).is_some());
        assert!(Group1MessageId::new(16).is_none());
        assert!(Group3MessageId::new(6).is_some());
        assert!(Group3MessageId::new(7).is_none());
        assert!(Group4MessageId::new(0x2F).is_some());
        assert!(Group4MessageId::new(0x30).is_none());
    }

    #[test]
    fn groups_and_arbitration_order() {
        // Group 1 wins over Group 2, inside Group 2 the MAC is more significant than the message.
        let poll_resp = Identifier::group1(Group1MessageId::POLL_RESPONSE, mac(63)).as_raw();
        let dup_mac_0 = Identifier::group2(mac(0), Group2Message::BitStrobeCommand).as_raw();
        assert!(poll_resp < dup_mac_0);
        let m4_msg7 = Identifier::group2(mac(4), Group2Message::DuplicateMacCheck).as_raw();
        let m5_msg0 = Identifier::group2(mac(5), Group2Message::BitStrobeCommand).as_raw();
        assert!(m4_msg7 < m5_msg0);
        assert_eq!(Identifier::decode(CanId::new(0x7F5).unwrap()).group(), None);
    }
}
