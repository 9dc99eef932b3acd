//! `bring-up`, `breaker`, `power-cycle`: the node as the bench master meets it.

use super::world::{bus_with, direction, machine_fault, world, Options, MAC};
use crate::board::BoardKind;
use crate::device::Firmware;
use can_io::sim::PowerOn;
use converter_sim::device::{COMMAND_CLOSE, COMMAND_OPEN, SWITCH_BYTE, SWITCH_CLOSED, SWITCH_OPEN};
use devicenet::reference::BRING_UP;
use devicenet::Duration;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use slave_fw::serial::breaker::SwitchState;

/// The 28 frames of protocol §2, byte for byte and in order, every check holding. The
/// serial number in the device's frames is the reference's own: the emulated chip's unique ID
/// folds to it ([`crate::uid`]), nothing is substituted.
pub fn bring_up(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let mut session = Session::new(&mut bus);
    let connected = Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let records = session.records();
    for (i, want) in BRING_UP.iter().enumerate() {
        let Some(got) = records.get(i) else {
            return Err(format!("{} frames, not {}", records.len(), BRING_UP.len()));
        };
        let got_key = (direction(got.origin), got.frame.id().as_raw(), got.frame.data());
        if got_key != (want.direction, want.id, want.data) {
            return Err(format!(
                "frame {i} ({}): id {:#05x} {:02x?}, want {:#05x} {:02x?}",
                want.meaning, got_key.1, got_key.2, want.id, want.data
            ));
        }
    }
    if records.len() != BRING_UP.len() {
        return Err(format!("{} frames, not {}", records.len(), BRING_UP.len()));
    }
    match session.failures() {
        0 => Ok(()),
        n => Err(format!("{n} checks of the master failed")),
    }
}

/// Close, then open, through the poll output: the breaker on the instrument USART obeys and its
/// switch state comes back in the input image.
pub fn breaker(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    // 15 polls 100 ms apart: the close command goes out at once, the breaker's status frame
    // (once a second) shows it closed.
    let close = [COMMAND_CLOSE, 1, 0, 0, 0, 0, 0, 0];
    let opts = ConnectOptions { polls: 15, output: Some(close.to_vec()), ..ConnectOptions::default() };
    let summary = master.connect(&opts);
    machine_fault(&handle)?;
    let summary = summary.map_err(|e| format!("connect: {e}"))?;
    let input = summary.last_input.unwrap_or_default();
    if input.get(SWITCH_BYTE) != Some(&SWITCH_CLOSED) {
        return Err(format!("after Close the input image is {input:02x?}"));
    }
    if handle.borrow().breaker().switch_state() != SwitchState::Closed {
        return Err("the input image says closed but the breaker is not".into());
    }
    let open = [COMMAND_OPEN, 2, 0, 0, 0, 0, 0, 0];
    let mut input = Vec::new();
    for _ in 0..15 {
        let deadline = master.session.now() + Duration::from_millis(100);
        input =
            master.poll(MAC, &open, 18, 8, Duration::from_millis(500)).map_err(|e| format!("poll: {e}"))?;
        master.idle_until(deadline).map_err(|e| format!("idle: {e}"))?;
    }
    machine_fault(&handle)?;
    if input.get(SWITCH_BYTE) != Some(&SWITCH_OPEN) {
        return Err(format!("after Open the input image is {input:02x?}"));
    }
    if handle.borrow().breaker().switch_state() != SwitchState::Open {
        return Err("the input image says open but the breaker is not".into());
    }
    match master.session.failures() {
        0 => Ok(()),
        n => Err(format!("{n} checks of the master failed")),
    }
}

/// The DeviceNet object (class 3), instance 1, attribute 3: the bus-off interrupt (BOI).
const BOI: (u16, u16, u8) = (3, 1, 3);

/// A setting made over the network survives a power cycle: the master sets BOI (a stored
/// setting, DeviceNet object attribute 3) on the running node; the settings journal in flash
/// then holds it (decoded by the board crate); after a power cycle (SRAM and every register
/// reset, the flash array kept) a new bring-up reads it back from the node.
pub fn power_cycle(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let (class, instance, attribute) = BOI;
    {
        let mut session = Session::new(&mut bus);
        let mut master = Master::new(&mut session, MasterConfig::default());
        let connected = master.connect(&ConnectOptions::default());
        machine_fault(&handle)?;
        connected.map_err(|e| format!("connect: {e}"))?;
        let (before, _) = master.get(MAC, class, instance, attribute).map_err(|e| format!("get BOI: {e}"))?;
        if before != [0] {
            return Err(format!("BOI reads {before:02x?} before it is set"));
        }
        master.set(MAC, class, instance, attribute, &[1]).map_err(|e| format!("set BOI: {e}"))?;
        let deadline = master.session.now() + Duration::from_millis(500);
        master.idle_until(deadline).map_err(|e| format!("idle: {e}"))?;
    }
    machine_fault(&handle)?;
    match handle.borrow().stored_settings() {
        Some((settings, _)) if settings.bus_off_interrupt => {}
        Some((settings, n)) => {
            return Err(format!("the journal's newest record ({n}) has BOI clear: {settings:?}"))
        }
        None => return Err("no valid record in the settings journal".into()),
    }
    let mut bus = bus_with(&handle, options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect after the power cycle: {e}"))?;
    let (after, _) = master.get(MAC, class, instance, attribute).map_err(|e| format!("get BOI: {e}"))?;
    if after != [1] {
        return Err(format!("after the power cycle BOI reads {after:02x?}, not 01"));
    }
    match master.session.failures() {
        0 => Ok(()),
        n => Err(format!("{n} checks of the master failed")),
    }
}
