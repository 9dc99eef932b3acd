//! Olimex STM32-P405 (STM32F405RGT6), a development board one can buy.
//!
//! | fact | value | source |
//! |---|---|---|
//! | chip | STM32F405RG | \[1\], \[2\] (`stm32f405Xg.dtsi`) |
//! | clock | 8 MHz crystal (HSE, not bypassed) → PLL M=4, N=168, P=2 → 168 MHz; APB1 ÷4 = 42 MHz | \[2\] (`&clk_hse` 8 MHz, `&pll`, `&rcc`) |
//! | APB2 | ÷4 = 42 MHz (Zephyr's ÷2 = 84 MHz would stop USART1's 16-bit divider at 1282 bit/s; at 42 MHz the UEXT RS-485 line goes down to 641 bit/s, as USART2 does) | our choice |
//! | CAN1 | PB8 RX / PB9 TX (AF9), to the board's CAN transceiver | \[2\] (`can1_rx_pb8 can1_tx_pb9`, a `can-transceiver` node, 1 Mbit/s), \[3\] (`PB8_CAN1_RX`, `PB9_CAN1_TX`) |
//! | instrument (default) | USART2, PA2 TX / PA3 RX (AF7), the board's RS-232 port; no DE | \[2\] (`usart2_tx_pa2 usart2_rx_pa3`, the console), \[3\] |
//! | status LED | PC12, high = lit | \[2\] (`gpioc 12 GPIO_ACTIVE_HIGH`), \[4\] (`GPIO_LED_STATUS` … `GPIO_PIN12`), \[5\] (`LED0_PIN GPIO_PIN(PORT_C, 12)`) |
//! | UEXT | 1 +3.3 V, 2 GND, 3 PA9 USART1_TX, 4 PA10 USART1_RX, 5 PB6, 6 PB7, 7 PA6, 8 PA7, 9 PA5, 10 PA4 (SPI1_NSS) | \[1\] ("UEXT" table) |
//! | user button | PA0 | \[1\], \[2\] |
//! | OTG FS VBUS sense | PC4 (so PA9 is free for USART1) | \[4\] (`GPIO_OTGFS_VBUS` … `GPIO_PIN4`) |
//! | settings | flash sectors 1 and 2, as on the reference board (same chip) | RM0090 §3.3 |
//!
//! Not confirmed by any source read for this work, to check against Olimex's user manual and
//! schematic (`STM32-P103_P405_sch.pdf`) before relying on it: the CAN and RS-232 transceiver
//! parts and the CAN connector's pin-out; the LED's colour (\[1\] says red, \[2\] names it
//! `green_led_1`); the power input range of the supply jack; the BOOT0 jumper's name and position
//! and the USB connector used by the ROM DFU loader (AN2606 names USB OTG FS on PA11/PA12 for the
//! STM32F405's DFU); whether PA4 is wired to anything else on the board.
//!
//! **RS-485 instruments** ([`UEXT_RS485`]): a 3.3 V half-duplex transceiver (MAX3485, SP3485 or
//! similar) on the UEXT connector, USART1 PA9 TX / PA10 RX, DE and /RE together on **PA4**, UEXT
//! pin 10: the only pin the firmware needs beyond the USART sits on the same 10-pin connector
//! (one ribbon cable carries 3.3 V, GND, TX, RX and DE), and it is SPI1's NSS, which the firmware
//! does not use. The `olimex-p405` build ([`BOARD`]) runs the RS-232 port, the
//! `olimex-p405-rs485` build ([`BOARD_RS485`]) the UEXT one; otherwise they are the same.
//!
//! The board has no DIP switches: the MAC ID and data rate come from the stored settings. It has
//! one LED, which shows what [`crate::leds::single_lit`] says.
//!
//! Sources:
//! 1. Zephyr Project, "OLIMEX-STM32-P405" board page, sections "Pin Mapping" (LED, push buttons)
//!    and "External Connectors" (JTAG, UEXT),
//!    <https://docs.zephyrproject.org/latest/boards/olimex/stm32_p405/doc/index.html>.
//! 2. Zephyr Project, `boards/olimex/stm32_p405/olimex_stm32_p405.dts` (github.com/zephyrproject-rtos/zephyr).
//! 3. Zephyr Project (2017), `boards/arm/olimex_stm32_p405/pinmux.c`, the board's pin assignment.
//! 4. Apache NuttX, `boards/arm/stm32/olimex-stm32-p405/src/olimex-stm32-p405.h` (LED, button, OTG VBUS).
//! 5. RIOT OS, `boards/olimex-stm32-p405/include/board.h`.
//! 6. Olimex, STM32-P405 product page and user manual,
//!    <https://www.olimex.com/Products/ARM/ST/STM32-P405/> (not retrieved for this work).

use super::{BoardSpec, ClockTree, InstrumentPort, LedWiring, Usart};
use crate::boards::reference::STM32F405RG_LAYOUT;
use crate::boards::Chip;
use crate::pins::{pin, Port};

/// The Olimex STM32-P405 with the instrument on its RS-232 port.
pub const BOARD: BoardSpec = BoardSpec {
    name: "Olimex STM32-P405",
    feature: "olimex-p405",
    board_id: 2,
    chip: Chip::Stm32f405rg,
    clocks: ClockTree {
        hse_hz: 8_000_000,
        hse_bypass: false,
        sysclk_hz: 168_000_000,
        pclk1_hz: 42_000_000,
        pclk2_hz: 42_000_000,
    },
    can_rx: pin(Port::B, 8),
    can_tx: pin(Port::B, 9),
    instrument: InstrumentPort {
        usart: Usart::Usart2,
        tx: pin(Port::A, 2),
        rx: pin(Port::A, 3),
        driver_enable: None,
    },
    leds: LedWiring::Single(pin(Port::C, 12)),
    switches: None,
    flash: STM32F405RG_LAYOUT,
    memory_x: include_str!("../../memory/stm32f405rg.x"),
};

/// The Olimex STM32-P405 with an RS-485 instrument through a 3.3 V transceiver on UEXT.
pub const BOARD_RS485: BoardSpec = BoardSpec {
    name: "Olimex STM32-P405, RS-485 on UEXT",
    feature: "olimex-p405-rs485",
    board_id: 3,
    instrument: UEXT_RS485,
    ..BOARD
};

/// An RS-485 instrument through a 3.3 V transceiver on the UEXT connector: USART1 on UEXT pins 3
/// (PA9, TX) and 4 (PA10, RX), DE on UEXT pin 10 (PA4).
pub const UEXT_RS485: InstrumentPort = InstrumentPort {
    usart: Usart::Usart1,
    tx: pin(Port::A, 9),
    rx: pin(Port::A, 10),
    driver_enable: Some(pin(Port::A, 4)),
};
