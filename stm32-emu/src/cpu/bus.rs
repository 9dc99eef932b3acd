//! The bus behind the CPU: the peripheral models by address, the System Control Space, the
//! flash memory array, and the time. The CPU emulator's memory callbacks land here; this is
//! also the [`Machine`] the models see.

use super::scs::{Masks, Scs};
use crate::periph::{ClockGate, Clocks, Machine, Nanos, Peripheral, ResetCause, Width};

/// The flash memory array's base address (RM0090 §2.3 "Memory map", §3.3 table 5).
pub const FLASH_BASE: u32 = 0x0800_0000;
/// The flash memory array's size: 1 MiB on the STM32F405RG and F446RE.
pub const FLASH_SIZE: u32 = 0x0010_0000;
/// The peripheral region: APB1 at 0x4000_0000 to AHB2's end below 0x6000_0000 (RM0090 §2.3,
/// table 1).
pub const PERIPHERAL_BASE: u32 = 0x4000_0000;
/// The peripheral region's size, bit-band alias included.
pub const PERIPHERAL_SIZE: u32 = 0x2000_0000;
/// The peripheral bit-band alias (PM0214 §2.2.5 "Bit-banding": 0x4200_0000–0x43FF_FFFF maps
/// each bit of 0x4000_0000–0x400F_FFFF to a word).
pub const PERIPHERAL_BIT_BAND: u32 = 0x4200_0000;
/// The end of the peripheral bit-band alias.
const PERIPHERAL_BIT_BAND_END: u32 = 0x4400_0000;
/// The private peripheral bus (PM0214 §2.2 figure 11): 0xE000_0000–0xE00F_FFFF.
pub const PPB_BASE: u32 = 0xE000_0000;
/// The private peripheral bus's size.
pub const PPB_SIZE: u32 = 0x0010_0000;
/// The System Control Space within the PPB (PM0214 §4.1).
pub const SCS_BASE: u32 = 0xE000_E000;

/// An access the machine could not complete: the emulated core would take a BusFault; the
/// machine stops and reports it instead.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BusError {
    /// The address accessed.
    pub address: u32,
    /// The address of the instruction that made the access.
    pub pc: u32,
    /// Whether it was a store.
    pub write: bool,
}

/// An access a model refused because its peripheral's RCC clock enable bit was clear
/// ([`Machine::unclocked_access`]; what the chip does, [`crate::periph`]'s module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnclockedAccess {
    /// The model's name (`"bxCAN1"`).
    pub peripheral: &'static str,
    /// The register's address.
    pub address: u32,
    /// The enable bit that was clear.
    pub gate: ClockGate,
    /// The address of the instruction that made the access.
    pub pc: u32,
    /// Whether it was a store (lost) rather than a load (which read 0).
    pub write: bool,
}

/// One peripheral model and the register block it answers.
struct Slot {
    base: u32,
    size: u32,
    /// `None` while the model is being called (it is lent out with the bus as its machine).
    model: Option<Box<dyn Peripheral>>,
}

/// Everything the CPU's memory callbacks reach.
pub struct Bus {
    slots: Vec<Slot>,
    /// The System Control Space (SCB, NVIC, SysTick).
    pub scs: Scs,
    /// The flash memory array; the CPU sees a copy, refreshed when `flash_dirty` is set.
    pub flash: Vec<u8>,
    /// The bytes of the flash array (a half-open range of offsets) that may have changed since
    /// the CPU's copy was refreshed; `None` when none did. Only this range is copied into the
    /// CPU's view: a whole copy per programmed word also threw away every translated block of
    /// code and made a 128 KiB swap take seconds.
    pub flash_dirty: Option<(usize, usize)>,
    /// Time at the start of the current slice of instructions.
    pub slice_start: Nanos,
    /// HCLK during the current slice.
    pub hclk: u32,
    /// The clocks last reported by the RCC model (or the reset clocks).
    clocks: Clocks,
    /// Instructions executed in the current slice.
    pub executed: u64,
    /// Instructions the current slice may execute.
    pub budget: u64,
    /// The address of the instruction being executed.
    pub pc: u32,
    /// The priority masks as last read from the core.
    pub masks: Masks,
    /// A bus error met in the current slice.
    pub error: Option<BusError>,
    /// The CPU exception number the emulator raised (its interrupt hook), if any.
    pub interrupt: Option<u32>,
    /// Time the models stalled the core in the current slice ([`Machine::stall`]).
    pub stalled: Nanos,
    /// When a model reported a power cut ([`Machine::power_cut`]), not yet taken by the machine.
    pub power_cut: Option<Nanos>,
    /// A system reset a model asked for ([`Machine::system_reset`]), not yet performed.
    pub reset_request: Option<ResetCause>,
    /// The model answering the current access reported a bus error ([`Machine::bus_error`]).
    model_bus_error: bool,
    /// The model answering the current access refused it, its clock gate closed
    /// ([`Machine::unclocked_access`]).
    model_unclocked: Option<ClockGate>,
    /// The first access a model refused for want of its clock; the machine stops on it.
    pub unclocked: Option<UnclockedAccess>,
    /// An access asked the core to stop after the current instruction (an exception became
    /// pending, a reset was requested, the flash array changed).
    pub stop_requested: bool,
}

