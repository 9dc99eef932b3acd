//! The System Control Space of the Cortex-M4 (0xE000_E000–0xE000_EFFF): the system control
//! block (SCB, PM0214 §4.4), the nested vectored interrupt controller (NVIC, PM0214 §4.2), the
//! SysTick timer (PM0214 §4.5, [`super::systick`]) and the floating-point control registers
//! (PM0214 §4.6), with the exception state they share: which exceptions are pending, active
//! and enabled, and at which priority.
//!
//! This is a plain state machine; the CPU side (stacking, EXC_RETURN) is in [`super::core`].
//! Addresses this model does not know read as zero and ignore writes (the Cortex-M4's
//! reserved SCS space is RAZ/WI or UNPREDICTABLE, PM0214 §4.1; RAZ/WI is the kind choice).

use super::systick::{self, SysTick};

/// Exception numbers of the Cortex-M4 (PM0214 §2.3.2 "Exception types").
pub mod exception {
    /// Reset.
    pub const RESET: u16 = 1;
    /// Non-maskable interrupt.
    pub const NMI: u16 = 2;
    /// HardFault.
    pub const HARD_FAULT: u16 = 3;
    /// MemManage fault.
    pub const MEM_MANAGE: u16 = 4;
    /// BusFault.
    pub const BUS_FAULT: u16 = 5;
    /// UsageFault.
    pub const USAGE_FAULT: u16 = 6;
    /// Supervisor call.
    pub const SV_CALL: u16 = 11;
    /// PendSV.
    pub const PEND_SV: u16 = 14;
    /// SysTick.
    pub const SYS_TICK: u16 = 15;
    /// The first external interrupt (IRQ0, RM0090 §12.2 table 61 position 0).
    pub const IRQ0: u16 = 16;
}

/// External interrupt lines the model keeps: 4 words of NVIC registers. The STM32F405 has 82
/// (RM0090 §12.2: "up to 82 maskable interrupt channels" on STM32F405xx/07xx), the F446 97.
pub const MAX_IRQS: usize = 128;
const EXCEPTIONS: usize = exception::IRQ0 as usize + MAX_IRQS;

/// The CPUID of the STM32F4's core: Cortex-M4 r0p1 (PM0214 §4.4.1; RM0090 §38.6.3 gives the
/// same part number 0xC24 for the ROM table).
pub const CPUID: u32 = 0x410F_C241;
/// CCR at reset: STKALIGN set, 8-byte stack alignment on exception entry (PM0214 §4.4.7).
const CCR_RESET: u32 = 0x0000_0200;
/// FPCCR at reset: ASPEN and LSPEN set (PM0214 §4.6.2).
const FPCCR_RESET: u32 = 0xC000_0000;
/// AIRCR's key: writes without 0x05FA in VECTKEY are ignored (PM0214 §4.4.5).
const VECTKEY: u32 = 0x05FA;

