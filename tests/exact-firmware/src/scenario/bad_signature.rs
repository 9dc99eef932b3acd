//! `firmware-update-bad-signature` (every board; issue 31), the bootloader's half: an image the
//! bootloader must refuse is placed in DFU with STATE at SWAP, and at the power-on
//!
//! - the board's own firmware with the next minor revision in its image-info block, signed with
//!   the TEST key, one bit of the signature flipped;
//! - the board's own firmware with another board's ID in its image-info block (the next board
//!   of the board crate's list), correctly signed with the TEST key;
//!
//! each time the bootloader cancels the request (STATE BOOT, 0xD0), nothing is swapped (ACTIVE
//! holds the old firmware and DFU the refused image, byte for byte), no watchdog reset, and the
//! master brings the old firmware up. The refused images differ from the old firmware (the ELF's
//! image) in their image-info block, so a swap would show in ACTIVE even if the swapped image
//! confirmed (STATE BOOT too).
//!
//! Then over the bus: the first file (image and flipped trailer) sent by `master-core`'s update
//! client without a public key, so that the device is the one to check: every chunk goes, Verify
//! is refused with 0xD0/1 (bad signature), STATE is not SWAP, ACTIVE still holds the old firmware
//! and it answers at its revision. The other board's file is not sent: the client refuses it
//! before sending (`check_file`, master-core's tests), so the device's Update refusal (0xD0/2) is
//! not reached here.

use super::dfu::{
    active_holds, dfu_holds, fast_flash_board, flat_image, place_in_dfu, run_until, state, test_signed,
    with_info, BOOT_MAGIC, SWAP_MAGIC,
};
use super::trial::SETTLE;
use super::world::{bus_with, machine_fault, Options};
use crate::board::BoardKind;
use crate::device::{EmulatedBoard, Firmware};
use can_io::sim::PowerOn;
use devicenet::Instant;
use fw_image::ImageInfo;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use master_core::update::{self, Step, UpdateError, UpdateFile};
use std::cell::RefCell;
use std::rc::Rc;

/// The scenario; see the module docs.
pub fn bad_signature(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let old = flat_image(&elf.elf)?;
    let info = ImageInfo::parse(&old).map_err(|e| format!("the firmware's image-info block: {e}"))?;
    let revision = fw_image::Revision { minor: info.revision.minor.wrapping_add(1), ..info.revision };
    let newer = with_info(&old, ImageInfo { revision, ..info });
    let mut flipped = test_signed(&newer)?;
    flipped.signature[17] ^= 0x08;
    refused(board, elf, options, &newer, &flipped.to_bytes())
        .map_err(|e| format!("a signature bit flipped: {e}"))?;
    let ids: Vec<u16> = board::boards::ALL.iter().map(|spec| spec.board_id).collect();
    let at = ids.iter().position(|&id| id == info.board_id).ok_or("the image's board ID is no board's")?;
    let other = ids[(at + 1) % ids.len()];
    if other == info.board_id {
        return Err("the board crate lists one board: no other board's ID".into());
    }
    let foreign = with_info(&old, ImageInfo { board_id: other, ..info });
    let trailer = test_signed(&foreign)?.to_bytes();
    refused(board, elf, options, &foreign, &trailer)
        .map_err(|e| format!("an image signed for board ID {other}: {e}"))?;
    let mut file = newer.clone();
    file.extend_from_slice(&flipped.to_bytes());
    refused_at_verify(board, elf, options, file)
        .map_err(|e| format!("over the bus, a signature bit flipped: {e}"))
}

/// The flipped file sent by `master-core`'s update client without a public key (so that the
/// client does not refuse it itself): every chunk goes, the device refuses Verify with 0xD0/1
/// (bad signature), STATE is not SWAP, ACTIVE holds the old firmware and it still answers at its
/// revision.
fn refused_at_verify(
    board: BoardKind,
    elf: &Firmware,
    options: &Options,
    file: Vec<u8>,
) -> Result<(), String> {
    let old = flat_image(&elf.elf)?;
    let file = UpdateFile::parse("flipped.bin", file).map_err(|e| format!("the signed file: {e}"))?;
    let handle = Rc::new(RefCell::new(fast_flash_board(board, elf, options, None)?));
    let mut bus = bus_with(&handle, options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let mac = options.setting.mac;
    let before = master
        .open_explicit(mac)
        .map_err(UpdateError::from)
        .and_then(|()| update::device_info(&mut master, mac));
    let outcome = update::run(&mut master, mac, &file, None, &mut |_| {});
    machine_fault(&handle)?;
    let before = before.map_err(|e| format!("before: {e}"))?;
    match outcome {
        Err(UpdateError::Refused { step: Step::Verify, general, additional: 1, .. })
            if general.as_raw() == 0xD0 => {}
        other => return Err(format!("the update ended {other:?}, not Verify refused with 0xD0/1")),
    }
    let state = state(&handle);
    if state == [SWAP_MAGIC; 4] || !active_holds(&handle, &old) {
        return Err(format!(
            "after the refusal: STATE {state:02x?}, ACTIVE the old firmware: {}",
            active_holds(&handle, &old)
        ));
    }
    let after = update::device_info(&mut master, mac);
    machine_fault(&handle)?;
    let after = after.map_err(|e| format!("after the refusal: {e}"))?;
    if after.revision != before.revision {
        return Err(format!(
            "the device runs {:?} after the refusal, {:?} before",
            after.revision, before.revision
        ));
    }
    Ok(())
}

/// `image` and `trailer` in DFU, STATE SWAP: after the power-on the request is cancelled and the
/// old firmware comes up unchanged.
fn refused(
    board: BoardKind,
    elf: &Firmware,
    options: &Options,
    image: &[u8],
    trailer: &[u8],
) -> Result<(), String> {
    let old = flat_image(&elf.elf)?;
    let mut device = EmulatedBoard::new(board, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    place_in_dfu(&mut device, image, trailer)?;
    let handle = Rc::new(RefCell::new(device));
    let mut bus = bus_with(&handle, options, PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    run_until(&mut session, Instant::ZERO + SETTLE)?;
    machine_fault(&handle)?;
    let state = state(&handle);
    if state != [BOOT_MAGIC; 4] {
        return Err(format!("STATE's magic is {state:02x?}, not BOOT (the request cancelled)"));
    }
    if !active_holds(&handle, &old) {
        return Err("ACTIVE no longer holds the old firmware".into());
    }
    if !dfu_holds(&handle, image) {
        return Err("DFU no longer holds the refused image (something was swapped)".into());
    }
    let resets = handle.borrow().watchdog_resets();
    if resets != 0 {
        return Err(format!("{resets} watchdog resets"));
    }
    let connected = Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map(|_| ()).map_err(|e| format!("connect to the old firmware: {e}"))
}
