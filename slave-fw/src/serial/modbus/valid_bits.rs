//! The data-valid bits' place in the input image: their length and the check of
//! `valid_bits_offset` (what the bits mean: [`units`](super::units)). A module of its own so that
//! the configuration's validation and the unit table both use it without importing each other.

use super::entry::ScanEntry;
use crate::serial::error::{as_u32, ConfigError, Field, Problem};
use crate::serial::IMAGE_CAPACITY;

/// Bytes the data-valid bits of a scan list of `entries` take.
pub const fn valid_bits_len(entries: usize) -> usize {
    entries.div_ceil(8)
}

/// Checks [`ModbusConfig::valid_bits_offset`](super::ModbusConfig::valid_bits_offset): the bits lie within `input_len` and overlap no read
/// entry's data.
pub(super) fn validate(
    valid_bits_offset: Option<u16>,
    scan: &[ScanEntry],
    input_len: u16,
) -> Result<(), ConfigError> {
    let Some(offset) = valid_bits_offset else {
        return Ok(());
    };
    let len = valid_bits_len(scan.len());
    let input = usize::from(input_len);
    if input < len {
        // No offset fits: the image is too short for the bits.
        return ConfigError::check_range(Field::InputLen, as_u32(input), as_u32(len), as_u32(IMAGE_CAPACITY));
    }
    ConfigError::check_range(Field::ValidBitsOffset, u32::from(offset), 0, as_u32(input - len))?;
    let bits = usize::from(offset)..usize::from(offset) + len;
    let overlap = scan.iter().position(|e| {
        let r = e.range();
        !e.function.is_write() && r.start < bits.end && bits.start < r.end
    });
    match overlap {
        Some(other) => Err(ConfigError {
            field: Field::ValidBitsOffset,
            index: None,
            problem: Problem::Overlap { other: u16::try_from(other).unwrap_or(u16::MAX) },
        }),
        None => Ok(()),
    }
}
