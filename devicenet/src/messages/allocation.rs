//! Allocate_Master/Slave_Connection_Set and Release_Master/Slave_Connection_Set service data and
//! the DeviceNet object's allocation information (protocol §3.4, §6.1): which connections
//! of the Predefined Master/Slave Connection Set are named, and by which master.
//!
//! These layouts are explicit *service data* only, what follows service, class 3 and instance 1
//! (see [`crate::explicit::Request`]), or the attribute value of a Get response.

use super::{exact, fixed_length, mac_byte, MessageError};
use crate::id::MacId;
use core::fmt;
use core::ops::{BitAnd, BitAndAssign, BitOr, BitOrAssign};

/// Allocation choice bits (protocol §3.4): which Predefined Master/Slave connections an Allocate or
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

/// Allocate_Master/Slave_Connection_Set request service data (protocol §3.4), what follows service
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

/// Release_Master/Slave_Connection_Set request service data (protocol §3.4), what follows service
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

/// DeviceNet object attribute 5, allocation information (protocol §6.1):
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::explicit::BodyFormat;
    use crate::messages::testing::mac;
    use rstest::rstest;
    use std::format;

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
        use crate::objects::class;
        let (_, body) = split_message(&[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]).unwrap();
        let req = Request::parse(body, BodyFormat::Class8Instance8).unwrap();
        assert_eq!(
            (req.service, req.class, req.instance),
            (ServiceCode::AllocateMasterSlave, class::DEVICENET, 1)
        );
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
}
