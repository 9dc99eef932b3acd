//! The emulated board on real interfaces (`exact-firmware-serve`): the exact ELF on the models,
//! its CAN side behind an SLCAN adapter on a pty, its instrument USART on another pty, its
//! settings flash in a file, in wall time.
//!
//! ```text
//! exact-firmware-serve --board reference --elf target/thumbv7em-none-eabihf/firmware/slave-fw-firmware-reference \
//!     --slcan /dev/pts/7 --instrument /dev/pts/9 --instrument-line 9600,8N1 --flash board.flash
//! dnet-master --bus slcan:/dev/pts/8 connect --mac 5      # the far end of the SLCAN pty pair
//! dnet-sim-breaker --serial /dev/pts/10                   # the far end of the instrument pair
//! ```
//!
//! ## The CAN side: an SLCAN adapter with the board as the other node
//!
//! The SLCAN pty is what a USB-CAN adapter's serial port would be: the host sends `C`, `Sn`,
//! `O` and `tIIIL…` lines and gets `\r`, `z\r` or BEL back (can-io's adapter state machine,
//! `can_io::slcan::Adapter`, the one the QEMU build's firmware runs), and the board's frames as
//! `tIIIL…` lines. The bus between the adapter and the board runs at the host's `Sn` rate: a board
//! at another rate gets its frames flagged and counts errors, as on a real bus. While the host's
//! channel is closed (or listen-only) the adapter is off the bus and the board alone on it: its
//! frames are not acknowledged (TEC up to error passive) and stay pending, and the frame pending
//! when the host opens goes out then, as the real board's would.
//!
//! ## Time
//!
//! The machine runs in wall time, never ahead of it: at each turn of the loop (about 2 ms apart
//! when it keeps up) it runs up to the wall clock's instant, but at most [`SLICE`] (5 ms) of bus
//! time; the host's frames read in a turn reach the board at the time the machine has reached.
//! An emulator slower than the firmware's work needs thus makes the board fall behind the wall
//! clock, and the host sees it answer late, but the firmware's own timers (a fragment's
//! acknowledgement, the duplicate MAC ID check) see the host answer in time, as on the chip; a
//! turn that ran the machine to the wall clock in one go would let them expire first. Behind by
//! more than a slice, the ptys are read without waiting until the machine has caught up.
//! [`Summary::worst_lag`] reports how far behind it fell. Measured on the 2-core test machine
//! under load, debug build: the power-on's start-up 150–700 ms, then turns of 5–10 ms (an
//! explicit request answered in 5–25 ms); the 640 flash operations that store a downloaded
//! configuration about 1.5 s of wall time (0.4 s in a release build), longer than the firmware
//! takes on the chip. The frames on the wire take no time between the adapter and the board (the
//! simulated bus's frame times are not applied).
//!
//! ## The instrument line
//!
//! See [`line`](mod@line): the USART's characters are sampled at `--instrument-line`, the line
//! the far end uses; a BRR, parity or stop bit setting that does not match garbles or drops the bytes.
//!
//! ## Power
//!
//! `--power-on now` (the default) powers the board when the program starts; `--power-on
//! master-online` when the host's master goes on-line (1 s after its second duplicate MAC ID
//! check request, as the simulated bus's default and the reference capture), for the 28-frame
//! bring-up. A power cycle is a stop (SIGINT or SIGTERM: the flash file is saved, a summary
//! printed, exit 0) and a start on the same `--flash` file. The file is also saved 100 ms after
//! the firmware's last flash operation, so a SIGKILL loses nothing older.
//!
//! ## The node's MAC ID and rate
//!
//! On a board with DIP switches (reference) `--mac` and `--rate` are the switches (default 5 and
//! 125k). On a board without them they are the settings record a new flash file starts with;
//! without them a new file is erased (the board as it leaves the factory); with an existing file
//! they must agree with its newest record, or the start is refused.

pub mod flash_file;
pub mod line;

use crate::board::{BoardKind, NodeSetting};
use crate::device::{EmulatedBoard, Firmware};
use can_io::sim::{MasterOnlineWatch, SimDevice};
use can_io::slcan::{self, Adapter, LineBuffer};
use devicenet::slave::BaudRate;
use devicenet::{Instant, MacId};
use flash_file::{FlashFile, FlashFileError};
use line::{InstrumentLine, LineCounts, LineSpec};
use std::io::{Read, Write};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};

/// When the board is powered on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PowerOn {
    /// At the start.
    Now,
    /// When the host's master is on-line (module docs).
    MasterOnline,
}

