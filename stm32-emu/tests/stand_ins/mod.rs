//! Stand-ins for the peripheral models other engineers are writing (RCC, FLASH, GPIO, USART,
//! bxCAN): just enough register behaviour for the firmware to boot, and a record of what it
//! wrote. They check nothing; the real models do.

#![allow(dead_code)]

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;
use stm32_emu::periph::{ClockGate, Clocks, Machine, Peripheral, ResetKind, Width};

/// What the stand-ins saw, shared with the test.
#[derive(Debug, Default)]
pub struct Record {
    /// Every store: (model name, offset, value), in order.
    pub stores: Vec<(&'static str, u32, u32)>,
}

/// A shared [`Record`].
pub type Shared = Rc<RefCell<Record>>;

/// A plain register file with reset values; stores are recorded.
pub struct Registers {
    name: &'static str,
    reset: BTreeMap<u32, u32>,
    regs: BTreeMap<u32, u32>,
    record: Shared,
}

impl Registers {
    pub fn new(name: &'static str, reset: &[(u32, u32)], record: &Shared) -> Registers {
        let reset: BTreeMap<u32, u32> = reset.iter().copied().collect();
        Registers { name, regs: reset.clone(), reset, record: record.clone() }
    }
    fn get(&self, offset: u32) -> u32 {
        self.regs.get(&offset).copied().unwrap_or(0)
    }
    fn set(&mut self, offset: u32, value: u32) {
        self.regs.insert(offset, value);
    }
    /// Merges a narrow store into its word.
    fn store(&mut self, offset: u32, width: Width, value: u32) -> (u32, u32) {
        let word = offset & !3;
        let shift = (offset & 3) * 8;
        let mask = match width {
            Width::Byte => 0xFF << shift,
            Width::Half => 0xFFFF << shift,
            Width::Word => 0xFFFF_FFFF,
        };
        let merged = (self.get(word) & !mask) | ((value << shift) & mask);
        self.record.borrow_mut().stores.push((self.name, word, merged));
        (word, merged)
    }
    fn load(&self, offset: u32, width: Width) -> u32 {
        let shift = (offset & 3) * 8;
        let word = self.get(offset & !3) >> shift;
        match width {
            Width::Byte => word & 0xFF,
            Width::Half => word & 0xFFFF,
            Width::Word => word,
        }
    }
}

/// RCC: every ready flag follows its enable at once (HSI, HSE, PLL, LSI, LSE), SWS follows
/// SW, and the clocks are derived from CFGR and PLLCFGR (RM0090 §7.3).
pub struct Rcc {
    regs: Registers,
    hse_hz: u32,
}

impl Rcc {
    pub fn new(hse_hz: u32, record: &Shared) -> Rcc {
        // CR: HSION, HSIRDY, HSITRIM 16; PLLCFGR 0x2400_3010; CSR 0x0E00_0000 (RM0090 §7.3).
        let reset = [(0x00, 0x0000_0083), (0x04, 0x2400_3010), (0x74, 0x0E00_0000)];
        Rcc { regs: Registers::new("RCC", &reset, record), hse_hz }
    }
    fn pll_hz(&self) -> u32 {
        let pllcfgr = self.regs.get(0x04);
        let source = if pllcfgr & (1 << 22) != 0 { self.hse_hz } else { 16_000_000 };
        let m = (pllcfgr & 0x3F).max(1);
        let n = (pllcfgr >> 6) & 0x1FF;
        let p = (((pllcfgr >> 16) & 3) + 1) * 2;
        (u64::from(source) / u64::from(m) * u64::from(n) / u64::from(p)) as u32
    }
}

fn ahb_divider(hpre: u32) -> u32 {
    if hpre < 8 {
        1
    } else {
        [2, 4, 8, 16, 64, 128, 256, 512][(hpre - 8) as usize]
    }
}

fn apb_divider(ppre: u32) -> u32 {
    if ppre < 4 {
        1
    } else {
        1 << (ppre - 3)
    }
}

impl Peripheral for Rcc {
    fn name(&self) -> &'static str {
        "RCC stand-in"
    }
    fn read(&mut self, offset: u32, width: Width, _: &mut dyn Machine) -> u32 {
        self.regs.load(offset, width)
    }
    fn write(&mut self, offset: u32, width: Width, value: u32, _: &mut dyn Machine) {
        let (word, mut value) = self.regs.store(offset, width, value);
        match word {
            0x00 => {
                // HSIRDY, HSERDY, PLLRDY, PLLI2SRDY follow HSION, HSEON, PLLON, PLLI2SON.
                for on in [0, 16, 24, 26] {
                    value = (value & !(1 << (on + 1))) | ((value >> on & 1) << (on + 1));
                }
            }
            0x08 => value = (value & !0xC) | ((value & 3) << 2),
            0x70 => value = (value & !2) | ((value & 1) << 1),
            0x74 => value = (value & !2) | ((value & 1) << 1),
            _ => {}
        }
        self.regs.set(word, value);
    }
    fn reset(&mut self, _: ResetKind) {
        self.regs.regs = self.regs.reset.clone();
    }
    fn clocks(&self) -> Option<Clocks> {
        let cfgr = self.regs.get(0x08);
        let sysclk = match (cfgr >> 2) & 3 {
            1 => self.hse_hz,
            2 => self.pll_hz(),
            _ => 16_000_000,
        };
        let hclk = sysclk / ahb_divider((cfgr >> 4) & 0xF);
        Some(Clocks {
            sysclk,
            hclk,
            pclk1: hclk / apb_divider((cfgr >> 10) & 7),
            pclk2: hclk / apb_divider((cfgr >> 13) & 7),
        })
    }
    fn clock_gate(&self, gate: ClockGate) -> Option<bool> {
        let (offset, bit) = match gate {
            ClockGate::Ahb1(bit) => (0x30, bit),
            ClockGate::Apb1(bit) => (0x40, bit),
            ClockGate::Apb2(bit) => (0x44, bit),
        };
        Some(self.regs.get(offset) & (1 << bit) != 0)
    }
}

