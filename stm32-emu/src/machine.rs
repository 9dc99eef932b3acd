//! The machine: an STM32F405 or F446 whose core runs a firmware ELF on the peripheral models.
//!
//! ```no_run
//! # fn models() -> Vec<(u32, u32, Box<dyn stm32_emu::periph::Peripheral>)> { Vec::new() }
//! use stm32_emu::machine::{Chip, Stm32};
//! let mut mcu = Stm32::new(Chip::Stm32F405, [0x11; 12])?;
//! for (base, size, model) in models() {
//!     mcu.add_peripheral(base, size, model)?;
//! }
//! mcu.load_elf(&std::fs::read("target/thumbv7em-none-eabihf/firmware/slave-fw-firmware")?)?;
//! mcu.run_for(10_000_000)?; // 10 ms
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Time
//!
//! One instruction takes one HCLK cycle. The Cortex-M4 retires most instructions in one
//! cycle and loads, stores, branches and divisions in 2–12 (the Cortex-M4 Technical
//! Reference Manual, ARM DDI 0439, §3.3.1; flash wait states come on top), so
//! emulated time runs somewhat ahead of the instruction stream; what the firmware measures
//! with SysTick and what the models see agree with each other, which is what matters here.
//! HCLK is the RCC model's ([`Peripheral::clocks`]), or the 16 MHz HSI with no RCC model.
//! The machine runs the core in slices of at most [`Stm32::set_advance_period`] (10 µs by
//! default), calls [`Peripheral::advance`] on every model between slices and also before each
//! access to a model, and ends a slice early at SysTick's next interrupt, a model's
//! [`Peripheral::next_event`] and every access after which an exception preempts. An
//! exception that an MSR BASEPRI, MSR PRIMASK or CPSIE unmasks (no bus access) is taken at the
//! end of the current slice, at most one advance period late.
//!
//! # Flash
//!
//! The CPU fetches and loads from a copy of the flash array (at 0x0800_0000 and aliased at 0).
//! CPU stores into it go to the FLASH model ([`Peripheral::flash_store`]), which changes the
//! array through [`Machine::flash_memory`] or keeps its own ([`Peripheral::flash_array`],
//! [`Stm32::add_flash`] for [`crate::flash::Flash`]); the copy is refreshed before the next
//! instruction. The array survives resets and power cycles.
//!
//! # Sleep
//!
//! WFI, WFE and an idle `loop {}` (`b .`, what RTIC 2 runs with no idle task) do not spin:
//! time jumps to the next event (SysTick, a model's next event, at most 1 ms at a time) until
//! an exception would preempt (PM0214 §2.5.2 "Wakeup from WFI"; PRIMASK does not keep the
//! core asleep). SCR.SLEEPONEXIT sleeps on the return to thread mode.
//!
//! # Resets
//!
//! A power-on reset ([`Stm32::power_on_reset`], after [`Stm32::load_elfs`]) clears SRAM; a
//! system reset keeps it. A system reset comes from AIRCR.SYSRESETREQ or from a model
//! ([`Machine::system_reset`]: the IWDG's timeout, [`crate::iwdg`]); it is performed before the
//! next instruction, and its cause reaches the RCC model's RCC_CSR flags (SFTRSTF, IWDGRSTF).
//! The core restarts through the vector table at 0 (the flash alias: 0x0800_0000's), whatever
//! VTOR held.
//!
//! # Faults
//!
//! What would be a BusFault, UsageFault or HardFault on the chip (an access to an unmapped
//! address or to a peripheral address no model answers, an undefined instruction, a bad
//! EXC_RETURN) stops the run with a [`Fault`] naming the address and the instruction; the
//! firmware's fault handlers are not run. An access to a peripheral whose RCC clock enable bit
//! is clear is no fault on the chip (it reads 0, a write is lost, and the model answers so), but
//! the machine stops after it too, with [`Fault::Unclocked`] naming the peripheral, the register
//! and the enable bit: firmware that touches a peripheral it has not clocked is broken, and would
//! otherwise spin on a flag that never rises.