/// Offsets within the System Control Space.
pub mod offset {
    /// ICTR, interrupt controller type (ARMv7-M ARM B3.4.2).
    pub const ICTR: u32 = 0x004;
    /// NVIC_ISER0, set-enable (PM0214 §4.2.2).
    pub const ISER: u32 = 0x100;
    /// NVIC_ICER0, clear-enable (PM0214 §4.2.3).
    pub const ICER: u32 = 0x180;
    /// NVIC_ISPR0, set-pending (PM0214 §4.2.4).
    pub const ISPR: u32 = 0x200;
    /// NVIC_ICPR0, clear-pending (PM0214 §4.2.5).
    pub const ICPR: u32 = 0x280;
    /// NVIC_IABR0, active bits (PM0214 §4.2.6).
    pub const IABR: u32 = 0x300;
    /// NVIC_IPR0, priorities, one byte per interrupt (PM0214 §4.2.7).
    pub const IPR: u32 = 0x400;
    /// CPUID (PM0214 §4.4.1).
    pub const CPUID: u32 = 0xD00;
    /// ICSR, interrupt control and state (PM0214 §4.4.2).
    pub const ICSR: u32 = 0xD04;
    /// VTOR, vector table offset (PM0214 §4.4.3).
    pub const VTOR: u32 = 0xD08;
    /// AIRCR, application interrupt and reset control (PM0214 §4.4.4).
    pub const AIRCR: u32 = 0xD0C;
    /// SCR, system control (PM0214 §4.4.6).
    pub const SCR: u32 = 0xD10;
    /// CCR, configuration and control (PM0214 §4.4.7).
    pub const CCR: u32 = 0xD14;
    /// SHPR1–3, system handler priorities, one byte per exception 4–15 (PM0214 §4.4.8).
    pub const SHPR: u32 = 0xD18;
    /// SHCSR, system handler control and state (PM0214 §4.4.9).
    pub const SHCSR: u32 = 0xD24;
    /// CFSR, configurable fault status (PM0214 §4.4.10).
    pub const CFSR: u32 = 0xD28;
    /// HFSR, hard fault status (PM0214 §4.4.14).
    pub const HFSR: u32 = 0xD2C;
    /// BFAR, bus fault address (PM0214 §4.4.16).
    pub const BFAR: u32 = 0xD38;
    /// CPACR, coprocessor access control (PM0214 §4.6.1).
    pub const CPACR: u32 = 0xD88;
    /// STIR, software trigger interrupt (PM0214 §4.2.8).
    pub const STIR: u32 = 0xF00;
    /// FPCCR, floating-point context control (PM0214 §4.6.2).
    pub const FPCCR: u32 = 0xF34;
    /// FPCAR, floating-point context address (PM0214 §4.6.3).
    pub const FPCAR: u32 = 0xF38;
    /// FPDSCR, floating-point default status control (PM0214 §4.6.5).
    pub const FPDSCR: u32 = 0xF3C;
}

/// The core's priority-masking registers, read from the CPU (PM0214 §2.1.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Masks {
    /// PRIMASK bit 0: only NMI and HardFault are taken.
    pub primask: bool,
    /// FAULTMASK bit 0: only NMI is taken.
    pub faultmask: bool,
    /// BASEPRI: exceptions of this priority value or higher (numerically) are not taken; 0
    /// disables the mask.
    pub basepri: u8,
}

/// The System Control Space model.
#[derive(Clone, Debug)]
pub struct Scs {
    irqs: usize,
    enabled: [bool; EXCEPTIONS],
    pending: [bool; EXCEPTIONS],
    active: [bool; EXCEPTIONS],
    /// Priority bytes of exceptions 4–15 (SHPR) and of every IRQ (IPR), by exception number.
    priority: [u8; EXCEPTIONS],
    /// The level of each external interrupt line (level-sensitive, PM0214 §4.2.9).
    lines: [bool; MAX_IRQS],
    vtor: u32,
    prigroup: u32,
    scr: u32,
    ccr: u32,
    cfsr: u32,
    hfsr: u32,
    bfar: u32,
    cpacr: u32,
    fpccr: u32,
    fpcar: u32,
    fpdscr: u32,
    /// The exception the core is handling (IPSR), 0 in thread mode.
    current: u16,
    /// AIRCR.SYSRESETREQ was written with the key: the machine is to reset.
    reset_requested: bool,
    /// The SysTick timer.
    pub systick: SysTick,
}

impl Scs {
    /// The System Control Space at reset, with `irqs` external interrupt lines.
    pub fn new(irqs: usize) -> Scs {
        let mut enabled = [false; EXCEPTIONS];
        // NMI, HardFault, SVCall, PendSV, SysTick are always enabled (PM0214 §2.3.2);
        // MemManage, BusFault, UsageFault are enabled in SHCSR.
        for e in [exception::NMI, exception::HARD_FAULT, exception::SV_CALL] {
            enabled[usize::from(e)] = true;
        }
        enabled[usize::from(exception::PEND_SV)] = true;
        enabled[usize::from(exception::SYS_TICK)] = true;
        Scs {
            irqs: irqs.min(MAX_IRQS),
            enabled,
            pending: [false; EXCEPTIONS],
            active: [false; EXCEPTIONS],
            priority: [0; EXCEPTIONS],
            lines: [false; MAX_IRQS],
            vtor: 0,
            prigroup: 0,
            scr: 0,
            ccr: CCR_RESET,
            cfsr: 0,
            hfsr: 0,
            bfar: 0,
            cpacr: 0,
            fpccr: FPCCR_RESET,
            fpcar: 0,
            fpdscr: 0,
            current: 0,
            reset_requested: false,
            systick: SysTick::new(),
        }
    }

