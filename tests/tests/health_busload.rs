//! The scanner's bus load (guide: docs/src/plant/health.md) counted against can-utils'
//! `canbusload -e` (exact bit stuffing) on `vcan0`: the same frames, played onto the interface by
//! `canplayer`, counted by both; the bits must agree exactly (the time is the same for both, so the
//! bus load's error is the bits' error).
//!
//! Needs a `vcan0` interface, root and can-utils: `#[ignore]`d, run in the vcan guest by
//! `scripts/canvm-run`:
//!
//! ```text
//! cargo test -p system-tests --test health_busload --no-run
//! CARGO_TARGET_X86_64_UNKNOWN_LINUX_GNU_RUNNER=scripts/canvm-run \
//!     cargo test -p system-tests --test health_busload -- --ignored
//! ```

use can_io::sim::frame_bits;
use devicenet::CanFrame;
use std::process::{Command, Stdio};
use std::time::Duration;

/// The frames: the reference bring-up, then frames whose bit patterns stuff little and much.
fn frames() -> Vec<CanFrame> {
    let mut out: Vec<CanFrame> =
        devicenet::reference::BRING_UP.iter().filter_map(|f| CanFrame::from_raw(f.id, f.data).ok()).collect();
    let mut x: u64 = 0x2545_F491_4F6C_DD1D;
    for i in 0..400u32 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let len = (x % 9) as usize;
        let id = (x >> 8) as u16 & 0x7FF;
        let data: Vec<u8> = match i % 4 {
            0 => vec![0x00; len],
            1 => vec![0xFF; len],
            _ => x.to_le_bytes()[..len].to_vec(),
        };
        out.extend(CanFrame::from_raw(if i % 4 == 0 { 0 } else { id }, &data).ok());
    }
    out
}

fn run(cmd: &mut Command) {
    let status = cmd.status().unwrap_or_else(|e| panic!("{cmd:?}: {e}"));
    assert!(status.success(), "{cmd:?}: {status}");
}

#[test]
#[ignore = "needs vcan0, root and can-utils: run in the vcan guest (scripts/canvm-run)"]
fn bus_load_bits_agree_with_canbusload_exact() {
    run(Command::new("ip").args(["link", "set", "vcan0", "up"]));
    let frames = frames();
    let dir = std::env::temp_dir().join(format!("health-busload-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("frames.log");
    let text: String = frames
        .iter()
        .map(|f| {
            let data: String = f.data().iter().map(|b| format!("{b:02X}")).collect();
            format!("(0.000000) vcan0 {:03X}#{data}\n", f.id().as_raw())
        })
        .collect();
    std::fs::write(&log, text).unwrap();
    let load = Command::new("canbusload")
        .args(["-e", "vcan0@500000"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("canbusload (can-utils)");
    std::thread::sleep(Duration::from_millis(1500));
    run(Command::new("canplayer").args(["-t", "-g", "1", "-I", log.to_str().unwrap()]));
    std::thread::sleep(Duration::from_millis(2500));
    run(Command::new("kill").args(["-INT", &load.id().to_string()]));
    let out = load.wait_with_output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    // ` vcan0@500000   FRAMES   BITS  PAYLOAD  LOAD%` once a second.
    let (mut counted, mut bits) = (0u64, 0u64);
    for line in text.lines() {
        let cells: Vec<&str> = line.split_whitespace().collect();
        if cells.first().is_some_and(|c| c.starts_with("vcan0@")) && cells.len() >= 3 {
            counted += cells[1].parse::<u64>().unwrap_or_else(|_| panic!("{line}"));
            bits += cells[2].parse::<u64>().unwrap_or_else(|_| panic!("{line}"));
        }
    }
    let ours: u64 = frames.iter().map(|f| u64::from(frame_bits(f))).sum();
    eprintln!("canbusload -e: {counted} frames, {bits} bits; ours: {} frames, {ours} bits", frames.len());
    assert_eq!(counted, frames.len() as u64, "canbusload saw every frame:\n{text}");
    assert!(bits > 0, "nothing compared:\n{text}");
    let error = (ours as f64 - bits as f64) / bits as f64;
    eprintln!("bus-load error against canbusload -e: {:+.4} %", error * 100.0);
    assert_eq!(ours, bits, "bits on the wire differ ({:+.4} %)", error * 100.0);
    let _ = std::fs::remove_dir_all(&dir);
}
