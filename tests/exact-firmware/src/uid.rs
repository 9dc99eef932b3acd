//! A unique device ID whose CRC-32 fold ([`board::uid::serial_number`]) is a chosen serial number.
//!
//! The firmware derives its DeviceNet serial number from the chip's 96-bit unique ID (RM0090
//! §39.1, board/src/uid.rs). The reference transcript (protocol §2) carries the serial
//! 0x12345678. Rather than compare the bring-up with the serial substituted, the emulated chip is
//! given an ID whose fold *is* that serial: the frames are then compared unchanged, and the
//! firmware's own read and fold of the ID register are exercised on the way.
//!
//! CRC-32 is affine over GF(2) in its input bits, so the last four bytes of the ID are solved
//! for: the first eight are fixed (`b"stm32emu"`), and the 32 × 32 system of the last four
//! bytes' effect on the CRC is solved by Gaussian elimination.

use devicenet::crc32::crc32;

/// The 12 ID bytes (memory order, as [`stm32_emu::machine::Stm32::new`] takes them) whose CRC-32
/// is `serial`.
pub fn unique_id_for_serial(serial: u32) -> [u8; 12] {
    let mut id = *b"stm32emu\0\0\0\0";
    let base = crc32(&id);
    // Column k: the CRC change made by flipping bit k of the last four bytes.
    let columns: Vec<u32> = (0..32)
        .map(|k| {
            let mut flipped = id;
            flipped[8 + k / 8] ^= 1 << (k % 8);
            crc32(&flipped) ^ base
        })
        .collect();
    let x = solve(&columns, serial ^ base);
    id[8..].copy_from_slice(&x.to_le_bytes());
    id
}

/// The x (bit k = column k used) with XOR of the chosen columns = `target`. CRC-32 of a fixed
/// prefix is a bijection of the last 32 bits, so the system always has one solution.
fn solve(columns: &[u32], target: u32) -> u32 {
    // Rows: (column value, which input bits make it).
    let mut rows: Vec<(u32, u32)> = columns.iter().enumerate().map(|(k, &c)| (c, 1u32 << k)).collect();
    let mut basis: Vec<(u32, u32)> = Vec::new();
    for bit in (0..32).rev() {
        let Some(p) = rows.iter().position(|&(c, _)| c >> bit & 1 == 1) else { continue };
        let pivot = rows.swap_remove(p);
        for row in rows.iter_mut().chain(basis.iter_mut()) {
            if row.0 >> bit & 1 == 1 {
                row.0 ^= pivot.0;
                row.1 ^= pivot.1;
            }
        }
        basis.push(pivot);
    }
    // Fully reduced, each basis column is its pivot bit alone.
    basis.iter().filter(|&&(c, _)| c & target != 0).fold(0, |x, &(_, m)| x ^ m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fold_of_the_solved_id_is_the_serial() {
        for serial in [0x1234_5678, 0, u32::MAX, 0xDEAD_BEEF] {
            let id = unique_id_for_serial(serial);
            let words = [0, 1, 2]
                .map(|i| u32::from_le_bytes([id[4 * i], id[4 * i + 1], id[4 * i + 2], id[4 * i + 3]]));
            assert_eq!(board::uid::serial_number(words), serial, "{serial:#x}");
        }
    }
}