    /// Resets the System Control Space (both power-on and system reset put every SCS register
    /// to its reset value, PM0214 §4.4 tables). The interrupt line levels are the peripherals'
    /// and stay.
    pub fn reset(&mut self) {
        let lines = self.lines;
        *self = Scs::new(self.irqs);
        self.lines = lines;
    }

    /// VTOR: the vector table's address.
    pub const fn vtor(&self) -> u32 {
        self.vtor
    }

    /// CCR.STKALIGN: exception entry aligns the stack to 8 bytes.
    pub const fn stack_align_8(&self) -> bool {
        self.ccr & (1 << 9) != 0
    }

    /// SCR.SLEEPONEXIT: the core sleeps on returning to thread mode (PM0214 §4.4.6).
    pub const fn sleep_on_exit(&self) -> bool {
        self.scr & (1 << 1) != 0
    }

    /// CPACR: whether CP10 and CP11 (the FPU) are enabled for privileged access.
    pub const fn fpu_enabled(&self) -> bool {
        self.cpacr & (0b0101 << 20) == (0b0101 << 20)
    }

    /// Whether a system reset request waits (AIRCR.SYSRESETREQ, PM0214 §4.4.4).
    pub const fn reset_pending(&self) -> bool {
        self.reset_requested
    }

    /// Takes a pending system reset request (AIRCR.SYSRESETREQ, PM0214 §4.4.4).
    pub fn take_reset_request(&mut self) -> bool {
        core::mem::take(&mut self.reset_requested)
    }

    /// The exception being handled (IPSR), 0 in thread mode.
    pub const fn current(&self) -> u16 {
        self.current
    }

    /// Whether exception `number` is active.
    pub fn is_active(&self, number: u16) -> bool {
        self.active.get(usize::from(number)).copied().unwrap_or(false)
    }

    /// Whether exception `number` is pending.
    pub fn is_pending(&self, number: u16) -> bool {
        self.pending.get(usize::from(number)).copied().unwrap_or(false)
    }

    /// Pends exception `number` (SysTick reaching 0, SVC, a peripheral line).
    pub fn set_pending(&mut self, number: u16) {
        if let Some(p) = self.pending.get_mut(usize::from(number)) {
            *p = true;
        }
    }

    /// Drives external interrupt line `irq`. A line held high pends its interrupt whenever the
    /// interrupt is not active (level-sensitive, PM0214 §4.2.9).
    pub fn set_line(&mut self, irq: u16, level: bool) {
        let i = usize::from(irq);
        if i >= self.irqs {
            return;
        }
        self.lines[i] = level;
        let number = usize::from(exception::IRQ0) + i;
        if level && !self.active[number] {
            self.pending[number] = true;
        }
    }

    fn sample_lines(&mut self) {
        for irq in 0..self.irqs {
            let number = usize::from(exception::IRQ0) + irq;
            if self.lines[irq] && !self.active[number] {
                self.pending[number] = true;
            }
        }
    }

    /// The priority of an exception as the hardware compares it: -3, -2, -1 for Reset, NMI,
    /// HardFault, the configured byte (upper 4 bits implemented on the STM32F4, PM0214 §4.2.7)
    /// otherwise.
    pub fn priority(&self, number: u16) -> i16 {
        match number {
            exception::RESET => -3,
            exception::NMI => -2,
            exception::HARD_FAULT => -1,
            n => i16::from(self.priority.get(usize::from(n)).copied().unwrap_or(0)),
        }
    }

    /// The group priority (PM0214 §4.4.5 "Binary point"): the priority with the subpriority
    /// bits that PRIGROUP selects cleared.
    fn group_priority(&self, priority: i16) -> i16 {
        if priority < 0 {
            return priority;
        }
        let sub_bits = self.prigroup + 1;
        let mask = (0xFF_u32 << sub_bits) & 0xFF;
        (priority as u32 & mask) as i16
    }

    /// The execution priority (ARMv7-M ARM B1.5.4): the highest (lowest value) of the active
    /// exceptions' group priorities and of the masks; 256 in thread mode with no mask.
    pub fn execution_priority(&self, masks: Masks) -> i16 {
        let mut priority = 256;
        // Slice iteration: this runs after every bus access, in unoptimised test builds too.
        for (number, _) in self.active.iter().enumerate().skip(1).filter(|(_, &a)| a) {
            priority = priority.min(self.group_priority(self.priority(number as u16)));
        }
        if masks.basepri & 0xF0 != 0 {
            priority = priority.min(self.group_priority(i16::from(masks.basepri & 0xF0)));
        }
        if masks.primask {
            priority = priority.min(0);
        }
        if masks.faultmask {
            priority = priority.min(-1);
        }
        priority
    }

