//! The Group 4 Offline Connection Set (protocol §3.8, §II.6): finding a node in the
//! Communication Faulted state, having it identify itself and giving it a new MAC ID (protocol §7.4).
//!
//! The messages vary in length and share one identifier per direction, so [`OfflineMessage`] is
//! decoded from the Group 4 message ID together with the whole CAN data field, and emitted into a
//! caller's buffer.

use super::{exact, mac_byte, service, DeviceKey, MessageError};
use crate::id::{Group4MessageId, MacId};

/// The first byte of the Communication Faulted request/response messages (protocol §3.8):
/// `[reserved(7) | match(6) | value(5–0)]`. What "match" and "value" select is UNCONFIRMED (notes
/// §9 item 11); the ICP example sends `3F` (match 0, value 63).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultedSelector {
    /// The match bit (bit 6).
    pub match_flag: bool,
    /// The 6-bit value, `0..=63`; `emit` keeps the low 6 bits.
    pub value: u8,
}

impl FaultedSelector {
    /// Decodes the byte; the reserved bit 7 must be zero.
    pub const fn from_byte(b: u8) -> Result<FaultedSelector, MessageError> {
        if b & 0x80 != 0 {
            Err(MessageError::ReservedBitsSet)
        } else {
            Ok(FaultedSelector { match_flag: b & 0x40 != 0, value: b & 0x3F })
        }
    }

    /// Encodes the byte.
    pub const fn to_byte(self) -> u8 {
        (self.match_flag as u8) << 6 | (self.value & 0x3F)
    }
}

/// Who (Communication Faulted request) service byte.
const WHO: u8 = 0x4B;
/// Identify (Communication Faulted request) service byte; the response is `0xCC`.
const IDENTIFY: u8 = 0x4C;
/// Change MAC ID service byte.
const CHANGE_MAC_ID: u8 = 0x4D;
/// Offline ownership request service byte; the response is `0xCB`.
const OWNERSHIP: u8 = 0x4B;

/// A message of the Group 4 Offline Connection Set (protocol §3.8), decoded from its Group 4 message
/// ID and data. Used to find and recover a node in the Communication Faulted state (protocol §7.4).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OfflineMessage {
    /// 0x7ED, `[selector] 4B <time-delay byte offset>`: asks faulted nodes to identify themselves.
    WhoRequest {
        /// Which faulted nodes should answer.
        selector: FaultedSelector,
        /// The byte offset (0–6, UNCONFIRMED) that sets each responder's time delay; kept as sent.
        time_delay_offset: u8,
    },
    /// 0x7EC, `<port> <vendor LE16> <serial LE32>`: a faulted node answers Who.
    WhoResponse {
        /// The port byte, kept whole.
        port: u8,
        /// The faulted node's identity.
        device: DeviceKey,
    },
    /// 0x7ED, `[selector] 4C` or `[selector] 4C <vendor LE16> <serial LE32>`: asks a node to
    /// identify itself (e.g. by its LEDs).
    IdentifyRequest {
        /// Which faulted nodes are addressed.
        selector: FaultedSelector,
        /// The addressed node's identity, in the 8-byte form.
        device: Option<DeviceKey>,
    },
    /// 0x7EC, `[selector] CC`: the answer to Identify.
    IdentifyResponse {
        /// Echoed selector.
        selector: FaultedSelector,
    },
    /// 0x7ED, `<new MAC> 4D <vendor LE16> <serial LE32>`: gives the identified node a new MAC ID,
    /// after which it re-runs the duplicate MAC ID check.
    ChangeMacIdRequest {
        /// The MAC ID to take.
        new_mac: MacId,
        /// The addressed node's identity.
        device: DeviceKey,
    },
    /// 0x7EF, `<client MAC> 4B <vendor LE16> <serial LE32>`: a tool asks to own the offline set.
    OwnershipRequest {
        /// The requesting tool's MAC ID.
        client: MacId,
        /// The node whose offline set is requested.
        device: DeviceKey,
    },
    /// 0x7EE, `<client MAC> CB <vendor LE16> <serial LE32>`: ownership granted.
    OwnershipResponse {
        /// The owning tool's MAC ID.
        client: MacId,
        /// The responding node's identity.
        device: DeviceKey,
    },
}

impl OfflineMessage {
    /// The longest layout, in bytes.
    pub const MAX_LEN: usize = 8;