impl Bus {
    /// A bus with no peripheral, the flash array erased (0xFF, RM0090 §3.6.3).
    pub fn new(irqs: usize) -> Bus {
        Bus {
            slots: Vec::new(),
            scs: Scs::new(irqs),
            flash: vec![0xFF; FLASH_SIZE as usize],
            flash_dirty: Some((0, FLASH_SIZE as usize)),
            slice_start: 0,
            hclk: Clocks::RESET.hclk,
            clocks: Clocks::RESET,
            executed: 0,
            budget: 0,
            pc: 0,
            masks: Masks::default(),
            error: None,
            model_bus_error: false,
            model_unclocked: None,
            unclocked: None,
            stalled: 0,
            power_cut: None,
            reset_request: None,
            interrupt: None,
            stop_requested: false,
        }
    }

    /// Adds a model answering `size` bytes from `base`. Refused (returned) when the block
    /// leaves the peripheral region or overlaps another model's.
    pub fn add(
        &mut self,
        base: u32,
        size: u32,
        model: Box<dyn Peripheral>,
    ) -> Result<(), Box<dyn Peripheral>> {
        let end = u64::from(base) + u64::from(size);
        let region = u64::from(PERIPHERAL_BASE)..=u64::from(PERIPHERAL_BASE) + u64::from(PERIPHERAL_SIZE);
        let below_alias = end <= u64::from(PERIPHERAL_BIT_BAND);
        let above_alias = base >= PERIPHERAL_BIT_BAND_END;
        let inside = size > 0
            && region.contains(&u64::from(base))
            && region.contains(&end)
            && (below_alias || above_alias);
        let overlaps = self
            .slots
            .iter()
            .any(|s| u64::from(base) < u64::from(s.base) + u64::from(s.size) && end > u64::from(s.base));
        if !inside || overlaps {
            return Err(model);
        }
        self.slots.push(Slot { base, size, model: Some(model) });
        self.slots.sort_by_key(|s| s.base);
        Ok(())
    }

    /// The program and erase operations of the FLASH model, if there is one.
    pub fn flash_operations(&self) -> Option<u64> {
        self.slots.iter().find_map(|s| s.model.as_ref()?.flash_operations())
    }