/// What to serve.
#[derive(Clone, Debug)]
pub struct ServeOptions {
    /// The board.
    pub board: BoardKind,
    /// The ELF's path.
    pub elf: PathBuf,
    /// The bootloader ELF's path (issue 31), flashed beside the firmware; `None`: the firmware only.
    pub bootloader: Option<PathBuf>,
    /// The SLCAN pty (the adapter's serial port).
    pub slcan: String,
    /// The instrument pty.
    pub instrument: String,
    /// The instrument side's line.
    pub instrument_line: LineSpec,
    /// The settings flash file.
    pub flash: PathBuf,
    /// The MAC ID (switches, or a new file's record).
    pub mac: Option<MacId>,
    /// The data rate (switches, or a new file's record).
    pub rate: Option<BaudRate>,
    /// When the board is powered on.
    pub power_on: PowerOn,
}

/// Why serving stopped or could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The firmware ELF or its bootloader cannot be read or has no loadable segment.
    #[error("{reason} (scripts/firmware-size builds every board's ELF into target/thumbv7em-none-eabihf/firmware/, scripts/build-bootloader its bootloader)")]
    Firmware {
        /// What failed, naming the file.
        reason: String,
    },
    /// The machine refused the ELF or the flash contents.
    #[error("{what}: {fault}")]
    Machine {
        /// What was being done.
        what: String,
        /// The emulator's fault.
        fault: stm32_emu::machine::Fault,
    },
    /// A pty cannot be opened.
    #[error("{what} {path}: {source}")]
    Open {
        /// Which one.
        what: &'static str,
        /// Its path.
        path: String,
        /// What failed.
        source: serialport::Error,
    },
    /// Reading a pty failed (its far end gone for good, say).
    #[error("{what} {path}: {source}")]
    Io {
        /// Which one.
        what: &'static str,
        /// Its path.
        path: String,
        /// What failed.
        source: std::io::Error,
    },
    /// The flash file.
    #[error(transparent)]
    Flash(#[from] FlashFileError),
    /// `--mac`/`--rate` given for one without the other on a board without switches.
    #[error("{board} has no switches: give --mac and --rate together (the settings record of a new flash file), or neither")]
    HalfSetting {
        /// The board.
        board: &'static str,
    },
    /// `--mac`/`--rate` disagree with the flash file's newest record.
    #[error(
        "{board} has no switches and {file} holds MAC {stored_mac} at {}k, not --mac {mac} --rate {}k: leave --mac/--rate out, or use a new file",
        .stored_rate.bits_per_second() / 1000,
        .rate.bits_per_second() / 1000
    )]
    SettingDiffers {
        /// The board.
        board: &'static str,
        /// The flash file.
        file: PathBuf,
        /// What it holds.
        stored_mac: u8,
        /// What it holds.
        stored_rate: BaudRate,
        /// What was given.
        mac: u8,
        /// What was given.
        rate: BaudRate,
    },
    /// The firmware (or the emulation) stopped the machine.
    #[error("the machine stopped: {0}")]
    Fault(String),
}

/// What a run did, printed when it ends.
#[derive(Clone, Copy, Debug, Default)]
pub struct Summary {
    /// Wall time served, in seconds.
    pub seconds: f64,
    /// Frames the host put on the bus.
    pub from_host: u64,
    /// Frames of the board sent to the host.
    pub to_host: u64,
    /// Writes to the host the pty did not take (its far end not reading): lost.
    pub lost_to_host: u64,
    /// Writes to the instrument the pty did not take: lost.
    pub lost_to_instrument: u64,
    /// The instrument line.
    pub line: LineCounts,
    /// The worst time, in microseconds, the machine ended a turn behind the wall clock.
    pub worst_lag_us: u64,
    /// The flash operations of the firmware.
    pub flash_operations: u64,
}

impl Summary {
    /// The worst lag behind the wall clock.
    pub fn worst_lag(&self) -> std::time::Duration {
        std::time::Duration::from_micros(self.worst_lag_us)
    }
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:.1} s; CAN: {} frames from the host, {} to it ({} writes lost); instrument: {} bytes out ({} writes lost), {} in, {} garbled; worst lag {:.1} ms; {} flash operations",
            self.seconds,
            self.from_host,
            self.to_host,
            self.lost_to_host,
            self.line.to_instrument,
            self.lost_to_instrument,
            self.line.from_instrument,
            self.line.garbled,
            self.worst_lag_us as f64 / 1000.0,
            self.flash_operations
        )
    }
}

/// A pty opened raw, each read waiting at most [`TURN`].
fn open_pty(what: &'static str, path: &str) -> Result<Box<dyn serialport::SerialPort>, ServeError> {
    serialport::new(path, 115_200).timeout(TURN).open().map_err(|source| ServeError::Open {
        what,
        path: path.to_string(),
        source,
    })
}