    /// Decodes `data` received with Group 4 message ID `message`.
    pub fn parse(message: Group4MessageId, data: &[u8]) -> Result<OfflineMessage, MessageError> {
        match message {
            Group4MessageId::COMM_FAULTED_REQUEST => Self::parse_request(data),
            Group4MessageId::COMM_FAULTED_RESPONSE => Self::parse_response(data),
            Group4MessageId::OFFLINE_OWNERSHIP_REQUEST => {
                let (client, device) = Self::parse_ownership(OWNERSHIP, data)?;
                Ok(OfflineMessage::OwnershipRequest { client, device })
            }
            Group4MessageId::OFFLINE_OWNERSHIP_RESPONSE => {
                let (client, device) = Self::parse_ownership(OWNERSHIP | 0x80, data)?;
                Ok(OfflineMessage::OwnershipResponse { client, device })
            }
            other => Err(MessageError::NotOfflineMessage(other.as_raw())),
        }
    }

    /// Communication Faulted request (0x7ED): the service byte selects the layout.
    fn parse_request(data: &[u8]) -> Result<OfflineMessage, MessageError> {
        let svc = match data {
            [_, svc, ..] => *svc,
            _ => return Err(MessageError::Truncated { needed: 2, got: data.len() }),
        };
        match svc {
            WHO => {
                let [sel, _, time_delay_offset] = exact::<3>(data)?;
                Ok(OfflineMessage::WhoRequest {
                    selector: FaultedSelector::from_byte(sel)?,
                    time_delay_offset,
                })
            }
            IDENTIFY => match *data {
                [sel, _] => Ok(OfflineMessage::IdentifyRequest {
                    selector: FaultedSelector::from_byte(sel)?,
                    device: None,
                }),
                [sel, _, k0, k1, k2, k3, k4, k5] => Ok(OfflineMessage::IdentifyRequest {
                    selector: FaultedSelector::from_byte(sel)?,
                    device: Some(DeviceKey::from_bytes([k0, k1, k2, k3, k4, k5])),
                }),
                _ => Err(MessageError::WrongLength { expected: 8, got: data.len() }),
            },
            CHANGE_MAC_ID => {
                let [mac, _, k0, k1, k2, k3, k4, k5] = exact::<8>(data)?;
                Ok(OfflineMessage::ChangeMacIdRequest {
                    new_mac: mac_byte(mac)?,
                    device: DeviceKey::from_bytes([k0, k1, k2, k3, k4, k5]),
                })
            }
            other => Err(MessageError::UnknownService(other)),
        }
    }

    /// Communication Faulted response (0x7EC): the length selects the layout.
    fn parse_response(data: &[u8]) -> Result<OfflineMessage, MessageError> {
        match *data {
            [port, k0, k1, k2, k3, k4, k5] => Ok(OfflineMessage::WhoResponse {
                port,
                device: DeviceKey::from_bytes([k0, k1, k2, k3, k4, k5]),
            }),
            [sel, svc] => {
                service(IDENTIFY | 0x80, svc)?;
                Ok(OfflineMessage::IdentifyResponse { selector: FaultedSelector::from_byte(sel)? })
            }
            _ => Err(MessageError::WrongLength { expected: 7, got: data.len() }),
        }
    }

    /// Offline ownership request/response: `<client MAC> <svc> <vendor> <serial>`.
    fn parse_ownership(expected: u8, data: &[u8]) -> Result<(MacId, DeviceKey), MessageError> {
        let [client, svc, k0, k1, k2, k3, k4, k5] = exact::<8>(data)?;
        service(expected, svc)?;
        Ok((mac_byte(client)?, DeviceKey::from_bytes([k0, k1, k2, k3, k4, k5])))
    }

    /// The Group 4 message ID the message travels on.
    pub const fn message_id(&self) -> Group4MessageId {
        match self {
            OfflineMessage::WhoRequest { .. }
            | OfflineMessage::IdentifyRequest { .. }
            | OfflineMessage::ChangeMacIdRequest { .. } => Group4MessageId::COMM_FAULTED_REQUEST,
            OfflineMessage::WhoResponse { .. } | OfflineMessage::IdentifyResponse { .. } => {
                Group4MessageId::COMM_FAULTED_RESPONSE
            }
            OfflineMessage::OwnershipRequest { .. } => Group4MessageId::OFFLINE_OWNERSHIP_REQUEST,
            OfflineMessage::OwnershipResponse { .. } => Group4MessageId::OFFLINE_OWNERSHIP_RESPONSE,
        }
    }

