//! `firmware-update-power-cut`'s transfer half (issue 31): a power cut after **every** chunk of
//! the transfer. `master-core`'s update client sends the board's build at another revision
//! (`<elf>-newer`, as `firmware-update` does) once, uncut; each time the device has acknowledged
//! chunk `n` (so it holds the chunk and its log word in flash) the DFU sectors are taken as a
//! power cut there leaves them (nothing else changes in the array during the transfer: STATE
//! only at Apply). Then, for every `n`, one board (one machine, powered down between) powers up
//! on the array of before the update with DFU as the cut after chunk `n` left it, together with
//! the master (their duplicate MAC ID checks overlap): the old firmware comes up at its revision, and
//! the client's Update (`master_core::update::announce`) is answered with the resume point
//! `n + 1`. On the cut after the middle chunk the client then runs the whole update again: it
//! resumes there and completes, confirmed at the new revision, ACTIVE byte for byte the new
//! image. (A chunk torn half-way by a cut is not here: the object finds it neither erased nor
//! the chunk and starts the image over, `slave_fw::update`'s tests.)

use super::dfu::{active_holds, fast_flash_board, newer_file, NewerFile, TEST_PUBLIC_KEY};
use super::world::{with_master, Handle, Options};
use crate::board::BoardKind;
use crate::device::Firmware;
use board::flash_layout::DFU;
use can_io::sim::PowerOn;
use fw_image::Revision;
use master_core::update::{self, Event, Outcome, Report, UpdateFile};
use std::cell::RefCell;
use std::rc::Rc;

/// Connects to the board and runs the update; `progress` sees its events.
fn update_on(
    handle: &Handle,
    options: &Options,
    file: &UpdateFile,
    progress: &mut dyn FnMut(Event),
) -> Result<Report, String> {
    with_master(handle, options, PowerOn::WhenMasterOnline, |master| {
        update::run(master, options.setting.mac, file, Some(TEST_PUBLIC_KEY), progress)
            .map_err(|e| format!("the update: {e}"))
    })
}

/// The DFU sectors (`board::flash_layout::DFU`) from the flash array.
fn dfu_of(array: &[u8]) -> Vec<u8> {
    let start = (DFU.base - board::memory::FLASH_BASE) as usize;
    array[start..start + DFU.size as usize].to_vec()
}

/// Puts `array` with DFU replaced by `dfu` into the (powered-down) board's flash, as a power
/// cut left it: the same machine powers up on it again, as after `power-cycle`.
fn cut_array(handle: &Handle, array: &[u8], dfu: &[u8]) -> Result<(), String> {
    let mut array = array.to_vec();
    let start = (DFU.base - board::memory::FLASH_BASE) as usize;
    array[start..start + dfu.len()].copy_from_slice(dfu);
    let mut device = handle.borrow_mut();
    // The model's array is 1 MiB; the F446 has 512 KiB of it (RM0390).
    if device.kind().spec.chip == board::boards::Chip::Stm32f446re {
        array.truncate(512 * 1024);
    }
    device.mcu().program_flash(0, &array).map_err(|e| format!("the array the cut left: {e}"))
}

/// Powers the board up, connects, and asks where the transfer of `file` resumes: the running
/// revision (class 0x6A attribute 2) and Update's next chunk.
fn resume_point(handle: &Handle, options: &Options, file: &UpdateFile) -> Result<(Revision, u32), String> {
    // The board powers up with the master: their duplicate MAC ID checks overlap (2 s of
    // emulation less per cut than after the master's own).
    with_master(handle, options, PowerOn::AtStart, |master| {
        let mac = options.setting.mac;
        master
            .open_explicit(mac)
            .map_err(update::UpdateError::from)
            .and_then(|()| update::device_info(master, mac))
            .and_then(|info| Ok((info.revision, update::announce(master, mac, file, file.chunks())?)))
            .map_err(|e| e.to_string())
    })
}

/// See the [module docs](self).
pub fn transfer_cut(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let NewerFile { image: new, trailer, file } = newer_file(elf)?;
    let handle = Rc::new(RefCell::new(fast_flash_board(board, elf, options, None)?));
    let before = handle.borrow_mut().mcu().flash().to_vec();
    let mut cuts: Vec<Vec<u8>> = Vec::new();
    let watched = Rc::clone(&handle);
    let first = update_on(&handle, options, &file, &mut |event| {
        if let Event::Chunk { chunk, .. } = event {
            if usize::try_from(chunk).is_ok_and(|c| c == cuts.len()) {
                cuts.push(dfu_of(watched.borrow_mut().mcu().flash()));
            }
        }
    })?;
    if first.outcome != Outcome::Confirmed {
        return Err(format!("the uncut update ended {}", first.outcome));
    }
    if cuts.len() != file.chunks() as usize {
        return Err(format!("{} of {} chunks acknowledged in order", cuts.len(), file.chunks()));
    }
    let device = Rc::new(RefCell::new(fast_flash_board(board, elf, options, None)?));
    for (n, dfu) in cuts.iter().enumerate() {
        cut_array(&device, &before, dfu)?;
        let (revision, next) = resume_point(&device, options, &file)
            .map_err(|e| format!("after a cut once chunk {n} was acknowledged: {e}"))?;
        if revision != first.before.revision || next as usize != n + 1 {
            return Err(format!(
                "after a cut once chunk {n} was acknowledged: revision {revision:?} (want the old {:?}), resume at chunk {next} (want {})",
                first.before.revision,
                n + 1
            ));
        }
    }
    let half = cuts.len() / 2;
    cut_array(&device, &before, &cuts[half])?;
    let second = update_on(&device, options, &file, &mut |_| {})
        .map_err(|e| format!("after a cut once chunk {half} was acknowledged: {e}"))?;
    if second.before.revision != first.before.revision {
        return Err(format!(
            "after the cut the device ran {:?}, not the old firmware's {:?}",
            second.before.revision, first.before.revision
        ));
    }
    if second.resumed_at as usize != half + 1
        || second.outcome != Outcome::Confirmed
        || second.revision != trailer.revision
    {
        return Err(format!(
            "after a cut once chunk {half} was acknowledged: resumed at chunk {} (want {}), {} at {:?}",
            second.resumed_at,
            half + 1,
            second.outcome,
            second.revision
        ));
    }
    if !active_holds(&device, &new) {
        return Err("after the resumed update ACTIVE does not hold the new image".into());
    }
    Ok(())
}
