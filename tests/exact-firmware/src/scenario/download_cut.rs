//! `download-cut`: a power cut at **every** flash operation of a configuration download leaves
//! the old configuration or the new one in force, never neither.
//!
//! Running the download once per operation (about 640, one per byte of the settings record)
//! would take most of an hour per board. Instead:
//!
//! 1. **Record.** The download of [`configure`](super::configure) runs once on a fresh board,
//!    the CPU in slices of [`SLICE`] (a quarter of one program operation, 16 µs): after each,
//!    the operations the FLASH model started ([`Stm32::flash_operations`]) are taken with the
//!    bytes of the settings sectors they changed and `FLASH_CR` (the program size); the stores
//!    of one 16-byte row stall back to back, so a slice may hold a few, taken one changed byte
//!    each in address order, the HAL's order (`Recorder::after_slice`).
//! 2. **Cut.** For each operation k, the settings sectors as a power cut at k leaves them: with
//!    the operation not started (the image after operation k − 1), and torn half-way. The torn
//!    image is the FLASH model's own ([`CutKind::Torn`]): a stand-alone model on the image
//!    before k, unlocked, replays operation k with the cut planned there. A program is replayed
//!    with the data the array shows after it (exact on erased bytes, which the journal writes).
//! 3. **Power up.** The exact ELF is powered up on each distinct image, alone on a bus: its
//!    first frame must be its duplicate MAC ID check at MAC 5 within 100 ms (the stored MAC and
//!    rate in force), and its instrument USART must run the factory configuration's line (9600
//!    8N1) or the meter's (19200 8E1).
//! 4. **Closer.** The line does not show a configuration fault (an unusable stored image runs
//!    the factory configuration, faulted: configuration state 3), so on some images the master
//!    checks the configuration state and the Identity product name ([`state_after_power_up`],
//!    about 3 s of emulated time each, too long for every image): every 64th operation torn,
//!    the last image with the old configuration's line, the first with the new one's, and the
//!    image after the last operation. Each must be the configuration its line says: state 0
//!    and the factory name, or state 1 and the meter's.

use super::configure::METER;
use super::world::{bus_with, duplicate_mac_id, machine_fault, world, Handle, Options, MAC};
use crate::board::BoardKind;
use crate::device::EmulatedBoard;
use crate::device::Firmware;
use can_io::bus::Bus;
use can_io::sim::PowerOn;
use devicenet::Instant;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::collections::HashSet;
use std::hash::{DefaultHasher, Hash, Hasher};
use std::rc::Rc;
use stm32_emu::flash::{self, CutKind, Flash};
use stm32_emu::machine::Stm32;
use stm32_emu::periph::{ClockGate, Clocks, Machine, Nanos, Peripheral, Width};
use stm32_emu::usart::line::{LineSettings, Parity};

/// The CPU's slice while the download is recorded: a quarter of a program operation (16 µs,
/// stm32-emu `FlashTiming`), so that a slice holds one operation, or the few a row's stalled
/// stores start back to back (`Recorder::after_slice`).
pub const SLICE: Nanos = 4_000;

/// The master checks the configuration state and product name on the image of every
/// `CLOSE_EVERY`-th operation torn (and on the boundary images, module docs).
const CLOSE_EVERY: usize = 64;

/// `FLASH_CR`'s offset (RM0090 §3.9.8).
const FLASH_CR: u32 = 0x10;

/// One flash operation of the download: the settings-sector bytes it changed (flash offset, new
/// value) and `FLASH_CR` after it.
#[derive(Clone, Debug)]
struct Operation {
    changes: Vec<(usize, u8)>,
    cr: u32,
}

/// What the slice watch collects.
struct Recorder {
    /// Flash offset of the settings sectors and their contents as last seen.
    start: usize,
    shadow: Vec<u8>,
    /// Operations counted so far.
    seen: u64,
    operations: Vec<Operation>,
    error: Option<String>,
}

