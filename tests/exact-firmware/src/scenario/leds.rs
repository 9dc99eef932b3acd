//! `leds`: the Module Status and Network Status patterns (protocol §7.3, devicenet's
//! `led` module, board/src/leds.rs) on the LED pins' output levels, sampled after every slice of
//! CPU time (at most [`STEP`]) over virtual time.
//!
//! On a board with one LED (board/src/leds.rs, `single_lit`) it is lit when the Module Status is
//! red, or green with the Network Status lit; the scenario writes that rule out itself
//! (`expected`) rather than take the board crate's function.

use super::world::{machine_fault, master_checks, Handle, Options, MAC};
use crate::board::BoardKind;
use crate::device::Firmware;
use crate::device::{EmulatedBoard, OnBus, STEP};
use board::boards::LedWiring;
use can_io::sim::{PowerOn, SimBus};
use devicenet::led::Lit;
use devicenet::{Duration, Instant};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::cell::RefCell;
use std::rc::Rc;
use stm32_emu::periph::Nanos;

/// How far a lit or dark stretch may differ from the rule's: the firmware refreshes its LEDs
/// every 25 ms (slave-fw-firmware `LED_PERIOD`), on its 1 ms tick.
const TOLERANCE_MS: u64 = 30;

/// The pins' levels as a bit mask: for two bicolour LEDs bit 0 MS green, 1 MS red, 2 NS green,
/// 3 NS red; for one LED bit 0.
pub(super) type Levels = u8;

/// What the board's LED pins show when the Module Status is `module` and the Network Status is
/// `network`.
fn expected(wiring: LedWiring, module: Lit, network: Lit) -> Levels {
    match wiring {
        LedWiring::Bicolour { .. } => {
            let bits = |lit| match lit {
                Lit::Off => 0,
                Lit::Green => 1,
                Lit::Red => 2,
            };
            bits(module) | bits(network) << 2
        }
        LedWiring::Single(_) => u8::from(module == Lit::Red || (module == Lit::Green && network != Lit::Off)),
    }
}

/// A stretch of time (ms from the LEDs' first change) with one level.
#[derive(Clone, Copy, Debug)]
struct Run {
    start: u64,
    end: u64,
    levels: Levels,
}

impl Run {
    fn len(&self) -> u64 {
        self.end - self.start
    }
}

/// The LED pins' changes: (machine time, levels), the first the levels before power-on.
pub(super) type Changes = Rc<RefCell<Vec<(Nanos, Levels)>>>;

/// Records every change of the LED pins' levels (machine time, levels).
pub(super) fn watch_leds(handle: &Handle) -> Result<Changes, String> {
    let kind = handle.borrow().kind();
    let (port, pins): (_, Vec<u8>) = match kind.spec.leds {
        LedWiring::Bicolour { ms_green } => (ms_green.port, (0..4).map(|i| ms_green.number + i).collect()),
        LedWiring::Single(pin) => (pin.port, vec![pin.number]),
    };
    let gpio = handle.borrow().gpio(crate::board::port(port)).ok_or("no model of the LEDs' port")?;
    let changes = Rc::new(RefCell::new(vec![(0, 0)]));
    let log = Rc::clone(&changes);
    handle.borrow_mut().watch(Some((
        STEP,
        Box::new(move |mcu| {
            let gpio = gpio.borrow();
            let levels = pins
                .iter()
                .enumerate()
                .fold(0, |l, (i, &n)| l | u8::from(gpio.output_level(n) == Some(true)) << i);
            let mut log = log.borrow_mut();
            if log.last().is_some_and(|&(_, last)| last != levels) {
                log.push((mcu.now(), levels));
            }
        }),
    )));
    Ok(changes)
}

/// The stretches from `changes` up to `end` (machine time), in ms from `origin`.
fn runs(changes: &[(Nanos, Levels)], origin: Nanos, end: Nanos) -> Vec<Run> {
    let ms = |t: Nanos| t.saturating_sub(origin) / 1_000_000;
    let mut out = Vec::new();
    for (i, &(at, levels)) in changes.iter().enumerate() {
        let next = changes.get(i + 1).map_or(end, |&(t, _)| t);
        if at >= origin && next > at {
            out.push(Run { start: ms(at), end: ms(next), levels });
        }
    }
    out
}

/// Steps of `(levels, ms)` merged where consecutive levels are equal.
fn merged(steps: &[(Levels, u64)]) -> Vec<(Levels, u64)> {
    let mut out: Vec<(Levels, u64)> = Vec::new();
    for &(levels, ms) in steps {
        match out.last_mut() {
            Some(last) if last.0 == levels => last.1 += ms,
            _ => out.push((levels, ms)),
        }
    }
    out
}

