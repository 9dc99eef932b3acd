//! The bootloader's own ELF on the stm32-emu machine (an STM32F405 with the FLASH and IWDG
//! models): a plain boot, a swap of a well-signed image, the refusal of a badly signed one, and
//! the revert of a trial image that never confirmed (from flash as a finished swap leaves it, so
//! that no test copies the 128 KiB pages twice: each copy takes about 16 s of wall time). The applications are a few bytes each: a
//! vector table, an image-info block and an endless loop, told apart by the loop's address.
//!
//! Ignored by default: it needs the thumb build with the TEST key. Run it with
//!
//! ```text
//! scripts/build-bootloader --test-key reference
//! cargo test -p bootloader --test emulated -- --ignored
//! ```
//!
//! It runs `target/thumbv7em-none-eabihf/firmware/bootloader-reference`, or
//! `DNET_BOOTLOADER_ELF=path`.

use std::path::Path;

use board::flash_layout::{ACTIVE, DFU, FLASH_BASE, KEY_BLOCK_ADDRESS, MAX_IMAGE_LEN, STATE};
use fw_image::{ImageInfo, Revision, INFO_OFFSET, TRAILER_LEN};
use stm32_emu::flash::{Flash, FlashTiming};
use stm32_emu::iwdg::{self, Iwdg};
use stm32_emu::machine::{Chip, Stm32};
use unicorn_engine::RegisterARM;

const TEST_SEED: &[u8; 32] = include_bytes!("../../contrib/keys/test-ed25519.secret");
const TEST_PUBLIC: &[u8; 32] = include_bytes!("../../contrib/keys/test-ed25519.public");
/// The reference board's ID (board::boards::reference).
const BOARD_ID: u16 = 1;
const SWAP_MAGIC: u8 = 0xF0;
const BOOT_MAGIC: u8 = 0xD0;
const REVERT_MAGIC: u8 = 0xC0;
/// The applications' stack pointer.
const APP_STACK: u32 = 0x2000_8000;
/// Where the old and the new application loop (`b .`).
const OLD_LOOP: u32 = ACTIVE.base + 0x300;
const NEW_LOOP: u32 = ACTIVE.base + 0x380;
/// Emulated time allowed to reach an application (the check, a swap with fast flash timing).
const LIMIT_NS: u64 = 20_000_000_000;
/// IWDG_PR's value before a trial image (/256) and otherwise (/64), and IWDG_RLR's.
const PR_TRIAL: u32 = 6;
const PR_NORMAL: u32 = 4;

fn bootloader_elf() -> Vec<u8> {
    let path = std::env::var("DNET_BOOTLOADER_ELF").unwrap_or_else(|_| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../target/thumbv7em-none-eabihf/firmware/bootloader-reference")
            .display()
            .to_string()
    });
    std::fs::read(&path).unwrap_or_else(|e| {
        panic!("{path}: {e}: build it with `scripts/build-bootloader --test-key reference`")
    })
}

/// An application image for ACTIVE: the vector table (stack, reset vector to its loop), the
/// image-info block, and `b .` at `loop_at`.
fn application(loop_at: u32, revision: u8) -> Vec<u8> {
    let offset = (loop_at - ACTIVE.base) as usize;
    let mut image = vec![0u8; offset + 2];
    image[..4].copy_from_slice(&APP_STACK.to_le_bytes());
    image[4..8].copy_from_slice(&(loop_at | 1).to_le_bytes());
    let info = ImageInfo { board_id: BOARD_ID, revision: Revision { major: 1, minor: revision } };
    image[INFO_OFFSET..INFO_OFFSET + 16].copy_from_slice(&info.to_bytes());
    image[offset..].copy_from_slice(&0xE7FEu16.to_le_bytes()); // b .
    image
}

