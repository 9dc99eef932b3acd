//! A scan entry ([`ScanEntry`]) and its data between the DeviceNet images and the Modbus wire:
//! the request an entry sends, the read data it stores in the [`ByteOrder`] of the images (and
//! the [`WordOrder`] of its register pairs), and which output changes call for a write.

use super::pdu::Function;
pub use super::schedule::WriteMode;
use crate::serial::IMAGE_CAPACITY;

/// How a register's two bytes are laid out in the DeviceNet images.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum ByteOrder {
    /// Low byte first, as DeviceNet carries an INT/UINT (registers are swapped from the wire).
    #[default]
    LittleEndian,
    /// High byte first, as on the Modbus wire.
    BigEndian,
}

/// How an instrument lays a 32-bit value (DINT, UDINT, REAL) over a register pair, the way
/// vendor manuals name it: the value's bytes are `A B C D`, most significant first, and the
/// letters give their order on the wire, first register first (guide:
/// docs/src/integrator/modbus.md, "32-bit word order"). The converter stores the value in the
/// profile's [`ByteOrder`]: `D C B A` in little-endian images (as DeviceNet carries a DINT or
/// REAL), `A B C D` in big-endian ones. Every order is a fixed permutation of the four bytes and
/// its own inverse, so writes (function 16) take the image to the wire the same way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum WordOrder {
    /// Each register on its own in the profile's [`ByteOrder`], no pairs (the default).
    #[default]
    Registers,
    /// Big-endian: high register first, high byte first in each.
    Abcd,
    /// High register first, its bytes swapped ("byte swap").
    Badc,
    /// Low register first, high byte first in each ("word swap").
    Cdab,
    /// Little-endian: low register first, low byte first in each.
    Dcba,
}

impl WordOrder {
    /// Every order, in image code order (bits 5-7 of a scan entry's function byte).
    pub const ALL: [WordOrder; 5] =
        [WordOrder::Registers, WordOrder::Abcd, WordOrder::Badc, WordOrder::Cdab, WordOrder::Dcba];

    /// Whether this is [`WordOrder::Registers`], the default.
    pub fn is_registers(&self) -> bool {
        *self == WordOrder::Registers
    }

    /// Whether this order moves bytes between the two registers of a pair (and so needs an even
    /// register count).
    pub const fn is_pairwise(self) -> bool {
        !matches!(self, WordOrder::Registers)
    }

    /// The image byte `k` is wire byte `k ^ mask`: bit 0 swaps the bytes of a register, bit 1
    /// the registers of a pair. The wire carries value byte `i` (0 = A) at `i ^ w` for `w` =
    /// 0 (abcd), 1 (badc), 2 (cdab), 3 (dcba); a little-endian image holds value byte `k ^ 3` at
    /// `k`, a big-endian one value byte `k`.
    const fn mask(self, order: ByteOrder) -> usize {
        let image = match order {
            ByteOrder::LittleEndian => 3,
            ByteOrder::BigEndian => 0,
        };
        match self {
            // A register's two bytes: a one-register value `A B` on the wire.
            WordOrder::Registers => image & 1,
            WordOrder::Abcd => image,
            WordOrder::Badc => image ^ 1,
            WordOrder::Cdab => image ^ 2,
            WordOrder::Dcba => image ^ 3,
        }
    }
}

/// One transaction of the scan list.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct ScanEntry {
    /// The slave's unit address, `1..=247` (broadcast is not used).
    pub unit: u8,
    /// The function: 1–4 read into the input image, 5, 6, 15, 16 write from the output image.
    pub function: Function,
    /// The first coil, input or register (0-based protocol address).
    pub address: u16,
    /// How many coils, inputs or registers: `1..=2000` bits / `1..=125` registers to read,
    /// `1..=1968` / `1..=123` to write, exactly 1 for functions 5 and 6.
    pub count: u16,
    /// Byte offset of this entry's data in the input image (reads) or output image (writes).
    pub offset: u16,
    /// How register pairs are ordered in the image (functions 3, 4 and 16 with an even count).
    #[cfg_attr(feature = "serde", serde(default, skip_serializing_if = "WordOrder::is_registers"))]
    pub word_order: WordOrder,
    /// Reads: read every `period_ms` instead of every scan cycle; writes with
    /// [`WriteMode::Cyclic`]: re-sent every `period_ms` (`1..=3_600_000`). `None`: the scan cycle
    /// (reads) or no re-sending (writes). See the [schedule](super::schedule) module.
    #[cfg_attr(feature = "serde", serde(default, skip_serializing_if = "Option::is_none"))]
    pub period_ms: Option<u32>,
    /// When a write entry is sent (write functions only; reads keep the default).
    #[cfg_attr(feature = "serde", serde(default, skip_serializing_if = "WriteMode::is_change"))]
    pub write: WriteMode,
    /// The output image byte whose every change of value sends this entry once: a write with
    /// [`WriteMode::Trigger`], or a read (then read only on trigger, not every cycle).
    #[cfg_attr(feature = "serde", serde(default, skip_serializing_if = "Option::is_none"))]
    pub trigger_offset: Option<u16>,
}

