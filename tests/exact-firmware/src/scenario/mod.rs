//! The scenarios: each runs one board ELF on a fresh [`EmulatedBoard`](crate::EmulatedBoard) on
//! a simulated bus and compares what happens with what must; [`Outcome::line`] is the runner's
//! line for it. A scenario that does not apply to a board ([`Scenario::applies`]) is not run on
//! it, and not listed.
//!
//! | scenario | boards | file |
//! |---|---|---|
//! | `bring-up`, `breaker`, `power-cycle` | every board | [`bring_up`] |
//! | `configure` | every board | [`configure`] |
//! | `ccv` | every board | [`ccv`] |
//! | `line-events` | every board | [`line_events`] |
//! | `download-cut` | every board | [`download_cut`] |
//! | `wrong-bit-rate`, `bus-load`, `bus-off` | every board | [`can`] |
//! | `switches` | boards with DIP switches (the reference board) | [`switches`] |
//! | `mac63-autobaud-125k`, `-250k`, `-500k`, `autobaud-silent-bus` | boards without switches | [`autobaud`] |
//! | `leds` | every board | [`leds`] |
//! | `can-self-test-fault` | every board | [`self_test`] |
//! | `settings-migration` | every board (linked at ACTIVE, issue 31) | [`migration`] |
//! | `trial-confirm` | every board: an image swapped in by the bootloader confirms once on-line | [`trial`] |
//! | `update-object` | every board: class 0x6A's attributes 5–8 (chunk size, largest image, board ID, key ID) | [`update_object`] |
//! | `firmware-update-rollback` | every board: an image that never confirms is reverted by the watchdog | [`rollback`] |
//! | `firmware-update-bad-signature` | every board: a bad signature or another board's image is refused by the bootloader | [`bad_signature`] |
//! | `firmware-update` | every board: the update over the bus by `master-core`'s client, confirmed, then a power cycle with no flash operation | [`update`] |
//! | `firmware-update-power-cut` | every board, only when named ([`ON_REQUEST`]): a power cut at 12 points of the swap, the new image comes up; after every chunk of the transfer, the old firmware comes up and the transfer resumes at the next chunk | [`swap_cut`], [`transfer_cut`] |

pub mod autobaud;
pub mod bad_signature;
pub mod bring_up;
pub mod can;
pub mod ccv;
pub mod configure;
pub mod dfu;
pub mod download_cut;
pub mod leds;
pub mod line_events;
pub mod migration;
pub mod rollback;
pub mod self_test;
pub mod swap_cut;
pub mod switches;
pub mod transfer_cut;
pub mod trial;
pub mod update;
pub mod update_object;
pub mod world;

use crate::board::BoardKind;
use crate::device::Firmware;
pub use world::{Options, MAC};

/// A scenario: its name, the boards it applies to, and what it runs.
#[derive(Clone, Copy)]
pub struct Scenario {
    /// The name printed.
    pub name: &'static str,
    /// Whether it applies to a board (switches, autobaud).
    pub applies: fn(BoardKind) -> bool,
    /// Runs it on `elf` of `board`; `Err` says why it failed.
    pub run: fn(BoardKind, &Firmware, &Options) -> Result<(), String>,
}

fn every_board(_: BoardKind) -> bool {
    true
}

fn with_switches(board: BoardKind) -> bool {
    board.switches().is_some()
}

fn without_switches(board: BoardKind) -> bool {
    board.switches().is_none()
}

/// Every scenario, in the order the runner runs them.
pub const ALL: [Scenario; 24] = [
    Scenario { name: "bring-up", applies: every_board, run: bring_up::bring_up },
    Scenario { name: "breaker", applies: every_board, run: bring_up::breaker },
    Scenario { name: "power-cycle", applies: every_board, run: bring_up::power_cycle },
    Scenario { name: "configure", applies: every_board, run: configure::configure },
    Scenario { name: "ccv", applies: every_board, run: ccv::ccv },
    Scenario { name: "download-cut", applies: every_board, run: download_cut::download_cut },
    Scenario { name: "wrong-bit-rate", applies: every_board, run: can::wrong_bit_rate },
    Scenario { name: "bus-load", applies: every_board, run: can::bus_load },
    Scenario { name: "bus-off", applies: every_board, run: can::bus_off },
    Scenario { name: "switches", applies: with_switches, run: switches::switches },
    Scenario { name: "mac63-autobaud-125k", applies: without_switches, run: autobaud::at_125k },
    Scenario { name: "mac63-autobaud-250k", applies: without_switches, run: autobaud::at_250k },
    Scenario { name: "mac63-autobaud-500k", applies: without_switches, run: autobaud::at_500k },
    Scenario { name: "autobaud-silent-bus", applies: without_switches, run: autobaud::silent_bus },
    Scenario { name: "leds", applies: every_board, run: leds::leds },
    Scenario { name: "can-self-test-fault", applies: every_board, run: self_test::can_self_test_fault },
    Scenario { name: "line-events", applies: every_board, run: line_events::line_events },
    Scenario { name: "settings-migration", applies: every_board, run: migration::settings_migration },
    Scenario { name: "trial-confirm", applies: every_board, run: trial::trial_confirm },
    Scenario { name: "update-object", applies: every_board, run: update_object::update_object },
    Scenario { name: "firmware-update-rollback", applies: every_board, run: rollback::rollback },
    Scenario {
        name: "firmware-update-bad-signature",
        applies: every_board,
        run: bad_signature::bad_signature,
    },
    Scenario { name: "firmware-update", applies: every_board, run: update::firmware_update },
    Scenario { name: "firmware-update-power-cut", applies: every_board, run: swap_cut::swap_cut },
];

/// The scenarios run only when named (`--scenario NAME`): too slow for every run.
/// `firmware-update-power-cut` takes about 6 minutes of CPU time per board (12 cuts of the swap,
/// each emulating the bootloader's check and swap twice; an update over the bus, a power-up after
/// each of its 510 chunks, and a resumed update).
pub const ON_REQUEST: [&str; 1] = ["firmware-update-power-cut"];

/// The result of one scenario on one board.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The board's build name.
    pub board: String,
    /// The scenario.
    pub scenario: &'static str,
    /// `Err(why)` when it failed.
    pub result: Result<(), String>,
}

impl Outcome {
    /// `ok   BOARD SCENARIO` or `FAIL BOARD SCENARIO: why`.
    pub fn line(&self) -> String {
        match &self.result {
            Ok(()) => format!("ok   {} {}", self.board, self.scenario),
            Err(why) => format!("FAIL {} {}: {}", self.board, self.scenario, why.replace('\n', " ")),
        }
    }
}

/// Runs `scenario` on `elf` of `board`. A scenario that does not apply to the board fails
/// (the runner does not call it for such a board).
pub fn run(scenario: &Scenario, board: BoardKind, elf: &Firmware, options: &Options) -> Outcome {
    let result = if (scenario.applies)(board) {
        (scenario.run)(board, elf, options)
    } else {
        Err(format!("does not apply to the {} board", board.name))
    };
    Outcome { board: board.name.to_string(), scenario: scenario.name, result }
}
