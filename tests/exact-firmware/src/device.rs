//! [`EmulatedBoard`]: the exact firmware ELF of one board on the stm32-emu models, a
//! [`SimDevice`] of the simulated CAN bus, with the simulated breaker on its instrument USART.
//!
//! ## Time
//!
//! The machine's clock (nanoseconds since its power-up) tracks the bus's virtual clock
//! (microseconds): at power-on the two are tied, and from then on every bus instant is the
//! machine time that many microseconds later. The bus calls the board at least every
//! [`STEP`] while the CPU runs; the CPU runs up to each instant it is called at before a frame
//! is delivered to it, so a frame arrives at the time it completes on the wire.
//!
//! ## The CAN side
//!
//! Frames reach the bxCAN model through its bus side (stm32-emu `bxcan::bus`) at the bus's bit
//! rate: a controller at another rate counts a receive error (REC) instead. What the controller
//! offers is taken after each run: at the bus's rate it goes on the bus (the master acknowledges
//! it, [`TxOutcome::Acknowledged`]); at another rate it is destroyed by the master's error flag
//! ([`TxOutcome::ErrorFlagged`], TEC + 8) and offered again one frame time later, so the node
//! never joins. The simulated bus itself has no error flags: a frame the controller at the
//! wrong rate flags is still delivered to the other nodes (no other node is at risk here).
//!
//! ## The instrument line
//!
//! Characters the instrument USART sends are sampled at the breaker's line (9600 bit/s 8N1, the
//! reference configuration's instrument line, slave-fw/src/image.rs) and handed to the
//! [`SimulatedBreaker`] at the time their stop bit ends; the breaker's bytes go to the USART's
//! receiver as characters at 9600 8N1, one after the other, from the instant it sends them. The
//! RS-485 driver enable is not looked at (the line is a point-to-point wire here).
//!
//! ## On real interfaces
//!
//! exact-firmware-serve ([`crate::serve`]) takes the line from the breaker
//! ([`EmulatedBoard::detach_breaker`]) and serves the USART's characters on a pty itself; it sets
//! the bus's rate from its SLCAN host's `Sn` ([`EmulatedBoard::set_bus_rate`]) and whether any
//! node acknowledges ([`EmulatedBoard::set_acknowledging`]: not while the host's channel is
//! closed, when the board is alone on its bus).

use crate::board::{BoardKind, NodeSetting};
use crate::shared::Shared;
use crate::uid::unique_id_for_serial;
use can_io::bus::Bitrate;
use can_io::sim::SimDevice;
use converter_sim::SimulatedBreaker;
use devicenet::{CanFrame, CanId, Instant, MacId};
use std::cell::RefCell;
use std::collections::VecDeque;
use std::path::Path;
use std::rc::Rc;

thread_local! {
    /// The wall-clock instant after which every machine of this thread stops
    /// ([`set_wall_deadline`]).
    static WALL_DEADLINE: std::cell::Cell<Option<std::time::Instant>> = const { std::cell::Cell::new(None) };
}

/// Bounds the wall time of the machines this thread runs from now on: past `deadline` a machine
/// stops with a fault (`no verdict within the wall-time limit`), so that firmware that keeps the
/// emulator busy (a register it spins on never changing) ends its scenario with a FAIL instead of
/// hanging the runner. `None` lifts the bound.
pub fn set_wall_deadline(deadline: Option<std::time::Instant>) {
    WALL_DEADLINE.with(|d| d.set(deadline));
}
use stm32_emu::bxcan::{Bxcan, Frame, FrameId, TxOutcome, CAN1_BASE};
use stm32_emu::flash::{CutKind, Flash};
use stm32_emu::gpio::{Gpio, Port};
use stm32_emu::machine::{Fault, Stm32};
use stm32_emu::periph::Nanos;
use stm32_emu::rcc::{Rcc, BASE as RCC_BASE};
use stm32_emu::usart::line::{Character, LineSettings, Receiver};
use stm32_emu::usart::{Usart, UsartId};

