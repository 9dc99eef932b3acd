//! The check before a swap (the design page, "Where the image is checked"): embassy-boot's
//! `BootLoader` swaps whatever STATE asks for, so before `prepare_boot` the bootloader looks at
//! STATE itself and, when a swap is requested and not yet started, checks the image in DFU:
//! its trailer, its image-info block's board ID against this board's, and the Ed25519 signature
//! over SHA-512(image) with the bootloader's own key (`fw_image::verify_digest`). A refused image
//! is cancelled through `mark_booted` (STATE's BOOT magic), so the old image boots and nothing
//! unverified is ever swapped.
//!
//! Generic over `NorFlash`, so the host tests run it over flash in memory.

use embassy_boot::BlockingFirmwareState;
use embedded_storage::nor_flash::{NorFlash, NorFlashError, NorFlashErrorKind};
use fw_image::{
    ImageHasher, ImageInfo, InfoError, Trailer, TrailerError, VerifyError, INFO_LEN, INFO_OFFSET,
};

/// embassy-boot's STATE magic for a requested swap (embassy-boot 0.7 `SWAP_MAGIC`, private there).
pub const SWAP_MAGIC: u8 = 0xF0;
/// The value of erased flash.
const ERASED: u8 = 0xFF;

/// Where the signed file's trailer is kept in DFU: the last 128 bytes of its first page (design
/// page, "The image and its signature"; the swap carries it into ACTIVE with the image).
pub const TRAILER_OFFSET: u32 = board::flash_layout::MAX_IMAGE_LEN;

/// Bytes hashed per flash read.
const CHUNK: usize = 256;

/// Why a pending image was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refusal {
    /// A flash read failed.
    Flash(NorFlashErrorKind),
    /// No valid trailer at [`TRAILER_OFFSET`].
    Trailer(TrailerError),
    /// The image is too short for its image-info block.
    NoImageInfo,
    /// The image-info block is not valid.
    ImageInfo(InfoError),
    /// The image is for another board.
    AnotherBoard {
        /// The image-info block's board ID.
        image: u16,
    },
    /// The length, key or signature check failed.
    Verify(VerifyError),
}

/// What [`guard_swap`] found and did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Guard {
    /// No swap requested, or one already under way (its image was checked before it started):
    /// `prepare_boot` may run.
    NothingToCheck,
    /// A swap requested and the image in DFU checked: `prepare_boot` may swap it.
    Verified,
    /// The image was refused and the request cancelled (STATE holds BOOT): `prepare_boot` finds
    /// nothing to do.
    Cancelled(Refusal),
    /// The image was refused but STATE could not be rewritten: `prepare_boot` must not run.
    CancelFailed(Refusal),
}

/// Whether STATE asks for a swap that has not started: the SWAP magic, the progress marked valid
/// and the first progress word still erased (embassy-boot's STATE layout: magic, progress
/// validity, then one word per step; `WRITE_SIZE` bytes each).
///
/// # Errors
/// A failed read.
pub fn swap_requested_not_started<S: NorFlash>(state: &mut S) -> Result<bool, S::Error> {
    let mut word = [0u8; 16];
    let word = word.get_mut(..S::WRITE_SIZE).unwrap_or(&mut []);
    let size = S::WRITE_SIZE as u32;
    state.read(0, word)?;
    if word.is_empty() || word.iter().any(|&b| b != SWAP_MAGIC) {
        return Ok(false);
    }
    for index in [1, 2] {
        state.read(index * size, word)?;
        if word.iter().any(|&b| b != ERASED) {
            return Ok(false);
        }
    }
    Ok(true)
}

/// Checks the image in DFU: trailer, board, length, key and signature.
///
/// # Errors
/// The first check that failed.
pub fn check_dfu<D: NorFlash>(
    dfu: &mut D,
    public_key: &[u8; 32],
    board_id: u16,
) -> Result<ImageInfo, Refusal> {
    let flash = |e: D::Error| Refusal::Flash(e.kind());
    let mut trailer = [0u8; fw_image::TRAILER_LEN];
    dfu.read(TRAILER_OFFSET, &mut trailer).map_err(flash)?;
    let trailer = Trailer::parse(&trailer).map_err(Refusal::Trailer)?;
    let len = trailer.image_len;
    if (len as usize) < INFO_OFFSET + INFO_LEN || len > TRAILER_OFFSET {
        return Err(Refusal::NoImageInfo);
    }
    let mut info = [0u8; INFO_LEN];
    dfu.read(INFO_OFFSET as u32, &mut info).map_err(flash)?;
    let info = ImageInfo::from_bytes(&info).map_err(Refusal::ImageInfo)?;
    if info.board_id != board_id {
        return Err(Refusal::AnotherBoard { image: info.board_id });
    }
    let mut hasher = ImageHasher::new();
    let mut chunk = [0u8; CHUNK];
    let mut offset = 0;
    while offset < len {
        let n = (len - offset).min(CHUNK as u32) as usize;
        let bytes = chunk.get_mut(..n).unwrap_or(&mut []);
        dfu.read(offset, bytes).map_err(flash)?;
        hasher.update(bytes);
        offset += n as u32;
    }
    let (digest, hashed) = hasher.finalize();
    fw_image::verify_digest(&digest, hashed, &trailer, public_key).map_err(Refusal::Verify)?;
    Ok(info)
}

/// The step before `prepare_boot`: when a swap is requested and not started, checks DFU and
/// cancels a refused image (`mark_booted`). A failed STATE read counts as nothing to check:
/// `prepare_boot` reads the same word and fails the same way.
pub fn guard_swap<S: NorFlash, D: NorFlash>(
    state: &mut S,
    dfu: &mut D,
    public_key: &[u8; 32],
    board_id: u16,
) -> Guard {
    if !matches!(swap_requested_not_started(state), Ok(true)) {
        return Guard::NothingToCheck;
    }
    let refusal = match check_dfu(dfu, public_key, board_id) {
        Ok(_) => return Guard::Verified,
        Err(refusal) => refusal,
    };
    let mut aligned = [0u8; 16];
    let Some(aligned) = aligned.get_mut(..S::WRITE_SIZE) else {
        return Guard::CancelFailed(refusal);
    };
    match BlockingFirmwareState::new(state, aligned).mark_booted() {
        Ok(()) => Guard::Cancelled(refusal),
        Err(_) => Guard::CancelFailed(refusal),
    }
}

#[cfg(test)]
mod tests;
