//! Per-unit health in the real firmware on QEMU: the emulated board (a new settings flash file)
//! starts as the factory default; `dnet-master configure` downloads the two-unit gateway of
//! `modbus_units.rs` with `valid_bits_offset = 4`, so the key travels in the configuration image
//! over DeviceNet; after its reset the board is the Modbus master of pymodbus's RTU server on
//! USART2, and the same scenario must hold: both data-valid bits 1, then unit 2 silenced, its bit
//! 0 and lost data and retries for unit 2 only, read from class 0x69 by `dnet-master units` (the
//! `get` and EDS readers of the pty test are host code, left out here to keep the run short).
//!
//! ```sh
//! scripts/qemu-firmware --build-only
//! DNET_QEMU=1 DNET_PYTHON=.venv/bin/python cargo test -p system-tests --test qemu_modbus_units -- --ignored
//! ```

mod modbus_units_support;

use modbus_units_support::{exercise, DESCRIPTION, SERVER};
use pty_rig::{qemu, require_pymodbus, scratch, Proc};
use std::time::Duration;

#[test]
#[ignore = "runs QEMU and pymodbus: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p system-tests --test qemu_modbus_units -- --ignored"]
fn the_firmware_keeps_per_unit_health() {
    if !qemu::enabled() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("qemu-modbus-units");
    let board = qemu::Board::start(&dir, 90);
    let usart2 = board.usart2.as_str();
    let mute = dir.join("mute-unit-2");
    let _ = std::fs::remove_file(&mute);
    let server = Proc::spawn(&python, &["-c", SERVER, usart2, mute.to_str().unwrap()]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());

    let config = board.configure(&dir, "modbus-units.toml", DESCRIPTION, 5);
    let bus = board.bus();
    exercise(&bus, &config, &dir, &mute, &[&board.qemu, &server], false);
    let _ = std::fs::remove_file(&mute);
}
