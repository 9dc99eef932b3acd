//! What every scenario builds on: the options, the bus with the emulated board on it, and the
//! checks they share.

use crate::board::{BoardKind, NodeSetting};
use crate::device::Firmware;
use crate::device::{EmulatedBoard, OnBus};
use can_io::bus::{Bitrate, Origin};
use can_io::sim::{PowerOn, SimBus};
use devicenet::reference::Direction;
use devicenet::slave::BaudRate;
use devicenet::MacId;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;

/// The device's MAC ID in every scenario that does not choose another (the reference
/// transcript's).
pub const MAC: MacId = MacId::from_low_bits(5);

/// How a scenario runs (the defaults are the real scenarios; the others exist so that a test
/// can prove a scenario fails when the world is wrong).
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// The bus's bit rate.
    pub bus_rate: Bitrate,
    /// The node's MAC and rate before power-on.
    pub setting: NodeSetting,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            bus_rate: Bitrate::K125,
            setting: NodeSetting { mac: MAC, rate: BaudRate::Kbps125, bus_off_interrupt: false },
        }
    }
}

/// The board's handle the scenario keeps while the bus holds the board.
pub type Handle = Rc<RefCell<EmulatedBoard>>;

/// The bus with the emulated board on it, and the test's handle on the board.
pub fn world(
    board: BoardKind,
    elf: &Firmware,
    options: &Options,
    power: PowerOn,
) -> Result<(SimBus, Handle), String> {
    let device = EmulatedBoard::new(board, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    let handle = Rc::new(RefCell::new(device));
    Ok((bus_with(&handle, options, power), handle))
}

/// A new bus with the board on it: powering it on there is a power cycle if it ran before.
pub fn bus_with(handle: &Handle, options: &Options, power: PowerOn) -> SimBus {
    let mut bus = SimBus::new(options.bus_rate);
    bus.attach(Box::new(OnBus(Rc::clone(handle))), power);
    bus
}

/// Puts the board on a new bus (powered up as `power`), connects a master to it and runs `f`
/// with that master; the machine's fault comes first, then the connect's error, then `f`'s.
pub fn with_master<T>(
    handle: &Handle,
    options: &Options,
    power: PowerOn,
    f: impl FnOnce(&mut Master<'_, '_>) -> Result<T, String>,
) -> Result<T, String> {
    let mut bus = bus_with(handle, options, power);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions::default());
    machine_fault(handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let result = f(&mut master);
    machine_fault(handle)?;
    result
}

/// The machine's fault, if it stopped.
pub fn machine_fault(handle: &Handle) -> Result<(), String> {
    match handle.borrow().fault() {
        Some(fault) => Err(format!("the machine stopped: {fault}")),
        None => Ok(()),
    }
}

/// The master's verdicts: `Err` when any of its checks failed.
pub fn master_checks(session: &Session<'_>) -> Result<(), String> {
    match session.failures() {
        0 => Ok(()),
        n => Err(format!("{n} checks of the master failed")),
    }
}

/// Who sent a recorded frame, as the reference transcript says it.
pub fn direction(origin: Origin) -> Direction {
    match origin {
        Origin::Local => Direction::MasterToSlave,
        Origin::Remote => Direction::SlaveToMaster,
    }
}

/// The bus rate of a DeviceNet data rate.
pub fn bitrate(rate: BaudRate) -> Bitrate {
    match rate {
        BaudRate::Kbps125 => Bitrate::K125,
        BaudRate::Kbps250 => Bitrate::K250,
        BaudRate::Kbps500 => Bitrate::K500,
    }
}

/// The CAN identifier of `mac`'s duplicate MAC ID check message (Group 2 message 7,
/// protocol §1.2).
pub fn duplicate_mac_id(mac: MacId) -> u16 {
    devicenet::Identifier::group2(mac, devicenet::Group2Message::DuplicateMacCheck).as_raw()
}

/// The same board powered up again with the flash array `previous` left (a power cycle), on a
/// bus at `options.bus_rate`: a new machine, since the emulated board's bus rate is fixed when
/// it is built.
pub fn power_cycled(previous: &Handle, elf: &Firmware, options: &Options) -> Result<Handle, String> {
    let (kind, array) = {
        let mut board = previous.borrow_mut();
        (board.kind(), board.mcu().flash().to_vec())
    };
    let mut device = EmulatedBoard::new(kind, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    let layout = kind.spec.flash;
    for base in layout.settings_bases {
        let start = (base - board::memory::FLASH_BASE) as usize;
        let sector = array
            .get(start..start + layout.settings_sector_size as usize)
            .ok_or("the settings sectors lie outside the flash array")?;
        device.mcu().program_flash(start as u32, sector).map_err(|e| format!("the flash: {e}"))?;
    }
    Ok(Rc::new(RefCell::new(device)))
}
