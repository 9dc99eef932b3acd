//! Clock tree of the selected board ([`crate::boards::SELECTED`]).
//!
//! Every board runs the PLL from its HSE input (a crystal, or the ST-LINK's 8 MHz MCO in bypass
//! mode on the Nucleo) to its system clock; bxCAN1 and USART2 run from APB1, USART1 from APB2.
//! QEMU's `netduinoplus2` emulates neither the HSE nor the PLL, so the emulated build (of the
//! reference board) leaves RCC at its reset state (HSI, 16 MHz on every bus) and never touches it.

use crate::boards::SELECTED;

/// The HSE input of the board.
pub const HSE_HZ: u32 = SELECTED.clocks.hse_hz;
/// Whether the HSE input is an external clock (bypass) rather than a crystal.
pub const HSE_BYPASS: bool = SELECTED.clocks.hse_bypass;
/// The internal RC oscillator, the clock after reset.
pub const HSI_HZ: u32 = 16_000_000;

/// System clock of the real board (PLL from HSE).
pub const SYSCLK_HZ: u32 = SELECTED.clocks.sysclk_hz;
/// APB1 clock of the real board: bxCAN1 and USART2 run from it.
pub const PCLK1_HZ: u32 = SELECTED.clocks.pclk1_hz;
/// APB2 clock of the real board: USART1 runs from it.
pub const PCLK2_HZ: u32 = SELECTED.clocks.pclk2_hz;

/// The clock the instrument's USART runs from in this build: its APB clock on a real board, HSI
/// on the emulated one.
pub const INSTRUMENT_UART_HZ: u32 =
    if cfg!(feature = "emulated") { HSI_HZ } else { SELECTED.instrument_clock_hz() };

/// The clock SysTick counts in this build.
///
/// On a real board this is the core clock. QEMU 7.2's `netduinoplus2` feeds the Cortex-M4 core
/// clock (and with it SysTick) a fixed 168 MHz whatever RCC says, so the emulated build uses the
/// reference board's figure even though its peripherals run from HSI.
pub const SYSTICK_HZ: u32 = SYSCLK_HZ;

/// Baud rate of the USART1 service port (and of the SLCAN link in the emulated build).
pub const SERVICE_BAUD: u32 = 115_200;
