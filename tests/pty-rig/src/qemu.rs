//! The emulated board for the QEMU system tests: `scripts/qemu-firmware --no-build` (the ELF that
//! `scripts/qemu-firmware --build-only` left) with its settings flash in a folder of the test's
//! scratch directory, and the two ptys it prints: USART1 carries SLCAN, USART2 the instrument line.

use crate::{bin, workspace_dir, Proc};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Whether the QEMU tests are asked for (`DNET_QEMU=1`, as `scripts/check` sets); says so on
/// stderr when they are not.
pub fn enabled() -> bool {
    let on = std::env::var("DNET_QEMU").as_deref() == Ok("1");
    if !on {
        eprintln!("DNET_QEMU=1 not set: not running QEMU");
    }
    on
}

/// A running emulated board; QEMU is stopped when it is dropped, on failure too.
pub struct Board {
    /// The script and the QEMU it runs.
    pub qemu: Proc,
    /// The pty of USART1 (SLCAN: `--bus slcan:` this).
    pub usart1: String,
    /// The pty of USART2 (the instrument's line).
    pub usart2: String,
}

impl Board {
    /// Starts the board with its flash in `dir/flash` and QEMU bounded to `timeout_s` seconds;
    /// panics (failing the test) when the script does not print its ptys within 20 s.
    pub fn start(dir: &Path, timeout_s: u32) -> Board {
        let flash_dir = dir.join("flash");
        std::fs::create_dir_all(&flash_dir).expect("create the flash folder");
        let pty_file = dir.join("qemu.ptys");
        let qemu = Proc::spawn(
            workspace_dir().join("scripts/qemu-firmware"),
            &[
                "--no-build",
                "--timeout",
                &timeout_s.to_string(),
                "--flash-dir",
                flash_dir.to_str().expect("a UTF-8 scratch path"),
                "--pty-file",
                pty_file.to_str().expect("a UTF-8 scratch path"),
            ],
        );
        assert!(qemu.wait_stdout("FLASH=", Duration::from_secs(20)).is_some(), "{}", qemu.dump());
        let lines = qemu.stdout.lines();
        let value = |key: &str| {
            lines
                .iter()
                .find_map(|l| l.strip_prefix(key).map(str::to_string))
                .unwrap_or_else(|| panic!("scripts/qemu-firmware printed no {key}:\n{}", qemu.dump()))
        };
        let (usart1, usart2) = (value("USART1="), value("USART2="));
        Board { qemu, usart1, usart2 }
    }

    /// The `--bus` argument that reaches the board: `slcan:` its USART1 pty.
    pub fn bus(&self) -> String {
        format!("slcan:{}", self.usart1)
    }

    /// Writes `description` to `dir/name` and downloads it to the board at `mac` with
    /// `dnet-master configure` (at most 60 s); panics (failing the test) unless it exits 0.
    /// Returns the description's path.
    pub fn configure(&self, dir: &Path, name: &str, description: &str, mac: u8) -> PathBuf {
        let config = dir.join(name);
        std::fs::write(&config, description).expect("write the description");
        let mut configure = Proc::spawn(
            bin("dnet-master"),
            &[
                "--bus",
                &self.bus(),
                "configure",
                "--mac",
                &mac.to_string(),
                config.to_str().expect("a UTF-8 scratch path"),
            ],
        );
        let status = configure.wait(Duration::from_secs(60));
        assert_eq!(
            status.and_then(|s| s.code()),
            Some(0),
            "configure:\n{}\n{}",
            configure.dump(),
            self.qemu.dump()
        );
        config
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        self.qemu.terminate();
    }
}
