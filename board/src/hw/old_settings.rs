//! The settings journal's location before the firmware update (sectors 10 and 11 of the
//! STM32F405, 6 and 7 of the F446: [`memory::OLD_SETTINGS_BASES`]), read only, for the one-time
//! move of the settings into the journal's new sectors
//! ([`SettingsStore::migrate_from`](crate::settings::SettingsStore::migrate_from)).

use crate::memory;
use crate::settings::{FlashError, Sector, SettingsFlash};

/// The old settings sectors as a [`SettingsFlash`] that only reads: erase and program fail with
/// [`FlashError::Controller`] (the migration never calls them).
pub struct OldSettingsFlash {
    _private: (),
}

impl OldSettingsFlash {
    /// The old location of the selected board's chip.
    pub const fn new() -> OldSettingsFlash {
        OldSettingsFlash { _private: () }
    }
}

impl Default for OldSettingsFlash {
    fn default() -> Self {
        OldSettingsFlash::new()
    }
}

impl SettingsFlash for OldSettingsFlash {
    fn sector_len(&self) -> usize {
        memory::OLD_SETTINGS_SECTOR_SIZE as usize
    }

    fn read(&mut self, sector: Sector, offset: usize, buf: &mut [u8]) -> Result<(), FlashError> {
        let size = memory::OLD_SETTINGS_SECTOR_SIZE as usize;
        match offset.checked_add(buf.len()) {
            Some(end) if end <= size => {}
            _ => return Err(FlashError::OutOfBounds),
        }
        let base = memory::OLD_SETTINGS_BASES[sector.index()] as usize + offset;
        // SAFETY: `base..base + buf.len()` lies in one of the chip's old settings sectors (checked
        // above), memory-mapped flash that is always readable; nothing writes it while it is read
        // (this type never erases nor programs).
        let bytes = unsafe { core::slice::from_raw_parts(base as *const u8, buf.len()) };
        buf.copy_from_slice(bytes);
        Ok(())
    }

    fn erase(&mut self, _sector: Sector) -> Result<(), FlashError> {
        Err(FlashError::Controller)
    }

    fn program(&mut self, _sector: Sector, _offset: usize, _data: &[u8]) -> Result<(), FlashError> {
        Err(FlashError::Controller)
    }
}
