//! The Cortex-M4 core: unicorn's ARMv7-M instruction set emulation, with the memory map, the
//! bus callbacks, and the exception model unicorn leaves out.
//!
//! Unicorn (QEMU's TCG without QEMU's boards) runs M-profile code but has no NVIC: it never
//! takes an interrupt and, outside its own exception entry, treats a branch to EXC_RETURN as
//! an exception it cannot handle (raising QEMU's EXCP_EXCEPTION_EXIT or a prefetch abort at
//! 0xFFFF_FFxx). Projects running Cortex-M firmware on unicorn (fuzzware, HALucinator's
//! unicorn back end, qiling) therefore do exception entry and return themselves, outside the
//! emulated instruction stream; so does this core:
//!
//! - unicorn is kept in thread mode (its IPSR 0) the whole time; the exception being handled
//!   is the model's ([`super::scs::Scs::current`]). MRS of IPSR therefore reads 0, which the firmware
//!   does not do; ICSR.VECTACTIVE is right.
//! - entry (PM0214 §2.3.7 "Exception entry and return"): the 8-word frame (R0–R3, R12, LR,
//!   return address, xPSR) or, when CONTROL.FPCA is set, the 26-word frame with S0–S15 and
//!   FPSCR, pushed on the stack in use, 8-byte aligned when CCR.STKALIGN is set (xPSR bit 9
//!   records the padding); LR = EXC_RETURN; the handler runs on MSP. Lazy stacking
//!   (FPCCR.LSPEN) is not modelled: the FP registers are stored at entry, which leaves the
//!   frame as lazy stacking would have left it by the handler's first FP instruction; FPCAR
//!   and LSPACT are not maintained.
//! - return: unicorn stops at the branch to 0xFFFF_FFxx (its interrupt hook); the frame is
//!   popped, CONTROL.SPSEL and FPCA restored from EXC_RETURN, PC from the frame. A pending
//!   exception that would preempt the context returned to is entered without popping and
//!   pushing again (tail chaining, PM0214 §2.3.7); the frame in memory is the same.
//! - the active handler's stack is MSP; a thread on PSP (CONTROL.SPSEL) is switched by
//!   writing CONTROL, which banks R13 inside unicorn.

use super::bus::{
    bit_band, Bus, FLASH_BASE, FLASH_SIZE, PERIPHERAL_BASE, PERIPHERAL_SIZE, PPB_BASE, PPB_SIZE,
};
use super::scs::Masks;
use crate::periph::Width;
use unicorn_engine::unicorn_const::{Arch, Mode};
use unicorn_engine::{uc_error, ArmCpuModel, HookType, MemType, Prot, RegisterARM, Unicorn};

/// QEMU's exception numbers, as unicorn's interrupt hook reports them.
pub mod excp {
    /// An undefined instruction (EXCP_UDEF).
    pub const UDEF: u32 = 1;
    /// SVC (EXCP_SWI).
    pub const SWI: u32 = 2;
    /// A prefetch abort (EXCP_PREFETCH_ABORT).
    pub const PREFETCH_ABORT: u32 = 3;
    /// A data abort (EXCP_DATA_ABORT).
    pub const DATA_ABORT: u32 = 4;
    /// BKPT (EXCP_BKPT).
    pub const BKPT: u32 = 7;
    /// A branch to EXC_RETURN (EXCP_EXCEPTION_EXIT).
    pub const EXCEPTION_EXIT: u32 = 8;
}

/// Where the memory of one chip lies (RM0090 §2.3 "Memory map", §2.3.1 "Embedded SRAM").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryMap {
    /// SRAM from 0x2000_0000, in bytes (SRAM1 and SRAM2 contiguous).
    pub sram: u32,
    /// Core-coupled memory from 0x1000_0000, in bytes (0 where there is none).
    pub ccm: u32,
    /// The flash size in KiB as the device's F_SIZE register at 0x1FFF_7A22 reads it (RM0090
    /// §39.2 "Flash size"); the CPU sees this much flash (at most [`FLASH_SIZE`]), and an access
    /// past it is a bus fault.
    pub flash_kib: u16,
}