use crate::cpu::bus::{Bus, UnclockedAccess, FLASH_BASE};
use crate::cpu::core::{Core, CoreFault, MemoryMap, Return, SliceEnd};
use crate::cpu::scs::{exception, Scs};
use crate::periph::{Clocks, Machine, Nanos, Peripheral, ResetCause, ResetKind};
use std::fmt;
use unicorn_engine::RegisterARM;

/// The chips the machine models.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chip {
    /// STM32F405RG: 1 MiB flash, 112 + 16 KiB SRAM, 64 KiB CCM, 82 interrupt lines (RM0090
    /// §2.3.1, §12.2).
    Stm32F405,
    /// STM32F446RE: 512 KiB flash in the RE package (sectors 0–7; an access past 0x0807_FFFF
    /// is a bus fault), 128 KiB SRAM, no CCM, 97 interrupt lines (RM0390 §2.3, §10.2).
    Stm32F446,
}

impl Chip {
    fn memory(self) -> MemoryMap {
        match self {
            Chip::Stm32F405 => MemoryMap { sram: 128 * 1024, ccm: 64 * 1024, flash_kib: 1024 },
            Chip::Stm32F446 => MemoryMap { sram: 128 * 1024, ccm: 0, flash_kib: 512 },
        }
    }

    fn irqs(self) -> usize {
        match self {
            Chip::Stm32F405 => 82,
            Chip::Stm32F446 => 97,
        }
    }
}

/// Why the machine stopped or could not be built.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Fault {
    /// The core met a fault (see [`CoreFault`]).
    Core(CoreFault),
    /// The CPU emulator refused to be set up.
    Emulator(String),
    /// A peripheral block outside the peripheral region or overlapping another.
    Block {
        /// The block's base.
        base: u32,
        /// The model's name.
        name: &'static str,
    },
    /// The ELF file is not a 32-bit little-endian ARM executable, or has a loadable segment
    /// outside flash.
    Elf(String),
    /// Two loadable segments of the ELF files given to [`Stm32::load_elfs`] would be programmed
    /// over each other (a bootloader and an application linked into the same flash): nothing
    /// was programmed.
    ElfOverlap {
        /// The segment met first (the lower ELF index, or the lower address in one file).
        first: ElfSegment,
        /// The segment it overlaps.
        second: ElfSegment,
    },
    /// The power failed: a planned power cut of the FLASH model
    /// ([`crate::flash::Flash::plan_power_cut`]) happened. The machine stopped after the
    /// access; [`Stm32::power_on_reset`] powers it up again on the flash array as the cut left it.
    PowerCut {
        /// The time of the cut.
        at: Nanos,
    },
    /// The firmware accessed a peripheral whose RCC clock enable bit was clear: the model
    /// answered as the chip does (read 0, write lost, [`crate::periph`]'s module docs) and the
    /// machine stopped after the access, since firmware never means it (a clock it forgot to
    /// enable).
    Unclocked(UnclockedAccess),
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::Core(CoreFault::Bus { address, pc, write }) => {
                let kind = if *write { "store to" } else { "load from" };
                write!(f, "bus fault: {kind} {address:#010x}, where nothing answers, at pc {pc:#010x}")
            }
            Fault::Core(CoreFault::Undefined { pc }) => write!(f, "undefined instruction at pc {pc:#010x}"),
            Fault::Core(CoreFault::Breakpoint { pc }) => write!(f, "BKPT at pc {pc:#010x}"),
            Fault::Core(CoreFault::InvalidExceptionReturn { exc_return }) => {
                write!(f, "invalid exception return to {exc_return:#010x}")
            }
            Fault::Core(CoreFault::InvalidVector { exception, vector }) => {
                write!(f, "vector of exception {exception} is {vector:#010x}, not a Thumb address")
            }
            Fault::Core(CoreFault::NoCoprocessor { pc }) => {
                write!(f, "floating-point instruction with the FPU off in CPACR, before pc {pc:#010x}")
            }
            Fault::Core(CoreFault::Stacking { sp }) => {
                write!(f, "exception stacking at sp {sp:#010x} met no memory")
            }
            Fault::Core(CoreFault::Emulator { error, pc }) => {
                write!(f, "emulator error {error} at pc {pc:#010x}")
            }
            Fault::Emulator(e) => write!(f, "CPU emulator: {e}"),
            Fault::Block { base, name } => {
                write!(f, "{name} at {base:#010x}: outside the peripheral region or overlapping")
            }
            Fault::Elf(e) => write!(f, "ELF: {e}"),
            Fault::ElfOverlap { first, second } => write!(f, "{first} overlaps {second}"),
            Fault::PowerCut { at } => write!(f, "power cut at {at} ns (planned in the FLASH model)"),
            Fault::Unclocked(UnclockedAccess { peripheral, address, gate, pc, write }) => {
                let (kind, result) = if *write { ("store to", "lost") } else { ("load from", "read 0") };
                write!(
                    f,
                    "{kind} {peripheral} register {address:#010x} with its clock off ({gate} clear; {result}) at pc {pc:#010x}"
                )
            }
        }
    }
}