    /// The pending, enabled exception of highest priority (lowest group priority, then lowest
    /// priority, then lowest number, PM0214 §2.3.6), if any.
    pub fn highest_pending(&self) -> Option<u16> {
        let mut best: Option<(i16, i16, u16)> = None;
        let last = usize::from(exception::IRQ0) + self.irqs;
        let candidates = self.pending[..last].iter().zip(&self.enabled[..last]).enumerate().skip(2);
        for (n, _) in candidates.filter(|(_, (&p, &e))| p && e) {
            let number = n as u16;
            let priority = self.priority(number);
            let key = (self.group_priority(priority), priority, number);
            if best.is_none_or(|b| key < b) {
                best = Some(key);
            }
        }
        best.map(|(_, _, number)| number)
    }

    /// The pending exception that preempts the execution priority `masks` leave, if any.
    pub fn preempting(&self, masks: Masks) -> Option<u16> {
        let number = self.highest_pending()?;
        let group = self.group_priority(self.priority(number));
        (group < self.execution_priority(masks)).then_some(number)
    }

    /// Whether a pending exception would wake the core from WFI: one that would preempt if
    /// PRIMASK were clear (PM0214 §2.5.2 "Wakeup from WFI").
    pub fn wakes(&self, masks: Masks) -> bool {
        self.preempting(Masks { primask: false, ..masks }).is_some()
    }

    /// Exception entry bookkeeping (PM0214 §2.3.7): `number` becomes active and not pending,
    /// and the current exception.
    pub fn activate(&mut self, number: u16) {
        let n = usize::from(number);
        self.pending[n] = false;
        self.active[n] = true;
        self.current = number;
    }

    /// Exception return bookkeeping: the current exception is no longer active and the core
    /// returns to `to` (the stacked IPSR: 0 for thread mode). A still asserted line pends its
    /// interrupt again (PM0214 §4.2.9).
    pub fn deactivate(&mut self, to: u16) {
        if let Some(a) = self.active.get_mut(usize::from(self.current)) {
            *a = false;
        }
        self.current = to;
        self.sample_lines();
    }

    /// Whether no exception is active (RETTOBASE, and the return to thread mode).
    pub fn none_active(&self) -> bool {
        !self.active.iter().any(|&a| a)
    }

    /// Reads a 32-bit word at `offset` within the System Control Space.
    pub fn read(&mut self, offset: u32) -> u32 {
        match offset {
            offset::ICTR => (self.irqs as u32).div_ceil(32).saturating_sub(1),
            0x010..=0x01C => self.systick.read(offset),
            offset::ISER..=0x13C | offset::ICER..=0x1BC => self.irq_bits(offset & 0x7F, &self.enabled),
            offset::ISPR..=0x23C | offset::ICPR..=0x2BC => self.irq_bits(offset & 0x7F, &self.pending),
            offset::IABR..=0x33C => self.irq_bits(offset & 0x7F, &self.active),
            offset::IPR..=0x5EC => self.priority_word(u32::from(exception::IRQ0) + (offset - offset::IPR)),
            offset::CPUID => CPUID,
            offset::ICSR => self.icsr(),
            offset::VTOR => self.vtor,
            offset::AIRCR => (0xFA05 << 16) | (self.prigroup << 8),
            offset::SCR => self.scr,
            offset::CCR => self.ccr,
            offset::SHPR..=0xD20 => self.priority_word(4 + (offset - offset::SHPR)),
            offset::SHCSR => self.shcsr(),
            offset::CFSR => self.cfsr,
            offset::HFSR => self.hfsr,
            offset::BFAR => self.bfar,
            offset::CPACR => self.cpacr,
            offset::FPCCR => self.fpccr,
            offset::FPCAR => self.fpcar,
            offset::FPDSCR => self.fpdscr,
            _ => 0,
        }
    }

