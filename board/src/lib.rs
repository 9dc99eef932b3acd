//! # board
//!
//! The hardware facts of the boards the serial-to-DeviceNet converter runs on, in one place
//! (style.md practice 8): the firmware never names a pin, a clock or a register value. The board
//! is chosen at build time by a Cargo feature ([`boards`]).
//!
//! | module | what it holds | host-tested |
//! |---|---|---|
//! | [`boards`] | each board's description ([`boards::BoardSpec`]: chip, clocks, pins, LEDs, switches, flash layout, with its sources) and the selected one | yes, every board |
//! | [`clocks`] | the selected board's clock tree (e.g. 8 MHz HSE → 168 MHz SYSCLK, APB1 42 MHz); the emulated board's HSI | – |
//! | [`pins`] | pins as values | yes |
//! | [`autobaud`] | the data rate found by listening in silent mode (boards without switches, no stored rate): the sans-IO state machine and its rule | yes |
//! | [`bit_timing`] | `const fn` bxCAN bit timing (`CAN_BTR`) for 125k/250k/500k at the board's PCLK1 | yes, every board's PCLK1 |
//! | [`filters`] | the acceptance list: this node's Group 2 identifiers only | yes |
//! | [`switches`] | DIP switch decoding and the MAC/baud/"changed" decision at reset (boards without switches: the stored values) | yes |
//! | [`leds`] | MS/NS bicolour LED pin levels, or what a board's one LED shows | yes |
//! | [`self_test`] | the power-up self-test of the CAN path in silent loopback mode: its frame, bound and verdict | yes |
//! | [`flash_layout`] | the firmware update's flash layout on every board (bootloader, settings, STATE, ACTIVE, DFU), the bootloader's key block, the board ID | yes |
//! | [`settings`] | the power-safe settings journal (CRC-32 from `devicenet::crc32`, two sectors, sequence numbers) | yes |
//! | [`memory`] | the memory map and `memory.x` per chip (`board/memory/`: the firmware in ACTIVE, settings in sectors 1–2, their old location read once; the emulated build from 0x0800_0000) | yes |
//! | [`uart`] | the instrument line's character formats the USART can make, and the USART register values (`BRR`, `CR1`, `CR2`) that make them | yes |
//! | [`uid`] | the DeviceNet serial number, folded from the MCU's 96-bit unique ID (CRC-32) | yes |
//! | `hw` | the update partitions' flash driver (`hw::nor_flash`: embedded-storage's `NorFlash` per run of equal sectors, word programming), peripheral set-up, the USARTs driven through their registers (`hw::Usart`), the flash sector driver (the emulated board's: a host file over semihosting), CAN error status, the unique ID's read (real board) (`target_os = "none"` only) | – |
//!
//! ## Features
//!
//! | feature | effect |
//! |---|---|
//! | `reference` (default), `olimex-p405`, `olimex-p405-rs485`, `nucleo-f446re` | the board (exactly one); it also chooses stm32f4xx-hal's chip feature (`stm32f405` or `stm32f446`) and `memory.x` |
//! | `emulated` | `hw` builds the board QEMU's `netduinoplus2` emulates: RCC untouched (HSI, 16 MHz), no bxCAN; USART1 carries SLCAN (the codec is `can_io::slcan`) |
//! | `defmt` | `defmt::Format` on the value types |
//! | `bootloader-link` | build.rs ships no `memory.x`: the bootloader (`bootloader/`) links with its own |
//! | `fault-btr`, `fault-filter`, `fault-can-clock`, `fault-flash-unlock`, `fault-usart-brr`, `fault-never-confirm` | **self-test only, never in a release build**: each makes one hardware fact wrong (bit timing for half PCLK1; a Group 2 filter bank that matches nothing; CAN1's clock enable undone; flash programmed without the unlock sequence; the instrument USART's BRR for half its clock) so that `scripts/exact-firmware --self-test` can prove a scenario catches it; `fault-never-confirm` changes nothing here and only marks the firmware's build whose trial image never confirms (the update's rollback scenario). Such a build has the symbol `BOARD_FAULT_SELF_TEST_ONLY`, and `scripts/firmware-size` refuses an ELF that has it |
//!
//! It depends on the protocol core only (for the MAC ID and data rate types); the SLCAN codec the
//! emulated board speaks is `can_io::slcan`, shared with the host.
//!
//! `unsafe` is allowed in this crate only, and used only in `hw`: for register accesses the HAL
//! does not offer (CAN error status and test modes, the LED port in one write, the DIP switch
//! port's pull-ups, the USARTs' configuration and data registers, the unique ID) and for the
//! semihosting calls of the emulated board's settings file. The firmware's `memcpy` family is
//! `compiler_builtins`'.
#![no_std]

#[cfg(test)]
extern crate std;

pub mod autobaud;
pub mod bit_timing;
pub mod boards;
pub mod clocks;
pub mod filters;
pub mod flash_layout;
pub mod leds;
pub mod memory;
pub mod pins;
pub mod self_test;
pub mod settings;
pub mod switches;
pub mod uart;
pub mod uid;

#[cfg(target_os = "none")]
#[allow(unsafe_code)] // register and flash access the HAL lacks, and semihosting (crate docs)
pub mod hw;

pub use settings::{Settings, SettingsStore};

/// Present only in a build with one of the self-test's `fault-*` features (crate docs, Features):
/// `scripts/firmware-size` looks for this symbol in every ELF it measures and refuses one that has it.
#[cfg(any(
    feature = "fault-btr",
    feature = "fault-filter",
    feature = "fault-can-clock",
    feature = "fault-flash-unlock",
    feature = "fault-usart-brr",
    feature = "fault-never-confirm"
))]
#[used]
#[allow(unsafe_code)] // #[no_mangle] (an unsafe attribute): the symbol must keep its name for firmware-size
#[no_mangle]
pub static BOARD_FAULT_SELF_TEST_ONLY: u8 = 0;
pub use switches::{Resolved, SwitchReading};
