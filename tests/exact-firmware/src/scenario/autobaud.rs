//! `mac63-autobaud-125k`, `-250k`, `-500k` and `autobaud-silent-bus` (boards without switches):
//! out of the box (no settings record) the node starts at MAC ID 63 and finds the data rate by
//! listening in bxCAN silent mode (the rule of board/src/autobaud.rs: 125k, 250k, 500k in turn;
//! a rate is found by a frame received there with no error seen, and left at the first error or
//! after a 2 s dwell without a frame).

use super::world::{bitrate, duplicate_mac_id, machine_fault, master_checks, Handle, Options};
use crate::board::{BoardKind, NodeSetting};
use crate::device::Firmware;
use crate::device::{EmulatedBoard, OnBus};
use can_io::bus::{Bus, Origin};
use can_io::sim::{PowerOn, SimBus};
use converter_sim::SoftSlave;
use devicenet::slave::BaudRate;
use devicenet::{Duration, Instant, MacId};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;
use stm32_emu::bxcan::{msr, offset, CAN1_BASE, LBKM, SILM};

/// The other node of the network the board joins (a soft slave the master polls).
const OTHER: MacId = MacId::from_low_bits(10);
/// The MAC ID the master gives the node once it joined at 63.
const NEW_MAC: MacId = MacId::from_low_bits(5);

/// The board with an erased settings journal, as it leaves the factory; `rate` is only the
/// bus's.
fn blank_board(board: BoardKind, elf: &Firmware, rate: BaudRate) -> Result<Handle, String> {
    let setting = NodeSetting { mac: MacId::MAX, rate, bus_off_interrupt: false };
    let mut device =
        EmulatedBoard::new(board, elf, setting, bitrate(rate)).map_err(|e| format!("the machine: {e}"))?;
    let layout = board.spec.flash;
    let erased = vec![0xFF; layout.settings_sector_size as usize];
    for base in layout.settings_bases {
        device
            .mcu()
            .program_flash(base - board::memory::FLASH_BASE, &erased)
            .map_err(|e| format!("erasing the settings: {e}"))?;
    }
    if let Some(record) = device.stored_settings() {
        return Err(format!("the settings journal still holds {record:?}"));
    }
    Ok(Rc::new(RefCell::new(device)))
}

/// The `mac63-autobaud` scenario at 125 kbit/s.
pub fn at_125k(board: BoardKind, elf: &Firmware, _: &Options) -> Result<(), String> {
    mac63_autobaud(board, elf, BaudRate::Kbps125)
}

/// The `mac63-autobaud` scenario at 250 kbit/s.
pub fn at_250k(board: BoardKind, elf: &Firmware, _: &Options) -> Result<(), String> {
    mac63_autobaud(board, elf, BaudRate::Kbps250)
}

/// The `mac63-autobaud` scenario at 500 kbit/s.
pub fn at_500k(board: BoardKind, elf: &Firmware, _: &Options) -> Result<(), String> {
    mac63_autobaud(board, elf, BaudRate::Kbps500)
}

