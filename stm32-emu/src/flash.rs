//! The embedded flash memory and its interface (RM0090 §3 "Embedded Flash memory interface",
//! registers §3.9, base 0x4002_3C00).
//!
//! One [`Flash`] holds the 1 MiB main memory array of the STM32F405RG (sectors 0–11 of 16, 16,
//! 16, 16, 64 and 7 × 128 KiB at 0x0800_0000, RM0090 §3.3 table 5) and the interface registers:
//! ACR (wait states and caches, §3.9.1), KEYR (§3.9.2), OPTKEYR (§3.9.3), SR (§3.9.4), CR
//! (§3.9.5) and OPTCR (§3.9.6). The register block is the [`Peripheral`]; the machine maps the
//! array through [`Flash::array_read`] / [`Flash::array_write`] (or the [`FlashArray`] adapter).
//!
//! What the manual refuses, the model refuses: CR stays locked until the KEY1/KEY2 sequence, a
//! wrong key raises a bus error and locks CR until the next reset (§3.6.1); an array write
//! without PG sets PGSERR, one whose width is not PSIZE's sets PGPERR, one across a 128-bit row
//! PGAERR, one into a write-protected sector WRPERR (§3.9.4). Programming only clears bits (NOR
//! flash), and a sector erase sets its bytes to 0xFF; BSY stays set for the datasheet's
//! programming or erase time ([`FlashTiming`]). An access that the hardware stalls while BSY is
//! set (a CR write, an array read or write, §3.6.1, §3.6.4) completes the operation at once and
//! adds the remaining busy time to [`Flash::take_stall`], for the machine to add to its clock.
//!
//! The STM32F446RE has 512 KiB, sectors 0–7 (RM0390 §3.3 table 4; [`ArraySize::Kib512`], which
//! [`crate::machine::Stm32::add_flash`] selects for that chip): an erase of sector 8–11 is refused
//! like one of 12–15 (PGSERR, [`FlashNote::NoSuchSector`]: what the chip does is not documented),
//! and a program beyond 0x0807_FFFF is a bus error, what an access to a reserved address is on
//! the chip (the machine maps no flash there, so a CPU load or store faults before it reaches
//! the model). PGSERR rather than a silent erase of nothing: firmware that names sector 8 on
//! this part is wrong, and the error flag makes the HAL's erase fail loudly.
//!
//! The option bytes ([`OptionBytes`]: nWRP, RDP, USER, BOR_LEV) are flash cells too: OPTSTRT
//! programs FLASH_OPTCR's values into them (at once: the model gives the operation no busy time),
//! every reset loads them back into OPTCR (RM0090 §3.7.1), and the write protection in force is
//! theirs, so an OPTCR write without OPTSTRT protects nothing and is gone at the next reset. RDP
//! is kept but not enforced (no debugger here), and a level 1 → 0 change does not erase the
//! array.
//!
//! The contents survive emulated power cycles: [`Flash::image`] and [`Flash::from_image`] for the
//! array, [`Flash::option_bytes`] and [`Flash::with_option_bytes`] for the option bytes. A
//! power cut can be planned at the n-th program or erase operation ([`Flash::plan_power_cut`]),
//! with that operation not started or torn half-way; the model then stops and reports it
//! ([`Flash::power_cut`]).

use crate::gpio::{lanes, read_lanes};
use crate::periph::{Machine, Nanos, Peripheral, ResetKind, Width};

mod options;
pub use options::OptionBytes;

/// The interface registers' base address (RM0090 §2.3 table 1).
pub const BASE: u32 = 0x4002_3C00;
/// The main memory array's address (RM0090 §3.3 table 5).
pub const ARRAY_BASE: u32 = 0x0800_0000;
/// The main memory array's size: 1 MiB on the STM32F405RG. (The model always keeps this many
/// bytes; on a smaller part, [`ArraySize`], the rest stays erased and out of reach.)
pub const ARRAY_SIZE: usize = 1024 * 1024;