impl Recorder {
    /// After a slice: the operations it started. One slice may hold several: the HAL
    /// (stm32f4xx-hal `UnlockedFlash::program`) writes a 16-byte row's bytes back to back, in
    /// increasing address order, each store stalling until the previous program ends. Those are
    /// taken one changed byte each, in address order (a byte programmed to what it was, 0xFF,
    /// changes nothing and leaves no image of its own).
    fn after_slice(&mut self, mcu: &mut Stm32) {
        let count = mcu.flash_operations().unwrap_or(0);
        if count == self.seen {
            return;
        }
        let started = count - self.seen;
        self.seen = count;
        let cr = mcu.read_peripheral(flash::BASE + FLASH_CR).unwrap_or(0);
        let now = &mcu.flash()[self.start..self.start + self.shadow.len()];
        let mut changes = Vec::new();
        for (i, (old, new)) in self.shadow.iter_mut().zip(now).enumerate() {
            if old != new {
                changes.push((self.start + i, *new));
                *old = *new;
            }
        }
        let erase = changes.len() > 16 && changes.iter().all(|&(_, v)| v == 0xFF);
        if erase && started == 1 {
            self.operations.push(Operation { changes, cr });
        } else if !erase && changes.len() as u64 <= started && cr & flash::cr::PSIZE == 0 {
            self.operations.extend(changes.into_iter().map(|c| Operation { changes: vec![c], cr }));
        } else if self.error.is_none() {
            self.error = Some(format!(
                "{started} flash operations in one {SLICE} ns slice changed {} bytes (FLASH_CR {cr:#010x}): not one \
                 byte program each, nor one erase",
                changes.len()
            ));
        }
    }
}

/// The machine a stand-alone FLASH model needs: the reset clocks, time standing still.
struct Bench;

impl Machine for Bench {
    fn clocks(&self) -> Clocks {
        Clocks::RESET
    }
    fn clock_enabled(&self, _: ClockGate) -> bool {
        true
    }
    fn set_irq(&mut self, _: u16, _: bool) {}
    fn now(&self) -> Nanos {
        0
    }
}

/// The array a power cut tearing `op` leaves, from `array` (the whole flash array before it):
/// the FLASH model's own torn operation.
fn torn(array: &[u8], op: &Operation) -> Result<Vec<u8>, String> {
    let Some(&(first, _)) = op.changes.first() else { return Ok(array.to_vec()) };
    let mut model = Flash::from_image(array.to_vec()).map_err(|e| e.to_string())?;
    let m = &mut Bench;
    let psize = (op.cr & flash::cr::PSIZE) >> 8;
    model.write(0x04, Width::Word, flash::KEY1, m);
    model.write(0x04, Width::Word, flash::KEY2, m);
    model.plan_power_cut(0, CutKind::Torn);
    let bytes = 1usize << psize;
    let span = op.changes.last().map_or(0, |&(last, _)| last) - first;
    if span < bytes && first % bytes + span < bytes {
        let width = match psize {
            0 => Width::Byte,
            1 => Width::Half,
            2 => Width::Word,
            _ => return Err(format!("a program of {bytes} bytes at {first:#x}: not replayable")),
        };
        let at = first - first % bytes;
        let mut after = array[at..at + bytes].to_vec();
        for &(offset, value) in &op.changes {
            after[offset - at] = value;
        }
        let value = after.iter().rev().fold(0u32, |v, &b| v << 8 | u32::from(b));
        model.write(FLASH_CR, Width::Word, flash::cr::PG | psize << 8, m);
        model.array_write(at as u32, width, value, m);
    } else {
        let sector = (0..12u8)
            .find(|&n| flash::sector(n).is_some_and(|(s, len)| (s..s + len).contains(&first)))
            .ok_or_else(|| format!("no sector holds {first:#x}"))?;
        let cr = flash::cr::SER | u32::from(sector) << 3 | psize << 8;
        model.write(FLASH_CR, Width::Word, cr, m);
        model.write(FLASH_CR, Width::Word, cr | flash::cr::STRT, m);
    }
    if model.power_cut().is_none() {
        return Err(format!("the FLASH model refused the replay of the operation at {first:#x}"));
    }
    Ok(model.image().to_vec())
}

/// Which configuration a powered-up board runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum InForce {
    Old,
    New,
}

/// The line of the factory configuration and of the meter's.
fn configuration_of(line: &LineSettings) -> Option<InForce> {
    let near = |baud: f64| (line.baud - baud).abs() < baud * 0.01;
    match (line.parity, line.data_bits()) {
        (Parity::None, 8) if near(9600.0) => Some(InForce::Old),
        (Parity::Even, 8) if near(19_200.0) => Some(InForce::New),
        _ => None,
    }
}

