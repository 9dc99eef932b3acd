//! Finding the board firmware ELF for the tests that run it.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Where `cargo build -p slave-fw-firmware --profile firmware --target thumbv7em-none-eabihf`
/// puts it, and scripts/firmware-size's copy of the reference board's build.
const CANDIDATES: [&str; 2] = ["slave-fw-firmware", "slave-fw-firmware-reference"];

/// The ELF named by `STM32_EMU_FIRMWARE`, or the newest board (not emulated) build of the
/// reference board: the plain name holds whichever build ran last, and scripts/firmware-size
/// leaves the emulated one (QEMU, semihosting) there.
pub fn board_elf() -> Result<(PathBuf, Vec<u8>), String> {
    if let Ok(path) = std::env::var("STM32_EMU_FIRMWARE") {
        let elf = std::fs::read(&path).map_err(|e| format!("{path}: {e}"))?;
        return Ok((path.into(), elf));
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/thumbv7em-none-eabihf/firmware");
    let mut found: Option<(SystemTime, PathBuf, Vec<u8>)> = None;
    for name in CANDIDATES {
        let path = dir.join(name);
        let (Ok(elf), Ok(meta)) = (std::fs::read(&path), std::fs::metadata(&path)) else {
            continue;
        };
        let emulated = stm32_emu::cpu::elf::symbol_address(&elf, "HostFileFlash").is_some();
        let modified = meta.modified().unwrap_or(SystemTime::UNIX_EPOCH);
        if !emulated && found.as_ref().is_none_or(|(t, _, _)| modified > *t) {
            found = Some((modified, path, elf));
        }
    }
    found.map(|(_, path, elf)| (path, elf)).ok_or_else(|| {
        format!(
            "no board firmware ELF in {}: build it with `cargo build -p slave-fw-firmware --profile firmware \
             --target thumbv7em-none-eabihf` or name one in STM32_EMU_FIRMWARE",
            dir.display()
        )
    })
}

/// The files to load for the board firmware `elf` (issue 31): `elf` alone when it is linked at
/// 0x0800_0000 (no bootloader), else the reference board's bootloader first, which starts it:
/// the one named by `STM32_EMU_BOOTLOADER`, or scripts/build-bootloader's `bootloader-reference`.
pub fn with_bootloader(elf: Vec<u8>) -> Result<Vec<Vec<u8>>, String> {
    let segments = stm32_emu::cpu::elf::load_segments(&elf).map_err(|e| format!("firmware ELF: {e}"))?;
    if segments.iter().any(|&(address, _)| address == 0x0800_0000) {
        return Ok(vec![elf]);
    }
    let path = match std::env::var("STM32_EMU_BOOTLOADER") {
        Ok(path) => PathBuf::from(path),
        Err(_) => Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../target/thumbv7em-none-eabihf/firmware/bootloader-reference"),
    };
    let bootloader = std::fs::read(&path).map_err(|e| {
        format!(
            "{}: {e} (the firmware is linked past 0x0800_0000 and needs the bootloader: \
             scripts/build-bootloader --test-key reference, or name one in STM32_EMU_BOOTLOADER)",
            path.display()
        )
    })?;
    Ok(vec![bootloader, elf])
}
