//! The memory map of the selected board's chip as the firmware uses it. `board/memory/<chip>.x`
//! says the same to the linker (build.rs ships the selected build's as `memory.x`); host tests
//! check every board's file against its [`FlashLayout`](crate::boards::FlashLayout) and
//! [`crate::flash_layout`].
//!
//! | region | STM32F405RG (reference, Olimex STM32-P405) | STM32F446RE (NUCLEO-F446RE) | emulated (QEMU) |
//! |---|---|---|---|
//! | bootloader | sector 0, 0x0800_0000, 16 KiB ([`crate::flash_layout::BOOTLOADER`]) | the same | none |
//! | settings sector A | sector 1, 0x0800_4000, 16 KiB | the same | a host file (`hw::HostFileFlash`) |
//! | settings sector B | sector 2, 0x0800_8000, 16 KiB | the same | the same file |
//! | STATE, reserved | sectors 3 and 4 ([`crate::flash_layout`]) | the same | – |
//! | program (`FLASH`) | ACTIVE, sector 5, 0x0802_0000: 128 KiB less the signed image's 128-byte trailer | the same | sectors 0–9 from 0x0800_0000, 768 KiB |
//! | DFU | sectors 6 and 7 | the same | – |
//! | the settings' old location, read once ([`OLD_SETTINGS_BASES`]) | sectors 10 and 11, 0x080C_0000, 2 × 128 KiB | sectors 6 and 7, 0x0804_0000, 2 × 128 KiB | – |
//! | `RAM` (SRAM1 + SRAM2) | 0x2000_0000, 128 KiB − 8 | the same | the same |
//! | `RETAINED` | 0x2001_FFF8, 8 bytes: the reset-surviving cell ([`RETAINED_CELL`], `hw::retained`) | the same | the same |
//! | `CCMRAM` | 0x1000_0000, 64 KiB (core only, no DMA; QEMU's netduinoplus2 lacks it); unused | none | unused |
//!
//! The settings need two separately erasable sectors (see [`crate::settings`]). Before the
//! firmware update (issue 31) the firmware ran from 0x0800_0000 and the journal sat in the chip's
//! last two sectors; a board that gets the bootloader keeps its settings because the firmware moves
//! them at its first start ([`SettingsStore::migrate_from`](crate::settings::SettingsStore::migrate_from)
//! over `hw::OldSettingsFlash`). The emulated board has no bootloader (QEMU models no flash
//! controller): it is linked from 0x0800_0000 as before, with its own memory file
//! ([`EMULATED_MEMORY_X`]).

use crate::boards::{Chip, RAM_BASE as BOARD_RAM_BASE, SELECTED};

/// Start of flash.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Total flash of the chip.
pub const FLASH_SIZE: u32 = SELECTED.flash.flash_size;
/// Where the program is linked: ACTIVE on a board with the bootloader, the start of flash on the
/// emulated one.
pub const PROGRAM_BASE: u32 =
    if cfg!(feature = "emulated") { FLASH_BASE } else { crate::flash_layout::ACTIVE.base };
/// Flash the program may use from [`PROGRAM_BASE`].
pub const PROGRAM_FLASH_SIZE: u32 =
    if cfg!(feature = "emulated") { EMULATED_PROGRAM_SIZE } else { SELECTED.flash.program_size };
/// The emulated board's program area: sectors 0–9 (the board's memory file before the update).
pub const EMULATED_PROGRAM_SIZE: u32 = 768 * 1024;
/// Flash sector numbers of the settings sectors A and B.
pub const SETTINGS_SECTORS: [u8; 2] = SELECTED.flash.settings_sectors;
/// Start of settings sector A.
pub const SETTINGS_A_BASE: u32 = SELECTED.flash.settings_bases[0];
/// Start of settings sector B.
pub const SETTINGS_B_BASE: u32 = SELECTED.flash.settings_bases[1];
/// Size of each settings sector.
pub const SETTINGS_SECTOR_SIZE: u32 = SELECTED.flash.settings_sector_size;
/// Start of the settings journal's two sectors before the firmware update: the chip's last two.
pub const OLD_SETTINGS_BASES: [u32; 2] = old_settings_bases(SELECTED.chip);
/// Size of each of the old settings sectors.
pub const OLD_SETTINGS_SECTOR_SIZE: u32 = 128 * 1024;
/// Start of SRAM1 (SRAM2 follows it contiguously).
pub const RAM_BASE: u32 = BOARD_RAM_BASE;
/// SRAM1 + SRAM2.
pub const RAM_SIZE: u32 = SELECTED.flash.ram_size;
/// Start of the core-coupled memory (STM32F405 only).
pub const CCMRAM_BASE: u32 = 0x1000_0000;
/// Size of the core-coupled memory (0: the chip has none).
pub const CCMRAM_SIZE: u32 = SELECTED.flash.ccmram_size;

