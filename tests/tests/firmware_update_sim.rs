//! `dnet-master firmware-update` and `sign-firmware` in process, on the simulated bus: what is
//! refused before the bus is touched (a file that is not a signed image, a public key of the wrong
//! length), and a device without the update object (the simulated reference converter answers
//! class 0x6A with 0x16). The whole update runs on the real SLCAN path in `firmware_update.rs`.

use std::path::PathBuf;

/// `dnet-master ARGS` in process: exit status, standard output, standard error.
fn dnet(args: &[&str]) -> (u8, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let mut all = vec!["dnet-master"];
    all.extend_from_slice(args);
    let code = master_harness::cli::run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("fw-update-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A test image for the emulated board (5), revision 7.3, signed with the TEST key.
fn signed() -> PathBuf {
    let mut image: Vec<u8> = (0..1024).map(|i| (i * 31 + 7) as u8).collect();
    image[0x200..0x210].copy_from_slice(b"DNFI\x01\x00\x05\x00\x07\x03\0\0\0\0\0\0");
    let raw = scratch("image.bin");
    std::fs::write(&raw, &image).unwrap();
    let out = scratch("image.signed.bin");
    let key = concat!(env!("CARGO_MANIFEST_DIR"), "/../contrib/keys/test-ed25519.secret");
    let args = ["sign-firmware", raw.to_str().unwrap(), "--key", key, "--board", "emulated", "-o"];
    let (code, stdout, stderr) = dnet(&[&args[..], &[out.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{stdout}{stderr}");
    assert!(stdout.contains("1024 bytes for board emulated (ID 5), revision 7.3, signed"), "{stdout}");
    assert_eq!(std::fs::metadata(&out).unwrap().len(), 1024 + 128);
    out
}

#[test]
fn a_device_without_the_update_object_is_named() {
    let file = signed();
    let (code, stdout, stderr) =
        dnet(&["--bus", "sim", "firmware-update", "--mac", "5", file.to_str().unwrap()]);
    assert_eq!(code, 1, "{stdout}{stderr}");
    assert!(
        stderr.contains("MAC 5: this firmware cannot be updated over the network (class 0x6A answers object does not exist"),
        "{stderr}"
    );
}

#[test]
fn a_file_that_is_not_a_signed_image_is_refused_before_the_bus() {
    let raw = scratch("plain.bin");
    std::fs::write(&raw, vec![0u8; 4096]).unwrap();
    let (code, stdout, stderr) =
        dnet(&["--bus", "sim", "--json", "firmware-update", "--mac", "5", raw.to_str().unwrap()]);
    assert_eq!(code, 2, "{stdout}{stderr}");
    assert!(
        stderr.contains("plain.bin: the trailer (the last 128 bytes): not a signed firmware file"),
        "{stderr}"
    );
    // Refused before the bus: no frame at all.
    let json: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(json["ok"], false, "{json}");
    assert!(json.get("frames").is_none(), "{json}");
}

#[test]
fn a_public_key_of_the_wrong_length_is_refused() {
    let file = signed();
    let key = scratch("short.public");
    std::fs::write(&key, [0u8; 31]).unwrap();
    let args = ["--bus", "sim", "firmware-update", "--mac", "5", file.to_str().unwrap(), "--public-key"];
    let (code, stdout, stderr) = dnet(&[&args[..], &[key.to_str().unwrap()]].concat());
    assert_eq!(code, 2, "{stdout}{stderr}");
    assert!(stderr.contains("--public-key"), "{stderr}");
    assert!(stderr.contains("32 raw bytes of an Ed25519 public key"), "{stderr}");
}
