//! Link arguments for the bare-metal target only, so host builds (`cargo test`, clippy) stay
//! clean: cortex-m-rt's `link.x` (which includes the board crate's `memory.x`), identical code
//! folding and, with the `defmt` feature, `defmt.x`.

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=DNET_MAC");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() == Ok("none") {
        println!("cargo:rustc-link-arg-bins=--nmagic");
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        // Identical code folding: the panic entries, the copy_from_slice instances and the
        // handlers that only loop share one body each (firmware size budget; nothing compares
        // function addresses).
        println!("cargo:rustc-link-arg-bins=--icf=all");
        if std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
            println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
        }
    }
}
