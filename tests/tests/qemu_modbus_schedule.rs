//! Per-entry scheduling in the real firmware on QEMU: the emulated board (a new settings flash
//! file) starts as the factory default; `dnet-master configure` downloads the scheduling gateway
//! of `modbus_schedule.rs` (a read every 50 ms cycle, a read with `period_ms = 1000`, a
//! function-16 write with `write = "trigger"` on output byte 4), so the schedule keys travel in the
//! configuration image over DeviceNet; after its reset the board is the Modbus master of
//! pymodbus's RTU server on USART2, and the same three monitor runs must show in the server's
//! log the slow entry read about once a second and the triggered write only after its trigger byte
//! changed.
//!
//! ```sh
//! scripts/qemu-firmware --build-only
//! DNET_QEMU=1 DNET_PYTHON=.venv/bin/python cargo test -p system-tests --test qemu_modbus_schedule -- --ignored
//! ```

mod modbus_schedule_support;

use modbus_schedule_support::{exercise, DESCRIPTION, SERVER};
use pty_rig::{qemu, require_pymodbus, scratch, Proc};
use std::time::Duration;

#[test]
#[ignore = "runs QEMU and pymodbus: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p system-tests --test qemu_modbus_schedule -- --ignored"]
fn the_firmware_runs_a_downloaded_schedule() {
    if !qemu::enabled() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("qemu-modbus-schedule");
    let board = qemu::Board::start(&dir, 90);
    let usart2 = board.usart2.as_str();
    let server = Proc::spawn(&python, &["-c", SERVER, usart2]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());

    board.configure(&dir, "modbus-schedule.toml", DESCRIPTION, 5);
    let bus = board.bus();
    // QEMU's timer runs slower than the host's clock under load (1.3-1.4 s per firmware second in
    // one run on a busy 2-core machine): the gaps are checked loosely, the rates against each other.
    exercise(&bus, &server, &[&board.qemu], 0.9..2.0);
}