    /// Every model's name and block, in address order.
    pub fn blocks(&self) -> impl Iterator<Item = (u32, u32, &'static str)> + '_ {
        self.slots.iter().map(|s| (s.base, s.size, s.model.as_ref().map_or("?", |m| m.name())))
    }

    /// Time now: the slice's start plus the instructions executed in it at HCLK (one
    /// instruction per cycle, see [`crate::machine`]) plus the stalls in it.
    pub fn time(&self) -> Nanos {
        self.slice_start + self.executed * 1_000_000_000 / u64::from(self.hclk.max(1)) + self.stalled
    }

    fn slot_index(&self, address: u32) -> Option<usize> {
        let i = self.slots.partition_point(|s| s.base <= address).checked_sub(1)?;
        let slot = &self.slots[i];
        (address - slot.base < slot.size).then_some(i)
    }

    /// Calls `f` with model `i` and the bus as its machine, the model lent out meanwhile.
    /// A model that keeps the flash array is compared with the machine's copy afterwards when
    /// `changes_flash` (a store) or when an operation of the model started or ended (its next
    /// event came or went): not on every poll of a busy flag, a 1 MiB comparison each.
    fn with_model<R>(
        &mut self,
        i: usize,
        changes_flash: bool,
        f: impl FnOnce(&mut dyn Peripheral, &mut Bus) -> R,
    ) -> Option<R> {
        let mut model = self.slots[i].model.take()?;
        let busy = model.next_event().is_some();
        let result = f(model.as_mut(), self);
        if let Some(clocks) = model.clocks() {
            self.clocks = clocks;
        }
        if changes_flash || busy != model.next_event().is_some() {
            self.take_flash_array(model.as_ref());
        }
        self.slots[i].model = Some(model);
        Some(result)
    }

    /// Widens the range of flash offsets the CPU's copy must take again to `start..end`.
    pub fn mark_flash_dirty(&mut self, start: usize, end: usize) {
        self.flash_dirty = Some(match self.flash_dirty {
            Some((s, e)) => (s.min(start), e.max(end)),
            None => (start, end),
        });
    }

    /// Copies `model`'s flash array (if it keeps one) over the machine's copy where they differ.
    fn take_flash_array(&mut self, model: &dyn Peripheral) {
        if let Some(array) = model.flash_array() {
            if array.len() != self.flash.len() {
                return;
            }
            if let Some((start, end)) = changed_span(array, &self.flash) {
                self.flash[start..end].copy_from_slice(&array[start..end]);
                self.mark_flash_dirty(start, end);
                self.stop_requested = true;
            }
        }
    }

    /// A load from the peripheral region (`address` absolute, bit-band alias included).
    pub fn peripheral_read(&mut self, address: u32, width: Width) -> u32 {
        if (PERIPHERAL_BIT_BAND..PERIPHERAL_BIT_BAND_END).contains(&address) {
            let (word, bit) = bit_band_target(address);
            return (self.peripheral_read(word, Width::Word) >> bit) & 1;
        }
        let Some(i) = self.slot_index(address) else {
            self.fault(address, false);
            return 0;
        };
        let offset = address - self.slots[i].base;
        let now = self.time();
        let value = self
            .with_model(i, false, |model, bus| {
                model.advance(now, bus);
                model.read(offset, width, bus)
            })
            .unwrap_or(0);
        if core::mem::take(&mut self.model_bus_error) {
            self.fault(address, false);
        }
        self.note_unclocked(i, address, false);
        value
    }

    /// A store to the peripheral region (`address` absolute, bit-band alias included: a
    /// read-modify-write of the target word, PM0214 §2.2.5).
    pub fn peripheral_write(&mut self, address: u32, width: Width, value: u32) {
        if (PERIPHERAL_BIT_BAND..PERIPHERAL_BIT_BAND_END).contains(&address) {
            let (word, bit) = bit_band_target(address);
            let old = self.peripheral_read(word, Width::Word);
            let new = (old & !(1 << bit)) | ((value & 1) << bit);
            return self.peripheral_write(word, Width::Word, new);
        }
        let Some(i) = self.slot_index(address) else {
            return self.fault(address, true);
        };
        let offset = address - self.slots[i].base;
        let now = self.time();
        self.with_model(i, true, |model, bus| {
            model.advance(now, bus);
            model.write(offset, width, value, bus);
        });
        if core::mem::take(&mut self.model_bus_error) {
            self.fault(address, true);
        }
        self.note_unclocked(i, address, true);
    }

    /// Records the access to model `i` at `address` as refused for want of its clock, if the
    /// model said so, and asks the core to stop.
    fn note_unclocked(&mut self, i: usize, address: u32, write: bool) {
        let Some(gate) = self.model_unclocked.take() else { return };
        if self.unclocked.is_none() {
            let peripheral = self.slots[i].model.as_ref().map_or("?", |m| m.name());
            self.unclocked = Some(UnclockedAccess { peripheral, address, gate, pc: self.pc, write });
        }
        self.stop_requested = true;
    }

    /// A CPU store into the flash array (`offset` from [`FLASH_BASE`]), offered to the models
    /// until one takes it ([`Peripheral::flash_store`]). With no FLASH model the store is
    /// ignored, as a locked flash ignores it. The CPU's copy is refreshed afterwards either way.
    pub fn flash_store(&mut self, offset: u32, width: Width, value: u32) {
        for i in 0..self.slots.len() {
            if self.with_model(i, true, |model, bus| model.flash_store(offset, width, value, bus))
                == Some(true)
            {
                break;
            }
        }
        // The model's array is compared afterwards (`with_model`), which marks what changed.
        self.stop_requested = true;
    }

    /// Takes the flash contents from a model that keeps the array ([`Peripheral::flash_array`]).
    pub fn sync_flash_arrays(&mut self) {
        for slot in &self.slots {
            let array = slot.model.as_ref().and_then(|m| m.flash_array());
            if let Some(array) = array.filter(|a| a.len() == self.flash.len()) {
                self.flash.copy_from_slice(array);
                self.flash_dirty = Some((0, array.len()));
            }
        }
    }

    /// A programmer's download into the flash array: the machine's copy and the models that
    /// keep one ([`Peripheral::flash_load`]).
    pub fn load_flash(&mut self, offset: usize, bytes: &[u8]) {
        self.flash[offset..offset + bytes.len()].copy_from_slice(bytes);
        self.mark_flash_dirty(offset, offset + bytes.len());
        for slot in &mut self.slots {
            if let Some(model) = slot.model.as_mut() {
                model.flash_load(offset as u32, bytes);
            }
        }
    }

    /// A load from the private peripheral bus: the System Control Space answers; the rest of
    /// the PPB (ITM, DWT, FPB, TPIU) is not modelled and reads as zero.
    pub fn ppb_read(&mut self, address: u32, width: Width) -> u32 {
        if !(SCS_BASE..SCS_BASE + 0x1000).contains(&address) {
            return 0;
        }
        let offset = address - SCS_BASE;
        let word = self.scs.read(offset & !3);
        let shift = (offset & 3) * 8;
        match width {
            Width::Word => word,
            Width::Half => (word >> shift) & 0xFFFF,
            Width::Byte => (word >> shift) & 0xFF,
        }
    }

    /// A store to the private peripheral bus (see [`Bus::ppb_read`]).
    pub fn ppb_write(&mut self, address: u32, width: Width, value: u32) {
        if (SCS_BASE..SCS_BASE + 0x1000).contains(&address) {
            self.scs.write_sized(address - SCS_BASE, width.bytes(), value);
        }
    }

    fn fault(&mut self, address: u32, write: bool) {
        if self.error.is_none() {
            self.error = Some(BusError { address, pc: self.pc, write });
        }
        self.stop_requested = true;
    }

    /// Advances every model to `now`.
    pub fn advance_all(&mut self, now: Nanos) {
        for i in 0..self.slots.len() {
            self.with_model(i, false, |model, bus| model.advance(now, bus));
        }
    }

    /// Every model's name and [`Peripheral::next_event`], in address order (for diagnostics:
    /// what keeps a sleeping core from skipping ahead).
    pub fn next_events(&self) -> Vec<(&'static str, Option<Nanos>)> {
        self.slots.iter().filter_map(|s| s.model.as_ref()).map(|m| (m.name(), m.next_event())).collect()
    }

    /// The earliest [`Peripheral::next_event`] of the models.
    pub fn next_event(&self) -> Option<Nanos> {
        self.slots.iter().filter_map(|s| s.model.as_ref()?.next_event()).min()
    }

    /// Tells every model the cause of the system reset just performed.
    pub fn record_reset_cause(&mut self, cause: ResetCause) {
        for slot in &mut self.slots {
            if let Some(model) = slot.model.as_mut() {
                model.record_reset_cause(cause);
            }
        }
    }

    /// Resets every model.
    pub fn reset_all(&mut self, kind: crate::periph::ResetKind) {
        for slot in &mut self.slots {
            if let Some(model) = slot.model.as_mut() {
                model.reset(kind);
            }
        }
        self.clocks = Clocks::RESET;
        for slot in &self.slots {
            if let Some(clocks) = slot.model.as_ref().and_then(|m| m.clocks()) {
                self.clocks = clocks;
            }
        }
    }
}

/// The word address and bit a bit-band alias address names (PM0214 §2.2.5:
/// bit_word_addr = bit_band_base + byte_offset × 32 + bit_number × 4).
fn bit_band_target(address: u32) -> (u32, u32) {
    bit_band(PERIPHERAL_BIT_BAND, PERIPHERAL_BASE, address)
}

/// The word address and bit the alias address `address` names in the bit-band region at
/// `region` with its alias at `alias` (PM0214 §2.2.5).
pub fn bit_band(alias: u32, region: u32, address: u32) -> (u32, u32) {
    let offset = address - alias;
    let byte = offset / 32;
    let bit = (offset % 32) / 4 + (byte & 3) * 8;
    (region + (byte & !3), bit)
}

impl Machine for Bus {
    fn clocks(&self) -> Clocks {
        self.slots.iter().find_map(|s| s.model.as_ref()?.clocks()).unwrap_or(self.clocks)
    }

