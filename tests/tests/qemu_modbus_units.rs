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
use pty_rig::{bin, require_pymodbus, scratch, workspace_dir, Proc};
use std::time::Duration;

#[test]
#[ignore = "runs QEMU and pymodbus: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p system-tests --test qemu_modbus_units -- --ignored"]
fn the_firmware_keeps_per_unit_health() {
    if std::env::var("DNET_QEMU").as_deref() != Ok("1") {
        eprintln!("DNET_QEMU=1 not set: not running QEMU");
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("qemu-modbus-units");
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
    let mute = dir.join("mute-unit-2");
    let _ = std::fs::remove_file(&mute);
    let server = Proc::spawn(&python, &["-c", SERVER, &usart2, mute.to_str().unwrap()]);
    assert!(server.wait_stdout("ready", Duration::from_secs(20)).is_some(), "{}", server.dump());

    let config = dir.join("modbus-units.toml");
    std::fs::write(&config, DESCRIPTION).unwrap();
    let bus = format!("slcan:{usart1}");
    let mut configure = Proc::spawn(
        bin("dnet-master"),
        &["--bus", &bus, "configure", "--mac", "5", config.to_str().unwrap()],
    );
    let status = configure.wait(Duration::from_secs(60));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "configure:\n{}\n{}", configure.dump(), qemu.0.dump());
    exercise(&bus, &config, &dir, &mute, &[&qemu.0, &server], false);
    let _ = std::fs::remove_file(&mute);
}

/// The QEMU script, stopped with SIGTERM even when the test fails, so that it stops QEMU (a
/// killed script would leave QEMU running until its timeout).
struct Qemu(Proc);

impl Drop for Qemu {
    fn drop(&mut self) {
        self.0.terminate();
    }
}