    /// The data bytes, left-aligned, and their count.
    fn encode(&self) -> ([u8; 8], usize) {
        let mut b = [0u8; 8];
        let len = match *self {
            OfflineMessage::WhoRequest { selector, time_delay_offset } => {
                b[..3].copy_from_slice(&[selector.to_byte(), WHO, time_delay_offset]);
                3
            }
            OfflineMessage::WhoResponse { port, device } => {
                b[0] = port;
                b[1..7].copy_from_slice(&device.to_bytes());
                7
            }
            OfflineMessage::IdentifyRequest { selector, device } => {
                b[..2].copy_from_slice(&[selector.to_byte(), IDENTIFY]);
                match device {
                    Some(device) => {
                        b[2..8].copy_from_slice(&device.to_bytes());
                        8
                    }
                    None => 2,
                }
            }
            OfflineMessage::IdentifyResponse { selector } => {
                b[..2].copy_from_slice(&[selector.to_byte(), IDENTIFY | 0x80]);
                2
            }
            OfflineMessage::ChangeMacIdRequest { new_mac, device } => {
                b[..2].copy_from_slice(&[new_mac.as_raw(), CHANGE_MAC_ID]);
                b[2..8].copy_from_slice(&device.to_bytes());
                8
            }
            OfflineMessage::OwnershipRequest { client, device } => {
                b[..2].copy_from_slice(&[client.as_raw(), OWNERSHIP]);
                b[2..8].copy_from_slice(&device.to_bytes());
                8
            }
            OfflineMessage::OwnershipResponse { client, device } => {
                b[..2].copy_from_slice(&[client.as_raw(), OWNERSHIP | 0x80]);
                b[2..8].copy_from_slice(&device.to_bytes());
                8
            }
        };
        (b, len)
    }

    /// Bytes [`OfflineMessage::emit`] writes.
    pub fn buffer_len(&self) -> usize {
        self.encode().1
    }

    /// Writes the data into `buf`, returning its length.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, MessageError> {
        let (bytes, len) = self.encode();
        match (buf.get_mut(..len), bytes.get(..len)) {
            (Some(out), Some(src)) => {
                out.copy_from_slice(src);
                Ok(len)
            }
            _ => Err(MessageError::BufferTooSmall { needed: len, got: buf.len() }),
        }
    }
}

impl TryFrom<(Group4MessageId, &[u8])> for OfflineMessage {
    type Error = MessageError;

    fn try_from((message, data): (Group4MessageId, &[u8])) -> Result<OfflineMessage, MessageError> {
        OfflineMessage::parse(message, data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::messages::testing::{any_key, any_mac, group4, mac, SLAVE};
    use proptest::prelude::*;
    use rstest::rstest;

    const SEL_3F: FaultedSelector = FaultedSelector { match_flag: false, value: 63 };

    #[rstest]
    #[case::icp_who_request(0x7ED, &[0x3F, 0x4B, 0x02], OfflineMessage::WhoRequest { selector: SEL_3F, time_delay_offset: 2 })]
    #[case::icp_who_response(0x7EC, &[0x00, 0x23, 0x03, 0x01, 0x00, 0x00, 0x00], OfflineMessage::WhoResponse { port: 0, device: DeviceKey { vendor_id: 0x0323, serial_number: 1 } })]
    #[case::who_request_match(0x7ED, &[0x45, 0x4B, 0x00], OfflineMessage::WhoRequest { selector: FaultedSelector { match_flag: true, value: 5 }, time_delay_offset: 0 })]
    #[case::identify_short(0x7ED, &[0x3F, 0x4C], OfflineMessage::IdentifyRequest { selector: SEL_3F, device: None })]
    #[case::identify_device(0x7ED, &[0x3F, 0x4C, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], OfflineMessage::IdentifyRequest { selector: SEL_3F, device: Some(SLAVE) })]
    #[case::identify_response(0x7EC, &[0x3F, 0xCC], OfflineMessage::IdentifyResponse { selector: SEL_3F })]
    #[case::change_mac_to_6(0x7ED, &[0x06, 0x4D, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], OfflineMessage::ChangeMacIdRequest { new_mac: mac(6), device: SLAVE })]
    #[case::ownership_request(0x7EF, &[0x00, 0x4B, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], OfflineMessage::OwnershipRequest { client: mac(0), device: SLAVE })]
    #[case::ownership_response(0x7EE, &[0x00, 0xCB, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], OfflineMessage::OwnershipResponse { client: mac(0), device: SLAVE })]
    fn offline_codec(#[case] id: u16, #[case] bytes: &[u8], #[case] msg: OfflineMessage) {
        let message = group4(id);
        assert_eq!(OfflineMessage::parse(message, bytes), Ok(msg));
        assert_eq!(OfflineMessage::try_from((message, bytes)), Ok(msg));
        assert_eq!(msg.message_id(), message);
        let mut buf = [0u8; 8];
        let n = msg.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], bytes);
        assert_eq!(msg.buffer_len(), n);
    }

