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
use pty_rig::{bin, require_pymodbus, scratch, workspace_dir, Proc};
use std::time::Duration;

#[test]
#[ignore = "runs QEMU and pymodbus: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p system-tests --test qemu_modbus_schedule -- --ignored"]
fn the_firmware_runs_a_downloaded_schedule() {
    if std::env::var("DNET_QEMU").as_deref() != Ok("1") {
        eprintln!("DNET_QEMU=1 not set: not running QEMU");
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("qemu-modbus-schedule");
    let flash_dir = dir.join("flash");
    std::fs::create_dir_all(&flash_dir).unwrap();
    let pty_file = dir.join("qemu.ptys");
    let qemu = Qemu(Proc::spawn(
        workspace_dir().join("scripts/qemu-firmware"),
        &[
            "--no-build",
            "--timeout",
            "90",
            "--flash-dir",
            flash_dir.to_str().unwrap(),
            "--pty-file",
            pty_file.to_str().unwrap(),
        ],
    ));
    assert!(qemu.0.wait_stdout("FLASH=", Duration::from_secs(20)).is_some(), "{}", qemu.0.dump());
    let lines = qemu.0.stdout.lines();
    let value = |key: &str| {
        lines
            .iter()
            .find_map(|l| l.strip_prefix(key).map(str::to_string))
            .unwrap_or_else(|| panic!("no {key}"))
    };
    let (usart1, usart2) = (value("USART1="), value("USART2="));
    let server = Proc::spawn(&python, &["-c", SERVER, &usart2]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());

    let config = dir.join("modbus-schedule.toml");
    std::fs::write(&config, DESCRIPTION).unwrap();
    let bus = format!("slcan:{usart1}");
    let mut configure = Proc::spawn(
        bin("dnet-master"),
        &["--bus", &bus, "configure", "--mac", "5", config.to_str().unwrap()],
    );
    let status = configure.wait(Duration::from_secs(60));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "configure:\n{}\n{}", configure.dump(), qemu.0.dump());
    // QEMU's timer runs slower than the host's clock under load (1.3-1.4 s per firmware second in
    // one run on a busy 2-core machine): the gaps are checked loosely, the rates against each other.
    exercise(&bus, &server, &[&qemu.0], 0.9..2.0);
}

/// The QEMU script, stopped with SIGTERM even when the test fails, so that it stops QEMU (a
/// killed script would leave QEMU running until its timeout).
struct Qemu(Proc);

impl Drop for Qemu {
    fn drop(&mut self) {
        self.0.terminate();
    }
}
