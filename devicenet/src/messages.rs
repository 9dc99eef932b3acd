//! Fixed-layout message bodies: the duplicate MAC ID check, Allocate/Release service data, UCMM
//! open/close, the device heartbeat and shutdown messages and the Group 4 Offline Connection Set
//! (devicenet-notes §3.4–§3.8).
//!
//! Each message is a plain `Copy` value with `parse` and `emit`. Where the layout has one length,
//! `emit` returns an array of exactly that length (`LEN`), and the type converts with
//! `TryFrom<&[u8]>` and `From<_> for [u8; LEN]`. The Offline Connection Set messages vary in
//! length and share one identifier per direction, so [`OfflineMessage`] is decoded from the Group 4
//! message ID together with the data and emitted into a caller's buffer.
//!
//! What a layout covers differs by message, following the notes:
//!
//! * [`DuplicateMacCheck`], [`OfflineMessage`]: the whole CAN data field.
//! * [`AllocateRequest`], [`ReleaseRequest`], [`AllocationInfo`]: explicit *service data* only,
//!   what follows service, class and instance (see [`crate::explicit::Request`]), or the attribute
//!   value of a Get response.
//! * UCMM, heartbeat and shutdown: the whole CAN data field, header byte included; these messages
//!   are never fragmented.
//!
//! No-panic contract: every `parse` takes any byte slice and returns a value or a
//! [`MessageError`]; it accepts exactly the byte strings its `emit` can produce, so a successful
//! parse re-emits the same bytes. Fixed-length `emit`s cannot fail: fields narrower than their
//! Rust type (a 7-bit port, a 4-bit message ID) are masked to their width, as each field's doc says.
//! [`OfflineMessage::emit`] checks the buffer length first.

use crate::explicit::{BodyFormat, Header};
use crate::id::{Group4MessageId, MacId};
use core::fmt;
use core::ops::{BitAnd, BitAndAssign, BitOr, BitOrAssign};

/// Why a message body could not be parsed or emitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MessageError {
    /// The message has a fixed length and the data has another.
    WrongLength {
        /// Bytes the layout has.
        expected: usize,
        /// Bytes present.
        got: usize,
    },
    /// The data ends before the bytes that select the layout.
    Truncated {
        /// Bytes required.
        needed: usize,
        /// Bytes present.
        got: usize,
    },
    /// The output buffer is too small.
    BufferTooSmall {
        /// Bytes required.
        needed: usize,
        /// Bytes available.
        got: usize,
    },
    /// A bit the layout reserves (must be zero) is set, e.g. bits 7–6 of a MAC ID byte.
    ReservedBitsSet,
    /// The fragmentation bit is set in a message that is never fragmented (UCMM, heartbeat,
    /// shutdown).
    Fragmented,
    /// The service byte (R/R bit included) is not the one this message carries.
    UnexpectedService {
        /// The service byte the layout requires.
        expected: u8,
        /// The service byte present.
        got: u8,
    },
    /// An Offline Connection Set request with a service byte this crate has no layout for.
    UnknownService(u8),
    /// A Group 4 message ID outside the Offline Connection Set (0x00–0x2B are reserved).
    NotOfflineMessage(u8),
    /// A MAC ID byte that is neither `0..=63` nor the "none" value the field allows.
    MacOutOfRange(u8),
}

impl fmt::Display for MessageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MessageError::WrongLength { expected, got } => {
                write!(f, "wrong length: the message has {expected} bytes, got {got}")
            }
            MessageError::Truncated { needed, got } => {
                write!(f, "message truncated: needs {needed} bytes, has {got}")
            }
            MessageError::BufferTooSmall { needed, got } => {
                write!(f, "buffer too small: needs {needed} bytes, has {got}")
            }
            MessageError::ReservedBitsSet => f.write_str("a reserved bit is set"),
            MessageError::Fragmented => f.write_str("fragment bit set in a message that is never fragmented"),
            MessageError::UnexpectedService { expected, got } => {
                write!(f, "service byte 0x{got:02X}, expected 0x{expected:02X}")
            }
            MessageError::UnknownService(s) => {
                write!(f, "unknown Offline Connection Set service 0x{s:02X}")
            }
            MessageError::NotOfflineMessage(m) => {
                write!(f, "Group 4 message 0x{m:02X} is not part of the Offline Connection Set")
            }
            MessageError::MacOutOfRange(m) => write!(f, "MAC ID {m} is out of range 0..=63"),
        }
    }
}

impl core::error::Error for MessageError {}

/// The data as an array of exactly `N` bytes.
fn exact<const N: usize>(data: &[u8]) -> Result<[u8; N], MessageError> {
    <[u8; N]>::try_from(data).map_err(|_| MessageError::WrongLength { expected: N, got: data.len() })
}

/// A MAC ID byte whose bits 7–6 are reserved (zero).
const fn mac_byte(b: u8) -> Result<MacId, MessageError> {
    match MacId::new(b) {
        Some(mac) => Ok(mac),
        None => Err(MessageError::ReservedBitsSet),
    }
}

/// An unfragmented header byte (UCMM, heartbeat, shutdown).
const fn unfragmented(b: u8) -> Result<Header, MessageError> {
    let header = Header::from_byte(b);
    if header.fragmented {
        Err(MessageError::Fragmented)
    } else {
        Ok(header)
    }
}

const fn service(expected: u8, got: u8) -> Result<(), MessageError> {
    if expected == got {
        Ok(())
    } else {
        Err(MessageError::UnexpectedService { expected, got })
    }
}

