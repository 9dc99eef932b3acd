//! The internal flash as `embedded_storage`'s [`NorFlash`], one type per run of equal sectors, for
//! embassy-boot's partitions ([`crate::flash_layout`]): [`StateFlash`] (sector 3, erase size
//! 16 KiB) and [`SlotFlash`] (ACTIVE and DFU, 128 KiB). STM32F4 sectors differ in size (RM0090
//! §3.3 table 5), and `NorFlash::ERASE_SIZE` is a constant of the type, so one type per size.
//!
//! Programming is by 32-bit word (PSIZE x32, the parallelism for a 2.7–3.6 V supply, RM0090 §3.5.2;
//! `WRITE_SIZE` 4), erasing by sector, both in the sequences of RM0090 §3.6: unlock through
//! FLASH_KEYR (§3.5.1) if FLASH_CR is locked, wait for BSY clear, set SER and SNB (or PG), start,
//! wait for BSY clear, read the error flags of FLASH_SR (§3.9.4: WRPERR, PGAERR, PGPERR, PGSERR,
//! OPERR) and clear them, clear SER/PG and lock again. The settings journal
//! (`hw::InternalFlash`) erases and programs through stm32f4xx-hal's `LockedFlash` instead, whose
//! `NorFlash` declares one 128 KiB erase size for the whole array and programs bytes (PSIZE x8):
//! neither fits embassy-boot's 16 KiB STATE nor its word-sized progress marks.
//!
//! [`read_key_block`] reads the bootloader's key block (end of sector 0) for the firmware's update
//! object, through the same read path.
//!
//! Reads are plain memory reads of the memory-mapped array. The data cache (FLASH_ACR DCEN, off
//! after reset, on when the firmware's HAL enables it) is reset after every erase and program, so
//! that no stale line is read back after the array changed underneath it.

use core::sync::atomic::{compiler_fence, Ordering};

use embedded_storage::nor_flash::{
    check_erase, check_read, check_write, ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use stm32f4xx_hal::pac;

use crate::flash_layout::{
    self, KeyBlock, KeyBlockError, Partition, KEY_BLOCK_ADDRESS, KEY_BLOCK_LEN, LARGE_SECTOR_SIZE,
    SMALL_SECTOR_SIZE,
};

/// STATE's flash: 16 KiB sectors.
pub type StateFlash = FlashSectors<{ SMALL_SECTOR_SIZE as usize }>;
/// ACTIVE's and DFU's flash: 128 KiB sectors.
pub type SlotFlash = FlashSectors<{ LARGE_SECTOR_SIZE as usize }>;

/// FLASH_KEYR's unlock sequence (RM0090 §3.5.1).
const KEY1: u32 = 0x4567_0123;
const KEY2: u32 = 0xCDEF_89AB;
/// FLASH_CR bits (RM0090 §3.9.5).
const CR_PG: u32 = 1 << 0;
const CR_SER: u32 = 1 << 1;
const CR_SNB_SHIFT: u32 = 3;
const CR_PSIZE_X32: u32 = 0b10 << 8;
const CR_STRT: u32 = 1 << 16;
const CR_LOCK: u32 = 1 << 31;
/// FLASH_SR bits (RM0090 §3.9.4).
const SR_OPERR: u32 = 1 << 1;
const SR_WRPERR: u32 = 1 << 4;
const SR_PGAERR: u32 = 1 << 5;
const SR_PGPERR: u32 = 1 << 6;
const SR_PGSERR: u32 = 1 << 7;
const SR_BSY: u32 = 1 << 16;
const SR_ERRORS: u32 = SR_OPERR | SR_WRPERR | SR_PGAERR | SR_PGPERR | SR_PGSERR;
/// FLASH_ACR's data cache bits (RM0090 §3.9.1).
const ACR_DCEN: u32 = 1 << 10;
const ACR_DCRST: u32 = 1 << 12;

/// Why a flash operation failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlashOpError {
    /// The range is outside the partition.
    OutOfBounds,
    /// The offset or length is not a multiple of the write or erase size.
    NotAligned,
    /// FLASH_CR stayed locked after the unlock sequence.
    Locked,
    /// WRPERR: the sector is write protected (option bytes nWRP).
    WriteProtection,
    /// PGAERR: a write not aligned to the parallelism.
    ProgrammingAlignment,
    /// PGPERR: a write whose size is not the parallelism (PSIZE).
    ProgrammingParallelism,
    /// PGSERR: a write or erase out of sequence (e.g. PG not set).
    ProgrammingSequence,
    /// OPERR: the operation failed (error interrupts only; kept for completeness).
    Operation,
}