/// The longest the bus lets the CPU run unattended: frames it queues are taken this late at most.
pub const STEP: Nanos = 250_000;
/// The serial number of the reference transcript (protocol §2); the emulated chip's
/// unique ID folds to it ([`crate::uid`]).
pub const REFERENCE_SERIAL: u32 = 0x1234_5678;
/// The breaker's line: the reference configuration's 9600 bit/s, 8N1.
pub const BREAKER_LINE: LineSettings = LineSettings::new_8n1(9600.0);

/// What the CAN side has seen, for the scenarios' checks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CanCounts {
    /// Frames the controller put on the bus.
    pub sent: u64,
    /// Frames the controller offered at a bit rate the bus does not run.
    pub flagged: u64,
    /// The highest transmit error counter seen.
    pub peak_tec: u8,
    /// The highest receive error counter seen.
    pub peak_rec: u8,
    /// Times the controller went bus-off.
    pub bus_offs: u64,
    /// Frames received from the bus.
    pub received: u64,
    /// Deliveries after which a receive FIFO showed FOVR (a message lost, RM0090 §32.7.5).
    pub overruns: u64,
}

/// What is flashed into a board before its first power-on: the firmware ELF and, on a board with
/// the firmware update (issue 31), the bootloader ELF that starts it. Both are programmed at their
/// load addresses, as a probe flashes them; the reset vector is then the bootloader's.
#[derive(Clone, Debug)]
pub struct Firmware {
    /// The firmware (`slave-fw-firmware`) ELF.
    pub elf: Vec<u8>,
    /// The bootloader ELF, if the board has one.
    pub bootloader: Option<Vec<u8>>,
    /// The same board's `fault-never-confirm` build at another revision, if there is one: the
    /// image of the rollback scenario (`firmware-update-rollback`).
    pub never_confirm: Option<Vec<u8>>,
    /// The same board's firmware built at another revision, if there is one: the image of the
    /// update over the bus (`firmware-update`).
    pub newer: Option<Vec<u8>>,
}

impl Firmware {
    /// The firmware `elf`, started by `bootloader` when there is one.
    pub fn new(elf: Vec<u8>, bootloader: Option<Vec<u8>>) -> Firmware {
        Firmware { elf, bootloader, never_confirm: None, newer: None }
    }

    /// The firmware ELF at `elf` and its bootloader: `bootloader` when given, else, for a firmware
    /// linked at ACTIVE (`board::flash_layout::ACTIVE`, which needs the bootloader to start it), the
    /// build beside it, `bootloader-<board>` (scripts/build-bootloader's name); a firmware linked at
    /// the start of flash (before issue 31) runs alone. The `fault-never-confirm` build and the
    /// build at another revision are taken from beside the firmware ELF, its name with
    /// `-never-confirm` and `-newer` appended (scripts/exact-firmware's copies), when they are
    /// there. Errors name the file.
    pub fn from_files(board: &str, elf: &Path, bootloader: Option<&Path>) -> Result<Firmware, String> {
        let read = |path: &Path| std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()));
        let firmware = read(elf)?;
        let segments =
            stm32_emu::cpu::elf::load_segments(&firmware).map_err(|e| format!("{}: {e}", elf.display()))?;
        let Some(lowest) = segments.iter().map(|(address, _)| *address).min() else {
            return Err(format!("{}: no loadable segment", elf.display()));
        };
        let bootloader = match bootloader {
            Some(path) => Some(read(path)?),
            None if lowest >= board::flash_layout::ACTIVE.base => {
                let beside = elf.with_file_name(format!("bootloader-{board}"));
                Some(read(&beside).map_err(|e| {
                    format!("{e} (the firmware is linked at ACTIVE: it needs the board's bootloader, --bootloader or scripts/build-bootloader)")
                })?)
            }
            None => None,
        };
        let beside = |suffix: &str| {
            let mut name = elf.as_os_str().to_owned();
            name.push(suffix);
            match std::fs::read(&name) {
                Ok(bytes) => Ok(Some(bytes)),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
                Err(e) => Err(format!("{}: {e}", Path::new(&name).display())),
            }
        };
        let (never_confirm, newer) = (beside("-never-confirm")?, beside("-newer")?);
        Ok(Firmware { elf: firmware, bootloader, never_confirm, newer })
    }

    /// The ELF files in the order they are flashed: the bootloader first.
    pub fn images(&self) -> Vec<&[u8]> {
        self.bootloader.iter().map(Vec::as_slice).chain([self.elf.as_slice()]).collect()
    }
}