/// `TryFrom<&[u8]>` and `From<_> for [u8; LEN]` for a fixed-length message.
macro_rules! fixed_length {
    ($ty:ident, $len:literal) => {
        impl $ty {
            /// The length of the layout in bytes.
            pub const LEN: usize = $len;
        }

        impl TryFrom<&[u8]> for $ty {
            type Error = MessageError;

            fn try_from(data: &[u8]) -> Result<$ty, MessageError> {
                $ty::parse(data)
            }
        }

        impl From<$ty> for [u8; $len] {
            fn from(message: $ty) -> [u8; $len] {
                message.emit()
            }
        }
    };
}

/// The identity of a device on the wire: vendor ID and serial number, as carried by the duplicate
/// MAC ID check and the Offline Connection Set (Identity attributes 1 and 6, notes §6.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceKey {
    /// Vendor ID.
    pub vendor_id: u16,
    /// Serial number.
    pub serial_number: u32,
}

impl DeviceKey {
    /// Decodes `<vendor LE16> <serial LE32>`.
    pub const fn from_bytes(b: [u8; 6]) -> DeviceKey {
        DeviceKey {
            vendor_id: u16::from_le_bytes([b[0], b[1]]),
            serial_number: u32::from_le_bytes([b[2], b[3], b[4], b[5]]),
        }
    }

    /// Encodes `<vendor LE16> <serial LE32>`.
    pub const fn to_bytes(self) -> [u8; 6] {
        let [v0, v1] = self.vendor_id.to_le_bytes();
        let [s0, s1, s2, s3] = self.serial_number.to_le_bytes();
        [v0, v1, s0, s1, s2, s3]
    }
}

// ---------------------------------------------------------------------------------------------
// Duplicate MAC ID check (notes §3.5)

/// Duplicate MAC ID check message body (notes §3.5): always 7 bytes, sent on Group 2 message 7
/// with the checked MAC in the identifier.
///
/// `[R/R(7) | port(6–0)] <vendor LE16> <serial LE32>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DuplicateMacCheck {
    /// `false` for a request, `true` for a response (R/R bit).
    pub response: bool,
    /// Physical port number, `0..=127` (0 for single-port devices); `emit` keeps the low 7 bits.
    pub port: u8,
    /// The sender's vendor ID (Identity attribute 1).
    pub vendor_id: u16,
    /// The sender's serial number (Identity attribute 6).
    pub serial_number: u32,
}

impl DuplicateMacCheck {
    /// A request from a device with this port and identity.
    pub const fn request(port: u8, vendor_id: u16, serial_number: u32) -> DuplicateMacCheck {
        DuplicateMacCheck { response: false, port, vendor_id, serial_number }
    }

    /// A response from a device with this port and identity.
    pub const fn response(port: u8, vendor_id: u16, serial_number: u32) -> DuplicateMacCheck {
        DuplicateMacCheck { response: true, port, vendor_id, serial_number }
    }

    /// The sender's vendor ID and serial number.
    pub const fn device_key(&self) -> DeviceKey {
        DeviceKey { vendor_id: self.vendor_id, serial_number: self.serial_number }
    }

    /// Parses the 7 data bytes.
    pub fn parse(data: &[u8]) -> Result<DuplicateMacCheck, MessageError> {
        let [b0, k0, k1, k2, k3, k4, k5] = exact::<7>(data)?;
        let key = DeviceKey::from_bytes([k0, k1, k2, k3, k4, k5]);
        Ok(DuplicateMacCheck {
            response: b0 & 0x80 != 0,
            port: b0 & 0x7F,
            vendor_id: key.vendor_id,
            serial_number: key.serial_number,
        })
    }

    /// The 7 data bytes.
    pub fn emit(&self) -> [u8; 7] {
        let [k0, k1, k2, k3, k4, k5] = self.device_key().to_bytes();
        [(self.response as u8) << 7 | (self.port & 0x7F), k0, k1, k2, k3, k4, k5]
    }
}

fixed_length!(DuplicateMacCheck, 7);

// ---------------------------------------------------------------------------------------------
// Allocate / Release (notes §3.4)

/// Allocation choice bits (notes §3.4): which Predefined Master/Slave connections an Allocate or
/// Release names. A bit set that keeps all 8 bits, the reserved bit 7 included, so a validator
/// can reject it and a decoder can show it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AllocationChoice(u8);

impl AllocationChoice {
    /// Bit 0: explicit messaging.
    pub const EXPLICIT: AllocationChoice = AllocationChoice(0x01);
    /// Bit 1: polled I/O.
    pub const POLL: AllocationChoice = AllocationChoice(0x02);
    /// Bit 2: bit-strobed I/O.
    pub const BIT_STROBE: AllocationChoice = AllocationChoice(0x04);
    /// Bit 3: multicast poll.
    pub const MULTICAST_POLL: AllocationChoice = AllocationChoice(0x08);
    /// Bit 4: change of state.
    pub const CHANGE_OF_STATE: AllocationChoice = AllocationChoice(0x10);
    /// Bit 5: cyclic.
    pub const CYCLIC: AllocationChoice = AllocationChoice(0x20);
    /// Bit 6: acknowledge suppression (only meaningful with change of state or cyclic).
    pub const ACK_SUPPRESSION: AllocationChoice = AllocationChoice(0x40);
    /// Bit 7: reserved.
    pub const RESERVED: AllocationChoice = AllocationChoice(0x80);