/// The machine with the bootloader, `old` in ACTIVE, and (if given) `new` and its trailer in DFU
/// with the SWAP magic in STATE, as the firmware's Apply leaves them (`swapped`: and both swap
/// steps marked done, as the bootloader leaves a finished swap); powered on.
fn machine(old: &[u8], new: Option<(&[u8], [u8; TRAILER_LEN])>, swapped: bool) -> Stm32 {
    let mut mcu = Stm32::new(Chip::Stm32F405, *b"bootloader-t").expect("machine");
    mcu.add_flash(Flash::new().with_timing(FlashTiming::FAST)).expect("flash model");
    mcu.add_peripheral(iwdg::BASE, 0x400, Box::new(Iwdg::new())).expect("IWDG model");
    let elf = bootloader_elf();
    mcu.load_elf(&elf).expect("the bootloader loads");
    assert_eq!(
        flash_at(&mcu, KEY_BLOCK_ADDRESS, 32),
        TEST_PUBLIC.to_vec(),
        "the bootloader was not built with --test-key"
    );
    mcu.program_flash(ACTIVE.base - FLASH_BASE, old).expect("ACTIVE");
    if let Some((image, trailer)) = new {
        let dfu = DFU.base - FLASH_BASE;
        mcu.program_flash(dfu, image).expect("DFU");
        mcu.program_flash(dfu + MAX_IMAGE_LEN, &trailer).expect("trailer");
        mcu.program_flash(STATE.base - FLASH_BASE, &[SWAP_MAGIC; 4]).expect("STATE");
        if swapped {
            // embassy-boot's STATE: magic, progress validity, then one word per step (0 = done).
            mcu.program_flash(STATE.base + 8 - FLASH_BASE, &[0; 8]).expect("STATE progress");
        }
    }
    mcu.power_on_reset().expect("power on");
    mcu
}

/// Runs until the core loops at `at` (an application started), or fails naming where it is.
fn runs_to(mcu: &mut Stm32, at: u32) {
    let reached = mcu.run_until(LIMIT_NS, |m| m.pc() == at).expect("runs without a fault");
    assert!(
        reached,
        "pc {:#010x} after {} s: expected the loop at {at:#010x}",
        mcu.pc(),
        LIMIT_NS / 1_000_000_000
    );
    assert_eq!(mcu.scs().vtor(), ACTIVE.base, "VTOR points at ACTIVE");
    assert_eq!(mcu.register(RegisterARM::SP), APP_STACK, "MSP from ACTIVE's vector table");
}

fn watchdog_prescaler(mcu: &mut Stm32) -> (u32, u32) {
    let pr = mcu.read_peripheral(iwdg::BASE + 0x04).expect("IWDG_PR");
    let rlr = mcu.read_peripheral(iwdg::BASE + 0x08).expect("IWDG_RLR");
    (pr, rlr)
}

fn flash_at(mcu: &Stm32, address: u32, len: usize) -> Vec<u8> {
    let at = (address - FLASH_BASE) as usize;
    mcu.flash()[at..at + len].to_vec()
}

#[test]
#[ignore = "needs scripts/build-bootloader --test-key reference"]
fn no_update_jumps_to_active_with_the_short_watchdog() {
    let old = application(OLD_LOOP, 0);
    let mut mcu = machine(&old, None, false);
    runs_to(&mut mcu, OLD_LOOP);
    assert_eq!(watchdog_prescaler(&mut mcu), (PR_NORMAL, 0xFFF));
    assert_eq!(mcu.flash_operations(), Some(0), "a plain boot writes no flash");
}

