//! `firmware-update-rollback` (every board; issue 31): an image that never confirms is rolled
//! back. The board's `fault-never-confirm` build at another revision (scripts/exact-firmware
//! builds it with `DNET_FW_REVISION=9.9` and keeps it beside the firmware ELF as
//! `<elf>-never-confirm`), signed with the TEST key, is placed in DFU with STATE at SWAP; at the
//! power-on (the FLASH model at `FlashTiming::FAST`, [`fast_flash_board`], for wall time):
//!
//! 1. by [`SETTLE`] the bootloader has swapped it into ACTIVE and started it on trial: ACTIVE
//!    holds it, STATE is still SWAP (it never confirms), no watchdog reset yet;
//! 2. at [`BEFORE_WATCHDOG`] (less than the trial watchdog's 32.8 s after any jump) it still runs:
//!    ACTIVE unchanged, no watchdog reset (a fault that reset the chip earlier would show here);
//! 3. by [`REVERTED`] the watchdog has reset the chip (the IWDG model counts it), the bootloader
//!    has swapped the old image back: ACTIVE holds the old firmware byte for byte, STATE says
//!    REVERT (0xC0, embassy-boot's mark after a revert), and the master brings the old firmware
//!    up.

use super::dfu::{
    active_holds, fast_flash_board, flat_image, place_in_dfu, run_until, state, test_signed, REVERT_MAGIC,
    SWAP_MAGIC,
};
use super::trial::SETTLE;
use super::world::{bus_with, machine_fault, Options};
use crate::board::BoardKind;
use crate::device::Firmware;
use can_io::sim::PowerOn;
use devicenet::{Duration, Instant};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;

/// Before the trial watchdog (32.8 s from the jump, which comes after the swap) can fire.
pub const BEFORE_WATCHDOG: Duration = Duration::from_secs(32);
/// The swap, 32.8 s of trial, the revert (as long as the swap) and the old firmware's duplicate
/// MAC ID check, with room.
pub const REVERTED: Duration = Duration::from_secs(60);

/// The scenario; see the module docs.
pub fn rollback(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let Some(never_confirm) = &elf.never_confirm else {
        return Err("no fault-never-confirm build beside the firmware ELF (<elf>-never-confirm, scripts/exact-firmware builds it)".into());
    };
    let old = flat_image(&elf.elf)?;
    let new = flat_image(never_confirm)?;
    let (old_info, new_info) = (fw_image::ImageInfo::parse(&old), fw_image::ImageInfo::parse(&new));
    match (old_info, new_info) {
        (Ok(o), Ok(n)) if o.board_id == n.board_id && o.revision != n.revision => {}
        other => {
            return Err(format!(
                "the never-confirm image must be this board's at another revision: {other:?}"
            ))
        }
    }
    let trailer = test_signed(&new)?.to_bytes();
    let mut device = fast_flash_board(board, elf, options, None)?;
    place_in_dfu(&mut device, &new, &trailer)?;
    let handle = Rc::new(RefCell::new(device));
    let mut bus = bus_with(&handle, options, PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    for (at, what) in [(SETTLE, "after the swap"), (BEFORE_WATCHDOG, "before the watchdog's time")] {
        run_until(&mut session, Instant::ZERO + at)?;
        machine_fault(&handle)?;
        let (state, resets) = (state(&handle), handle.borrow().watchdog_resets());
        if !active_holds(&handle, &new) || state != [SWAP_MAGIC; 4] || resets != 0 {
            return Err(format!(
                "{what} ({} s): ACTIVE holds the new image: {}, STATE {state:02x?} (want SWAP), {resets} watchdog resets (want 0)",
                at.total_micros() / 1_000_000,
                active_holds(&handle, &new)
            ));
        }
    }
    run_until(&mut session, Instant::ZERO + REVERTED)?;
    let (state, resets) = (state(&handle), handle.borrow().watchdog_resets());
    machine_fault(&handle).map_err(|e| {
        format!(
            "{e} (then: {resets} watchdog resets, STATE {state:02x?}, ACTIVE the old firmware: {}, the new: {})",
            active_holds(&handle, &old),
            active_holds(&handle, &new)
        )
    })?;
    if resets != 1 {
        return Err(format!("{resets} watchdog resets by {} s, not 1", REVERTED.total_micros() / 1_000_000));
    }
    if state != [REVERT_MAGIC; 4] {
        return Err(format!("STATE's magic is {state:02x?} after the rollback, not REVERT"));
    }
    if !active_holds(&handle, &old) {
        return Err("ACTIVE does not hold the old firmware byte for byte after the rollback".into());
    }
    let connected = Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map(|_| ()).map_err(|e| format!("connect to the old firmware after the rollback: {e}"))
}
