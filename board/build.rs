//! Puts the selected build's `memory.x` (board/memory/<chip>.x, chosen by the board feature, or
//! stm32f405rg-emulated.x with the `emulated` feature: no bootloader, linked from 0x0800_0000) where
//! cortex-m-rt's `link.x` finds it: the link search path of whatever binary depends on this crate;
//! none with the `bootloader-link` feature (the bootloader brings its own).

use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=memory");
    println!("cargo:rerun-if-changed=build.rs");
    // The bootloader links with its own memory.x (bootloader/memory.x): none from here, so that
    // only one is on the link search path.
    if env::var_os("CARGO_FEATURE_BOOTLOADER_LINK").is_some() {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    // The STM32F446RE board's file when its feature is on, else the STM32F405RG's (the reference
    // board and the Olimex STM32-P405); src/boards refuses any other combination.
    let file = if env::var_os("CARGO_FEATURE_EMULATED").is_some() {
        "stm32f405rg-emulated"
    } else if env::var_os("CARGO_FEATURE_NUCLEO_F446RE").is_some() {
        "stm32f446re"
    } else {
        "stm32f405rg"
    };
    let source = format!("memory/{file}.x");
    fs::copy(&source, out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
}
