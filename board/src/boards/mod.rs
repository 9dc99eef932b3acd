//! The boards the firmware runs on, each described once as a [`BoardSpec`], and the one this build
//! is for, [`SELECTED`].
//!
//! | board | chip | Cargo feature | module |
//! |---|---|---|---|
//! | the reference adapter board | STM32F405RG | `reference` (default) | [`reference`](mod@reference) |
//! | Olimex STM32-P405 (instrument on its RS-232 port) | STM32F405RG | `olimex-p405` | [`olimex_p405`] |
//! | Olimex STM32-P405, RS-485 instrument on UEXT | STM32F405RG | `olimex-p405-rs485` | [`olimex_p405`] |
//! | NUCLEO-F446RE + Waveshare RS485 CAN Shield | STM32F446RE | `nucleo-f446re` | [`nucleo_f446re`] |
//!
//! Exactly one board feature is on in a build (a `compile_error!` otherwise); `emulated` is the
//! QEMU variant of the reference board and needs `reference`. The board feature also chooses
//! stm32f4xx-hal's chip feature (board/Cargo.toml). Every description is compiled on the host,
//! whatever the feature, so that the host tests check every board (bit timing at each board's
//! PCLK1, pin overlaps, the flash layout against the board's `memory/*.x`).
//!
//! Each board's module documents what was checked against which vendor document, and marks what
//! no source confirmed.

pub mod nucleo_f446re;
pub mod olimex_p405;
pub mod reference;

use crate::pins::Pin;

#[cfg(not(any(
    feature = "reference",
    feature = "olimex-p405",
    feature = "olimex-p405-rs485",
    feature = "nucleo-f446re"
)))]
compile_error!(
    "choose a board: one of the features `reference`, `olimex-p405`, `olimex-p405-rs485`, `nucleo-f446re`"
);

/// How many board features are on.
const BOARD_FEATURES: usize = cfg!(feature = "reference") as usize
    + cfg!(feature = "olimex-p405") as usize
    + cfg!(feature = "olimex-p405-rs485") as usize
    + cfg!(feature = "nucleo-f446re") as usize;
const _: () = assert!(
    BOARD_FEATURES <= 1,
    "choose one board only: `reference` is a default feature, so build another board with \
     `--no-default-features --features <board>`"
);

#[cfg(all(feature = "emulated", not(feature = "reference")))]
compile_error!("`emulated` is the QEMU variant of the reference board: build it with `reference`");

/// The microcontroller on a board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chip {
    /// STM32F405RG: 1 MiB flash, 128 KiB SRAM + 64 KiB CCM RAM, 168 MHz.
    Stm32f405rg,
    /// STM32F446RE: 512 KiB flash, 128 KiB SRAM, 180 MHz.
    Stm32f446re,
}

impl Chip {
    /// The name `probe-rs --chip` knows it by.
    pub const fn probe_rs_name(self) -> &'static str {
        match self {
            Chip::Stm32f405rg => "STM32F405RGTx",
            Chip::Stm32f446re => "STM32F446RETx",
        }
    }

    /// The largest APB1 clock (PCLK1) the chip allows, in Hz (DS8626 / DS10693, general
    /// operating conditions).
    pub const fn pclk1_max_hz(self) -> u32 {
        match self {
            Chip::Stm32f405rg => 42_000_000,
            Chip::Stm32f446re => 45_000_000,
        }
    }

    /// The largest system clock, in Hz.
    pub const fn sysclk_max_hz(self) -> u32 {
        match self {
            Chip::Stm32f405rg => 168_000_000,
            Chip::Stm32f446re => 180_000_000,
        }
    }
}

/// The clock tree a board runs: the PLL from the HSE input to the system clock.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClockTree {
    /// The HSE input frequency.
    pub hse_hz: u32,
    /// The HSE input is an external clock (bypass mode), not a crystal.
    pub hse_bypass: bool,
    /// The system clock (and the core clock SysTick counts).
    pub sysclk_hz: u32,
    /// APB1: bxCAN1 and USART2.
    pub pclk1_hz: u32,
    /// APB2: USART1.
    pub pclk2_hz: u32,
}

/// A USART the firmware can drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Usart {
    /// USART1 (APB2).
    Usart1,
    /// USART2 (APB1).
    Usart2,
}

