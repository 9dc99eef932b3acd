//! Frame checksums: 8-bit sum, 8-bit XOR and CRC-16/MODBUS.
//!
//! A framed profile computes its checksum over the data bytes only (not the start byte, length
//! byte or end delimiter), as the breaker of the source paper does. Two-byte checksums go on the
//! wire low byte first, as Modbus RTU sends its CRC.

/// The checksum of a framed-serial frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum Checksum {
    /// No checksum byte.
    None = 0,
    /// One byte: the sum of the data bytes modulo 256 (the breaker's checksum).
    #[default]
    Sum8 = 1,
    /// One byte: the XOR of the data bytes.
    Xor8 = 2,
    /// Two bytes, low first: CRC-16/MODBUS of the data bytes.
    Crc16Modbus = 3,
}

impl Checksum {
    /// How many bytes the checksum occupies on the wire (0, 1 or 2).
    #[allow(clippy::manual_div_ceil)] // `div_ceil` branches on the remainder (flash).
    pub const fn byte_len(self) -> usize {
        // (discriminant + 1) / 2 = 0, 1, 1, 2: two instructions where the match is a jump
        // inlined at every use (firmware size budget); `byte_len_per_checksum` pins the values.
        (self as usize + 1) / 2
    }

    /// The checksum of `data` as a number (0 for [`Checksum::None`]).
    pub fn compute(self, data: &[u8]) -> u16 {
        match self {
            Checksum::None => 0,
            Checksum::Sum8 => u16::from(sum8(data)),
            Checksum::Xor8 => u16::from(xor8(data)),
            Checksum::Crc16Modbus => crc16_modbus(data),
        }
    }

    /// The checksum of `data` as it goes on the wire: the first [`byte_len`](Self::byte_len)
    /// bytes of the returned array.
    pub fn wire_bytes(self, data: &[u8]) -> [u8; 2] {
        let value = self.compute(data);
        match self.byte_len() {
            1 => [value as u8, 0],
            _ => value.to_le_bytes(),
        }
    }

    /// `true` when `trailer` is exactly the wire checksum of `data`.
    pub fn verify(self, data: &[u8], trailer: &[u8]) -> bool {
        let expected = self.wire_bytes(data);
        expected.get(..self.byte_len()) == Some(trailer)
    }
}

/// The sum of `data` modulo 256.
pub fn sum8(data: &[u8]) -> u8 {
    data.iter().fold(0u8, |acc, &b| acc.wrapping_add(b))
}

/// The XOR of `data`.
pub fn xor8(data: &[u8]) -> u8 {
    data.iter().fold(0u8, |acc, &b| acc ^ b)
}

/// CRC-16/MODBUS: reflected polynomial 0xA001 (0x8005), initial value 0xFFFF, no final XOR.
/// On the wire the low byte goes first (Modbus over Serial Line §6.2.2).
pub fn crc16_modbus(data: &[u8]) -> u16 {
    data.iter().fold(CRC16_MODBUS_INIT, |crc, &b| crc16_modbus_step(crc, b))
}

/// The initial value of CRC-16/MODBUS, for [`crc16_modbus_step`].
pub const CRC16_MODBUS_INIT: u16 = 0xFFFF;

/// CRC-16/MODBUS `crc` advanced over one byte `b`: folding it over bytes from
/// [`CRC16_MODBUS_INIT`] gives [`crc16_modbus`] (the configuration consistency value folds it
/// over an image with some bytes replaced, `crate::converter::consistency`).
pub fn crc16_modbus_step(crc: u16, b: u8) -> u16 {
    // Two nibbles per byte, low first (the CRC is reflected). The table has 16 entries and
    // each index is 4 bits.
    let crc = crc ^ u16::from(b);
    let crc = (crc >> 4) ^ CRC16_NIBBLES.get(usize::from(crc & 0xF)).copied().unwrap_or(0);
    (crc >> 4) ^ CRC16_NIBBLES.get(usize::from(crc & 0xF)).copied().unwrap_or(0)
}

/// The CRC-16/MODBUS of each 4-bit value, built at compile time: 32 bytes of flash where a
/// byte-wide table takes 512, for two lookups per byte instead of one (at serial speeds, nothing).
const CRC16_NIBBLES: [u16; 16] = crc16_nibbles();

