//! NUCLEO-F446RE with the Waveshare RS485 CAN Shield, two boards one can buy.
//!
//! | fact | value | source |
//! |---|---|---|
//! | chip | STM32F446RE (512 KiB flash, 128 KiB SRAM, 180 MHz) | \[1\], \[5\] |
//! | clock | HSE **bypass**: the ST-LINK's 8 MHz MCO drives OSC_IN (no crystal fitted at X3) | \[1\] (`&clk_hse { hse-bypass; clock-frequency = <DT_FREQ_M(8)>; /* STLink 8MHz clock */ }`), \[4\] §6.7.1 |
//! | clock tree | PLL → 180 MHz SYSCLK (the F446's maximum, with the regulator's over-drive, which stm32f4xx-hal turns on above 168 MHz); APB1 ÷4 = 45 MHz (its maximum); APB2 ÷4 = 45 MHz too (below): USART1, the instrument, runs from it | \[5\] (clock limits), stm32f4xx-hal 0.23 `rcc/f4/mod.rs` (`SYSCLK_MAX`, over-drive) |
//! | CAN1 | D15 = PB8 RX, D14 = PB9 TX (AF9), the shield's SN65HVD230 | \[2\] §2.2 ("D14 (PB_9) and D15 (PB_8) are CAN's sending and receiving ports respectively as default"), \[3\] (pin table) |
//! | instrument | USART1, D8 = PA9 TX, D2 = PA10 RX (AF7), the shield's RS-485 transceiver with DE and /RE on D7 = PA8, high = transmit | \[2\] §2.2, §2.3.1, \[3\] (pin table: "D7 PA8 RS485 Sending & Receiving Enable Terminal") |
//! | shield jumper | "485 RXD/TXD JMP" on the D8/D2 (UART1) side, not D0/D1: PA2/PA3 are the ST-LINK's virtual COM port | \[2\] §2.2, \[1\] (`usart2` is the console) |
//! | LED | LD2, green, PA5, high = lit | \[1\] (`gpioa 5 GPIO_ACTIVE_HIGH`, "User LD2"), \[4\] |
//! | settings | flash sectors 1 and 2 (2 × 16 KiB at 0x0800_4000), the firmware update's layout; sectors 6 and 7 before it (now DFU): the F446RE has sectors 0–7 only | RM0390 §3.3 (flash organisation) |
//!
//! Contradictions: the issue names the shield's RS-485 transceiver SP3485; the shield's user
//! manual Rev 1.4 \[2\] says MAX3485, and Zephyr's page \[3\] says "SP3485/MAX3485" in its overview
//! and "MAX485" under Hardware. All are 3.3 V half-duplex parts with DE/RE: the firmware does not
//! care, the page says which one to expect by revision. The issue's "selectable CAN pins via
//! jumpers" is not in the manual's text \[2\], which calls D14/D15 the default; only the RS-485
//! UART is jumper-selectable there.
//!
//! Not confirmed by a source read for this work: the solder bridges of the MCO clock path (UM1724
//! §6.7.1: SB16 and SB50 on, SB55 off on boards that take MCO; the default on MB1136 C-02 and
//! later) and the JP5 position for external power. Nothing else the firmware drives shares these
//! pins: PA5 is also Arduino D13 (SPI1_SCK), which the shield leaves unconnected \[3\].
//!
//! APB2 could run at 90 MHz, but USART1's 16-bit divider then stops at 1373 bit/s: at 45 MHz the
//! instrument line goes down to 687 bit/s (1200 bit/s instruments work), as on the reference
//! board's 42 MHz USART2. Nothing else the firmware uses runs from APB2.
//!
//! The boards have no DIP switches: the MAC ID and data rate come from the stored settings. LD2 is
//! the only LED the firmware drives ([`crate::leds::single_lit`]).
//!
//! Sources:
//! 1. Zephyr Project, `boards/st/nucleo_f446re/nucleo_f446re.dts` (github.com/zephyrproject-rtos/zephyr).
//! 2. Waveshare, "RS485 CAN Shield User Manual", Rev 1.4 (2015-05-19), §1.1, §2.2, §2.3.1,
//!    <https://files.waveshare.com/upload/1/1a/RS485-CAN-Shield-User-Manual.pdf>; the wiki page
//!    <https://www.waveshare.com/wiki/RS485_CAN_Shield>.
//! 3. Zephyr Project, `boards/shields/waveshare_rs485_can/doc/index.rst` ("Hardware
//!    configuration", "STM32 Pin Connection").
//! 4. ST, UM1724 "STM32 Nucleo-64 boards (MB1136)", Rev 14: §6.3 power supply (VIN 7–12 V, E5V,
//!    USB), §6.7.1 OSC clock supply, <https://www.st.com/resource/en/user_manual/um1724-stm32-nucleo64-boards-mb1136-stmicroelectronics.pdf>.
//! 5. ST, DS10693 STM32F446xC/E datasheet (not retrieved for this work): 180 MHz, APB1 45 MHz,
//!    alternate functions. The limits are also stm32f4xx-hal 0.23's (`SYSCLK_MAX`, `PCLK1_MAX`
//!    for `gpio-f446`, asserted when the clocks are frozen). CAN1 on PB8/PB9 (AF9) is checked by
//!    the build: the HAL's CAN1 pin types for `gpio-f446` accept only its CAN1 pins. USART1 on
//!    PA9/PA10 (AF7) is the firmware's `into_alternate::<7>()`, which the HAL does not check
//!    against a table: the source is \[2\] and \[3\] (PA9/PA10 are the shield's UART1) and AF7
//!    being USART1–3 on every STM32F4 (as on the STM32F405, DS8626).

use super::{BoardSpec, ClockTree, FlashLayout, InstrumentPort, LedWiring, Usart};
use crate::boards::Chip;
use crate::pins::{pin, Port};

/// The NUCLEO-F446RE with the Waveshare RS485 CAN Shield.
pub const BOARD: BoardSpec = BoardSpec {
    name: "NUCLEO-F446RE + Waveshare RS485 CAN Shield",
    feature: "nucleo-f446re",
    board_id: 4,
    chip: Chip::Stm32f446re,
    clocks: ClockTree {
        hse_hz: 8_000_000,
        hse_bypass: true,
        sysclk_hz: 180_000_000,
        pclk1_hz: 45_000_000,
        pclk2_hz: 45_000_000,
    },
    can_rx: pin(Port::B, 8),
    can_tx: pin(Port::B, 9),
    instrument: InstrumentPort {
        usart: Usart::Usart1,
        tx: pin(Port::A, 9),
        rx: pin(Port::A, 10),
        driver_enable: Some(pin(Port::A, 8)),
    },
    leds: LedWiring::Single(pin(Port::A, 5)),
    switches: None,
    flash: FlashLayout {
        flash_size: 512 * 1024,
        program_size: crate::flash_layout::MAX_IMAGE_LEN,
        settings_sectors: [1, 2],
        settings_bases: [0x0800_4000, 0x0800_8000],
        settings_sector_size: 16 * 1024,
        ram_size: 128 * 1024,
        ccmram_size: 0,
    },
    memory_x: include_str!("../../memory/stm32f446re.x"),
};
