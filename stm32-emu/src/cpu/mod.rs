//! The CPU of the machine: a Cortex-M4 with FPU ([`core`], on the unicorn engine), its
//! System Control Space ([`scs`]: SCB, NVIC, SysTick) and the bus to the peripheral models
//! ([`bus`]).
//!
//! References: the Cortex-M4 programming manual PM0214 (rev 10) to which RM0090 §2.1 and §12
//! refer for the core and its peripherals, and the ARMv7-M Architecture Reference Manual
//! where PM0214 leaves out the pseudocode.

pub mod bus;
pub mod core;
pub mod elf;
pub mod flash_port;
pub mod scs;
pub mod systick;