/// How much of the array the part has (RM0090 §3.3 table 5, RM0390 §3.3 table 4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ArraySize {
    /// 1 MiB, sectors 0–11 (STM32F405RG).
    #[default]
    Mib1,
    /// 512 KiB, sectors 0–7 (STM32F446RE).
    Kib512,
}

impl ArraySize {
    /// The size in bytes.
    pub const fn bytes(self) -> usize {
        match self {
            ArraySize::Mib1 => ARRAY_SIZE,
            ArraySize::Kib512 => ARRAY_SIZE / 2,
        }
    }

    /// The number of sectors.
    pub const fn sectors(self) -> u8 {
        match self {
            ArraySize::Mib1 => 12,
            ArraySize::Kib512 => 8,
        }
    }
}
/// The flash global interrupt's position (RM0090 §12.2 table 61).
pub const IRQ: u16 = 4;
/// KEY1 of the unlock sequence (RM0090 §3.6.1).
pub const KEY1: u32 = 0x4567_0123;
/// KEY2 of the unlock sequence (RM0090 §3.6.1).
pub const KEY2: u32 = 0xCDEF_89AB;
/// OPTKEY1 of the option-byte unlock sequence (RM0090 §3.7.2).
pub const OPTKEY1: u32 = 0x0819_2A3B;
/// OPTKEY2 of the option-byte unlock sequence (RM0090 §3.7.2).
pub const OPTKEY2: u32 = 0x4C5D_6E7F;

/// Sector `n`'s offset in the array and its size (RM0090 §3.3 table 5).
pub const fn sector(n: u8) -> Option<(usize, usize)> {
    const K: usize = 1024;
    match n {
        0..=3 => Some((n as usize * 16 * K, 16 * K)),
        4 => Some((64 * K, 64 * K)),
        5..=11 => Some(((n as usize - 4) * 128 * K, 128 * K)),
        _ => None,
    }
}

/// Register offsets (RM0090 §3.9.8 "Flash interface register map").
mod reg {
    pub const ACR: u32 = 0x00;
    pub const KEYR: u32 = 0x04;
    pub const OPTKEYR: u32 = 0x08;
    pub const SR: u32 = 0x0C;
    pub const CR: u32 = 0x10;
    pub const OPTCR: u32 = 0x14;
}

/// FLASH_SR bits (RM0090 §3.9.4).
pub mod sr {
    /// End of operation (set only with EOPIE).
    pub const EOP: u32 = 1 << 0;
    /// Operation error (set only with ERRIE).
    pub const OPERR: u32 = 1 << 1;
    /// Write protection error.
    pub const WRPERR: u32 = 1 << 4;
    /// Programming alignment error.
    pub const PGAERR: u32 = 1 << 5;
    /// Programming parallelism error.
    pub const PGPERR: u32 = 1 << 6;
    /// Programming sequence error.
    pub const PGSERR: u32 = 1 << 7;
    /// Busy.
    pub const BSY: u32 = 1 << 16;
    /// The flags cleared by writing 1.
    pub const W1C: u32 = EOP | OPERR | WRPERR | PGAERR | PGPERR | PGSERR;
}

/// FLASH_CR bits (RM0090 §3.9.5).
pub mod cr {
    /// Programming.
    pub const PG: u32 = 1 << 0;
    /// Sector erase.
    pub const SER: u32 = 1 << 1;
    /// Mass erase.
    pub const MER: u32 = 1 << 2;
    /// Sector number, bits 6:3.
    pub const SNB: u32 = 0xF << 3;
    /// Program size, bits 9:8: x8, x16, x32, x64.
    pub const PSIZE: u32 = 3 << 8;
    /// Start an erase.
    pub const STRT: u32 = 1 << 16;
    /// End-of-operation interrupt enable.
    pub const EOPIE: u32 = 1 << 24;
    /// Error interrupt enable.
    pub const ERRIE: u32 = 1 << 25;
    /// Lock.
    pub const LOCK: u32 = 1 << 31;
}