/// Where the instrument is connected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InstrumentPort {
    /// The USART.
    pub usart: Usart,
    /// Its TX pin (AF7).
    pub tx: Pin,
    /// Its RX pin (AF7).
    pub rx: Pin,
    /// The RS-485 driver enable (DE, with /RE tied to it; high = transmit), or `None` for an
    /// RS-232 line.
    pub driver_enable: Option<Pin>,
}

/// The board's status LEDs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LedWiring {
    /// Module Status and Network Status, each a red/green pair: four consecutive pins of one port
    /// from this one, MS green, MS red, NS green, NS red, high = lit.
    Bicolour {
        /// The MS green pin; the other three follow it.
        ms_green: Pin,
    },
    /// One LED, high = lit ([`crate::leds::single_lit`] says what it shows).
    Single(Pin),
}

/// Eight DIP switches on eight consecutive pins of one port, each closing to ground against the
/// pin's pull-up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SwitchBank {
    /// The pin of switch 1; switches 2–8 follow it.
    pub first: Pin,
}

/// Where program and settings live in the chip's flash, and the RAM.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlashLayout {
    /// Total flash.
    pub flash_size: u32,
    /// Flash the program may use, from ACTIVE ([`crate::flash_layout::ACTIVE`]: 128 KiB less the
    /// signed image's trailer).
    pub program_size: u32,
    /// The settings journal's two sectors (numbers, for the erase command).
    pub settings_sectors: [u8; 2],
    /// Their start addresses.
    pub settings_bases: [u32; 2],
    /// The size of each (both the same).
    pub settings_sector_size: u32,
    /// SRAM from 0x2000_0000.
    pub ram_size: u32,
    /// CCM RAM at 0x1000_0000 (0: none).
    pub ccmram_size: u32,
}

/// Everything the firmware needs to know about a board.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardSpec {
    /// The board's name.
    pub name: &'static str,
    /// The Cargo feature that selects it.
    pub feature: &'static str,
    /// The board ID of the firmware update (issue 31): the number a firmware image's image-info
    /// block and the bootloader's key block carry, so that no board runs another board's image
    /// (reference 1, olimex-p405 2, olimex-p405-rs485 3, nucleo-f446re 4; the emulated build is
    /// [`EMULATED_BOARD_ID`]).
    pub board_id: u16,
    /// The microcontroller.
    pub chip: Chip,
    /// Clocks.
    pub clocks: ClockTree,
    /// CAN1 RX (AF9).
    pub can_rx: Pin,
    /// CAN1 TX (AF9).
    pub can_tx: Pin,
    /// The instrument's serial port.
    pub instrument: InstrumentPort,
    /// The status LEDs.
    pub leds: LedWiring,
    /// The DIP switches, if the board has them; without them MAC ID and data rate come from the
    /// stored settings.
    pub switches: Option<SwitchBank>,
    /// Flash and RAM.
    pub flash: FlashLayout,
    /// The linker script's `MEMORY` block for this board (board/memory/*.x; build.rs ships it).
    pub memory_x: &'static str,
}

impl BoardSpec {
    /// The clock of the instrument's USART: APB2 for USART1, APB1 for USART2.
    pub const fn instrument_clock_hz(&self) -> u32 {
        match self.instrument.usart {
            Usart::Usart1 => self.clocks.pclk2_hz,
            Usart::Usart2 => self.clocks.pclk1_hz,
        }
    }
}

/// The board ID of the emulated (QEMU) build, which has no bootloader and no update.
pub const EMULATED_BOARD_ID: u16 = 5;

/// The board ID of this build's board ([`BoardSpec::board_id`] of [`SELECTED`], or
/// [`EMULATED_BOARD_ID`] with the `emulated` feature).
pub const BOARD_ID: u16 = if cfg!(feature = "emulated") { EMULATED_BOARD_ID } else { SELECTED.board_id };

/// Every board, for the host tests.
pub const ALL: [&BoardSpec; 4] =
    [&reference::BOARD, &olimex_p405::BOARD, &olimex_p405::BOARD_RS485, &nucleo_f446re::BOARD];

/// The board this build is for (Cargo feature).
#[cfg(not(any(feature = "olimex-p405", feature = "olimex-p405-rs485", feature = "nucleo-f446re")))]
pub const SELECTED: &BoardSpec = &reference::BOARD;
/// The board this build is for (Cargo feature).
#[cfg(all(feature = "olimex-p405", not(any(feature = "olimex-p405-rs485", feature = "nucleo-f446re"))))]
pub const SELECTED: &BoardSpec = &olimex_p405::BOARD;
/// The board this build is for (Cargo feature).
#[cfg(all(feature = "olimex-p405-rs485", not(feature = "nucleo-f446re")))]
pub const SELECTED: &BoardSpec = &olimex_p405::BOARD_RS485;
/// The board this build is for (Cargo feature).
#[cfg(feature = "nucleo-f446re")]
pub const SELECTED: &BoardSpec = &nucleo_f446re::BOARD;

