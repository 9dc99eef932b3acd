//! The flash layout of the firmware update (issue 31; the guide's "Firmware update over DeviceNet"
//! design page, section "Flash layout"): the same on every board but the emulated one, because
//! sectors 0–7 are the same on the STM32F405RG and the STM32F446RE (RM0090 §3.3 table 5, RM0390
//! §3.3).
//!
//! | sector | address | size | partition |
//! |---|---|---|---|
//! | 0 | 0x0800_0000 | 16 KiB | [`BOOTLOADER`]; its last 64 bytes the [`KeyBlock`] |
//! | 1–2 | 0x0800_4000 | 2 × 16 KiB | [`SETTINGS`], the settings journal's sectors A and B |
//! | 3 | 0x0800_C000 | 16 KiB | [`STATE`], embassy-boot's magic and swap progress |
//! | 4 | 0x0801_0000 | 64 KiB | [`RESERVED`] |
//! | 5 | 0x0802_0000 | 128 KiB | [`ACTIVE`], where the firmware is linked and runs |
//! | 6–7 | 0x0804_0000 | 2 × 128 KiB | [`DFU`]: the incoming image and the swap's spare page |
//!
//! embassy-boot's rules (its `assert_partitions`): the page is the larger of ACTIVE's and DFU's
//! erase size (here 128 KiB); ACTIVE and DFU are multiples of it, DFU at least one page bigger
//! than ACTIVE; STATE holds `2 + 4N` words for N pages of ACTIVE. The host tests check them, and
//! the bootloader's `prepare_boot` asserts them again at run time.

/// Start of the flash array.
pub const FLASH_BASE: u32 = 0x0800_0000;

/// A run of flash sectors.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Partition {
    /// Its first byte's address.
    pub base: u32,
    /// Its size in bytes.
    pub size: u32,
    /// Its first sector's number (the erase command's SNB).
    pub first_sector: u8,
    /// How many sectors it spans.
    pub sectors: u8,
}

impl Partition {
    /// The address one past its last byte.
    pub const fn end(&self) -> u32 {
        self.base + self.size
    }

    /// Whether `address` lies in it.
    pub const fn contains(&self, address: u32) -> bool {
        address >= self.base && address < self.end()
    }
}

/// Sector 0: the bootloader, at the reset vector.
pub const BOOTLOADER: Partition =
    Partition { base: 0x0800_0000, size: 16 * 1024, first_sector: 0, sectors: 1 };
/// Sectors 1 and 2: the settings journal's sectors A and B.
pub const SETTINGS: [Partition; 2] = [
    Partition { base: 0x0800_4000, size: 16 * 1024, first_sector: 1, sectors: 1 },
    Partition { base: 0x0800_8000, size: 16 * 1024, first_sector: 2, sectors: 1 },
];
/// Sector 3: embassy-boot's STATE partition.
pub const STATE: Partition = Partition { base: 0x0800_C000, size: 16 * 1024, first_sector: 3, sectors: 1 };
/// Sector 4: unused (neither page size fits it).
pub const RESERVED: Partition = Partition { base: 0x0801_0000, size: 64 * 1024, first_sector: 4, sectors: 1 };
/// Sector 5: the running firmware.
pub const ACTIVE: Partition = Partition { base: 0x0802_0000, size: 128 * 1024, first_sector: 5, sectors: 1 };
/// Sectors 6 and 7: the incoming image (sector 6) and the swap's spare page (sector 7).
pub const DFU: Partition = Partition { base: 0x0804_0000, size: 256 * 1024, first_sector: 6, sectors: 2 };

/// Erase size of the 16 KiB sectors 0–3 (STATE's `NorFlash::ERASE_SIZE`).
pub const SMALL_SECTOR_SIZE: u32 = 16 * 1024;
/// Erase size of the 128 KiB sectors from 5 on (ACTIVE's and DFU's `NorFlash::ERASE_SIZE`).
pub const LARGE_SECTOR_SIZE: u32 = 128 * 1024;
/// The driver's write unit: one 32-bit word (PSIZE x32, RM0090 §3.5.2).
pub const WRITE_SIZE: u32 = 4;