impl FlashOpError {
    /// The first error flag set in a FLASH_SR value, if any.
    const fn from_sr(sr: u32) -> Option<FlashOpError> {
        if sr & SR_WRPERR != 0 {
            Some(FlashOpError::WriteProtection)
        } else if sr & SR_PGAERR != 0 {
            Some(FlashOpError::ProgrammingAlignment)
        } else if sr & SR_PGPERR != 0 {
            Some(FlashOpError::ProgrammingParallelism)
        } else if sr & SR_PGSERR != 0 {
            Some(FlashOpError::ProgrammingSequence)
        } else if sr & SR_OPERR != 0 {
            Some(FlashOpError::Operation)
        } else {
            None
        }
    }
}

impl NorFlashError for FlashOpError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashOpError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashOpError::NotAligned => NorFlashErrorKind::NotAligned,
            _ => NorFlashErrorKind::Other,
        }
    }
}

impl core::fmt::Display for FlashOpError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FlashOpError::OutOfBounds => "outside the partition",
            FlashOpError::NotAligned => "not aligned to the write or erase size",
            FlashOpError::Locked => "FLASH_CR stayed locked",
            FlashOpError::WriteProtection => "write protected (WRPERR)",
            FlashOpError::ProgrammingAlignment => "programming alignment error (PGAERR)",
            FlashOpError::ProgrammingParallelism => "programming parallelism error (PGPERR)",
            FlashOpError::ProgrammingSequence => "programming sequence error (PGSERR)",
            FlashOpError::Operation => "operation error (OPERR)",
        })
    }
}

/// A partition of whole flash sectors of `ERASE_SIZE` bytes each, as a [`NorFlash`] whose offset 0
/// is the partition's first byte.
///
/// It reaches the FLASH registers through the PAC's pointer, so the bootloader's three partitions
/// share the one controller; each operation is complete (BSY clear, the controller locked again)
/// when its call returns, so they never interleave as long as no interrupt handler uses the flash.
#[derive(Debug)]
pub struct FlashSectors<const ERASE_SIZE: usize> {
    partition: Partition,
}

impl<const ERASE_SIZE: usize> FlashSectors<ERASE_SIZE> {
    /// The partition as a flash, or `None` when one of its sectors is not `ERASE_SIZE` bytes.
    pub const fn new(partition: Partition) -> Option<Self> {
        let mut at = partition.base;
        while at < partition.end() {
            match flash_layout::sector_of(at) {
                Some(sector) if sector.size as usize == ERASE_SIZE => at = sector.end(),
                _ => return None,
            }
        }
        Some(FlashSectors { partition })
    }

    /// The partition it covers.
    pub const fn partition(&self) -> Partition {
        self.partition
    }
}

/// The bootloader's three partitions ([`flash_layout::STATE`], [`flash_layout::ACTIVE`],
/// [`flash_layout::DFU`]), made from the FLASH peripheral.
pub struct UpdateFlash {
    /// Sector 3.
    pub state: StateFlash,
    /// Sector 5.
    pub active: SlotFlash,
    /// Sectors 6 and 7.
    pub dfu: SlotFlash,
}

