//! Link arguments for the bare-metal target only, so host builds (`cargo test`, clippy) stay
//! clean: cortex-m-rt's `link.x` (which includes the board crate's `memory.x`), identical code
//! folding and, with the `defmt` feature, `defmt.x`. And the firmware revision of the image-info
//! block (src/image_info.rs): `DNET_FW_REVISION=MAJOR.MINOR` when set, else the crate's version.

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=DNET_MAC");
    println!("cargo:rerun-if-env-changed=DNET_FW_REVISION");
    write_revision();
    if env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        // Identical code folding: the panic entries, the copy_from_slice instances and the
        // handlers that only loop share one body each (firmware size budget; nothing compares
        // function addresses).
        println!("cargo:rustc-link-arg-bins=--icf=all");
        if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
            println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
        }
    }
}

/// `OUT_DIR/revision.rs`: the image-info block's revision, each part a USINT (the build fails,
/// naming the variable, on anything else).
fn write_revision() {
    let (source, major, minor) = match env::var("DNET_FW_REVISION") {
        Ok(value) => {
            let (major, minor) = value
                .split_once('.')
                .unwrap_or_else(|| panic!("DNET_FW_REVISION={value:?}: expected MAJOR.MINOR, e.g. 1.2"));
            ("DNET_FW_REVISION", major.to_owned(), minor.to_owned())
        }
        Err(_) => (
            "the crate's version",
            env::var("CARGO_PKG_VERSION_MAJOR").expect("cargo sets it"),
            env::var("CARGO_PKG_VERSION_MINOR").expect("cargo sets it"),
        ),
    };
    let part = |name: &str, text: &str| -> u8 {
        text.parse().unwrap_or_else(|_| panic!("{source}: the {name} revision {text:?} is not 0..=255"))
    };
    let (major, minor) = (part("major", &major), part("minor", &minor));
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let code = format!(
        "/// The firmware revision in the image-info block ({source}).\n\
         pub const REVISION: Revision = Revision {{ major: {major}, minor: {minor} }};\n"
    );
    fs::write(out.join("revision.rs"), code).expect("write revision.rs");
}