/// Which of embassy-boot's partition rules (its `assert_partitions`, and its page alignment) a
/// layout breaks, `None` when it meets them all: ACTIVE and DFU aligned to and multiples of the
/// page, DFU at least one page bigger than ACTIVE, STATE aligned to its erase size and holding
/// `2 + 4N` words of `write_size` for N pages of ACTIVE.
pub const fn embassy_boot_rule_broken(
    active: Partition,
    dfu: Partition,
    state: Partition,
    page: u32,
    state_erase_size: u32,
    write_size: u32,
) -> Option<&'static str> {
    if active.base % page != 0 || active.size % page != 0 {
        Some("ACTIVE is not whole pages")
    } else if dfu.base % page != 0 || dfu.size % page != 0 {
        Some("DFU is not whole pages")
    } else if dfu.size < active.size + page {
        Some("DFU is not one page bigger than ACTIVE")
    } else if state.base % state_erase_size != 0 || state.size % state_erase_size != 0 {
        Some("STATE is not whole sectors")
    } else if 2 + 4 * (active.size / page) > state.size / write_size {
        Some("STATE holds fewer than 2 + 4N words")
    } else if page % write_size != 0 {
        Some("the page is not whole words")
    } else {
        None
    }
}

// The layout meets embassy-boot's rules, checked at every build (the bootloader's `prepare_boot`
// asserts them again at run time).
const _: () =
    assert!(embassy_boot_rule_broken(ACTIVE, DFU, STATE, LARGE_SECTOR_SIZE, SMALL_SECTOR_SIZE, WRITE_SIZE)
        .is_none());

/// The signed file's trailer, stored in the last bytes of the image's slot.
pub const TRAILER_LEN: u32 = 128;
/// The largest image: ACTIVE less the trailer, 130,944 bytes.
pub const MAX_IMAGE_LEN: u32 = ACTIVE.size - TRAILER_LEN;

/// Length of the key block at the end of [`BOOTLOADER`].
pub const KEY_BLOCK_LEN: usize = 64;
/// Address of the key block: the last [`KEY_BLOCK_LEN`] bytes of sector 0.
pub const KEY_BLOCK_ADDRESS: u32 = BOOTLOADER.end() - KEY_BLOCK_LEN as u32;

/// The sector of the array's first eight (the same on both chips) that holds `address`.
pub const fn sector_of(address: u32) -> Option<Partition> {
    if address < FLASH_BASE {
        return None;
    }
    let offset = address - FLASH_BASE;
    if offset < 0x1_0000 {
        let n = offset / SMALL_SECTOR_SIZE;
        Some(Partition {
            base: FLASH_BASE + n * SMALL_SECTOR_SIZE,
            size: SMALL_SECTOR_SIZE,
            first_sector: n as u8,
            sectors: 1,
        })
    } else if offset < 0x2_0000 {
        Some(RESERVED)
    } else if offset < 0x10_0000 / 2 {
        let n = (offset - 0x2_0000) / LARGE_SECTOR_SIZE;
        Some(Partition {
            base: ACTIVE.base + n * LARGE_SECTOR_SIZE,
            size: LARGE_SECTOR_SIZE,
            first_sector: 5 + n as u8,
            sectors: 1,
        })
    } else {
        None
    }
}

/// The bootloader's key block: the last 64 bytes of sector 0, written with the bootloader, read by
/// the firmware (the key its update object checks with, the board it accepts).
///
/// | offset | size | field |
/// |---|---|---|
/// | 0 | 32 | the Ed25519 public key |
/// | 32 | 2 | the board ID (UINT, little-endian) |
/// | 34 | 2 | the bootloader's revision (major, minor) |
/// | 36 | 24 | reserved, 0 |
/// | 60 | 4 | CRC-32 (IEEE, as `devicenet::crc32`) of bytes 0–59, little-endian |
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyBlock {
    /// The public key every image must be signed for.
    pub public_key: [u8; 32],
    /// The board ID the bootloader accepts.
    pub board_id: u16,
    /// The bootloader's revision, (major, minor).
    pub revision: (u8, u8),
}

/// Why the bytes at [`KEY_BLOCK_ADDRESS`] are not a key block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum KeyBlockError {
    /// The CRC does not match (no bootloader, or another layout).
    BadCrc,
    /// A reserved byte is not 0.
    ReservedNotZero,
}

