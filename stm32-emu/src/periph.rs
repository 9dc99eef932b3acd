//! The interface every peripheral model implements, and what a model may ask of the machine.
//!
//! A model owns one register block (a base address and a size, RM0090 §2.3 "Memory map").
//! The machine decodes each CPU access to the model and the offset within its block, and calls
//! [`Peripheral::read`] or [`Peripheral::write`] with the access size. Time moves only through
//! [`Peripheral::advance`]. What a model needs from the rest of the chip (the bus clocks set by
//! RCC, its interrupt lines to the NVIC) it gets through [`Machine`].
//!
//! # A peripheral whose clock is off
//!
//! Every model with an RCC enable bit answers an access while that bit is clear as the chip
//! does: a read returns 0 and a write is lost. ST's reference manuals say so in the note on
//! their RCC peripheral clock enable registers ("When the peripheral clock is not active, the
//! peripheral register values may not be readable by software and the returned value is always
//! 0x0", e.g. RM0091 §6.4.6 `RCC_AHBENR`); RM0090 §7.3.10, §7.3.13 and §7.3.14 give the enable
//! bits of the STM32F405 (RM0390 §6.3 those of the F446) without that note, and the STM32F40x
//! errata (ES0182, DocID022183 rev 8 §2.1.13 "Delay after an RCC peripheral clock enabling")
//! describe writes that reach a peripheral before its clock runs as not taken into account. Such an access is never what
//! firmware means, so the model also tells the machine ([`Machine::unclocked_access`]), which
//! stops and names the peripheral, the register address and the enable bit
//! (`crate::machine::Fault::Unclocked`) instead of letting the firmware spin on a register
//! that reads 0 forever.

use std::fmt;

/// The width of one bus access.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Width {
    /// 8 bits.
    Byte,
    /// 16 bits.
    Half,
    /// 32 bits.
    Word,
}

impl Width {
    /// The access size in bytes.
    pub const fn bytes(self) -> u32 {
        match self {
            Width::Byte => 1,
            Width::Half => 2,
            Width::Word => 4,
        }
    }
}

/// Time since the emulated power-up, in nanoseconds.
pub type Nanos = u64;

/// The clock frequencies the reset and clock control (RCC) model derives from its registers
/// (RM0090 §7.2 "Clocks"), in hertz. A peripheral whose clock is not enabled reads as such
/// through [`Machine::clock_enabled`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Clocks {
    /// The system clock, SYSCLK.
    pub sysclk: u32,
    /// The AHB clock, HCLK (the core and SysTick).
    pub hclk: u32,
    /// The APB1 peripheral clock, PCLK1 (bxCAN, USART2/3, UART4/5).
    pub pclk1: u32,
    /// The APB2 peripheral clock, PCLK2 (USART1/6).
    pub pclk2: u32,
}

impl Clocks {
    /// The clocks at reset: the 16 MHz HSI, no prescaler (RM0090 §7.2).
    pub const RESET: Clocks =
        Clocks { sysclk: 16_000_000, hclk: 16_000_000, pclk1: 16_000_000, pclk2: 16_000_000 };
}

/// A peripheral clock-enable bit of RCC: the register (AHB1ENR, APB1ENR, APB2ENR) and bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockGate {
    /// RCC_AHB1ENR bit n (GPIOx, RM0090 §7.3.10).
    Ahb1(u8),
    /// RCC_APB1ENR bit n (CAN1 = 25, USART2 = 17, RM0090 §7.3.13).
    Apb1(u8),
    /// RCC_APB2ENR bit n (USART1 = 4, USART6 = 5, RM0090 §7.3.14).
    Apb2(u8),
}

