//! `firmware-update-power-cut` (every board; issue 31): the transfer half is
//! [`super::transfer_cut`]'s, run after this one. The swap half: a power cut at a sample of
//! the bootloader's flash operations while it swaps a new image in, then power again: the new
//! image comes up and confirms, ACTIVE byte for byte.
//!
//! The new image is the board's own firmware at the next minor revision (its image-info block
//! changed only), signed with the TEST key, in DFU with STATE at SWAP; the FLASH model runs at
//! `FlashTiming::FAST` ([`fast_flash_board`]) for wall time.
//!
//! 1. **Record** (as `download-cut` does, [`super::download_cut`]): the swap runs once on a
//!    fresh board, the CPU in slices of [`SLICE`]; after each, the operations the FLASH model
//!    started are taken with `FLASH_CR` (an erase: SER; a program: PG) and whether STATE's bytes
//!    changed (a progress word) or not (the image's data). The swap is over when no operation
//!    started for [`QUIET`].
//! 2. **Cut.** The cut points: every erase and every progress word, both before the operation
//!    starts and torn half-way, and the first and last data program of each page torn
//!    (stm32-emu's `CutKind::Before` and `CutKind::Torn`: the FLASH model's own planned cut, counted from the
//!    power-up, [`EmulatedBoard::with_power_cut`](crate::device::EmulatedBoard::with_power_cut)
//!    done on a FAST model).
//! 3. **Power up again** on the array the cut left (a new board with that array: the FLASH model
//!    ignores every write after its cut): within [`SETTLE`] (looked at every [`STEP`]) the bootloader has finished the
//!    swap from its progress words and the new image has confirmed (STATE BOOT), ACTIVE holds it
//!    byte for byte, and no watchdog reset happened. The master brings the image of the last
//!    cut up.

use super::dfu::BOOT_MAGIC;
use super::dfu::{
    active_holds, fast_flash_board, old_and_newer, place_in_dfu, run_until, state, test_signed,
};
use super::world::{bus_with, machine_fault, Handle, Options};
use crate::board::BoardKind;
use crate::device::Firmware;
use board::flash_layout::STATE;
use can_io::sim::PowerOn;
use devicenet::{Duration, Instant};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;
use stm32_emu::flash::{self, CutKind};
use stm32_emu::machine::Stm32;
use stm32_emu::periph::Nanos;

/// The CPU's slice while the swap is recorded: a quarter of a word program (16 µs).
pub const SLICE: Nanos = 4_000;
/// No flash operation for this long ends the recording (the swap's longest gap between two
/// operations is a 2 KiB read between chunks, microseconds).
pub const QUIET: Duration = Duration::from_millis(50);
/// Recording stops with an error past this (the swap takes about a second at FAST timing).
pub const RECORD_LIMIT: Duration = Duration::from_secs(8);
/// After the power comes back: the rest of the swap, the start and the duplicate MAC ID check,
/// the confirmation, with room.
pub const SETTLE: Duration = Duration::from_secs(5);
/// How often a cut run looks whether the cut happened, and a powered-up one whether the image
/// confirmed.
pub const STEP: Duration = Duration::from_millis(20);
/// `FLASH_CR`'s offset (RM0090 §3.9.8).
const FLASH_CR: u32 = 0x10;

/// What a flash operation of the swap is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Erase,
    Progress,
    Data,
}

/// What the slice watch collects.
struct Recorder {
    /// STATE's bytes as last seen.
    state: Vec<u8>,
    seen: u64,
    /// Each operation's index (from the model's start) and kind.
    operations: Vec<(u64, Kind)>,
    error: Option<String>,
}

