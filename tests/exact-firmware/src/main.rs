//! `exact-firmware`: runs every scenario that applies to each board ELF given and prints one line
//! each, then `exact firmware: B boards, S scenarios passed, F failed`; exits 0 only when F is 0.
//!
//! ```text
//! exact-firmware --board reference --elf target/…/slave-fw-firmware-reference [--bootloader ELF] [--board … --elf …]
//! exact-firmware --dir target/thumbv7em-none-eabihf/firmware [--only BOARD] [--scenario NAME]
//! exact-firmware … [--limit SECONDS] [--jobs N]
//! ```
//!
//! The scenarios (`exact_firmware::scenario`): `bring-up`, `breaker`, `power-cycle`,
//! `configure`, `ccv`, `download-cut` (a power cut at every flash operation of a download),
//! `wrong-bit-rate`, `bus-load`, `bus-off`, `leds`, `can-self-test-fault`, `line-events`,
//! `settings-migration`, `trial-confirm`, `update-object`, `firmware-update-rollback`,
//! `firmware-update-bad-signature` and `firmware-update` on every board;
//! `switches` on a board with DIP switches (the reference board); `mac63-autobaud-125k`,
//! `-250k`, `-500k` and `autobaud-silent-bus` on a board without them. A scenario that does not
//! apply to a board is not run on it and not listed. `firmware-update-power-cut` (a power cut
//! after every chunk of the transfer and at 12 points of the bootloader's swap, about 6 minutes
//! of CPU per board) runs only when named with `--scenario` (`scenario::ON_REQUEST`).
//!
//! `--limit` bounds each scenario's wall time (default 300 s, the longest scenario,
//! `download-cut`, taking a minute or more on a busy machine; 1,800 s for
//! `firmware-update-power-cut`): past it the machine stops and the
//! scenario fails (`the machine stopped: no verdict within the wall-time limit`), so that a
//! firmware which keeps the emulator busy fails instead of hanging the runner.
//!
//! `--jobs` runs that many boards at a time, each on its own thread (default 1); each board's
//! lines are printed together when it is done, in the order of the boards.
//!
//! With `--dir`, the ELFs are the copies scripts/firmware-size makes: `slave-fw-firmware-<board>`
//! for each board of the board crate. A firmware linked at ACTIVE (0x0802_0000, issue 31) is
//! flashed with its board's bootloader: `--bootloader ELF` after its `--elf`, else
//! `bootloader-<board>` beside the firmware ELF (scripts/build-bootloader's copy); the reset vector
//! is then the bootloader's, which starts the firmware. `firmware-update-rollback` takes the
//! board's `fault-never-confirm` build from beside the firmware ELF, its name with
//! `-never-confirm` appended (scripts/exact-firmware builds it); without it that scenario fails.

use exact_firmware::board::BoardKind;
use exact_firmware::device::{set_wall_deadline, Firmware};
use exact_firmware::scenario::{self, Options, Outcome, Scenario};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::mpsc;
use std::time::Duration;

fn usage() -> ExitCode {
    eprintln!(
        "usage: exact-firmware (--board NAME --elf PATH [--bootloader PATH])... | --dir DIR [--only BOARD]... [--scenario NAME]... [--limit SECONDS] [--jobs N]"
    );
    ExitCode::from(2)
}

/// A board's name, its firmware ELF and, if given, its bootloader ELF.
struct BoardFiles {
    name: String,
    elf: PathBuf,
    bootloader: Option<PathBuf>,
}

/// What the command line asks for.
struct Run {
    boards: Vec<BoardFiles>,
    scenarios: Vec<&'static Scenario>,
    /// `--limit`, if given.
    limit: Option<Duration>,
    jobs: usize,
}

/// The wall-time limit of a scenario without `--limit`: the longest of the default ones,
/// `download-cut`, takes a minute or more on a busy machine.
const DEFAULT_LIMIT: Duration = Duration::from_secs(300);
/// The same for a scenario run only on request (`firmware-update-power-cut`: 510 power-ups after
/// a cut and the swap's cuts, about 6 minutes on an idle core).
const ON_REQUEST_LIMIT: Duration = Duration::from_secs(1800);

