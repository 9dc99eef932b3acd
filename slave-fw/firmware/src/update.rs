//! The firmware update object (class 0x6A, `slave_fw::update`) on the real boards (issue 31; the
//! design page, docs/src/development/firmware-update.md). The emulated board has none: QEMU
//! models no flash controller, and requests to class 0x6A get 0x16 there.
//!
//! - DFU is flash sectors 6–7 through board's `hw::nor_flash::SlotFlash` (128 KiB erase, word
//!   writes: the object's geometry, checked by `UpdateObject::new`), wrapped in [`FedFlash`],
//!   which feeds the independent watchdog before each sector erase.
//! - Apply marks the image with embassy-boot's `BlockingFirmwareState::mark_updated` over STATE
//!   ([`StateMark`]); the object's Verify has checked it already (below), and the bootloader
//!   checks it again before the swap (`bootloader/src/check.rs`). The object keeps the trailer
//!   in DFU's first page's last 128 bytes, where that check reads it.
//! - The board ID is `board::boards::BOARD_ID`, the running revision the image-info block's
//!   (`crate::image_info`), the public key (attribute 8 is its key ID) and the bootloader's
//!   revision (attribute 10) come from the bootloader's key block in sector 0
//!   (`board::hw::nor_flash::read_key_block`). Without a valid key block there is no object.
//!
//! **Why `mark_updated`, not `verify_and_mark_updated`.** The object's Verify has checked the
//! trailer, the board, the length, the key and the Ed25519 signature over SHA-512 of DFU's image
//! with the bootloader's own key, and a later Transfer (the only other writer of DFU) clears that
//! verdict, so Apply finds DFU as Verify checked it. The bootloader's pre-swap check is the gate
//! that counts (a cut or a bug between Apply and the reset meets it), and it reads the same
//! trailer. A second check here would need embassy-boot's `ed25519-salty` feature and a
//! `FirmwareUpdater` over DFU, and would hash 130,944 bytes and verify again inside Apply's
//! request, for nothing the two other checks do not already do.
//!
//! **Flash stalls.** An erase stalls the CPU (RM0090 §3.5: a read of the array during an erase
//! waits), interrupts included, as the vector table and the code are in flash: Update erases
//! both DFU sectors (two 128 KiB erases, 1 s typical and 2 s at most each at ×32 parallelism by
//! the STM32F405 datasheet's t_ERASE128KB; the unconfirmed figures of the design page), Apply
//! erases STATE (16 KiB). [`FedFlash`] feeds the watchdog before each sector, so each erase has
//! the whole 8.2 s period. During the stall bxCAN keeps receiving into its 3-message FIFO 0;
//! once it is full, further frames for this node are lost (FOVR, counted by the controller,
//! not by the node). Few come: the master waits for Update's response (`master_core::update`
//! gives it 10 s), no I/O connection runs during an update (the object refuses with 0x10), and
//! the acceptance filters pass only frames for this node. SysTick's interrupts are lost too,
//! so the millisecond clock runs about 1 s slow per sector erased: the node's timers take
//! longer, never shorter.
//!
//! **What the stall means for the master and for Apply** (both met on stm32-emu, whose FLASH
//! model stalls code in flash through an erase as the chip does):
//! - The node queues the acknowledgement of a request's last fragment before it serves the
//!   request and sends both after, so Update's two erases (about 2 s) hold that acknowledgement
//!   back past DeviceNet's 1 s fragment acknowledge timeout. `master_core`'s update client waits
//!   for it as long as for the response (docs/src/development/firmware-update.md, "Update's
//!   erase and the acknowledge of its last fragment").
//! - Apply's reset is due `RESET_DELAY` after the request's time, read before STATE's erase; the
//!   millisecond clock stands still during the erase, so the response still has its 100 ms to
//!   leave after it.

