//! `dnet-master replay` as a bench test on the real SLCAN path (issue 33, item 9): `dnet-master`
//! against `dnet-soft-slave` on SLCAN over a socat pty pair, `dnet-sim-breaker` as the instrument.
//! The transcript is the bring-up recorded on the simulated bus, the device's power-up included
//! (the soft slave is the same reference device):
//!
//! - replayed from its first frame against the running device, it fails (the device's duplicate
//!   MAC ID check is due and never comes) and the note says when to power the device on;
//! - `--from-online` skips the start-up and the rest replays;
//! - poll data recorded with other values diverges, and replays with `--ignore-data io`, reported
//!   as not compared;
//! - `--from-online=wait` waits for a device powered on after the replay started.
//!
//! Needs socat and the soft slave's binaries (`cargo build -p soft-slave`): ignored in the plain
//! host-test run, run by the `scripts/check` stage "dnet-master on the real SLCAN path"; skips with
//! a message without socat, fails in CI.

use pty_rig::{require_socat, Proc, PtyRig};
use std::path::{Path, PathBuf};
use std::time::Duration;

const DNET: &str = env!("CARGO_BIN_EXE_dnet-master");

/// `dnet-master --bus slcan:PTY replay ARGS` as a process.
fn start_replay(rig: &PtyRig, args: &[&str]) -> Proc {
    let bus = rig.master_bus_arg();
    let mut all = vec!["--bus", bus.as_str(), "replay"];
    all.extend_from_slice(args);
    Proc::spawn(DNET, &all)
}

/// Its exit status and everything it printed.
fn finish(rig: &PtyRig, mut p: Proc, args: &[&str]) -> (i32, String) {
    let status = p
        .wait(Duration::from_secs(60))
        .unwrap_or_else(|| panic!("dnet-master replay {args:?} hangs\n{}\n{}", p.dump(), rig.dump()));
    (status.code().unwrap_or(-1), format!("{}{}", p.stdout.text(), p.stderr.text()))
}

fn replay(rig: &PtyRig, args: &[&str]) -> (i32, String) {
    let p = start_replay(rig, args);
    finish(rig, p, args)
}

/// The bring-up with two polls recorded on the simulated bus, left allocated (`--keep`): the
/// master's and the device's duplicate MAC ID checks (4 frames), then 28 frames.
fn sim_transcript(dir: &Path) -> PathBuf {
    let log = dir.join("sim.log");
    let o = std::process::Command::new(DNET)
        .args([
            "--bus",
            "sim",
            "--keep",
            "--log",
            log.to_str().unwrap(),
            "connect",
            "--mac",
            "5",
            "--polls",
            "2",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stdout));
    log
}

#[test]
#[ignore = "needs socat: run by scripts/check"]
fn replay_from_online_and_ignore_data_on_the_slcan_path() {
    if !require_socat() {
        return;
    }
    let mut rig = PtyRig::breaker("replay-online", &["--period", "0.3"], None);
    let log = sim_transcript(&rig.dir);
    let path = log.to_str().unwrap();
    // The device on-line (its own duplicate MAC ID check over): it answers a request.
    let bus = rig.master_bus_arg();
    let mut get = Proc::spawn(DNET, &["--bus", bus.as_str(), "get", "5", "1", "1", "1"]);
    let status = get.wait(Duration::from_secs(60)).expect("get ends");
    assert!(status.success(), "{}\n{}", get.dump(), rig.dump());

    // In step with the transcript: the device, on-line already, never sends its check.
    let (code, out) = replay(&rig, &[path]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("replay diverged at transcript line 3"), "{out}");
    assert!(out.contains("the device sent nothing within"), "{out}");
    assert!(out.contains("power it on between 1.0 s and 3.0 s after the replay starts"), "{out}");

    // --from-online: the start-up skipped, the device's 15 frames of the rest compared.
    let (code, out) = replay(&rig, &[path, "--from-online"]);
    assert_eq!(code, 0, "{out}\n{}", rig.dump());
    assert!(out.contains("replay held: 32 frames, 15 from the device compared byte for byte"), "{out}");
    assert!(out.contains("4 start-up frames skipped (--from-online)"), "{out}");

    // Poll data recorded with other values: a divergence, unless the I/O data is ignored.
    let text = std::fs::read_to_string(&log).unwrap().replace("3C5#0000000000000000", "3C5#0000010203040506");
    let live = rig.dir.join("live.log");
    std::fs::write(&live, text).unwrap();
    let live = live.to_str().unwrap();
    let (code, out) = replay(&rig, &[live, "--from-online"]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("the device sent a different frame"), "{out}");
    let (code, out) = replay(&rig, &[live, "--from-online", "--ignore-data", "io"]);
    assert_eq!(code, 0, "{out}\n{}", rig.dump());
    assert!(
        out.contains("9 from the device compared byte for byte, 6 I/O frames from the device not compared"),
        "{out}"
    );

    // --from-online=wait: the device powered on after the replay started; its own duplicate MAC
    // ID check is compared with the transcript's and the rest follows it.
    // On the bench the USB-CAN adapter stays plugged in while the device is off; here the soft
    // slave is both, so a stand-in answers the adapter's set-up commands (CR to each) meanwhile.
    rig.stop_slave();
    const STAND_IN: &str = "import os, sys\n\
fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)\n\
while True:\n    os.write(fd, b'\\r' * os.read(fd, 256).count(b'\\r'))\n";
    let mut adapter = Proc::spawn("python3", &["-c", STAND_IN, &rig.can.a]);
    std::thread::sleep(Duration::from_millis(500));
    let args = [path, "--from-online=wait"];
    let p = start_replay(&rig, &args);
    std::thread::sleep(Duration::from_secs(3));
    assert!(p.stdout.text().is_empty(), "still waiting for the device: {}\n{}", p.dump(), adapter.dump());
    adapter.terminate();
    rig.start_slave(None);
    let (code, out) = finish(&rig, p, &args);
    assert_eq!(code, 0, "{out}\n{}", rig.dump());
    assert!(out.contains("replay held: 32 frames, 17 from the device compared byte for byte"), "{out}");
    assert!(out.contains("2 start-up frames skipped"), "the master's own check: {out}");
    assert!(out.contains("note: waiting for MAC 5's duplicate MAC ID check: power it on"), "{out}");
}
