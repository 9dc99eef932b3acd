//! The trial boot of a new image and the watchdog (issue 31; the design page,
//! docs/src/development/firmware-update.md, "Confirmation and the watchdog"), real boards only.
//!
//! The bootloader starts the independent watchdog before every jump into the firmware; after a
//! swap it leaves STATE at SWAP, and an image that does not confirm is reverted at the next reset.
//! So this firmware:
//!
//! - reads STATE at start ([`Trial::start`]): SWAP means this image runs on trial, REVERT that
//!   the bootloader rolled the last one back ([`Trial::boot_state`], for the update object);
//! - confirms once the node is on-line (the duplicate MAC ID check passed: [`Trial::online`]),
//!   with embassy-boot's `BlockingFirmwareState::mark_booted` over board's STATE flash driver;
//! - feeds the watchdog from the converter task, which runs at least every LED period
//!   ([`Trial::feed`]), but during a trial only after the confirmation: an image that hangs or
//!   never comes on-line is reset by the watchdog and rolled back.
//!
//! With the self-test feature `fault-never-confirm` (for the rollback scenario of
//! `scripts/exact-firmware`, never in a release build) an image never confirms nor feeds the
//! watchdog during a trial; outside a trial it behaves as any build.

use board::flash_layout;
use board::hw::nor_flash::StateFlash;
use embassy_boot::{AlignedBuffer, BlockingFirmwareState, State};
use slave_fw::update::BootState;

/// The STATE partition as a flash (whole 16 KiB sectors, checked at compile time).
const STATE_FLASH: StateFlash = match StateFlash::new(flash_layout::STATE) {
    Some(flash) => flash,
    None => panic!("flash_layout::STATE is not whole 16 KiB sectors"),
};

/// Whether this image runs on trial, and its confirmation.
pub struct Trial {
    state: StateFlash,
    /// The image runs on trial and has not confirmed yet.
    pending: bool,
    /// STATE said REVERT at start: the bootloader rolled the last image back.
    rolled_back: bool,
}

/// What [`Trial::online`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Confirmation {
    /// Not on trial, or confirmed already.
    NotOnTrial,
    /// STATE now says BOOT: the image stays.
    Confirmed,
    /// STATE could not be written: the image is still on trial (the watchdog will roll it back).
    Failed,
    /// The `fault-never-confirm` build: left on trial on purpose.
    Withheld,
}

impl Trial {
    /// Reads STATE: on trial when it says SWAP. A STATE that cannot be read counts as not on
    /// trial (the bootloader decides at the next reset either way).
    pub fn start() -> Trial {
        let mut state = STATE_FLASH;
        let mut aligned = AlignedBuffer([0u8; flash_layout::WRITE_SIZE as usize]);
        let read = BlockingFirmwareState::new(&mut state, &mut aligned.0).get_state();
        Trial {
            state,
            pending: matches!(read, Ok(State::Swap)),
            rolled_back: matches!(read, Ok(State::Revert)),
        }
    }

    /// How this image was started, for the update object's state (attribute 1): on trial, or
    /// after a rollback (embassy-boot leaves REVERT in STATE until the next update marks one).
    pub const fn boot_state(&self) -> BootState {
        if self.pending {
            BootState::Trial
        } else if self.rolled_back {
            BootState::RolledBack
        } else {
            BootState::Confirmed
        }
    }

    /// This image runs on trial and has not confirmed yet.
    pub const fn is_pending(&self) -> bool {
        self.pending
    }

    /// The node went on-line: confirms the image when it runs on trial.
    pub fn online(&mut self) -> Confirmation {
        if !self.pending {
            return Confirmation::NotOnTrial;
        }
        if cfg!(feature = "fault-never-confirm") {
            return Confirmation::Withheld;
        }
        let mut aligned = AlignedBuffer([0u8; flash_layout::WRITE_SIZE as usize]);
        match BlockingFirmwareState::new(&mut self.state, &mut aligned.0).mark_booted() {
            Ok(()) => {
                self.pending = false;
                Confirmation::Confirmed
            }
            Err(_) => Confirmation::Failed,
        }
    }

    /// Feeds the watchdog, except while the image waits for its confirmation.
    pub fn feed(&self) {
        if !self.pending {
            board::hw::feed_watchdog();
        }
    }
}