/// The longest a read of one pty waits: a turn of the loop takes at most two of these.
pub const TURN: std::time::Duration = std::time::Duration::from_millis(1);
/// The most bus time the machine runs in one turn: what the host sent meanwhile reaches it at
/// most this late, by the machine's clock, however slow the emulator is.
pub const SLICE: devicenet::Duration = devicenet::Duration::from_millis(5);
/// The flash file is saved this long after the firmware's last flash operation.
pub const SAVE_AFTER: std::time::Duration = std::time::Duration::from_millis(100);

/// The board, its flash set up from the file (or new) and `options`' MAC and rate.
fn build_board(options: &ServeOptions, file: &FlashFile) -> Result<(EmulatedBoard, bool), ServeError> {
    let kind = options.board;
    // As the runner does: a firmware linked at ACTIVE takes the bootloader beside it unless one is given.
    let elf = Firmware::from_files(kind.name, &options.elf, options.bootloader.as_deref())
        .map_err(|reason| ServeError::Firmware { reason })?;
    let has_switches = kind.switches().is_some();
    let given = match (options.mac, options.rate) {
        (Some(mac), Some(rate)) => Some((mac, rate)),
        (None, None) => None,
        (mac, rate) if has_switches => {
            Some((mac.unwrap_or(MacId::from_low_bits(5)), rate.unwrap_or(BaudRate::Kbps125)))
        }
        _ => return Err(ServeError::HalfSetting { board: kind.name }),
    };
    let (mac, rate) = given.unwrap_or((MacId::from_low_bits(5), BaudRate::Kbps125));
    let setting = NodeSetting { mac, rate, bus_off_interrupt: false };
    let machine = |what: &str| {
        let what = what.to_string();
        move |fault| ServeError::Machine { what, fault }
    };
    let mut board = EmulatedBoard::new(kind, &elf, setting, rate.into())
        .map_err(machine(&options.elf.display().to_string()))?;
    let loaded = file.load()?;
    let existing = loaded.is_some();
    // A board with switches starts with a record that mirrors them (EmulatedBoard::new); one
    // without keeps the file's journal, the given record, or none (erased).
    let sectors = match loaded {
        Some(sectors) => Some(sectors),
        None if !has_switches && given.is_none() => Some(file.erased()),
        None => None,
    };
    for (offset, bytes) in sectors.iter().flatten() {
        board.mcu().program_flash(*offset, bytes).map_err(machine("the flash file's sectors"))?;
    }
    if existing && !has_switches {
        if let (Some((mac, rate)), Some((stored, _))) = (given, board.stored_settings()) {
            if (stored.mac_id, stored.baud_rate) != (mac, rate) {
                return Err(ServeError::SettingDiffers {
                    board: kind.name,
                    file: file.path().to_path_buf(),
                    stored_mac: stored.mac_id.as_raw(),
                    stored_rate: stored.baud_rate,
                    mac: mac.as_raw(),
                    rate,
                });
            }
        }
    }
    board.detach_breaker();
    Ok((board, existing))
}

/// The bit rate of an `Sn` code (can-io's table, [`slcan::bitrate_code`], read backwards).
fn code_rate(code: u8) -> Option<u32> {
    [10_000, 20_000, 50_000, 100_000, 125_000, 250_000, 500_000, 800_000, 1_000_000]
        .into_iter()
        .find(|&bps| slcan::bitrate_code(bps) == Some(code))
}