/// The supply voltage range, which sets the wait states a clock needs (RM0090 §3.5.1 table 10)
/// and the parallelism the supply allows (§3.6.2, table "Program/erase parallelism").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoltageRange {
    /// 2.7–3.6 V (the adapter board, 3.3 V): 30 MHz per wait state.
    V27To36,
    /// 2.4–2.7 V: 24 MHz per wait state.
    V24To27,
    /// 2.1–2.4 V: 22 MHz per wait state.
    V21To24,
    /// 1.8–2.1 V: 20 MHz per wait state.
    V18To21,
}

impl VoltageRange {
    /// The wait states (FLASH_ACR.LATENCY) HCLK needs (RM0090 §3.5.1 table 10).
    pub const fn required_latency(self, hclk: u32) -> u32 {
        let step = match self {
            VoltageRange::V27To36 => 30_000_000,
            VoltageRange::V24To27 => 24_000_000,
            VoltageRange::V21To24 => 22_000_000,
            VoltageRange::V18To21 => 20_000_000,
        };
        hclk.saturating_sub(1) / step
    }

    /// The widest parallelism the range allows without VPP: x32 at 2.7 V and above, x16 from
    /// 2.1 V, x8 below (RM0090 §3.6.2). x64 needs VPP, which the board does not have.
    const fn max_psize(self) -> u32 {
        match self {
            VoltageRange::V27To36 => 2,
            VoltageRange::V24To27 | VoltageRange::V21To24 => 1,
            VoltageRange::V18To21 => 0,
        }
    }
}

/// How long programming and erasing keep BSY set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FlashTiming {
    /// One program access.
    pub program: Nanos,
    /// Erase of a 16 KiB sector, per PSIZE (x8, x16, x32, x64).
    pub erase_16k: [Nanos; 4],
    /// Erase of the 64 KiB sector, per PSIZE.
    pub erase_64k: [Nanos; 4],
    /// Erase of a 128 KiB sector, per PSIZE.
    pub erase_128k: [Nanos; 4],
    /// Mass erase, per PSIZE.
    pub mass_erase: [Nanos; 4],
}

impl FlashTiming {
    /// The STM32F405 datasheet's typical figures (DS8626 "Flash memory programming": word
    /// program 16 µs, sector erase 16 KiB 400/300/250 ms, 64 KiB 1200/700/550 ms, 128 KiB
    /// 2/1.3/1 s, mass erase 16/11/8 s at x8/x16/x32; x64 taken as x32). Quoted from memory: no
    /// source here confirms them.
    pub const DATASHEET: FlashTiming = FlashTiming {
        program: 16_000,
        erase_16k: [400_000_000, 300_000_000, 250_000_000, 250_000_000],
        erase_64k: [1_200_000_000, 700_000_000, 550_000_000, 550_000_000],
        erase_128k: [2_000_000_000, 1_300_000_000, 1_000_000_000, 1_000_000_000],
        mass_erase: [16_000_000_000, 11_000_000_000, 8_000_000_000, 8_000_000_000],
    };
    /// A thousandth of the datasheet's erase times and its program time: quick emulation.
    pub const FAST: FlashTiming = FlashTiming {
        program: 16_000,
        erase_16k: [400_000, 300_000, 250_000, 250_000],
        erase_64k: [1_200_000, 700_000, 550_000, 550_000],
        erase_128k: [2_000_000, 1_300_000, 1_000_000, 1_000_000],
        mass_erase: [16_000_000, 11_000_000, 8_000_000, 8_000_000],
    };
}

impl Default for FlashTiming {
    fn default() -> Self {
        FlashTiming::DATASHEET
    }
}

/// What a planned power cut does to the operation it hits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CutKind {
    /// The operation does not start: the array is as before it.
    Before,
    /// The operation is torn half-way: an erase leaves the first half of its sector erased and
    /// the rest as it was, a program clears only the lower half of the bits it would clear.
    /// (A real torn operation leaves undefined contents; this is one of them.)
    Torn,
}

/// A power cut that happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PowerCut {
    /// The operation's index (0 is the first program or erase since the model was built).
    pub operation: u64,
    /// What happened to it.
    pub kind: CutKind,
    /// The time of the cut.
    pub at: Nanos,
}