impl std::error::Error for Fault {}

/// A loadable segment of one of the ELF files given to [`Stm32::load_elfs`], as
/// [`Fault::ElfOverlap`] names it: the file's index in the list and the flash bytes its
/// contents take (`start..end`, load addresses).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ElfSegment {
    /// The file's index in the list (0: the first, e.g. the bootloader).
    pub elf: usize,
    /// The segment's load address.
    pub start: u32,
    /// The address after its last byte.
    pub end: u32,
}

/// `ELF 1's segment 0x08020000..0x08020400`.
impl fmt::Display for ElfSegment {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ELF {}'s segment {:#010x}..{:#010x}", self.elf, self.start, self.end)
    }
}

impl From<CoreFault> for Fault {
    fn from(fault: CoreFault) -> Fault {
        Fault::Core(fault)
    }
}

/// The longest time the machine skips at once while the core sleeps.
const MAX_SLEEP_STEP: Nanos = 1_000_000;

/// An STM32F4: the core, its memory, the System Control Space and the peripheral models.
pub struct Stm32 {
    core: Core,
    chip: Chip,
    /// Time since power-up; the bus's slice start between slices.
    now: Nanos,
    /// Nanoseconds × HCLK not yet turned into whole nanoseconds.
    remainder: u64,
    advance_period: Nanos,
    sleeping: bool,
    entries: Vec<u64>,
    returns: Vec<u64>,
    resets: u32,
    /// Instructions executed since the machine was built, and those of them in handler mode.
    instructions: u64,
    handler_instructions: u64,
}

impl Stm32 {
    /// A powered-off chip with an erased flash array and no peripheral model;
    /// `unique_id` is what the 96-bit unique ID register reads (RM0090 §39.1).
    pub fn new(chip: Chip, unique_id: [u8; 12]) -> Result<Stm32, Fault> {
        let bus = Bus::new(chip.irqs());
        let core = Core::new(chip.memory(), unique_id, bus).map_err(|e| Fault::Emulator(format!("{e:?}")))?;
        Ok(Stm32 {
            core,
            chip,
            now: 0,
            remainder: 0,
            advance_period: 10_000,
            sleeping: false,
            entries: vec![0; 16 + crate::cpu::scs::MAX_IRQS],
            returns: vec![0; 16 + crate::cpu::scs::MAX_IRQS],
            resets: 0,
            instructions: 0,
            handler_instructions: 0,
        })
    }

    /// The chip.
    pub const fn chip(&self) -> Chip {
        self.chip
    }

    /// Adds the FLASH interface model ([`crate::flash::Flash`], which keeps the array itself)
    /// at its register block (RM0090 §2.3 table 1: 0x4002_3C00). Its array becomes the
    /// machine's flash contents (a model made [`crate::flash::Flash::from_image`] brings a
    /// previous run's); CPU stores into flash go to [`crate::flash::Flash::array_write`]. On the
    /// F446 the model is given the chip's 512 KiB ([`crate::flash::ArraySize::Kib512`]).
    pub fn add_flash(&mut self, flash: crate::flash::Flash) -> Result<(), Fault> {
        let flash = match self.chip {
            Chip::Stm32F405 => flash,
            Chip::Stm32F446 => flash.with_size(crate::flash::ArraySize::Kib512),
        };
        let port = crate::cpu::flash_port::FlashPort::new(flash);
        self.add_peripheral(crate::flash::BASE, 0x400, Box::new(port))?;
        self.core.bus_mut().sync_flash_arrays();
        self.core.refresh_flash();
        Ok(())
    }