/// The power-up test: the first stretches are the steps, each within the tolerance, the last
/// at least as long.
fn check_sequence(what: &str, runs: &[Run], steps: &[(Levels, u64)]) -> Result<(), String> {
    let steps = merged(steps);
    for (i, &(levels, ms)) in steps.iter().enumerate() {
        let Some(run) = runs.get(i) else {
            return Err(format!("{what}: {} stretches, not {}: {runs:?}", runs.len(), steps.len()));
        };
        let last = i + 1 == steps.len();
        let long_enough = run.len() + TOLERANCE_MS >= ms;
        if run.levels != levels || !long_enough || (!last && run.len() > ms + TOLERANCE_MS) {
            return Err(format!(
                "{what}: step {i} shows {:04b} for {} ms, not {levels:04b} for {ms} ms",
                run.levels,
                run.len()
            ));
        }
    }
    Ok(())
}

/// Between `from` and `to` (ms) the pins show `levels` throughout.
fn check_solid(what: &str, runs: &[Run], from: u64, to: u64, levels: Levels) -> Result<(), String> {
    let inside: Vec<_> = runs.iter().filter(|r| r.end > from && r.start < to).collect();
    match inside.iter().find(|r| r.levels != levels) {
        _ if inside.is_empty() => Err(format!("{what}: nothing seen between {from} and {to} ms")),
        Some(r) => Err(format!(
            "{what}: {:04b} from {} to {} ms, not {levels:04b} throughout {from}..{to} ms",
            r.levels, r.start, r.end
        )),
        None => Ok(()),
    }
}

/// Between `from` and `to` (ms) the pins alternate between `on` and `off`, 500 ms each (the
/// stretches cut by the window's ends excepted), at least three whole stretches.
fn check_flashing(
    what: &str,
    runs: &[Run],
    from: u64,
    to: u64,
    on: Levels,
    off: Levels,
) -> Result<(), String> {
    let inside: Vec<_> = runs.iter().filter(|r| r.end > from && r.start < to).collect();
    let whole: Vec<_> = inside.iter().filter(|r| r.start > from && r.end < to).collect();
    if let Some(r) = inside.iter().find(|r| r.levels != on && r.levels != off) {
        return Err(format!(
            "{what}: {:04b} from {} to {} ms, neither {on:04b} nor {off:04b}",
            r.levels, r.start, r.end
        ));
    }
    if let Some(r) = whole.iter().find(|r| r.len().abs_diff(500) > TOLERANCE_MS) {
        return Err(format!("{what}: {:04b} for {} ms (from {} ms), not 500 ms", r.levels, r.len(), r.start));
    }
    if whole.len() < 3 {
        return Err(format!(
            "{what}: {} whole flashes between {from} and {to} ms, not 3 or more: {inside:?}",
            whole.len()
        ));
    }
    Ok(())
}