/// A board whose settings sectors hold `sectors` (at flash offset `start`), not powered yet.
fn board_with(
    board: BoardKind,
    elf: &Firmware,
    options: &Options,
    start: usize,
    sectors: &[u8],
) -> Result<Handle, String> {
    let mut device = EmulatedBoard::new(board, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    device.mcu().program_flash(start as u32, sectors).map_err(|e| format!("the image: {e}"))?;
    Ok(Rc::new(RefCell::new(device)))
}

/// Powers the board up alone on a bus: its first frame must be the duplicate MAC ID check at
/// [`MAC`] within 100 ms; then which configuration its instrument line shows.
fn quick_power_up(
    board: BoardKind,
    elf: &Firmware,
    options: &Options,
    start: usize,
    sectors: &[u8],
) -> Result<InForce, String> {
    let handle = board_with(board, elf, options, start, sectors)?;
    let mut bus = bus_with(&handle, options, PowerOn::AtStart);
    let first = bus.recv(Instant::from_millis(100)).map_err(|e| format!("bus: {e}"))?;
    machine_fault(&handle)?;
    match first {
        Some(event) if event.frame.id().as_raw() == duplicate_mac_id(MAC) => {}
        Some(event) => {
            return Err(format!(
                "first frame {:#05x}, not the duplicate MAC ID check at MAC 5",
                event.frame.id().as_raw()
            ))
        }
        None => return Err("no frame within 100 ms (not at MAC 5 at 125k, or silent)".into()),
    }
    let line = handle.borrow().instrument_line();
    configuration_of(&line).ok_or_else(|| format!("the instrument line is {line:?}: neither configuration"))
}

/// The configuration object's state and the Identity product name of the node at [`MAC`],
/// powered on again on `handle`'s flash.
pub fn state_after_power_up(handle: &Handle, options: &Options) -> Result<(Vec<u8>, Vec<u8>), String> {
    let mut bus = bus_with(handle, options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    master.set_device(MAC);
    let online = master.network_access().and_then(|()| master.await_online(&[MAC]));
    machine_fault(handle)?;
    online.map_err(|e| format!("back on-line: {e}"))?;
    let choice = devicenet::messages::AllocationChoice::EXPLICIT;
    master
        .allocate(MAC, master_core::client::Port::Group2Only, choice)
        .map_err(|e| format!("explicit connection: {e}"))?;
    let class = master_harness::configure::CONFIGURATION_CLASS;
    let (state, _) = master.get(MAC, class, 1, 3).map_err(|e| format!("configuration state: {e}"))?;
    let (name, _) = master.get(MAC, 1, 1, 7).map_err(|e| format!("product name: {e}"))?;
    Ok((state, name))
}

/// The download, recorded.
struct Recording {
    /// Its flash operations, in order.
    operations: Vec<Operation>,
    /// The whole flash array before them.
    array: Vec<u8>,
    /// The flash offset of the settings sectors.
    start: usize,
    /// The Identity product name before the download (its length first).
    factory_name: Vec<u8>,
}

/// Runs the download on a fresh board, its flash operations recorded.
fn record(board: BoardKind, elf: &Firmware, options: &Options) -> Result<Recording, String> {
    use master_harness::configure::download;
    let meter =
        slave_fw::description::DeviceDescription::parse(METER).map_err(|e| format!("the meter: {e}"))?;
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let layout = board.spec.flash;
    let base = layout.settings_bases.iter().min().copied().unwrap_or(0);
    let end = layout.settings_bases.iter().max().copied().unwrap_or(0) + layout.settings_sector_size;
    let start = (base - board::memory::FLASH_BASE) as usize;
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let (name, _) = master.get(MAC, 1, 1, 7).map_err(|e| format!("product name: {e}"))?;
    let array = handle.borrow_mut().mcu().flash().to_vec();
    let recorder = Rc::new(RefCell::new(Recorder {
        start,
        shadow: array[start..start + (end - base) as usize].to_vec(),
        seen: handle.borrow().flash_operations(),
        operations: Vec::new(),
        error: None,
    }));
    let watch = Rc::clone(&recorder);
    handle.borrow_mut().watch(Some((SLICE, Box::new(move |mcu| watch.borrow_mut().after_slice(mcu)))));
    let report = download(&mut master, MAC, &meter, &mut |_| {});
    handle.borrow_mut().watch(None);
    machine_fault(&handle)?;
    let report = report.map_err(|e| format!("download: {e}"))?;
    if let Some(check) = report.failures().first() {
        return Err(format!("after the download: {check:?}"));
    }
    let recorder = recorder.borrow();
    if let Some(error) = &recorder.error {
        return Err(format!("recording the download: {error}"));
    }
    if recorder.operations.is_empty() {
        return Err("the download took no flash operation".into());
    }
    Ok(Recording { operations: recorder.operations.clone(), array, start, factory_name: name })
}

/// See the [module docs](self).
pub fn download_cut(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    cut_at_every_operation(board, elf, options).map(|_| ())
}

/// [`download_cut`], giving the number of flash operations covered.
pub fn cut_at_every_operation(board: BoardKind, elf: &Firmware, options: &Options) -> Result<usize, String> {
    let meter =
        slave_fw::description::DeviceDescription::parse(METER).map_err(|e| format!("the meter: {e}"))?;
    let Recording { operations, mut array, start, factory_name } = record(board, elf, options)?;
    let len = {
        let layout = board.spec.flash;
        let base = layout.settings_bases.iter().min().copied().unwrap_or(0);
        (layout.settings_bases.iter().max().copied().unwrap_or(0) + layout.settings_sector_size - base)
            as usize
    };
    let mut meter_name = vec![meter.converter.device.identity.product_name.len() as u8];
    meter_name.extend_from_slice(meter.converter.device.identity.product_name.as_bytes());
    let mut checked = HashSet::new();
    // The images the master checks more closely: (what, image, the configuration it runs).
    let mut sampled = Vec::new();
    let mut last_old = None;
    let mut first_new = None;
    let count = operations.len();
    for (k, op) in operations.iter().enumerate() {
        let torn_array = torn(&array, op).map_err(|e| format!("operation {k} of {count}: {e}"))?;
        let before = array[start..start + len].to_vec();
        let torn_image = torn_array[start..start + len].to_vec();
        let cuts = [
            (format!("cut before operation {k} of {count}"), before),
            (format!("operation {k} of {count} torn"), torn_image),
        ];
        for (what, image) in cuts {
            let mut hasher = DefaultHasher::new();
            image.hash(&mut hasher);
            if !checked.insert(hasher.finish()) {
                continue;
            }
            let in_force =
                quick_power_up(board, elf, options, start, &image).map_err(|e| format!("{what}: {e}"))?;
            if k % CLOSE_EVERY == 0 && what.ends_with("torn") {
                sampled.push((what.clone(), image.clone(), in_force));
            }
            match in_force {
                InForce::Old => last_old = Some((what, image, in_force)),
                InForce::New if first_new.is_none() => first_new = Some((what, image, in_force)),
                InForce::New => {}
            }
        }
        for &(offset, value) in &op.changes {
            array[offset] = value;
        }
    }
    let after = array[start..start + len].to_vec();
    let in_force =
        quick_power_up(board, elf, options, start, &after).map_err(|e| format!("after the download: {e}"))?;
    if in_force != InForce::New {
        return Err("after the whole download the old configuration is in force".into());
    }
    let last = Some(("after the last operation".to_string(), after, in_force));
    for (what, image, in_force) in
        sampled.into_iter().chain([last_old, first_new, last].into_iter().flatten())
    {
        let handle = board_with(board, elf, options, start, &image)?;
        let (state, name) = state_after_power_up(&handle, options).map_err(|e| format!("{what}: {e}"))?;
        let want = match in_force {
            InForce::Old => (vec![0], factory_name.clone()),
            InForce::New => (vec![1], meter_name.clone()),
        };
        if (state.clone(), name.clone()) != want {
            return Err(format!(
                "{what}: the line says the {in_force:?} configuration, the node says configuration state {state:02x?}, product name {name:02x?}"
            ));
        }
    }
    Ok(count)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_torn_byte_program_clears_the_lower_half_of_its_bits() {
        let mut array = vec![0xFF; flash::ARRAY_SIZE];
        let at = 0xE_0000;
        let op = Operation { changes: vec![(at + 3, 0x00)], cr: 0 };
        let torn_array = torn(&array, &op).expect("replayed");
        assert_eq!(torn_array[at + 3], 0xF0, "4 of the 8 bits, the lower ones");
        // Over a programmed byte the replay's data is the result (0xFC): the model clears the
        // lower of its two clear bits, already clear, so the torn byte is the one before.
        array[at + 3] = 0xFE;
        let over = Operation { changes: vec![(at + 3, 0xFC)], cr: 0 };
        assert_eq!(torn(&array, &over).expect("replayed")[at + 3], 0xFE);
    }

    #[test]
    fn a_torn_erase_erases_the_first_half_of_the_sector() {
        let mut array = vec![0x00; flash::ARRAY_SIZE];
        let (start, len) = flash::sector(11).expect("sector 11");
        array[start] = 0x12;
        let op = Operation { changes: (start..start + len).map(|i| (i, 0xFF)).collect(), cr: 2 << 8 };
        let torn_array = torn(&array, &op).expect("replayed");
        assert!(torn_array[start..start + len / 2].iter().all(|&b| b == 0xFF));
        assert!(torn_array[start + len / 2..start + len].iter().all(|&b| b == 0x00));
    }

    #[test]
    fn only_the_two_configurations_lines_are_recognised() {
        assert_eq!(configuration_of(&LineSettings::new_8n1(9600.0)), Some(InForce::Old));
        let even = LineSettings {
            baud: 19_200.0,
            word_bits: 9,
            parity: Parity::Even,
            stop_bits: stm32_emu::usart::line::StopBits::One,
        };
        assert_eq!(configuration_of(&even), Some(InForce::New));
        assert_eq!(configuration_of(&LineSettings::new_8n1(19_200.0)), None, "19200 but no parity");
        assert_eq!(configuration_of(&LineSettings::new_8n1(38_400.0)), None);
    }
}