    /// Adds a peripheral model answering `size` bytes from `base` (its register block, RM0090
    /// §2.3 table 1). Accesses to the peripheral region that no model answers are bus faults.
    pub fn add_peripheral(&mut self, base: u32, size: u32, model: Box<dyn Peripheral>) -> Result<(), Fault> {
        self.core.bus_mut().add(base, size, model).map_err(|model| Fault::Block { base, name: model.name() })
    }

    /// Sets the longest time between two [`Peripheral::advance`] calls (10 µs by default).
    pub fn set_advance_period(&mut self, period: Nanos) {
        self.advance_period = period.max(1);
    }

    /// Writes `bytes` into the flash array at `offset` from 0x0800_0000 (a programmer's
    /// download: no FLASH model involved). Refused past the chip's flash (512 KiB on the F446).
    pub fn program_flash(&mut self, offset: u32, bytes: &[u8]) -> Result<(), Fault> {
        let start = offset as usize;
        let size = self.chip.memory().flash_bytes() as usize;
        let end = start.checked_add(bytes.len()).filter(|&e| e <= size);
        let Some(end) = end else {
            return Err(Fault::Elf(format!("{} bytes at flash offset {offset:#x} do not fit", bytes.len())));
        };
        let _ = end;
        self.core.bus_mut().load_flash(start, bytes);
        self.core.refresh_flash();
        Ok(())
    }

    /// The program and erase operations the FLASH model started so far (the index a planned
    /// power cut counts, [`crate::flash::Flash::plan_power_cut`]); `None` without one.
    pub fn flash_operations(&self) -> Option<u64> {
        self.core.bus().flash_operations()
    }

    /// The flash array (what a programmer would read back).
    pub fn flash(&self) -> &[u8] {
        &self.core.bus().flash
    }

    /// Programs the loadable segments of an ELF executable into flash at their load addresses
    /// (as a debug probe flashes it), then performs a power-on reset: [`Stm32::load_elfs`] with
    /// one file.
    pub fn load_elf(&mut self, elf: &[u8]) -> Result<(), Fault> {
        self.load_elfs(&[elf])
    }

    /// Programs the loadable segments of every ELF executable of `elfs` into flash at their
    /// load addresses (a probe flashing a bootloader and then the application it starts), then
    /// performs one power-on reset, through the vector table at 0x0800_0000 (the first file's,
    /// normally). Nothing is programmed if a file cannot be read, has a segment outside flash, or
    /// has a segment that overlaps another's ([`Fault::ElfOverlap`] names both).
    pub fn load_elfs(&mut self, elfs: &[&[u8]]) -> Result<(), Fault> {
        let flash_end = u64::from(FLASH_BASE) + u64::from(self.chip.memory().flash_bytes());
        let mut segments: Vec<(ElfSegment, &[u8])> = Vec::new();
        for (index, elf) in elfs.iter().enumerate() {
            let which = if elfs.len() > 1 { format!("ELF {index}: ") } else { String::new() };
            let loads = crate::cpu::elf::load_segments(elf).map_err(|e| Fault::Elf(format!("{which}{e}")))?;
            for (address, data) in loads {
                let end = u64::from(address) + data.len() as u64;
                let in_flash = address >= FLASH_BASE && end <= flash_end;
                if !in_flash {
                    return Err(Fault::Elf(format!("{which}segment at {address:#010x} is not in flash")));
                }
                segments.push((ElfSegment { elf: index, start: address, end: end as u32 }, data));
            }
        }
        segments.sort_by_key(|(segment, _)| (segment.start, segment.elf));
        for pair in segments.windows(2) {
            let (a, b) = (pair[0].0, pair[1].0);
            if b.start < a.end {
                let (first, second) = if (a.elf, a.start) <= (b.elf, b.start) { (a, b) } else { (b, a) };
                return Err(Fault::ElfOverlap { first, second });
            }
        }
        for (segment, data) in segments {
            self.program_flash(segment.start - FLASH_BASE, data)?;
        }
        self.power_on_reset()
    }

