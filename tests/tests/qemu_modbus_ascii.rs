//! Modbus ASCII in the real firmware on QEMU: the emulated board (a new settings flash file)
//! starts as the factory default; `dnet-master configure` downloads the meter description
//! (`slave-fw/descriptions/modbus-meter.toml`) with `framing = "ascii"` and 7E1, the format of
//! Modbus over Serial Line V1.02 §2.5.2.1; after its reset the board is an ASCII master and reads
//! pymodbus's ASCII framer (`FramerType.ASCII`) on USART2 into its poll response, and writes the
//! poll command to it. Then a download with `framing = "tcp"` is refused at Commit_Download with
//! the key, and the board keeps its ASCII configuration.
//!
//! QEMU's USART model carries data bytes only (see `qemu_configure.rs`, "The serial line"): the
//! board runs 7E1 (8-bit words with parity, the parity bit masked off), the host end of USART2 is
//! 8N1; the ASCII characters are 7-bit either way.
//!
//! ```sh
//! scripts/qemu-firmware --build-only
//! DNET_QEMU=1 DNET_PYTHON=.venv/bin/python cargo test -p system-tests --test qemu_modbus_ascii -- --ignored
//! ```

use pty_rig::pymodbus::{self, Link, GATEWAY_REGISTERS};
use pty_rig::{bin, qemu, require_pymodbus, scratch, workspace_dir, Proc};
use slave_fw::serial::StatusByte;
use std::path::Path;
use std::time::Duration;

/// The emulated board's MAC ID (the script's default build).
const BOARD: &str = "5";

/// The meter description with `framing` and the serial format replaced, written to `dir`.
fn meter_with(dir: &Path, framing: &str, data_bits: &str) -> std::path::PathBuf {
    let text =
        std::fs::read_to_string(workspace_dir().join("slave-fw/descriptions/modbus-meter.toml")).unwrap();
    let find = ["[profile.modbus]\n", "data_bits = \"eight\"\n"];
    assert!(find.iter().all(|f| text.contains(f)), "the meter description changed");
    let text = text.replacen(find[0], &format!("{}framing = \"{framing}\"\n", find[0]), 1).replacen(
        find[1],
        &format!("data_bits = \"{data_bits}\"\n"),
        1,
    );
    let path = dir.join(format!("modbus-meter-{framing}.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// `dnet-master --bus slcan:USART1 ARGS...`: the exit status, stdout and stderr.
fn dnet_master(usart1: &str, args: &[&str]) -> (Option<i32>, String, String) {
    let bus = format!("slcan:{usart1}");
    let mut all = vec!["--bus", bus.as_str()];
    all.extend_from_slice(args);
    let mut p = Proc::spawn(bin("dnet-master"), &all);
    let status = p.wait(Duration::from_secs(120));
    (status.and_then(|s| s.code()), p.stdout.text(), p.stderr.text())
}

#[test]
#[ignore = "runs QEMU and pymodbus: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p system-tests --test qemu_modbus_ascii -- --ignored"]
fn the_firmware_reads_and_writes_a_modbus_ascii_instrument_and_refuses_tcp() {
    if !qemu::enabled() {
        return;
    }
    let Some(python) = require_pymodbus() else {
        return;
    };
    let dir = scratch("qemu-modbus-ascii");
    let board = qemu::Board::start(&dir, 180);
    let (usart1, usart2) = (board.usart1.as_str(), board.usart2.as_str());
    let server = pymodbus::server(&python, Link::Ascii(usart2), &GATEWAY_REGISTERS);

    let ascii = meter_with(&dir, "ascii", "seven");
    let (code, out, err) = dnet_master(usart1, &["configure", "--mac", BOARD, ascii.to_str().unwrap()]);
    assert_eq!(code, Some(0), "configure:\n{out}\n{err}\n{}", board.qemu.dump());

    // The poll command 11 22 33 44 goes to holding registers 16..17 (little-endian image).
    let poll = |qemu: &Proc| {
        let (code, out, err) = dnet_master(
            usart1,
            &["--json", "monitor", "--mac", BOARD, "--epr", "100", "--count", "30", "--output", "11223344"],
        );
        assert_eq!(code, Some(0), "monitor:\n{out}\n{err}\n{}", qemu.dump());
        pymodbus::last_sample(&out)
    };
    let last = poll(&board.qemu);
    assert_eq!(last.len(), 14, "{last:02X?}");
    assert_eq!(&last[..8], &[0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07], "input registers 0..3");
    assert_eq!(&last[8..12], &[0xCD, 0xAB, 0x34, 0x12], "holding registers 100..101");
    assert_eq!(last[12] & 0x0F, StatusByte::LINK_OK, "link ok, no errors: {:#04X}", last[12]);
    let write = "write unit=1 function=16 address=16 values=0x2211,0x4433";
    assert!(server.wait_stdout(write, Duration::from_secs(3)).is_some(), "{write}\n{}", server.dump());

    // Modbus TCP is refused where the board checks a configuration, and ASCII keeps running.
    let tcp = meter_with(&dir, "tcp", "eight");
    let (code, out, err) = dnet_master(usart1, &["configure", "--mac", BOARD, tcp.to_str().unwrap()]);
    assert_ne!(code, Some(0), "a TCP download must be refused:\n{out}\n{err}");
    assert!(format!("{out}{err}").contains("profile.modbus.framing"), "{out}\n{err}");
    let last = poll(&board.qemu);
    assert_eq!(&last[..8], &[0x02, 0x01, 0x04, 0x03, 0x06, 0x05, 0x08, 0x07], "still reading over ASCII");
}