    /// Writes a 32-bit word at `offset`. Narrower stores are merged by the caller
    /// ([`Scs::write_sized`]).
    pub fn write(&mut self, offset: u32, value: u32) {
        match offset {
            0x010..=0x01C => self.systick.write(offset, value),
            offset::ISER..=0x13C => self.set_irq_bits(offset - offset::ISER, value, Field::Enabled, true),
            offset::ICER..=0x1BC => self.set_irq_bits(offset - offset::ICER, value, Field::Enabled, false),
            offset::ISPR..=0x23C => self.set_irq_bits(offset - offset::ISPR, value, Field::Pending, true),
            offset::ICPR..=0x2BC => self.set_irq_bits(offset - offset::ICPR, value, Field::Pending, false),
            offset::IPR..=0x5EC => {
                self.set_priority_word(u32::from(exception::IRQ0) + (offset - offset::IPR), value, 0xF)
            }
            offset::ICSR => self.write_icsr(value),
            // TBLOFF, bits [29:9] (PM0214 §4.4.3).
            offset::VTOR => self.vtor = value & 0x3FFF_FE00,
            offset::AIRCR => self.write_aircr(value),
            offset::SCR => self.scr = value & 0b1_0110,
            offset::CCR => self.ccr = value & 0x0000_031B,
            offset::SHPR..=0xD20 => self.set_priority_word(4 + (offset - offset::SHPR), value, 0xF),
            offset::SHCSR => self.write_shcsr(value),
            // Write-one-to-clear status registers (PM0214 §4.4.10, §4.4.14).
            offset::CFSR => self.cfsr &= !value,
            offset::HFSR => self.hfsr &= !value,
            offset::BFAR => self.bfar = value,
            // CP10 and CP11 fields only (PM0214 §4.6.1).
            offset::CPACR => self.cpacr = value & 0x00F0_0000,
            offset::STIR => {
                let irq = (value & 0x1FF) as usize;
                if irq < self.irqs {
                    self.pending[usize::from(exception::IRQ0) + irq] = true;
                }
            }
            offset::FPCCR => self.fpccr = (self.fpccr & 0x1FF) | (value & 0xC000_0000),
            offset::FPCAR => self.fpcar = value & !7,
            offset::FPDSCR => self.fpdscr = value & 0x07C0_0000,
            _ => {}
        }
    }

    /// Writes `bytes` bytes of `value` at `offset` (any alignment within a word): the byte
    /// accessible registers (IPR, SHPR, PM0214 §4.2.7, §4.4.8) take a byte store as a store to
    /// that byte alone; for the others the store is merged into the current word (a read of
    /// a clear-on-read flag like COUNTFLAG is avoided: SysTick is word-only).
    pub fn write_sized(&mut self, offset: u32, bytes: u32, value: u32) {
        let word = offset & !3;
        if bytes == 4 {
            return self.write(word, value);
        }
        let shift = (offset & 3) * 8;
        let mask = if bytes == 1 { 0xFF } else { 0xFFFF };
        let byte_regs = (offset::IPR..=0x5EF).contains(&offset) || (offset::SHPR..=0xD23).contains(&offset);
        if byte_regs {
            let first = if (offset::IPR..0x5F0).contains(&word) {
                u32::from(exception::IRQ0) + (word - offset::IPR)
            } else {
                4 + (word - offset::SHPR)
            };
            let lanes = if bytes == 1 { 1 << (offset & 3) } else { 3 << (offset & 3) };
            return self.set_priority_word(first, (value & mask) << shift, lanes);
        }
        let old = if (0x010..=0x01C).contains(&word) { 0 } else { self.read(word) };
        self.write(word, (old & !(mask << shift)) | ((value & mask) << shift));
    }

    fn irq_bits(&self, word_offset: u32, field: &[bool; EXCEPTIONS]) -> u32 {
        let first = (word_offset / 4 * 32) as usize;
        (0..32)
            .filter(|b| first + b < self.irqs && field[usize::from(exception::IRQ0) + first + b])
            .fold(0, |w, b| w | 1 << b)
    }

    fn set_irq_bits(&mut self, word_offset: u32, value: u32, field: Field, set: bool) {
        let first = (word_offset / 4 * 32) as usize;
        for bit in (0..32).filter(|b| value & (1 << b) != 0 && first + b < self.irqs) {
            let n = usize::from(exception::IRQ0) + first + bit;
            match field {
                Field::Enabled => self.enabled[n] = set,
                Field::Pending => self.pending[n] = set,
            }
        }
        if field == Field::Pending && !set {
            // A line still asserted pends its interrupt again at once.
            self.sample_lines();
        }
    }