/// The old settings location of `chip`: sectors 10 and 11 (STM32F405RG, RM0090 §3.3 table 5) or
/// 6 and 7 (STM32F446RE, RM0390 §3.3), 128 KiB each.
pub const fn old_settings_bases(chip: Chip) -> [u32; 2] {
    match chip {
        Chip::Stm32f405rg => [0x080C_0000, 0x080E_0000],
        Chip::Stm32f446re => [0x0804_0000, 0x0806_0000],
    }
}

/// The reset-surviving cell: a word and its check word in the last 8 bytes of SRAM, outside
/// `RAM` in memory.x, so neither the start-up code nor QEMU's ELF loader (which reloads the
/// program's segments at a system reset) writes them. Their content after a power-on is
/// undefined; the check word tells.
pub const RETAINED_CELL: u32 = RAM_BASE + RAM_SIZE - RETAINED_SIZE;
/// Size of the reset-surviving cell.
pub const RETAINED_SIZE: u32 = 8;

/// Where the firmware's image-info block (the `fw-image` crate's: magic `DNFI`, board ID,
/// revision) lies, counted from the start of the image: memory.x places the `.image_info` section
/// there, after the vector table, and starts `.text` after it.
pub const IMAGE_INFO_OFFSET: u32 = 0x200;
/// The room memory.x keeps for the image-info block (a larger block fails the link).
pub const IMAGE_INFO_LEN: u32 = 16;
// After the longest vector table of the two chips (the F446's, 0x1C4 bytes).
const _: () = assert!(IMAGE_INFO_OFFSET >= 0x1C4);

/// The emulated board's linker script `MEMORY` block (board/memory/stm32f405rg-emulated.x).
pub const EMULATED_MEMORY_X: &str = include_str!("../memory/stm32f405rg-emulated.x");

