//! The boards: which chip, clocks, instrument USART, switches and settings sectors, read from
//! the board crate's own descriptions ([`board::boards::ALL`], host-compiled whatever the
//! feature), and the names scripts/firmware-size gives their ELFs.

use board::boards::{BoardSpec, Chip, Usart};
use board::settings::Settings;
use devicenet::slave::BaudRate;
use devicenet::MacId;
use stm32_emu::gpio::Port;
use stm32_emu::usart::UsartId;

/// A board the runner knows: its build name and the board crate's description of it.
#[derive(Clone, Copy, Debug)]
pub struct BoardKind {
    /// The name of the build (`reference`, `olimex-p405`, …): the board crate's Cargo feature,
    /// which scripts/firmware-size appends to the ELF's name.
    pub name: &'static str,
    /// The board crate's description.
    pub spec: &'static BoardSpec,
}

impl BoardKind {
    /// Every board of the board crate.
    pub fn all() -> Vec<BoardKind> {
        board::boards::ALL.iter().map(|spec| BoardKind { name: spec.feature, spec }).collect()
    }

    /// The board of the build called `name`.
    pub fn by_name(name: &str) -> Option<BoardKind> {
        BoardKind::all().into_iter().find(|b| b.name == name)
    }

    /// The emulator's chip.
    pub fn chip(&self) -> stm32_emu::machine::Chip {
        match self.spec.chip {
            Chip::Stm32f405rg => stm32_emu::machine::Chip::Stm32F405,
            Chip::Stm32f446re => stm32_emu::machine::Chip::Stm32F446,
        }
    }

    /// The HSE input: a crystal, or an external clock in bypass mode (the NUCLEO's ST-LINK MCO).
    pub fn hse(&self) -> stm32_emu::rcc::Hse {
        let hz = self.spec.clocks.hse_hz;
        if self.spec.clocks.hse_bypass {
            stm32_emu::rcc::Hse::External(hz)
        } else {
            stm32_emu::rcc::Hse::Crystal(hz)
        }
    }

    /// The instrument's USART.
    pub fn instrument_usart(&self) -> UsartId {
        match self.spec.instrument.usart {
            Usart::Usart1 => UsartId::Usart1,
            Usart::Usart2 => UsartId::Usart2,
        }
    }

    /// The DIP switches' port and first pin, if the board has them.
    pub fn switches(&self) -> Option<(Port, u8)> {
        let first = self.spec.switches?.first;
        Some((port(first.port), first.number))
    }

    /// The flash offset (from 0x0800_0000) of settings sector A.
    pub fn settings_offset(&self) -> u32 {
        self.spec.flash.settings_bases[0] - board::memory::FLASH_BASE
    }
}

/// The emulator's GPIO port of a board pin's port.
pub fn port(p: board::pins::Port) -> Port {
    use board::pins::Port as B;
    match p {
        B::A => Port::A,
        B::B => Port::B,
        B::C => Port::C,
    }
}

/// What the node is set to before power-on: the MAC ID and data rate, by switches where the
/// board has them (not in the program position), and in the settings journal in every case, so
/// that a board without switches does not depend on its factory default.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeSetting {
    /// The MAC ID.
    pub mac: MacId,
    /// The data rate.
    pub rate: BaudRate,
    /// The bus-off interrupt setting (BOI, DeviceNet attribute 3), stored only.
    pub bus_off_interrupt: bool,
}

impl NodeSetting {
    /// The switch bits ("on" = 1, board/src/switches.rs): MAC on switches 1–6, the rate on 7–8.
    pub fn switch_bits(&self) -> u8 {
        let rate = match self.rate {
            BaudRate::Kbps125 => 0,
            BaudRate::Kbps250 => 1,
            BaudRate::Kbps500 => 2,
        };
        self.mac.as_raw() | rate << 6
    }

    /// The settings record (the board crate's own encoder), sequence 1. The last switch reading
    /// is the one the switches will show, so that the "switch changed" attributes stay clear.
    pub fn record(&self, has_switches: bool) -> [u8; board::settings::RECORD_LEN] {
        let settings = Settings {
            mac_id: self.mac,
            baud_rate: self.rate,
            bus_off_interrupt: self.bus_off_interrupt,
            last_switches: has_switches.then(|| self.switch_bits()),
            image: heapless::Vec::new(),
        };
        settings.encode(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setting(mac: u8, rate: BaudRate) -> NodeSetting {
        NodeSetting { mac: MacId::new(mac).expect("MAC"), rate, bus_off_interrupt: true }
    }

    #[test]
    fn switch_bits_put_the_mac_on_1_to_6_and_the_rate_on_7_and_8() {
        assert_eq!(setting(5, BaudRate::Kbps125).switch_bits(), 0b0000_0101);
        assert_eq!(setting(5, BaudRate::Kbps500).switch_bits(), 0b1000_0101);
        assert_eq!(setting(63, BaudRate::Kbps250).switch_bits(), 0b0111_1111);
    }

    #[test]
    fn the_record_is_the_board_crates_and_decodes_back() {
        let s = setting(5, BaudRate::Kbps250);
        let (decoded, sequence) = Settings::decode(&s.record(true)).expect("a valid record");
        assert_eq!(sequence, 1);
        assert_eq!((decoded.mac_id, decoded.baud_rate, decoded.bus_off_interrupt), (s.mac, s.rate, true));
        assert_eq!(decoded.last_switches, Some(s.switch_bits()));
        assert_eq!(Settings::decode(&s.record(false)).expect("valid").0.last_switches, None);
    }

    #[test]
    fn every_board_of_the_board_crate_is_known_by_its_feature() {
        let names: Vec<_> = BoardKind::all().iter().map(|b| b.name).collect();
        assert_eq!(names, ["reference", "olimex-p405", "olimex-p405-rs485", "nucleo-f446re"]);
        let nucleo = BoardKind::by_name("nucleo-f446re").expect("nucleo");
        assert_eq!(nucleo.chip(), stm32_emu::machine::Chip::Stm32F446);
        assert_eq!(nucleo.settings_offset(), 0x4000, "sector 1 (the firmware update's layout)");
        assert!(nucleo.switches().is_none());
        assert_eq!(BoardKind::by_name("reference").and_then(|b| b.switches()), Some((Port::B, 0)));
    }
}