impl Recorder {
    fn after_slice(&mut self, mcu: &mut Stm32) {
        let count = mcu.flash_operations().unwrap_or(0);
        if count == self.seen {
            return;
        }
        let (first, started) = (self.seen, count - self.seen);
        self.seen = count;
        let cr = mcu.read_peripheral(flash::BASE + FLASH_CR).unwrap_or(0);
        let start = (STATE.base - board::memory::FLASH_BASE) as usize;
        let now = &mcu.flash()[start..start + self.state.len()];
        let state_changed = now != self.state.as_slice();
        if state_changed {
            self.state.copy_from_slice(now);
        }
        let kind = match (cr & flash::cr::SER != 0, state_changed) {
            (true, _) => Kind::Erase,
            (false, true) => Kind::Progress,
            (false, false) => Kind::Data,
        };
        if started > 1 && kind != Kind::Data && self.error.is_none() {
            self.error =
                Some(format!("{started} flash operations in one {SLICE} ns slice, one of them {kind:?}"));
        }
        self.operations.extend((first..count).map(|i| (i, kind)));
    }
}

/// Runs the swap once, its flash operations recorded.
fn record(
    board: BoardKind,
    elf: &Firmware,
    options: &Options,
    new: &[u8],
    trailer: &[u8],
) -> Result<Vec<(u64, Kind)>, String> {
    let mut device = fast_flash_board(board, elf, options, None)?;
    place_in_dfu(&mut device, new, trailer)?;
    let recorder = Rc::new(RefCell::new(Recorder {
        state: device.mcu_flash(STATE.base, STATE.size as usize),
        seen: device.flash_operations(),
        operations: Vec::new(),
        error: None,
    }));
    let watch = Rc::clone(&recorder);
    device.watch(Some((SLICE, Box::new(move |mcu| watch.borrow_mut().after_slice(mcu)))));
    let handle = Rc::new(RefCell::new(device));
    let mut bus = bus_with(&handle, options, PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    let mut last = (0, Instant::ZERO);
    loop {
        let at = session.now() + QUIET;
        run_until(&mut session, at)?;
        machine_fault(&handle)?;
        let count = recorder.borrow().operations.len();
        if count > 0 && count == last.0 {
            break;
        }
        if session.now() > Instant::ZERO + RECORD_LIMIT {
            return Err(format!(
                "recording: the swap still runs after {} s ({count} operations)",
                RECORD_LIMIT.total_micros() / 1_000_000
            ));
        }
        last = (count, session.now());
    }
    handle.borrow_mut().watch(None);
    let recorder = recorder.borrow();
    if let Some(error) = &recorder.error {
        return Err(format!("recording the swap: {error}"));
    }
    Ok(recorder.operations.clone())
}

/// The cut points of a recording (module docs), in order: every erase and progress word not
/// started and torn, the first and last data program of each page torn.
fn cut_points(operations: &[(u64, Kind)]) -> Vec<(u64, CutKind)> {
    let mut points = Vec::new();
    for (i, &(index, kind)) in operations.iter().enumerate() {
        let previous = i.checked_sub(1).map(|p| operations[p].1);
        let next = operations.get(i + 1).map(|o| o.1);
        match kind {
            Kind::Erase | Kind::Progress => {
                points.push((index, CutKind::Before));
                points.push((index, CutKind::Torn));
            }
            Kind::Data if previous != Some(Kind::Data) || next != Some(Kind::Data) => {
                points.push((index, CutKind::Torn));
            }
            Kind::Data => {}
        }
    }
    points
}

/// Runs the bus in steps of [`STEP`] while `going` holds, up to `limit` from its start.
fn run_while(
    session: &mut Session<'_>,
    limit: Duration,
    mut going: impl FnMut() -> bool,
) -> Result<(), String> {
    while going() && session.now() < Instant::ZERO + limit {
        let at = session.now() + STEP;
        run_until(session, at)?;
    }
    Ok(())
}

/// A power cut at operation `index` (`how`), then power again: the swap finishes and the new
/// image confirms.
fn cut_and_power_up(
    board: BoardKind,
    elf: &Firmware,
    options: &Options,
    (new, trailer): (&[u8], &[u8]),
    (index, how): (u64, CutKind),
) -> Result<Handle, String> {
    let mut device = fast_flash_board(board, elf, options, Some((index, how)))?;
    place_in_dfu(&mut device, new, trailer)?;
    let handle = Rc::new(RefCell::new(device));
    {
        let mut bus = bus_with(&handle, options, PowerOn::AtStart);
        let mut session = Session::new(&mut bus);
        run_while(&mut session, RECORD_LIMIT, || handle.borrow().power_cut().is_none())?;
    }
    machine_fault(&handle)?;
    if handle.borrow().power_cut().is_none() {
        return Err("the planned power cut never happened".into());
    }
    // The FLASH model ignores every write after its cut: the power comes back on a new board
    // whose array is the one the cut left.
    let mut array = handle.borrow_mut().mcu().flash().to_vec();
    // The model's array is 1 MiB; the F446 has 512 KiB of it (RM0390).
    if board.spec.chip == board::boards::Chip::Stm32f446re {
        array.truncate(512 * 1024);
    }
    let mut device = fast_flash_board(board, elf, options, None)?;
    device.mcu().program_flash(0, &array).map_err(|e| format!("the array the cut left: {e}"))?;
    let handle = Rc::new(RefCell::new(device));
    let mut bus = bus_with(&handle, options, PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    run_while(&mut session, SETTLE, || {
        state(&handle) != [BOOT_MAGIC; 4] && handle.borrow().fault().is_none()
    })?;
    machine_fault(&handle)?;
    let (state, resets) = (state(&handle), handle.borrow().watchdog_resets());
    if state != [BOOT_MAGIC; 4] || !active_holds(&handle, new) || resets != 0 {
        return Err(format!(
            "after the power came back: STATE {state:02x?} (want BOOT), ACTIVE the new image: {}, {resets} watchdog resets",
            active_holds(&handle, new)
        ));
    }
    drop(session);
    Ok(handle)
}

/// See the [module docs](self).
pub fn swap_cut(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    cut_during_the_swap(board, elf, options)?;
    super::transfer_cut::transfer_cut(board, elf, options).map_err(|e| format!("the transfer half: {e}"))
}

/// [`swap_cut`], giving the number of the swap's flash operations and of the cuts made.
pub fn cut_during_the_swap(
    board: BoardKind,
    elf: &Firmware,
    options: &Options,
) -> Result<(usize, usize), String> {
    let (_, new) = old_and_newer(&elf.elf)?;
    let trailer = test_signed(&new)?.to_bytes();
    let operations = record(board, elf, options, &new, &trailer)?;
    let kinds = |k: Kind| operations.iter().filter(|o| o.1 == k).count();
    if kinds(Kind::Erase) == 0 || kinds(Kind::Progress) == 0 || kinds(Kind::Data) == 0 {
        return Err(format!(
            "the recorded swap has {} erases, {} progress words and {} data programs: not a swap",
            kinds(Kind::Erase),
            kinds(Kind::Progress),
            kinds(Kind::Data)
        ));
    }
    let points = cut_points(&operations);
    let mut last = None;
    for &(index, how) in &points {
        let what = operations.iter().find(|o| o.0 == index).map(|o| o.1);
        let handle = cut_and_power_up(board, elf, options, (&new, &trailer), (index, how)).map_err(|e| {
            format!("a cut at operation {index} ({what:?}, {how:?}) of {}: {e}", operations.len())
        })?;
        last = Some(handle);
    }
    let handle = last.ok_or("no cut point")?;
    let mut bus = bus_with(&handle, options, PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    let connected = Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect to the new image after the last cut: {e}"))?;
    Ok((operations.len(), points.len()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cut_points_take_every_erase_and_progress_word_and_each_pages_first_and_last_program() {
        let mut ops = vec![(0, Kind::Erase)];
        ops.extend((1..=100).map(|i| (i, Kind::Data)));
        ops.extend([(101, Kind::Progress), (102, Kind::Erase), (103, Kind::Data), (104, Kind::Data)]);
        let (b, t) = (CutKind::Before, CutKind::Torn);
        let want = vec![
            (0, b),
            (0, t),
            (1, t),
            (100, t),
            (101, b),
            (101, t),
            (102, b),
            (102, t),
            (103, t),
            (104, t),
        ];
        assert_eq!(cut_points(&ops), want);
    }
}