/// The exact firmware of one board on the models. See the [module docs](self).
pub struct EmulatedBoard {
    kind: BoardKind,
    mcu: Stm32,
    can: Rc<RefCell<Bxcan>>,
    instrument: Rc<RefCell<Usart>>,
    iwdg: Rc<RefCell<stm32_emu::iwdg::Iwdg>>,
    setting: NodeSetting,
    bus_rate: u32,
    breaker: SimulatedBreaker,
    /// The breaker is on the instrument line (not after [`EmulatedBoard::detach_breaker`]).
    breaker_attached: bool,
    /// Another node acknowledges the controller's frames (not when the board is alone).
    acknowledging: bool,
    outbox: VecDeque<CanFrame>,
    /// The bus instant (µs) and machine time tied at power-on.
    epoch: Option<(u64, Nanos)>,
    /// A frame the bus cannot carry is offered again from then.
    next_attempt: Nanos,
    counts: CanCounts,
    was_bus_off: bool,
    /// The machine time of a planned power cut that happened.
    power_cut: Option<Nanos>,
    fault: Option<String>,
    /// Every GPIO port's model: the switches' inputs, the LEDs' outputs.
    gpios: Vec<(Port, Rc<RefCell<Gpio>>)>,
    /// [`EmulatedBoard::watch`]: the longest slice the CPU runs, and what looks at the machine
    /// after each.
    watch: Option<(Nanos, SliceWatch)>,
}

/// What [`EmulatedBoard::watch`] calls after each slice of CPU time.
pub type SliceWatch = Box<dyn FnMut(&mut Stm32)>;

impl EmulatedBoard {
    /// The board `kind` with `elf` (and its bootloader) in its flash, set to `setting` (switches and settings journal),
    /// on a bus at `bus_rate`; powered off until [`SimDevice::power_on`].
    pub fn new(
        kind: BoardKind,
        elf: &Firmware,
        setting: NodeSetting,
        bus_rate: Bitrate,
    ) -> Result<Self, Fault> {
        EmulatedBoard::with_power_cut(kind, elf, setting, bus_rate, None)
    }

    /// [`EmulatedBoard::new`] with a power cut planned at flash operation `cut.0` (counted from
    /// the power-up, [`Stm32::flash_operations`]): the machine stops there
    /// ([`EmulatedBoard::power_cut`]) until the next power-on, on the flash array as it left it.
    pub fn with_power_cut(
        kind: BoardKind,
        elf: &Firmware,
        setting: NodeSetting,
        bus_rate: Bitrate,
        cut: Option<(u64, CutKind)>,
    ) -> Result<Self, Fault> {
        let mut flash = Flash::new();
        if let Some((operation, how)) = cut {
            flash.plan_power_cut(operation, how);
        }
        EmulatedBoard::with_flash(kind, elf, setting, bus_rate, flash)
    }

