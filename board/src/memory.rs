//! The STM32F405RG memory map as the firmware uses it (`memory.x` at the crate root says the same
//! to the linker; a host test checks they agree).
//!
//! | region | address | size | use |
//! |---|---|---|---|
//! | flash sectors 0–9 | 0x0800_0000 | 768 KiB | program (`FLASH`) |
//! | flash sector 10 | 0x080C_0000 | 128 KiB | settings, sector A |
//! | flash sector 11 | 0x080E_0000 | 128 KiB | settings, sector B |
//! | SRAM1 + SRAM2 | 0x2000_0000 | 128 KiB − 8 | `RAM`: data, bss, stack |
//! | end of SRAM2 | 0x2001_FFF8 | 8 bytes | `RETAINED`: the reset-surviving cell ([`RETAINED_CELL`], `hw::retained`) |
//! | CCM RAM | 0x1000_0000 | 64 KiB | `CCMRAM` (core only, no DMA; QEMU's netduinoplus2 lacks it); unused for now |
//!
//! The settings need two separately erasable sectors (see [`crate::settings`]); the last two
//! keep the program area contiguous from the reset vector.

/// Start of flash.
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Total flash of the STM32F405RG.
pub const FLASH_SIZE: u32 = 1024 * 1024;
/// Flash the program may use (sectors 0–9).
pub const PROGRAM_FLASH_SIZE: u32 = 768 * 1024;
/// Flash sector numbers of the settings sectors A and B.
pub const SETTINGS_SECTORS: [u8; 2] = [10, 11];
/// Start of settings sector A.
pub const SETTINGS_A_BASE: u32 = 0x080C_0000;
/// Start of settings sector B.
pub const SETTINGS_B_BASE: u32 = 0x080E_0000;
/// Size of each settings sector.
pub const SETTINGS_SECTOR_SIZE: u32 = 128 * 1024;
/// Start of SRAM1 (SRAM2 follows it contiguously).
pub const RAM_BASE: u32 = 0x2000_0000;
/// SRAM1 + SRAM2.
pub const RAM_SIZE: u32 = 128 * 1024;
/// Start of the core-coupled memory.
pub const CCMRAM_BASE: u32 = 0x1000_0000;
/// Size of the core-coupled memory.
pub const CCMRAM_SIZE: u32 = 64 * 1024;

/// The reset-surviving cell: a word and its check word in the last 8 bytes of SRAM, outside
/// `RAM` in memory.x, so neither the start-up code nor QEMU's ELF loader (which reloads the
/// program's segments at a system reset) writes them. Their content after a power-on is
/// undefined; the check word tells.
pub const RETAINED_CELL: u32 = RAM_BASE + RAM_SIZE - RETAINED_SIZE;
/// Size of the reset-surviving cell.
pub const RETAINED_SIZE: u32 = 8;

/// The linker script, as shipped to cortex-m-rt by the build script.
pub const MEMORY_X: &str = include_str!("../memory.x");

#[cfg(test)]
mod tests {
    use super::*;
    use std::format;

    #[test]
    fn settings_sectors_follow_the_program_area() {
        assert_eq!(FLASH_BASE + PROGRAM_FLASH_SIZE, SETTINGS_A_BASE);
        assert_eq!(SETTINGS_A_BASE + SETTINGS_SECTOR_SIZE, SETTINGS_B_BASE);
        assert_eq!(SETTINGS_B_BASE + SETTINGS_SECTOR_SIZE, FLASH_BASE + FLASH_SIZE);
    }

    #[test]
    fn memory_x_agrees() {
        let line = |name: &str| {
            MEMORY_X
                .lines()
                .map(str::trim)
                .find(|l| l.starts_with(name))
                .unwrap_or_else(|| panic!("{name} missing from memory.x"))
                .replace(' ', "")
        };
        assert_eq!(line("FLASH "), "FLASH:ORIGIN=0x08000000,LENGTH=768K");
        assert_eq!(
            line("RAM "),
            format!("RAM:ORIGIN=0x{RAM_BASE:08X},LENGTH=0x{:X}", RAM_SIZE - RETAINED_SIZE)
        );
        assert_eq!(
            line("RETAINED "),
            format!("RETAINED:ORIGIN=0x{RETAINED_CELL:08X},LENGTH={RETAINED_SIZE}")
        );
        assert_eq!(line("CCMRAM "), "CCMRAM:ORIGIN=0x10000000,LENGTH=64K");
        assert_eq!(line("SETTINGS "), "SETTINGS:ORIGIN=0x080C0000,LENGTH=256K");
    }
}
