//! The scenarios on the reference board's exact firmware ELF, and proof that they fail when the
//! world is wrong.
//!
//! Ignored by default: they need the thumb build. Build it and run them with
//! `cargo build -p slave-fw-firmware --profile firmware --target thumbv7em-none-eabihf &&
//! cargo test -p exact-firmware --test scenarios -- --ignored` (or name an ELF in
//! `EXACT_FIRMWARE_ELF`; scripts/firmware-size's `slave-fw-firmware-reference` is taken when newer).

use can_io::bus::Bitrate;
use devicenet::MacId;
use exact_firmware::board::BoardKind;
use exact_firmware::device::Firmware;
use exact_firmware::scenario::{self, Options, Scenario};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// The reference board's ELF: `EXACT_FIRMWARE_ELF`, else the newest board (not the QEMU
/// `emulated`, semihosting) build of the reference board in the firmware target directory.
fn reference_elf() -> Firmware {
    if let Ok(path) = std::env::var("EXACT_FIRMWARE_ELF") {
        return Firmware::from_files("reference", Path::new(&path), None).unwrap_or_else(|e| panic!("{e}"));
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/thumbv7em-none-eabihf/firmware");
    let mut found: Option<(SystemTime, PathBuf)> = None;
    for name in ["slave-fw-firmware", "slave-fw-firmware-reference"] {
        let path = dir.join(name);
        let (Ok(elf), Ok(meta)) = (std::fs::read(&path), std::fs::metadata(&path)) else { continue };
        let emulated = stm32_emu::cpu::elf::symbol_address(&elf, "HostFileFlash").is_some();
        let modified = meta.modified().unwrap_or(SystemTime::UNIX_EPOCH);
        if !emulated && found.as_ref().is_none_or(|(t, _)| modified > *t) {
            found = Some((modified, path));
        }
    }
    let (_, path) = found.unwrap_or_else(|| panic!("no reference board ELF in {}", dir.display()));
    // A firmware linked at ACTIVE takes scripts/build-bootloader's bootloader-reference beside it.
    Firmware::from_files("reference", &path, None).unwrap_or_else(|e| panic!("{e}"))
}

fn reference() -> BoardKind {
    BoardKind::by_name("reference").expect("the board crate describes the reference board")
}

fn scenario(name: &str) -> Scenario {
    *scenario::ALL.iter().find(|s| s.name == name).expect("a scenario of that name")
}

#[test]
#[ignore = "needs the thumb build of slave-fw-firmware"]
fn every_scenario_passes_on_the_reference_board() {
    let elf = reference_elf();
    for s in
        scenario::ALL.iter().filter(|s| (s.applies)(reference()) && !scenario::ON_REQUEST.contains(&s.name))
    {
        let outcome = scenario::run(s, reference(), &elf, &Options::default());
        assert!(outcome.result.is_ok(), "{}", outcome.line());
        assert_eq!(outcome.line(), format!("ok   reference {}", s.name));
    }
}

#[test]
#[ignore = "needs the thumb build of slave-fw-firmware"]
fn bring_up_fails_on_a_bus_at_another_rate_than_the_board() {
    let elf = reference_elf();
    let options = Options { bus_rate: Bitrate::K250, ..Options::default() };
    let outcome = scenario::run(&scenario("bring-up"), reference(), &elf, &options);
    eprintln!("{}", outcome.line());
    assert!(outcome.result.is_err(), "{}", outcome.line());
    assert!(outcome.line().starts_with("FAIL reference bring-up: "), "{}", outcome.line());
}

#[test]
#[ignore = "needs the thumb build of slave-fw-firmware"]
fn bring_up_fails_when_the_node_is_at_another_mac() {
    let elf = reference_elf();
    let mut options = Options::default();
    options.setting.mac = MacId::new(6).expect("MAC 6");
    let outcome = scenario::run(&scenario("bring-up"), reference(), &elf, &options);
    eprintln!("{}", outcome.line());
    assert!(outcome.result.is_err(), "{}", outcome.line());
}

#[test]
#[ignore = "needs scripts/exact-firmware's builds (slave-fw-firmware-reference and its -newer beside it)"]
fn rollback_fails_when_the_image_confirms() {
    let mut elf = reference_elf();
    let newer =
        elf.newer.clone().expect("slave-fw-firmware-reference-newer beside the ELF (scripts/exact-firmware)");
    // A build that confirms in place of the fault-never-confirm one: nothing to roll back.
    elf.never_confirm = Some(newer);
    let outcome =
        scenario::run(&scenario("firmware-update-rollback"), reference(), &elf, &Options::default());
    eprintln!("{}", outcome.line());
    assert!(outcome.result.is_err(), "{}", outcome.line());
}

#[test]
#[ignore = "needs scripts/exact-firmware's builds (slave-fw-firmware-reference and its -newer beside it)"]
fn firmware_update_fails_without_a_build_at_another_revision() {
    let mut elf = reference_elf();
    elf.newer = Some(elf.elf.clone());
    let outcome = scenario::run(&scenario("firmware-update"), reference(), &elf, &Options::default());
    assert!(outcome.result.is_err(), "{}", outcome.line());
}

#[test]
#[ignore = "needs scripts/exact-firmware's builds (slave-fw-firmware-reference and its -newer beside it)"]
fn the_transfer_half_of_the_power_cut_resumes_on_the_reference_board() {
    let elf = reference_elf();
    let result = exact_firmware::scenario::transfer_cut::transfer_cut(reference(), &elf, &Options::default());
    assert!(result.is_ok(), "{result:?}");
}