impl MemoryMap {
    /// The flash the CPU sees, in bytes.
    pub const fn flash_bytes(self) -> u32 {
        let bytes = self.flash_kib as u32 * 1024;
        if bytes < FLASH_SIZE {
            bytes
        } else {
            FLASH_SIZE
        }
    }
}

/// SRAM's base address.
pub const SRAM_BASE: u32 = 0x2000_0000;
/// The SRAM bit-band alias (PM0214 §2.2.5).
pub const SRAM_BIT_BAND: u32 = 0x2200_0000;
/// The core-coupled memory's base address (RM0090 §2.3.1).
pub const CCM_BASE: u32 = 0x1000_0000;
/// The system memory block (bootloader, OTP, unique ID), read-only (RM0090 §3.3 table 5).
pub const SYSTEM_MEMORY_BASE: u32 = 0x1FFF_0000;
const SYSTEM_MEMORY_SIZE: u32 = 0x8000;
/// The 96-bit unique device ID (RM0090 §39.1 "Unique device ID register").
pub const UNIQUE_ID_ADDRESS: u32 = 0x1FFF_7A10;
const FLASH_SIZE_ADDRESS: u32 = 0x1FFF_7A22;

/// The registers stacked on exception entry, in frame order (PM0214 figure 12).
const FRAME_REGISTERS: [RegisterARM; 6] =
    [RegisterARM::R0, RegisterARM::R1, RegisterARM::R2, RegisterARM::R3, RegisterARM::R12, RegisterARM::LR];
const FP_REGISTERS: [RegisterARM; 16] = [
    RegisterARM::S0,
    RegisterARM::S1,
    RegisterARM::S2,
    RegisterARM::S3,
    RegisterARM::S4,
    RegisterARM::S5,
    RegisterARM::S6,
    RegisterARM::S7,
    RegisterARM::S8,
    RegisterARM::S9,
    RegisterARM::S10,
    RegisterARM::S11,
    RegisterARM::S12,
    RegisterARM::S13,
    RegisterARM::S14,
    RegisterARM::S15,
];
const CONTROL_SPSEL: u32 = 1 << 1;
const CONTROL_FPCA: u32 = 1 << 2;
const XPSR_T: u32 = 1 << 24;
const XPSR_IT: u32 = 0x0600_FC00;

/// Why the core could not go on. Each names the instruction's address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CoreFault {
    /// An access to an address with nothing behind it (a BusFault on the chip).
    Bus {
        /// The address accessed.
        address: u32,
        /// The instruction.
        pc: u32,
        /// A store.
        write: bool,
    },
    /// An undefined instruction (a UsageFault on the chip).
    Undefined {
        /// The instruction.
        pc: u32,
    },
    /// A BKPT instruction with no debugger attached (a HardFault on the chip).
    Breakpoint {
        /// The instruction.
        pc: u32,
    },
    /// An exception return with an EXC_RETURN the ARMv7-M architecture does not define, or
    /// in thread mode (an INVPC UsageFault on the chip).
    InvalidExceptionReturn {
        /// The value branched to.
        exc_return: u32,
    },
    /// A vector table entry without the Thumb bit (an INVSTATE UsageFault on the chip).
    InvalidVector {
        /// The exception.
        exception: u16,
        /// The entry.
        vector: u32,
    },
    /// A floating-point instruction while CPACR leaves CP10/CP11 disabled (a NOCP UsageFault on
    /// the chip, PM0214 §4.6.1). Detected after the slice that ran it (unicorn's FPU is always
    /// on; CONTROL.FPCA shows an FP instruction ran), so `pc` is where that slice stopped.
    NoCoprocessor {
        /// Where the slice stopped.
        pc: u32,
    },
    /// Stacking or unstacking met memory that is not there.
    Stacking {
        /// The stack pointer.
        sp: u32,
    },
    /// Another fault unicorn reported.
    Emulator {
        /// unicorn's error, as its number.
        error: u32,
        /// The instruction.
        pc: u32,
    },
}