/// The linker script's `MEMORY` block of the selected build, as build.rs ships it to cortex-m-rt.
pub const MEMORY_X: &str = if cfg!(feature = "emulated") { EMULATED_MEMORY_X } else { SELECTED.memory_x };

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boards::ALL;
    use crate::flash_layout::{ACTIVE, MAX_IMAGE_LEN, SETTINGS};
    use std::format;
    use std::string::String;

    fn line(memory_x: &str, name: &str) -> Option<String> {
        memory_x.lines().map(str::trim).find(|l| l.starts_with(name)).map(|l| l.replace(' ', ""))
    }

    #[test]
    fn every_board_has_the_update_layout() {
        for board in ALL {
            let f = board.flash;
            // The program is ACTIVE less the trailer; the settings are flash_layout's sectors 1 and 2.
            assert_eq!(f.program_size, MAX_IMAGE_LEN, "{}", board.name);
            assert_eq!(
                f.settings_sectors,
                [SETTINGS[0].first_sector, SETTINGS[1].first_sector],
                "{}",
                board.name
            );
            assert_eq!(f.settings_sectors, [1, 2], "{}", board.name);
            assert_eq!(f.settings_bases, [SETTINGS[0].base, SETTINGS[1].base], "{}", board.name);
            assert_eq!(f.settings_sector_size, SETTINGS[0].size, "{}", board.name);
            assert_eq!(SETTINGS[1].size, SETTINGS[0].size);
        }
    }

    #[test]
    fn the_old_settings_were_the_last_two_sectors() {
        for board in ALL {
            let old = old_settings_bases(board.chip);
            assert_eq!(old[0] + OLD_SETTINGS_SECTOR_SIZE, old[1], "{}", board.name);
            assert_eq!(
                old[1] + OLD_SETTINGS_SECTOR_SIZE,
                FLASH_BASE + board.flash.flash_size,
                "{}",
                board.name
            );
            // Clear of the new journal and of ACTIVE (on the F446 they are DFU now).
            assert!(old[0] >= ACTIVE.base + ACTIVE.size, "{}", board.name);
        }
    }

    fn memory_x_says(x: &str, name: &str, flash: String, settings: String, ram_size: u32, ccm: u32) {
        let kib = |bytes: u32| format!("{}K", bytes / 1024);
        assert_eq!(line(x, "FLASH "), Some(flash), "{name}");
        assert_eq!(line(x, "SETTINGS "), Some(settings), "{name}");
        assert_eq!(
            line(x, "RAM "),
            Some(format!("RAM:ORIGIN=0x{RAM_BASE:08X},LENGTH=0x{:X}", ram_size - RETAINED_SIZE)),
            "{name}"
        );
        assert_eq!(
            line(x, "RETAINED "),
            Some(format!(
                "RETAINED:ORIGIN=0x{:08X},LENGTH={RETAINED_SIZE}",
                RAM_BASE + ram_size - RETAINED_SIZE
            )),
            "{name}"
        );
        let ccm = (ccm > 0).then(|| format!("CCMRAM:ORIGIN=0x{CCMRAM_BASE:08X},LENGTH={}", kib(ccm)));
        assert_eq!(line(x, "CCMRAM "), ccm, "{name}");
    }

    #[test]
    fn memory_x_agrees() {
        for board in ALL {
            let f = board.flash;
            memory_x_says(
                board.memory_x,
                board.name,
                format!("FLASH:ORIGIN=0x{:08X},LENGTH={}", ACTIVE.base, f.program_size),
                format!(
                    "SETTINGS:ORIGIN=0x{:08X},LENGTH={}K",
                    f.settings_bases[0],
                    2 * f.settings_sector_size / 1024
                ),
                f.ram_size,
                f.ccmram_size,
            );
        }
    }

    #[test]
    fn the_emulated_memory_x_links_from_the_start_of_flash() {
        let f = crate::boards::reference::BOARD.flash;
        let old = old_settings_bases(Chip::Stm32f405rg);
        memory_x_says(
            EMULATED_MEMORY_X,
            "emulated",
            format!("FLASH:ORIGIN=0x{FLASH_BASE:08X},LENGTH={}K", EMULATED_PROGRAM_SIZE / 1024),
            format!("SETTINGS:ORIGIN=0x{:08X},LENGTH={}K", old[0], 2 * OLD_SETTINGS_SECTOR_SIZE / 1024),
            f.ram_size,
            f.ccmram_size,
        );
        assert_eq!(FLASH_BASE + EMULATED_PROGRAM_SIZE, old[0]);
    }

    #[test]
    fn memory_x_places_the_image_info_block() {
        let at = format!("ORIGIN(FLASH)+0x{IMAGE_INFO_OFFSET:X}");
        let end = format!("ORIGIN(FLASH)+0x{:X}", IMAGE_INFO_OFFSET + IMAGE_INFO_LEN);
        let files = ALL.iter().map(|b| (b.name, b.memory_x)).chain([("emulated", EMULATED_MEMORY_X)]);
        for (name, x) in files {
            assert_eq!(line(x, ".image_info "), Some(format!(".image_info{at}:")), "{name}");
            assert_eq!(line(x, "_stext "), Some(format!("_stext={end};")), "{name}");
            assert_eq!(line(x, ". = "), Some(format!(".={end};")), "{name}");
            assert_eq!(line(x, "INSERT "), Some("INSERTAFTER.vector_table;".into()), "{name}");
        }
    }

    #[test]
    fn the_selected_build_is_the_one_linked() {
        assert_eq!(MEMORY_X, if cfg!(feature = "emulated") { EMULATED_MEMORY_X } else { SELECTED.memory_x });
        assert_eq!(RETAINED_CELL, 0x2001_FFF8);
    }
}