/// A misuse the part does not refuse but that breaks the product, recorded for the machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FlashNote {
    /// The array was read with fewer wait states than HCLK needs (RM0090 §3.5.1 table 10):
    /// the part would read wrong data.
    LatencyTooLow {
        /// HCLK at the read.
        hclk: u32,
        /// FLASH_ACR.LATENCY.
        latency: u32,
    },
    /// STRT with an erase of a sector the part does not have (SNB 12–15 on a 1 MiB part, 8–15
    /// on a 512 KiB one): RM0090 and RM0390 do not say what happens (RM0390's FLASH_CR lists
    /// SNB values for sectors 0–7 only; not retrieved here); the model raises PGSERR.
    NoSuchSector(u8),
    /// An array write while BSY was set: the bus stalled (RM0090 §3.6.4).
    Stalled,
}

impl std::fmt::Display for FlashNote {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FlashNote::LatencyTooLow { hclk, latency } => {
                write!(
                    f,
                    "flash read with {latency} wait states at HCLK {hclk} Hz (RM0090 table 10 asks more)"
                )
            }
            FlashNote::NoSuchSector(n) => write!(f, "erase of sector {n}, which this part does not have"),
            FlashNote::Stalled => f.write_str("flash array written while BSY: the bus stalled"),
        }
    }
}

/// The flash memory and its interface.
#[derive(Clone, Debug)]
pub struct Flash {
    array: Vec<u8>,
    size: ArraySize,
    /// The option bytes programmed (OPTCR's values at every reset).
    options: OptionBytes,
    timing: FlashTiming,
    voltage: VoltageRange,
    now: Nanos,
    acr: u32,
    cr: u32,
    sr: u32,
    optcr: u32,
    /// The unlock sequence: KEY1 seen.
    key1_seen: bool,
    optkey1_seen: bool,
    /// A wrong key locked CR until the next reset (RM0090 §3.6.1).
    locked_up: bool,
    busy_until: Nanos,
    /// The operation under way ends well: EOP rises at its end (with EOPIE).
    eop_pending: bool,
    operations: u64,
    plan: Option<(u64, CutKind)>,
    cut: Option<PowerCut>,
    bus_error: bool,
    stall: Nanos,
    notes: Vec<FlashNote>,
}

/// The image given to [`Flash::from_image`] is not the array's size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WrongImageSize(pub usize);

impl std::fmt::Display for WrongImageSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "a flash image of {} bytes, not {ARRAY_SIZE}", self.0)
    }
}

impl std::error::Error for WrongImageSize {}

/// FLASH_OPTCR's OPTLOCK and OPTSTRT (RM0090 §3.9.6).
const OPTLOCK: u32 = 1 << 0;
const OPTSTRT: u32 = 1 << 1;

impl Flash {
    /// An erased array (every byte 0xFF), registers at reset, the datasheet's timing, 3.3 V.
    pub fn new() -> Flash {
        Flash::with_array(vec![0xFF; ARRAY_SIZE])
    }

    /// The array as a previous power cycle left it ([`Flash::image`]).
    pub fn from_image(image: Vec<u8>) -> Result<Flash, WrongImageSize> {
        if image.len() != ARRAY_SIZE {
            return Err(WrongImageSize(image.len()));
        }
        Ok(Flash::with_array(image))
    }

    fn with_array(array: Vec<u8>) -> Flash {
        Flash {
            array,
            size: ArraySize::Mib1,
            options: OptionBytes::FACTORY,
            timing: FlashTiming::default(),
            voltage: VoltageRange::V27To36,
            now: 0,
            acr: 0,
            cr: cr::LOCK,
            sr: 0,
            optcr: OptionBytes::FACTORY.optcr() | OPTLOCK,
            key1_seen: false,
            optkey1_seen: false,
            locked_up: false,
            busy_until: 0,
            eop_pending: false,
            operations: 0,
            plan: None,
            cut: None,
            bus_error: false,
            stall: 0,
            notes: Vec::new(),
        }
    }