impl ScanEntry {
    /// Bytes this entry occupies in its image.
    pub const fn image_len(&self) -> usize {
        self.function.data_len(self.count)
    }

    pub(crate) fn range(&self) -> core::ops::Range<usize> {
        let start = usize::from(self.offset);
        start..start + self.image_len()
    }
}

/// Whether write entry `e` has the same significant bits in both output images.
pub(crate) fn same_output(e: &ScanEntry, old: &[u8; IMAGE_CAPACITY], new: &[u8; IMAGE_CAPACITY]) -> bool {
    let r = e.range();
    let len = r.len();
    match (old.get(r.clone()), new.get(r)) {
        (Some(a), Some(b)) => {
            a.iter().zip(b).enumerate().all(|(k, (&x, &y))| (x ^ y) & significant_bits(e, k, len) == 0)
        }
        _ => true,
    }
}

/// The bits of byte `k` (of `len`) that carry data for entry `e`.
fn significant_bits(e: &ScanEntry, k: usize, len: usize) -> u8 {
    let rem = e.count % 8;
    if e.function.is_bits() && k + 1 == len && rem != 0 {
        (1u8 << rem) - 1
    } else {
        0xFF
    }
}

/// Copies a read response's data into the input image at the entry's offset.
pub(crate) fn store_read(input: &mut [u8], e: &ScanEntry, data: &[u8], order: ByteOrder) {
    if let Some(dst) = input.get_mut(e.range()) {
        convert(e, order, data, dst);
    }
}

/// Copies entry `e`'s data between the wire and its image, the same conversion either way: bits
/// masked to the entry's quantity, register bytes placed by the entry's [`WordOrder`] (an order is
/// its own inverse, so reads and writes share it).
fn convert(e: &ScanEntry, order: ByteOrder, from: &[u8], to: &mut [u8]) {
    let len = from.len();
    let mask = if e.function.is_bits() { 0 } else { e.word_order.mask(order) };
    for (k, d) in to.iter_mut().enumerate().take(len) {
        *d = from.get(k ^ mask).copied().unwrap_or(0) & significant_bits(e, k, len);
    }
}

/// Writes the request of scan entry `e` without its CRC into `out` and returns its length (writes
/// take their data from `output`); `None` where [`pdu::Request::emit`] refuses the entry (a quantity
/// out of range) or its data lies outside `output`. The bytes `Request::emit` writes, written
/// here directly: building a `Request` to emit it costs some 500 bytes of firmware flash.
pub(crate) fn encode_entry(e: &ScanEntry, output: &[u8], order: ByteOrder, out: &mut [u8]) -> Option<usize> {
    let f = e.function;
    let single = matches!(f, Function::WriteSingleCoil | Function::WriteSingleRegister);
    if !single && !(1..=f.max_count()).contains(&e.count) {
        return None;
    }
    let data = if f.is_write() { output.get(e.range())? } else { &[] };
    let (head, rest) = out.split_first_chunk_mut::<6>()?;
    let [address_hi, address_lo] = e.address.to_be_bytes();
    let [count_hi, count_lo] = e.count.to_be_bytes();
    *head = [e.unit, f.code(), address_hi, address_lo, count_hi, count_lo];
    // Tested by kind rather than matched on the function: a match copies the header's stores
    // into every arm (firmware size).
    if !f.is_write() {
        return Some(6);
    }
    if !single {
        let (byte_count, payload) = rest.split_first_mut()?;
        *byte_count = data.len() as u8;
        convert(e, order, data, payload.get_mut(..data.len())?);
        return Some(7 + data.len());
    }
    // The single writes carry the value where the quantity would be.
    head[4..].fill(0);
    if f.is_bits() {
        if data.first().is_some_and(|b| b & 1 != 0) {
            head[4] = 0xFF;
        }
    } else {
        convert(e, order, data, &mut head[4..]);
    }
    Some(6)
}