    /// [`EmulatedBoard::new`] on the FLASH model `flash` as given (its timing, a planned power
    /// cut), `elf` and the settings then programmed into it.
    pub fn with_flash(
        kind: BoardKind,
        elf: &Firmware,
        setting: NodeSetting,
        bus_rate: Bitrate,
        flash: Flash,
    ) -> Result<Self, Fault> {
        let mut mcu = Stm32::new(kind.chip(), unique_id_for_serial(REFERENCE_SERIAL))?;
        mcu.add_peripheral(RCC_BASE, 0x400, Box::new(Rcc::new(kind.hse())))?;
        mcu.add_flash(flash)?;
        mcu.add_peripheral(stm32_emu::pwr::BASE, 0x400, Box::new(stm32_emu::pwr::Pwr::new(kind.chip())))?;
        // The bootloader starts it before every jump; the firmware feeds it (issue 31).
        let iwdg = Shared::new(stm32_emu::iwdg::Iwdg::new());
        let iwdg_handle = iwdg.handle();
        mcu.add_peripheral(stm32_emu::iwdg::BASE, 0x400, Box::new(iwdg))?;
        let mut switch_port = None;
        let mut gpios = Vec::new();
        for port in [Port::A, Port::B, Port::C, Port::D, Port::E, Port::H] {
            let gpio = Shared::new(Gpio::new(port));
            if kind.switches().is_some_and(|(p, _)| p == port) {
                switch_port = Some(gpio.handle());
            }
            gpios.push((port, gpio.handle()));
            mcu.add_peripheral(port.base(), 0x400, Box::new(gpio))?;
        }
        let mut instrument = None;
        for id in [UsartId::Usart1, UsartId::Usart2] {
            let usart = Shared::new(Usart::new(id));
            if id == kind.instrument_usart() {
                instrument = Some(usart.handle());
            }
            mcu.add_peripheral(id.base(), 0x400, Box::new(usart))?;
        }
        let can = Shared::new(Bxcan::new());
        let can_handle = can.handle();
        mcu.add_peripheral(CAN1_BASE, 0x400, Box::new(can))?;
        mcu.load_elfs(&elf.images())?;
        mcu.program_flash(kind.settings_offset(), &setting.record(kind.switches().is_some()))?;
        if let (Some(gpio), Some((_, first))) = (switch_port, kind.switches()) {
            // Each switch closes its pin to ground against the pull-up: "on" reads low.
            let bits = setting.switch_bits();
            for i in 0..8 {
                let on = bits >> i & 1 == 1;
                gpio.borrow_mut().drive_pin(first + i, on.then_some(false));
            }
        }
        let Some(instrument) = instrument else {
            return Err(Fault::Emulator(format!("{}: no instrument USART", kind.name)));
        };
        let mut breaker = SimulatedBreaker::new(Instant::ZERO);
        breaker.set_load(converter_sim::device::LOAD);
        Ok(EmulatedBoard {
            kind,
            mcu,
            can: can_handle,
            instrument,
            iwdg: iwdg_handle,
            setting,
            bus_rate: bus_rate.bits_per_second(),
            breaker,
            breaker_attached: true,
            acknowledging: true,
            outbox: VecDeque::new(),
            epoch: None,
            next_attempt: 0,
            counts: CanCounts::default(),
            was_bus_off: false,
            power_cut: None,
            fault: None,
            gpios,
            watch: None,
        })
    }

    /// The model of GPIO port `port` (the world's handle: drive its inputs, read its outputs).
    pub fn gpio(&self, port: Port) -> Option<Rc<RefCell<Gpio>>> {
        self.gpios.iter().find(|(p, _)| *p == port).map(|(_, g)| Rc::clone(g))
    }

    /// From now on the CPU runs at most `slice` at a time and `watch` looks at the machine after
    /// each slice (`None` ends it): e.g. to see each flash operation on its own.
    pub fn watch(&mut self, watch: Option<(Nanos, SliceWatch)>) {
        self.watch = watch;
    }

    /// The board.
    pub fn kind(&self) -> BoardKind {
        self.kind
    }

    /// Why the machine stopped (a fault of the firmware or of the emulation), if it did.
    pub fn fault(&self) -> Option<&str> {
        self.fault.as_deref()
    }

    /// When the planned power cut happened (machine time), if it did: the board is dead until
    /// it is powered on again.
    pub fn power_cut(&self) -> Option<Nanos> {
        self.power_cut
    }

    /// The flash operations so far ([`Stm32::flash_operations`]).
    pub fn flash_operations(&self) -> u64 {
        self.mcu.flash_operations().unwrap_or(0)
    }

    /// The system resets the independent watchdog caused since the board was built.
    pub fn watchdog_resets(&self) -> u32 {
        self.iwdg.borrow().watchdog_resets()
    }