    /// Power-on reset (RM0090 §7.1.3): SRAM cleared, every model reset as at power-on, the
    /// core started from the vector table. Flash keeps its contents.
    pub fn power_on_reset(&mut self) -> Result<(), Fault> {
        self.core.clear_ram();
        self.reset(ResetKind::PowerOn, None)
    }

    /// System reset (RM0090 §7.1.2), as AIRCR.SYSRESETREQ requests it: SRAM kept, the RCC
    /// model's SFTRSTF set.
    pub fn system_reset(&mut self) -> Result<(), Fault> {
        self.reset(ResetKind::System, Some(ResetCause::Software))
    }

    /// A reset of `kind`; a system reset's `cause` goes to the models
    /// ([`Peripheral::record_reset_cause`]: RCC_CSR's flags).
    fn reset(&mut self, kind: ResetKind, cause: Option<ResetCause>) -> Result<(), Fault> {
        let bus = self.core.bus_mut();
        bus.scs.reset();
        bus.reset_request = None;
        bus.reset_all(kind);
        if let Some(cause) = cause {
            bus.record_reset_cause(cause);
        }
        self.sleeping = false;
        self.resets += 1;
        self.core.refresh_flash();
        self.core.reset()?;
        Ok(())
    }

    /// Resets performed since the machine was built (the power-on reset of
    /// [`Stm32::load_elf`] included).
    pub const fn resets(&self) -> u32 {
        self.resets
    }

    /// Time since power-up.
    pub const fn now(&self) -> Nanos {
        self.now
    }

    /// The program counter.
    pub fn pc(&self) -> u32 {
        self.core.reg(RegisterARM::PC)
    }

    /// A core register.
    pub fn register(&self, register: RegisterARM) -> u32 {
        self.core.reg(register)
    }

    /// Reads memory as the CPU sees it (flash, SRAM, CCM, system memory); `false` where
    /// nothing is mapped.
    pub fn read_memory(&self, address: u32, buf: &mut [u8]) -> bool {
        self.core.read_memory(address, buf)
    }

    /// Writes SRAM or CCM (a test's stand-in for what a debugger would write).
    pub fn write_memory(&mut self, address: u32, bytes: &[u8]) -> bool {
        self.core.write_memory(address, bytes)
    }

    /// Reads a peripheral register word as a debugger would (the model's read side effects
    /// included); `None` where no model answers.
    pub fn read_peripheral(&mut self, address: u32) -> Option<u32> {
        let bus = self.core.bus_mut();
        let before = bus.error;
        let unclocked = bus.unclocked;
        let value = bus.peripheral_read(address, crate::periph::Width::Word);
        let missing = bus.error != before;
        bus.error = before;
        // A debugger's read of an unclocked peripheral reads 0 too, but is not the firmware's.
        bus.unclocked = unclocked;
        bus.stop_requested = false;
        (!missing).then_some(value)
    }

    /// Lends the machine, as its models see it ([`Machine`]: clocks, interrupt lines to the
    /// NVIC, the time, which is [`Stm32::now`] between runs), to `f`: for a world outside the
    /// chip that drives a model's outside through a handle of its own, e.g. a CAN bus calling
    /// the bxCAN model's bus side ([`crate::bxcan::Bxcan::poll_transmit`],
    /// [`crate::bxcan::Bxcan::on_wire`]) between runs. An interrupt line `f` raises is taken
    /// at the start of the next run.
    pub fn with_machine<R>(&mut self, f: impl FnOnce(&mut dyn Machine) -> R) -> R {
        f(self.core.bus_mut())
    }

    /// The System Control Space (SCB, NVIC, SysTick), for inspection.
    pub fn scs(&self) -> &Scs {
        &self.core.bus().scs
    }

    /// How many times exception `number` was entered (tail chains included).
    pub fn exceptions_taken(&self, number: u16) -> u64 {
        self.entries.get(usize::from(number)).copied().unwrap_or(0)
    }

