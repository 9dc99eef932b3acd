//! Link arguments for the bare-metal target only, so host builds (`cargo test`, clippy) stay
//! clean: cortex-m-rt's `link.x` (which includes the board crate's `memory.x`) and, with the
//! `defmt` feature, `defmt.x`.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=DNET_MAC");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        if std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
            println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
        }
    }
}