    /// The names [`fmt::Display`] uses, bit 0 first.
    const NAMES: [(AllocationChoice, &'static str); 8] = [
        (AllocationChoice::EXPLICIT, "explicit"),
        (AllocationChoice::POLL, "poll"),
        (AllocationChoice::BIT_STROBE, "bit_strobe"),
        (AllocationChoice::MULTICAST_POLL, "multicast_poll"),
        (AllocationChoice::CHANGE_OF_STATE, "change_of_state"),
        (AllocationChoice::CYCLIC, "cyclic"),
        (AllocationChoice::ACK_SUPPRESSION, "ack_suppression"),
        (AllocationChoice::RESERVED, "reserved"),
    ];

    /// The set with exactly these bits; every byte is kept.
    pub const fn from_bits(bits: u8) -> AllocationChoice {
        AllocationChoice(bits)
    }

    /// The choice byte.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// No connection (choice byte 0).
    pub const fn empty() -> AllocationChoice {
        AllocationChoice(0)
    }

    /// `true` when every bit of `other` is set in `self`.
    pub const fn contains(self, other: AllocationChoice) -> bool {
        self.0 & other.0 == other.0
    }

    /// `true` when `self` and `other` share a bit.
    pub const fn intersects(self, other: AllocationChoice) -> bool {
        self.0 & other.0 != 0
    }

    /// The bits set in either.
    pub const fn union(self, other: AllocationChoice) -> AllocationChoice {
        AllocationChoice(self.0 | other.0)
    }

    /// The bits set in `self` and not in `other`.
    pub const fn difference(self, other: AllocationChoice) -> AllocationChoice {
        AllocationChoice(self.0 & !other.0)
    }

    /// The bits set in both.
    pub const fn intersection(self, other: AllocationChoice) -> AllocationChoice {
        AllocationChoice(self.0 & other.0)
    }

    /// `true` when no bit is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
}

impl BitOr for AllocationChoice {
    type Output = AllocationChoice;

    fn bitor(self, rhs: AllocationChoice) -> AllocationChoice {
        self.union(rhs)
    }
}

impl BitOrAssign for AllocationChoice {
    fn bitor_assign(&mut self, rhs: AllocationChoice) {
        *self = self.union(rhs);
    }
}

impl BitAnd for AllocationChoice {
    type Output = AllocationChoice;

    fn bitand(self, rhs: AllocationChoice) -> AllocationChoice {
        self.intersection(rhs)
    }
}

impl BitAndAssign for AllocationChoice {
    fn bitand_assign(&mut self, rhs: AllocationChoice) {
        *self = self.intersection(rhs);
    }
}

impl From<u8> for AllocationChoice {
    fn from(bits: u8) -> AllocationChoice {
        AllocationChoice(bits)
    }
}

impl From<AllocationChoice> for u8 {
    fn from(choice: AllocationChoice) -> u8 {
        choice.0
    }
}

/// The names of the set bits joined by `|` (`explicit|poll`), or `none`.
impl fmt::Display for AllocationChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_empty() {
            return f.write_str("none");
        }
        let mut first = true;
        for (bit, name) in AllocationChoice::NAMES {
            if self.contains(bit) {
                if !first {
                    f.write_str("|")?;
                }
                f.write_str(name)?;
                first = false;
            }
        }
        Ok(())
    }
}

/// Allocate_Master/Slave_Connection_Set request service data (notes §3.4), what follows service
/// 0x4B, class 3, instance 1: `<allocation choice> <allocator MAC>` (allocator bits 7–6 zero).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AllocateRequest {
    /// The connections to allocate (not validated here: an empty or reserved choice parses).
    pub choice: AllocationChoice,
    /// The allocating master's MAC ID.
    pub allocator: MacId,
}

impl AllocateRequest {
    /// Parses the 2 service-data bytes.
    pub fn parse(data: &[u8]) -> Result<AllocateRequest, MessageError> {
        let [choice, allocator] = exact::<2>(data)?;
        Ok(AllocateRequest { choice: AllocationChoice(choice), allocator: mac_byte(allocator)? })
    }

    /// The 2 service-data bytes.
    pub fn emit(&self) -> [u8; 2] {
        [self.choice.bits(), self.allocator.as_raw()]
    }
}

fixed_length!(AllocateRequest, 2);

/// Release_Master/Slave_Connection_Set request service data (notes §3.4), what follows service
/// 0x4C, class 3, instance 1: `<release choice>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReleaseRequest {
    /// The connections to release (not validated here).
    pub choice: AllocationChoice,
}

impl ReleaseRequest {
    /// Parses the 1 service-data byte.
    pub fn parse(data: &[u8]) -> Result<ReleaseRequest, MessageError> {
        let [choice] = exact::<1>(data)?;
        Ok(ReleaseRequest { choice: AllocationChoice(choice) })
    }

    /// The 1 service-data byte.
    pub fn emit(&self) -> [u8; 1] {
        [self.choice.bits()]
    }
}

fixed_length!(ReleaseRequest, 1);

/// DeviceNet object attribute 5, allocation information (notes §6.1):
/// `<allocation choice> <master MAC>`, master MAC 255 when the set is not allocated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AllocationInfo {
    /// The connections currently allocated.
    pub choice: AllocationChoice,
    /// The owning master, `None` when unallocated (sent as 255).
    pub master: Option<MacId>,
}

impl AllocationInfo {
    /// The master MAC byte of an unallocated set.
    pub const UNALLOCATED: u8 = 0xFF;

    /// Parses the 2-byte attribute value.
    pub fn parse(data: &[u8]) -> Result<AllocationInfo, MessageError> {
        let [choice, master] = exact::<2>(data)?;
        let master = match master {
            AllocationInfo::UNALLOCATED => None,
            raw => Some(MacId::new(raw).ok_or(MessageError::MacOutOfRange(raw))?),
        };
        Ok(AllocationInfo { choice: AllocationChoice(choice), master })
    }