#[test]
#[ignore = "needs scripts/build-bootloader --test-key reference"]
fn a_well_signed_image_is_swapped_byte_exact() {
    let old = application(OLD_LOOP, 0);
    let new = application(NEW_LOOP, 1);
    let trailer = fw_image::sign(&new, TEST_SEED).expect("sign").to_bytes();
    let mut mcu = machine(&old, Some((&new, trailer)), false);
    runs_to(&mut mcu, NEW_LOOP);
    assert_eq!(watchdog_prescaler(&mut mcu), (PR_TRIAL, 0xFFF), "the trial image's long watchdog");
    assert_eq!(flash_at(&mcu, ACTIVE.base, new.len()), new, "ACTIVE holds the new image");
    assert_eq!(flash_at(&mcu, ACTIVE.base + MAX_IMAGE_LEN, TRAILER_LEN), trailer.to_vec(), "and its trailer");
    assert_eq!(flash_at(&mcu, DFU.base + ACTIVE.size, old.len()), old, "the old image kept for a revert");
    assert_eq!(flash_at(&mcu, STATE.base, 4), [SWAP_MAGIC; 4], "still on trial");
    assert_eq!(flash_at(&mcu, STATE.base + 8, 8), [0; 8], "both swap steps marked done");
    // The check is the deepest path (salty's SHA-512 and Ed25519).
    let stack = stack_used(&mcu);
    eprintln!("bootloader stack: {stack} bytes at the deepest");
    assert!((1024..8 * 1024).contains(&stack), "{stack} bytes of stack");
}

/// The bootloader's deepest stack use: SRAM is zero after the power-on reset and the stack
/// (flip-link: below `.bss`, whose 4 bytes end SRAM less the reset-surviving cell) grows down,
/// so the lowest non-zero word is (at least) as deep as it went. The applications use no stack.
fn stack_used(mcu: &Stm32) -> u32 {
    const SRAM: u32 = 0x2000_0000;
    const STACK_TOP: u32 = 0x2001_FFF0;
    let mut ram = vec![0u8; (STACK_TOP - SRAM) as usize];
    assert!(mcu.read_memory(SRAM, &mut ram), "SRAM readable");
    let lowest = ram.chunks(4).position(|w| w != [0; 4]).expect("the stack was used");
    STACK_TOP - SRAM - 4 * lowest as u32
}

#[test]
#[ignore = "needs scripts/build-bootloader --test-key reference"]
fn a_trial_image_never_confirmed_is_reverted_byte_exact() {
    // As the swap above leaves flash: the new image in ACTIVE, the old one in DFU's second page,
    // SWAP with both swap steps done; the new image never called mark_booted.
    let old = application(OLD_LOOP, 0);
    let new = application(NEW_LOOP, 1);
    let trailer = fw_image::sign(&new, TEST_SEED).expect("sign").to_bytes();
    let mut mcu = machine(&new, Some((&new, trailer)), true);
    mcu.program_flash(DFU.base + ACTIVE.size - FLASH_BASE, &old).expect("DFU page 1");
    mcu.power_on_reset().expect("power on");
    runs_to(&mut mcu, OLD_LOOP);
    assert_eq!(flash_at(&mcu, ACTIVE.base, old.len()), old, "the old image back, byte-exact");
    assert_eq!(flash_at(&mcu, STATE.base, 4), [REVERT_MAGIC; 4]);
    assert_eq!(watchdog_prescaler(&mut mcu), (PR_NORMAL, 0xFFF));
}

#[test]
#[ignore = "needs scripts/build-bootloader --test-key reference"]
fn a_bad_signature_is_not_swapped_and_state_cancelled() {
    let old = application(OLD_LOOP, 0);
    let mut new = application(NEW_LOOP, 1);
    let trailer = fw_image::sign(&new, TEST_SEED).expect("sign").to_bytes();
    new[0x100] ^= 0x01; // one bit of the signed bytes
    let mut mcu = machine(&old, Some((&new, trailer)), false);
    runs_to(&mut mcu, OLD_LOOP);
    assert_eq!(flash_at(&mcu, ACTIVE.base, old.len()), old, "ACTIVE untouched");
    assert_eq!(flash_at(&mcu, STATE.base, 4), [BOOT_MAGIC; 4], "the request cancelled (mark_booted)");
    assert!(flash_at(&mcu, STATE.base + 4, 64).iter().all(|&b| b == 0xFF), "no swap progress");
    assert_eq!(flash_at(&mcu, DFU.base, new.len()), new, "DFU not swapped");
    assert_eq!(watchdog_prescaler(&mut mcu), (PR_NORMAL, 0xFFF));
}