    #[rstest]
    #[case::reserved_group4(0x7C0, &[0x3F, 0x4B, 0x02], MessageError::NotOfflineMessage(0x00))]
    #[case::reserved_group4_2b(0x7EB, &[], MessageError::NotOfflineMessage(0x2B))]
    #[case::request_no_service(0x7ED, &[0x3F], MessageError::Truncated { needed: 2, got: 1 })]
    #[case::request_empty(0x7ED, &[], MessageError::Truncated { needed: 2, got: 0 })]
    #[case::request_unknown_service(0x7ED, &[0x3F, 0x4E], MessageError::UnknownService(0x4E))]
    #[case::request_response_service(0x7ED, &[0x3F, 0xCC], MessageError::UnknownService(0xCC))]
    #[case::who_reserved_bit(0x7ED, &[0xBF, 0x4B, 0x02], MessageError::ReservedBitsSet)]
    #[case::who_too_long(0x7ED, &[0x3F, 0x4B, 0x02, 0x00], MessageError::WrongLength { expected: 3, got: 4 })]
    #[case::identify_odd_length(0x7ED, &[0x3F, 0x4C, 0x34, 0x12], MessageError::WrongLength { expected: 8, got: 4 })]
    #[case::change_mac_out_of_range(0x7ED, &[0x40, 0x4D, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], MessageError::ReservedBitsSet)]
    #[case::change_mac_short(0x7ED, &[0x06, 0x4D, 0x34, 0x12], MessageError::WrongLength { expected: 8, got: 4 })]
    #[case::response_wrong_length(0x7EC, &[0x00, 0x23, 0x03], MessageError::WrongLength { expected: 7, got: 3 })]
    #[case::identify_response_service(0x7EC, &[0x3F, 0x4C], MessageError::UnexpectedService { expected: 0xCC, got: 0x4C })]
    #[case::identify_response_reserved(0x7EC, &[0xBF, 0xCC], MessageError::ReservedBitsSet)]
    #[case::ownership_request_as_response(0x7EE, &[0x00, 0x4B, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], MessageError::UnexpectedService { expected: 0xCB, got: 0x4B })]
    #[case::ownership_client_reserved(0x7EF, &[0xC0, 0x4B, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], MessageError::ReservedBitsSet)]
    #[case::ownership_short(0x7EF, &[0x00, 0x4B], MessageError::WrongLength { expected: 8, got: 2 })]
    fn offline_errors(#[case] id: u16, #[case] bytes: &[u8], #[case] err: MessageError) {
        assert_eq!(OfflineMessage::parse(group4(id), bytes), Err(err));
    }

    #[test]
    fn offline_emit_checks_buffer() {
        let msg = OfflineMessage::WhoResponse { port: 0, device: SLAVE };
        assert_eq!(msg.emit(&mut [0u8; 6]), Err(MessageError::BufferTooSmall { needed: 7, got: 6 }));
        assert_eq!(msg.emit(&mut [0u8; 7]), Ok(7));
    }

    fn any_selector() -> impl Strategy<Value = FaultedSelector> {
        (any::<bool>(), 0u8..=63).prop_map(|(match_flag, value)| FaultedSelector { match_flag, value })
    }

    fn any_offline() -> impl Strategy<Value = OfflineMessage> {
        prop_oneof![
            (any_selector(), any::<u8>()).prop_map(|(selector, time_delay_offset)| {
                OfflineMessage::WhoRequest { selector, time_delay_offset }
            }),
            (any::<u8>(), any_key()).prop_map(|(port, device)| OfflineMessage::WhoResponse { port, device }),
            (any_selector(), proptest::option::of(any_key()))
                .prop_map(|(selector, device)| OfflineMessage::IdentifyRequest { selector, device }),
            any_selector().prop_map(|selector| OfflineMessage::IdentifyResponse { selector }),
            (any_mac(), any_key())
                .prop_map(|(new_mac, device)| OfflineMessage::ChangeMacIdRequest { new_mac, device }),
            (any_mac(), any_key())
                .prop_map(|(client, device)| OfflineMessage::OwnershipRequest { client, device }),
            (any_mac(), any_key())
                .prop_map(|(client, device)| OfflineMessage::OwnershipResponse { client, device }),
        ]
    }

    proptest! {
        #[test]
        fn offline_messages_round_trip(msg in any_offline()) {
            let mut buf = [0u8; OfflineMessage::MAX_LEN];
            let n = msg.emit(&mut buf).unwrap();
            prop_assert_eq!(OfflineMessage::parse(msg.message_id(), &buf[..n]), Ok(msg));
        }
    }
}
