//! Fixed-layout message bodies: the duplicate MAC ID check, Allocate/Release service data, UCMM
//! open/close, the device heartbeat and shutdown messages and the Group 4 Offline Connection Set
//! (protocol §3.4–§3.8), one file per message family:
//!
//! | file | messages |
//! |---|---|
//! | `duplicate_mac.rs` | [`DuplicateMacCheck`] (protocol §3.5) |
//! | `allocation.rs` | [`AllocationChoice`], [`AllocateRequest`], [`ReleaseRequest`], [`AllocationInfo`] (protocol §3.4) |
//! | `ucmm.rs` | [`UcmmOpenRequest`], [`UcmmOpenResponse`], [`UcmmCloseRequest`], [`UcmmCloseResponse`] (protocol §3.6) |
//! | `heartbeat.rs` | [`DeviceHeartbeat`], [`DeviceShutdown`] (protocol §3.7) |
//! | `offline.rs` | [`OfflineMessage`], the Group 4 Offline Connection Set (protocol §3.8) |
//!
//! Every type is re-exported here: its path is `devicenet::messages::Name`. This file holds what
//! the families share: [`MessageError`], [`DeviceKey`] and the length and field checks.
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

mod allocation;
mod duplicate_mac;
mod heartbeat;
mod offline;
mod ucmm;

pub use allocation::{AllocateRequest, AllocationChoice, AllocationInfo, ReleaseRequest};
pub use duplicate_mac::DuplicateMacCheck;
pub use heartbeat::{
    DeviceHeartbeat, DeviceShutdown, DeviceState, HeartbeatFlags, DEVICE_HEARTBEAT, DEVICE_SHUTDOWN,
};
pub use offline::{FaultedSelector, OfflineMessage};
pub use ucmm::{
    GroupSelect, UcmmCloseRequest, UcmmCloseResponse, UcmmOpenRequest, UcmmOpenResponse, UCMM_CLOSE,
    UCMM_OPEN,
};

use crate::explicit::Header;
use crate::id::MacId;
use core::fmt;

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
use fixed_length;

/// The identity of a device on the wire: vendor ID and serial number, as carried by the duplicate
/// MAC ID check and the Offline Connection Set (Identity attributes 1 and 6, protocol §6.2).
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

/// Values and strategies the families' tests share.
#[cfg(test)]
mod testing {
    use super::DeviceKey;
    use crate::frame::CanId;
    use crate::id::{Group4MessageId, Identifier, MacId};
    use proptest::prelude::*;

    pub(super) fn mac(n: u8) -> MacId {
        MacId::new(n).unwrap()
    }

    /// The Group 4 message ID of a raw identifier (0x7C0–0x7EF).
    pub(super) fn group4(raw: u16) -> Group4MessageId {
        match Identifier::decode(CanId::new(raw).unwrap()) {
            Identifier::Group4 { message } => message,
            other => panic!("0x{raw:03X} is not Group 4: {other:?}"),
        }
    }

    /// The master of the reference capture (protocol §2, frame 0).
    pub(super) const MASTER: DeviceKey = DeviceKey { vendor_id: 0x0001, serial_number: 0x0102_0304 };
    /// The reference slave (protocol §2, frame 2).
    pub(super) const SLAVE: DeviceKey = DeviceKey { vendor_id: 0x1234, serial_number: 0x1234_5678 };

    pub(super) fn any_mac() -> impl Strategy<Value = MacId> {
        (0u8..=63).prop_map(MacId::from_low_bits)
    }

    pub(super) fn any_key() -> impl Strategy<Value = DeviceKey> {
        (any::<u16>(), any::<u32>())
            .prop_map(|(vendor_id, serial_number)| DeviceKey { vendor_id, serial_number })
    }
}

#[cfg(test)]
mod tests {
    use super::testing::{any_key, any_mac};
    use super::*;
    use crate::explicit::BodyFormat;
    use crate::id::Group4MessageId;
    use proptest::prelude::*;
    use std::format;

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