    /// The 2-byte attribute value.
    pub fn emit(&self) -> [u8; 2] {
        let master = match self.master {
            Some(mac) => mac.as_raw(),
            None => AllocationInfo::UNALLOCATED,
        };
        [self.choice.bits(), master]
    }
}

fixed_length!(AllocationInfo, 2);

// ---------------------------------------------------------------------------------------------
// UCMM (notes §3.6)

/// The UCMM Open Explicit Messaging Connection request service byte.
pub const UCMM_OPEN: u8 = 0x4B;
/// The UCMM Close Connection request service byte.
pub const UCMM_CLOSE: u8 = 0x4C;

/// The message group a UCMM open request asks the server to use (notes §3.6), a 4-bit code that
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

/// UCMM Open Explicit Messaging Connection request, the whole frame data (notes §3.6), sent on
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

/// UCMM Open Explicit Messaging Connection success response, the whole frame data (notes §3.6),
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

/// UCMM Close Connection request, the whole frame data (notes §3.6):
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

/// UCMM Close Connection success response, the whole frame data (notes §3.6): `[hdr] CC`.
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

// ---------------------------------------------------------------------------------------------
// Heartbeat / shutdown (notes §3.7)

/// The Device Heartbeat service byte (response form of 0x4D).
pub const DEVICE_HEARTBEAT: u8 = 0xCD;
/// The Device Shutdown service byte (response form of 0x4E).
pub const DEVICE_SHUTDOWN: u8 = 0xCE;

/// The Identity object's state (attribute 8, notes §6.2), as carried by the heartbeat; unknown
/// values are kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeviceState {
    /// 0: non-existent.
    NonExistent,
    /// 1: device self testing.
    SelfTesting,
    /// 2: standby.
    Standby,
    /// 3: operational.
    Operational,
    /// 4: major recoverable fault.
    MajorRecoverableFault,
    /// 5: major unrecoverable fault.
    MajorUnrecoverableFault,
    /// Any other value, kept as received.
    Unknown(u8),
}

impl From<u8> for DeviceState {
    fn from(raw: u8) -> DeviceState {
        match raw {
            0 => DeviceState::NonExistent,
            1 => DeviceState::SelfTesting,
            2 => DeviceState::Standby,
            3 => DeviceState::Operational,
            4 => DeviceState::MajorRecoverableFault,
            5 => DeviceState::MajorUnrecoverableFault,
            other => DeviceState::Unknown(other),
        }
    }
}

impl From<DeviceState> for u8 {
    fn from(state: DeviceState) -> u8 {
        match state {
            DeviceState::NonExistent => 0,
            DeviceState::SelfTesting => 1,
            DeviceState::Standby => 2,
            DeviceState::Operational => 3,
            DeviceState::MajorRecoverableFault => 4,
            DeviceState::MajorUnrecoverableFault => 5,
            DeviceState::Unknown(raw) => raw,
        }
    }
}

/// The heartbeat's fault/event flags byte (notes §3.7), a bit set that keeps all 8 bits (bits 7–4
/// are reserved).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HeartbeatFlags(u8);

impl HeartbeatFlags {
    /// Bit 0, DF: device fault, an internal fault not caused by the user or the bus.
    pub const DEVICE_FAULT: HeartbeatFlags = HeartbeatFlags(0x01);
    /// Bit 1, UF: user fault.
    pub const USER_FAULT: HeartbeatFlags = HeartbeatFlags(0x02);
    /// Bit 2, SF: system fault, caused by bus interaction (e.g. a connection timeout).
    pub const SYSTEM_FAULT: HeartbeatFlags = HeartbeatFlags(0x04);
    /// Bit 3, EV: event.
    pub const EVENT: HeartbeatFlags = HeartbeatFlags(0x08);

    /// The set with exactly these bits.
    pub const fn from_bits(bits: u8) -> HeartbeatFlags {
        HeartbeatFlags(bits)
    }

    /// The flags byte.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// `true` when every bit of `other` is set in `self`.
    pub const fn contains(self, other: HeartbeatFlags) -> bool {
        self.0 & other.0 == other.0
    }

    /// The bits set in either.
    pub const fn union(self, other: HeartbeatFlags) -> HeartbeatFlags {
        HeartbeatFlags(self.0 | other.0)
    }
}

/// Device Heartbeat message, the whole frame data (notes §3.7), sent by a device on its response
/// identifier with its own MAC in the header:
/// `[hdr] CD <Identity instance LE16> <state> <flags> <configuration consistency LE16>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceHeartbeat {
    /// Transaction ID.
    pub xid: bool,
    /// The sending device (header MAC).
    pub mac: MacId,
    /// The Identity object instance reported on.
    pub identity_instance: u16,
    /// The Identity object's state.
    pub state: DeviceState,
    /// Fault and event flags.
    pub flags: HeartbeatFlags,
    /// The configuration consistency value (Identity attribute 9), 0 when unsupported.
    pub configuration_consistency: u16,
}

