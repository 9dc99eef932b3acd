//! `can-self-test-fault`: the power-up self-test of the CAN path (board/src/self_test.rs) on a
//! chip whose bxCAN loop back path is broken from power-up (stm32-emu
//! `Bxcan::set_loopback_broken`): the test frame completes but never comes back, the fault the
//! self-test's module docs say it catches (the mailbox/FIFO path). The firmware must take that
//! for a major unrecoverable fault and stay off the bus.
//!
//! Only what can be seen without the bus is checked, since the node must not be on it: its
//! frames, its controller's mode, its LEDs. The Identity status bit 11 the converter sets cannot
//! be read (the node answers nothing).

use super::leds::{watch_leds, Levels};
use super::world::{machine_fault, world, Options, MAC};
use crate::board::BoardKind;
use crate::device::Firmware;
use board::boards::LedWiring;
use can_io::bus::Origin;
use can_io::sim::PowerOn;
use devicenet::Instant;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use stm32_emu::bxcan::Mode;
use stm32_emu::periph::Nanos;

/// From this long after power-on the LEDs must show the fault steadily: the power-up LED test
/// (6 steps of 250 ms, protocol §7.3) starts within 200 ms of power-on, and the firmware
/// refreshes its LEDs every 25 ms.
const SETTLED_MS: u64 = 1_800;
/// How long the scenario runs (bus time): the master goes on-line, finds no node at [`MAC`],
/// and the LEDs are watched for the rest.
const RUN_MS: u64 = 8_000;

/// What a node with a major unrecoverable fault that is off the bus shows: Module Status solid
/// red, Network Status off (not on-line, protocol §7.3); on one LED (board/src/leds.rs, "red
/// (major fault) | any | on"): lit.
fn fault_levels(wiring: LedWiring) -> Levels {
    match wiring {
        LedWiring::Bicolour { .. } => 0b0010,
        LedWiring::Single(_) => 1,
    }
}

/// The LEDs from `from` to `end` (machine time) show `levels` throughout, after having changed
/// at least once before `from` (the power-up test: the firmware runs and drives them).
fn check_leds(changes: &[(Nanos, Levels)], from: Nanos, end: Nanos, levels: Levels) -> Result<(), String> {
    if changes.len() < 2 || changes[1].0 >= from {
        return Err(format!("the LEDs never changed before {} ms: {changes:?}", from / 1_000_000));
    }
    // The levels at `from`: the last change at or before it.
    let at_from = changes.iter().take_while(|&&(t, _)| t <= from).last().map_or(0, |&(_, l)| l);
    if at_from != levels {
        return Err(format!("{at_from:04b} at {} ms, not {levels:04b}", from / 1_000_000));
    }
    match changes.iter().find(|&&(t, l)| t > from && t < end && l != levels) {
        Some(&(t, l)) => Err(format!("{l:04b} from {} ms, not {levels:04b} throughout", t / 1_000_000)),
        None => Ok(()),
    }
}

/// With the loop back path broken from power-up, the board alone with the master for 8 s: the
/// node offers no frame to the bus (not even a duplicate MAC ID check request), the master finds
/// nothing at [`MAC`], the controller is left asleep (off the bus), and from 1.8 s after power-on
/// (the power-up LED test over) the LEDs show Module Status solid red and Network Status off (one
/// LED: lit) throughout.
pub fn can_self_test_fault(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::AtStart)?;
    handle.borrow_mut().break_can_loopback();
    let origin = handle.borrow_mut().mcu().now();
    let changes = watch_leds(&handle)?;
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions { target: MAC, polls: 1, ..ConnectOptions::default() });
    machine_fault(&handle)?;
    if connected.is_ok() {
        return Err(format!(
            "the master connected to MAC {} through a node that must be off the bus",
            MAC.as_raw()
        ));
    }
    master.idle_until(Instant::from_millis(RUN_MS)).map_err(|e| format!("idle: {e}"))?;
    machine_fault(&handle)?;
    let end = handle.borrow_mut().mcu().now();
    if end < origin + RUN_MS * 1_000_000 / 2 {
        return Err(format!("the machine ran {} ms only", (end - origin) / 1_000_000));
    }
    let from_node = session.records().iter().filter(|r| r.origin == Origin::Remote).count();
    let counts = handle.borrow().counts();
    if from_node > 0 || counts.sent > 0 || counts.flagged > 0 {
        return Err(format!(
            "the node offered frames to the bus: {from_node} on the wire, {} sent, {} flagged",
            counts.sent, counts.flagged
        ));
    }
    let mode = handle.borrow().can_mode();
    if mode != Mode::Sleep {
        return Err(format!("the controller is in {mode:?} mode, not left asleep (off the bus)"));
    }
    let changes = changes.borrow();
    let legend = match board.spec.leds {
        LedWiring::Bicolour { .. } => "bits NS red, NS green, MS red, MS green",
        LedWiring::Single(_) => "the one LED",
    };
    check_leds(&changes, origin + SETTLED_MS * 1_000_000, end, fault_levels(board.spec.leds))
        .map_err(|e| format!("the LEDs ({legend}): {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Nanos = 1_000_000;

    #[test]
    fn steady_levels_after_a_change_pass_and_anything_else_fails() {
        let good = [(0, 0), (100 * MS, 1), (500 * MS, 2)];
        assert_eq!(check_leds(&good, 1000 * MS, 5000 * MS, 2), Ok(()));
        assert!(check_leds(&good, 1000 * MS, 5000 * MS, 1).is_err(), "other levels");
        let late = [(0, 0), (100 * MS, 2), (3000 * MS, 6)];
        assert!(check_leds(&late, 1000 * MS, 5000 * MS, 2).is_err(), "a change in the window");
        assert!(check_leds(&[(0, 2)], 1000 * MS, 5000 * MS, 2).is_err(), "never driven");
    }
}