impl core::fmt::Display for KeyBlockError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            KeyBlockError::BadCrc => f.write_str("the key block's CRC-32 does not match"),
            KeyBlockError::ReservedNotZero => f.write_str("a reserved byte of the key block is not 0"),
        }
    }
}

/// The CRC-32 of [`KeyBlock`], as a `const`, so that the bootloader's block is built at compile
/// time (the same CRC as `devicenet::crc32`; a test checks they agree).
const KEY_BLOCK_CRC: crc::Crc<u32, crc::NoTable> = crc::Crc::<u32, crc::NoTable>::new(&crc::CRC_32_ISO_HDLC);

impl KeyBlock {
    /// The block's 64 bytes (a `const fn`: the bootloader places them by a linker section).
    pub const fn to_bytes(&self) -> [u8; KEY_BLOCK_LEN] {
        let mut bytes = [0u8; KEY_BLOCK_LEN];
        let mut i = 0;
        while i < 32 {
            bytes[i] = self.public_key[i];
            i += 1;
        }
        let board = self.board_id.to_le_bytes();
        bytes[32] = board[0];
        bytes[33] = board[1];
        bytes[34] = self.revision.0;
        bytes[35] = self.revision.1;
        let (covered, _) = bytes.split_at(KEY_BLOCK_LEN - 4);
        let crc = KEY_BLOCK_CRC.checksum(covered).to_le_bytes();
        bytes[60] = crc[0];
        bytes[61] = crc[1];
        bytes[62] = crc[2];
        bytes[63] = crc[3];
        bytes
    }