/// How a slice of instructions ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SliceEnd {
    /// The budget ran out, or an access asked to stop (pending exception, reset, flash).
    Stopped,
    /// WFI or WFE: the core sleeps until an event.
    Sleep,
    /// A branch to EXC_RETURN.
    ExceptionReturn(u32),
    /// SVC: the SVCall exception is pending.
    SupervisorCall,
}

/// Where an exception return went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Return {
    /// Back to thread mode.
    Thread,
    /// Back to the handler it preempted.
    Handler,
    /// Straight into this pending exception's handler (tail chaining).
    Chained(u16),
}

/// The core: unicorn with the [`Bus`] as its data.
pub struct Core {
    uc: Unicorn<'static, Bus>,
    map: MemoryMap,
}

impl Core {
    /// A Cortex-M4 with the memory of `map`, the unique ID `unique_id` in system memory and
    /// `bus` behind it.
    pub fn new(map: MemoryMap, unique_id: [u8; 12], bus: Bus) -> Result<Core, uc_error> {
        let mut uc = Unicorn::new_with_data(Arch::ARM, Mode::THUMB | Mode::MCLASS, bus)?;
        uc.ctl_set_cpu_model(ArmCpuModel::CORTEX_M4 as i32)?;
        // The flash array and its alias at 0 (boot from main flash, RM0090 §2.4 "Boot
        // configuration", BOOT0 = 0): two copies refreshed together, never written by the CPU.
        let flash = u64::from(map.flash_bytes());
        uc.mem_map(u64::from(FLASH_BASE), flash, Prot::READ | Prot::EXEC)?;
        uc.mem_map(0, flash, Prot::READ | Prot::EXEC)?;
        uc.mem_map(u64::from(SRAM_BASE), u64::from(map.sram), Prot::ALL)?;
        if map.ccm > 0 {
            // The CCM is on the D-bus only: data, no instruction fetch (RM0090 §2.3.1).
            uc.mem_map(u64::from(CCM_BASE), u64::from(map.ccm), Prot::READ | Prot::WRITE)?;
        }
        uc.mem_map(u64::from(SYSTEM_MEMORY_BASE), u64::from(SYSTEM_MEMORY_SIZE), Prot::READ)?;
        uc.mem_write(u64::from(UNIQUE_ID_ADDRESS), &unique_id)?;
        uc.mem_write(u64::from(FLASH_SIZE_ADDRESS), &map.flash_kib.to_le_bytes())?;
        Self::map_buses(&mut uc)?;
        Self::map_sram_bit_band(&mut uc, map.sram)?;
        Self::add_hooks(&mut uc)?;
        Ok(Core { uc, map })
    }

