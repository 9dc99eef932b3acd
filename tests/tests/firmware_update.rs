//! `dnet-master firmware-update` and `sign-firmware` the way they are used: the soft slave
//! (`--firmware-dir`, `--firmware-key`: its update object, class 0x6A) between `dnet-sim-breaker` on one socat pty
//! pair and SLCAN on a second, the master at the far end. The images are small test images (any
//! bytes with a valid image-info block at 0x200), signed by `dnet-master sign-firmware` with the
//! TEST key (`contrib/keys/test-ed25519.secret`).
//!
//! - `a_signed_image_is_sent_applied_and_confirmed`: the new revision reported, confirmed.
//! - `an_interrupted_update_resumes_where_it_stopped`: SIGINT after some chunks, the run again
//!   resumes at a chunk past 0 and completes.
//! - `a_bad_signature_is_refused_by_the_device_and_locally`: refused at Verify by the device
//!   (0xD0/1) without `--public-key`, before anything is sent with it.
//! - `an_image_for_another_board_is_refused_before_sending`.
//! - `no_update_while_an_io_connection_is_established`: 0x10 device state conflict at Update.
//!
//! Needs socat and the built `dnet-soft-slave`, `dnet-sim-breaker` and `dnet-master`: ignored in
//! the plain host-test run, run by `scripts/check` with `-- --ignored`.

use pty_rig::{bin, require_socat, workspace_dir, Proc, PtyRig};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The board the soft slave accepts (its class 0x6A attribute 7; `--firmware-board-id`'s default:
/// the reference adapter it emulates).
const SOFT_SLAVE_BOARD: (&str, u16) = ("reference", 1);

/// A bench with the soft slave serving the update object from `dir/firmware`, checking with the
/// TEST public key.
fn rig(test: &str) -> PtyRig {
    let mut rig = PtyRig::breaker(test, &[], None);
    let firmware = rig.dir.join("firmware");
    std::fs::create_dir_all(&firmware).unwrap();
    let _ = rig.stop_slave();
    let key = workspace_dir().join("contrib/keys/test-ed25519.public");
    rig.start_slave_with(
        None,
        &["--firmware-dir", firmware.to_str().unwrap(), "--firmware-key", key.to_str().unwrap()],
    );
    rig
}

/// A test image of `len` bytes for `board` at `revision`, signed with the TEST key into
/// `dir/NAME.signed.bin`; returns that path.
fn signed_image(dir: &Path, name: &str, len: usize, board: (&str, u16), revision: (u8, u8)) -> PathBuf {
    let mut image: Vec<u8> = (0..len).map(|i| (i * 31 + 7) as u8).collect();
    let info = [
        b'D',
        b'N',
        b'F',
        b'I',
        1,
        0,
        board.1 as u8,
        (board.1 >> 8) as u8,
        revision.0,
        revision.1,
        0,
        0,
        0,
        0,
        0,
        0,
    ];
    image[0x200..0x210].copy_from_slice(&info);
    let raw = dir.join(format!("{name}.bin"));
    std::fs::write(&raw, &image).unwrap();
    let out = dir.join(format!("{name}.signed.bin"));
    let key = workspace_dir().join("contrib/keys/test-ed25519.secret");
    let mut sign = Proc::spawn(
        bin("dnet-master"),
        &[
            "sign-firmware",
            raw.to_str().unwrap(),
            "--key",
            key.to_str().unwrap(),
            "--board",
            board.0,
            "-o",
            out.to_str().unwrap(),
        ],
    );
    let status = sign.wait(Duration::from_secs(20));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "sign-firmware\n{}", sign.dump());
    out
}

