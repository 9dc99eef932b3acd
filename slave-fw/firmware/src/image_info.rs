//! The firmware's image-info block (`fw_image::ImageInfo`: magic `DNFI`, board ID, firmware
//! revision), linked at `board::memory::IMAGE_INFO_OFFSET` from the image's start by memory.x's
//! `.image_info` section. The bootloader, the update object and `dnet-master firmware-update` read
//! an image's board and revision there (the design page, docs/src/development/firmware-update.md,
//! "The image and its signature").
//!
//! The revision is the firmware crate's Cargo version (major.minor), or the build-time variable
//! `DNET_FW_REVISION=MAJOR.MINOR` when set (build.rs checks both fit a USINT each); the board ID is
//! the selected board's (`board::boards`).

use fw_image::{ImageInfo, Revision, INFO_LEN, INFO_OFFSET};

// `REVISION`, written by build.rs.
include!(concat!(env!("OUT_DIR"), "/revision.rs"));

/// The block's content for this build.
pub const INFO: ImageInfo = ImageInfo { board_id: board::boards::BOARD_ID, revision: REVISION };

// memory.x places the section where fw-image looks for the block, with room for it.
const _: () = assert!(board::memory::IMAGE_INFO_OFFSET as usize == INFO_OFFSET);
const _: () = assert!(board::memory::IMAGE_INFO_LEN as usize == INFO_LEN);

/// The block itself, in the image.
#[cfg(target_os = "none")]
#[used]
#[allow(unsafe_code)] // #[link_section] (an unsafe attribute): memory.x places this section at 0x200
#[link_section = ".image_info"]
pub static IMAGE_INFO: [u8; INFO_LEN] = INFO.to_bytes();

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_block_parses_back() {
        let mut image = [0xFFu8; INFO_OFFSET + INFO_LEN];
        image[INFO_OFFSET..].copy_from_slice(&INFO.to_bytes());
        assert_eq!(ImageInfo::parse(&image), Ok(INFO));
    }

    #[test]
    fn the_revision_is_the_build_variable_or_the_crate_version() {
        let (major, minor) = match option_env!("DNET_FW_REVISION") {
            Some(v) => v.split_once('.').unwrap(),
            None => (env!("CARGO_PKG_VERSION_MAJOR"), env!("CARGO_PKG_VERSION_MINOR")),
        };
        assert_eq!((REVISION.major, REVISION.minor), (major.parse().unwrap(), minor.parse().unwrap()));
    }
}