    /// How many times exception `number`'s handler returned (into a tail chain included).
    pub fn exceptions_returned(&self, number: u16) -> u64 {
        self.returns.get(usize::from(number)).copied().unwrap_or(0)
    }

    /// Instructions the core executed since the machine was built (the machine's own count,
    /// one per instruction the emulator ran; time advances one HCLK cycle for each, see the
    /// [module docs](self)). Sleep adds none.
    pub const fn instructions(&self) -> u64 {
        self.instructions
    }

    /// The part of [`Stm32::instructions`] executed in handler mode (an exception or interrupt
    /// handler active: with RTIC, every task of an application without an idle task). A slice
    /// of instructions never spans an exception entry or return, so each is counted whole in
    /// one mode or the other. Exception entry and return themselves (stacking, vector fetch,
    /// 12 cycles or more on a Cortex-M4) are not instructions and are not counted; see
    /// [`Stm32::exceptions_taken`].
    pub const fn handler_instructions(&self) -> u64 {
        self.handler_instructions
    }

    /// Counts `executed` instructions of the slice that just ran in the mode it ran in.
    fn count_instructions(&mut self, executed: u64) {
        self.instructions += executed;
        if self.core.bus().scs.current() != 0 {
            self.handler_instructions += executed;
        }
    }

    /// Whether the core sleeps (WFI, WFE, an idle loop).
    pub const fn sleeping(&self) -> bool {
        self.sleeping
    }

    /// The clocks in force (the RCC model's, or the reset clocks).
    pub fn clocks(&self) -> Clocks {
        self.core.bus().clocks()
    }

    /// Runs for `duration` nanoseconds of emulated time.
    pub fn run_for(&mut self, duration: Nanos) -> Result<(), Fault> {
        let end = self.now.saturating_add(duration);
        while self.now < end {
            self.step(end)?;
        }
        Ok(())
    }

    /// Runs until `done` holds (checked between slices) or `limit` nanoseconds have passed;
    /// returns whether `done` held.
    pub fn run_until(&mut self, limit: Nanos, mut done: impl FnMut(&Stm32) -> bool) -> Result<bool, Fault> {
        let end = self.now.saturating_add(limit);
        while self.now < end {
            if done(self) {
                return Ok(true);
            }
            self.step(end)?;
        }
        Ok(done(self))
    }

    /// One step: a pending system reset, an exception to take, then a slice of instructions
    /// or of sleep.
    fn step(&mut self, end: Nanos) -> Result<(), Fault> {
        // The machine stays stopped on an unclocked access (as on a bus error).
        if let Some(access) = self.core.bus().unclocked {
            return Err(Fault::Unclocked(access));
        }
        if self.core.bus_mut().scs.take_reset_request() {
            return self.system_reset();
        }
        if let Some(cause) = self.core.bus_mut().reset_request.take() {
            return self.reset(ResetKind::System, Some(cause));
        }
        if self.take_exception()? {
            // The handler's first instruction is the next slice's (a caller sees the entry).
            return Ok(());
        }
        if self.sleeping {
            return self.sleep(end);
        }
        let budget = self.slice_budget(end);
        let outcome = self.core.run(budget);
        let executed = self.core.bus().executed;
        self.count_instructions(executed);
        self.account(executed);
        self.core.refresh_flash();
        if let Some(at) = self.core.bus_mut().power_cut.take() {
            return Err(Fault::PowerCut { at });
        }
        let outcome = outcome?;
        if let Some(access) = self.core.bus().unclocked {
            return Err(Fault::Unclocked(access));
        }
        if self.core.fp_used_while_disabled() {
            return Err(Fault::Core(CoreFault::NoCoprocessor { pc: self.pc() }));
        }
        match outcome {
            SliceEnd::Stopped => {
                if executed >= budget && self.core.at_idle_loop() {
                    self.sleeping = true;
                }
            }
            SliceEnd::Sleep => self.sleeping = true,
            SliceEnd::SupervisorCall => self.core.bus_mut().scs.set_pending(exception::SV_CALL),
            SliceEnd::ExceptionReturn(exc_return) => {
                let returning = self.core.bus().scs.current();
                let to = self.core.return_from_exception(exc_return)?;
                if let Some(count) = self.returns.get_mut(usize::from(returning)) {
                    *count += 1;
                }
                self.after_return(to);
            }
        }
        Ok(())
    }

