//! The CAN frame value type: an 11-bit identifier and 0..=8 data bytes.
//!
//! DeviceNet uses only CAN 2.0A data frames (11-bit identifiers). [`CanFrame`] converts to and from
//! any [`embedded_can::Frame`], so `bxcan::Frame` on the board and `socketcan::CanFrame` on Linux
//! both plug in through one small function at the edge. Conversion from a foreign frame is
//! fallible: extended identifiers and remote frames are not DeviceNet traffic.

use core::fmt;

/// An 11-bit CAN identifier, `0x000..=0x7FF`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CanId(pub(crate) u16);

impl CanId {
    /// The largest 11-bit identifier.
    pub const MAX: CanId = CanId(0x7FF);

    /// `Some` when `raw` fits in 11 bits.
    pub const fn new(raw: u16) -> Option<CanId> {
        if raw <= 0x7FF {
            Some(CanId(raw))
        } else {
            None
        }
    }

    /// The identifier as a number.
    pub const fn as_raw(self) -> u16 {
        self.0
    }
}

impl fmt::Display for CanId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:03X}", self.0)
    }
}

/// Why a frame could not be built or converted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError {
    /// The identifier does not fit in 11 bits.
    IdentifierOutOfRange(u32),
    /// An extended (29-bit) identifier: not DeviceNet traffic.
    ExtendedIdentifier(u32),
    /// A remote transmission request: DeviceNet does not use them.
    RemoteFrame,
    /// More than 8 data bytes.
    TooLong(usize),
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::IdentifierOutOfRange(id) => {
                write!(f, "identifier 0x{id:X} does not fit in 11 bits")
            }
            FrameError::ExtendedIdentifier(id) => {
                write!(f, "extended identifier 0x{id:08X} is not DeviceNet traffic")
            }
            FrameError::RemoteFrame => f.write_str("remote frames are not DeviceNet traffic"),
            FrameError::TooLong(n) => write!(f, "{n} data bytes, a CAN frame holds at most 8"),
        }
    }
}

impl core::error::Error for FrameError {}

/// A classic CAN data frame with an 11-bit identifier and up to 8 data bytes.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: CanId,
    len: u8,
    data: [u8; 8],
}

impl CanFrame {
    /// A frame with `id` and `data`; fails when `data` is longer than 8 bytes.
    // Inlined: most callers know the data length (some 30 bytes of the firmware's flash).
    #[inline]
    pub fn new(id: CanId, data: &[u8]) -> Result<CanFrame, FrameError> {
        let mut buf = [0u8; 8];
        buf.get_mut(..data.len()).ok_or(FrameError::TooLong(data.len()))?.copy_from_slice(data);
        Ok(CanFrame { id, len: data.len() as u8, data: buf })
    }

    /// A frame from a raw identifier and data, both checked.
    pub fn from_raw(id: u16, data: &[u8]) -> Result<CanFrame, FrameError> {
        let id = CanId::new(id).ok_or(FrameError::IdentifierOutOfRange(u32::from(id)))?;
        CanFrame::new(id, data)
    }

    /// The identifier.
    pub const fn id(&self) -> CanId {
        self.id
    }

    /// The data length code (0..=8).
    pub const fn dlc(&self) -> usize {
        self.len as usize
    }

    /// The data bytes.
    pub fn data(&self) -> &[u8] {
        // `len` is at most 8 by construction, so the whole `len` bytes are returned.
        self.data.get(..usize::from(self.len)).unwrap_or_default()
    }

    /// The number of bits this frame occupies on the wire, stuff bits included in the worst
    /// case (CAN 2.0A: 47 fixed bits + 8 per data byte, of which 34 + 8n are subject to stuffing).
    pub const fn worst_case_bits(&self) -> u32 {
        let n = self.len as u32;
        let stuffable = 34 + 8 * n;
        47 + 8 * n + (stuffable - 1) / 4
    }
}

impl fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// `ID#DATA` as in can-utils (`42B#00CB00`).
impl fmt::Display for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}#", self.id)?;
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

#[cfg(feature = "defmt")]
impl defmt::Format for CanFrame {
    fn format(&self, f: defmt::Formatter) {
        defmt::write!(f, "{=u16:03X}#{=[u8]:02X}", self.id.0, self.data())
    }
}