/// A blank board on a network at `rate` where the master polls another node: the node must
/// offer no frame until it found the rate (none flagged at another rate, its first frame after
/// the network's first), then run the duplicate MAC ID check at 63 at `rate`, be allocated and
/// polled there; the master sets its MAC ID to 5 (DeviceNet object attribute 1), the journal
/// then holds MAC 5 at `rate`, and after a power cycle on a bus where nobody else talks the
/// node's first frame is its duplicate MAC ID check at 5 (no autobaud: the rate is stored), and
/// the master brings it up there.
fn mac63_autobaud(board: BoardKind, elf: &Firmware, rate: BaudRate) -> Result<(), String> {
    let handle = blank_board(board, elf, rate)?;
    let mut bus = SimBus::new(bitrate(rate));
    bus.attach(Box::new(OnBus(Rc::clone(&handle))), PowerOn::AtStart);
    bus.attach(Box::new(SoftSlave::reference(OTHER)), PowerOn::AtStart);
    {
        let mut session = Session::new(&mut bus);
        let mut master = Master::new(&mut session, MasterConfig::default());
        let traffic =
            master.connect(&ConnectOptions { target: OTHER, polls: 20, ..ConnectOptions::default() });
        machine_fault(&handle)?;
        traffic.map_err(|e| format!("the other node: {e}"))?;
        let counts = handle.borrow().counts();
        if counts.flagged > 0 {
            return Err(format!("{} frames offered at a rate the bus does not run", counts.flagged));
        }
        let records = master.session.records();
        let first_other = records.iter().find(|r| r.origin == Origin::Local).map(|r| r.at);
        let mine: Vec<_> = records
            .iter()
            .filter(|r| r.origin == Origin::Remote && Master::is_from(&r.frame, MacId::MAX))
            .collect();
        let Some(first) = mine.first() else {
            return Err(format!(
                "no frame of the node at MAC 63 at {rate:?} ({} frames on the bus)",
                records.len()
            ));
        };
        if first.frame.id().as_raw() != duplicate_mac_id(MacId::MAX) {
            return Err(format!(
                "the node's first frame is {:#05x}, not its duplicate MAC ID check at 63",
                first.frame.id().as_raw()
            ));
        }
        if first_other.is_none_or(|t| first.at <= t) {
            return Err(
                "the node sent before the network's first frame: it cannot have known the rate".into()
            );
        }
        let joined =
            master.connect(&ConnectOptions { target: MacId::MAX, polls: 3, ..ConnectOptions::default() });
        machine_fault(&handle)?;
        joined.map_err(|e| format!("at MAC 63: {e}"))?;
        master.set(MacId::MAX, 3, 1, 1, &[NEW_MAC.as_raw()]).map_err(|e| format!("set the MAC ID: {e}"))?;
        let deadline = master.session.now() + Duration::from_millis(500);
        master.idle_until(deadline).map_err(|e| format!("idle: {e}"))?;
        machine_fault(&handle)?;
        master_checks(master.session)?;
    }
    match handle.borrow().stored_settings() {
        Some((s, _)) if (s.mac_id, s.baud_rate) == (NEW_MAC, rate) => {}
        other => {
            return Err(format!(
                "after the MAC ID was set the journal holds {other:?}, not MAC 5 at {rate:?}"
            ))
        }
    }
    let mut bus = SimBus::new(bitrate(rate));
    bus.attach(Box::new(OnBus(Rc::clone(&handle))), PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    master.idle_until(Instant::from_millis(200)).map_err(|e| format!("idle: {e}"))?;
    let first =
        master.session.records().iter().find(|r| r.origin == Origin::Remote).map(|r| r.frame.id().as_raw());
    if first != Some(duplicate_mac_id(NEW_MAC)) {
        return Err(format!("after the power cycle the node's first frame within 200 ms is {first:#05x?}, not its duplicate MAC ID check at 5"));
    }
    let connected = master.connect(&ConnectOptions { target: NEW_MAC, ..ConnectOptions::default() });
    machine_fault(&handle)?;
    connected.map_err(|e| format!("after the power cycle at MAC 5: {e}"))?;
    master_checks(master.session)
}

/// A blank board alone on a silent bus for 4.5 s: it never offers a frame (none reaches the bus,
/// none is flagged), its controller listens in silent mode only (every `CAN_BTR` seen in normal
/// mode, other than the power-up self-test's loop back, has SILM set), and it moves on from the
/// first rate when the dwell ends without a frame (two bit timings seen). Not the third rate:
/// the firmware counts the dwell in delay loops (`cortex_m::asm::delay`), which take about twice
/// as long on the one-instruction-per-cycle core of stm32-emu, so the second dwell ends past 8 s
/// of emulated time, and each emulated second of that busy loop costs several seconds of wall
/// time.
pub fn silent_bus(board: BoardKind, elf: &Firmware, _: &Options) -> Result<(), String> {
    let handle = blank_board(board, elf, BaudRate::Kbps125)?;
    let seen = Rc::new(RefCell::new(Vec::new()));
    let record = Rc::clone(&seen);
    handle.borrow_mut().watch(Some((
        crate::device::STEP,
        Box::new(move |mcu| {
            // MSR reads 0 while the controller is unclocked; SAMP_RX is set otherwise.
            let msr = mcu.read_peripheral(CAN1_BASE + offset::MSR).unwrap_or(0);
            let normal = msr != 0 && msr & (msr::INAK | msr::SLAK) == 0;
            if let (true, Some(btr)) = (normal, mcu.read_peripheral(CAN1_BASE + offset::BTR)) {
                if btr & LBKM == 0 && !record.borrow().iter().any(|&(b, _)| b == btr) {
                    record.borrow_mut().push((btr, mcu.now() / 1_000_000));
                }
            }
        }),
    )));
    let mut bus = SimBus::new(bitrate(BaudRate::Kbps125));
    bus.attach(Box::new(OnBus(Rc::clone(&handle))), PowerOn::AtStart);
    if let Some(event) = bus.recv(Instant::from_millis(4500)).map_err(|e| format!("bus: {e}"))? {
        return Err(format!(
            "a frame reached the silent bus: {:#05x} {:02x?}",
            event.frame.id().as_raw(),
            event.frame.data()
        ));
    }
    machine_fault(&handle)?;
    let counts = handle.borrow().counts();
    if counts.sent + counts.flagged > 0 {
        return Err(format!("the node offered {} frames on a silent bus", counts.sent + counts.flagged));
    }
    let seen = seen.borrow();
    if let Some((btr, _)) = seen.iter().find(|&&(b, _)| b & SILM == 0) {
        return Err(format!("the controller left silent mode on a silent bus (CAN_BTR {btr:#010x})"));
    }
    if seen.len() < 2 {
        return Err(format!(
            "{} bit timings listened at in 4.5 s (CAN_BTR, from ms: {seen:08x?}): the first rate was never left",
            seen.len()
        ));
    }
    Ok(())
}
