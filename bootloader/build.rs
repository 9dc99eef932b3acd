//! The bootloader's link set-up and its public key, for the bare-metal target only (host builds,
//! `cargo test` and clippy, need neither):
//!
//! - `memory.x` (this crate's: sector 0 less the 64-byte key block, and the key block's own
//!   region) where cortex-m-rt's `link.x` finds it; the board crate ships none with its
//!   `bootloader-link` feature, so only this one is on the link search path.
//! - `OUT_DIR/key.rs`: the Ed25519 public key images must be signed with, from the file named by
//!   `DNET_FW_PUBLIC_KEY` (32 raw bytes), or with the `test-key` feature the repository's TEST
//!   key (contrib/keys/test-ed25519.public); the build fails, naming the variable, without one.

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-env-changed=DNET_FW_PUBLIC_KEY");
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    // Identical code folding, as the firmware (nothing compares function addresses).
    println!("cargo:rustc-link-arg-bins=--icf=all");
    write_key(&out);
}

fn write_key(out: &std::path::Path) {
    let (path, source) = if env::var_os("CARGO_FEATURE_TEST_KEY").is_some() {
        let path = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"))
            .join("../contrib/keys/test-ed25519.public");
        (path, "the TEST key (feature test-key)")
    } else {
        match env::var_os("DNET_FW_PUBLIC_KEY") {
            Some(path) => (PathBuf::from(path), "DNET_FW_PUBLIC_KEY"),
            None => panic!(
                "DNET_FW_PUBLIC_KEY is not set: give the path of the 32-byte raw Ed25519 public key \
                 images are signed with (or build with the feature test-key for tests only)"
            ),
        }
    };
    println!("cargo:rerun-if-changed={}", path.display());
    let key = fs::read(&path).unwrap_or_else(|e| panic!("{source}: {}: {e}", path.display()));
    let key: [u8; 32] = key.as_slice().try_into().unwrap_or_else(|_| {
        panic!("{source}: {}: {} bytes, a raw Ed25519 public key is 32", path.display(), key.len())
    });
    let major = env::var("CARGO_PKG_VERSION_MAJOR").expect("cargo sets it");
    let minor = env::var("CARGO_PKG_VERSION_MINOR").expect("cargo sets it");
    let code = format!(
        "/// The Ed25519 public key images must be signed with ({source}: {path}).\n\
         pub const PUBLIC_KEY: [u8; 32] = {key:?};\n\
         /// The bootloader's revision (the crate's version, major and minor).\n\
         pub const REVISION: (u8, u8) = ({major}, {minor});\n",
        path = path.display().to_string().escape_default(),
    );
    fs::write(out.join("key.rs"), code).expect("write key.rs");
}
