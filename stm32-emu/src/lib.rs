//! # stm32-emu
//!
//! Register-level models of the STM32F4 peripherals the adapter firmware touches, written from
//! the reference manual RM0090 (rev 19) and cited by section, and the runner that executes the
//! exact firmware ELF of every board on them.
//!
//! The models are plain Rust state machines behind one trait, [`periph::Peripheral`]: a bus
//! access in, register contents and interrupt lines out, time advanced explicitly. They know
//! nothing of the CPU emulator, so each is unit-tested against the manual's register facts on
//! its own.
#![forbid(unsafe_code)]

pub mod bxcan;
pub mod cpu;
pub mod flash;
pub mod gpio;
pub mod machine;
pub mod periph;
pub mod pwr;
pub mod rcc;
pub mod usart;