    /// Uses `timing` for programming and erasing.
    pub fn with_timing(mut self, timing: FlashTiming) -> Flash {
        self.timing = timing;
        self
    }

    /// A part with `size` of flash (the array keeps [`ARRAY_SIZE`] bytes; beyond `size` they
    /// stay as they are and out of reach).
    pub fn with_size(mut self, size: ArraySize) -> Flash {
        self.size = size;
        self
    }

    /// The part's flash size.
    pub fn size(&self) -> ArraySize {
        self.size
    }

    /// Option bytes as a previous power cycle left them ([`Flash::option_bytes`]); OPTCR shows
    /// them (locked), as after a reset.
    pub fn with_option_bytes(mut self, options: OptionBytes) -> Flash {
        self.options = options;
        self.optcr = options.optcr() | OPTLOCK;
        self
    }

    /// The option bytes programmed: what survives a power cycle with [`Flash::image`].
    pub fn option_bytes(&self) -> OptionBytes {
        self.options
    }

    /// Runs at `voltage` (the board: 2.7–3.6 V).
    pub fn with_voltage(mut self, voltage: VoltageRange) -> Flash {
        self.voltage = voltage;
        self
    }

    /// The array's contents, sector 0 first: what survives a power cycle.
    pub fn image(&self) -> &[u8] {
        &self.array
    }

    /// Writes `data` at `offset` of the array as a debug probe does before the program runs
    /// (the program's ELF): no register, no timing. Out-of-range bytes are dropped.
    pub fn load(&mut self, offset: usize, data: &[u8]) {
        let end = (offset + data.len()).min(ARRAY_SIZE);
        if offset < end {
            self.array[offset..end].copy_from_slice(&data[..end - offset]);
        }
    }

    /// Plans a power cut at the program or erase operation with index `operation` (0: the next
    /// one if none has run yet; counted since the model was built).
    pub fn plan_power_cut(&mut self, operation: u64, kind: CutKind) {
        self.plan = Some((operation, kind));
    }

    /// The program and erase operations started so far.
    pub fn operations(&self) -> u64 {
        self.operations
    }

    /// The power cut, once it happened: the model ignores every write after it; the machine
    /// stops the core and powers up again from [`Flash::image`].
    pub fn power_cut(&self) -> Option<PowerCut> {
        self.cut
    }

    /// Whether an access since the last call raised a bus error (a wrong key, RM0090 §3.6.1):
    /// the machine turns it into the core's BusFault / HardFault.
    pub fn take_bus_error(&mut self) -> bool {
        std::mem::take(&mut self.bus_error)
    }

    /// The time accesses since the last call stalled the bus while BSY was set.
    pub fn take_stall(&mut self) -> Nanos {
        std::mem::take(&mut self.stall)
    }

    /// The misuses recorded so far.
    pub fn notes(&self) -> &[FlashNote] {
        &self.notes
    }

    /// Whether FLASH_CR is locked.
    pub fn is_locked(&self) -> bool {
        self.cr & cr::LOCK != 0
    }

    fn busy(&self) -> bool {
        self.busy_until > self.now
    }

    /// Stalls until the operation in progress ends (RM0090 §3.6.1, §3.6.4: the bus stalls), the
    /// time left going to [`Flash::take_stall`]: an access while BSY, and an instruction fetch
    /// from the array after an access that started an operation while the code runs from flash
    /// ([`crate::cpu::flash_port`]).
    pub fn stall_until_idle(&mut self) {
        if self.busy() {
            self.stall += self.busy_until - self.now;
            self.now = self.busy_until;
        }
        self.settle();
    }

    fn update(&mut self, now: Nanos) {
        self.now = self.now.max(now);
        self.settle();
    }

    /// At the end of a successful operation EOP rises, if EOPIE is set (RM0090 §3.9.4).
    fn settle(&mut self) {
        if self.eop_pending && !self.busy() {
            self.eop_pending = false;
            if self.cr & cr::EOPIE != 0 {
                self.sr |= sr::EOP;
            }
        }
    }

    fn psize(&self) -> u32 {
        (self.cr & cr::PSIZE) >> 8
    }