fn parse() -> Option<Run> {
    let mut args = std::env::args().skip(1);
    let mut boards: Vec<BoardFiles> = Vec::new();
    let mut pending: Option<String> = None;
    let mut dir: Option<PathBuf> = None;
    let mut only: Vec<String> = Vec::new();
    let mut names: Vec<String> = Vec::new();
    let mut limit = None;
    let mut jobs = 1;
    while let Some(arg) = args.next() {
        let value = args.next()?;
        match arg.as_str() {
            "--board" => pending = Some(value),
            "--elf" => {
                boards.push(BoardFiles { name: pending.take()?, elf: PathBuf::from(value), bootloader: None })
            }
            "--bootloader" => {
                boards.last_mut().filter(|b| b.bootloader.is_none())?.bootloader = Some(value.into())
            }
            "--dir" => dir = Some(PathBuf::from(value)),
            "--only" => only.push(value),
            "--scenario" => names.push(value),
            "--limit" => limit = Some(Duration::from_secs(value.parse().ok()?)),
            "--jobs" => jobs = value.parse().ok().filter(|&n| n > 0)?,
            _ => return None,
        }
    }
    if let Some(dir) = dir {
        for kind in BoardKind::all() {
            let elf = dir.join(format!("slave-fw-firmware-{}", kind.name));
            boards.push(BoardFiles { name: kind.name.to_string(), elf, bootloader: None });
        }
    }
    boards.retain(|b| only.is_empty() || only.contains(&b.name));
    if let Some(unknown) = names.iter().find(|n| !scenario::ALL.iter().any(|s| s.name == n.as_str())) {
        eprintln!("exact-firmware: no scenario called {unknown}");
        return None;
    }
    let scenarios: Vec<_> = scenario::ALL
        .iter()
        .filter(|s| match names.is_empty() {
            true => !scenario::ON_REQUEST.contains(&s.name),
            false => names.iter().any(|n| n == s.name),
        })
        .collect();
    if boards.is_empty() || pending.is_some() || scenarios.is_empty() {
        return None;
    }
    Some(Run { boards, scenarios, limit, jobs })
}

/// Every chosen scenario that applies to one board; a board that cannot be loaded fails each.
fn run_board(files: &BoardFiles, scenarios: &[&Scenario], limit: Option<Duration>) -> Vec<Outcome> {
    let name = files.name.as_str();
    let loaded = BoardKind::by_name(name).ok_or_else(|| format!("no board called {name}")).and_then(|kind| {
        Firmware::from_files(name, &files.elf, files.bootloader.as_deref()).map(|elf| (kind, elf))
    });
    let mut outcomes = Vec::new();
    for s in scenarios {
        let outcome = match &loaded {
            Ok((kind, _)) if !(s.applies)(*kind) => continue,
            Ok((kind, elf)) => {
                let limit = limit.unwrap_or(match scenario::ON_REQUEST.contains(&s.name) {
                    true => ON_REQUEST_LIMIT,
                    false => DEFAULT_LIMIT,
                });
                set_wall_deadline(Some(std::time::Instant::now() + limit));
                scenario::run(s, *kind, elf, &Options::default())
            }
            Err(why) => Outcome { board: name.to_string(), scenario: s.name, result: Err(why.clone()) },
        };
        outcomes.push(outcome);
    }
    outcomes
}

fn main() -> ExitCode {
    let Some(run) = parse() else { return usage() };
    let (sender, receiver) = mpsc::channel();
    let mut results: Vec<Option<Vec<Outcome>>> = vec![None; run.boards.len()];
    let (mut passed, mut failed, mut printed) = (0, 0, 0);
    let next = std::sync::atomic::AtomicUsize::new(0);
    std::thread::scope(|scope| {
        for _ in 0..run.jobs.min(run.boards.len()) {
            let sender = sender.clone();
            let (run, next) = (&run, &next);
            scope.spawn(move || loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(files) = run.boards.get(i) else { break };
                let outcomes = run_board(files, &run.scenarios, run.limit);
                if sender.send((i, outcomes)).is_err() {
                    break;
                }
            });
        }
        drop(sender);
        for (i, outcomes) in receiver {
            results[i] = Some(outcomes);
            // The boards' lines in order, each as soon as it and those before it are done.
            while let Some(Some(outcomes)) = results.get(printed) {
                for outcome in outcomes {
                    println!("{}", outcome.line());
                    if outcome.result.is_ok() {
                        passed += 1;
                    } else {
                        failed += 1;
                    }
                }
                printed += 1;
            }
        }
    });
    if printed != run.boards.len() {
        println!(
            "FAIL exact-firmware: {} of {} boards never finished (a thread panicked)",
            run.boards.len() - printed,
            run.boards.len()
        );
        failed += 1;
    }
    println!("exact firmware: {} boards, {passed} scenarios passed, {failed} failed", run.boards.len());
    if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
