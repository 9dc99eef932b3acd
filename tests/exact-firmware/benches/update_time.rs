//! The update time of a whole image over the bus (issue 31's figure): the `firmware-update`
//! scenario's update (`exact_firmware::scenario::update::timed_update`: `master-core`'s client,
//! every request and chunk acknowledged, the device back and confirmed) on the exact ELF of each
//! board given (default `reference`), at 125 kbit/s and 500 kbit/s, in the emulator's bus time
//! with the FLASH model at the datasheet's times.
//!
//! ```text
//! scripts/exact-firmware --scenario firmware-update     # builds the ELFs (and runs the scenario)
//! cargo bench -p exact-firmware --bench update_time [-- BOARD ...]
//! ```
//!
//! The ELFs are scripts/exact-firmware's, in `$CARGO_TARGET_DIR` (default `target`)
//! `/thumbv7em-none-eabihf/firmware/`. The figure is bus time: what a master with no turnaround
//! of its own would take; a host adapter's latency per frame comes on top.

use can_io::bus::Bitrate;
use devicenet::slave::BaudRate;
use exact_firmware::board::BoardKind;
use exact_firmware::device::Firmware;
use exact_firmware::scenario::update::timed_update;
use exact_firmware::scenario::world::Options;
use std::path::PathBuf;
use std::process::ExitCode;

fn main() -> ExitCode {
    let mut boards: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    if boards.is_empty() {
        boards.push("reference".into());
    }
    let target =
        std::env::var_os("CARGO_TARGET_DIR").map_or_else(|| PathBuf::from("../../target"), PathBuf::from);
    let dir = target.join("thumbv7em-none-eabihf/firmware");
    let mut failed = false;
    for name in &boards {
        let Some(board) = BoardKind::by_name(name) else {
            eprintln!("no board {name}");
            return ExitCode::from(2);
        };
        let elf = dir.join(format!("slave-fw-firmware-{name}"));
        let firmware = match Firmware::from_files(name, &elf, None) {
            Ok(f) => f,
            Err(e) => {
                eprintln!("{}: {e} (run scripts/exact-firmware first)", elf.display());
                return ExitCode::from(2);
            }
        };
        for (bus_rate, rate, label) in
            [(Bitrate::K125, BaudRate::Kbps125, "125k"), (Bitrate::K500, BaudRate::Kbps500, "500k")]
        {
            let mut options = Options { bus_rate, ..Options::default() };
            options.setting.rate = rate;
            match timed_update(board, &firmware, &options) {
                Ok(t) => println!(
                    "{name} {label}: {} bytes, {} chunks, {:.1} s (back on-line {:.1} s after Apply), {}",
                    t.new.len(),
                    t.report.chunks,
                    t.elapsed.total_micros() as f64 / 1e6,
                    t.report.back_after.total_micros() as f64 / 1e6,
                    t.report.outcome
                ),
                Err(e) => {
                    println!("{name} {label}: FAIL {e}");
                    failed = true;
                }
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}
