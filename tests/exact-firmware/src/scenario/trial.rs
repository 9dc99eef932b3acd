//! `trial-confirm` (every board; issue 31): an image the bootloader swapped in runs on trial and
//! confirms itself once on-line. The board's firmware, signed with the repository's TEST key
//! (contrib/keys), is placed in DFU with its trailer and STATE set to SWAP, as the update object's
//! Apply leaves them; at the power-on the bootloader checks it, swaps it into ACTIVE and starts it
//! on trial; once its duplicate MAC ID check passed the firmware must have called `mark_booted`
//! (STATE's magic BOOT, 0xD0), and the master brings it up. The rollback of an image that never
//! confirms is `firmware-update-rollback`'s ([`super::rollback`]).

use super::dfu::{active_holds, flat_image, place_in_dfu, run_until, state, test_signed, BOOT_MAGIC};
use super::world::{bus_with, machine_fault, Options};
use crate::board::BoardKind;
use crate::device::{EmulatedBoard, Firmware};
use can_io::sim::PowerOn;
use devicenet::{Duration, Instant};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;

/// Emulated time the check, the swap (two 128 KiB erases and a page of word programs each way,
/// at the datasheet's timing) and the duplicate MAC ID check take, with room.
pub const SETTLE: Duration = Duration::from_secs(12);

/// The scenario; see the module docs.
pub fn trial_confirm(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let image = flat_image(&elf.elf)?;
    let trailer = test_signed(&image)?.to_bytes();
    let mut device = EmulatedBoard::new(board, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    place_in_dfu(&mut device, &image, &trailer)?;
    let handle = Rc::new(RefCell::new(device));
    let mut bus = bus_with(&handle, options, PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    run_until(&mut session, Instant::ZERO + SETTLE)?;
    machine_fault(&handle)?;
    let state = state(&handle);
    if state != [BOOT_MAGIC; 4] {
        return Err(format!(
            "STATE's magic is {state:02x?} after the trial image came up, not BOOT (confirmed)"
        ));
    }
    if !active_holds(&handle, &image) {
        return Err("ACTIVE does not hold the swapped image byte for byte".into());
    }
    let connected = Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map(|_| ()).map_err(|e| format!("connect to the confirmed image: {e}"))
}