impl DeviceHeartbeat {
    /// Parses the 8 data bytes.
    pub fn parse(data: &[u8]) -> Result<DeviceHeartbeat, MessageError> {
        let [header, svc, i0, i1, state, flags, c0, c1] = exact::<8>(data)?;
        let header = unfragmented(header)?;
        service(DEVICE_HEARTBEAT, svc)?;
        Ok(DeviceHeartbeat {
            xid: header.xid,
            mac: header.mac,
            identity_instance: u16::from_le_bytes([i0, i1]),
            state: DeviceState::from(state),
            flags: HeartbeatFlags(flags),
            configuration_consistency: u16::from_le_bytes([c0, c1]),
        })
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; 8] {
        let [i0, i1] = self.identity_instance.to_le_bytes();
        let [c0, c1] = self.configuration_consistency.to_le_bytes();
        let header = Header::new(self.xid, self.mac).to_byte();
        [header, DEVICE_HEARTBEAT, i0, i1, u8::from(self.state), self.flags.bits(), c0, c1]
    }
}

fixed_length!(DeviceHeartbeat, 8);

/// Device Shutdown message, the whole frame data (notes §3.7), sent by a device on its response
/// identifier with its own MAC in the header:
/// `[hdr] CE <class LE16> <instance LE16> <shutdown code LE16>`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DeviceShutdown {
    /// Transaction ID.
    pub xid: bool,
    /// The sending device (header MAC).
    pub mac: MacId,
    /// The class of the object that caused the shutdown.
    pub class: u16,
    /// The instance of the object that caused the shutdown.
    pub instance: u16,
    /// The shutdown code.
    pub shutdown_code: u16,
}

impl DeviceShutdown {
    /// Parses the 8 data bytes.
    pub fn parse(data: &[u8]) -> Result<DeviceShutdown, MessageError> {
        let [header, svc, c0, c1, i0, i1, s0, s1] = exact::<8>(data)?;
        let header = unfragmented(header)?;
        service(DEVICE_SHUTDOWN, svc)?;
        Ok(DeviceShutdown {
            xid: header.xid,
            mac: header.mac,
            class: u16::from_le_bytes([c0, c1]),
            instance: u16::from_le_bytes([i0, i1]),
            shutdown_code: u16::from_le_bytes([s0, s1]),
        })
    }

    /// The 8 data bytes.
    pub fn emit(&self) -> [u8; 8] {
        let [c0, c1] = self.class.to_le_bytes();
        let [i0, i1] = self.instance.to_le_bytes();
        let [s0, s1] = self.shutdown_code.to_le_bytes();
        [Header::new(self.xid, self.mac).to_byte(), DEVICE_SHUTDOWN, c0, c1, i0, i1, s0, s1]
    }
}

fixed_length!(DeviceShutdown, 8);

// ---------------------------------------------------------------------------------------------
// Offline Connection Set (notes §3.8)

/// The first byte of the Communication Faulted request/response messages (notes §3.8):
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