    fn clock_enabled(&self, gate: ClockGate) -> bool {
        // With no RCC model every gate is open.
        self.slots.iter().find_map(|s| s.model.as_ref()?.clock_gate(gate)).unwrap_or(true)
    }

    fn set_irq(&mut self, irq: u16, level: bool) {
        self.scs.set_line(irq, level);
        if level && self.scs.preempting(self.masks).is_some() {
            self.stop_requested = true;
        }
    }

    fn now(&self) -> Nanos {
        self.time()
    }

    fn power_cut(&mut self) {
        if self.power_cut.is_none() {
            self.power_cut = Some(self.time());
        }
        self.stop_requested = true;
    }

    fn flash_memory(&mut self) -> Option<&mut [u8]> {
        self.mark_flash_dirty(0, self.flash.len());
        self.stop_requested = true;
        Some(&mut self.flash)
    }

    fn bus_error(&mut self) {
        self.model_bus_error = true;
    }

    fn unclocked_access(&mut self, gate: ClockGate) {
        self.model_unclocked = Some(gate);
    }

    fn stall(&mut self, nanos: Nanos) {
        self.stalled += nanos;
    }

    fn fetches_from_flash(&self) -> bool {
        self.pc < FLASH_SIZE || (FLASH_BASE..FLASH_BASE + FLASH_SIZE).contains(&self.pc)
    }

