//! A signed firmware file (the image followed by its 128-byte trailer, `fw_image`'s formats) and
//! the checks the master makes against the device before it sends a byte (the design page, "Where
//! the image is checked", the dnet-master column).

use super::{DeviceInfo, CHUNK_SIZE};
use fw_image::{
    ImageHasher, ImageInfo, InfoError, KeyId, Revision, Trailer, TrailerError, VerifyError, TRAILER_LEN,
};

/// A signed firmware file, read and taken apart; its parts agree with each other
/// ([`UpdateFile::parse`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UpdateFile {
    /// The file's name, for messages.
    pub name: String,
    /// The image (the flat binary) and the trailer, as in the file.
    bytes: Vec<u8>,
    /// The trailer.
    pub trailer: Trailer,
    /// The image's image-info block.
    pub info: ImageInfo,
    /// The image ID announced with Update: the first 8 bytes of SHA-512 of the whole file.
    pub image_id: [u8; 8],
    /// The board ID (the trailer's; [`UpdateFile::parse`] checked it is the image-info block's).
    pub board_id: u16,
    /// The firmware revision (the image-info block's).
    pub revision: Revision,
}

/// Why a file is not sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum FileError {
    /// Shorter than a trailer and one image byte.
    #[error("{len} bytes: a signed firmware file is an image followed by a 128-byte trailer")]
    TooShort {
        /// The file's length.
        len: usize,
    },
    /// The last 128 bytes are not a trailer.
    #[error("the trailer (the last 128 bytes): {0}")]
    Trailer(TrailerError),
    /// The trailer's length is not the image's.
    #[error("the trailer says the image is {trailer} bytes, the file holds {image} before it")]
    Length {
        /// The trailer's.
        trailer: u32,
        /// The image's.
        image: usize,
    },
    /// The image has no valid image-info block.
    #[error("the image: {0}")]
    Info(InfoError),
    /// The trailer's copies of the board and revision are not the image-info block's.
    #[error("the trailer names board {trailer_board} revision {trailer_revision}, the image-info block board {info_board} revision {info_revision}")]
    Disagree {
        /// The trailer's board.
        trailer_board: u16,
        /// The trailer's revision.
        trailer_revision: Revision,
        /// The block's board.
        info_board: u16,
        /// The block's revision.
        info_revision: Revision,
    },
    /// The file is for another board than the device (`which`: the trailer or the image-info
    /// block).
    #[error("the {which} names board {file}; the device is board {device}")]
    AnotherBoard {
        /// Which part of the file.
        which: &'static str,
        /// The file's board.
        file: u16,
        /// The device's (attribute 7).
        device: u16,
    },
    /// The image is larger than the device takes.
    #[error("the image is {len} bytes; the device takes at most {max} (attribute 6)")]
    TooLarge {
        /// The image's length.
        len: u32,
        /// The device's attribute 6.
        max: u32,
    },
    /// Signed with another key than the device's bootloader carries.
    #[error("signed with key {file}; the device's bootloader checks key {device} (attribute 8)")]
    AnotherKey {
        /// The trailer's key ID.
        file: KeyId,
        /// The device's.
        device: KeyId,
    },
    /// The signature does not verify with the public key given.
    #[error("the signature does not verify with the public key given: {0}")]
    Signature(VerifyError),
}

impl UpdateFile {
    /// Takes `bytes` (a whole signed file named `name`) apart: the trailer, its length against
    /// the image's, the image-info block, the trailer's copies against the block.
    ///
    /// # Errors
    ///
    /// [`FileError`] naming the first thing wrong.
    pub fn parse(name: &str, bytes: Vec<u8>) -> Result<UpdateFile, FileError> {
        if bytes.len() <= TRAILER_LEN {
            return Err(FileError::TooShort { len: bytes.len() });
        }
        let split = bytes.len() - TRAILER_LEN;
        let (image, tail) = bytes.split_at(split);
        let trailer = Trailer::parse(tail).map_err(FileError::Trailer)?;
        if trailer.image_len as usize != image.len() {
            return Err(FileError::Length { trailer: trailer.image_len, image: image.len() });
        }
        let info = ImageInfo::parse(image).map_err(FileError::Info)?;
        if info.board_id != trailer.board_id || info.revision != trailer.revision {
            return Err(FileError::Disagree {
                trailer_board: trailer.board_id,
                trailer_revision: trailer.revision,
                info_board: info.board_id,
                info_revision: info.revision,
            });
        }
        let mut hasher = ImageHasher::new();
        hasher.update(&bytes);
        let (digest, _) = hasher.finalize();
        let mut image_id = [0u8; 8];
        image_id.copy_from_slice(&digest[..8]);
        Ok(UpdateFile {
            name: name.to_string(),
            board_id: trailer.board_id,
            revision: info.revision,
            bytes,
            trailer,
            info,
            image_id,
        })
    }

    /// The image (the flat binary, without the trailer).
    pub fn image(&self) -> &[u8] {
        &self.bytes[..self.bytes.len() - TRAILER_LEN]
    }

    /// The trailer's bytes as in the file (Verify's data).
    pub fn trailer_bytes(&self) -> &[u8] {
        &self.bytes[self.bytes.len() - TRAILER_LEN..]
    }

    /// The image's length (the trailer's, checked).
    pub fn image_len(&self) -> u32 {
        self.trailer.image_len
    }

    /// Chunks of [`CHUNK_SIZE`] bytes in the image (the last one may be shorter).
    pub fn chunks(&self) -> u32 {
        u32::try_from(self.image().len().div_ceil(CHUNK_SIZE)).unwrap_or(u32::MAX)
    }

