//! `trial-confirm` (every board; issue 31): an image the bootloader swapped in runs on trial and
//! confirms itself once on-line. The board's firmware, signed with the repository's TEST key
//! (contrib/keys), is placed in DFU with its trailer and STATE set to SWAP, as the update object's
//! Apply leaves them; at the power-on the bootloader checks it, swaps it into ACTIVE and starts it
//! on trial; once its duplicate MAC ID check passed the firmware must have called `mark_booted`
//! (STATE's magic BOOT, 0xD0), and the master brings it up. The rollback of an image that never
//! confirms is the update scenarios' (`fault-never-confirm`).

use super::world::{bus_with, machine_fault, Options};
use crate::board::BoardKind;
use crate::device::{EmulatedBoard, Firmware};
use board::flash_layout::{ACTIVE, DFU, MAX_IMAGE_LEN, STATE};
use board::memory::FLASH_BASE;
use can_io::sim::PowerOn;
use devicenet::{Duration, Instant};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;

/// The repository's TEST signing seed (contrib/keys/README.md: never for a release).
const TEST_SEED: &[u8; 32] = include_bytes!("../../../../contrib/keys/test-ed25519.secret");
/// embassy-boot's STATE magics.
const SWAP_MAGIC: u8 = 0xF0;
const BOOT_MAGIC: u8 = 0xD0;
/// Emulated time the check, the swap (two 128 KiB erases and a page of word programs each way,
/// at the datasheet's timing) and the duplicate MAC ID check take, with room.
const SETTLE: Duration = Duration::from_secs(12);

/// The flat image of the firmware ELF from ACTIVE's start (gaps 0xFF), as sign-firmware makes it.
fn flat_image(elf: &[u8]) -> Result<Vec<u8>, String> {
    let segments = stm32_emu::cpu::elf::load_segments(elf).map_err(|e| format!("the firmware ELF: {e}"))?;
    let mut image = Vec::new();
    for (address, data) in segments {
        let Some(offset) = address.checked_sub(ACTIVE.base).map(|o| o as usize) else {
            return Err(format!("a segment at {address:#010x} below ACTIVE"));
        };
        if image.len() < offset + data.len() {
            image.resize(offset + data.len(), 0xFF);
        }
        image[offset..offset + data.len()].copy_from_slice(data);
    }
    Ok(image)
}

/// The scenario; see the module docs.
pub fn trial_confirm(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let image = flat_image(&elf.elf)?;
    let trailer = fw_image::sign(&image, TEST_SEED).map_err(|e| format!("signing: {e}"))?.to_bytes();
    let mut device = EmulatedBoard::new(board, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    {
        let mcu = device.mcu();
        let dfu = DFU.base - FLASH_BASE;
        mcu.program_flash(dfu, &image).map_err(|e| format!("DFU: {e}"))?;
        mcu.program_flash(dfu + MAX_IMAGE_LEN, &trailer).map_err(|e| format!("the trailer: {e}"))?;
        mcu.program_flash(STATE.base - FLASH_BASE, &[SWAP_MAGIC; 4]).map_err(|e| format!("STATE: {e}"))?;
    }
    let handle = Rc::new(RefCell::new(device));
    let mut bus = bus_with(&handle, options, PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    let settled = Instant::ZERO + SETTLE;
    while session.now() < settled {
        if session.next(settled).map_err(|e| format!("the bus: {e}"))?.is_none() {
            break;
        }
    }
    machine_fault(&handle)?;
    let state = handle.borrow().mcu_flash(STATE.base, 4);
    if state != [BOOT_MAGIC; 4] {
        return Err(format!(
            "STATE's magic is {state:02x?} after the trial image came up, not BOOT (confirmed)"
        ));
    }
    let active = handle.borrow().mcu_flash(ACTIVE.base, image.len());
    if active != image {
        return Err("ACTIVE does not hold the swapped image byte for byte".into());
    }
    let connected = Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map(|_| ()).map_err(|e| format!("connect to the confirmed image: {e}"))
}