/// A message of the Group 4 Offline Connection Set (notes §3.8), decoded from its Group 4 message
/// ID and data. Used to find and recover a node in the Communication Faulted state (notes §7.4).
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
    use crate::frame::CanId;
    use crate::id::Identifier;
    use proptest::prelude::*;
    use rstest::rstest;
    use std::format;

    fn mac(n: u8) -> MacId {
        MacId::new(n).unwrap()
    }

    /// The Group 4 message ID of a raw identifier (0x7C0–0x7EF).
    fn group4(raw: u16) -> Group4MessageId {
        match Identifier::decode(CanId::new(raw).unwrap()) {
            Identifier::Group4 { message } => message,
            other => panic!("0x{raw:03X} is not Group 4: {other:?}"),
        }
    }

    const MASTER: DeviceKey = DeviceKey { vendor_id: 0x0001, serial_number: 0x0102_0304 };
    const SLAVE: DeviceKey = DeviceKey { vendor_id: 0x1234, serial_number: 0x1234_5678 };

    // --- duplicate MAC ID check -------------------------------------------------------------

    #[rstest]
    #[case::frame0_master_request(&[0x00, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01], DuplicateMacCheck::request(0, 0x0001, 0x0102_0304))]
    #[case::frame2_slave_request(&[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], DuplicateMacCheck::request(0, 0x1234, 0x1234_5678))]
    #[case::slave_response(&[0x80, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], DuplicateMacCheck::response(0, 0x1234, 0x1234_5678))]
    #[case::port_127_response(&[0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF], DuplicateMacCheck::response(127, 0xFFFF, 0xFFFF_FFFF))]
    #[case::port_5_request(&[0x05, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00], DuplicateMacCheck::request(5, 0, 0))]
    fn duplicate_mac_codec(#[case] bytes: &[u8], #[case] msg: DuplicateMacCheck) {
        assert_eq!(DuplicateMacCheck::parse(bytes), Ok(msg));
        assert_eq!(DuplicateMacCheck::try_from(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
        assert_eq!(<[u8; DuplicateMacCheck::LEN]>::from(msg), msg.emit());
    }

    #[test]
    fn duplicate_mac_identity() {
        let frame0 = DuplicateMacCheck::parse(&[0x00, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01]).unwrap();
        assert_eq!(frame0.device_key(), MASTER);
        let frame2 = DuplicateMacCheck::parse(&[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]).unwrap();
        assert_eq!(frame2.device_key(), SLAVE);
    }

    #[rstest]
    #[case::empty(&[], 0)]
    #[case::six(&[0x00, 0x34, 0x12, 0x78, 0x56, 0x34], 6)]
    #[case::eight(&[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12, 0x00], 8)]
    fn duplicate_mac_wrong_length(#[case] bytes: &[u8], #[case] got: usize) {
        assert_eq!(DuplicateMacCheck::parse(bytes), Err(MessageError::WrongLength { expected: 7, got }));
    }

    #[test]
    fn duplicate_mac_port_is_masked_on_emit() {
        let msg = DuplicateMacCheck::request(0x85, 0, 0);
        assert_eq!(msg.emit()[0], 0x05);
    }

    // --- allocate / release -----------------------------------------------------------------

    #[rstest]
    #[case::allocate_explicit(&[0x01, 0x00], AllocationChoice::EXPLICIT, 0)]
    #[case::allocate_poll(&[0x02, 0x00], AllocationChoice::POLL, 0)]
    #[case::explicit_and_poll_by_63(&[0x03, 0x3F], AllocationChoice::EXPLICIT | AllocationChoice::POLL, 63)]
    #[case::cos_ack_suppressed(&[0x50, 0x0A], AllocationChoice::CHANGE_OF_STATE | AllocationChoice::ACK_SUPPRESSION, 10)]
    #[case::empty_choice_parses(&[0x00, 0x00], AllocationChoice::empty(), 0)]
    #[case::reserved_choice_parses(&[0x80, 0x01], AllocationChoice::RESERVED, 1)]
    fn allocate_codec(#[case] bytes: &[u8], #[case] choice: AllocationChoice, #[case] allocator: u8) {
        let msg = AllocateRequest { choice, allocator: mac(allocator) };
        assert_eq!(AllocateRequest::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[rstest]
    #[case::allocator_bit6(&[0x01, 0x40], MessageError::ReservedBitsSet)]
    #[case::allocator_bit7(&[0x01, 0x80], MessageError::ReservedBitsSet)]
    #[case::allocator_ff(&[0x02, 0xFF], MessageError::ReservedBitsSet)]
    #[case::empty(&[], MessageError::WrongLength { expected: 2, got: 0 })]
    #[case::choice_only(&[0x01], MessageError::WrongLength { expected: 2, got: 1 })]
    #[case::trailing_byte(&[0x01, 0x00, 0x00], MessageError::WrongLength { expected: 2, got: 3 })]
    fn allocate_errors(#[case] bytes: &[u8], #[case] err: MessageError) {
        assert_eq!(AllocateRequest::parse(bytes), Err(err));
    }

    #[test]
    fn allocate_inside_explicit_request() {
        // Frame 6 of the capture: `00 4B 03 01 01 00` on 0x42E.
        use crate::explicit::{split_message, Request, ServiceCode};
        let (_, body) = split_message(&[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]).unwrap();
        let req = Request::parse(body, BodyFormat::Class8Instance8).unwrap();
        assert_eq!((req.service, req.class, req.instance), (ServiceCode::AllocateMasterSlave, 3, 1));
        assert_eq!(
            AllocateRequest::parse(req.data),
            Ok(AllocateRequest { choice: AllocationChoice::EXPLICIT, allocator: mac(0) })
        );
    }

    #[rstest]
    #[case::release_explicit(&[0x01], AllocationChoice::EXPLICIT)]
    #[case::release_poll(&[0x02], AllocationChoice::POLL)]
    #[case::release_both(&[0x03], AllocationChoice::EXPLICIT | AllocationChoice::POLL)]
    #[case::release_nothing(&[0x00], AllocationChoice::empty())]
    fn release_codec(#[case] bytes: &[u8], #[case] choice: AllocationChoice) {
        let msg = ReleaseRequest { choice };
        assert_eq!(ReleaseRequest::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[rstest]
    #[case::empty(&[], 0)]
    #[case::two(&[0x01, 0x00], 2)]
    fn release_wrong_length(#[case] bytes: &[u8], #[case] got: usize) {
        assert_eq!(ReleaseRequest::parse(bytes), Err(MessageError::WrongLength { expected: 1, got }));
    }

    #[rstest]
    #[case::unallocated(&[0x00, 0xFF], AllocationInfo { choice: AllocationChoice::empty(), master: None })]
    #[case::explicit_poll_by_0(&[0x03, 0x00], AllocationInfo { choice: AllocationChoice::from_bits(3), master: Some(mac(0)) })]
    fn allocation_info_codec(#[case] bytes: &[u8], #[case] info: AllocationInfo) {
        assert_eq!(AllocationInfo::parse(bytes), Ok(info));
        assert_eq!(&info.emit(), bytes);
    }

    #[test]
    fn allocation_info_errors() {
        assert_eq!(AllocationInfo::parse(&[0x01, 0x40]), Err(MessageError::MacOutOfRange(0x40)));
        assert_eq!(AllocationInfo::parse(&[0x01]), Err(MessageError::WrongLength { expected: 2, got: 1 }));
    }

    #[rstest]
    #[case::none(AllocationChoice::empty(), "none")]
    #[case::explicit(AllocationChoice::EXPLICIT, "explicit")]
    #[case::explicit_poll(AllocationChoice::from_bits(0x03), "explicit|poll")]
    #[case::strobe_multicast(AllocationChoice::from_bits(0x0C), "bit_strobe|multicast_poll")]
    #[case::cos_cyclic_ack(AllocationChoice::from_bits(0x70), "change_of_state|cyclic|ack_suppression")]
    #[case::all(
        AllocationChoice::from_bits(0xFF),
        "explicit|poll|bit_strobe|multicast_poll|change_of_state|cyclic|ack_suppression|reserved"
    )]
    #[case::reserved(AllocationChoice::RESERVED, "reserved")]
    fn allocation_choice_display(#[case] choice: AllocationChoice, #[case] text: &str) {
        assert_eq!(format!("{choice}"), text);
    }

    #[test]
    fn allocation_choice_set_operations() {
        let both = AllocationChoice::EXPLICIT | AllocationChoice::POLL;
        assert_eq!(both.bits(), 0x03);
        assert!(both.contains(AllocationChoice::POLL));
        assert!(both.contains(both));
        assert!(!both.contains(AllocationChoice::POLL | AllocationChoice::CYCLIC));
        assert!(both.intersects(AllocationChoice::POLL | AllocationChoice::CYCLIC));
        assert!(!both.intersects(AllocationChoice::CYCLIC));
        assert_eq!(both & AllocationChoice::POLL, AllocationChoice::POLL);
        assert_eq!(both.difference(AllocationChoice::EXPLICIT), AllocationChoice::POLL);
        assert_eq!(both.union(AllocationChoice::CYCLIC).bits(), 0x23);
        assert!(AllocationChoice::empty().is_empty());
        assert!(AllocationChoice::default().is_empty());
        assert!(!both.is_empty());
        assert!(both.contains(AllocationChoice::empty()));
        assert_eq!(AllocationChoice::RESERVED.bits(), 0x80);
        let mut c = AllocationChoice::empty();
        c |= AllocationChoice::BIT_STROBE;
        c |= AllocationChoice::MULTICAST_POLL;
        assert_eq!(c.bits(), 0x0C);
        c &= AllocationChoice::MULTICAST_POLL;
        assert_eq!(c, AllocationChoice::MULTICAST_POLL);
        assert_eq!(u8::from(AllocationChoice::from(0xA5)), 0xA5);
        // Every named constant is one distinct bit.
        let all = AllocationChoice::NAMES.iter().fold(AllocationChoice::empty(), |acc, (bit, _)| {
            assert_eq!(bit.bits().count_ones(), 1);
            assert!(!acc.intersects(*bit));
            acc | *bit
        });
        assert_eq!(all.bits(), 0xFF);
    }

    // --- UCMM -------------------------------------------------------------------------------

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

    // --- heartbeat / shutdown ---------------------------------------------------------------

    #[rstest]
    #[case::operational(&[0x05, 0xCD, 0x01, 0x00, 0x03, 0x00, 0x00, 0x00], DeviceHeartbeat { xid: false, mac: mac(5), identity_instance: 1, state: DeviceState::Operational, flags: HeartbeatFlags::default(), configuration_consistency: 0 })]
    #[case::system_fault(&[0x05, 0xCD, 0x01, 0x00, 0x04, 0x04, 0xCD, 0xAB], DeviceHeartbeat { xid: false, mac: mac(5), identity_instance: 1, state: DeviceState::MajorRecoverableFault, flags: HeartbeatFlags::SYSTEM_FAULT, configuration_consistency: 0xABCD })]
    #[case::unknown_state(&[0x7F, 0xCD, 0x02, 0x01, 0x09, 0xF9, 0x00, 0x00], DeviceHeartbeat { xid: true, mac: mac(63), identity_instance: 0x102, state: DeviceState::Unknown(9), flags: HeartbeatFlags::from_bits(0xF9), configuration_consistency: 0 })]
    fn heartbeat_codec(#[case] bytes: &[u8], #[case] msg: DeviceHeartbeat) {
        assert_eq!(DeviceHeartbeat::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[rstest]
    #[case::identity_reset(&[0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00], DeviceShutdown { xid: false, mac: mac(5), class: 1, instance: 1, shutdown_code: 4 })]
    #[case::vendor_code(&[0x45, 0xCE, 0x66, 0x00, 0x01, 0x00, 0x01, 0x02], DeviceShutdown { xid: true, mac: mac(5), class: 0x66, instance: 1, shutdown_code: 0x201 })]
    fn shutdown_codec(#[case] bytes: &[u8], #[case] msg: DeviceShutdown) {
        assert_eq!(DeviceShutdown::parse(bytes), Ok(msg));
        assert_eq!(&msg.emit(), bytes);
    }

    #[rstest]
    #[case::heartbeat_as_shutdown(&[0x05, 0xCD, 0, 0, 0, 0, 0, 0], MessageError::UnexpectedService { expected: 0xCE, got: 0xCD })]
    #[case::fragmented(&[0x85, 0xCE, 0, 0, 0, 0, 0, 0], MessageError::Fragmented)]
    #[case::short(&[0x05, 0xCE, 0, 0, 0, 0, 0], MessageError::WrongLength { expected: 8, got: 7 })]
    fn shutdown_errors(#[case] bytes: &[u8], #[case] err: MessageError) {
        assert_eq!(DeviceShutdown::parse(bytes), Err(err));
    }

    #[test]
    fn heartbeat_errors_and_states() {
        assert_eq!(
            DeviceHeartbeat::parse(&[0x05, 0x4D, 0, 0, 0, 0, 0, 0]),
            Err(MessageError::UnexpectedService { expected: 0xCD, got: 0x4D })
        );
        for raw in 0..=0xFFu8 {
            assert_eq!(u8::from(DeviceState::from(raw)), raw);
        }
        let flags = HeartbeatFlags::DEVICE_FAULT.union(HeartbeatFlags::EVENT);
        assert_eq!(flags.bits(), 0x09);
        assert!(flags.contains(HeartbeatFlags::EVENT));
        assert!(!flags.contains(HeartbeatFlags::USER_FAULT));
    }

    // --- Offline Connection Set -------------------------------------------------------------

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

    #[test]
    fn errors_display() {
        assert_eq!(
            format!("{}", MessageError::WrongLength { expected: 7, got: 6 }),
            "wrong length: the message has 7 bytes, got 6"
        );
        assert_eq!(
            format!("{}", MessageError::UnexpectedService { expected: 0x4B, got: 0xCB }),
            "service byte 0xCB, expected 0x4B"
        );
        assert_eq!(format!("{}", MessageError::ReservedBitsSet), "a reserved bit is set");
    }

    // --- properties -------------------------------------------------------------------------

    fn any_mac() -> impl Strategy<Value = MacId> {
        (0u8..=63).prop_map(MacId::from_low_bits)
    }

    fn any_key() -> impl Strategy<Value = DeviceKey> {
        (any::<u16>(), any::<u32>())
            .prop_map(|(vendor_id, serial_number)| DeviceKey { vendor_id, serial_number })
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

    /// When `parse` accepts `bytes`, `emit` gives back exactly `bytes`.
    fn reemits<T, const N: usize>(
        bytes: &[u8],
        parse: fn(&[u8]) -> Result<T, MessageError>,
        emit: fn(&T) -> [u8; N],
    ) {
        if let Ok(msg) = parse(bytes) {
            assert_eq!(&emit(&msg)[..], bytes);
        }
    }

    proptest! {
        #[test]
        fn parsers_never_panic_and_reemit_their_input(
            bytes in proptest::collection::vec(any::<u8>(), 0..=10),
            g4 in 0u8..=0x2F,
        ) {
            reemits(&bytes, DuplicateMacCheck::parse, DuplicateMacCheck::emit);
            reemits(&bytes, AllocateRequest::parse, AllocateRequest::emit);
            reemits(&bytes, ReleaseRequest::parse, ReleaseRequest::emit);
            reemits(&bytes, AllocationInfo::parse, AllocationInfo::emit);
            reemits(&bytes, UcmmOpenRequest::parse, UcmmOpenRequest::emit);
            reemits(&bytes, UcmmOpenResponse::parse, UcmmOpenResponse::emit);
            reemits(&bytes, UcmmCloseRequest::parse, UcmmCloseRequest::emit);
            reemits(&bytes, UcmmCloseResponse::parse, UcmmCloseResponse::emit);
            reemits(&bytes, DeviceHeartbeat::parse, DeviceHeartbeat::emit);
            reemits(&bytes, DeviceShutdown::parse, DeviceShutdown::emit);
            let message = Group4MessageId::new(g4).unwrap();
            if let Ok(msg) = OfflineMessage::parse(message, &bytes) {
                let mut buf = [0u8; OfflineMessage::MAX_LEN];
                let n = msg.emit(&mut buf).unwrap();
                prop_assert_eq!(&buf[..n], &bytes[..]);
                prop_assert_eq!(msg.message_id(), message);
            }
        }

        #[test]
        fn offline_messages_round_trip(msg in any_offline()) {
            let mut buf = [0u8; OfflineMessage::MAX_LEN];
            let n = msg.emit(&mut buf).unwrap();
            prop_assert_eq!(OfflineMessage::parse(msg.message_id(), &buf[..n]), Ok(msg));
        }

        #[test]
        fn fixed_messages_round_trip(
            response in any::<bool>(), port in 0u8..=127, key in any_key(),
            choice in any::<u8>(), allocator in any_mac(), master in proptest::option::of(any_mac()),
            xid in any::<bool>(), node in any_mac(), format in 0u8..16, select in 0u8..16,
            id_a in 0u8..16, id_b in 0u8..16, word_a in any::<u16>(), word_b in any::<u16>(),
            state in any::<u8>(), flags in any::<u8>(),
        ) {
            let dup = DuplicateMacCheck { response, port, vendor_id: key.vendor_id, serial_number: key.serial_number };
            prop_assert_eq!(DuplicateMacCheck::parse(&dup.emit()), Ok(dup));

            let choice = AllocationChoice::from_bits(choice);
            let allocate = AllocateRequest { choice, allocator };
            prop_assert_eq!(AllocateRequest::parse(&allocate.emit()), Ok(allocate));
            let release = ReleaseRequest { choice };
            prop_assert_eq!(ReleaseRequest::parse(&release.emit()), Ok(release));
            let info = AllocationInfo { choice, master };
            prop_assert_eq!(AllocationInfo::parse(&info.emit()), Ok(info));

            let body_format = BodyFormat::from_code(format);
            let open = UcmmOpenRequest {
                xid, destination: node, body_format,
                group_select: GroupSelect::from_nibble(select), source_message_id: id_a,
            };
            prop_assert_eq!(UcmmOpenRequest::parse(&open.emit()), Ok(open));
            let opened = UcmmOpenResponse {
                xid, destination: node, body_format,
                destination_message_id: id_a, source_message_id: id_b, connection_instance: word_a,
            };
            prop_assert_eq!(UcmmOpenResponse::parse(&opened.emit()), Ok(opened));
            let close = UcmmCloseRequest { xid, destination: node, connection_instance: word_a };
            prop_assert_eq!(UcmmCloseRequest::parse(&close.emit()), Ok(close));
            let closed = UcmmCloseResponse { xid, destination: node };
            prop_assert_eq!(UcmmCloseResponse::parse(&closed.emit()), Ok(closed));

            let heartbeat = DeviceHeartbeat {
                xid, mac: node, identity_instance: word_a, state: DeviceState::from(state),
                flags: HeartbeatFlags::from_bits(flags), configuration_consistency: word_b,
            };
            prop_assert_eq!(DeviceHeartbeat::parse(&heartbeat.emit()), Ok(heartbeat));
            let shutdown = DeviceShutdown { xid, mac: node, class: word_a, instance: word_b, shutdown_code: key.vendor_id };
            prop_assert_eq!(DeviceShutdown::parse(&shutdown.emit()), Ok(shutdown));
        }
    }
}