    /// The simulated breaker on the instrument line.
    pub fn breaker(&self) -> &SimulatedBreaker {
        &self.breaker
    }

    /// Takes the instrument line away from the simulated breaker: the USART's characters then
    /// stay in its model ([`EmulatedBoard::instrument_usart`]) for whoever serves the line.
    pub fn detach_breaker(&mut self) {
        self.breaker_attached = false;
    }

    /// The instrument USART model (what the line outside the chip reaches).
    pub fn instrument_usart(&self) -> Rc<RefCell<Usart>> {
        Rc::clone(&self.instrument)
    }

    /// The bus's bit rate from now on (an SLCAN host's `Sn`).
    pub fn set_bus_rate(&mut self, bits_per_second: u32) {
        self.bus_rate = bits_per_second;
    }

    /// Whether another node acknowledges the controller's frames: without one, each is
    /// [`TxOutcome::NoAcknowledge`] and offered again one frame time later (TEC + 8 up to error
    /// passive, ISO 11898-1 rule 3a), as on a bus with no other node.
    pub fn set_acknowledging(&mut self, acknowledging: bool) {
        self.acknowledging = acknowledging;
    }

    /// The instrument USART's line as its registers set it.
    pub fn instrument_line(&self) -> LineSettings {
        self.instrument.borrow().settings()
    }

    /// The machine.
    pub fn mcu(&mut self) -> &mut Stm32 {
        &mut self.mcu
    }

    /// `len` bytes of the flash array from `address` (0x0800_0000 on), as far as the array goes.
    pub fn mcu_flash(&self, address: u32, len: usize) -> Vec<u8> {
        let start = address.saturating_sub(board::memory::FLASH_BASE) as usize;
        self.mcu.flash().iter().skip(start).take(len).copied().collect()
    }

    /// The newest valid record of the settings journal in flash (board/src/settings.rs: the
    /// highest sequence number across both sectors), decoded by the board crate.
    pub fn stored_settings(&self) -> Option<(board::settings::Settings, u32)> {
        let flash = self.mcu.flash();
        let layout = self.kind.spec.flash;
        let mut newest: Option<(board::settings::Settings, u32)> = None;
        for base in layout.settings_bases {
            let start = (base - board::memory::FLASH_BASE) as usize;
            let sector = flash.get(start..start + layout.settings_sector_size as usize)?;
            for chunk in sector.chunks_exact(board::settings::RECORD_LEN) {
                let Ok(record) = chunk.try_into() else { continue };
                if let Ok((settings, sequence)) = board::settings::Settings::decode(record) {
                    if newest.as_ref().is_none_or(|(_, n)| sequence > *n) {
                        newest = Some((settings, sequence));
                    }
                }
            }
        }
        newest
    }

    /// The bxCAN model's error counters (TEC, REC) and whether it is bus-off.
    pub fn can_errors(&self) -> (u8, u8, bool) {
        let can = self.can.borrow();
        let (tec, rec) = can.error_counters();
        (tec, rec, can.is_bus_off())
    }

    /// Breaks the bxCAN's loop back path from power-up (stm32-emu `Bxcan::set_loopback_broken`):
    /// the fault the firmware's CAN self-test is meant to catch.
    pub fn break_can_loopback(&mut self) {
        self.can.borrow_mut().set_loopback_broken(true);
    }

    /// The bxCAN model's operating mode.
    pub fn can_mode(&self) -> stm32_emu::bxcan::Mode {
        self.can.borrow().mode()
    }

    /// `CAN_ESR` as the firmware reads it.
    pub fn esr(&mut self) -> Option<u32> {
        self.mcu.read_peripheral(CAN1_BASE + stm32_emu::bxcan::offset::ESR)
    }

    /// What the CAN side has seen.
    pub fn counts(&self) -> CanCounts {
        self.counts
    }

    fn nanos(&self, at: Instant) -> Nanos {
        match self.epoch {
            Some((bus_us, base)) => base + at.total_micros().saturating_sub(bus_us) * 1000,
            None => self.mcu.now(),
        }
    }

