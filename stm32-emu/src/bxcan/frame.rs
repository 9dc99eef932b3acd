//! CAN frames as the bxCAN model sees them: an 11- or 29-bit identifier, data or remote, a data
//! length code and up to 8 bytes, with the register images of RM0090 §32.9.3 ("CAN mailbox
//! registers": `CAN_TIxR`/`CAN_RIxR`, `CAN_TDTxR`/`CAN_RDTxR`, `CAN_TDLxR`/`CAN_RDLxR`,
//! `CAN_TDHxR`/`CAN_RDHxR`).
//!
//! `devicenet::CanFrame` does not fit here: it has neither remote frames nor extended
//! identifiers, and the filter module must tell both apart (IDE and RTR bits, RM0090 §32.7.4).

/// The IDE bit of an identifier register: extended identifier (RM0090 §32.9.3).
pub(crate) const IDE: u32 = 1 << 2;
/// The RTR bit of an identifier register: remote frame (RM0090 §32.9.3).
pub(crate) const RTR: u32 = 1 << 1;

/// A CAN identifier, checked against its width.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FrameId {
    /// An 11-bit (CAN 2.0A) identifier.
    Standard(u16),
    /// A 29-bit (CAN 2.0B) identifier.
    Extended(u32),
}

impl FrameId {
    /// The largest standard identifier.
    pub const MAX_STANDARD: u16 = 0x7FF;
    /// The largest extended identifier.
    pub const MAX_EXTENDED: u32 = 0x1FFF_FFFF;

    /// A standard identifier, or `None` above 11 bits.
    pub const fn standard(raw: u16) -> Option<FrameId> {
        if raw <= Self::MAX_STANDARD {
            Some(FrameId::Standard(raw))
        } else {
            None
        }
    }

    /// An extended identifier, or `None` above 29 bits.
    pub const fn extended(raw: u32) -> Option<FrameId> {
        if raw <= Self::MAX_EXTENDED {
            Some(FrameId::Extended(raw))
        } else {
            None
        }
    }
}

/// One CAN data or remote frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Frame {
    id: FrameId,
    remote: bool,
    dlc: u8,
    data: [u8; 8],
}

impl Frame {
    /// A data frame; `None` when `data` is longer than 8 bytes.
    pub fn new_data(id: FrameId, data: &[u8]) -> Option<Frame> {
        let mut bytes = [0u8; 8];
        bytes.get_mut(..data.len())?.copy_from_slice(data);
        Some(Frame { id, remote: false, dlc: data.len() as u8, data: bytes })
    }

    /// A remote frame asking for `dlc` bytes; `None` when `dlc` is above 8.
    pub fn new_remote(id: FrameId, dlc: u8) -> Option<Frame> {
        (dlc <= 8).then_some(Frame { id, remote: true, dlc, data: [0; 8] })
    }

    /// The identifier.
    pub const fn id(&self) -> FrameId {
        self.id
    }

    /// Whether this is a remote frame.
    pub const fn is_remote(&self) -> bool {
        self.remote
    }

    /// The data length code, `0..=15` (codes above 8 carry 8 bytes, CAN 2.0).
    pub const fn dlc(&self) -> u8 {
        self.dlc
    }

    /// The data bytes (none for a remote frame).
    pub fn data(&self) -> &[u8] {
        let len = if self.remote { 0 } else { usize::from(self.dlc.min(8)) };
        self.data.get(..len).unwrap_or_default()
    }

    /// The identifier register image, `CAN_TIxR`/`CAN_RIxR` without TXRQ: `STID[10:0]` in bits
    /// 31:21, `EXID[17:0]` in 20:3 (an extended identifier's 29 bits in 31:3), IDE bit 2, RTR
    /// bit 1 (RM0090 §32.9.3). It is also the 32-bit filter word (RM0090 §32.7.4).
    pub const fn id_register(&self) -> u32 {
        let id = match self.id {
            FrameId::Standard(raw) => (raw as u32) << 21,
            FrameId::Extended(raw) => (raw << 3) | IDE,
        };
        if self.remote {
            id | RTR
        } else {
            id
        }
    }

    /// The 16-bit filter word: `STID[10:0]` in bits 15:5, RTR bit 4, IDE bit 3, `EXID[17:15]`
    /// in 2:0 (RM0090 §32.7.4, "Filter bank scale configuration").
    pub const fn filter16(&self) -> u16 {
        let reg = self.id_register();
        // STID and EXID[17:15] are register bits 31:18; IDE and RTR move to 3 and 4.
        let high = (reg >> 16) & 0xFFE0 | (reg >> 18) & 0x0007;
        let ide = if reg & IDE != 0 { 1 << 3 } else { 0 };
        let rtr = if reg & RTR != 0 { 1 << 4 } else { 0 };
        (high | ide | rtr) as u16
    }

    /// The data registers `CAN_TDLxR`/`CAN_RDLxR` and `CAN_TDHxR`/`CAN_RDHxR`: byte 0 in bits
    /// 7:0 of the low register, byte 4 in bits 7:0 of the high one (RM0090 §32.9.3).
    pub(crate) fn data_registers(&self) -> [u32; 2] {
        let [a, b, c, d, e, f, g, h] = self.data;
        [u32::from_le_bytes([a, b, c, d]), u32::from_le_bytes([e, f, g, h])]
    }