impl ClockGate {
    /// The RCC register that holds the gate's enable bit.
    pub const fn register(self) -> &'static str {
        match self {
            ClockGate::Ahb1(_) => "RCC_AHB1ENR",
            ClockGate::Apb1(_) => "RCC_APB1ENR",
            ClockGate::Apb2(_) => "RCC_APB2ENR",
        }
    }

    /// The bit's number in [`ClockGate::register`].
    pub const fn bit(self) -> u8 {
        match self {
            ClockGate::Ahb1(bit) | ClockGate::Apb1(bit) | ClockGate::Apb2(bit) => bit,
        }
    }

    /// The enable bit's name in RM0090 §7.3.10, §7.3.13 and §7.3.14 (`"CAN1EN"`), for the bits
    /// of the peripherals the models cover and their neighbours; `None` for the others.
    pub const fn bit_name(self) -> Option<&'static str> {
        const AHB1: [&str; 9] = [
            "GPIOAEN", "GPIOBEN", "GPIOCEN", "GPIODEN", "GPIOEEN", "GPIOFEN", "GPIOGEN", "GPIOHEN", "GPIOIEN",
        ];
        match self {
            ClockGate::Ahb1(bit) if (bit as usize) < AHB1.len() => Some(AHB1[bit as usize]),
            ClockGate::Apb1(11) => Some("WWDGEN"),
            ClockGate::Apb1(17) => Some("USART2EN"),
            ClockGate::Apb1(18) => Some("USART3EN"),
            ClockGate::Apb1(19) => Some("UART4EN"),
            ClockGate::Apb1(20) => Some("UART5EN"),
            ClockGate::Apb1(25) => Some("CAN1EN"),
            ClockGate::Apb1(26) => Some("CAN2EN"),
            ClockGate::Apb1(28) => Some("PWREN"),
            ClockGate::Apb2(4) => Some("USART1EN"),
            ClockGate::Apb2(5) => Some("USART6EN"),
            ClockGate::Apb2(14) => Some("SYSCFGEN"),
            _ => None,
        }
    }
}

/// `RCC_APB1ENR.CAN1EN (bit 25)`, or `RCC_APB1ENR bit 27` for a bit without a name here.
impl fmt::Display for ClockGate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.bit_name() {
            Some(name) => write!(f, "{}.{name} (bit {})", self.register(), self.bit()),
            None => write!(f, "{} bit {}", self.register(), self.bit()),
        }
    }
}

/// Which reset the machine performs (RM0090 §7.1 "Reset").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetKind {
    /// Power-on reset (RM0090 §7.1.3): every register to its reset value, and what only a power
    /// cycle clears (the backup domain, the RCC_CSR reset flags as "POR") too.
    PowerOn,
    /// System reset (RM0090 §7.1.2), e.g. the core's SYSRESETREQ: every register to its reset
    /// value except the RCC_CSR reset flags and the backup domain; flash contents and SRAM stay.
    System,
}

/// What caused a system reset, for the RCC_CSR flags (RM0090 §7.1, §7.3.21).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    /// SYSRESETREQ of the core (SFTRSTF).
    Software,
    /// The independent watchdog (IWDGRSTF).
    IndependentWatchdog,
    /// The window watchdog (WWDGRSTF).
    WindowWatchdog,
    /// The NRST pin pulled low from outside (PINRSTF).
    Pin,
}

/// What a model may ask of the rest of the machine during an access or an [`Peripheral::advance`].
pub trait Machine {
    /// The clock frequencies now in force.
    fn clocks(&self) -> Clocks;
    /// Whether the clock gate of a peripheral is open.
    fn clock_enabled(&self, gate: ClockGate) -> bool;
    /// Drives an interrupt line of the NVIC (its position in the vector table, RM0090 §12.2
    /// table 61): level-sensitive, as the STM32's peripheral interrupt lines are.
    fn set_irq(&mut self, irq: u16, level: bool);
    /// Time since power-up.
    fn now(&self) -> Nanos;
    /// The flash memory array (RM0090 §3.3 "Embedded flash memory", 1 MiB from 0x0800_0000,
    /// offset 0 = that address), for the FLASH interface model to erase and program. The
    /// machine keeps it across resets and power cycles, shows the CPU every change once the
    /// access that made it returns, and lets no CPU store reach it directly: those come to
    /// [`Peripheral::flash_store`]. `None` where there is no array (a model's unit test).
    fn flash_memory(&mut self) -> Option<&mut [u8]> {
        None
    }
    /// Ends the access being answered in a bus error (RM0090 §3.6.1: a wrong key sequence
    /// to FLASH_KEYR "generates a bus error"). The machine stops and reports the access; the
    /// default ignores it.
    fn bus_error(&mut self) {}
    /// The model refused the access being answered because `gate`, its RCC clock enable bit,
    /// is clear (a read returned 0, a write was lost: see the [module docs](self)). The machine
    /// stops after the access and reports it with the address; the default ignores it.
    fn unclocked_access(&mut self, gate: ClockGate) {
        let _ = gate;
    }
    /// The power fails during the access being answered (a planned power cut of the FLASH
    /// model, [`crate::flash::Flash::plan_power_cut`]): the machine stops the core after it and
    /// reports the cut. The default ignores it.
    fn power_cut(&mut self) {}
    /// Whether the core runs code from the flash array (the instruction executing is at
    /// 0x0800_0000 or its alias at 0), so that its next instruction fetch stalls while the FLASH
    /// interface is busy (RM0090 §3.6.4). The default: no.
    fn fetches_from_flash(&self) -> bool {
        false
    }
    /// Stalls the core for `nanos` (the bus held the access, e.g. the flash interface while BSY
    /// is set, RM0090 §3.6.1): the machine adds the time to its clock. The default ignores it.
    fn stall(&mut self, nanos: Nanos) {
        let _ = nanos;
    }
    /// Asks for a system reset (RM0090 §7.1.2) for `cause` (the IWDG's count reaching 0): the
    /// machine performs it before the next instruction and tells every model the cause
    /// ([`Peripheral::record_reset_cause`]). The default ignores it.
    fn system_reset(&mut self, cause: ResetCause) {
        let _ = cause;
    }
}