    fn instant(&self, t: Nanos) -> Instant {
        match self.epoch {
            Some((bus_us, base)) => Instant::from_micros(bus_us + t.saturating_sub(base).div_ceil(1000)),
            None => Instant::ZERO,
        }
    }

    /// Runs the CPU to `target`, the instrument line serviced as it goes.
    fn run_to(&mut self, target: Nanos) {
        while self.fault.is_none() && self.power_cut.is_none() && self.mcu.now() < target {
            let now = self.mcu.now();
            let mut until = target.min(now + STEP);
            if let Some((slice, _)) = &self.watch {
                until = until.min(now + slice);
            }
            if let Some(at) = self.breaker.poll_at().filter(|_| self.breaker_attached) {
                until = until.min(self.nanos(at).max(now + 1));
            }
            if WALL_DEADLINE.with(|d| d.get()).is_some_and(|d| std::time::Instant::now() >= d) {
                self.fault = Some(format!(
                    "no verdict within the wall-time limit, the machine at {} ns (busy, e.g. spinning on a register)",
                    now
                ));
                return;
            }
            match self.mcu.run_for(until - now) {
                Ok(()) => {}
                Err(Fault::PowerCut { at }) => {
                    self.power_cut = Some(at);
                    return;
                }
                Err(fault) => self.fault = Some(format!("{fault} at {} ns", self.mcu.now())),
            }
            if let Some((_, watch)) = &mut self.watch {
                watch(&mut self.mcu);
            }
            self.service_line();
        }
    }

    /// Moves characters between the instrument USART and the breaker.
    fn service_line(&mut self) {
        if !self.breaker_attached {
            return;
        }
        let receiver = Receiver { settings: BREAKER_LINE, over8: false, one_bit: false };
        let mut sent = Vec::new();
        while let Some(t) = self.instrument.borrow_mut().pop_transmitted() {
            let got = receiver.sample(&t.character);
            if !got.framing_error && !got.parity_error {
                sent.push((t.end, got.word as u8));
            }
        }
        for (end, byte) in sent {
            let at = self.instant(end);
            self.breaker.on_bytes(&[byte], at);
        }
        let now = self.mcu.now();
        let at = self.instant(now);
        while let Some(bytes) = self.breaker.poll_transmit(at) {
            let mut usart = self.instrument.borrow_mut();
            for &b in &bytes {
                usart.receive(Character::encode(u16::from(b), BREAKER_LINE), now);
            }
        }
    }

    /// Keeps the error counters' peaks and counts bus-off entries.
    fn note_errors(&mut self) {
        let (tec, rec, bus_off) = self.can_errors();
        self.counts.peak_tec = self.counts.peak_tec.max(tec);
        self.counts.peak_rec = self.counts.peak_rec.max(rec);
        if bus_off && !self.was_bus_off {
            self.counts.bus_offs += 1;
        }
        self.was_bus_off = bus_off;
    }

    /// Counts a delivery after which FOVR is set in either receive FIFO.
    fn note_overrun(&mut self) {
        use stm32_emu::bxcan::{offset, rfr};
        let fifos =
            [offset::RF0R, offset::RF1R].map(|o| self.mcu.read_peripheral(CAN1_BASE + o).unwrap_or(0));
        if fifos.iter().any(|r| r & rfr::FOVR != 0) {
            self.counts.overruns += 1;
        }
    }