    /// The frame a transmit mailbox holds: its identifier register (TXRQ ignored), the DLC
    /// field of `CAN_TDTxR` (bits 3:0) and the two data registers.
    pub(crate) fn from_registers(tir: u32, tdtr: u32, low: u32, high: u32) -> Frame {
        let id =
            if tir & IDE != 0 { FrameId::Extended(tir >> 3) } else { FrameId::Standard((tir >> 21) as u16) };
        let [a, b, c, d] = low.to_le_bytes();
        let [e, f, g, h] = high.to_le_bytes();
        Frame { id, remote: tir & RTR != 0, dlc: (tdtr & 0xF) as u8, data: [a, b, c, d, e, f, g, h] }
    }

    /// The frame's arbitration field as a number, lower wins (ISO 11898-1 arbitration): the
    /// 11 base identifier bits, then for a standard frame RTR and IDE (0), for an extended one
    /// SRR (1), IDE (1), the 18 extension bits and RTR. A standard data frame beats a remote
    /// frame of its identifier and an extended frame of the same base identifier. The bxCAN
    /// orders its own mailboxes by identifier the same way when TXFP is 0 (RM0090 §32.7.1).
    pub const fn arbitration_key(&self) -> u32 {
        let rtr = self.remote as u32;
        match self.id {
            FrameId::Standard(raw) => ((raw as u32) << 20) | (rtr << 19),
            FrameId::Extended(raw) => {
                let base = raw >> 18;
                (base << 20) | (1 << 19) | (1 << 18) | ((raw & 0x3FFFF) << 1) | rtr
            }
        }
    }

    /// The frame's length on the wire in bits, stuff bits excluded: start of frame to the end
    /// of the intermission (CAN 2.0: 47 bits for a standard frame, 67 for an extended one, plus
    /// 8 per data byte).
    pub fn wire_bits(&self) -> u32 {
        let fixed = match self.id {
            FrameId::Standard(_) => 47,
            FrameId::Extended(_) => 67,
        };
        fixed + 8 * self.data().len() as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn std(raw: u16) -> FrameId {
        FrameId::standard(raw).unwrap()
    }

    #[rstest]
    // bxcan 0.8 IdReg::new_standard: id << 21; new_extended: id << 3 | IDE; with_rtr: | RTR.
    #[case::standard_data(Frame::new_data(std(0x42B), &[1]).unwrap(), 0x42B << 21)]
    #[case::standard_remote(Frame::new_remote(std(0x7FF), 0).unwrap(), 0x7FF << 21 | RTR)]
    #[case::extended_data(
        Frame::new_data(FrameId::extended(0x1234_5678).unwrap(), &[]).unwrap(),
        0x1234_5678 << 3 | IDE
    )]
    fn identifier_register(#[case] frame: Frame, #[case] reg: u32) {
        assert_eq!(frame.id_register(), reg);
        let back = Frame::from_registers(reg, u32::from(frame.dlc()), 0, 0);
        assert_eq!(back.id(), frame.id());
        assert_eq!(back.is_remote(), frame.is_remote());
    }

    #[rstest]
    // bxcan 0.8 Mask16::frames_with_std_id: id << 5; F16_RTR = 0b10000, F16_IDE = 0b01000.
    #[case::standard(Frame::new_data(std(0x428), &[]).unwrap(), 0x428 << 5)]
    #[case::remote(Frame::new_remote(std(0x428), 0).unwrap(), 0x428 << 5 | 0b1_0000)]
    // Extended 0x1FFF_FFFF: STID all ones, IDE, EXID[17:15] all ones.
    #[case::extended(
        Frame::new_data(FrameId::extended(0x1FFF_FFFF).unwrap(), &[]).unwrap(),
        0xFFE0 | 0b0_1000 | 0b111
    )]
    fn filter_word_16_bit(#[case] frame: Frame, #[case] word: u16) {
        assert_eq!(frame.filter16(), word);
    }

    #[test]
    fn data_registers_little_endian() {
        let frame = Frame::new_data(std(1), &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        assert_eq!(frame.data_registers(), [0x0403_0201, 0x0807_0605]);
        let back = Frame::from_registers(1 << 21, 8, 0x0403_0201, 0x0807_0605);
        assert_eq!(back, frame);
    }

    #[rstest]
    #[case::lower_id_wins(Frame::new_data(std(0x100), &[]), Frame::new_data(std(0x101), &[]))]
    #[case::data_beats_remote(Frame::new_data(std(0x100), &[]), Frame::new_remote(std(0x100), 0))]
    #[case::standard_beats_extended_of_same_base(
        Frame::new_remote(std(0x100), 0),
        Frame::new_data(FrameId::extended(0x100 << 18).unwrap(), &[])
    )]
    fn arbitration(#[case] winner: Option<Frame>, #[case] loser: Option<Frame>) {
        assert!(winner.unwrap().arbitration_key() < loser.unwrap().arbitration_key());
    }

    #[rstest]
    #[case::too_long_data(Frame::new_data(std(1), &[0; 9]))]
    #[case::too_long_remote(Frame::new_remote(std(1), 9))]
    fn refused(#[case] frame: Option<Frame>) {
        assert_eq!(frame, None);
    }

    #[test]
    fn identifier_ranges() {
        assert_eq!(FrameId::standard(0x800), None);
        assert_eq!(FrameId::extended(0x2000_0000), None);
    }
}