    fn note(&mut self, note: FlashNote) {
        if !self.notes.contains(&note) {
            self.notes.push(note);
        }
    }

    /// Raises `flag`, and OPERR with it when ERRIE is set (RM0090 §3.9.4).
    fn error(&mut self, flag: u32) {
        self.sr |= flag;
        if self.cr & cr::ERRIE != 0 {
            self.sr |= sr::OPERR;
        }
    }

    fn finish_ok(&mut self, busy: Nanos) {
        self.busy_until = self.now + busy;
        self.eop_pending = true;
    }

    /// Counts an operation and applies a planned power cut: `Some(kind)` if it hits this one.
    fn next_operation(&mut self) -> Option<CutKind> {
        let index = self.operations;
        self.operations += 1;
        match self.plan {
            Some((at, kind)) if at == index => {
                self.cut = Some(PowerCut { operation: index, kind, at: self.now });
                Some(kind)
            }
            _ => None,
        }
    }

    fn write_protected(&self, sector: u8) -> bool {
        self.options.write_protected(sector)
    }

    /// Sector `n`'s offset and size, if the part has it.
    fn existing_sector(&self, n: u8) -> Option<(usize, usize)> {
        sector(n).filter(|_| n < self.size.sectors())
    }

    /// The sector holding array offset `offset`.
    fn sector_of(offset: usize) -> u8 {
        (0..12)
            .find(|&n| sector(n).is_some_and(|(start, len)| (start..start + len).contains(&offset)))
            .unwrap_or(12)
    }

    /// An erase started by STRT (RM0090 §3.6.3): SER with SNB, or MER.
    fn start_erase(&mut self) {
        let snb = ((self.cr & cr::SNB) >> 3) as u8;
        let psize = self.psize() as usize;
        let (range, busy) = if self.cr & cr::MER != 0 {
            // A mass erase with a protected sector is refused (RM0090 §3.6.3 does not say;
            // RM0090 §3.9.4's WRPERR covers "an erase ... to a write-protected part").
            if (0..self.size.sectors()).any(|n| self.write_protected(n)) {
                self.error(sr::WRPERR);
                return;
            }
            (0..self.size.bytes(), self.timing.mass_erase[psize])
        } else if self.cr & cr::SER != 0 {
            let Some((start, len)) = self.existing_sector(snb) else {
                self.note(FlashNote::NoSuchSector(snb));
                self.error(sr::PGSERR);
                return;
            };
            if self.write_protected(snb) {
                self.error(sr::WRPERR);
                return;
            }
            let busy = match len {
                0x4000 => self.timing.erase_16k[psize],
                0x10000 => self.timing.erase_64k[psize],
                _ => self.timing.erase_128k[psize],
            };
            (start..start + len, busy)
        } else {
            // STRT without SER or MER starts nothing (RM0090 §3.9.5 names no other use).
            return;
        };
        let range = match self.next_operation() {
            Some(CutKind::Before) => return,
            Some(CutKind::Torn) => range.start..range.start + range.len() / 2,
            None => range,
        };
        self.array[range].fill(0xFF);
        self.finish_ok(busy);
    }

    /// FLASH_CR (RM0090 §3.9.5): not writable while LOCK is set (only by the key sequence);
    /// a write while BSY stalls until the operation ends (§3.6.1).
    fn write_cr(&mut self, value: u32) {
        if self.is_locked() {
            return;
        }
        self.stall_until_idle();
        // Bits 15:10, 23:17 and 30:26 are reserved; SNB is 4 bits on the STM32F405.
        const WRITABLE: u32 =
            cr::PG | cr::SER | cr::MER | cr::SNB | cr::PSIZE | cr::EOPIE | cr::ERRIE | cr::LOCK;
        self.cr = value & WRITABLE;
        if value & cr::STRT != 0 {
            self.start_erase();
        }
    }

