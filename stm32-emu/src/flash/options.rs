//! The option bytes (RM0090 §3.7 "Option bytes", table 16; FLASH_OPTCR's layout, §3.9.6): what
//! FLASH_OPTCR loads at every reset and what OPTSTRT programs. They are flash cells: they survive
//! resets and power cycles ([`super::Flash::option_bytes`], [`super::Flash::with_option_bytes`]).

/// The option bytes, in FLASH_OPTCR's bit positions: BOR_LEV (3:2), USER (7:5: WDG_SW,
/// nRST_STOP, nRST_STDBY), RDP (15:8), nWRP (27:16, one bit per sector, 0 = protected).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OptionBytes(u32);

/// The bits of FLASH_OPTCR that are option bytes (RM0090 §3.9.6; bit 4 is reserved).
const MASK: u32 = 0x0FFF_FFEC;
/// USER's WDG_SW: 1 software watchdog, 0 hardware watchdog (RM0090 §3.9.6).
const WDG_SW: u32 = 1 << 5;
/// RDP level 0 (RM0090 §3.7.3: 0xAA; 0xCC is level 2, anything else level 1).
const RDP_LEVEL_0: u8 = 0xAA;

impl OptionBytes {
    /// As delivered (RM0090 §3.9.6, OPTCR's reset value 0x0FFF_AAED without OPTLOCK): no sector
    /// write-protected, RDP level 0, software watchdog, BOR off.
    pub const FACTORY: OptionBytes = OptionBytes(0x0FFF_AAEC);

    /// The option bytes a FLASH_OPTCR value names (the control bits OPTLOCK and OPTSTRT, and
    /// the reserved bits, dropped).
    pub const fn from_optcr(optcr: u32) -> OptionBytes {
        OptionBytes(optcr & MASK)
    }

    /// As FLASH_OPTCR shows them (OPTLOCK and OPTSTRT clear).
    pub const fn optcr(self) -> u32 {
        self.0
    }

    /// Whether sector `sector` is write-protected (its nWRP bit is 0; RM0090 §3.7.4). Sectors
    /// 12 and up have no bit and are not protected.
    pub const fn write_protected(self, sector: u8) -> bool {
        sector < 12 && self.0 >> (16 + sector as u32) & 1 == 0
    }

    /// These option bytes with sector `sector` (0–11) write-protected or not.
    pub const fn with_write_protection(self, sector: u8, protected: bool) -> OptionBytes {
        if sector >= 12 {
            return self;
        }
        let bit = 1 << (16 + sector as u32);
        OptionBytes(if protected { self.0 & !bit } else { self.0 | bit })
    }

    /// The RDP byte (RM0090 §3.7.3: 0xAA level 0, 0xCC level 2, any other level 1).
    pub const fn read_protection(self) -> u8 {
        (self.0 >> 8) as u8
    }

    /// Whether the RDP byte names level 0 (no read protection).
    pub const fn read_protection_level_0(self) -> bool {
        self.read_protection() == RDP_LEVEL_0
    }

    /// Whether the hardware watchdog is selected (WDG_SW = 0: the IWDG runs from every reset,
    /// [`crate::iwdg::Iwdg::with_hardware_watchdog`]).
    pub const fn hardware_watchdog(self) -> bool {
        self.0 & WDG_SW == 0
    }
}

impl Default for OptionBytes {
    fn default() -> Self {
        OptionBytes::FACTORY
    }
}