    /// Takes what the controller offers: onto the bus at the bus's rate, flagged otherwise.
    fn service_can(&mut self) {
        let now = self.mcu.now();
        if now < self.next_attempt {
            return;
        }
        let can = Rc::clone(&self.can);
        loop {
            let Some(tx) = self.mcu.with_machine(|m| can.borrow_mut().poll_transmit(now, m)) else { return };
            let pclk1 = self.mcu.clocks().pclk1;
            let timing = can.borrow().bit_timing();
            if !self.acknowledging {
                self.mcu
                    .with_machine(|m| can.borrow_mut().transmit_outcome(TxOutcome::NoAcknowledge, now, m));
                self.note_errors();
                self.next_attempt = now + timing.bits_to_nanos(u64::from(tx.frame.wire_bits()), pclk1);
                return;
            }
            if timing.follows(pclk1, self.bus_rate) {
                match to_devicenet(&tx.frame) {
                    Some(frame) => self.outbox.push_back(frame),
                    None => {
                        self.fault = Some(format!(
                            "the controller sent a frame DeviceNet has no use for: {:?}",
                            tx.frame
                        ))
                    }
                }
                self.counts.sent += 1;
                self.mcu.with_machine(|m| can.borrow_mut().transmit_outcome(TxOutcome::Acknowledged, now, m));
            } else {
                // The master, error active at the bus's rate, flags the frame it cannot decode.
                self.counts.flagged += 1;
                self.mcu.with_machine(|m| can.borrow_mut().transmit_outcome(TxOutcome::ErrorFlagged, now, m));
                self.note_errors();
                let bits = u64::from(tx.frame.wire_bits()) + 20; // and the error frame
                self.next_attempt = now + timing.bits_to_nanos(bits, pclk1);
                return;
            }
        }
    }
}

/// The DeviceNet frame of a standard data frame; `None` for extended or remote frames.
fn to_devicenet(frame: &Frame) -> Option<CanFrame> {
    match frame.id() {
        FrameId::Standard(raw) if !frame.is_remote() => CanFrame::new(CanId::new(raw)?, frame.data()).ok(),
        _ => None,
    }
}

impl EmulatedBoard {
    /// Runs the machine up to `now`, the bus's time; false when the board is off (not powered
    /// yet, or its power was cut, now or earlier: what it had queued is then lost).
    fn catch_up(&mut self, now: Instant) -> bool {
        if self.epoch.is_none() || self.power_cut.is_some() {
            return false;
        }
        let t = self.nanos(now);
        self.run_to(t);
        if self.power_cut.is_some() {
            self.outbox.clear();
            return false;
        }
        true
    }
}

impl SimDevice for EmulatedBoard {
    fn mac(&self) -> MacId {
        self.setting.mac
    }

    fn power_on(&mut self, now: Instant) {
        self.epoch = Some((now.total_micros(), self.mcu.now()));
        self.outbox.clear();
        self.next_attempt = 0;
        self.power_cut = None;
        if let Err(fault) = self.mcu.power_on_reset() {
            self.fault = Some(format!("power-on: {fault}"));
        }
    }

    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        if !self.catch_up(now) {
            return;
        }
        let Some(frame) =
            FrameId::standard(frame.id().as_raw()).and_then(|id| Frame::new_data(id, frame.data()))
        else {
            return;
        };
        let (can, rate) = (Rc::clone(&self.can), self.bus_rate);
        let t = self.mcu.now();
        self.mcu.with_machine(|m| can.borrow_mut().on_wire(&frame, rate, false, t, m));
        self.counts.received += 1;
        self.note_errors();
        self.note_overrun();
        self.service_can();
    }

    fn handle_timeout(&mut self, now: Instant) {
        if !self.catch_up(now) {
            return;
        }
        self.note_errors();
        self.service_can();
    }

    fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.outbox.pop_front()
    }

    fn poll_at(&self) -> Option<Instant> {
        if self.epoch.is_none() || self.fault.is_some() || self.power_cut.is_some() {
            return None;
        }
        Some(self.instant(self.mcu.now() + STEP))
    }
}

/// The board on a bus while the scenario keeps its handle: attaching the same board to a new bus
/// powers it on again, a power cycle (SRAM and registers reset, the flash array kept).
pub struct OnBus(pub Rc<RefCell<EmulatedBoard>>);

impl SimDevice for OnBus {
    fn mac(&self) -> MacId {
        self.0.borrow().mac()
    }
    fn power_on(&mut self, now: Instant) {
        self.0.borrow_mut().power_on(now);
    }
    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.0.borrow_mut().handle_frame(frame, now);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.0.borrow_mut().handle_timeout(now);
    }
    fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.0.borrow_mut().poll_transmit()
    }
    fn poll_at(&self) -> Option<Instant> {
        self.0.borrow().poll_at()
    }
}
