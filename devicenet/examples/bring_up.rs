//! Runs the core's slave node through the 28-frame bring-up of `../shared/devicenet-notes.md` §2
//! on a virtual clock, with a scripted master, and prints the frame-by-frame table with a verdict
//! for each frame. Exits non-zero on any difference.
//!
//! `cargo run -p devicenet --example bring_up`

use devicenet::reference::{Direction, BRING_UP, INPUT_IMAGE};
use devicenet::{CanFrame, DeviceConfig, Duration, Instant, SlaveNode};
use std::process::ExitCode;

struct Seen {
    at: Instant,
    direction: Direction,
    frame: CanFrame,
}

fn drain(node: &mut SlaveNode, at: Instant, seen: &mut Vec<Seen>) {
    while let Some(frame) = node.poll_transmit() {
        seen.push(Seen { at, direction: Direction::SlaveToMaster, frame });
    }
}

fn run_until(node: &mut SlaveNode, until: Instant, seen: &mut Vec<Seen>) {
    while let Some(at) = node.poll_at().filter(|&at| at <= until) {
        node.handle_timeout(at);
        drain(node, at, seen);
    }
    node.handle_timeout(until);
    drain(node, until, seen);
}

fn main() -> ExitCode {
    let mut node = match SlaveNode::new(DeviceConfig::reference()) {
        Ok(node) => node,
        Err(e) => {
            eprintln!("invalid device configuration: {e}");
            return ExitCode::FAILURE;
        }
    };
    if node.set_input(&INPUT_IMAGE).is_err() {
        eprintln!("input image does not match the produced size");
        return ExitCode::FAILURE;
    }
    let mut seen = Vec::new();
    let mut now = Instant::ZERO;
    let masters = BRING_UP.iter().filter(|f| f.direction == Direction::MasterToSlave);
    for (k, f) in masters.enumerate() {
        now = match k {
            0 => Instant::ZERO,
            1 => Instant::from_secs(1),
            2 => Instant::from_secs(4),
            3 => Instant::from_millis(4500),
            _ => now + Duration::from_millis(10),
        };
        if k == 2 {
            run_until(&mut node, Instant::from_secs(2), &mut seen);
            node.power_on(Instant::from_secs(2));
            drain(&mut node, Instant::from_secs(2), &mut seen);
        }
        run_until(&mut node, now, &mut seen);
        let Ok(frame) = CanFrame::from_raw(f.id, f.data) else { return ExitCode::FAILURE };
        seen.push(Seen { at: now, direction: Direction::MasterToSlave, frame });
        node.handle_frame(&frame, now);
        drain(&mut node, now, &mut seen);
    }
    run_until(&mut node, now + Duration::from_millis(10), &mut seen);

    println!(
        "{:>3}  {:>10}  {:<3}  {:<4} {:<24} {:<58} verdict",
        "#", "time", "dir", "id", "data", "meaning"
    );
    let mut failures = 0;
    for i in 0..seen.len().max(BRING_UP.len()) {
        let (got, want) = (seen.get(i), BRING_UP.get(i));
        let ok = matches!((got, want), (Some(g), Some(w))
            if g.direction == w.direction && g.frame.id().as_raw() == w.id && g.frame.data() == w.data);
        failures += usize::from(!ok);
        let dir = |d: Direction| if d == Direction::MasterToSlave { "M->" } else { "S->" };
        match got {
            Some(g) => {
                let data: Vec<String> = g.frame.data().iter().map(|b| format!("{b:02X}")).collect();
                println!(
                    "{i:>3}  {:>10}  {}  {:03X}  {:<24} {:<58} {}",
                    g.at.to_string(),
                    dir(g.direction),
                    g.frame.id().as_raw(),
                    data.join(" "),
                    want.map_or("(not in the reference sequence)", |w| w.meaning),
                    if ok { "ok" } else { "DIFFERS" }
                );
            }
            None => println!("{i:>3}  missing: {}", want.map_or("", |w| w.meaning)),
        }
    }
    if failures == 0 {
        println!("\n28 frames, all as in devicenet-notes §2");
        ExitCode::SUCCESS
    } else {
        println!("\n{failures} frame(s) differ from devicenet-notes §2");
        ExitCode::FAILURE
    }
}