/// `dnet-master --bus BUS --json firmware-update --mac 5 FILE ARGS`, run to its end: exit status,
/// JSON, standard error.
fn update(rig: &PtyRig, file: &Path, args: &[&str]) -> (Option<i32>, Value, String) {
    let bus = rig.master_bus_arg();
    let mut all =
        vec!["--bus", bus.as_str(), "--json", "firmware-update", "--mac", "5", file.to_str().unwrap()];
    all.extend_from_slice(args);
    let mut master = Proc::spawn(bin("dnet-master"), &all);
    let status = master.wait(Duration::from_secs(60));
    let json = serde_json::from_str(master.stdout.text().trim())
        .unwrap_or_else(|e| panic!("firmware-update's JSON: {e}\n{}\n{}", master.dump(), rig.dump()));
    (status.and_then(|s| s.code()), json, master.stderr.text())
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn a_signed_image_is_sent_applied_and_confirmed() {
    if !require_socat() {
        return;
    }
    let rig = rig("fw-update-full");
    let file = signed_image(&rig.dir, "new", 2048, SOFT_SLAVE_BOARD, (7, 3));
    let (code, json, stderr) = update(&rig, &file, &[]);
    assert_eq!(code, Some(0), "{json}\n{stderr}\n{}", rig.dump());
    let r = &json["firmware_update"];
    assert_eq!(r["outcome"], "confirmed", "{json}");
    assert_eq!(r["revision"], "7.3", "{json}");
    assert_ne!(r["revision_before"], "7.3", "{json}");
    assert_eq!(r["chunks"], 16, "{json}");
    assert_eq!(r["resumed_at"], 0, "{json}");
    assert_eq!(r["sent"], 16, "{json}");
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn an_interrupted_update_resumes_where_it_stopped() {
    if !require_socat() {
        return;
    }
    let rig = rig("fw-update-resume");
    // 512 chunks: about 5 s on the ptys (12.7 KiB/s measured), long enough to stop in the middle.
    let file = signed_image(&rig.dir, "new", 64 * 1024, SOFT_SLAVE_BOARD, (7, 4));
    let bus = rig.master_bus_arg();
    let mut first = Proc::spawn(
        bin("dnet-master"),
        &["--bus", &bus, "firmware-update", "--mac", "5", file.to_str().unwrap()],
    );
    // Progress lines come every 2 s off a terminal: the second one is well into the transfer.
    let end = std::time::Instant::now() + Duration::from_secs(20);
    while first.stderr.text().matches("/512 chunks").count() < 2 && std::time::Instant::now() < end {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(first.stderr.text().matches("/512 chunks").count(), 2, "{}\n{}", first.dump(), rig.dump());
    first.signal("INT");
    let status = first.wait(Duration::from_secs(10));
    assert_eq!(status.and_then(|s| s.code()), Some(130), "{}", first.dump());
    let said = first.stdout.text();
    let resume_at: u32 = said
        .split("resume at chunk ")
        .nth(1)
        .and_then(|rest| rest.split(|c: char| !c.is_ascii_digit()).next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no resume point printed\n{}", first.dump()));
    assert!(resume_at > 0 && resume_at < 512, "interrupted at chunk {resume_at}\n{}", first.dump());

    let (code, json, stderr) = update(&rig, &file, &[]);
    assert_eq!(code, Some(0), "{json}\n{stderr}\n{}", rig.dump());
    let r = &json["firmware_update"];
    let resumed = r["resumed_at"].as_u64().unwrap();
    // The device logs a chunk after the master saw its answer at the latest: it resumes at the
    // chunk the first run named, or one past it when its last answer was lost to the stop.
    assert!(
        resumed == u64::from(resume_at) || resumed == u64::from(resume_at) + 1,
        "resumed at {resumed}, the first run stopped before chunk {resume_at}: {json}"
    );
    assert_eq!(r["sent"].as_u64().unwrap(), 512 - resumed, "{json}");
    assert_eq!(r["outcome"], "confirmed", "{json}");
    assert_eq!(r["revision"], "7.4", "{json}");
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn a_bad_signature_is_refused_by_the_device_and_locally() {
    if !require_socat() {
        return;
    }
    let rig = rig("fw-update-bad-signature");
    let file = signed_image(&rig.dir, "new", 1024, SOFT_SLAVE_BOARD, (7, 5));
    let mut bytes = std::fs::read(&file).unwrap();
    bytes[0x300] ^= 0x01;
    std::fs::write(&file, &bytes).unwrap();

    let (code, json, _) = update(&rig, &file, &[]);
    assert_eq!(code, Some(1), "{json}");
    let error = json["error"].as_str().unwrap_or_default();
    assert!(error.contains("Verify: MAC 5 refused: 0xD0/0x01 (bad signature)"), "{json}");

    let public = workspace_dir().join("contrib/keys/test-ed25519.public");
    let (code, json, _) = update(&rig, &file, &["--public-key", public.to_str().unwrap()]);
    assert_eq!(code, Some(2), "{json}");
    let error = json["error"].as_str().unwrap_or_default();
    assert!(error.contains("the signature does not verify with the public key given"), "{json}");
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn an_image_for_another_board_is_refused_before_sending() {
    if !require_socat() {
        return;
    }
    let rig = rig("fw-update-board");
    let other = if SOFT_SLAVE_BOARD.1 == 4 { ("reference", 1) } else { ("nucleo-f446re", 4) };
    let file = signed_image(&rig.dir, "other", 1024, other, (7, 6));
    let (code, json, _) = update(&rig, &file, &[]);
    assert_eq!(code, Some(2), "{json}");
    let error = json["error"].as_str().unwrap_or_default();
    assert!(
        error.contains(&format!(
            "the trailer names board {}; the device is board {}",
            other.1, SOFT_SLAVE_BOARD.1
        )),
        "{json}"
    );
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn no_update_while_an_io_connection_is_established() {
    if !require_socat() {
        return;
    }
    let rig = rig("fw-update-io");
    let bus = rig.master_bus_arg();
    // The poll connection established and kept, its watchdog (4 x EPR) far beyond the test.
    let mut connect = Proc::spawn(
        bin("dnet-master"),
        &["--bus", &bus, "--keep", "connect", "--mac", "5", "--epr", "60000"],
    );
    let status = connect.wait(Duration::from_secs(30));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{}", connect.dump());

    let file = signed_image(&rig.dir, "new", 1024, SOFT_SLAVE_BOARD, (7, 7));
    let (code, json, _) = update(&rig, &file, &[]);
    assert_eq!(code, Some(1), "{json}");
    let error = json["error"].as_str().unwrap_or_default();
    assert!(error.contains("Update: MAC 5 refused: 0x10/"), "{json}");
    assert!(error.contains("device state conflict"), "{json}");
}
