//! # exact-firmware
//!
//! The exact firmware ELF of every board, run on the register-level models of stm32-emu (with its
//! board's bootloader, which starts it: [`device::Firmware`]), as a device of the simulated CAN bus: the bench master's library (master-core, what `dnet-master`
//! runs) drives it unchanged, and the simulated breaker of converter-sim sits on its instrument
//! USART (issue 26).
//!
//! | module | what it holds |
//! |---|---|
//! | [`board`] | the boards, from the board crate's own descriptions; the MAC/rate set before power-on |
//! | [`device`] | [`EmulatedBoard`]: the machine, its models, the bus and the breaker tied together |
//! | [`scenario`] | the scenarios and their one-line verdicts |
//! | [`uid`] | the unique ID whose CRC-32 fold is the reference serial number |
//! | [`shared`] | a model the machine and the world outside both hold |
//! | [`serve`] | `exact-firmware-serve`: the board on real interfaces, an SLCAN adapter and the instrument line on ptys, the settings flash in a file, in wall time |
//!
//! ## Scenarios
//!
//! On every board `bring-up`, `breaker`, `power-cycle`, `configure`, `ccv` (the configuration
//! consistency value after a download and a power cycle), `download-cut` (a power cut
//! at every flash operation of a download), `wrong-bit-rate`, `bus-load`, `bus-off`, `leds` and
//! `can-self-test-fault` (the CAN self-test failing), `settings-migration` (the settings an
//! earlier firmware stored in the chip's last two sectors moved into the journal's new sectors),
//! `trial-confirm` (the firmware, signed with the TEST key and swapped in by the bootloader, runs
//! on trial and confirms itself once on-line);
//! on a board with DIP switches `switches`;
//! on a board without them `mac63-autobaud-125k`, `-250k`, `-500k` and `autobaud-silent-bus`
//! ([`scenario`] says what each compares). The binary `exact-firmware` runs those that apply on
//! every board ELF given and scripts/exact-firmware on every board's build. `bus-off` found the
//! first firmware bug the models caught: bxcan 0.8's `enable_non_blocking` sets `MCR.ABOM`, so the
//! controller left bus-off by itself whatever the bus-off interrupt setting said
//! (protocol §7.2: BOI 0 stays bus-off); the firmware now clears it
//! (`board::hw::disable_automatic_bus_off_management`).
//!
//! ## What emulation proves, and what only a real board can
//!
//! Proven here, for the very bytes that are flashed: the firmware's start-up on the modelled
//! clock tree (RCC, PLL, flash wait states), its bxCAN set-up (bit timing at the board's PCLK1,
//! filters, modes) as far as the model follows RM0090, the whole DeviceNet behaviour of the
//! firmware against the master's library (the 28-frame bring-up byte for byte, polling), its
//! instrument USART at the configured rate against the simulated breaker, the MAC/rate choice
//! from switches or the flash settings journal, the serial number folded from the unique ID, and
//! the error counting of a node at the wrong bit rate.
//!
//! Not proven: anything the models do not model or model more kindly than silicon — analogue
//! effects (oscillator start-up, transceiver, line termination, bit sampling jitter), exact
//! instruction timing (one cycle per instruction, stm32-emu `machine` docs), DMA, peripherals
//! the firmware does not use, the RS-485 driver enable's timing on a real line, flash wear and
//! the real sector erase times beyond the FLASH model's, and the simulated bus's lack of error
//! flags (a frame one node flags is still delivered to the others). Those need a real board.

pub mod board;
pub mod device;
pub mod scenario;
pub mod serve;
pub mod shared;
pub mod uid;

pub use board::{BoardKind, NodeSetting};
pub use device::EmulatedBoard;