use crate::image_info;
use board::flash_layout::{self, DFU, STATE};
use board::hw::nor_flash::{read_key_block, FlashOpError, SlotFlash, StateFlash};
use embassy_boot::{AlignedBuffer, BlockingFirmwareState};
use embedded_storage::nor_flash::{ErrorType, NorFlash, ReadNorFlash};
use fw_image::{Revision, Trailer};
use slave_fw::update::{BootState, MarkError, MarkUpdated, Platform, UpdateObject, PAGE_SIZE};

/// The update object over DFU and STATE.
pub type FirmwareUpdate = UpdateObject<FedFlash, StateMark>;

/// DFU, sectors 6 and 7 (whole 128 KiB sectors, checked at compile time).
const DFU_FLASH: SlotFlash = match SlotFlash::new(DFU) {
    Some(flash) => flash,
    None => panic!("flash_layout::DFU is not whole 128 KiB sectors"),
};
// The object's geometry (`UpdateObject::new` checks it again at run time, `GeometryError`): the
// 128 KiB page is whole erase units, the 16-byte log header whole words, DFU's offset 0 is sector
// 6's first byte and DFU holds the two pages.
const _: () = assert!(PAGE_SIZE % SlotFlash::ERASE_SIZE == 0 && 16 % SlotFlash::WRITE_SIZE == 0);
const _: () = assert!(DFU.first_sector == 6 && DFU.size as usize == 2 * PAGE_SIZE);

/// STATE, sector 3 (one 16 KiB sector, checked at compile time).
const STATE_FLASH: StateFlash = match StateFlash::new(STATE) {
    Some(flash) => flash,
    None => panic!("flash_layout::STATE is not whole 16 KiB sectors"),
};

/// Why there is no update object.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NoUpdate {
    /// Sector 0 holds no valid key block.
    KeyBlock(flash_layout::KeyBlockError),
    /// DFU's geometry does not suit the object (not on these chips).
    Geometry,
}

/// The update object, the running image started as `boot` (`crate::trial`).
///
/// # Errors
/// [`NoUpdate`] when the key block is missing or DFU does not suit the object.
pub fn object(boot: BootState) -> Result<FirmwareUpdate, NoUpdate> {
    let key = read_key_block().map_err(NoUpdate::KeyBlock)?;
    let platform = Platform {
        board_id: board::boards::BOARD_ID,
        running: image_info::INFO.revision,
        public_key: key.public_key,
        bootloader: Revision { major: key.revision.0, minor: key.revision.1 },
        boot,
    };
    UpdateObject::new(FedFlash(DFU_FLASH), StateMark, platform).map_err(|_| NoUpdate::Geometry)
}

/// DFU's flash, the watchdog fed before each 128 KiB sector erase (module docs).
pub struct FedFlash(SlotFlash);

impl ErrorType for FedFlash {
    type Error = FlashOpError;
}

impl ReadNorFlash for FedFlash {
    const READ_SIZE: usize = SlotFlash::READ_SIZE;

    fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashOpError> {
        self.0.read(offset, bytes)
    }

    fn capacity(&self) -> usize {
        self.0.capacity()
    }
}

impl NorFlash for FedFlash {
    const WRITE_SIZE: usize = SlotFlash::WRITE_SIZE;
    const ERASE_SIZE: usize = SlotFlash::ERASE_SIZE;

    fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashOpError> {
        let mut at = from;
        while at < to {
            let end = to.min(at.saturating_add(Self::ERASE_SIZE as u32));
            board::hw::feed_watchdog();
            self.0.erase(at, end)?;
            at = end;
        }
        Ok(())
    }

    fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashOpError> {
        self.0.write(offset, bytes)
    }
}

/// Apply's work: embassy-boot's SWAP magic in STATE (module docs).
pub struct StateMark;

impl MarkUpdated for StateMark {
    fn mark_updated(&mut self, _trailer: &Trailer) -> Result<(), MarkError> {
        let mut state = STATE_FLASH;
        let mut aligned = AlignedBuffer([0u8; flash_layout::WRITE_SIZE as usize]);
        // STATE's erase stalls the CPU too.
        board::hw::feed_watchdog();
        BlockingFirmwareState::new(&mut state, &mut aligned.0).mark_updated().map_err(|_| MarkError)
    }
}
