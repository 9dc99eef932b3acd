//! `switches` (boards with DIP switches): the switches set the MAC ID and the data rate, read
//! once at reset (board/src/switches.rs); DeviceNet object attributes 6–9 report them
//! (protocol §II.7).

use super::world::{bitrate, bus_with, machine_fault, master_checks, power_cycled, Handle, Options};
use crate::board::{BoardKind, NodeSetting};
use crate::device::EmulatedBoard;
use crate::device::Firmware;
use can_io::sim::PowerOn;
use devicenet::slave::BaudRate;
use devicenet::{Duration, MacId};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;

/// The DeviceNet object (class 3, instance 1).
const DEVICENET: (u16, u16) = (3, 1);

/// Sets the switches to `bits` ("on" = 1: the pin closed to ground, board/src/switches.rs).
fn set_switches(handle: &Handle, bits: u8) -> Result<(), String> {
    let board = handle.borrow();
    let Some((port, first)) = board.kind().switches() else {
        return Err("the board has no switches".into());
    };
    let gpio = board.gpio(port).ok_or("no model of the switches' port")?;
    for i in 0..8 {
        let on = bits >> i & 1 == 1;
        gpio.borrow_mut().drive_pin(first + i, on.then_some(false));
    }
    Ok(())
}

/// What a boot must show: the MAC ID and rate in force and DeviceNet object attributes 1, 2
/// and 6–9.
struct Expected {
    mac: MacId,
    rate: BaudRate,
    mac_changed: bool,
    rate_changed: bool,
    mac_switch: u8,
    rate_switch: u8,
}

/// Powers the board on again on a bus at the expected rate, brings it up at the expected MAC
/// and reads the attributes; `while_running` then runs on the live node (its master and MAC).
fn boot(
    previous: &Handle,
    elf: &Firmware,
    switches: u8,
    want: &Expected,
    while_running: &mut dyn FnMut(&Handle, &mut Master<'_, '_>, MacId) -> Result<(), String>,
) -> Result<Handle, String> {
    let options = Options {
        bus_rate: bitrate(want.rate),
        setting: NodeSetting { mac: want.mac, rate: want.rate, bus_off_interrupt: false },
    };
    let handle = &power_cycled(previous, elf, &options)?;
    set_switches(handle, switches)?;
    let mut bus = bus_with(handle, &options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions { target: want.mac, ..ConnectOptions::default() });
    machine_fault(handle)?;
    connected.map_err(|e| format!("no node at MAC {} at {:?}: {e}", want.mac, want.rate))?;
    let expected = [
        (1, want.mac.as_raw()),
        (2, want.rate.attribute_value()),
        (6, u8::from(want.mac_changed)),
        (7, u8::from(want.rate_changed)),
        (8, want.mac_switch),
        (9, want.rate_switch),
    ];
    for (attribute, value) in expected {
        let (got, _) = master
            .get(want.mac, DEVICENET.0, DEVICENET.1, attribute)
            .map_err(|e| format!("MAC {}: get attribute {attribute}: {e}", want.mac))?;
        if got != [value] {
            return Err(format!("MAC {}: attribute {attribute} is {got:02x?}, not {value:02x}", want.mac));
        }
    }
    while_running(handle, &mut master, want.mac)?;
    machine_fault(handle)?;
    master_checks(master.session)?;
    Ok(Rc::clone(handle))
}

/// Three boots of the reference board's rule:
/// 1. stored MAC 5 at 125k (with that switch reading); the switches at MAC 12, 250k: the node
///    runs at MAC 12 on a 250k bus, attributes 6 and 7 report both switches moved, 8 and 9
///    their values; then, while it runs, the switches move to MAC 33, 500k: nothing changes (the
///    node still answers at MAC 12, attributes 1 and 8 still read 12), as they are read once at
///    reset; the journal holds the boot's reading (the "changed" attributes' reference);
/// 2. power cycle: the node runs at MAC 33 on a 500k bus, both "changed" again;
/// 3. the rate switches in the program position (3), MAC switches unchanged: the stored MAC 5
///    at 125k rules; attribute 6 clear (the MAC switches did not move), 7 set, 9 reads 3.
pub fn switches(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    if board.switches().is_none() {
        return Err("the board has no switches".into());
    }
    let stored = options.setting;
    let device =
        EmulatedBoard::new(board, elf, stored, options.bus_rate).map_err(|e| format!("the machine: {e}"))?;
    let factory = Rc::new(RefCell::new(device));
    let mac = |raw| MacId::new(raw).ok_or("MAC");
    let first = NodeSetting { mac: mac(12)?, rate: BaudRate::Kbps250, ..stored };
    let second = NodeSetting { mac: mac(33)?, rate: BaudRate::Kbps500, ..stored };
    let want = Expected {
        mac: first.mac,
        rate: first.rate,
        mac_changed: true,
        rate_changed: true,
        mac_switch: 12,
        rate_switch: 1,
    };
    let handle = boot(&factory, elf, first.switch_bits(), &want, &mut |handle, master, mac| {
        set_switches(handle, second.switch_bits())?;
        let deadline = master.session.now() + Duration::from_millis(500);
        master.idle_until(deadline).map_err(|e| format!("idle: {e}"))?;
        for attribute in [1, 8] {
            let (got, _) = master
                .get(mac, DEVICENET.0, DEVICENET.1, attribute)
                .map_err(|e| format!("after the switches moved while running: {e}"))?;
            if got != [12] {
                return Err(format!(
                    "the switches moved while running and attribute {attribute} reads {got:02x?}, not 0c"
                ));
            }
        }
        Ok(())
    })?;
    let journal = handle.borrow().stored_settings();
    match journal {
        Some((s, _))
            if s.last_switches == Some(first.switch_bits())
                && (s.mac_id, s.baud_rate) == (stored.mac, stored.rate) => {}
        other => {
            return Err(format!(
            "after the first boot the journal holds {other:?}, not the reading {:#04x} with MAC {} at {:?}",
            first.switch_bits(),
            stored.mac,
            stored.rate
        ))
        }
    }
    let want = Expected { mac: second.mac, rate: second.rate, mac_switch: 33, rate_switch: 2, ..want };
    let handle = boot(&handle, elf, second.switch_bits(), &want, &mut |_, _, _| Ok(()))?;
    let want = Expected {
        mac: stored.mac,
        rate: stored.rate,
        mac_changed: false,
        rate_changed: true,
        mac_switch: 33,
        rate_switch: 3,
    };
    boot(&handle, elf, second.switch_bits() | 0b1100_0000, &want, &mut |_, _, _| Ok(())).map(|_| ())
}
