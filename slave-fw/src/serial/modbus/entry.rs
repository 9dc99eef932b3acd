//! A scan entry ([`ScanEntry`]) and its data between the DeviceNet images and the Modbus wire:
//! the request an entry sends, the read data it stores in the [`ByteOrder`] of the images, and
//! which output changes call for a write.

use super::pdu::Function;
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
/// masked to the entry's quantity, register bytes swapped for little-endian images.
fn convert(e: &ScanEntry, order: ByteOrder, from: &[u8], to: &mut [u8]) {
    let len = from.len();
    let swap = usize::from(!e.function.is_bits() && order == ByteOrder::LittleEndian);
    for (k, d) in to.iter_mut().enumerate().take(len) {
        *d = from.get(k ^ swap).copied().unwrap_or(0) & significant_bits(e, k, len);
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