    fn map_buses(uc: &mut Unicorn<'static, Bus>) -> Result<(), uc_error> {
        uc.mmio_map(
            u64::from(PERIPHERAL_BASE),
            u64::from(PERIPHERAL_SIZE),
            Some(|uc: &mut Unicorn<'_, Bus>, offset: u64, size: usize| {
                let address = PERIPHERAL_BASE + offset as u32;
                let value = uc.get_data_mut().peripheral_read(address, width(size));
                after_access(uc);
                u64::from(value)
            }),
            Some(|uc: &mut Unicorn<'_, Bus>, offset: u64, size: usize, value: u64| {
                let address = PERIPHERAL_BASE + offset as u32;
                uc.get_data_mut().peripheral_write(address, width(size), value as u32);
                after_access(uc);
            }),
        )?;
        uc.mmio_map(
            u64::from(PPB_BASE),
            u64::from(PPB_SIZE),
            Some(|uc: &mut Unicorn<'_, Bus>, offset: u64, size: usize| {
                let value = uc.get_data_mut().ppb_read(PPB_BASE + offset as u32, width(size));
                u64::from(value)
            }),
            Some(|uc: &mut Unicorn<'_, Bus>, offset: u64, size: usize, value: u64| {
                uc.get_data_mut().ppb_write(PPB_BASE + offset as u32, width(size), value as u32);
                after_access(uc);
            }),
        )
    }

    /// The SRAM bit-band alias (PM0214 §2.2.5: 0x2200_0000 maps each bit of 0x2000_0000–
    /// 0x200F_FFFF to a word), over the SRAM there is: a load reads the bit, a store
    /// read-modify-writes its word.
    fn map_sram_bit_band(uc: &mut Unicorn<'static, Bus>, sram: u32) -> Result<(), uc_error> {
        let target = |offset: u64| bit_band(SRAM_BIT_BAND, SRAM_BASE, SRAM_BIT_BAND + offset as u32);
        uc.mmio_map(
            u64::from(SRAM_BIT_BAND),
            u64::from(sram) * 32,
            Some(move |uc: &mut Unicorn<'_, Bus>, offset: u64, _: usize| {
                let (word, bit) = target(offset);
                let mut b = [0; 4];
                let _ = uc.mem_read(u64::from(word), &mut b);
                u64::from((u32::from_le_bytes(b) >> bit) & 1)
            }),
            Some(move |uc: &mut Unicorn<'_, Bus>, offset: u64, _: usize, value: u64| {
                let (word, bit) = target(offset);
                let mut b = [0; 4];
                let _ = uc.mem_read(u64::from(word), &mut b);
                let old = u32::from_le_bytes(b);
                let new = (old & !(1 << bit)) | ((value as u32 & 1) << bit);
                let _ = uc.mem_write(u64::from(word), &new.to_le_bytes());
            }),
        )
    }

    fn add_hooks(uc: &mut Unicorn<'static, Bus>) -> Result<(), uc_error> {
        // Every instruction: its address (for fault reports), the slice's budget and the stop
        // an access requested. Stopping here stops before the instruction. (Stopping inside a
        // memory callback would make unicorn run the accessing instruction again.)
        uc.add_code_hook(1, 0, |uc, address, _| {
            let bus = uc.get_data_mut();
            if bus.executed >= bus.budget || bus.stop_requested {
                let _ = uc.emu_stop();
                return;
            }
            bus.executed += 1;
            bus.pc = address as u32;
        })?;
        uc.add_intr_hook(|uc, number| {
            uc.get_data_mut().interrupt = Some(number);
            let _ = uc.emu_stop();
        })?;
        // CPU stores into flash (either copy) go to the FLASH model; the store lands in the
        // CPU's copy, which is refreshed from the array before the next instruction.
        for base in [0, FLASH_BASE] {
            uc.add_mem_hook(
                HookType::MEM_WRITE_PROT,
                u64::from(base),
                u64::from(base + FLASH_SIZE - 1),
                move |uc, _, address, size, value| {
                    let offset = (address as u32).wrapping_sub(base);
                    uc.get_data_mut().flash_store(offset, width(size), value as u32);
                    true
                },
            )?;
        }
        let faults = HookType::MEM_UNMAPPED | HookType::MEM_READ_PROT | HookType::MEM_FETCH_PROT;
        uc.add_mem_hook(faults, 1, 0, record_fault)?;
        let system_memory_end = u64::from(SYSTEM_MEMORY_BASE + SYSTEM_MEMORY_SIZE - 1);
        uc.add_mem_hook(
            HookType::MEM_WRITE_PROT,
            u64::from(SYSTEM_MEMORY_BASE),
            system_memory_end,
            record_fault,
        )?;
        Ok(())
    }

    /// The bus.
    pub fn bus(&self) -> &Bus {
        self.uc.get_data()
    }

    /// The bus, mutable.
    pub fn bus_mut(&mut self) -> &mut Bus {
        self.uc.get_data_mut()
    }

    /// The memory map.
    pub const fn map(&self) -> MemoryMap {
        self.map
    }

    /// Reads a core register.
    pub fn reg(&self, register: RegisterARM) -> u32 {
        self.uc.reg_read(register).unwrap_or(0) as u32
    }

    /// Writes a core register.
    pub fn set_reg(&mut self, register: RegisterARM, value: u32) {
        let _ = self.uc.reg_write(register, u64::from(value));
    }

    /// The priority masks now in the core.
    pub fn masks(&self) -> Masks {
        Masks {
            primask: self.reg(RegisterARM::PRIMASK) & 1 != 0,
            faultmask: self.reg(RegisterARM::FAULTMASK) & 1 != 0,
            basepri: self.reg(RegisterARM::BASEPRI) as u8,
        }
    }

    /// Reads memory the CPU can read (flash, SRAM, CCM, system memory).
    pub fn read_memory(&self, address: u32, buf: &mut [u8]) -> bool {
        self.uc.mem_read(u64::from(address), buf).is_ok()
    }

    /// Writes memory (SRAM, CCM; flash through the array, see [`Core::refresh_flash`]).
    pub fn write_memory(&mut self, address: u32, bytes: &[u8]) -> bool {
        self.uc.mem_write(u64::from(address), bytes).is_ok()
    }

    /// Reads a little-endian word.
    pub fn read_word(&self, address: u32) -> Option<u32> {
        let mut b = [0; 4];
        self.read_memory(address, &mut b).then(|| u32::from_le_bytes(b))
    }

    /// Copies what changed of the flash array into the CPU's two copies (0x0800_0000 and the
    /// boot alias at 0), and drops the code Unicorn translated from those bytes.
    pub fn refresh_flash(&mut self) {
        let Some((start, end)) = self.bus_mut().flash_dirty.take() else {
            return;
        };
        let flash = core::mem::take(&mut self.bus_mut().flash);
        let end = end.min(self.map.flash_bytes() as usize).min(flash.len());
        if start < end {
            let seen = &flash[start..end];
            for base in [u64::from(FLASH_BASE), 0] {
                let _ = self.uc.mem_write(base + start as u64, seen);
                // Unicorn keeps the code it translated from the old bytes: without this, code run
                // from a sector before it was erased and programmed again (a swapped image) would
                // run stale.
                let _ = self.uc.ctl_remove_cache(base + start as u64, base + end as u64);
            }
        }
        self.bus_mut().flash = flash;
    }

    /// Fills SRAM and CCM with zeros (power-on: their contents are not kept).
    pub fn clear_ram(&mut self) {
        let _ = self.uc.mem_write(u64::from(SRAM_BASE), &vec![0; self.map.sram as usize]);
        if self.map.ccm > 0 {
            let _ = self.uc.mem_write(u64::from(CCM_BASE), &vec![0; self.map.ccm as usize]);
        }
    }

    /// Runs at most `budget` instructions from the current PC.
    pub fn run(&mut self, budget: u64) -> Result<SliceEnd, CoreFault> {
        let masks = self.masks();
        let bus = self.bus_mut();
        bus.executed = 0;
        bus.budget = budget;
        bus.interrupt = None;
        bus.stop_requested = false;
        bus.masks = masks;
        let pc = self.reg(RegisterARM::PC);
        // `until` never matches a Thumb PC (which is even), so only the hooks stop the run.
        let result = self.uc.emu_start(u64::from(pc | 1), 0xFFFF_FFFF, 0, 0);
        let bus = self.bus();
        if let Some(e) = bus.error {
            return Err(CoreFault::Bus { address: e.address, pc: e.pc, write: e.write });
        }
        let pc = self.reg(RegisterARM::PC);
        match (bus.interrupt, result) {
            (Some(excp::EXCEPTION_EXIT), _) => Ok(SliceEnd::ExceptionReturn(pc | 1)),
            (Some(excp::PREFETCH_ABORT), _) if pc >= 0xFFFF_FF00 => Ok(SliceEnd::ExceptionReturn(pc | 1)),
            (Some(excp::SWI), _) => Ok(SliceEnd::SupervisorCall),
            (Some(excp::UDEF), _) => Err(CoreFault::Undefined { pc: bus.pc }),
            (Some(excp::BKPT), _) => Err(CoreFault::Breakpoint { pc: bus.pc }),
            (Some(other), _) => Err(CoreFault::Emulator { error: 0x100 + other, pc: bus.pc }),
            (None, Err(uc_error::INSN_INVALID)) => self.hint(bus.pc),
            (None, Err(e)) => Err(CoreFault::Emulator { error: e as u32, pc: bus.pc }),
            (None, Ok(())) if bus.executed >= bus.budget || bus.stop_requested => Ok(SliceEnd::Stopped),
            // unicorn returns on WFI (QEMU's EXCP_HLT) with PC after it.
            (None, Ok(())) => Ok(SliceEnd::Sleep),
        }
    }

    /// The hint instructions unicorn refuses in M-profile mode (it stops with "invalid
    /// instruction" at them): WFE sleeps like WFI (the event register is not modelled: the
    /// core wakes on the next exception that would preempt, PM0214 §2.5.3), YIELD and SEV are
    /// NOPs (single core). Anything else at `pc` is an undefined instruction.
    fn hint(&mut self, pc: u32) -> Result<SliceEnd, CoreFault> {
        let mut b = [0; 2];
        let end = match self.read_memory(pc, &mut b).then(|| u16::from_le_bytes(b)) {
            Some(0xBF20) => SliceEnd::Sleep,
            Some(0xBF10 | 0xBF40) => SliceEnd::Stopped,
            _ => return Err(CoreFault::Undefined { pc }),
        };
        self.set_reg(RegisterARM::PC, pc + 2);
        Ok(end)
    }

    /// Whether an FP instruction ran with the FPU disabled in CPACR (see
    /// [`CoreFault::NoCoprocessor`]).
    pub fn fp_used_while_disabled(&self) -> bool {
        self.reg(RegisterARM::CONTROL) & CONTROL_FPCA != 0 && !self.bus().scs.fpu_enabled()
    }

    /// Whether the instruction at PC is `b .` (0xE7FE), an idle `loop {}`: the core can only
    /// leave it through an exception, so the machine sleeps through it as through WFI.
    pub fn at_idle_loop(&self) -> bool {
        let mut b = [0; 2];
        self.read_memory(self.reg(RegisterARM::PC), &mut b) && u16::from_le_bytes(b) == 0xE7FE
    }

    /// Whether the core is inside an IT block (exceptions are taken between IT blocks here).
    pub fn in_it_block(&self) -> bool {
        self.reg(RegisterARM::XPSR) & XPSR_IT != 0
    }

    /// Exception entry (PM0214 §2.3.7): stacks the context, sets LR to EXC_RETURN and jumps
    /// to the vector of `number`.
    pub fn enter_exception(&mut self, number: u16) -> Result<(), CoreFault> {
        let thread = self.bus().scs.current() == 0;
        let control = self.reg(RegisterARM::CONTROL);
        let on_psp = thread && control & CONTROL_SPSEL != 0;
        let fp = control & CONTROL_FPCA != 0;
        let sp = self.reg(RegisterARM::SP);
        let xpsr = self.reg(RegisterARM::XPSR) & !0x1FF | u32::from(self.bus().scs.current());
        let mut words = Vec::with_capacity(26);
        words.extend(FRAME_REGISTERS.iter().map(|&r| self.reg(r)));
        words.push(self.reg(RegisterARM::PC));
        words.push(xpsr);
        if fp {
            words.extend(FP_REGISTERS.iter().map(|&r| self.reg(r)));
            words.push(self.reg(RegisterARM::FPSCR));
            words.push(0);
        }
        let size = 4 * words.len() as u32;
        let mut frame = sp.wrapping_sub(size);
        if self.bus().scs.stack_align_8() && frame & 4 != 0 {
            frame &= !7;
            words[7] |= 1 << 9;
        }
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        if !self.write_memory(frame, &bytes) {
            return Err(CoreFault::Stacking { sp: frame });
        }
        self.set_reg(RegisterARM::SP, frame);
        // The handler runs on MSP with no FP context yet (ARMv7-M ARM B1.5.6 ExceptionTaken).
        self.set_reg(RegisterARM::CONTROL, control & !(CONTROL_SPSEL | CONTROL_FPCA));
        let exc_return = 0xFFFF_FFE1 | u32::from(!fp) << 4 | u32::from(thread) << 3 | u32::from(on_psp) << 2;
        self.jump_to_handler(number, exc_return, xpsr)
    }

    /// Enters `number`'s handler with `exc_return` in LR (entry and tail chaining).
    fn jump_to_handler(&mut self, number: u16, exc_return: u32, xpsr: u32) -> Result<(), CoreFault> {
        let table = self.bus().scs.vtor();
        let vector = self
            .read_word(table.wrapping_add(4 * u32::from(number)))
            .ok_or(CoreFault::Stacking { sp: table })?;
        if vector & 1 == 0 {
            return Err(CoreFault::InvalidVector { exception: number, vector });
        }
        self.set_reg(RegisterARM::LR, exc_return);
        // Flags kept, IT cleared, Thumb; unicorn's IPSR stays 0.
        self.set_reg(RegisterARM::XPSR_NZCVQG, (xpsr & !XPSR_IT & !0x1FF) | XPSR_T);
        self.set_reg(RegisterARM::PC, vector & !1);
        self.bus_mut().scs.activate(number);
        Ok(())
    }

    /// Exception return (PM0214 §2.3.7, table 17): `exc_return` is the value branched to.
    pub fn return_from_exception(&mut self, exc_return: u32) -> Result<Return, CoreFault> {
        let kind = exc_return & 0xF;
        let valid = exc_return | 0x10 == 0xFFFF_FFF0 | kind && matches!(kind, 0x1 | 0x9 | 0xD);
        if !valid || self.bus().scs.current() == 0 {
            return Err(CoreFault::InvalidExceptionReturn { exc_return });
        }
        let to_thread = kind != 0x1;
        let to_psp = kind == 0xD;
        let fp = exc_return & 0x10 == 0;
        let sp = self.reg(if to_psp { RegisterARM::PSP } else { RegisterARM::MSP });
        let count = if fp { 26 } else { 8 };
        let mut bytes = vec![0; count * 4];
        if !self.read_memory(sp, &mut bytes) {
            return Err(CoreFault::Stacking { sp });
        }
        let words: Vec<u32> =
            bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        let xpsr = words[7];
        let back_to = if to_thread { 0 } else { (xpsr & 0x1FF) as u16 };
        self.bus_mut().scs.deactivate(back_to);
        if let Some(next) = self.bus().scs.preempting(self.masks()) {
            // Tail chaining: the frame stays; the next handler returns through it.
            self.jump_to_handler(next, exc_return, xpsr)?;
            return Ok(Return::Chained(next));
        }
        for (&register, &value) in FRAME_REGISTERS.iter().zip(&words) {
            self.set_reg(register, value);
        }
        if fp {
            for (&register, &value) in FP_REGISTERS.iter().zip(&words[8..]) {
                self.set_reg(register, value);
            }
            self.set_reg(RegisterARM::FPSCR, words[24]);
        }
        let control = self.reg(RegisterARM::CONTROL) & !(CONTROL_SPSEL | CONTROL_FPCA);
        let control = control | if to_psp { CONTROL_SPSEL } else { 0 } | if fp { CONTROL_FPCA } else { 0 };
        self.set_reg(RegisterARM::CONTROL, control);
        let popped = sp.wrapping_add(4 * count as u32) | if xpsr & (1 << 9) != 0 { 4 } else { 0 };
        self.set_reg(RegisterARM::SP, popped);
        self.set_reg(RegisterARM::XPSR_NZCVQG, xpsr & !0x1FF & !(1 << 9));
        self.set_reg(RegisterARM::PC, words[6] & !1);
        Ok(if to_thread { Return::Thread } else { Return::Handler })
    }

    /// The core's part of a reset (PM0214 §2.3.2 "Reset"; ARMv7-M ARM B1.5.5 TakeReset): MSP
    /// and PC from the vector table at 0 (the flash alias), thread mode, privileged, MSP, no
    /// masks, Thumb.
    pub fn reset(&mut self) -> Result<(), CoreFault> {
        let sp = self.read_word(0).ok_or(CoreFault::Stacking { sp: 0 })?;
        let pc = self.read_word(4).ok_or(CoreFault::Stacking { sp: 0 })?;
        // No Thumb bit, or an address in the execute-never system region (an erased flash's
        // 0xFFFF_FFFF): the chip would lock up (ARMv7-M ARM B1.5.5).
        if pc & 1 == 0 || pc >= 0xE000_0000 {
            return Err(CoreFault::InvalidVector { exception: 1, vector: pc });
        }
        self.set_reg(RegisterARM::CONTROL, 0);
        for register in [RegisterARM::PRIMASK, RegisterARM::FAULTMASK, RegisterARM::BASEPRI] {
            self.set_reg(register, 0);
        }
        self.set_reg(RegisterARM::MSP, sp & !3);
        self.set_reg(RegisterARM::PSP, 0);
        self.set_reg(RegisterARM::SP, sp & !3);
        self.set_reg(RegisterARM::LR, 0xFFFF_FFFF);
        self.set_reg(RegisterARM::XPSR_NZCVQG, XPSR_T);
        self.set_reg(RegisterARM::FPSCR, 0);
        self.set_reg(RegisterARM::PC, pc & !1);
        Ok(())
    }
}