/// A register-level model of one peripheral.
pub trait Peripheral {
    /// A short name for messages (`"bxCAN1"`, `"USART2"`).
    fn name(&self) -> &'static str;
    /// Reads `width` bytes at `offset` within the block. Reserved addresses read 0.
    fn read(&mut self, offset: u32, width: Width, machine: &mut dyn Machine) -> u32;
    /// Writes `width` bytes at `offset` within the block. What the hardware ignores, the model
    /// ignores; what the hardware refuses (a protected register outside its mode), the model
    /// refuses the same way.
    fn write(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine);
    /// Advances the model's time to `now` (nanoseconds since power-up).
    fn advance(&mut self, now: Nanos, machine: &mut dyn Machine) {
        let _ = (now, machine);
    }
    /// Puts the model's registers to their reset values (RM0090 §7.1). The default does nothing,
    /// for a model that the machine builds anew instead.
    fn reset(&mut self, kind: ResetKind) {
        let _ = kind;
    }
    /// The next time at which the model changes state on its own (a frame's last bit, a
    /// character's stop bit), so that a sleeping core (WFI) can skip straight to it. `None`: the
    /// model has nothing scheduled; the machine still advances it at its regular period.
    fn next_event(&self) -> Option<Nanos> {
        None
    }
    /// For the FLASH interface model only: a CPU store of `width` bytes of `value` at `offset`
    /// into the flash memory array (RM0090 §3.6.2 "Programming"). The model programs the array
    /// through [`Machine::flash_memory`] if its registers allow it, or sets its error flags;
    /// it returns `true` to say it is the model that takes these stores. The default, `false`,
    /// is every other model's answer.
    fn flash_store(&mut self, offset: u32, width: Width, value: u32, machine: &mut dyn Machine) -> bool {
        let _ = (offset, width, value, machine);
        false
    }
    /// For a FLASH model that keeps the array itself instead of using
    /// [`Machine::flash_memory`]: the array's contents (1 MiB, offset 0 = 0x0800_0000). The
    /// machine shows the CPU these after every access to the model and every
    /// [`Peripheral::flash_store`]. `None` (the default) for every other model.
    fn flash_array(&self) -> Option<&[u8]> {
        None
    }
    /// For a FLASH model that keeps the array itself: a programmer's download of `bytes` at
    /// `offset` into the array (the ELF loaded before power-on), no register involved. The
    /// default ignores it.
    fn flash_load(&mut self, offset: u32, bytes: &[u8]) {
        let _ = (offset, bytes);
    }
    /// For the FLASH model only: the program and erase operations it started so far (what
    /// [`crate::flash::Flash::plan_power_cut`] counts). `None` (the default) for every other
    /// model.
    fn flash_operations(&self) -> Option<u64> {
        None
    }
    /// For the RCC model only: the clocks its registers now select. The machine answers
    /// [`Machine::clocks`] from the registered model that returns `Some`.
    fn clocks(&self) -> Option<Clocks> {
        None
    }
    /// For the RCC model only: whether `gate` is open. The machine answers
    /// [`Machine::clock_enabled`] from the registered model that returns `Some`.
    fn clock_gate(&self, gate: ClockGate) -> Option<bool> {
        let _ = gate;
        None
    }
    /// For the RCC model only: the cause of the system reset just performed (after
    /// [`Peripheral::reset`]), for its RCC_CSR flags. The default ignores it.
    fn record_reset_cause(&mut self, cause: ResetCause) {
        let _ = cause;
    }
}