    /// Chunk `n` (empty past the end).
    pub fn chunk(&self, n: u32) -> &[u8] {
        self.image().chunks(CHUNK_SIZE).nth(n as usize).unwrap_or(&[])
    }
}

/// The master's checks of `file` against the device (`device`, read from it) before anything is
/// sent: the board ID of the trailer and of the image-info block against attribute 7, the length
/// against attribute 6, the key ID against attribute 8, and, with `public_key` (the release's),
/// the signature.
///
/// # Errors
///
/// The first check that failed, in that order.
pub fn check_file(
    file: &UpdateFile,
    device: &DeviceInfo,
    public_key: Option<&[u8; 32]>,
) -> Result<(), FileError> {
    for (which, board) in [("trailer", file.trailer.board_id), ("image-info block", file.info.board_id)] {
        if board != device.board_id {
            return Err(FileError::AnotherBoard { which, file: board, device: device.board_id });
        }
    }
    if file.image_len() > device.largest_image {
        return Err(FileError::TooLarge { len: file.image_len(), max: device.largest_image });
    }
    if file.trailer.key_id.0 != device.key_id {
        return Err(FileError::AnotherKey { file: file.trailer.key_id, device: KeyId(device.key_id) });
    }
    if let Some(key) = public_key {
        fw_image::verify(file.image(), &file.trailer, key).map_err(FileError::Signature)?;
    }
    Ok(())
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::update::DeviceState;
    use rstest::rstest;

    const SEED: [u8; 32] = [7; 32];

    /// A signed file of `len` image bytes for `board` revision 2.3.
    pub(crate) fn signed(len: usize, board: u16) -> Vec<u8> {
        let mut image: Vec<u8> = (0..len).map(|i| (i * 7 + 3) as u8).collect();
        let info = ImageInfo { board_id: board, revision: Revision { major: 2, minor: 3 } };
        image[fw_image::INFO_OFFSET..fw_image::INFO_OFFSET + fw_image::INFO_LEN]
            .copy_from_slice(&info.to_bytes());
        let trailer = fw_image::sign(&image, &SEED).unwrap();
        image.extend_from_slice(&trailer.to_bytes());
        image
    }

    fn public() -> [u8; 32] {
        *salty::Keypair::from(&SEED).public.as_bytes()
    }

    fn device(board: u16) -> DeviceInfo {
        DeviceInfo {
            board_id: board,
            largest_image: 130_944,
            key_id: KeyId::of(&public()).0,
            state: DeviceState::Idle,
            revision: Revision { major: 1, minor: 0 },
            identity_revision: Revision { major: 1, minor: 1 },
        }
    }

    #[test]
    fn a_signed_file_parses_into_its_chunks() {
        let file = UpdateFile::parse("f.bin", signed(1000, 5)).unwrap();
        assert_eq!(file.image_len(), 1000);
        assert_eq!(file.chunks(), 8);
        assert_eq!(file.chunk(7).len(), 1000 - 7 * 128);
        assert_eq!(file.chunk(8), &[] as &[u8]);
        assert_eq!(file.revision, Revision { major: 2, minor: 3 });
        assert_eq!(check_file(&file, &device(5), Some(&public())), Ok(()));
    }

    #[rstest]
    #[case::short(|f: &mut Vec<u8>| f.truncate(128), FileError::TooShort { len: 128 })]
    #[case::no_trailer(|f: &mut Vec<u8>| { let n = f.len(); f[n - 128] = b'X'; }, FileError::Trailer(TrailerError::BadMagic))]
    #[case::length(|f: &mut Vec<u8>| { f.insert(0, 0); }, FileError::Length { trailer: 1000, image: 1001 })]
    #[case::no_info(|f: &mut Vec<u8>| { f[0x200] = b'X'; }, FileError::Info(InfoError::BadMagic))]
    fn a_broken_file_is_refused(#[case] damage: fn(&mut Vec<u8>), #[case] error: FileError) {
        let mut bytes = signed(1000, 5);
        damage(&mut bytes);
        assert_eq!(UpdateFile::parse("f.bin", bytes), Err(error));
    }

    #[test]
    fn the_trailer_must_agree_with_the_image_info_block() {
        let mut bytes = signed(1000, 5);
        let at = 1000 + 12;
        bytes[at] = 6;
        let err = UpdateFile::parse("f.bin", bytes).unwrap_err();
        assert!(matches!(err, FileError::Disagree { trailer_board: 6, info_board: 5, .. }), "{err:?}");
    }

    #[test]
    fn another_board_another_key_too_large_and_a_bad_signature_are_refused() {
        let file = UpdateFile::parse("f.bin", signed(1000, 5)).unwrap();
        assert_eq!(
            check_file(&file, &device(1), None),
            Err(FileError::AnotherBoard { which: "trailer", file: 5, device: 1 })
        );
        let mut small = device(5);
        small.largest_image = 999;
        assert_eq!(check_file(&file, &small, None), Err(FileError::TooLarge { len: 1000, max: 999 }));
        let mut other_key = device(5);
        other_key.key_id = [1; 8];
        assert!(matches!(check_file(&file, &other_key, None), Err(FileError::AnotherKey { .. })));

        let mut bytes = signed(1000, 5);
        bytes[10] ^= 1;
        let flipped = UpdateFile::parse("f.bin", bytes).unwrap();
        assert_eq!(
            check_file(&flipped, &device(5), None),
            Ok(()),
            "without a key the signature is the device's"
        );
        assert_eq!(
            check_file(&flipped, &device(5), Some(&public())),
            Err(FileError::Signature(VerifyError::BadSignature))
        );
    }
}