    fn system_reset(&mut self, cause: ResetCause) {
        self.reset_request.get_or_insert(cause);
        self.stop_requested = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;
    use std::cell::RefCell;
    use std::rc::Rc;

    /// The stores a [`Log`] saw: (offset, value).
    type Stores = Rc<RefCell<Vec<(u32, u32)>>>;

    /// A register file that logs stores.
    struct Log(Stores, [u32; 4]);

    impl Peripheral for Log {
        fn name(&self) -> &'static str {
            "log"
        }
        fn read(&mut self, offset: u32, _: Width, _: &mut dyn Machine) -> u32 {
            self.1[(offset / 4) as usize]
        }
        fn write(&mut self, offset: u32, _: Width, value: u32, _: &mut dyn Machine) {
            self.0.borrow_mut().push((offset, value));
            self.1[(offset / 4) as usize] = value;
        }
    }

    fn bus_with_log() -> (Bus, Stores) {
        let log = Rc::new(RefCell::new(Vec::new()));
        let mut bus = Bus::new(82);
        assert!(bus.add(0x4002_3800, 16, Box::new(Log(log.clone(), [0; 4]))).is_ok());
        (bus, log)
    }

    #[rstest]
    // RCC_APB1ENR bit 25 (CAN1EN) through the alias, as stm32f4xx-hal's `bb::set` writes it:
    // 0x4200_0000 + (0x2_3808 * 32) + 25 * 4.
    #[case::word_two_bit_25(0x4200_0000 + 0x2_3808 * 32 + 25 * 4, 0x4002_3808, 25)]
    #[case::word_zero_bit_0(0x4200_0000 + 0x2_3800 * 32, 0x4002_3800, 0)]
    fn bit_band_alias(#[case] alias: u32, #[case] word: u32, #[case] bit: u32) {
        assert_eq!(bit_band_target(alias), (word, bit));
    }

