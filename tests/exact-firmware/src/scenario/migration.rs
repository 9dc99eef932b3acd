//! `settings-migration` (every board; issue 31): a board that gets the bootloader keeps the
//! settings its earlier firmware stored in the chip's last two sectors (10–11 on the STM32F405,
//! 6–7 on the F446). The firmware linked at ACTIVE finds its journal (sectors 1–2) empty at the
//! first start and moves the old location's newest record into it (board's
//! `SettingsStore::migrate_from`; the guide's integrator/flash.md).

use super::world::{bitrate, bus_with, machine_fault, Options};
use crate::board::{BoardKind, NodeSetting};
use crate::device::{EmulatedBoard, Firmware};
use can_io::sim::PowerOn;
use devicenet::slave::BaudRate;
use devicenet::MacId;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;

/// The settings the earlier firmware stored: neither the test's default MAC and rate nor the
/// factory's, and the bus-off interrupt on, which only a record sets (the reference board's
/// switches give MAC and rate, never BOI).
const MOVED: NodeSetting =
    NodeSetting { mac: MacId::from_low_bits(12), rate: BaudRate::Kbps250, bus_off_interrupt: true };

/// The board with an erased journal at its new place and a record at the old one: after the
/// power-on the node comes up at the record's MAC and rate, and the journal holds the record.
pub fn settings_migration(board: BoardKind, elf: &Firmware, _: &Options) -> Result<(), String> {
    let options = Options { bus_rate: bitrate(MOVED.rate), setting: MOVED };
    let mut device =
        EmulatedBoard::new(board, elf, MOVED, options.bus_rate).map_err(|e| format!("the machine: {e}"))?;
    let layout = board.spec.flash;
    let erased = vec![0xFF; layout.settings_sector_size as usize];
    let old = board::memory::old_settings_bases(board.spec.chip)[0] - board::memory::FLASH_BASE;
    let has_switches = board.switches().is_some();
    {
        let mcu = device.mcu();
        for base in layout.settings_bases {
            mcu.program_flash(base - board::memory::FLASH_BASE, &erased)
                .map_err(|e| format!("erasing: {e}"))?;
        }
        mcu.program_flash(old, &MOVED.record(has_switches)).map_err(|e| format!("the old record: {e}"))?;
    }
    if let Some(record) = device.stored_settings() {
        return Err(format!("the journal still holds {record:?} before the start"));
    }
    let handle = Rc::new(RefCell::new(device));
    let mut bus = bus_with(&handle, &options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let connected = Master::new(&mut session, MasterConfig::default())
        .connect(&ConnectOptions { target: MOVED.mac, ..ConnectOptions::default() });
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect at the moved MAC {}: {e}", MOVED.mac.as_raw()))?;
    let stored = handle.borrow().stored_settings().map(|(settings, _)| settings);
    match stored {
        Some(s) if s.mac_id == MOVED.mac && s.baud_rate == MOVED.rate && s.bus_off_interrupt => Ok(()),
        other => Err(format!("the journal holds {other:?}, not the moved record")),
    }
}