impl embedded_can::Frame for CanFrame {
    fn new(id: impl Into<embedded_can::Id>, data: &[u8]) -> Option<Self> {
        match id.into() {
            embedded_can::Id::Standard(sid) => CanFrame::new(CanId(sid.as_raw()), data).ok(),
            embedded_can::Id::Extended(_) => None,
        }
    }

    fn new_remote(_id: impl Into<embedded_can::Id>, _dlc: usize) -> Option<Self> {
        None
    }

    fn is_extended(&self) -> bool {
        false
    }

    fn is_remote_frame(&self) -> bool {
        false
    }

    fn id(&self) -> embedded_can::Id {
        // The identifier is at most 0x7FF by construction, so this always succeeds.
        match embedded_can::StandardId::new(self.id.0) {
            Some(sid) => embedded_can::Id::Standard(sid),
            None => embedded_can::Id::Standard(embedded_can::StandardId::MAX),
        }
    }

    fn dlc(&self) -> usize {
        self.len as usize
    }

    fn data(&self) -> &[u8] {
        CanFrame::data(self)
    }
}

impl CanFrame {
    /// Converts any [`embedded_can::Frame`] (a `bxcan::Frame`, a `socketcan::CanFrame`) into a
    /// DeviceNet frame, rejecting extended identifiers and remote frames.
    pub fn from_embedded<F: embedded_can::Frame>(frame: &F) -> Result<CanFrame, FrameError> {
        if frame.is_remote_frame() {
            return Err(FrameError::RemoteFrame);
        }
        match frame.id() {
            embedded_can::Id::Standard(sid) => CanFrame::new(CanId(sid.as_raw()), frame.data()),
            embedded_can::Id::Extended(eid) => Err(FrameError::ExtendedIdentifier(eid.as_raw())),
        }
    }

    /// Converts this frame into any [`embedded_can::Frame`] implementation.
    pub fn to_embedded<F: embedded_can::Frame>(&self) -> Option<F> {
        let sid = embedded_can::StandardId::new(self.id.0)?;
        F::new(sid, self.data())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_can::Frame as _;
    use rstest::rstest;

    #[rstest]
    #[case::lowest(0x000, true)]
    #[case::highest(0x7FF, true)]
    #[case::twelve_bits(0x800, false)]
    #[case::max_u16(0xFFFF, false)]
    fn can_id_range(#[case] raw: u16, #[case] ok: bool) {
        assert_eq!(CanId::new(raw).is_some(), ok);
    }

    #[test]
    fn frame_holds_at_most_eight_bytes() {
        assert_eq!(CanFrame::from_raw(0x42B, &[0; 9]), Err(FrameError::TooLong(9)));
        assert_eq!(CanFrame::from_raw(0x800, &[]), Err(FrameError::IdentifierOutOfRange(0x800)));
        let f = CanFrame::from_raw(0x42B, &[0x00, 0xCB, 0x00]).unwrap();
        assert_eq!(f.dlc(), 3);
        assert_eq!(f.data(), &[0x00, 0xCB, 0x00]);
    }

    #[test]
    fn display_is_candump_style() {
        extern crate std;
        let f = CanFrame::from_raw(0x42B, &[0x00, 0xCB, 0x00]).unwrap();
        assert_eq!(std::format!("{f}"), "42B#00CB00");
        let empty = CanFrame::from_raw(0x42D, &[]).unwrap();
        assert_eq!(std::format!("{empty}"), "42D#");
    }

    #[test]
    fn embedded_can_round_trip() {
        let f = CanFrame::from_raw(0x3C5, &[0x82, 0x0E, 0x0F, 0x10, 0x11]).unwrap();
        let g: CanFrame = f.to_embedded().unwrap();
        assert_eq!(f, g);
        assert_eq!(CanFrame::from_embedded(&g), Ok(f));
        let ext = embedded_can::ExtendedId::new(0x1234_5678).unwrap();
        assert!(<CanFrame as embedded_can::Frame>::new(ext, &[]).is_none());
        assert!(CanFrame::new_remote(embedded_can::StandardId::ZERO, 0).is_none());
    }

    #[test]
    fn worst_case_bit_count() {
        // 8-byte frame: 111 bits + 24 stuff bits = 135 (the usual textbook worst case).
        let f = CanFrame::from_raw(0, &[0; 8]).unwrap();
        assert_eq!(f.worst_case_bits(), 135);
        let e = CanFrame::from_raw(0, &[]).unwrap();
        assert_eq!(e.worst_case_bits(), 47 + 8);
    }
}