impl UpdateFlash {
    /// Takes the flash controller for the three partitions.
    pub fn new(_flash: pac::FLASH) -> UpdateFlash {
        const STATE: Option<StateFlash> = StateFlash::new(flash_layout::STATE);
        const ACTIVE: Option<SlotFlash> = SlotFlash::new(flash_layout::ACTIVE);
        const DFU: Option<SlotFlash> = SlotFlash::new(flash_layout::DFU);
        // Checked at compile time: each partition is whole sectors of its type's size.
        const PARTS: (StateFlash, SlotFlash, SlotFlash) = match (STATE, ACTIVE, DFU) {
            (Some(s), Some(a), Some(d)) => (s, a, d),
            _ => panic!("a partition of flash_layout is not whole sectors of its erase size"),
        };
        let (state, active, dfu) = PARTS;
        UpdateFlash { state, active, dfu }
    }
}

/// Reads the bootloader's key block ([`KEY_BLOCK_ADDRESS`], the end of sector 0): the key and the
/// revision the firmware's update object reports and checks with. Only reads.
///
/// # Errors
/// [`KeyBlockError`] when the bytes there are not a key block (no bootloader, another layout).
pub fn read_key_block() -> Result<KeyBlock, KeyBlockError> {
    // Checked at compile time: sector 0 is one 16 KiB sector.
    const SECTOR_0: StateFlash = match StateFlash::new(flash_layout::BOOTLOADER) {
        Some(flash) => flash,
        None => panic!("flash_layout::BOOTLOADER is not one 16 KiB sector"),
    };
    let mut sector = SECTOR_0;
    // The block lies inside sector 0 (flash_layout's tests), so the bounds check passes; were it
    // ever to fail, the erased bytes left in `bytes` fail the CRC.
    let mut bytes = [0xFFu8; KEY_BLOCK_LEN];
    let _ = sector.read(KEY_BLOCK_ADDRESS - flash_layout::BOOTLOADER.base, &mut bytes);
    KeyBlock::parse(&bytes)
}

fn registers() -> &'static pac::flash::RegisterBlock {
    // SAFETY: the FLASH register block's fixed address; every access below is a volatile register
    // access, and operations run to completion within one call (type docs).
    unsafe { &*pac::FLASH::ptr() }
}

/// Waits for BSY clear, then returns and clears the error flags.
fn wait_and_check(flash: &pac::flash::RegisterBlock) -> Result<(), FlashOpError> {
    while flash.sr().read().bits() & SR_BSY != 0 {}
    let sr = flash.sr().read().bits();
    // SAFETY: writing 1 to an error flag clears it; 0 bits leave the others.
    flash.sr().write(|w| unsafe { w.bits(sr & SR_ERRORS) });
    match FlashOpError::from_sr(sr) {
        Some(error) => Err(error),
        None => Ok(()),
    }
}

/// Runs `operation` with FLASH_CR unlocked (RM0090 §3.5.1), then clears PG/SER, locks FLASH_CR and
/// resets the data cache.
fn unlocked<T>(
    operation: impl FnOnce(&pac::flash::RegisterBlock) -> Result<T, FlashOpError>,
) -> Result<T, FlashOpError> {
    let flash = registers();
    if flash.cr().read().bits() & CR_LOCK != 0 {
        // SAFETY: the documented key values.
        flash.keyr().write(|w| unsafe { w.bits(KEY1) });
        flash.keyr().write(|w| unsafe { w.bits(KEY2) });
        if flash.cr().read().bits() & CR_LOCK != 0 {
            return Err(FlashOpError::Locked);
        }
    }
    // Flags left by an earlier operation would be taken for this one's.
    wait_and_check(flash).ok();
    let result = operation(flash);
    // SAFETY: LOCK set, PG/SER/STRT clear: the controller's idle value.
    flash.cr().write(|w| unsafe { w.bits(CR_LOCK) });
    let acr = flash.acr().read().bits();
    if acr & ACR_DCEN != 0 {
        // SAFETY: DCEN off, DCRST on, then the old value (RM0090 §3.9.1: reset only while disabled).
        flash.acr().write(|w| unsafe { w.bits((acr & !ACR_DCEN) | ACR_DCRST) });
        flash.acr().write(|w| unsafe { w.bits(acr) });
    }
    compiler_fence(Ordering::SeqCst);
    result
}