    fn after_return(&mut self, to: Return) {
        match to {
            Return::Chained(next) => self.count_entry(next),
            Return::Handler => {}
            Return::Thread => self.sleeping = self.core.bus().scs.sleep_on_exit(),
        }
    }

    fn count_entry(&mut self, number: u16) {
        if let Some(count) = self.entries.get_mut(usize::from(number)) {
            *count += 1;
        }
    }

    /// Takes the exception that preempts, if any, between instructions outside an IT block;
    /// returns whether it did.
    fn take_exception(&mut self) -> Result<bool, Fault> {
        let masks = self.core.masks();
        let scs = &self.core.bus().scs;
        if self.sleeping {
            if !scs.wakes(masks) {
                return Ok(false);
            }
            self.sleeping = false;
        }
        let Some(number) = scs.preempting(masks) else {
            return Ok(false);
        };
        // An exception in an IT block would need ITSTATE in the frame, which unicorn keeps
        // consistent only between blocks: run the block out first (at most 4 instructions).
        for _ in 0..4 {
            if !self.core.in_it_block() {
                break;
            }
            let outcome = self.core.run(1);
            let executed = self.core.bus().executed;
            self.count_instructions(executed);
            self.account(executed);
            outcome?;
        }
        self.core.enter_exception(number)?;
        self.count_entry(number);
        Ok(true)
    }

    /// Instructions the next slice may run: up to the advance period, SysTick's next
    /// interrupt, the models' next event and `end`, at one instruction per HCLK cycle.
    fn slice_budget(&self, end: Nanos) -> u64 {
        let hclk = u64::from(self.hclk());
        let bus = self.core.bus();
        let mut until = end.min(self.now + self.advance_period);
        if let Some(event) = bus.next_event() {
            until = until.min(event.max(self.now + 1));
        }
        let mut cycles = ((until - self.now) * hclk).div_ceil(1_000_000_000).max(1);
        if let Some(tick) = bus.scs.systick.cycles_to_interrupt() {
            cycles = cycles.min(tick);
        }
        cycles.max(1)
    }

    fn hclk(&self) -> u32 {
        self.core.bus().clocks().hclk.max(1)
    }

    /// Turns `cycles` at HCLK and the slice's stalls into time; counts SysTick; advances every
    /// model.
    fn account(&mut self, cycles: u64) {
        let hclk = u64::from(self.hclk());
        let stalled = core::mem::take(&mut self.core.bus_mut().stalled);
        // A stall is time the core does not execute but SysTick counts.
        let cycles_total = cycles + stalled * hclk / 1_000_000_000;
        let total = self.remainder + cycles * 1_000_000_000;
        self.now += total / hclk + stalled;
        self.remainder = total % hclk;
        let now = self.now;
        let bus = self.core.bus_mut();
        if bus.scs.systick.advance(cycles_total) {
            bus.scs.set_pending(exception::SYS_TICK);
        }
        bus.slice_start = now;
        bus.executed = 0;
        bus.hclk = hclk as u32;
        bus.advance_all(now);
    }

    /// Sleeps to the next event, SysTick's next interrupt, 1 ms or `end`, whichever is first.
    fn sleep(&mut self, end: Nanos) -> Result<(), Fault> {
        let hclk = u64::from(self.hclk());
        let bus = self.core.bus();
        let mut until = end.min(self.now + MAX_SLEEP_STEP);
        if let Some(event) = bus.next_event() {
            until = until.min(event.max(self.now + 1));
        }
        let mut cycles = ((until - self.now) * hclk).div_ceil(1_000_000_000).max(1);
        if let Some(tick) = bus.scs.systick.cycles_to_interrupt() {
            cycles = cycles.min(tick);
        }
        self.account(cycles);
        Ok(())
    }
}