/// Records an access to memory that is not there (or not writable) as the slice's bus error;
/// unicorn then stops with the error.
fn record_fault(uc: &mut Unicorn<'_, Bus>, kind: MemType, address: u64, _: usize, _: i64) -> bool {
    let bus = uc.get_data_mut();
    if bus.error.is_none() {
        let write = matches!(kind, MemType::WRITE_UNMAPPED | MemType::WRITE_PROT);
        bus.error = Some(super::bus::BusError { address: address as u32, pc: bus.pc, write });
    }
    false
}

fn width(size: usize) -> Width {
    match size {
        1 => Width::Byte,
        2 => Width::Half,
        _ => Width::Word,
    }
}

/// After a peripheral or SCS access: stop before the next instruction (the code hook does)
/// if an exception now
/// preempts, a reset was requested or the flash array changed.
fn after_access(uc: &mut Unicorn<'_, Bus>) {
    let masks = Masks {
        primask: uc.reg_read(RegisterARM::PRIMASK).unwrap_or(0) & 1 != 0,
        faultmask: uc.reg_read(RegisterARM::FAULTMASK).unwrap_or(0) & 1 != 0,
        basepri: uc.reg_read(RegisterARM::BASEPRI).unwrap_or(0) as u8,
    };
    let bus = uc.get_data_mut();
    bus.masks = masks;
    let stop = bus.stop_requested
        || bus.scs.preempting(masks).is_some()
        || bus.scs.reset_pending()
        || bus.flash_dirty.is_some();
    if stop {
        bus.stop_requested = true;
    }
}
