//! # bootloader
//!
//! The bootloader of the converter boards (issue 31; the guide's "Firmware update over DeviceNet"
//! design page): it sits in flash sector 0 at the reset vector and, at every reset,
//!
//! 1. checks a pending update before anything is swapped ([`check::guard_swap`]: when STATE asks
//!    for a swap that has not started, the image in DFU must carry a valid trailer, this board's
//!    ID in its image-info block and an Ed25519 signature by this bootloader's key; otherwise the
//!    request is cancelled and the old image boots);
//! 2. runs embassy-boot's `BootLoader::prepare_boot` (blocking API): the power-fail-safe swap of
//!    ACTIVE and DFU page by page, or the revert of a trial image that never confirmed;
//! 3. starts the independent watchdog, with its longest timeout before a trial image (about 33 s,
//!    IWDG /256, reload 0xFFF on the 32 kHz LSI: RM0090 §21.3, table 107) and a shorter one
//!    (about 8 s, /64) otherwise: the firmware feeds it, and a trial image only once it has
//!    confirmed (`mark_booted`);
//! 4. sets VTOR to ACTIVE (sector 5, 0x0802_0000), loads MSP from ACTIVE's vector table and jumps
//!    to its reset vector.
//!
//! It sets up no clock (16 MHz HSI) and no peripheral but the watchdog. The flash partitions and
//! their driver are the board crate's (`board::flash_layout`, `board::hw::nor_flash`).
//!
//! ## Features and build-time variables
//!
//! | | effect |
//! |---|---|
//! | `reference` (default), `olimex-p405`, `olimex-p405-rs485`, `nucleo-f446re` | the board (exactly one): its board ID goes into the key block and is what images must carry |
//! | `DNET_FW_PUBLIC_KEY=/path/key.public` | the 32-byte raw Ed25519 public key images must be signed with (required) |
//! | `test-key` | **TEST ONLY**: the repository's test key (`contrib/keys/test-ed25519.public`) instead |
//!
//! The key block, the last 64 bytes of sector 0 (`board::flash_layout::KeyBlock`: the public
//! key, the board ID, this bootloader's revision, a CRC-32), is placed by the `.key_block` linker
//! section of `memory.x`; the firmware reads the key and board from it.
//!
//! `scripts/build-bootloader BOARD...` builds it per board; `scripts/firmware-size` measures it
//! against sector 0 less the key block (16,320 bytes).
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

// On the host only the tests use it (the binary is empty there).
#[cfg_attr(not(target_os = "none"), allow(dead_code))]
mod check;

#[cfg(target_os = "none")]
mod target {
    use board::boards::BOARD_ID;
    use board::flash_layout::{KeyBlock, ACTIVE, KEY_BLOCK_LEN};
    use board::hw::nor_flash::UpdateFlash;
    use cortex_m_rt::entry;
    use embassy_boot::{BootLoader, BootLoaderConfig, State};
    use panic_halt as _;
    use stm32f4xx_hal::pac;

    use crate::check::{guard_swap, Guard};

    include!(concat!(env!("OUT_DIR"), "/key.rs"));

    /// The key block, at the end of sector 0 (memory.x's `KEY_BLOCK` region).
    #[used]
    #[allow(unsafe_code)] // #[link_section] (an unsafe attribute): memory.x places the section
    #[link_section = ".key_block"]
    static KEY_BLOCK: [u8; KEY_BLOCK_LEN] =
        KeyBlock { public_key: PUBLIC_KEY, board_id: BOARD_ID, revision: REVISION }.to_bytes();

    /// The copy buffer of the swap: a divisor of the 128 KiB page, word aligned.
    #[repr(C, align(4))]
    struct Aligned([u8; 2048]);

    #[entry]
    fn main() -> ! {
        // `entry` runs once, so the peripherals are there.
        let Some(dp) = pac::Peripherals::take() else { panic!("peripherals taken twice") };
        let UpdateFlash { mut state, active, mut dfu } = UpdateFlash::new(dp.FLASH);
        let guard = guard_swap(&mut state, &mut dfu, &PUBLIC_KEY, BOARD_ID);
        let trial = match guard {
            // STATE says SWAP and cannot be rewritten: swapping would start an unverified image.
            Guard::CancelFailed(_) => false,
            Guard::NothingToCheck | Guard::Verified | Guard::Cancelled(_) => {
                let mut bootloader = BootLoader::new(BootLoaderConfig { active, dfu, state });
                let mut buffer = Aligned([0; 2048]);
                // A flash error mid-swap: the image in ACTIVE may be partly copied; the watchdog
                // resets it and the next start resumes the swap from its progress words.
                let prepared = bootloader.prepare_boot(&mut buffer.0);
                // prepare_boot answers the state it found (SWAP after a revert too): STATE as it
                // left it tells a trial image (still SWAP) from a reverted one (REVERT).
                prepared.is_err() || matches!(bootloader.read_state(&mut buffer.0), Ok(State::Swap) | Err(_))
            }
        };
        start_watchdog(&dp.IWDG, trial);
        let vector_table = ACTIVE.base;
        let mut cp = cortex_m::Peripherals::take();
        #[allow(unsafe_code)]
        // SAFETY: the one unsafe block of the bootloader. ACTIVE holds the firmware, linked at
        // ACTIVE.base, whose vector table starts there (stack pointer, then reset vector); VTOR
        // points the core at it, then `bootload` loads MSP and jumps to the reset handler.
        unsafe {
            if let Some(cp) = cp.as_mut() {
                cp.SCB.vtor.write(vector_table);
            }
            cortex_m::asm::bootload(vector_table as *const u32)
        }
    }

    /// Starts the IWDG (RM0090 §21.3: 0x5555 unlocks PR and RLR, 0xCCCC starts, 0xAAAA reloads):
    /// /256 and reload 0xFFF (about 32.8 s at 32 kHz) before a trial image, /64 (about 8.2 s)
    /// otherwise. The LSI starts with the watchdog (RCC LSION is forced by hardware).
    fn start_watchdog(iwdg: &pac::IWDG, trial: bool) {
        iwdg.kr().write(|w| w.key().start());
        iwdg.kr().write(|w| w.key().unlock());
        if trial {
            iwdg.pr().write(|w| w.pr().divide_by256());
        } else {
            iwdg.pr().write(|w| w.pr().divide_by64());
        }
        iwdg.rlr().write(|w| w.rl().set(0xFFF));
        // PVU and RVU clear once the LSI domain has taken the values.
        while iwdg.sr().read().bits() & 0b11 != 0 {}
        iwdg.kr().write(|w| w.key().feed());
    }
}

/// On the host the bootloader is its tests ([`check`]).
#[cfg(not(target_os = "none"))]
fn main() {}
