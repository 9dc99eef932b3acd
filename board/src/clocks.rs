//! Clock tree of the adapter board.
//!
//! The real board runs the PLL from an 8 MHz crystal (HSE) to a 168 MHz system clock with APB1 at
//! 42 MHz (bxCAN and USART2) and APB2 at 84 MHz (USART1). QEMU's `netduinoplus2` emulates neither
//! the HSE nor the PLL, so the emulated build leaves RCC at its reset state (HSI, 16 MHz on every
//! bus) and never touches it.

/// The crystal on the board (HSE).
pub const HSE_HZ: u32 = 8_000_000;
/// The internal RC oscillator, the clock after reset.
pub const HSI_HZ: u32 = 16_000_000;

/// System clock of the real board (PLL from HSE).
pub const SYSCLK_HZ: u32 = 168_000_000;
/// APB1 clock of the real board: bxCAN1 and USART2 run from it.
pub const PCLK1_HZ: u32 = 42_000_000;
/// APB2 clock of the real board: USART1 runs from it.
pub const PCLK2_HZ: u32 = 84_000_000;

/// The clock USART2 (the instrument port) runs from in the build selected by the `emulated`
/// feature: APB1 on the real board, HSI on the emulated one.
pub const INSTRUMENT_UART_HZ: u32 = if cfg!(feature = "emulated") { HSI_HZ } else { PCLK1_HZ };

/// The clock SysTick counts in the build selected by the `emulated` feature.
///
/// On the real board this is the 168 MHz core clock. QEMU 7.2's `netduinoplus2` feeds the
/// Cortex-M4 core clock (and with it SysTick) a fixed 168 MHz whatever RCC says, so the emulated
/// build uses the same figure even though its peripherals run from HSI.
pub const SYSTICK_HZ: u32 = SYSCLK_HZ;

/// Baud rate of the USART1 service port (and of the SLCAN link in the emulated build).
pub const SERVICE_BAUD: u32 = 115_200;
