//! The image-info block: who an image is for and which revision it is.
//!
//! The firmware carries the block at [`INFO_OFFSET`] bytes from the start of its image (after the
//! vector table: 0x188 bytes on the STM32F405, 0x1C4 on the F446), inside the signed bytes, so the
//! firmware and the bootloader read an image's board and revision without trusting the unsigned
//! trailer (the design page "The image and its signature").
//!
//! Layout, [`INFO_LEN`] bytes, integers little-endian as every DeviceNet integer:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `DNFI` |
//! | 4 | 1 | format version ([`INFO_FORMAT`]) |
//! | 5 | 1 | reserved, 0 |
//! | 6 | 2 | board ID (UINT) |
//! | 8 | 1 | firmware revision, major |
//! | 9 | 1 | firmware revision, minor |
//! | 10 | 6 | reserved, 0 |
//!
//! Parsing never panics: every access is checked against the slice it reads.

use crate::Revision;

/// Where the block starts, counted from the first byte of the image.
pub const INFO_OFFSET: usize = 0x200;
/// The block's length in bytes.
pub const INFO_LEN: usize = 16;
/// The block's magic.
pub const INFO_MAGIC: [u8; 4] = *b"DNFI";
/// The format version this crate writes and reads.
pub const INFO_FORMAT: u8 = 1;

/// The image-info block of an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageInfo {
    /// The board the image is built for (`board::boards`' board ID).
    pub board_id: u16,
    /// The firmware revision.
    pub revision: Revision,
}

/// Why an image has no valid image-info block.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum InfoError {
    /// The image ends before the block does.
    #[error("the image is {len} bytes, too short for an image-info block at 0x200")]
    TooShort {
        /// The image's length.
        len: usize,
    },
    /// The bytes at the block's offset are not `DNFI`.
    #[error("no image-info block: the bytes at 0x200 are not the magic DNFI")]
    BadMagic,
    /// A format version this crate does not know.
    #[error("image-info block format {0} is not known (this build reads format 1)")]
    UnknownFormat(u8),
    /// A reserved byte is not zero.
    #[error("image-info block byte {offset} is reserved and must be 0")]
    ReservedNotZero {
        /// The offset of the byte within the block.
        offset: usize,
    },
}

impl ImageInfo {
    /// The block's bytes, for the firmware's linked-in block (a `const fn`, so that a `static`
    /// can hold them).
    #[must_use]
    pub const fn to_bytes(&self) -> [u8; INFO_LEN] {
        let board = self.board_id.to_le_bytes();
        [
            INFO_MAGIC[0],
            INFO_MAGIC[1],
            INFO_MAGIC[2],
            INFO_MAGIC[3],
            INFO_FORMAT,
            0,
            board[0],
            board[1],
            self.revision.major,
            self.revision.minor,
            0,
            0,
            0,
            0,
            0,
            0,
        ]
    }

    /// Reads the block from its own bytes.
    ///
    /// # Errors
    /// [`InfoError`] when the magic, the format or a reserved byte is wrong.
    pub fn from_bytes(block: &[u8; INFO_LEN]) -> Result<Self, InfoError> {
        let [m0, m1, m2, m3, format, r5, b0, b1, major, minor, r10, r11, r12, r13, r14, r15] = *block;
        if [m0, m1, m2, m3] != INFO_MAGIC {
            return Err(InfoError::BadMagic);
        }
        if format != INFO_FORMAT {
            return Err(InfoError::UnknownFormat(format));
        }
        for (offset, byte) in
            [(5, r5), (10, r10), (11, r11), (12, r12), (13, r13), (14, r14)].into_iter().chain([(15, r15)])
        {
            if byte != 0 {
                return Err(InfoError::ReservedNotZero { offset });
            }
        }
        Ok(Self { board_id: u16::from_le_bytes([b0, b1]), revision: Revision { major, minor } })
    }

    /// Reads the block of an image (its first bytes at least; the rest may be absent).
    ///
    /// # Errors
    /// [`InfoError::TooShort`] when `image` ends before the block does, else as
    /// [`ImageInfo::from_bytes`].
    pub fn parse(image: &[u8]) -> Result<Self, InfoError> {
        let block = image
            .get(INFO_OFFSET..INFO_OFFSET + INFO_LEN)
            .and_then(|b| <&[u8; INFO_LEN]>::try_from(b).ok())
            .ok_or(InfoError::TooShort { len: image.len() })?;
        Self::from_bytes(block)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    const INFO: ImageInfo = ImageInfo { board_id: 0x0203, revision: Revision { major: 4, minor: 5 } };

    #[test]
    fn bytes_are_the_documented_layout() {
        assert_eq!(INFO.to_bytes(), [b'D', b'N', b'F', b'I', 1, 0, 0x03, 0x02, 4, 5, 0, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn parse_finds_the_block_at_0x200() {
        let mut image = [0xAAu8; 0x300];
        image[INFO_OFFSET..INFO_OFFSET + INFO_LEN].copy_from_slice(&INFO.to_bytes());
        assert_eq!(ImageInfo::parse(&image), Ok(INFO));
        // Only the block is needed, not the rest of the image.
        assert_eq!(ImageInfo::parse(&image[..INFO_OFFSET + INFO_LEN]), Ok(INFO));
    }

    #[rstest]
    #[case::magic(0, b'X', InfoError::BadMagic)]
    #[case::format(4, 2, InfoError::UnknownFormat(2))]
    #[case::reserved_5(5, 1, InfoError::ReservedNotZero { offset: 5 })]
    #[case::reserved_15(15, 0x80, InfoError::ReservedNotZero { offset: 15 })]
    fn parse_refuses_a_damaged_block(#[case] offset: usize, #[case] byte: u8, #[case] error: InfoError) {
        let mut block = INFO.to_bytes();
        block[offset] = byte;
        assert_eq!(ImageInfo::from_bytes(&block), Err(error));
    }

    #[test]
    fn parse_refuses_a_short_image() {
        let image = [0u8; INFO_OFFSET + INFO_LEN - 1];
        assert_eq!(ImageInfo::parse(&image), Err(InfoError::TooShort { len: INFO_OFFSET + INFO_LEN - 1 }));
    }
}
