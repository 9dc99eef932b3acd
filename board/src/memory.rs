//! The memory map of the selected board's chip as the firmware uses it. `board/memory/<chip>.x`
//! says the same to the linker (build.rs ships the selected board's as `memory.x`); a host test
//! checks every board's file against its [`FlashLayout`](crate::boards::FlashLayout).
//!
//! | region | STM32F405RG (reference, Olimex STM32-P405) | STM32F446RE (NUCLEO-F446RE) |
//! |---|---|---|
//! | program (`FLASH`) | sectors 0–9, 768 KiB | sectors 0–5, 256 KiB |
//! | settings sector A | sector 10, 0x080C_0000, 128 KiB | sector 6, 0x0804_0000, 128 KiB |
//! | settings sector B | sector 11, 0x080E_0000, 128 KiB | sector 7, 0x0806_0000, 128 KiB |
//! | `RAM` (SRAM1 + SRAM2) | 0x2000_0000, 128 KiB − 8 | the same |
//! | `RETAINED` | 0x2001_FFF8, 8 bytes: the reset-surviving cell ([`RETAINED_CELL`], `hw::retained`) | the same |
//! | `CCMRAM` | 0x1000_0000, 64 KiB (core only, no DMA; QEMU's netduinoplus2 lacks it); unused | none |
//!
//! The settings need two separately erasable sectors (see [`crate::settings`]); the last two
//! keep the program area contiguous from the reset vector.

use crate::boards::{RAM_BASE as BOARD_RAM_BASE, SELECTED};

/// Start of flash.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Total flash of the chip.
pub const FLASH_SIZE: u32 = SELECTED.flash.flash_size;
/// Flash the program may use.
pub const PROGRAM_FLASH_SIZE: u32 = SELECTED.flash.program_size;
/// Flash sector numbers of the settings sectors A and B.
pub const SETTINGS_SECTORS: [u8; 2] = SELECTED.flash.settings_sectors;
/// Start of settings sector A.
pub const SETTINGS_A_BASE: u32 = SELECTED.flash.settings_bases[0];
/// Start of settings sector B.
pub const SETTINGS_B_BASE: u32 = SELECTED.flash.settings_bases[1];
/// Size of each settings sector.
pub const SETTINGS_SECTOR_SIZE: u32 = SELECTED.flash.settings_sector_size;
/// Start of SRAM1 (SRAM2 follows it contiguously).
pub const RAM_BASE: u32 = BOARD_RAM_BASE;
/// SRAM1 + SRAM2.
pub const RAM_SIZE: u32 = SELECTED.flash.ram_size;
/// Start of the core-coupled memory (STM32F405 only).
pub const CCMRAM_BASE: u32 = 0x1000_0000;
/// Size of the core-coupled memory (0: the chip has none).
pub const CCMRAM_SIZE: u32 = SELECTED.flash.ccmram_size;

/// The reset-surviving cell: a word and its check word in the last 8 bytes of SRAM, outside
/// `RAM` in memory.x, so neither the start-up code nor QEMU's ELF loader (which reloads the
/// program's segments at a system reset) writes them. Their content after a power-on is
/// undefined; the check word tells.
pub const RETAINED_CELL: u32 = RAM_BASE + RAM_SIZE - RETAINED_SIZE;
/// Size of the reset-surviving cell.
pub const RETAINED_SIZE: u32 = 8;

/// The linker script's `MEMORY` block of the selected board, as build.rs ships it to cortex-m-rt.
pub const MEMORY_X: &str = SELECTED.memory_x;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::boards::ALL;
    use std::format;
    use std::string::String;

    fn line(memory_x: &str, name: &str) -> Option<String> {
        memory_x.lines().map(str::trim).find(|l| l.starts_with(name)).map(|l| l.replace(' ', ""))
    }

    #[test]
    fn settings_sectors_follow_the_program_area() {
        for board in ALL {
            let f = board.flash;
            assert_eq!(FLASH_BASE + f.program_size, f.settings_bases[0], "{}", board.name);
            assert_eq!(f.settings_bases[0] + f.settings_sector_size, f.settings_bases[1], "{}", board.name);
            assert_eq!(
                f.settings_bases[1] + f.settings_sector_size,
                FLASH_BASE + f.flash_size,
                "{}",
                board.name
            );
            // The last two sectors of the chip.
            let last = if f.flash_size == 1024 * 1024 { 11 } else { 7 };
            assert_eq!(f.settings_sectors, [last - 1, last], "{}", board.name);
        }
    }

    #[test]
    fn memory_x_agrees() {
        for board in ALL {
            let f = board.flash;
            let x = board.memory_x;
            let kib = |bytes: u32| format!("{}K", bytes / 1024);
            assert_eq!(
                line(x, "FLASH "),
                Some(format!("FLASH:ORIGIN=0x{FLASH_BASE:08X},LENGTH={}", kib(f.program_size))),
                "{}",
                board.name
            );
            assert_eq!(
                line(x, "SETTINGS "),
                Some(format!(
                    "SETTINGS:ORIGIN=0x{:08X},LENGTH={}",
                    f.settings_bases[0],
                    kib(2 * f.settings_sector_size)
                )),
                "{}",
                board.name
            );
            assert_eq!(
                line(x, "RAM "),
                Some(format!("RAM:ORIGIN=0x{RAM_BASE:08X},LENGTH=0x{:X}", f.ram_size - RETAINED_SIZE)),
                "{}",
                board.name
            );
            assert_eq!(
                line(x, "RETAINED "),
                Some(format!(
                    "RETAINED:ORIGIN=0x{:08X},LENGTH={RETAINED_SIZE}",
                    RAM_BASE + f.ram_size - RETAINED_SIZE
                )),
                "{}",
                board.name
            );
            let ccm = (f.ccmram_size > 0)
                .then(|| format!("CCMRAM:ORIGIN=0x{CCMRAM_BASE:08X},LENGTH={}", kib(f.ccmram_size)));
            assert_eq!(line(x, "CCMRAM "), ccm, "{}", board.name);
        }
    }

    #[test]
    fn the_selected_board_is_the_one_linked() {
        assert_eq!(MEMORY_X, SELECTED.memory_x);
        assert_eq!(RETAINED_CELL, 0x2001_FFF8);
    }
}
