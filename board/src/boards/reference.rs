//! The reference adapter board: the project's own design (not sold), STM32F405RG.
//!
//! | fact | value |
//! |---|---|
//! | clock | 8 MHz crystal (HSE) → PLL → 168 MHz SYSCLK, APB1 42 MHz, APB2 84 MHz |
//! | CAN1 | PB8 RX / PB9 TX (AF9) to the isolated transceiver |
//! | instrument | USART2, PA2 TX / PA3 RX (AF7), RS-485 DE (and /RE) on PA1; the RS-232 variant leaves PA1 unconnected (driving it is harmless) |
//! | service port | USART1, PA9 / PA10 (unused on the board, SLCAN in the emulated build) |
//! | DIP switches | PB0–PB7 to ground, pull-ups |
//! | LEDs | PC0–PC3: MS green, MS red, NS green, NS red, high = lit |
//! | settings | flash sectors 1 and 2 (2 × 16 KiB at 0x0800_4000; sectors 10 and 11 before the firmware update) |
//!
//! Sources: the board's own design (guide: docs/src/development/firmware.md,
//! docs/src/integrator/wiring.md); the STM32F405 facts from
//! RM0090 (flash organisation §3.3, Table 5: sectors 1 and 2 at 0x0800_4000 and 0x0800_8000)
//! and DS8626 (alternate functions: CAN1 PB8/PB9 AF9, USART2 PA2/PA3 AF7).

use super::{BoardSpec, ClockTree, FlashLayout, InstrumentPort, LedWiring, SwitchBank, Usart};
use crate::boards::Chip;
use crate::pins::{pin, Port};

/// The reference adapter board.
pub const BOARD: BoardSpec = BoardSpec {
    name: "reference adapter board",
    feature: "reference",
    board_id: 1,
    chip: Chip::Stm32f405rg,
    clocks: ClockTree {
        hse_hz: 8_000_000,
        hse_bypass: false,
        sysclk_hz: 168_000_000,
        pclk1_hz: 42_000_000,
        pclk2_hz: 84_000_000,
    },
    can_rx: pin(Port::B, 8),
    can_tx: pin(Port::B, 9),
    instrument: InstrumentPort {
        usart: Usart::Usart2,
        tx: pin(Port::A, 2),
        rx: pin(Port::A, 3),
        driver_enable: Some(pin(Port::A, 1)),
    },
    leds: LedWiring::Bicolour { ms_green: pin(Port::C, 0) },
    switches: Some(SwitchBank { first: pin(Port::B, 0) }),
    flash: STM32F405RG_LAYOUT,
    memory_x: include_str!("../../memory/stm32f405rg.x"),
};

/// The STM32F405RG's flash in the firmware update's layout ([`crate::flash_layout`]: the program
/// in ACTIVE, the settings in sectors 1 and 2; RM0090 §3.3, Table 5), and its SRAM1 + SRAM2
/// (128 KiB) and CCM RAM (64 KiB).
pub const STM32F405RG_LAYOUT: FlashLayout = FlashLayout {
    flash_size: 1024 * 1024,
    program_size: crate::flash_layout::MAX_IMAGE_LEN,
    settings_sectors: [1, 2],
    settings_bases: [0x0800_4000, 0x0800_8000],
    settings_sector_size: 16 * 1024,
    ram_size: 128 * 1024,
    ccmram_size: 64 * 1024,
};
