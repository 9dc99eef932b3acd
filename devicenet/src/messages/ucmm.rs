//! UCMM (Group 3) Open Explicit Messaging Connection and Close Connection, request and success
//! response (protocol §3.6). A group-2-only slave never answers them; the harness builds
//! frames 4–5 of the reference capture with them, and the decoder names them.
//!
//! Each layout is the whole CAN data field, header byte included; these messages are never
//! fragmented.

use super::{exact, fixed_length, service, unfragmented, MessageError};
use crate::explicit::{BodyFormat, Header};
use crate::id::MacId;

/// The UCMM Open Explicit Messaging Connection request service byte.
pub const UCMM_OPEN: u8 = 0x4B;
/// The UCMM Close Connection request service byte.
pub const UCMM_CLOSE: u8 = 0x4C;

/// The message group a UCMM open request asks the server to use (protocol §3.6), a 4-bit code that
/// keeps unknown values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GroupSelect {
    /// 0: Message Group 1.
    Group1,
    /// 1: Message Group 2.
    Group2,
    /// 3: Message Group 3.
    Group3,
    /// 0xF: reserved for node ping.
    NodePing,
    /// 2 and 4–14: reserved, kept as received.
    Reserved(u8),
}

impl GroupSelect {
    /// The group select for the low 4 bits of `nibble`.
    pub const fn from_nibble(nibble: u8) -> GroupSelect {
        match nibble & 0xF {
            0 => GroupSelect::Group1,
            1 => GroupSelect::Group2,
            3 => GroupSelect::Group3,
            0xF => GroupSelect::NodePing,
            other => GroupSelect::Reserved(other),
        }
    }

    /// The 4-bit code.
    pub const fn nibble(self) -> u8 {
        match self {
            GroupSelect::Group1 => 0,
            GroupSelect::Group2 => 1,
            GroupSelect::Group3 => 3,
            GroupSelect::NodePing => 0xF,
            GroupSelect::Reserved(n) => n & 0xF,
        }
    }
}

/// UCMM Open Explicit Messaging Connection request, the whole frame data (protocol §3.6), sent on
/// Group 3 message 6 from the client:
/// `[frag 0 | XID | dest MAC] 4B [reserved 4 | requested body format 4] [group select 4 | source message ID 4]`.
///
/// Frame 4 of the capture, `05 4B 00 34`: to MAC 5, body format 8/8, Group 3, source message ID 4.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UcmmOpenRequest {
    /// Transaction ID.
    pub xid: bool,
    /// The server being asked (header MAC).
    pub destination: MacId,
    /// The message body format the client asks for.
    pub body_format: BodyFormat,
    /// The message group the connection should use.
    pub group_select: GroupSelect,
    /// The client's source message ID, `0..=15` (0–4 for Group 3); `emit` keeps the low 4 bits.
    pub source_message_id: u8,
}

impl UcmmOpenRequest {
    /// Parses the 4 data bytes.
    pub fn parse(data: &[u8]) -> Result<UcmmOpenRequest, MessageError> {
        let [header, svc, format, select] = exact::<4>(data)?;
        let header = unfragmented(header)?;
        service(UCMM_OPEN, svc)?;
        if format & 0xF0 != 0 {
            return Err(MessageError::ReservedBitsSet);
        }
        Ok(UcmmOpenRequest {
            xid: header.xid,
            destination: header.mac,
            body_format: BodyFormat::from_code(format),
            group_select: GroupSelect::from_nibble(select >> 4),
            source_message_id: select & 0xF,
        })
    }

    /// The 4 data bytes.
    pub fn emit(&self) -> [u8; 4] {
        [
            Header::new(self.xid, self.destination).to_byte(),
            UCMM_OPEN,
            self.body_format.code(),
            self.group_select.nibble() << 4 | (self.source_message_id & 0xF),
        ]
    }
}

fixed_length!(UcmmOpenRequest, 4);

/// UCMM Open Explicit Messaging Connection success response, the whole frame data (protocol §3.6),
/// sent on Group 3 message 5 from the server:
/// `[hdr] CB [reserved 4 | actual body format 4] [dest message ID 4 | source message ID 4] <connection instance LE16>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UcmmOpenResponse {
    /// Transaction ID, echoed from the request.
    pub xid: bool,
    /// The client (header MAC).
    pub destination: MacId,
    /// The message body format the server chose.
    pub body_format: BodyFormat,
    /// The message ID the server consumes on, `0..=15`; `emit` keeps the low 4 bits.
    pub destination_message_id: u8,
    /// The message ID the server produces on, `0..=15`; `emit` keeps the low 4 bits.
    pub source_message_id: u8,
    /// The Connection object instance created.
    pub connection_instance: u16,
}