    #[test]
    fn bit_band_write_is_read_modify_write() {
        let (mut bus, log) = bus_with_log();
        bus.peripheral_write(0x4002_3808, Width::Word, 0x0000_0001);
        bus.peripheral_write(0x4200_0000 + 0x2_3808 * 32 + 25 * 4, Width::Word, 1);
        assert_eq!(log.borrow().last(), Some(&(8, 0x0200_0001)));
        assert_eq!(bus.peripheral_read(0x4200_0000 + 0x2_3808 * 32 + 25 * 4, Width::Word), 1);
    }

    #[test]
    fn unmapped_peripheral_address_is_a_bus_error() {
        let (mut bus, _) = bus_with_log();
        bus.pc = 0x0800_1234;
        assert_eq!(bus.peripheral_read(0x4000_6400, Width::Word), 0);
        assert_eq!(bus.error, Some(BusError { address: 0x4000_6400, pc: 0x0800_1234, write: false }));
        assert!(bus.stop_requested);
    }

    #[rstest]
    #[case::overlap(0x4002_3808, 16)]
    #[case::outside_the_region(0x2000_0000, 16)]
    #[case::in_the_bit_band_alias(0x4200_0000, 16)]
    fn refused_blocks(#[case] base: u32, #[case] size: u32) {
        let (mut bus, log) = bus_with_log();
        assert!(bus.add(base, size, Box::new(Log(log, [0; 4]))).is_err());
    }

    #[test]
    fn without_rcc_the_reset_clocks_and_open_gates() {
        let (bus, _) = bus_with_log();
        assert_eq!(bus.clocks(), Clocks::RESET);
        assert!(bus.clock_enabled(ClockGate::Apb1(25)));
    }

    #[test]
    fn time_counts_instructions_at_hclk_and_stalls() {
        let mut bus = Bus::new(82);
        bus.slice_start = 1_000;
        bus.hclk = 16_000_000;
        bus.executed = 16;
        assert_eq!(bus.time(), 2_000, "16 cycles at 16 MHz: 1 µs");
        bus.stall(500);
        assert_eq!(bus.now(), 2_500);
    }

    #[test]
    fn byte_store_to_ipr_through_the_ppb() {
        let mut bus = Bus::new(82);
        bus.ppb_write(0xE000_E400 + 8, Width::Byte, 0xE0);
        assert_eq!(bus.ppb_read(0xE000_E408, Width::Byte), 0xE0);
        assert_eq!(bus.scs.priority(16 + 8), 0xE0);
    }
}

/// The smallest range `start..end` outside which `a` and `b` (of one length) are equal, or `None`
/// when they are equal: compared a block at a time from each end (a program changes one word, an
/// erase one sector, of a 1 MiB array).
fn changed_span(a: &[u8], b: &[u8]) -> Option<(usize, usize)> {
    const BLOCK: usize = 256;
    let blocks = a.len().div_ceil(BLOCK);
    let block = |i: usize| (i * BLOCK, ((i + 1) * BLOCK).min(a.len()));
    let differs = |i: usize| {
        let (s, e) = block(i);
        a[s..e] != b[s..e]
    };
    let first = (0..blocks).find(|&i| differs(i))?;
    let last = (first..blocks).rev().find(|&i| differs(i)).unwrap_or(first);
    let (s, _) = block(first);
    let (_, e) = block(last);
    let start = s + a[s..e].iter().zip(&b[s..e]).position(|(x, y)| x != y).unwrap_or(0);
    let end = e - a[s..e].iter().zip(&b[s..e]).rev().position(|(x, y)| x != y).unwrap_or(0);
    Some((start, end))
}

#[cfg(test)]
mod changed_span_tests {
    use super::changed_span;

    #[test]
    fn equal_arrays_have_no_span() {
        assert_eq!(changed_span(&[1u8; 1000], &[1u8; 1000]), None);
    }

    #[test]
    fn the_span_is_exactly_the_changed_bytes() {
        let a = vec![0xFFu8; 4096];
        for (start, end) in [(0, 1), (4095, 4096), (255, 257), (100, 3000), (1024, 1028)] {
            let mut b = a.clone();
            b[start] = 0;
            b[end - 1] = 0;
            assert_eq!(changed_span(&a, &b), Some((start, end)), "{start}..{end}");
        }
    }
}