    /// FLASH_KEYR (RM0090 §3.6.1, §3.9.2): KEY1 then KEY2 unlocks CR; any other write is a
    /// wrong sequence: a bus error, and CR locked until the next reset. A write while CR is
    /// already unlocked is taken as a wrong sequence too (the manual does not name the case).
    fn write_keyr(&mut self, value: u32) {
        match (self.locked_up, self.is_locked(), self.key1_seen, value) {
            (false, true, false, KEY1) => self.key1_seen = true,
            (false, true, true, KEY2) => {
                self.key1_seen = false;
                self.cr &= !cr::LOCK;
            }
            _ => {
                self.key1_seen = false;
                self.locked_up = true;
                self.cr |= cr::LOCK;
                self.bus_error = true;
            }
        }
    }

    /// FLASH_OPTKEYR (RM0090 §3.7.2, §3.9.3): OPTKEY1 then OPTKEY2 clears OPTLOCK; a wrong
    /// sequence is a bus error, as for KEYR.
    fn write_optkeyr(&mut self, value: u32) {
        match (self.optkey1_seen, value) {
            (false, OPTKEY1) if self.optcr & 1 != 0 => self.optkey1_seen = true,
            (true, OPTKEY2) => {
                self.optkey1_seen = false;
                self.optcr &= !1;
            }
            _ => {
                self.optkey1_seen = false;
                self.bus_error = true;
            }
        }
    }

    /// FLASH_OPTCR (RM0090 §3.9.6), writable while OPTLOCK is clear. OPTSTRT programs the
    /// register's values into the option bytes, at once (no busy time), unless an operation is
    /// under way (§3.7.2: BSY must be clear; the model then ignores OPTSTRT).
    fn write_optcr(&mut self, value: u32) {
        if self.optcr & OPTLOCK != 0 {
            return;
        }
        self.optcr = OptionBytes::from_optcr(value).optcr() | value & OPTLOCK;
        if value & OPTSTRT != 0 && !self.busy() {
            self.options = OptionBytes::from_optcr(value);
        }
    }

    fn read_register(&mut self, offset: u32) -> u32 {
        match offset {
            reg::ACR => self.acr,
            reg::SR => self.sr | if self.busy() { sr::BSY } else { 0 },
            reg::CR => self.cr,
            reg::OPTCR => self.optcr,
            _ => 0,
        }
    }

    fn irq_level(&self) -> bool {
        self.cr & cr::EOPIE != 0 && self.sr & sr::EOP != 0
            || self.cr & cr::ERRIE != 0 && self.sr & sr::OPERR != 0
    }

    /// Reads the array (the CPU's fetches and loads): checks the wait states against HCLK
    /// (RM0090 §3.5.1 table 10) and stalls while an operation is under way (§3.6.4).
    pub fn array_read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        self.update(machine.now());
        self.stall_until_idle();
        let hclk = machine.clocks().hclk;
        let latency = self.acr & 7;
        if latency < self.voltage.required_latency(hclk) {
            self.note(FlashNote::LatencyTooLow { hclk, latency });
        }
        let at = offset as usize;
        (0..width.bytes() as usize)
            .map(|i| self.array.get(at + i).copied().unwrap_or(0))
            .rev()
            .fold(0, |word, byte| word << 8 | u32::from(byte))
    }

    /// Writes the array: a program operation (RM0090 §3.6.4) when PG is set, the access width
    /// is PSIZE's and the data stays within one 128-bit row; else the error flag the manual
    /// names and no change. Programming only clears bits: the new contents are the old AND the
    /// data. The F4 does not check that the target was erased (no ECC on this part; the HAL
    /// implements `MultiwriteNorFlash` on it), so programming over data ANDs into it; RM0090
    /// does not say so explicitly.
    pub fn array_write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        self.update(machine.now());
        if self.cut.is_some() {
            return;
        }
        if self.busy() {
            self.note(FlashNote::Stalled);
            self.stall_until_idle();
        }
        self.program(offset as usize, width, value);
        machine.set_irq(IRQ, self.irq_level());
    }

    fn program(&mut self, at: usize, width: Width, value: u32) {
        let bytes = width.bytes() as usize;
        let psize_bytes = 1usize << self.psize();
        if self.cr & cr::PG == 0 {
            return self.error(sr::PGSERR);
        }
        if bytes != psize_bytes || self.psize() > self.voltage.max_psize() {
            return self.error(sr::PGPERR);
        }
        if at + bytes > self.size.bytes() {
            // Past the part's flash the memory map is reserved (RM0390's memory map): a bus error.
            self.bus_error = true;
            return;
        }
        if at % 16 + bytes > 16 {
            return self.error(sr::PGAERR);
        }
        if self.write_protected(Flash::sector_of(at)) {
            return self.error(sr::WRPERR);
        }
        let mut clear = !value & (u32::MAX >> (32 - 8 * bytes));
        match self.next_operation() {
            Some(CutKind::Before) => return,
            Some(CutKind::Torn) => clear &= torn_half(clear),
            None => {}
        }
        for i in 0..bytes {
            self.array[at + i] &= !(clear >> (8 * i)) as u8;
        }
        self.finish_ok(self.timing.program);
    }
}