/// Appends the CRC to the `n` bytes of `out` (unit, function, data); returns the ADU's length.
pub(crate) fn append_crc(out: &mut [u8], n: usize) -> Option<usize> {
    let crc = crate::serial::checksum::crc16_modbus(out.get(..n)?).to_le_bytes();
    out.get_mut(n..n + 2)?.copy_from_slice(&crc);
    Some(n + 2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    /// 123.45 = 0x42F6_E666 as REAL, bytes A B C D = 42 F6 E6 66; the wire layouts from the
    /// order table of modbus.maxenergic.com/modbus-float32-byte-order.html (register 1, then 2).
    const VALUE: u32 = 0x42F6_E666;

    fn entry(function: Function, count: u16, word_order: WordOrder) -> ScanEntry {
        ScanEntry {
            unit: 1,
            function,
            address: 0,
            count,
            offset: 0,
            word_order,
            period_ms: None,
            write: WriteMode::Change,
            trigger_offset: None,
        }
    }

    #[rstest]
    #[case::abcd(WordOrder::Abcd, [0x42, 0xF6, 0xE6, 0x66])]
    #[case::cdab(WordOrder::Cdab, [0xE6, 0x66, 0x42, 0xF6])]
    #[case::badc(WordOrder::Badc, [0xF6, 0x42, 0x66, 0xE6])]
    #[case::dcba(WordOrder::Dcba, [0x66, 0xE6, 0xF6, 0x42])]
    fn a_register_pair_reads_as_the_value(#[case] order: WordOrder, #[case] wire: [u8; 4]) {
        for (byte_order, expected) in
            [(ByteOrder::LittleEndian, VALUE.to_le_bytes()), (ByteOrder::BigEndian, VALUE.to_be_bytes())]
        {
            for f in [Function::ReadHoldingRegisters, Function::ReadInputRegisters] {
                let mut input = [0u8; 4];
                store_read(&mut input, &entry(f, 2, order), &wire, byte_order);
                assert_eq!(input, expected, "{order:?} {byte_order:?} {f:?}");
            }
        }
    }

    #[rstest]
    #[case::abcd(WordOrder::Abcd, [0x42, 0xF6, 0xE6, 0x66])]
    #[case::cdab(WordOrder::Cdab, [0xE6, 0x66, 0x42, 0xF6])]
    #[case::badc(WordOrder::Badc, [0xF6, 0x42, 0x66, 0xE6])]
    #[case::dcba(WordOrder::Dcba, [0x66, 0xE6, 0xF6, 0x42])]
    fn a_register_pair_writes_the_value_in_order(#[case] order: WordOrder, #[case] wire: [u8; 4]) {
        let e = entry(Function::WriteMultipleRegisters, 2, order);
        let mut out = [0u8; 16];
        let n = encode_entry(&e, &VALUE.to_le_bytes(), ByteOrder::LittleEndian, &mut out).unwrap();
        assert_eq!(out[..n], [[1, 16, 0, 0, 0, 2, 4].as_slice(), &wire].concat());
        let n = encode_entry(&e, &VALUE.to_be_bytes(), ByteOrder::BigEndian, &mut out).unwrap();
        assert_eq!(out[7..n], wire);
    }

    #[test]
    fn two_pairs_are_ordered_each_on_its_own() {
        let e = entry(Function::ReadHoldingRegisters, 4, WordOrder::Cdab);
        let mut input = [0u8; 8];
        store_read(&mut input, &e, &[3, 4, 1, 2, 7, 8, 5, 6], ByteOrder::BigEndian);
        assert_eq!(input, [1, 2, 3, 4, 5, 6, 7, 8]);
    }

    #[rstest]
    #[case::little_endian(ByteOrder::LittleEndian, [0xF6, 0x42, 0x66, 0xE6])]
    #[case::big_endian(ByteOrder::BigEndian, [0x42, 0xF6, 0xE6, 0x66])]
    fn without_a_word_order_registers_follow_the_byte_order(
        #[case] order: ByteOrder,
        #[case] image: [u8; 4],
    ) {
        let mut input = [0u8; 4];
        let e = entry(Function::ReadHoldingRegisters, 2, WordOrder::Registers);
        store_read(&mut input, &e, &[0x42, 0xF6, 0xE6, 0x66], order);
        assert_eq!(input, image);
    }
}