/// The RAM layout every board shares: the last 8 bytes of SRAM are the reset-surviving cell.
pub const RAM_BASE: u32 = 0x2000_0000;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bit_timing::{bit_timing, TARGET_SAMPLE_POINT_PERMILLE};
    use crate::pins::Port;
    use std::vec::Vec;

    fn pins(board: &BoardSpec) -> Vec<Pin> {
        let mut pins = std::vec![board.can_rx, board.can_tx, board.instrument.tx, board.instrument.rx];
        pins.extend(board.instrument.driver_enable);
        match board.leds {
            LedWiring::Bicolour { ms_green } => {
                pins.extend((0..4).map(|i| Pin { port: ms_green.port, number: ms_green.number + i }))
            }
            LedWiring::Single(pin) => pins.push(pin),
        }
        if let Some(bank) = board.switches {
            pins.extend((0..8).map(|i| Pin { port: bank.first.port, number: bank.first.number + i }));
        }
        pins
    }

    #[test]
    fn no_pin_serves_twice_and_every_pin_exists() {
        for board in ALL {
            let pins = pins(board);
            for (i, a) in pins.iter().enumerate() {
                assert!(a.number < 16, "{}: {a:?}", board.name);
                for b in &pins[i + 1..] {
                    assert_ne!(a, b, "{}", board.name);
                }
            }
            // SWD (PA13/PA14) stays free for the probe.
            for swd in [13, 14] {
                assert!(!pins.contains(&Pin { port: Port::A, number: swd }), "{}", board.name);
            }
        }
    }

    #[test]
    fn clocks_within_the_chip_limits() {
        for board in ALL {
            let c = board.clocks;
            assert!(c.sysclk_hz <= board.chip.sysclk_max_hz(), "{}", board.name);
            assert!(c.pclk1_hz <= board.chip.pclk1_max_hz(), "{}", board.name);
            assert!(c.pclk2_hz <= 2 * board.chip.pclk1_max_hz(), "{}", board.name);
            assert_eq!(c.sysclk_hz % c.pclk1_hz, 0, "{}", board.name);
            assert_eq!(c.sysclk_hz % c.pclk2_hz, 0, "{}", board.name);
            // SysTick's 24-bit reload at 1 kHz.
            assert!(c.sysclk_hz / 1000 - 1 < 1 << 24);
        }
    }

    #[test]
    fn every_devicenet_rate_at_every_board_pclk1() {
        for board in ALL {
            for rate in [125_000, 250_000, 500_000] {
                let t = bit_timing(board.clocks.pclk1_hz, rate, TARGET_SAMPLE_POINT_PERMILLE)
                    .unwrap_or_else(|| panic!("{}: no timing for {rate}", board.name));
                assert_eq!(t.bit_rate(board.clocks.pclk1_hz), rate, "{}", board.name);
                let sp = t.sample_point_permille();
                assert!((850..=900).contains(&sp), "{}: {rate}: {sp} ‰", board.name);
            }
        }
    }

    #[test]
    fn every_instrument_line_from_1200_to_115200_bits() {
        use crate::uart::LineFormat;
        for board in ALL {
            for baud in [1200, 9600, 19_200, 115_200] {
                let clock = board.instrument_clock_hz();
                assert!(LineFormat::new_8n1(baud).registers(clock).is_ok(), "{}: {baud}", board.name);
            }
        }
    }

    #[test]
    fn only_the_reference_board_has_switches() {
        assert!(reference::BOARD.switches.is_some());
        assert!(olimex_p405::BOARD.switches.is_none());
        assert!(olimex_p405::BOARD_RS485.switches.is_none());
        assert!(nucleo_f446re::BOARD.switches.is_none());
    }

    #[test]
    fn features_name_the_boards() {
        let features: Vec<_> = ALL.iter().map(|b| b.feature).collect();
        assert_eq!(features, ["reference", "olimex-p405", "olimex-p405-rs485", "nucleo-f446re"]);
        let manifest = include_str!("../../Cargo.toml");
        for feature in features {
            assert!(manifest.lines().any(|l| l.starts_with(&std::format!("{feature} = "))), "{feature}");
        }
    }
}