/// FLASH interface: ACR as written, LOCK/KEYR, never busy; program (PG) and sector erase
/// (SER + STRT) act on the machine's flash array at once (RM0090 §3.9).
pub struct Flash {
    regs: Registers,
    keys: u8,
}

impl Flash {
    pub fn new(record: &Shared) -> Flash {
        // CR: LOCK (RM0090 §3.9.7); OPTCR 0x0FFF_AAED.
        Flash { regs: Registers::new("FLASH", &[(0x10, 0x8000_0000), (0x14, 0x0FFF_AAED)], record), keys: 0 }
    }
}

/// Sector boundaries of the 1 MiB array (RM0090 §3.3 table 5).
fn sector_range(sector: u32) -> (usize, usize) {
    let kib = match sector {
        0..=3 => (sector * 16, 16),
        4 => (64, 64),
        5..=11 => (128 * (sector - 4), 128),
        _ => (0, 0),
    };
    (kib.0 as usize * 1024, (kib.0 + kib.1) as usize * 1024)
}

impl Peripheral for Flash {
    fn name(&self) -> &'static str {
        "FLASH stand-in"
    }
    fn read(&mut self, offset: u32, width: Width, _: &mut dyn Machine) -> u32 {
        self.regs.load(offset, width)
    }
    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        let (word, value) = self.regs.store(offset, width, value);
        match word {
            0x04 => {
                self.keys = match (self.keys, value) {
                    (0, 0x4567_0123) => 1,
                    (1, 0xCDEF_89AB) => {
                        let cr = self.regs.get(0x10) & !0x8000_0000;
                        self.regs.set(0x10, cr);
                        0
                    }
                    _ => 0,
                };
            }
            0x10 => {
                let locked = self.regs.get(0x10) & 0x8000_0000 != 0;
                if locked {
                    return;
                }
                self.regs.set(0x10, value);
                if value & (1 << 16) != 0 && value & (1 << 1) != 0 {
                    let (start, end) = sector_range((value >> 3) & 0xF);
                    if let Some(flash) = machine.flash_memory() {
                        flash[start..end].fill(0xFF);
                    }
                }
            }
            0x0C => {
                let sr = self.regs.get(0x0C) & !(value & 0xF3);
                self.regs.set(0x0C, sr);
            }
            _ => self.regs.set(word, value),
        }
    }
    fn flash_store(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) -> bool {
        let cr = self.regs.get(0x10);
        if cr & 0x8000_0001 == 1 {
            if let Some(flash) = machine.flash_memory() {
                let at = offset as usize;
                for (i, byte) in value.to_le_bytes().iter().take(width.bytes() as usize).enumerate() {
                    flash[at + i] &= byte;
                }
            }
        }
        true
    }
    fn reset(&mut self, _: ResetKind) {
        self.regs.regs = self.regs.reset.clone();
        self.keys = 0;
    }
}

