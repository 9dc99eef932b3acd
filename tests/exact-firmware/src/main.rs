//! `exact-firmware`: runs every scenario on every board ELF given and prints one line each, then
//! `exact firmware: B boards, S scenarios passed, F failed`; exits 0 only when F is 0.
//!
//! ```text
//! exact-firmware --board reference --elf target/…/slave-fw-firmware-reference [--board … --elf …]
//! exact-firmware --dir target/thumbv7em-none-eabihf/firmware [--only BOARD] [--scenario NAME]
//! exact-firmware … [--limit SECONDS]
//! ```
//!
//! `--limit` bounds each scenario's wall time (default 120 s): past it the machine stops and the
//! scenario fails (`the machine stopped: no verdict within the wall-time limit`), so that a
//! firmware which keeps the emulator busy fails instead of hanging the runner.
//!
//! With `--dir`, the ELFs are the copies scripts/firmware-size makes: `slave-fw-firmware-<board>`
//! for each board of the board crate.

use exact_firmware::board::BoardKind;
use exact_firmware::device::set_wall_deadline;
use exact_firmware::scenario::{self, Options};
use std::path::PathBuf;
use std::process::ExitCode;

fn usage() -> ExitCode {
    eprintln!(
        "usage: exact-firmware (--board NAME --elf PATH)... | --dir DIR [--only BOARD]... [--scenario NAME]... [--limit SECONDS]"
    );
    ExitCode::from(2)
}

fn main() -> ExitCode {
    let mut args = std::env::args().skip(1);
    let mut boards: Vec<(String, PathBuf)> = Vec::new();
    let mut pending: Option<String> = None;
    let mut dir: Option<PathBuf> = None;
    let mut only: Vec<String> = Vec::new();
    let mut scenarios: Vec<String> = Vec::new();
    let mut limit = std::time::Duration::from_secs(120);
    while let Some(arg) = args.next() {
        let Some(value) = args.next() else { return usage() };
        match arg.as_str() {
            "--board" => pending = Some(value),
            "--elf" => match pending.take() {
                Some(name) => boards.push((name, PathBuf::from(value))),
                None => return usage(),
            },
            "--dir" => dir = Some(PathBuf::from(value)),
            "--only" => only.push(value),
            "--scenario" => scenarios.push(value),
            "--limit" => match value.parse() {
                Ok(seconds) => limit = std::time::Duration::from_secs(seconds),
                Err(_) => return usage(),
            },
            _ => return usage(),
        }
    }
    if let Some(dir) = dir {
        for kind in BoardKind::all() {
            boards.push((kind.name.to_string(), dir.join(format!("slave-fw-firmware-{}", kind.name))));
        }
    }
    boards.retain(|(name, _)| only.is_empty() || only.contains(name));
    if boards.is_empty() || pending.is_some() {
        return usage();
    }
    let chosen: Vec<_> = scenario::ALL
        .iter()
        .filter(|s| scenarios.is_empty() || scenarios.iter().any(|n| n == s.name))
        .collect();
    if chosen.is_empty() {
        return usage();
    }
    let (mut passed, mut failed) = (0, 0);
    for (name, path) in &boards {
        let loaded =
            BoardKind::by_name(name).ok_or_else(|| format!("no board called {name}")).and_then(|kind| {
                std::fs::read(path).map(|elf| (kind, elf)).map_err(|e| format!("{}: {e}", path.display()))
            });
        for s in &chosen {
            let outcome = match &loaded {
                Ok((kind, elf)) => {
                    set_wall_deadline(Some(std::time::Instant::now() + limit));
                    scenario::run(s, *kind, elf, &Options::default())
                }
                Err(why) => {
                    scenario::Outcome { board: name.clone(), scenario: s.name, result: Err(why.clone()) }
                }
            };
            println!("{}", outcome.line());
            if outcome.result.is_ok() {
                passed += 1;
            } else {
                failed += 1;
            }
        }
    }
    println!("exact firmware: {} boards, {passed} scenarios passed, {failed} failed", boards.len());
    if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