/// The board alone on a bus with the master, powered at the start:
/// - the power-up test, within 200 ms of power-on (from the LEDs' first change; on one LED,
///   dark in the first step, 250 ms before it): MS green, MS red, off, NS green, NS red,
///   off, 250 ms each (one LED, by its rule: dark in the MS green step, lit in the MS red step,
///   then dark; board/src/leds.rs says lit for both MS steps, which the firmware does not do);
/// - not on-line (the duplicate MAC ID check, up to 1 s after its second request): MS green,
///   NS off (one LED: dark);
/// - on-line, not allocated (until the master's network access ends): NS flashing green
///   (one LED: flashing);
/// - allocated, polled every 100 ms: NS green (one LED: lit);
/// - the poll connection timed out (polls stopped; expected packet rate 100 ms, so 400 ms): NS
///   flashing red (one LED: flashing).
pub fn leds(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let mut device = EmulatedBoard::new(board, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    let origin = device.mcu().now();
    let handle = Rc::new(RefCell::new(device));
    let changes = watch_leds(&handle)?;
    let mut bus = SimBus::new(options.bus_rate);
    bus.attach(Box::new(OnBus(Rc::clone(&handle))), PowerOn::AtStart);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let machine = |at: Instant| origin + at.total_micros() * 1000;
    master.idle_until(Instant::from_millis(4600)).map_err(|e| format!("idle: {e}"))?;
    let access = master.session.now();
    let connected = master.connect(&ConnectOptions { target: MAC, polls: 10, ..ConnectOptions::default() });
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let allocated = master.session.now();
    for _ in 0..15 {
        let deadline = master.session.now() + Duration::from_millis(100);
        master.poll(MAC, &[0; 8], 18, 8, Duration::from_millis(500)).map_err(|e| format!("poll: {e}"))?;
        master.idle_until(deadline).map_err(|e| format!("idle: {e}"))?;
    }
    let last_poll = master.session.now();
    master.idle_until(last_poll + Duration::from_millis(4000)).map_err(|e| format!("idle: {e}"))?;
    let end = master.session.now();
    machine_fault(&handle)?;
    master_checks(master.session)?;

    let changes = changes.borrow();
    let wiring = board.spec.leds;
    let e = |module, network| expected(wiring, module, network);
    use Lit::{Green, Off, Red};
    let steps = [(Green, Off), (Red, Off), (Off, Off), (Off, Green), (Off, Red), (Off, Off)];
    let mut sequence: Vec<_> = steps.iter().map(|&(m, n)| (e(m, n), 250)).collect();
    sequence.push((e(Green, Off), 400));
    let sequence = merged(&sequence);
    // The test starts where the first step differs from the dark pins before it (one LED: dark
    // in the first step, lit in the second).
    let Some(&(first_change, _)) = changes.get(1) else { return Err("the LEDs never changed".into()) };
    let lead = if sequence[0].0 == 0 { sequence[0].1 * 1_000_000 } else { 0 };
    let t0 = first_change.saturating_sub(lead);
    if t0.saturating_sub(origin) > 200_000_000 {
        return Err(format!("the power-up test began {} ms after power-on", (t0 - origin) / 1_000_000));
    }
    let mut changes = changes.clone();
    if lead > 0 {
        changes.insert(1, (t0, 0));
    }
    let ms = |at: Instant| (machine(at) - t0) / 1_000_000;
    let runs = runs(&changes, t0, machine(end));

    check_sequence("self-test, then not on-line", &runs, &sequence)?;
    // On-line 1 s after the node's second duplicate MAC ID request, about 2 s after power-on.
    check_flashing("on-line, not allocated", &runs, 2100, ms(access) + 1900, e(Green, Green), e(Green, Off))?;
    check_solid("allocated", &runs, ms(allocated) - 500, ms(last_poll), e(Green, Green))?;
    check_flashing(
        "poll connection timed out",
        &runs,
        ms(last_poll) + 500,
        ms(end),
        e(Green, Red),
        e(Green, Off),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn runs_of(steps: &[(Levels, u64)]) -> Vec<Run> {
        let mut at = 0;
        steps
            .iter()
            .map(|&(levels, ms)| {
                at += ms;
                Run { start: at - ms, end: at, levels }
            })
            .collect()
    }

    #[test]
    fn flashing_at_the_half_period_passes_and_another_period_fails() {
        let good = runs_of(&[(1, 300), (5, 500), (1, 500), (5, 500), (1, 500), (5, 200)]);
        assert_eq!(check_flashing("x", &good, 0, 2500, 5, 1), Ok(()));
        let fast = runs_of(&[(1, 250), (5, 250), (1, 250), (5, 250), (1, 250), (5, 250)]);
        assert!(check_flashing("x", &fast, 0, 1500, 5, 1).is_err());
        let solid = runs_of(&[(5, 3000)]);
        assert!(check_flashing("x", &solid, 0, 2500, 5, 1).is_err(), "no whole flash");
        let wrong_colour = runs_of(&[(1, 500), (9, 500), (1, 500), (9, 500)]);
        assert!(check_flashing("x", &wrong_colour, 0, 1900, 5, 1).is_err());
    }

    #[test]
    fn the_power_up_test_needs_every_step_in_order() {
        let steps = [(1, 250), (2, 250), (0, 250), (4, 250), (8, 250), (0, 250), (1, 400)];
        let good = runs_of(&[(1, 250), (2, 250), (0, 250), (4, 250), (8, 250), (0, 250), (1, 900)]);
        assert_eq!(check_sequence("x", &good, &steps), Ok(()));
        let swapped = runs_of(&[(2, 250), (1, 250), (0, 250), (4, 250), (8, 250), (0, 250), (1, 900)]);
        assert!(check_sequence("x", &swapped, &steps).is_err());
        let short = runs_of(&[(1, 100), (2, 250), (0, 250), (4, 250), (8, 250), (0, 250), (1, 900)]);
        assert!(check_sequence("x", &short, &steps).is_err());
    }

    #[test]
    fn one_led_is_lit_for_a_red_module_or_a_lit_network() {
        let single = LedWiring::Single(board::pins::Pin { port: board::pins::Port::A, number: 5 });
        assert_eq!(expected(single, Lit::Green, Lit::Off), 0);
        assert_eq!(expected(single, Lit::Green, Lit::Red), 1);
        assert_eq!(expected(single, Lit::Red, Lit::Off), 1);
        assert_eq!(expected(single, Lit::Off, Lit::Green), 0);
        let pair =
            LedWiring::Bicolour { ms_green: board::pins::Pin { port: board::pins::Port::C, number: 0 } };
        assert_eq!(expected(pair, Lit::Green, Lit::Red), 0b1001);
    }
}