impl UcmmOpenResponse {
    /// Parses the 6 data bytes.
    pub fn parse(data: &[u8]) -> Result<UcmmOpenResponse, MessageError> {
        let [header, svc, format, ids, i0, i1] = exact::<6>(data)?;
        let header = unfragmented(header)?;
        service(UCMM_OPEN | 0x80, svc)?;
        if format & 0xF0 != 0 {
            return Err(MessageError::ReservedBitsSet);
        }
        Ok(UcmmOpenResponse {
            xid: header.xid,
            destination: header.mac,
            body_format: BodyFormat::from_code(format),
            destination_message_id: ids >> 4,
            source_message_id: ids & 0xF,
            connection_instance: u16::from_le_bytes([i0, i1]),
        })
    }

    /// The 6 data bytes.
    pub fn emit(&self) -> [u8; 6] {
        let [i0, i1] = self.connection_instance.to_le_bytes();
        [
            Header::new(self.xid, self.destination).to_byte(),
            UCMM_OPEN | 0x80,
            self.body_format.code(),
            (self.destination_message_id & 0xF) << 4 | (self.source_message_id & 0xF),
            i0,
            i1,
        ]
    }
}

fixed_length!(UcmmOpenResponse, 6);

/// UCMM Close Connection request, the whole frame data (protocol §3.6):
/// `[hdr] 4C <connection instance LE16>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UcmmCloseRequest {
    /// Transaction ID.
    pub xid: bool,
    /// The server (header MAC).
    pub destination: MacId,
    /// The Connection object instance to close.
    pub connection_instance: u16,
}

impl UcmmCloseRequest {
    /// Parses the 4 data bytes.
    pub fn parse(data: &[u8]) -> Result<UcmmCloseRequest, MessageError> {
        let [header, svc, i0, i1] = exact::<4>(data)?;
        let header = unfragmented(header)?;
        service(UCMM_CLOSE, svc)?;
        Ok(UcmmCloseRequest {
            xid: header.xid,
            destination: header.mac,
            connection_instance: u16::from_le_bytes([i0, i1]),
        })
    }

    /// The 4 data bytes.
    pub fn emit(&self) -> [u8; 4] {
        let [i0, i1] = self.connection_instance.to_le_bytes();
        [Header::new(self.xid, self.destination).to_byte(), UCMM_CLOSE, i0, i1]
    }
}

fixed_length!(UcmmCloseRequest, 4);

/// UCMM Close Connection success response, the whole frame data (protocol §3.6): `[hdr] CC`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct UcmmCloseResponse {
    /// Transaction ID, echoed from the request.
    pub xid: bool,
    /// The client (header MAC).
    pub destination: MacId,
}

impl UcmmCloseResponse {
    /// Parses the 2 data bytes.
    pub fn parse(data: &[u8]) -> Result<UcmmCloseResponse, MessageError> {
        let [header, svc] = exact::<2>(data)?;
        let header = unfragmented(header)?;
        service(UCMM_CLOSE | 0x80, svc)?;
        Ok(UcmmCloseResponse { xid: header.xid, destination: header.mac })
    }

    /// The 2 data bytes.
    pub fn emit(&self) -> [u8; 2] {
        [Header::new(self.xid, self.destination).to_byte(), UCMM_CLOSE | 0x80]
    }
}

