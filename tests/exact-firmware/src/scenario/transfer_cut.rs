//! `firmware-update-power-cut`'s transfer half (issue 31): a power cut right after the device
//! acknowledged a chunk, half-way through the transfer. `master-core`'s update client sends the
//! board's build at another revision (`<elf>-newer`, as `firmware-update` does); when the device
//! has acknowledged chunk `chunks / 2` (so it must hold it, and its log word, in flash) the whole
//! flash array is taken as a power cut there leaves it. A new board on that array powers up: the
//! old firmware comes up at its revision, and the client, run again, resumes at the next chunk
//! (`chunks / 2 + 1`) and completes: confirmed at the new revision, ACTIVE byte for byte the new
//! image. (A chunk torn by the cut is not done here.)

use super::dfu::{active_holds, fast_flash_board, flat_image, test_signed};
use super::world::{bus_with, machine_fault, Handle, Options};
use crate::board::BoardKind;
use crate::device::Firmware;
use can_io::sim::PowerOn;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use master_core::update::{self, Event, Outcome, Report, UpdateFile};
use std::cell::RefCell;
use std::rc::Rc;

/// The repository's TEST public key (contrib/keys).
const TEST_PUBLIC_KEY: &[u8; 32] = include_bytes!("../../../../contrib/keys/test-ed25519.public");

/// Connects to the board and runs the update; `progress` sees its events.
fn update_on(
    handle: &Handle,
    options: &Options,
    file: &UpdateFile,
    progress: &mut dyn FnMut(Event),
) -> Result<Report, String> {
    let mut bus = bus_with(handle, options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions::default());
    machine_fault(handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let report = update::run(&mut master, options.setting.mac, file, Some(TEST_PUBLIC_KEY), progress);
    machine_fault(handle)?;
    report.map_err(|e| format!("the update: {e}"))
}

/// See the [module docs](self).
pub fn transfer_cut(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let Some(newer) = &elf.newer else {
        return Err("no build at another revision beside the firmware ELF (<elf>-newer)".into());
    };
    let new = flat_image(newer)?;
    let trailer = test_signed(&new)?;
    let mut bytes = new.clone();
    bytes.extend_from_slice(&trailer.to_bytes());
    let file = UpdateFile::parse("newer.bin", bytes).map_err(|e| format!("the signed file: {e}"))?;
    let handle = Rc::new(RefCell::new(fast_flash_board(board, elf, options, None)?));
    let half = file.chunks() / 2;
    let mut cut: Option<Vec<u8>> = None;
    let watched = Rc::clone(&handle);
    let first = update_on(&handle, options, &file, &mut |event| {
        if matches!(event, Event::Chunk { chunk, .. } if chunk == half) {
            cut = Some(watched.borrow_mut().mcu().flash().to_vec());
        }
    })?;
    if first.outcome != Outcome::Confirmed {
        return Err(format!("the uncut update ended {}", first.outcome));
    }
    let mut array = cut.ok_or_else(|| format!("chunk {half} was never acknowledged"))?;
    // The model's array is 1 MiB; the F446 has 512 KiB of it (RM0390).
    if board.spec.chip == board::boards::Chip::Stm32f446re {
        array.truncate(512 * 1024);
    }
    let mut device = fast_flash_board(board, elf, options, None)?;
    device.mcu().program_flash(0, &array).map_err(|e| format!("the array the cut left: {e}"))?;
    let handle = Rc::new(RefCell::new(device));
    let second = update_on(&handle, options, &file, &mut |_| {})
        .map_err(|e| format!("after a cut once chunk {half} was acknowledged: {e}"))?;
    if second.before.revision != first.before.revision {
        return Err(format!(
            "after the cut the device ran {:?}, not the old firmware's {:?}",
            second.before.revision, first.before.revision
        ));
    }
    if second.resumed_at != half + 1
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
    if !active_holds(&handle, &new) {
        return Err("after the resumed update ACTIVE does not hold the new image".into());
    }
    Ok(())
}
