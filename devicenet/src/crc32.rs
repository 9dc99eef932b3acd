//! CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320, init and final XOR 0xFFFFFFFF): not part
//! of DeviceNet, but the one CRC-32 of the firmware, shared by the crates that all depend on this
//! one: the board's settings records and the converter's configuration image (one copy in flash).
//! A 16-entry nibble table keeps it at 64 bytes of flash.

const POLY: u32 = 0xEDB8_8320;

// Evaluated at compile time; `i < 16` indexes a 16-entry array.
#[allow(clippy::indexing_slicing)]
const fn nibble_table() -> [u32; 16] {
    let mut table = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 4 {
            c = if c & 1 != 0 { (c >> 1) ^ POLY } else { c >> 1 };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
}

const TABLE: [u32; 16] = nibble_table();

/// The CRC-32 of `data` (the value zlib and Ethernet use: `"123456789"` gives `0xCBF43926`).
// Out of line: inlined into the settings journal's scan and save it costs some 44 bytes more.
#[inline(never)]
// The index is a nibble (`& 0xF`) into a 16-entry table: it cannot panic.
#[allow(clippy::indexing_slicing)]
pub fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in data {
        crc ^= u32::from(b);
        crc = (crc >> 4) ^ TABLE[(crc & 0xF) as usize];
        crc = (crc >> 4) ^ TABLE[(crc & 0xF) as usize];
    }
    !crc
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::check_value(b"123456789", 0xCBF4_3926)]
    #[case::empty(b"", 0)]
    #[case::one_zero(&[0u8], 0xD202_EF8D)]
    #[case::fox(b"The quick brown fox jumps over the lazy dog", 0x414F_A339)]
    fn known_values(#[case] data: &[u8], #[case] crc: u32) {
        assert_eq!(crc32(data), crc);
    }
}