    fn priority_word(&self, first: u32) -> u32 {
        (0..4).fold(0, |w, i| {
            let n = (first + i) as usize;
            let byte = if n < EXCEPTIONS { u32::from(self.priority[n]) } else { 0 };
            w | byte << (8 * i)
        })
    }

    /// Stores the byte lanes `lanes` of `value` as priorities of exceptions `first`..: only
    /// bits [7:4] are implemented (PM0214 §4.2.7: "the STM32F4 implements 4 bits"), and the
    /// priorities of exceptions 4–6 and above are writable; the fixed ones are not.
    fn set_priority_word(&mut self, first: u32, value: u32, lanes: u32) {
        for i in (0..4).filter(|i| lanes & (1 << i) != 0) {
            let n = (first + i) as usize;
            let writable = (4..EXCEPTIONS).contains(&n) && (n < 16 || n - 16 < self.irqs);
            if writable && ![7, 8, 9, 10, 13].contains(&n) {
                self.priority[n] = ((value >> (8 * i)) & 0xF0) as u8;
            }
        }
    }

    /// ICSR as a read returns it (PM0214 §4.4.2): VECTACTIVE, RETTOBASE, VECTPENDING,
    /// ISRPENDING, PENDSTSET, PENDSVSET, NMIPENDSET.
    pub fn icsr(&self) -> u32 {
        let pending = self.highest_pending().map_or(0, u32::from);
        let others_active = self.active.iter().enumerate().any(|(n, &a)| a && n != usize::from(self.current));
        let mut value = u32::from(self.current) | (pending << 12);
        if !others_active {
            value |= 1 << 11; // RETTOBASE
        }
        let irq_pending = (0..self.irqs).any(|i| self.pending[usize::from(exception::IRQ0) + i]);
        if irq_pending {
            value |= 1 << 22; // ISRPENDING
        }
        if self.pending[usize::from(exception::SYS_TICK)] {
            value |= 1 << 26;
        }
        if self.pending[usize::from(exception::PEND_SV)] {
            value |= 1 << 28;
        }
        if self.pending[usize::from(exception::NMI)] {
            value |= 1 << 31;
        }
        value
    }

    /// ICSR's set and clear bits (PM0214 §4.4.2): NMIPENDSET 31, PENDSVSET 28, PENDSVCLR 27,
    /// PENDSTSET 26, PENDSTCLR 25.
    fn write_icsr(&mut self, value: u32) {
        let bits = [
            (31, exception::NMI, true),
            (28, exception::PEND_SV, true),
            (27, exception::PEND_SV, false),
            (26, exception::SYS_TICK, true),
            (25, exception::SYS_TICK, false),
        ];
        for (bit, number, set) in bits {
            if value & (1 << bit) != 0 {
                self.pending[usize::from(number)] = set;
            }
        }
    }

    /// AIRCR (PM0214 §4.4.4): ignored without VECTKEY; PRIGROUP [10:8]; SYSRESETREQ (bit 2)
    /// requests a system reset.
    fn write_aircr(&mut self, value: u32) {
        if value >> 16 != VECTKEY {
            return;
        }
        self.prigroup = (value >> 8) & 7;
        if value & (1 << 2) != 0 {
            self.reset_requested = true;
        }
    }

    fn shcsr(&self) -> u32 {
        let active = [
            (0, exception::MEM_MANAGE),
            (1, exception::BUS_FAULT),
            (3, exception::USAGE_FAULT),
            (7, exception::SV_CALL),
            (10, exception::PEND_SV),
            (11, exception::SYS_TICK),
        ];
        let mut value =
            active.iter().filter(|(_, n)| self.active[usize::from(*n)]).fold(0, |w, (b, _)| w | 1 << b);
        for (bit, number) in
            [(16, exception::MEM_MANAGE), (17, exception::BUS_FAULT), (18, exception::USAGE_FAULT)]
        {
            if self.enabled[usize::from(number)] {
                value |= 1 << bit;
            }
        }
        if self.pending[usize::from(exception::SV_CALL)] {
            value |= 1 << 15;
        }
        value
    }

