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
//!
//! | module | what it models | source |
//! |---|---|---|
//! | [`cpu`] | the Cortex-M4 on unicorn: memory map, ELF loading, NVIC, SCB, SysTick, exception entry and return (unicorn has no NVIC) | PM0214 §2.3, §4.2–§4.5 |
//! | [`machine`] | the chip: models by address, time (one instruction, one HCLK cycle), sleep, resets (with their cause in RCC_CSR), several ELF files (a bootloader and its application) loaded before the power-on reset | RM0090 §2.3, §7.1 |
//! | [`rcc`] | HSI, HSE, PLL with ready flags, clock gates, resets | RM0090 §7.3 |
//! | [`flash`] | the FLASH interface and its array: unlock, PSIZE, sector erase, error flags, power cuts, option bytes kept across power cycles (write protection, RDP, WDG_SW), the F446's 512 KiB | RM0090 §3, RM0390 §3 |
//! | [`gpio`] | modes, alternate functions, pulls, BSRR, LCKR, levels from outside | RM0090 §8.4 |
//! | [`usart`] | BRR and oversampling, parity, stop bits, flags, the line's timing and garbling | RM0090 §30 |
//! | [`bxcan`] | CAN1: modes, BTR, filters, mailboxes, FIFOs, error counting, bus-off | RM0090 §32 |
//! | [`pwr`] | the regulator's over-drive handshake the F446 firmware waits for | RM0390 §5 |
//! | [`iwdg`] | the independent watchdog: keys, prescaler, reload, PVU/RVU, the reset on timeout (RCC_CSR.IWDGRSTF) | RM0090 §21 |
//!
//! Every model with an RCC clock enable bit (GPIO, USART, bxCAN, PWR) reads 0 and loses writes
//! while the bit is clear, as the chip does, and the machine stops on such an access with
//! [`machine::Fault::Unclocked`], naming the peripheral, the register and the bit ([`periph`]'s
//! module docs give the sources).
//!
//! Not modelled, because the firmware does not use them: the window watchdog, DMA, timers,
//! CAN2, USART3 and UART4/5. An access to a block no model answers is a bus fault that stops the machine, so a
//! firmware that starts using one of them fails loudly here until its model is written.
//!
//! ## Licence of what links it
//!
//! The models are this project's (MIT OR Apache-2.0). The CPU comes from the `unicorn-engine`
//! crate, whose C library is GPL-2.0: a binary that links this crate (the `exact-firmware` runner,
//! the tests) is test equipment under the GPL's terms and is never part of the firmware or of the
//! host programs a user installs (`dnet-master`, `dnet-eds`, `dnet-soft-slave`), none of which
//! depend on it (`cargo tree -p master-harness -e normal` shows no `unicorn-engine`).

pub mod bxcan;
pub mod cpu;
pub mod flash;
pub mod gpio;
pub mod iwdg;
pub mod machine;
pub mod periph;
pub mod pwr;
pub mod rcc;
pub mod usart;
