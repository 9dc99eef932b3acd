//! `dnet-master replay` as a bench test (issue 33, item 9), on the simulated bus: a transcript of
//! a running network (no duplicate MAC ID check) replays against a device brought on-line before
//! its first frame; `--from-online` skips the transcript's start-up; `--from-online=wait` waits for
//! a device powered on later; `--ignore-data io` reports the device's I/O data as not compared
//! instead of failing or passing it. The same on the real SLCAN path: `replay_pty.rs`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn dnet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dnet-master")).args(args).output().expect("run dnet-master")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-master-replay-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A transcript of `connect --keep --polls 2` on the simulated bus: the master's and the device's
/// duplicate MAC ID checks (4 frames), then the bring-up and two polls.
fn recorded(name: &str) -> PathBuf {
    let log = temp(name);
    let o = dnet(&[
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
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let lines = std::fs::read_to_string(&log).unwrap();
    assert!(lines.lines().nth(2).unwrap().contains("42F#00341278563412"), "{lines}");
    log
}

/// `path`'s lines with `edit` applied, written to `name`.
fn edited(path: &Path, name: &str, edit: impl Fn(&str) -> Option<String>) -> PathBuf {
    let out = temp(name);
    let text: String =
        std::fs::read_to_string(path).unwrap().lines().filter_map(edit).map(|l| l + "\n").collect();
    std::fs::write(&out, text).unwrap();
    out
}

fn replay(args: &[&str]) -> (i32, String) {
    let mut all = vec!["--bus", "sim", "replay"];
    all.extend_from_slice(args);
    let o = dnet(&all);
    (o.status.code().unwrap_or(-1), text(&o))
}

/// A capture of a running network has no duplicate MAC ID check: the simulated device is on-line
/// before its first frame (it used to power on at the start and run its check in the middle).
#[test]
fn a_capture_of_a_running_network_replays() {
    let full = recorded("running-full.log");
    let running = edited(&full, "running.log", |l| {
        (!l.contains("#00010004030201") && !l.contains("42F#")).then(|| l.into())
    });
    let (code, out) = replay(&[running.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("replay held: 28 frames, 15 from the device compared byte for byte"), "{out}");
    // No duplicate MAC ID check of the device on the bus at all.
    assert!(!out.contains(" 42F "), "{out}");
}

/// `--from-online` skips the start-up (the 4 duplicate MAC ID check frames) and names it.
#[test]
fn from_online_skips_the_start_up() {
    let full = recorded("skip.log");
    let (code, out) = replay(&[full.to_str().unwrap(), "--from-online"]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("4 start-up frames skipped (--from-online)"), "{out}");
    assert!(out.contains("replay held: 32 frames, 15 from the device compared byte for byte"), "{out}");
    assert!(!out.contains(" 42F "), "the device was on-line before the first frame: {out}");
}

/// A device powered on 5 s after the start: in step with the transcript it is too late; with
/// `--from-online=wait` its own check is compared with the transcript's and the replay goes on.
#[test]
fn from_online_wait_waits_for_the_device_powered_on_later() {
    let full = recorded("wait.log");
    let path = full.to_str().unwrap();
    let (code, out) = replay(&["--slave-power-on", "5000", path]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("replay diverged at transcript line 3"), "{out}");
    let (code, out) = replay(&["--slave-power-on", "5000", path, "--from-online=wait"]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("replay held: 32 frames, 17 from the device compared byte for byte"), "{out}");
    assert!(out.contains("2 start-up frames skipped"), "the master's own check: {out}");
    // A transcript without the device's check: the replay starts once the device is on-line.
    let running = edited(&full, "wait-running.log", |l| {
        (!l.contains("42F#") && !l.contains("#0001000403")).then(|| l.into())
    });
    let (code, out) = replay(&["--slave-power-on", "5000", running.to_str().unwrap(), "--from-online=wait"]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("replay held: 28 frames, 15 from the device compared byte for byte"), "{out}");
}

/// The poll responses recorded with other data (live values): a divergence by default; with
/// `--ignore-data io` not compared (said per frame and in the summary), the rest compared; a
/// different length is still a divergence.
#[test]
fn ignore_data_io_reports_io_data_as_not_compared() {
    let full = recorded("io.log");
    let live =
        edited(&full, "io-live.log", |l| Some(l.replace("3C5#0000000000000000", "3C5#0000010203040506")));
    let path = live.to_str().unwrap();
    let (code, out) = replay(&[path, "--from-online"]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("the device sent a different frame"), "{out}");

    let (code, out) = replay(&[path, "--from-online", "--ignore-data", "io"]);
    assert_eq!(code, 0, "{out}");
    assert!(
        out.contains("9 from the device compared byte for byte, 6 I/O frames from the device not compared"),
        "{out}"
    );
    let o = dnet(&["--bus", "sim", "--json", "replay", path, "--from-online", "--ignore-data", "io"]);
    let doc: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(doc["summary"]["not_compared"], 6, "{doc}");
    let notes: Vec<&str> = doc["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["id"] == "3C5")
        .map(|f| f["note"].as_str().unwrap_or(""))
        .collect();
    assert_eq!(notes.len(), 6, "{doc}");
    assert!(notes.iter().all(|n| n.starts_with("not compared: I/O data ignored")), "{notes:?}");
    assert!(doc["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|f| f["id"] == "3C5")
        .all(|f| f["verdict"] == "info"));

    let short = edited(&full, "io-short.log", |l| Some(l.replace("3C5#8200000000", "3C5#82000000")));
    let (code, out) = replay(&[short.to_str().unwrap(), "--from-online", "--ignore-data", "io"]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("a different identifier or length"), "{out}");
}

/// A transcript that `--from-online` would leave without a frame of the device fails (exit 1).
#[test]
fn from_online_with_nothing_left_fails() {
    let full = recorded("nothing.log");
    let start = edited(&full, "start-up.log", |l| {
        (l.contains("#00010004030201") || l.contains("42F#")).then(|| l.into())
    });
    let (code, out) = replay(&[start.to_str().unwrap(), "--mac", "5", "--from-online"]);
    assert_eq!(code, 1, "{out}");
    assert!(out.contains("nothing from MAC 5 is left to compare"), "{out}");
}