    /// Reads a block.
    ///
    /// # Errors
    /// [`KeyBlockError`] when the CRC or a reserved byte is wrong.
    pub fn parse(bytes: &[u8; KEY_BLOCK_LEN]) -> Result<KeyBlock, KeyBlockError> {
        let (covered, crc) = bytes.split_at(KEY_BLOCK_LEN - 4);
        let crc = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
        if devicenet::crc32::crc32(covered) != crc {
            return Err(KeyBlockError::BadCrc);
        }
        if covered[36..].iter().any(|&b| b != 0) {
            return Err(KeyBlockError::ReservedNotZero);
        }
        let mut public_key = [0u8; 32];
        public_key.copy_from_slice(&covered[..32]);
        Ok(KeyBlock {
            public_key,
            board_id: u16::from_le_bytes([covered[32], covered[33]]),
            revision: (covered[34], covered[35]),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boards::{ALL, EMULATED_BOARD_ID};

    /// embassy-boot's page: the larger of ACTIVE's and DFU's erase size.
    const PAGE: u32 = LARGE_SECTOR_SIZE;

    #[test]
    fn partitions_meet_embassy_boots_rules() {
        let rule = |active, dfu, state| {
            embassy_boot_rule_broken(active, dfu, state, PAGE, SMALL_SECTOR_SIZE, WRITE_SIZE)
        };
        assert_eq!(rule(ACTIVE, DFU, STATE), None);
        // And the check can fail: each rule broken once.
        let same_size_dfu = Partition { size: ACTIVE.size, ..DFU };
        assert_eq!(rule(ACTIVE, same_size_dfu, STATE), Some("DFU is not one page bigger than ACTIVE"));
        let active_in_sector_4 = Partition { base: RESERVED.base, ..ACTIVE };
        assert_eq!(rule(active_in_sector_4, DFU, STATE), Some("ACTIVE is not whole pages"));
        let dfu_of_small_sectors = Partition { size: DFU.size + SMALL_SECTOR_SIZE, ..DFU };
        assert_eq!(rule(ACTIVE, dfu_of_small_sectors, STATE), Some("DFU is not whole pages"));
        let tiny_state = Partition { size: 16, ..STATE };
        assert_eq!(rule(ACTIVE, DFU, tiny_state), Some("STATE is not whole sectors"));
        // STATE's 16 KiB hold 4,096 words: 2 + 4N words for up to 1,023 pages of ACTIVE.
        let huge_active = Partition { size: 1024 * PAGE, ..ACTIVE };
        let huge_dfu = Partition { size: 1025 * PAGE, ..DFU };
        assert_eq!(rule(huge_active, huge_dfu, STATE), Some("STATE holds fewer than 2 + 4N words"));
    }

    #[test]
    fn partitions_are_whole_sectors_in_order_without_overlap() {
        let order = [BOOTLOADER, SETTINGS[0], SETTINGS[1], STATE, RESERVED, ACTIVE, DFU];
        for pair in order.windows(2) {
            assert_eq!(pair[0].end(), pair[1].base, "{pair:?}");
            assert_eq!(pair[0].first_sector + pair[0].sectors, pair[1].first_sector, "{pair:?}");
        }
        for p in order {
            let first = sector_of(p.base).unwrap();
            assert_eq!(first.base, p.base, "{p:?}");
            assert_eq!(first.first_sector, p.first_sector, "{p:?}");
            let last = sector_of(p.end() - 1).unwrap();
            assert_eq!(last.end(), p.end(), "{p:?}");
            assert_eq!(last.first_sector, p.first_sector + p.sectors - 1, "{p:?}");
        }
        // The F446RE's 512 KiB end with DFU.
        assert_eq!(DFU.end(), FLASH_BASE + 512 * 1024);
        assert_eq!(sector_of(DFU.end()), None);
        assert_eq!(sector_of(FLASH_BASE - 1), None);
    }

    #[test]
    fn sector_table_is_rm0090s() {
        let bases: [(u32, u32); 8] = [
            (0x0800_0000, 16),
            (0x0800_4000, 16),
            (0x0800_8000, 16),
            (0x0800_C000, 16),
            (0x0801_0000, 64),
            (0x0802_0000, 128),
            (0x0804_0000, 128),
            (0x0806_0000, 128),
        ];
        for (n, (base, kib)) in bases.into_iter().enumerate() {
            let s = sector_of(base).unwrap();
            assert_eq!((s.first_sector as usize, s.base, s.size), (n, base, kib * 1024));
            assert_eq!(sector_of(base + kib * 1024 - 1), Some(s));
        }
    }

    #[test]
    fn largest_image_and_key_block() {
        assert_eq!(MAX_IMAGE_LEN, 130_944);
        assert_eq!(KEY_BLOCK_ADDRESS, 0x0800_3FC0);
    }

    #[test]
    fn board_ids_are_the_decided_ones_and_distinct() {
        let ids: std::vec::Vec<_> = ALL.iter().map(|b| (b.feature, b.board_id)).collect();
        assert_eq!(
            ids,
            [("reference", 1), ("olimex-p405", 2), ("olimex-p405-rs485", 3), ("nucleo-f446re", 4)]
        );
        assert_eq!(EMULATED_BOARD_ID, 5);
    }

    #[test]
    fn key_block_round_trips_and_its_crc_is_devicenets() {
        let block = KeyBlock { public_key: [0xA5; 32], board_id: 0x0104, revision: (2, 7) };
        let bytes = block.to_bytes();
        assert_eq!(&bytes[32..36], &[0x04, 0x01, 2, 7]);
        assert_eq!(&bytes[60..], &devicenet::crc32::crc32(&bytes[..60]).to_le_bytes());
        assert_eq!(KeyBlock::parse(&bytes), Ok(block));
    }

    #[test]
    fn key_block_refuses_erased_flash_a_flipped_bit_and_reserved_bytes() {
        assert_eq!(KeyBlock::parse(&[0xFF; KEY_BLOCK_LEN]), Err(KeyBlockError::BadCrc));
        let block = KeyBlock { public_key: [1; 32], board_id: 4, revision: (1, 0) };
        let mut bytes = block.to_bytes();
        bytes[5] ^= 1;
        assert_eq!(KeyBlock::parse(&bytes), Err(KeyBlockError::BadCrc));
        let mut bytes = block.to_bytes();
        bytes[40] = 1;
        let crc = devicenet::crc32::crc32(&bytes[..60]).to_le_bytes();
        bytes[60..].copy_from_slice(&crc);
        assert_eq!(KeyBlock::parse(&bytes), Err(KeyBlockError::ReservedNotZero));
    }
}
