//! The signed-file trailer: the 128 bytes after the flat binary in a signed firmware file.
//!
//! On the device the trailer is stored in the last 128 bytes of the DFU's first sector, where
//! the bootloader reads it; the swap carries it into ACTIVE (the design page "The image and its
//! signature"). It is not itself signed: the signature covers the image, and the image's own
//! [`ImageInfo`](crate::ImageInfo) block is what a check trusts for the board and revision.
//!
//! Layout, [`TRAILER_LEN`] bytes, integers little-endian:
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `DNFW` |
//! | 4 | 1 | format version ([`TRAILER_FORMAT`]) |
//! | 5 | 3 | reserved, 0 |
//! | 8 | 4 | image length (UDINT), 1 ..= [`MAX_IMAGE_LEN`] |
//! | 12 | 2 | board ID (UINT) |
//! | 14 | 1 | firmware revision, major |
//! | 15 | 1 | firmware revision, minor |
//! | 16 | 8 | key ID ([`KeyId`]) |
//! | 24 | 64 | Ed25519 signature over SHA-512(image) |
//! | 88 | 40 | zero padding |
//!
//! Parsing never panics.

use crate::{KeyId, Revision, MAX_IMAGE_LEN};

/// The trailer's length in bytes.
pub const TRAILER_LEN: usize = 128;
/// The trailer's magic.
pub const TRAILER_MAGIC: [u8; 4] = *b"DNFW";
/// The format version this crate writes and reads.
pub const TRAILER_FORMAT: u8 = 1;

/// Where the zero padding starts.
const PADDING_AT: usize = 88;

/// A signed file's trailer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trailer {
    /// The length of the image (the flat binary) in bytes.
    pub image_len: u32,
    /// The board the image is for (a copy of its image-info block's).
    pub board_id: u16,
    /// The image's firmware revision (a copy of its image-info block's).
    pub revision: Revision,
    /// The ID of the key that signed the image.
    pub key_id: KeyId,
    /// The Ed25519 signature over SHA-512(image).
    pub signature: [u8; 64],
}

/// Why 128 bytes are not a valid trailer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum TrailerError {
    /// The trailer is not 128 bytes long.
    #[error("a trailer is 128 bytes, not {0}")]
    WrongLength(usize),
    /// The first four bytes are not `DNFW`.
    #[error("not a signed firmware file: the trailer's magic is not DNFW")]
    BadMagic,
    /// A format version this crate does not know.
    #[error("trailer format {0} is not known (this build reads format 1)")]
    UnknownFormat(u8),
    /// The image length is 0 or above [`MAX_IMAGE_LEN`].
    #[error("the trailer's image length {0} is outside 1..=130944")]
    ImageLength(u32),
    /// A reserved or padding byte is not zero.
    #[error("trailer byte {offset} is reserved and must be 0")]
    ReservedNotZero {
        /// The byte's offset in the trailer.
        offset: usize,
    },
}

impl Trailer {
    /// The trailer's bytes.
    #[must_use]
    pub fn to_bytes(&self) -> [u8; TRAILER_LEN] {
        let fields = TRAILER_MAGIC
            .into_iter()
            .chain([TRAILER_FORMAT, 0, 0, 0])
            .chain(self.image_len.to_le_bytes())
            .chain(self.board_id.to_le_bytes())
            .chain([self.revision.major, self.revision.minor])
            .chain(self.key_id.0)
            .chain(self.signature);
        // The rest, from PADDING_AT on, stays zero.
        let mut out = [0u8; TRAILER_LEN];
        for (to, from) in out.iter_mut().zip(fields) {
            *to = from;
        }
        out
    }