/// The lower half of the set bits of `bits` (the ones a torn program still clears).
fn torn_half(bits: u32) -> u32 {
    let keep = bits.count_ones().div_ceil(2);
    let mut out = 0;
    let mut left = bits;
    for _ in 0..keep {
        let low = left & left.wrapping_neg();
        out |= low;
        left &= !low;
    }
    out
}

impl Default for Flash {
    fn default() -> Self {
        Flash::new()
    }
}

impl Peripheral for Flash {
    fn name(&self) -> &'static str {
        "FLASH"
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        self.update(machine.now());
        read_lanes(self.read_register(offset & !3), offset, width)
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        self.update(machine.now());
        if self.cut.is_some() {
            return;
        }
        let (offset, mask, value) = lanes(offset, width, value);
        let merged = |old: u32| old & !mask | value;
        match offset {
            // ACR: LATENCY 2:0, PRFTEN, ICEN, DCEN, ICRST, DCRST (RM0090 §3.9.1).
            reg::ACR => self.acr = merged(self.acr) & 0x1F07,
            reg::KEYR => self.write_keyr(value),
            reg::OPTKEYR => self.write_optkeyr(value),
            reg::SR => self.sr &= !(value & sr::W1C),
            reg::CR => {
                let old = self.cr;
                self.write_cr(merged(old));
            }
            reg::OPTCR => {
                let old = self.optcr;
                self.write_optcr(merged(old));
            }
            _ => {}
        }
        machine.set_irq(IRQ, self.irq_level());
    }

    fn advance(&mut self, now: Nanos, machine: &mut dyn Machine) {
        self.update(now);
        machine.set_irq(IRQ, self.irq_level());
    }

    /// A reset puts the registers to their reset values (ACR 0, CR 0x8000_0000 locked, SR 0,
    /// RM0090 §3.9) and ends a bus-error lock-up; the array keeps its contents. An operation
    /// under way keeps the contents it reached (the model applies them at its start).
    fn reset(&mut self, kind: ResetKind) {
        let _ = kind;
        self.acr = 0;
        self.cr = cr::LOCK;
        self.sr = 0;
        // OPTCR loads the option bytes at reset (RM0090 §3.7.1), locked.
        self.optcr = self.options.optcr() | OPTLOCK;
        self.key1_seen = false;
        self.optkey1_seen = false;
        self.locked_up = false;
        self.busy_until = self.now;
        self.eop_pending = false;
    }

    fn next_event(&self) -> Option<Nanos> {
        self.busy().then_some(self.busy_until)
    }
}

/// The flash array as a [`Peripheral`] of its own, for a machine that maps every region to one:
/// reads and writes go to [`Flash::array_read`] and [`Flash::array_write`].
pub struct FlashArray<'a>(pub &'a mut Flash);

impl Peripheral for FlashArray<'_> {
    fn name(&self) -> &'static str {
        "flash array"
    }

    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32 {
        self.0.array_read(offset, width, machine)
    }

    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) {
        self.0.array_write(offset, width, value, machine)
    }
}

#[cfg(test)]
mod tests;
