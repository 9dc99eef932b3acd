//! The DFU area as the update object uses it: the incoming image in the first 128 KiB page
//! (flash sector 6), its trailer in that page's last 128 bytes, and the chunk log in the second
//! page (sector 7, the swap's spare page, unused until the swap).
//!
//! The log (design page, "Resume after an interruption"): a 16-byte header, then one slot per
//! chunk (4 bytes, or `WRITE_SIZE` when larger), programmed to 0 after its chunk was programmed
//! and read back.
//!
//! | offset in page 2 | size | content |
//! |---|---|---|
//! | 0 | 4 | the announced size (UDINT) |
//! | 4 | 8 | the image ID |
//! | 12 | 4 | magic `DNFL`, last, so that a header torn by a power cut reads as no header |
//! | 16 + n × slot | slot | chunk n: erased = not logged, anything else = logged |
//!
//! A slot that is not erased counts as logged even if a cut tore its write: the log is written
//! only after the chunk was read back, so the chunk is whole. Every write goes to erased flash
//! (plain `NorFlash`, no second write to a word), except a chunk that is sent again: when its
//! flash already holds exactly the chunk, nothing is written (see [`Dfu::program_chunk`]).

use super::{CHUNK_SIZE, PAGE_SIZE};
use embedded_storage::nor_flash::NorFlash;
use fw_image::{ImageHasher, Trailer, TRAILER_LEN};

/// The log header's magic.
const LOG_MAGIC: [u8; 4] = *b"DNFL";
/// The log header's length.
const HEADER_LEN: usize = 16;
/// The longest write the object makes at once (a chunk or the trailer).
const MAX_WRITE: usize = CHUNK_SIZE;

/// What went wrong with the flash.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DfuError {
    /// The driver refused an erase, a program or a read.
    Flash,
    /// A chunk read back differs from what was programmed.
    ReadBack,
    /// The chunk's flash is neither erased nor the chunk (a program torn by a power cut): the
    /// image must start over.
    Torn,
}

/// A flash whose geometry the update object cannot use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeometryError {
    /// The flash is smaller than the two 128 KiB DFU pages.
    Capacity(usize),
    /// `ERASE_SIZE` does not divide 128 KiB.
    EraseSize(usize),
    /// `WRITE_SIZE` does not divide the 16-byte log header (so neither the chunk nor the trailer).
    WriteSize(usize),
    /// `READ_SIZE` does not divide 4.
    ReadSize(usize),
}

impl core::fmt::Display for GeometryError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            GeometryError::Capacity(n) => {
                write!(f, "the DFU flash holds {n} bytes, the update needs 262144")
            }
            GeometryError::EraseSize(n) => write!(f, "erase size {n} does not divide the 128 KiB page"),
            GeometryError::WriteSize(n) => write!(f, "write size {n} does not divide 16"),
            GeometryError::ReadSize(n) => write!(f, "read size {n} does not divide 4"),
        }
    }
}

impl core::error::Error for GeometryError {}

/// The announced image a log belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LogHeader {
    /// The announced size in bytes.
    pub size: u32,
    /// The image ID (the first 8 bytes of the signed file's SHA-512).
    pub image_id: [u8; 8],
}

/// The DFU pages over a `NorFlash` whose offset 0 is the start of DFU.
pub struct Dfu<F> {
    flash: F,
}

impl<F: NorFlash> Dfu<F> {
    /// The DFU area of `flash`, if its geometry fits.
    pub fn new(flash: F) -> Result<Self, GeometryError> {
        if flash.capacity() < 2 * PAGE_SIZE {
            return Err(GeometryError::Capacity(flash.capacity()));
        }
        if F::ERASE_SIZE == 0 || PAGE_SIZE % F::ERASE_SIZE != 0 {
            return Err(GeometryError::EraseSize(F::ERASE_SIZE));
        }
        if F::WRITE_SIZE == 0 || HEADER_LEN % F::WRITE_SIZE != 0 {
            return Err(GeometryError::WriteSize(F::WRITE_SIZE));
        }
        if F::READ_SIZE == 0 || 4 % F::READ_SIZE != 0 {
            return Err(GeometryError::ReadSize(F::READ_SIZE));
        }
        Ok(Self { flash })
    }

    /// The flash back (for a "power cut" in tests: a new object over the same flash).
    pub fn into_flash(self) -> F {
        self.flash
    }

    /// One log slot's length.
    fn slot_len() -> usize {
        F::WRITE_SIZE.max(4)
    }

    /// The flash offset of chunk `n`'s log slot.
    fn slot_offset(n: u32) -> u32 {
        (PAGE_SIZE + HEADER_LEN) as u32 + n * Self::slot_len() as u32
    }

    /// The log header, if a whole one is there.
    pub fn header(&mut self) -> Result<Option<LogHeader>, DfuError> {
        let mut buf = [0u8; HEADER_LEN];
        self.flash.read(PAGE_SIZE as u32, &mut buf).map_err(|_| DfuError::Flash)?;
        let [s0, s1, s2, s3, i0, i1, i2, i3, i4, i5, i6, i7, m0, m1, m2, m3] = buf;
        Ok(([m0, m1, m2, m3] == LOG_MAGIC).then_some(LogHeader {
            size: u32::from_le_bytes([s0, s1, s2, s3]),
            image_id: [i0, i1, i2, i3, i4, i5, i6, i7],
        }))
    }