// Evaluated at compile time only: an out-of-bounds index would fail the build, not panic.
#[allow(clippy::indexing_slicing)]
const fn crc16_nibbles() -> [u16; 16] {
    let mut table = [0u16; 16];
    let mut i = 0;
    while i < 16 {
        let mut crc = i as u16;
        let mut bit = 0;
        while bit < 4 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xA001 } else { crc >> 1 };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rstest::rstest;

    /// CRC-16/MODBUS by the `crc` crate's catalogue: an implementation independent of ours.
    fn crc16_reference(data: &[u8]) -> u16 {
        crc::Crc::<u16>::new(&crc::CRC_16_MODBUS).checksum(data)
    }

    // Published vectors: the wire bytes (low first) that follow each request/response.
    #[rstest]
    #[case::read_holding_10(&[0x01, 0x03, 0x00, 0x00, 0x00, 0x0A], [0xC5, 0xCD])]
    #[case::read_input_response(&[0x01, 0x04, 0x02, 0xFF, 0xFF], [0xB8, 0x80])]
    #[case::read_holding_1(&[0x01, 0x03, 0x00, 0x00, 0x00, 0x01], [0x84, 0x0A])]
    #[case::write_single_register(&[0x11, 0x06, 0x00, 0x01, 0x00, 0x03], [0x9A, 0x9B])]
    #[case::check_string(b"123456789", [0x37, 0x4B])]
    #[case::empty(&[], [0xFF, 0xFF])]
    fn crc16_vectors(#[case] data: &[u8], #[case] wire: [u8; 2]) {
        assert_eq!(crc16_modbus(data).to_le_bytes(), wire);
        assert_eq!(Checksum::Crc16Modbus.wire_bytes(data), wire);
        assert!(Checksum::Crc16Modbus.verify(data, &wire));
    }

    #[test]
    fn crc_of_message_and_its_crc_is_zero() {
        let mut frame = [0x01, 0x03, 0x00, 0x00, 0x00, 0x0A, 0, 0];
        let crc = crc16_modbus(&frame[..6]).to_le_bytes();
        frame[6..].copy_from_slice(&crc);
        assert_eq!(crc16_modbus(&frame), 0);
    }

    // The breaker status frame of the source paper: sum of the 18 data bytes modulo 256.
    #[rstest]
    #[case::sum_small(Checksum::Sum8, &[0x01, 0x02, 0x03], &[0x06])]
    #[case::sum_wraps(Checksum::Sum8, &[0xFF, 0x02], &[0x01])]
    #[case::sum_breaker_open(Checksum::Sum8, &[0, 0, 0, 0, 0, 0, 0, 0, 0, 0x0F, 0, 0, 0, 0, 0, 0, 0, 0], &[0x0F])]
    #[case::sum_breaker_closed(Checksum::Sum8, &[10, 11, 12, 1, 0, 0, 0, 0, 0, 0xF0, 0, 0, 0, 0, 0, 0, 0, 0], &[0x12])]
    #[case::xor(Checksum::Xor8, &[0x0F, 0xF0, 0x01], &[0xFE])]
    #[case::none(Checksum::None, &[1, 2, 3], &[])]
    fn eight_bit_checksums(#[case] c: Checksum, #[case] data: &[u8], #[case] wire: &[u8]) {
        assert_eq!(c.byte_len(), wire.len());
        assert!(c.verify(data, wire));
        assert_eq!(&c.wire_bytes(data)[..c.byte_len()], wire);
    }

    #[rstest]
    #[case::wrong_value(Checksum::Sum8, &[0x01], &[0x02])]
    #[case::too_long(Checksum::Sum8, &[0x01], &[0x01, 0x00])]
    #[case::too_short(Checksum::Crc16Modbus, &[0x01], &[0x7E])]
    #[case::none_with_trailer(Checksum::None, &[0x01], &[0x00])]
    fn verify_rejects(#[case] c: Checksum, #[case] data: &[u8], #[case] trailer: &[u8]) {
        assert!(!c.verify(data, trailer));
    }

    #[test]
    fn byte_len_per_checksum() {
        let lens =
            [Checksum::None, Checksum::Sum8, Checksum::Xor8, Checksum::Crc16Modbus].map(Checksum::byte_len);
        assert_eq!(lens, [0, 1, 1, 2]);
    }

    proptest! {
        #[test]
        fn table_matches_reference(data in proptest::collection::vec(any::<u8>(), 0..300)) {
            prop_assert_eq!(crc16_modbus(&data), crc16_reference(&data));
        }
    }
}
