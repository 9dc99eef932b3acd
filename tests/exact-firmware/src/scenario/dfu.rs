//! What the update scenarios share (issue 31): a firmware ELF as the flat image sign-firmware
//! makes, signed with the repository's TEST key, placed in DFU with its trailer and STATE set to
//! SWAP as the update object's Apply leaves them; the bus driven to an instant; STATE and ACTIVE
//! read back.

use super::world::Handle;
use crate::device::{EmulatedBoard, Firmware};
use board::flash_layout::{ACTIVE, DFU, MAX_IMAGE_LEN, STATE};
use board::memory::FLASH_BASE;
use devicenet::Instant;
use master_core::session::Session;
use master_core::update::UpdateFile;

/// The repository's TEST signing seed (contrib/keys/README.md: never for a release).
pub const TEST_SEED: &[u8; 32] = include_bytes!("../../../../contrib/keys/test-ed25519.secret");
/// Its public key: the bootloaders' of scripts/exact-firmware, and the update client's check
/// before sending.
pub const TEST_PUBLIC_KEY: &[u8; 32] = include_bytes!("../../../../contrib/keys/test-ed25519.public");
/// embassy-boot's STATE magics (embassy-boot 0.7 `lib.rs`).
pub const SWAP_MAGIC: u8 = 0xF0;
/// STATE after a confirmation or a cancelled request.
pub const BOOT_MAGIC: u8 = 0xD0;
/// STATE after a revert.
pub const REVERT_MAGIC: u8 = 0xC0;

/// The flat image of a firmware ELF from ACTIVE's start (gaps 0xFF), as sign-firmware makes it.
pub fn flat_image(elf: &[u8]) -> Result<Vec<u8>, String> {
    let segments = stm32_emu::cpu::elf::load_segments(elf).map_err(|e| format!("the firmware ELF: {e}"))?;
    let mut image = Vec::new();
    for (address, data) in segments {
        let Some(offset) = address.checked_sub(ACTIVE.base).map(|o| o as usize) else {
            return Err(format!("a segment at {address:#010x} below ACTIVE"));
        };
        if image.len() < offset + data.len() {
            image.resize(offset + data.len(), 0xFF);
        }
        image[offset..offset + data.len()].copy_from_slice(data);
    }
    Ok(image)
}

/// The update the scenarios send over the bus: the board's build at another revision
/// (`<elf>-newer`), signed with the TEST key.
pub struct NewerFile {
    /// The flat image.
    pub image: Vec<u8>,
    /// Its trailer.
    pub trailer: fw_image::Trailer,
    /// The signed file, image and trailer, as `dnet-master firmware-update` reads it.
    pub file: UpdateFile,
}

/// [`NewerFile`] of `elf`: fails without `<elf>-newer` (scripts/exact-firmware builds it) or when
/// that build is not this board's at another revision than the firmware's.
pub fn newer_file(elf: &Firmware) -> Result<NewerFile, String> {
    let Some(newer) = &elf.newer else {
        return Err("no build at another revision beside the firmware ELF (<elf>-newer, scripts/exact-firmware builds it)".into());
    };
    let image = flat_image(newer)?;
    let old = flat_image(&elf.elf)?;
    match (fw_image::ImageInfo::parse(&old), fw_image::ImageInfo::parse(&image)) {
        (Ok(o), Ok(n)) if o.board_id == n.board_id && o.revision != n.revision => {}
        other => return Err(format!("the newer build must be this board's at another revision: {other:?}")),
    }
    let trailer = test_signed(&image)?;
    let mut bytes = image.clone();
    bytes.extend_from_slice(&trailer.to_bytes());
    let file = UpdateFile::parse("newer.bin", bytes).map_err(|e| format!("the signed file: {e}"))?;
    Ok(NewerFile { image, trailer, file })
}

/// `image` signed with the TEST key: its trailer.
pub fn test_signed(image: &[u8]) -> Result<fw_image::Trailer, String> {
    fw_image::sign(image, TEST_SEED).map_err(|e| format!("signing: {e}"))
}

/// Places `image` and its `trailer` in DFU and sets STATE to SWAP (a board not powered yet).
pub fn place_in_dfu(device: &mut EmulatedBoard, image: &[u8], trailer: &[u8]) -> Result<(), String> {
    let mcu = device.mcu();
    let dfu = DFU.base - FLASH_BASE;
    mcu.program_flash(dfu, image).map_err(|e| format!("DFU: {e}"))?;
    mcu.program_flash(dfu + MAX_IMAGE_LEN, trailer).map_err(|e| format!("the trailer: {e}"))?;
    mcu.program_flash(STATE.base - FLASH_BASE, &[SWAP_MAGIC; 4]).map_err(|e| format!("STATE: {e}"))
}

/// Runs the bus (and the board on it) to `until`, or until nothing is left to happen.
pub fn run_until(session: &mut Session<'_>, until: Instant) -> Result<(), String> {
    while session.now() < until {
        if session.next(until).map_err(|e| format!("the bus: {e}"))?.is_none() {
            break;
        }
    }
    Ok(())
}

/// STATE's magic word.
pub fn state(handle: &Handle) -> Vec<u8> {
    handle.borrow().mcu_flash(STATE.base, 4)
}

/// Whether ACTIVE holds `image` byte for byte (the rest of the image's length).
pub fn active_holds(handle: &Handle, image: &[u8]) -> bool {
    handle.borrow().mcu_flash(ACTIVE.base, image.len()) == image
}

/// Whether DFU holds `image` byte for byte.
pub fn dfu_holds(handle: &Handle, image: &[u8]) -> bool {
    handle.borrow().mcu_flash(DFU.base, image.len()) == image
}

/// `image` with `info` in its image-info block (an image that differs from `image` only there).
pub fn with_info(image: &[u8], info: fw_image::ImageInfo) -> Vec<u8> {
    let mut changed = image.to_vec();
    let at = fw_image::INFO_OFFSET;
    if let Some(block) = changed.get_mut(at..at + fw_image::INFO_LEN) {
        block.copy_from_slice(&info.to_bytes());
    }
    changed
}

/// The board's own firmware image and the same image at the next minor revision (its image-info
/// block changed only), so that an image swapped in shows in ACTIVE.
pub fn old_and_newer(elf: &[u8]) -> Result<(Vec<u8>, Vec<u8>), String> {
    let old = flat_image(elf)?;
    let info =
        fw_image::ImageInfo::parse(&old).map_err(|e| format!("the firmware's image-info block: {e}"))?;
    let revision = fw_image::Revision { minor: info.revision.minor.wrapping_add(1), ..info.revision };
    let newer = with_info(&old, fw_image::ImageInfo { revision, ..info });
    Ok((old, newer))
}

/// The board on a FLASH model with `FlashTiming::FAST` (the datasheet's program time, a
/// thousandth of its erase times): the swap's four 128 KiB erases take milliseconds of emulated
/// time instead of seconds (which the core spends stalled, as code in flash is on the chip).
pub fn fast_flash_board(
    board: crate::board::BoardKind,
    elf: &crate::device::Firmware,
    options: &super::world::Options,
    cut: Option<(u64, stm32_emu::flash::CutKind)>,
) -> Result<EmulatedBoard, String> {
    let mut flash = stm32_emu::flash::Flash::new().with_timing(stm32_emu::flash::FlashTiming::FAST);
    if let Some((operation, kind)) = cut {
        flash.plan_power_cut(operation, kind);
    }
    EmulatedBoard::with_flash(board, elf, options.setting, options.bus_rate, flash)
        .map_err(|e| format!("the machine: {e}"))
}