    fn write_shcsr(&mut self, value: u32) {
        for (bit, number) in
            [(16, exception::MEM_MANAGE), (17, exception::BUS_FAULT), (18, exception::USAGE_FAULT)]
        {
            self.enabled[usize::from(number)] = value & (1 << bit) != 0;
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Field {
    Enabled,
    Pending,
}

/// The SysTick register offsets, re-exported for the machine.
pub use systick::offset as systick_offset;

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    const IRQS: usize = 82;
    /// EXTI2 (RM0090 table 61 position 8), the firmware's converter task.
    const EXTI2: u16 = 8;
    /// CAN1_RX0 (RM0090 table 61 position 20).
    const CAN1_RX0: u16 = 20;

    fn exc(irq: u16) -> u16 {
        exception::IRQ0 + irq
    }

    /// As cortex-m 0.7 `NVIC::set_priority` and `unmask` do: a byte store to IPR, a word store
    /// to ISER.
    fn enable(scs: &mut Scs, irq: u16, priority: u8) {
        scs.write_sized(offset::IPR + u32::from(irq), 1, u32::from(priority));
        scs.write(offset::ISER + u32::from(irq / 32) * 4, 1 << (irq % 32));
    }

    #[test]
    fn cpuid_ccr_and_fpccr_reset_values() {
        let mut scs = Scs::new(IRQS);
        assert_eq!(scs.read(offset::CPUID), 0x410F_C241);
        assert_eq!(scs.read(offset::CCR), 0x200);
        assert_eq!(scs.read(offset::FPCCR), 0xC000_0000);
        assert_eq!(scs.read(offset::AIRCR), 0xFA05_0000);
        assert_eq!(scs.read(offset::ICTR), 2);
    }

    #[rstest]
    #[case::four_bits_kept(0xFF, 0xF0)]
    #[case::low_nibble_reads_zero(0x1F, 0x10)]
    fn ipr_implements_four_bits(#[case] written: u32, #[case] read: u32) {
        let mut scs = Scs::new(IRQS);
        scs.write_sized(offset::IPR + 9, 1, written);
        assert_eq!(scs.read(offset::IPR + 8), read << 8);
    }

    #[test]
    fn iser_icer_ispr_icpr() {
        let mut scs = Scs::new(IRQS);
        enable(&mut scs, CAN1_RX0, 0xD0);
        assert_eq!(scs.read(offset::ISER), 1 << 20);
        assert_eq!(scs.read(offset::ICER), 1 << 20);
        scs.write(offset::ISPR, 1 << EXTI2);
        assert_eq!(scs.read(offset::ICPR), 1 << EXTI2);
        scs.write(offset::ICPR, 1 << EXTI2);
        assert_eq!(scs.read(offset::ISPR), 0);
        scs.write(offset::ICER, 1 << 20);
        assert_eq!(scs.read(offset::ISER), 0);
    }

    #[test]
    fn lines_beyond_the_device_are_raz_wi() {
        let mut scs = Scs::new(IRQS);
        scs.write(offset::ISER + 8, 0xFFFF_FFFF);
        // 82 lines: bits 0..17 of the third word.
        assert_eq!(scs.read(offset::ISER + 8), 0x3FFFF);
    }

    #[rstest]
    #[case::thread_mode_takes_it(Masks::default(), Some(exc(EXTI2)))]
    #[case::primask_masks(Masks { primask: true, ..Masks::default() }, None)]
    #[case::basepri_equal_masks(Masks { basepri: 0xE0, ..Masks::default() }, None)]
    #[case::basepri_lower_priority_lets_through(Masks { basepri: 0xF0, ..Masks::default() }, Some(exc(EXTI2)))]
    fn masking(#[case] masks: Masks, #[case] taken: Option<u16>) {
        let mut scs = Scs::new(IRQS);
        enable(&mut scs, EXTI2, 0xE0);
        scs.write(offset::ISPR, 1 << EXTI2);
        assert_eq!(scs.preempting(masks), taken);
    }

    #[test]
    fn priority_then_number_orders_pending_exceptions() {
        let mut scs = Scs::new(IRQS);
        enable(&mut scs, EXTI2, 0xE0);
        enable(&mut scs, CAN1_RX0, 0xD0);
        scs.write(offset::ISPR, (1 << EXTI2) | (1 << CAN1_RX0));
        assert_eq!(scs.highest_pending(), Some(exc(CAN1_RX0)));
        // SysTick at the same priority as CAN1_RX0 wins by its lower number.
        scs.write_sized(offset::SHPR + 11, 1, 0xD0);
        scs.write(offset::ICSR, 1 << 26);
        assert_eq!(scs.highest_pending(), Some(exception::SYS_TICK));
    }

    #[test]
    fn an_active_handler_is_preempted_only_by_higher_priority() {
        let mut scs = Scs::new(IRQS);
        enable(&mut scs, EXTI2, 0xE0);
        enable(&mut scs, CAN1_RX0, 0xD0);
        scs.activate(exc(CAN1_RX0));
        scs.write(offset::ISPR, 1 << EXTI2);
        assert_eq!(scs.preempting(Masks::default()), None);
        assert_eq!(scs.read(offset::ICSR) & 0x1FF, u32::from(exc(CAN1_RX0)));
        scs.deactivate(0);
        assert_eq!(scs.preempting(Masks::default()), Some(exc(EXTI2)));
    }

    #[test]
    fn prigroup_makes_subpriorities_not_preempt() {
        let mut scs = Scs::new(IRQS);
        // PRIGROUP 5: group priority bits [7:6], subpriority [5:0].
        scs.write(offset::AIRCR, 0x05FA_0500);
        enable(&mut scs, EXTI2, 0x80);
        enable(&mut scs, CAN1_RX0, 0xA0);
        scs.activate(exc(CAN1_RX0));
        scs.write(offset::ISPR, 1 << EXTI2);
        assert_eq!(scs.preempting(Masks::default()), None);
    }

    #[test]
    fn a_level_line_pends_again_after_return() {
        let mut scs = Scs::new(IRQS);
        enable(&mut scs, CAN1_RX0, 0xD0);
        scs.set_line(CAN1_RX0, true);
        assert_eq!(scs.preempting(Masks::default()), Some(exc(CAN1_RX0)));
        scs.activate(exc(CAN1_RX0));
        assert!(!scs.is_pending(exc(CAN1_RX0)));
        scs.deactivate(0);
        assert!(scs.is_pending(exc(CAN1_RX0)));
        scs.set_line(CAN1_RX0, false);
        scs.write(offset::ICPR, 1 << CAN1_RX0);
        assert!(!scs.is_pending(exc(CAN1_RX0)));
    }

    #[rstest]
    #[case::with_key(0x05FA_0004, true)]
    #[case::without_key(0x0000_0004, false)]
    #[case::wrong_key(0xFA05_0004, false)]
    fn sysresetreq_needs_the_key(#[case] value: u32, #[case] reset: bool) {
        let mut scs = Scs::new(IRQS);
        scs.write(offset::AIRCR, value);
        assert_eq!(scs.take_reset_request(), reset);
    }

    #[test]
    fn icsr_pendsv_and_systick_set_and_clear() {
        let mut scs = Scs::new(IRQS);
        scs.write(offset::ICSR, (1 << 28) | (1 << 26));
        assert_eq!(scs.read(offset::ICSR) & ((1 << 28) | (1 << 26)), (1 << 28) | (1 << 26));
        assert_eq!((scs.read(offset::ICSR) >> 12) & 0x1FF, u32::from(exception::PEND_SV));
        scs.write(offset::ICSR, (1 << 27) | (1 << 25));
        assert_eq!(scs.read(offset::ICSR) & ((1 << 28) | (1 << 26)), 0);
    }

    #[test]
    fn vtor_cpacr_and_stir() {
        let mut scs = Scs::new(IRQS);
        scs.write(offset::VTOR, 0x0800_0000);
        assert_eq!(scs.vtor(), 0x0800_0000);
        // cortex-m-rt's FPU enable: CP10 and CP11 full access.
        scs.write(offset::CPACR, 0xF << 20);
        assert!(scs.fpu_enabled());
        scs.write(offset::STIR, u32::from(EXTI2));
        assert!(scs.is_pending(exc(EXTI2)));
    }

    #[test]
    fn systick_through_the_scs() {
        let mut scs = Scs::new(IRQS);
        scs.write(systick_offset::RVR, 167_999);
        scs.write(systick_offset::CSR, 0b111);
        assert_eq!(scs.read(systick_offset::RVR), 167_999);
        assert_eq!(scs.systick.cycles_to_interrupt(), Some(168_000));
    }
}