/// GPIO port: plain registers; IDR reads `input`; BSRR sets and resets ODR.
pub struct Gpio {
    regs: Registers,
    input: u32,
}

impl Gpio {
    /// `reset`: MODER, OSPEEDR, PUPDR reset values (RM0090 §8.4: port A 0xA800_0000,
    /// 0x0C00_0000, 0x6400_0000; port B 0x0000_0280, 0x0000_00C0, 0x0000_0100; others 0).
    pub fn new(name: &'static str, reset: [u32; 3], input: u32, record: &Shared) -> Gpio {
        let reset = [(0x00, reset[0]), (0x08, reset[1]), (0x0C, reset[2])];
        Gpio { regs: Registers::new(name, &reset, record), input }
    }
}

impl Peripheral for Gpio {
    fn name(&self) -> &'static str {
        self.regs.name
    }
    fn read(&mut self, offset: u32, width: Width, _: &mut dyn Machine) -> u32 {
        if offset & !3 == 0x10 {
            return self.input >> ((offset & 3) * 8);
        }
        self.regs.load(offset, width)
    }
    fn write(&mut self, offset: u32, width: Width, value: u32, _: &mut dyn Machine) {
        let (word, value) = self.regs.store(offset, width, value);
        if word == 0x18 {
            let odr = (self.regs.get(0x14) | (value & 0xFFFF)) & !(value >> 16);
            self.regs.set(0x14, odr);
        } else {
            self.regs.set(word, value);
        }
    }
    fn reset(&mut self, _: ResetKind) {
        self.regs.regs = self.regs.reset.clone();
    }
}

/// USART: TXE and TC always set; DR stores recorded.
pub struct Usart {
    regs: Registers,
}

impl Usart {
    pub fn new(name: &'static str, record: &Shared) -> Usart {
        Usart { regs: Registers::new(name, &[(0x00, 0x00C0)], record) }
    }
}

impl Peripheral for Usart {
    fn name(&self) -> &'static str {
        self.regs.name
    }
    fn read(&mut self, offset: u32, width: Width, _: &mut dyn Machine) -> u32 {
        if offset & !3 == 0 {
            return 0x00C0;
        }
        self.regs.load(offset, width)
    }
    fn write(&mut self, offset: u32, width: Width, value: u32, _: &mut dyn Machine) {
        let (word, value) = self.regs.store(offset, width, value);
        self.regs.set(word, value);
    }
    fn reset(&mut self, _: ResetKind) {
        self.regs.regs = self.regs.reset.clone();
    }
}

/// bxCAN: MSR.INAK follows MCR.INRQ and SLAK follows SLEEP (outside init) at once; all three
/// mailboxes empty; everything else plain registers (RM0090 §32.9).
pub struct Bxcan {
    regs: Registers,
}

impl Bxcan {
    pub fn new(record: &Shared) -> Bxcan {
        // MCR 0x0001_0002, MSR 0x0000_0C02, TSR 0x1C00_0000, FMR 0x2A1C_0E01 (RM0090 §32.9).
        let reset = [(0x00, 0x0001_0002), (0x04, 0x0000_0C02), (0x08, 0x1C00_0000), (0x200, 0x2A1C_0E01)];
        Bxcan { regs: Registers::new("bxCAN1", &reset, record) }
    }
}

impl Peripheral for Bxcan {
    fn name(&self) -> &'static str {
        "bxCAN stand-in"
    }
    fn read(&mut self, offset: u32, width: Width, _: &mut dyn Machine) -> u32 {
        self.regs.load(offset, width)
    }
    fn write(&mut self, offset: u32, width: Width, value: u32, _: &mut dyn Machine) {
        let (word, value) = self.regs.store(offset, width, value);
        match word {
            0x00 => {
                self.regs.set(0x00, value);
                let inrq = value & 1;
                let slak = (value >> 1) & 1 & (inrq ^ 1);
                let msr = (self.regs.get(0x04) & !3) | inrq | (slak << 1);
                self.regs.set(0x04, msr);
            }
            // MSR, TSR: write-one-to-clear status bits; the stand-in keeps the mailboxes empty.
            0x04 | 0x08 => {}
            _ => self.regs.set(word, value),
        }
    }
    fn reset(&mut self, _: ResetKind) {
        self.regs.regs = self.regs.reset.clone();
    }
}