    /// Reads a trailer (exactly [`TRAILER_LEN`] bytes: the end of a signed file, or a Verify
    /// request's data).
    ///
    /// # Errors
    /// [`TrailerError`] naming the first thing wrong.
    pub fn parse(bytes: &[u8]) -> Result<Self, TrailerError> {
        let wrong_length = TrailerError::WrongLength(bytes.len());
        if bytes.len() != TRAILER_LEN {
            return Err(wrong_length);
        }
        let mut rest = bytes;
        let mut take = |n: usize| -> Result<&[u8], TrailerError> {
            let (head, tail) = rest.split_at_checked(n).ok_or(wrong_length)?;
            rest = tail;
            Ok(head)
        };
        let magic = take(4)?;
        let format = take(1)?;
        let reserved = take(3)?;
        let image_len = u32::from_le_bytes(array(take(4)?)?);
        let board_id = u16::from_le_bytes(array(take(2)?)?);
        let [major, minor] = array(take(2)?)?;
        let key_id = KeyId(array(take(8)?)?);
        let signature = array(take(64)?)?;
        let padding = take(TRAILER_LEN - PADDING_AT)?;
        if magic != TRAILER_MAGIC {
            return Err(TrailerError::BadMagic);
        }
        if format != [TRAILER_FORMAT] {
            return Err(TrailerError::UnknownFormat(format.first().copied().unwrap_or(0)));
        }
        let nonzero = |offset: usize| TrailerError::ReservedNotZero { offset };
        if let Some(i) = reserved.iter().position(|&b| b != 0) {
            return Err(nonzero(5 + i));
        }
        if let Some(i) = padding.iter().position(|&b| b != 0) {
            return Err(nonzero(PADDING_AT + i));
        }
        if image_len == 0 || image_len as usize > MAX_IMAGE_LEN {
            return Err(TrailerError::ImageLength(image_len));
        }
        Ok(Self { image_len, board_id, revision: Revision { major, minor }, key_id, signature })
    }
}

/// A slice of a length known to be `N` as an array.
fn array<const N: usize>(bytes: &[u8]) -> Result<[u8; N], TrailerError> {
    bytes.try_into().map_err(|_| TrailerError::WrongLength(bytes.len()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn trailer() -> Trailer {
        let mut signature = [0u8; 64];
        for (i, b) in signature.iter_mut().enumerate() {
            *b = i as u8 + 1;
        }
        Trailer {
            image_len: 0x0001_2345,
            board_id: 4,
            revision: Revision { major: 1, minor: 9 },
            key_id: KeyId([0xA0, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5, 0xA6, 0xA7]),
            signature,
        }
    }

    #[test]
    fn bytes_are_the_documented_layout() {
        let bytes = trailer().to_bytes();
        assert_eq!(&bytes[..16], b"DNFW\x01\0\0\0\x45\x23\x01\0\x04\0\x01\x09");
        assert_eq!(&bytes[16..24], &[0xA0, 0xA1, 0xA2, 0xA3, 0xA4, 0xA5, 0xA6, 0xA7]);
        assert_eq!(bytes[24], 1);
        assert_eq!(bytes[87], 64);
        assert!(bytes[88..].iter().all(|&b| b == 0));
    }

    #[test]
    fn parse_reads_what_to_bytes_wrote() {
        assert_eq!(Trailer::parse(&trailer().to_bytes()), Ok(trailer()));
    }

    #[rstest]
    #[case::magic(0, b'd', TrailerError::BadMagic)]
    #[case::format(4, 0, TrailerError::UnknownFormat(0))]
    #[case::reserved(7, 1, TrailerError::ReservedNotZero { offset: 7 })]
    #[case::padding(127, 1, TrailerError::ReservedNotZero { offset: 127 })]
    #[case::length_too_big(10, 0x02, TrailerError::ImageLength(0x0002_2345))]
    fn parse_refuses_a_damaged_trailer(#[case] offset: usize, #[case] byte: u8, #[case] error: TrailerError) {
        let mut bytes = trailer().to_bytes();
        bytes[offset] = byte;
        assert_eq!(Trailer::parse(&bytes), Err(error));
    }

    #[rstest]
    #[case::zero(0, false)]
    #[case::one(1, true)]
    #[case::largest(MAX_IMAGE_LEN as u32, true)]
    #[case::above(MAX_IMAGE_LEN as u32 + 1, false)]
    fn image_length_bounds(#[case] len: u32, #[case] ok: bool) {
        let mut t = trailer();
        t.image_len = len;
        let parsed = Trailer::parse(&t.to_bytes());
        if ok {
            assert_eq!(parsed, Ok(t));
        } else {
            assert_eq!(parsed, Err(TrailerError::ImageLength(len)));
        }
    }

    #[test]
    fn parse_refuses_a_wrong_length() {
        let bytes = trailer().to_bytes();
        assert_eq!(Trailer::parse(&bytes[..127]), Err(TrailerError::WrongLength(127)));
    }
}