impl<const ERASE_SIZE: usize> ErrorType for FlashSectors<ERASE_SIZE> {
    type Error = FlashOpError;
}

impl<const ERASE_SIZE: usize> ReadNorFlash for FlashSectors<ERASE_SIZE> {
    const READ_SIZE: usize = 1;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashOpError> {
        check_read(self, offset, bytes.len()).map_err(|_| FlashOpError::OutOfBounds)?;
        compiler_fence(Ordering::SeqCst);
        let from = (self.partition.base + offset) as *const u8;
        // SAFETY: the range lies in the partition (checked above), which is mapped flash.
        let source = unsafe { core::slice::from_raw_parts(from, bytes.len()) };
        bytes.copy_from_slice(source);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.partition.size as usize
    }
}

impl<const ERASE_SIZE: usize> NorFlash for FlashSectors<ERASE_SIZE> {
    const WRITE_SIZE: usize = flash_layout::WRITE_SIZE as usize;
    const ERASE_SIZE: usize = ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashOpError> {
        check_erase(self, from, to).map_err(kind_error)?;
        let mut at = self.partition.base + from;
        while at < self.partition.base + to {
            let sector = flash_layout::sector_of(at).ok_or(FlashOpError::OutOfBounds)?;
            erase_sector(sector)?;
            at = sector.end();
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashOpError> {
        check_write(self, offset, bytes.len()).map_err(kind_error)?;
        program(self.partition.base + offset, bytes)
    }
}

// The two operations apart from `FlashSectors`' erase size, so that each is in the firmware once
// however many partition types it uses.

/// Erases `sector`, a sector of a partition (checked by the caller).
fn erase_sector(sector: Partition) -> Result<(), FlashOpError> {
    // RM0090 §3.6.3: SER and SNB (with PSIZE), then STRT, then wait for BSY.
    unlocked(|flash| {
        let cr = CR_SER | CR_PSIZE_X32 | (u32::from(sector.first_sector) << CR_SNB_SHIFT);
        // SAFETY: SER, SNB of a sector in the partition, PSIZE x32.
        flash.cr().write(|w| unsafe { w.bits(cr) });
        flash.cr().write(|w| unsafe { w.bits(cr | CR_STRT) });
        wait_and_check(flash)
    })
}

/// Programs `bytes` (whole words) at `base`, a word-aligned address of a partition with room for
/// them (checked by the caller).
fn program(base: u32, bytes: &[u8]) -> Result<(), FlashOpError> {
    unlocked(|flash| {
        // RM0090 §3.6.4: PG with PSIZE x32, then one word at a time, each waited for.
        // SAFETY: PG and PSIZE x32.
        flash.cr().write(|w| unsafe { w.bits(CR_PG | CR_PSIZE_X32) });
        for (i, word) in bytes.chunks_exact(4).enumerate() {
            let value = u32::from_le_bytes([word[0], word[1], word[2], word[3]]);
            let address = (base + 4 * i as u32) as *mut u32;
            // SAFETY: a word-aligned address in the partition (checked by the caller) while PG is
            // set: the controller programs it.
            unsafe { core::ptr::write_volatile(address, value) };
            wait_and_check(flash)?;
        }
        Ok(())
    })
}

fn kind_error(error: NorFlashErrorKind) -> FlashOpError {
    match error {
        NorFlashErrorKind::NotAligned => FlashOpError::NotAligned,
        _ => FlashOpError::OutOfBounds,
    }
}
