//! Runs the core's slave node through the 28-frame bring-up of protocol §2
//! on a virtual clock, with a scripted master, and prints the frame-by-frame table with a verdict
//! for each frame. Exits non-zero on any difference.
//!
//! `cargo run -p devicenet --example bring_up`

#[path = "../tests/common/mod.rs"]
mod common;

use common::{play_bring_up, reference_node};
use devicenet::reference::{Direction, BRING_UP};
use std::process::ExitCode;

fn main() -> ExitCode {
    // The scripted master of the integration tests: the same frames at the same instants.
    let mut node = reference_node();
    let seen = play_bring_up(&mut node);

    println!(
        "{:>3}  {:>10}  {:<3}  {:<4} {:<24} {:<58} verdict",
        "#", "time", "dir", "id", "data", "meaning"
    );
    let mut failures = 0;
    for i in 0..seen.len().max(BRING_UP.len()) {
        let (got, want) = (seen.get(i), BRING_UP.get(i));
        let ok = matches!((got, want), (Some(g), Some(w))
            if g.direction == w.direction && g.id == w.id && g.data == w.data);
        failures += usize::from(!ok);
        let dir = |d: Direction| if d == Direction::MasterToSlave { "M->" } else { "S->" };
        match got {
            Some(g) => {
                let data: Vec<String> = g.data.iter().map(|b| format!("{b:02X}")).collect();
                println!(
                    "{i:>3}  {:>10}  {}  {:03X}  {:<24} {:<58} {}",
                    g.at.to_string(),
                    dir(g.direction),
                    g.id,
                    data.join(" "),
                    want.map_or("(not in the reference sequence)", |w| w.meaning),
                    if ok { "ok" } else { "DIFFERS" }
                );
            }
            None => println!("{i:>3}  missing: {}", want.map_or("", |w| w.meaning)),
        }
    }
    if failures == 0 {
        println!("\n28 frames, all as in protocol §2");
        ExitCode::SUCCESS
    } else {
        println!("\n{failures} frame(s) differ from protocol §2");
        ExitCode::FAILURE
    }
}