    /// Erases both pages and writes a new log header: a new image.
    pub fn start(&mut self, header: LogHeader) -> Result<(), DfuError> {
        self.flash.erase(0, (2 * PAGE_SIZE) as u32).map_err(|_| DfuError::Flash)?;
        let mut buf = [0u8; HEADER_LEN];
        for (to, from) in
            buf.iter_mut().zip(header.size.to_le_bytes().into_iter().chain(header.image_id).chain(LOG_MAGIC))
        {
            *to = from;
        }
        self.flash.write(PAGE_SIZE as u32, &buf).map_err(|_| DfuError::Flash)
    }

    /// The first of `chunks` chunks whose slot is erased (`chunks` when all are logged).
    pub fn first_unlogged(&mut self, chunks: u32) -> Result<u32, DfuError> {
        let mut word = [0u8; 4];
        for n in 0..chunks {
            self.flash.read(Self::slot_offset(n), &mut word).map_err(|_| DfuError::Flash)?;
            if word == [0xFF; 4] {
                return Ok(n);
            }
        }
        Ok(chunks)
    }

    /// Programs chunk `n` (`data`, at most 128 bytes; a short last chunk is padded with the erased
    /// value 0xFF to the write size), reads it back, then logs it.
    ///
    /// A chunk sent again after an interruption may find its flash already programmed (a cut
    /// between the chunk and its log slot): then nothing is written if it holds exactly `data`,
    /// and [`DfuError::Torn`] is returned if it holds anything else.
    pub fn program_chunk(&mut self, n: u32, data: &[u8]) -> Result<(), DfuError> {
        let offset = n * CHUNK_SIZE as u32;
        let padded = data.len().div_ceil(F::WRITE_SIZE) * F::WRITE_SIZE;
        let mut buf = [0xFFu8; MAX_WRITE];
        let (Some(head), Some(chunk)) = (buf.get_mut(..data.len()), data.get(..)) else {
            return Err(DfuError::Flash);
        };
        head.copy_from_slice(chunk);
        let Some(want) = buf.get(..padded) else { return Err(DfuError::Flash) };
        let mut have = [0u8; MAX_WRITE];
        let Some(have) = have.get_mut(..padded) else { return Err(DfuError::Flash) };
        self.flash.read(offset, have).map_err(|_| DfuError::Flash)?;
        if have != want {
            if have.iter().any(|&b| b != 0xFF) {
                return Err(DfuError::Torn);
            }
            self.flash.write(offset, want).map_err(|_| DfuError::Flash)?;
            self.flash.read(offset, have).map_err(|_| DfuError::Flash)?;
            if have != want {
                return Err(DfuError::ReadBack);
            }
        }
        let zeros = [0u8; HEADER_LEN];
        let Some(slot) = zeros.get(..Self::slot_len()) else { return Err(DfuError::Flash) };
        self.flash.write(Self::slot_offset(n), slot).map_err(|_| DfuError::Flash)
    }

    /// Reads `buf.len()` bytes at `offset` of the image.
    pub fn read(&mut self, offset: u32, buf: &mut [u8]) -> Result<(), DfuError> {
        self.flash.read(offset, buf).map_err(|_| DfuError::Flash)
    }

    /// SHA-512 of the first `len` bytes of the image.
    pub fn hash(&mut self, len: u32) -> Result<([u8; 64], usize), DfuError> {
        let mut hasher = ImageHasher::new();
        let mut buf = [0u8; CHUNK_SIZE];
        let mut at = 0u32;
        while at < len {
            let n = (len - at).min(CHUNK_SIZE as u32) as usize;
            let Some(piece) = buf.get_mut(..n) else { return Err(DfuError::Flash) };
            self.flash.read(at, piece).map_err(|_| DfuError::Flash)?;
            hasher.update(piece);
            at += n as u32;
        }
        Ok(hasher.finalize())
    }

    /// Stores the trailer in the first page's last 128 bytes, where the bootloader reads it
    /// (nothing is written when it is there already).
    pub fn store_trailer(&mut self, trailer: &Trailer) -> Result<(), DfuError> {
        let offset = (PAGE_SIZE - TRAILER_LEN) as u32;
        let want = trailer.to_bytes();
        let mut have = [0u8; TRAILER_LEN];
        self.flash.read(offset, &mut have).map_err(|_| DfuError::Flash)?;
        if have == want {
            return Ok(());
        }
        if have.iter().any(|&b| b != 0xFF) {
            return Err(DfuError::Torn);
        }
        self.flash.write(offset, &want).map_err(|_| DfuError::Flash)?;
        self.flash.read(offset, &mut have).map_err(|_| DfuError::Flash)?;
        if have == want {
            Ok(())
        } else {
            Err(DfuError::ReadBack)
        }
    }
}