fixed_length!(UcmmCloseResponse, 2);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::id::Identifier;
    use crate::messages::testing::mac;
    use rstest::rstest;

    #[rstest]
    #[case::frame4_open_to_5(&[0x05, 0x4B, 0x00, 0x34], UcmmOpenRequest { xid: false, destination: mac(5), body_format: BodyFormat::Class8Instance8, group_select: GroupSelect::Group3, source_message_id: 4 })]
    #[case::xid_group2_16_16(&[0x4A, 0x4B, 0x02, 0x10], UcmmOpenRequest { xid: true, destination: mac(10), body_format: BodyFormat::Class16Instance16, group_select: GroupSelect::Group2, source_message_id: 0 })]
    #[case::node_ping(&[0x3F, 0x4B, 0x00, 0xF0], UcmmOpenRequest { xid: false, destination: mac(63), body_format: BodyFormat::Class8Instance8, group_select: GroupSelect::NodePing, source_message_id: 0 })]
    #[case::reserved_select_and_format(&[0x01, 0x4B, 0x07, 0x2F], UcmmOpenRequest { xid: false, destination: mac(1), body_format: BodyFormat::Reserved(7), group_select: GroupSelect::Reserved(2), source_message_id: 15 })]
    fn ucmm_open_request_codec(#[case] bytes: &[u8], #[case] msg: UcmmOpenRequest) {
        assert_eq!(UcmmOpenRequest::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[rstest]
    #[case::fragmented(&[0x85, 0x4B, 0x00, 0x34], MessageError::Fragmented)]
    #[case::response_service(&[0x05, 0xCB, 0x00, 0x34], MessageError::UnexpectedService { expected: 0x4B, got: 0xCB })]
    #[case::close_service(&[0x05, 0x4C, 0x00, 0x34], MessageError::UnexpectedService { expected: 0x4B, got: 0x4C })]
    #[case::reserved_nibble(&[0x05, 0x4B, 0x10, 0x34], MessageError::ReservedBitsSet)]
    #[case::short(&[0x05, 0x4B, 0x00], MessageError::WrongLength { expected: 4, got: 3 })]
    fn ucmm_open_request_errors(#[case] bytes: &[u8], #[case] err: MessageError) {
        assert_eq!(UcmmOpenRequest::parse(bytes), Err(err));
    }

    #[test]
    fn ucmm_open_request_on_its_identifier() {
        // Frames 4–5: G3 message 6 from MAC 0 is 0x780.
        let id =
            Identifier::Group3 { message: crate::id::Group3MessageId::UNCONNECTED_REQUEST, source: mac(0) };
        assert_eq!(id.encode().as_raw(), 0x780);
        let msg = UcmmOpenRequest::parse(&[0x05, 0x4B, 0x00, 0x34]).unwrap();
        assert_eq!(msg.destination, mac(5));
    }

    #[rstest]
    #[case::server_5_to_master_0(&[0x00, 0xCB, 0x00, 0x34, 0x05, 0x00], UcmmOpenResponse { xid: false, destination: mac(0), body_format: BodyFormat::Class8Instance8, destination_message_id: 3, source_message_id: 4, connection_instance: 5 })]
    #[case::xid_wide_instance(&[0x4A, 0xCB, 0x01, 0xF0, 0x34, 0x12], UcmmOpenResponse { xid: true, destination: mac(10), body_format: BodyFormat::Class8Instance16, destination_message_id: 15, source_message_id: 0, connection_instance: 0x1234 })]
    fn ucmm_open_response_codec(#[case] bytes: &[u8], #[case] msg: UcmmOpenResponse) {
        assert_eq!(UcmmOpenResponse::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[test]
    fn ucmm_open_response_errors() {
        assert_eq!(
            UcmmOpenResponse::parse(&[0x00, 0x4B, 0x00, 0x34, 0x05, 0x00]),
            Err(MessageError::UnexpectedService { expected: 0xCB, got: 0x4B })
        );
        assert_eq!(
            UcmmOpenResponse::parse(&[0x00, 0xCB, 0xF0, 0x34, 0x05, 0x00]),
            Err(MessageError::ReservedBitsSet)
        );
        assert_eq!(
            UcmmOpenResponse::parse(&[0x80, 0xCB, 0x00, 0x34, 0x05, 0x00]),
            Err(MessageError::Fragmented)
        );
        // A UCMM error response (`[hdr] 94 …`) is an explicit response, not an open response.
        assert_eq!(
            UcmmOpenResponse::parse(&[0x00, 0x94, 0x08, 0xFF]),
            Err(MessageError::WrongLength { expected: 6, got: 4 })
        );
    }

    #[rstest]
    #[case::close_instance_5(&[0x05, 0x4C, 0x05, 0x00], UcmmCloseRequest { xid: false, destination: mac(5), connection_instance: 5 })]
    #[case::close_xid(&[0x45, 0x4C, 0x34, 0x12], UcmmCloseRequest { xid: true, destination: mac(5), connection_instance: 0x1234 })]
    fn ucmm_close_request_codec(#[case] bytes: &[u8], #[case] msg: UcmmCloseRequest) {
        assert_eq!(UcmmCloseRequest::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[test]
    fn ucmm_close_response_codec() {
        let msg = UcmmCloseResponse { xid: true, destination: mac(0) };
        assert_eq!(UcmmCloseResponse::parse(&[0x40, 0xCC]), Ok(msg));
        assert_eq!(msg.emit(), [0x40, 0xCC]);
        assert_eq!(
            UcmmCloseResponse::parse(&[0x40, 0x4C]),
            Err(MessageError::UnexpectedService { expected: 0xCC, got: 0x4C })
        );
        assert_eq!(
            UcmmCloseRequest::parse(&[0x05, 0xCC, 0x05, 0x00]),
            Err(MessageError::UnexpectedService { expected: 0x4C, got: 0xCC })
        );
    }

    #[test]
    fn group_select_nibbles() {
        for n in 0..16u8 {
            assert_eq!(GroupSelect::from_nibble(n).nibble(), n);
        }
        assert_eq!(GroupSelect::from_nibble(2), GroupSelect::Reserved(2));
        assert_eq!(GroupSelect::from_nibble(0x13), GroupSelect::Group3);
    }
}
