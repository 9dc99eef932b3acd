//! The board's DeviceNet serial number (Identity attribute 6, the serial of the duplicate MAC ID
//! check, protocol §7.1), derived from the MCU's 96-bit unique device ID.
//!
//! Every STM32F4 carries a factory-programmed unique ID of three 32-bit words at [`UID_ADDRESS`]
//! (RM0090 §39.1: bits 31:0 the X and Y coordinates on the wafer, bits 63:32 the wafer number and
//! the first lot characters, bits 95:64 the rest of the lot number). DeviceNet wants 32 bits,
//! unique for the vendor, so the board folds the 96 bits with CRC-32 ([`serial_number`]): the
//! CRC-32 (IEEE, `devicenet::crc32`, the one already in the firmware) of the 12 ID bytes as they
//! lie in memory (word 0 first, each word little-endian).
//!
//! Why CRC-32 rather than an XOR of the words: an XOR gives one serial to two chips whose IDs
//! differ by the same bits in two words; a CRC-32 tells apart any two IDs that differ within 32
//! consecutive bits (its burst-error guarantee), so chips of one wafer, whose IDs differ in word
//! 0 only, always get different serial numbers, and other pairs share one with odds of 1 in 2^32.
//!
//! The read itself is `hw::unique_id` (target builds, real board only). QEMU's `netduinoplus2`
//! maps nothing at [`UID_ADDRESS`] (`info mtree` of QEMU 7.2 shows flash, SRAM and the
//! peripherals only; a CPU read there is a bus fault), so the emulated build never reads it: it
//! keeps the reference device's serial number (the firmware's `config` module).

use devicenet::crc32::crc32;

/// The unique device ID's first word (RM0090 §39.1, "Unique device ID register (96 bits)").
pub const UID_ADDRESS: usize = 0x1FFF_7A10;

/// The serial number of the chip whose unique ID is `uid` (word at offset 0 first): the CRC-32
/// of its 12 bytes in memory order (module docs).
pub fn serial_number(uid: [u32; 3]) -> u32 {
    let mut bytes = [0u8; 12];
    for (chunk, word) in bytes.chunks_exact_mut(4).zip(uid) {
        chunk.copy_from_slice(&word.to_le_bytes());
    }
    crc32(&bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn the_serial_is_the_crc32_of_the_id_bytes_in_memory_order() {
        // The bytes of "123456789abc" as three little-endian words; zlib's CRC-32 of that text.
        let uid = [u32::from_le_bytes(*b"1234"), u32::from_le_bytes(*b"5678"), u32::from_le_bytes(*b"9abc")];
        assert_eq!(serial_number(uid), crc32(b"123456789abc"));
        assert_eq!(serial_number([0, 0, 0]), 0x7BD5_C66F, "CRC-32 of twelve zero bytes");
    }

    #[test]
    fn chips_of_one_wafer_get_different_serials() {
        // Same lot and wafer (words 1 and 2), every X/Y of a 64 x 64 grid: all distinct.
        let lot = [0x3133_4E04, 0x3832_3631];
        let serials: HashSet<u32> = (0..64u32)
            .flat_map(|x| (0..64u32).map(move |y| serial_number([x | y << 16, lot[0], lot[1]])))
            .collect();
        assert_eq!(serials.len(), 64 * 64);
    }

    #[test]
    fn any_one_word_changed_changes_the_serial() {
        let base = [0x0017_0031, 0x3133_4E04, 0x3832_3631];
        for word in 0..3 {
            for bit in 0..32 {
                let mut other = base;
                other[word] ^= 1 << bit;
                assert_ne!(serial_number(other), serial_number(base), "word {word} bit {bit}");
            }
        }
    }
}