/// Serves until `stop` is set (or the machine stops); `started` is told the line printed at the
/// start. The flash file is saved on the way out, whatever ended the run.
pub fn serve(
    options: &ServeOptions,
    stop: &AtomicBool,
    started: &mut dyn FnMut(&str),
) -> Result<Summary, ServeError> {
    let file = FlashFile::new(&options.flash, options.board);
    let (mut board, existing) = build_board(options, &file)?;
    let mut can = open_pty("SLCAN pty", &options.slcan)?;
    let mut instrument_port = open_pty("instrument pty", &options.instrument)?;
    let usart = board.instrument_usart();
    let mut line = InstrumentLine::new(options.instrument_line);
    let mut adapter = Adapter::new();
    let mut host_line = LineBuffer::new();
    let mut watch = MasterOnlineWatch::default();
    let mut power_at: Option<Instant> = match options.power_on {
        PowerOn::Now => Some(Instant::ZERO),
        PowerOn::MasterOnline => None,
    };
    let mut powered = false;
    board.set_acknowledging(false);
    let origin = std::time::Instant::now();
    let clock = || Instant::from_micros(u64::try_from(origin.elapsed().as_micros()).unwrap_or(u64::MAX));
    started(&format!(
        "{} started: SLCAN adapter on {}, instrument on {} at {}, flash {} ({}), power-on {}",
        options.board.name,
        options.slcan,
        options.instrument,
        options.instrument_line,
        options.flash.display(),
        if existing { "loaded" } else { "new" },
        match options.power_on {
            PowerOn::Now => "now",
            PowerOn::MasterOnline => "when the master is on-line",
        }
    ));
    let mut summary = Summary::default();
    let mut saved_ops = board.flash_operations();
    let mut last_change: Option<std::time::Instant> = None;
    let mut buf = [0u8; 512];
    let mut machine_at = Instant::ZERO;
    let outcome = loop {
        if stop.load(Ordering::Relaxed) {
            break Ok(());
        }
        if let Some(fault) = board.fault() {
            break Err(ServeError::Fault(fault.to_string()));
        }
        // The bus's instant is the machine's: host frames are delivered at the time it has reached.
        let now = machine_at;
        // Behind the wall clock by more than a slice: no waiting on the ptys, catch up.
        let wait = if clock() > now + SLICE { std::time::Duration::ZERO } else { TURN };
        if let Err(source) = can.set_timeout(wait) {
            break Err(ServeError::Open { what: "SLCAN pty", path: options.slcan.clone(), source });
        }
        if let Err(source) = instrument_port.set_timeout(wait) {
            break Err(ServeError::Open { what: "instrument pty", path: options.instrument.clone(), source });
        }
        if !powered && power_at.is_some_and(|at| now >= at) {
            board.power_on(now);
            powered = true;
        }
        // The host's lines: answers back at once, frames onto the bus.
        let n = match can.read(&mut buf) {
            Ok(n) => n,
            Err(e) if no_data(&e) => 0,
            Err(source) => {
                break Err(ServeError::Io { what: "SLCAN pty", path: options.slcan.clone(), source })
            }
        };
        let mut replies = Vec::new();
        for &b in &buf[..n] {
            let Some(got) = host_line.push(b) else { continue };
            let response = adapter.handle_line(got);
            replies.extend_from_slice(response.reply);
            if let Some(frame) = response.frame {
                summary.from_host += 1;
                if let Some(online) = watch.sent(&frame, now) {
                    power_at.get_or_insert(online);
                }
                board.handle_frame(&frame, now);
            }
        }
        if let Some(bps) = adapter.bitrate().and_then(code_rate) {
            board.set_bus_rate(bps);
        }
        // Bit 1 of the adapter's state: listen-only, which acknowledges nothing.
        board.set_acknowledging(adapter.is_open() && adapter.to_bits() & 2 == 0);
        // The instrument's bytes, as far as the line has room; lost while the board is off.
        let now_ns = board.mcu().now();
        let room = if powered { line.room(now_ns).min(buf.len()) } else { buf.len() };
        if room > 0 {
            match instrument_port.read(&mut buf[..room]) {
                Ok(n) if powered => line.to_usart(&mut usart.borrow_mut(), &buf[..n], now_ns),
                Ok(_) => {}
                Err(e) if no_data(&e) => {}
                Err(source) => {
                    break Err(ServeError::Io {
                        what: "instrument pty",
                        path: options.instrument.clone(),
                        source,
                    })
                }
            }
        }
        let target = clock().min(now + SLICE);
        board.handle_timeout(target);
        machine_at = target;
        let lag = clock().total_micros().saturating_sub(target.total_micros());
        summary.worst_lag_us = summary.worst_lag_us.max(lag);
        while let Some(frame) = board.poll_transmit() {
            replies.extend_from_slice(&slcan::frame_line(&frame));
            summary.to_host += 1;
        }
        if !replies.is_empty() && can.write_all(&replies).and_then(|()| can.flush()).is_err() {
            summary.lost_to_host += 1;
        }
        let out = line.from_usart(&mut usart.borrow_mut());
        if !out.is_empty() && instrument_port.write_all(&out).and_then(|()| instrument_port.flush()).is_err()
        {
            summary.lost_to_instrument += 1;
        }
        let ops = board.flash_operations();
        if ops != saved_ops {
            saved_ops = ops;
            last_change = Some(std::time::Instant::now());
        }
        if last_change.is_some_and(|t| t.elapsed() >= SAVE_AFTER) {
            last_change = None;
            file.save(board.mcu().flash())?;
        }
    };
    file.save(board.mcu().flash())?;
    summary.seconds = origin.elapsed().as_secs_f64();
    summary.line = line.counts();
    summary.flash_operations = board.flash_operations();
    outcome.map(|()| summary)
}

/// A read that ended without data.
fn no_data(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock | std::io::ErrorKind::Interrupted
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_sn_code_has_its_rate() {
        assert_eq!(code_rate(4), Some(125_000));
        assert_eq!(code_rate(5), Some(250_000));
        assert_eq!(code_rate(6), Some(500_000));
        assert_eq!(code_rate(8), Some(1_000_000));
        assert_eq!(code_rate(9), None);
    }
}
