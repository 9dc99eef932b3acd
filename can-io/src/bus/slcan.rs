//! SLCAN (Lawicel) over a serial line (`slcan:PATH[@SERIALBAUD]`), the host side: cheap USB-CAN
//! adapters, and the emulated firmware on QEMU. The line codec is the one in [`crate::slcan`],
//! shared with the firmware that plays the adapter.
//!
//! | command | meaning |
//! |---|---|
//! | `C\r` | close the channel |
//! | `S4\r` / `S5\r` / `S6\r` | 125 / 250 / 500 kbit/s |
//! | `O\r` | open the channel |
//! | `tIIILDD..\r` | transmit a standard frame (3 hex identifier digits, 1 DLC digit, data) |
//! | `F\r` | read the status flags (answer `Fxx\r`, [`SlcanStatus`]), sent by [`Bus::error_state`] at most once a second |
//!
//! The adapter answers commands with `\r` (ok) or BEL (`\x07`, error), confirms transmissions with
//! `z\r` on some firmwares, and reports received frames as `tIIILDD..` lines, optionally followed
//! by a 4-digit timestamp. Extended (`T`) and remote (`r`, `R`) frames are not DeviceNet traffic
//! and are skipped. [`Receiver`] turns the adapter's byte stream into [`AdapterLine`]s;
//! [`SlcanBus`] runs it over any [`SerialLink`].
//!
//! ## Opening
//!
//! 1. What waits in the port's input is read and thrown away (at most [`DRAIN_LIMIT`]): frames
//!    and answers left from a previous program belong to no request of this one.
//! 2. `C`, `Sn`, `O` are sent one at a time, and with [`SetUp::Adapter`] each must be answered
//!    within [`ANSWER_TIMEOUT`]: `\r`, or BEL to `C` (a Lawicel adapter refuses to close a closed
//!    channel). Frames that come meanwhile are kept (a pty pair delivers what waited on it once
//!    this end writes: a device's start-up frames, or an answer to an earlier run, which the
//!    master's session records as not judged). BEL to `Sn` or `O` is [`BusError::Refused`]; silence or bytes that are not SLCAN
//!    are [`BusError::NotAnAdapter`], naming the port (a wrong port, the instrument's serial line,
//!    a device that is not an adapter). CANable's slcan firmware, Lawicel's CANUSB and the
//!    emulated firmware ([`crate::slcan::Adapter`]) answer so.
//! 3. With [`SetUp::Peer`] the answers are not awaited: the far end may be a host program that
//!    starts later, as on the pty rig's back-to-back link. Until the far end is heard from (an
//!    adapter's answer, a peer's `O`, a frame) the frames sent are held (at most [`HELD_LIMIT`]),
//!    as a CAN controller alone on a bus keeps retrying an unacknowledged frame, and go out then:
//!    a device started before its master shows its start-up to the master, once the master has
//!    opened its channel, and nothing of it waits in the port as a stale leftover.
//!
//! Two host endpoints joined back to back (a null-modem pty pair) see each other's set-up
//! commands; each answers them `\r` as an adapter would ([`AdapterLine::HostCommand`]), so a
//! program that opens with [`SetUp::Adapter`] finds a peer that runs as an adapter. A peer's `F`
//! is answered `F00\r`: a back-to-back serial link has no CAN controller, so no CAN errors.
//!
//! ## Status flags
//!
//! [`Bus::error_state`] is `None` until the adapter answered an `F`; an adapter that refuses `F`
//! (BEL while one is outstanding) is not asked again and its error state stays `None`; the BEL is
//! not an error of the bus.

use super::health::{ErrorReport, SlcanStatus};
use super::{Bitrate, Bus, BusError, BusEvent, Origin};
use crate::slcan::{self, Command, LineBuffer};
use devicenet::{CanFrame, Instant};
use std::collections::VecDeque;
use std::io::{Read, Write};

/// The `Sn` command for a bit rate.
pub fn bitrate_command(bitrate: Bitrate) -> [u8; 3] {
    let code = slcan::bitrate_code(bitrate.bits_per_second()).unwrap_or(5);
    [b'S', b'0' + code, b'\r']
}

/// How long an adapter has to answer each set-up command.
pub const ANSWER_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(1);

/// The longest time opening spends throwing away what waits in the port's input.
pub const DRAIN_LIMIT: std::time::Duration = std::time::Duration::from_millis(500);

/// A read that brings nothing for this long ends the drain: the port's input is empty.
const DRAIN_QUIET: std::time::Duration = std::time::Duration::from_millis(20);

/// What opening requires of the far end (see the [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SetUp {
    /// An adapter: each set-up command is answered within [`ANSWER_TIMEOUT`].
    Adapter,
    /// Anything that speaks SLCAN, maybe later: the set-up commands are sent, answers not awaited
    /// (a device program whose far end is a host that may start after it).
    Peer,
}

/// Why a port is not taken for an SLCAN adapter.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum NotAnAdapter {
    /// Nothing came back.
    #[error("no answer to `{command}` within {} ms", .after.as_millis())]
    Silent {
        /// The set-up command (`C`, `S5`, `O`).
        command: &'static str,
        /// How long it waited.
        after: std::time::Duration,
    },
    /// Bytes came back, but no SLCAN answer among them.
    #[error("`{command}` was answered with {count} byte(s) that are not SLCAN ({shown})")]
    Garbage {
        /// The set-up command.
        command: &'static str,
        /// How many bytes came.
        count: usize,
        /// The first of them, printable ASCII as is, others as `\xNN`.
        shown: String,
    },
}

/// One line the adapter sent.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AdapterLine {
    /// A received standard data frame.
    Frame(CanFrame),
    /// `\r`: the last command was accepted.
    Ok,
    /// `z` / `Z`: a transmission was confirmed.
    Transmitted,
    /// BEL: the last command was refused.
    Error,
    /// `Fxx`: the status flags, the answer to `F`.
    Status(SlcanStatus),
    /// A set-up command (`C`, `Sn`, `O`, `L`) or the status request `F`: only a host sends these,
    /// so the far end is another host program on a back-to-back link. Answered `\r` (`F`:
    /// `F00\r`).
    HostCommand(Command),
    /// A line that is not a standard data frame (extended, remote, version, status, noise).
    Other(String),
}

/// Classifies one line from the adapter (without its `\r`).
pub fn classify(line: &[u8]) -> AdapterLine {
    match line {
        b"" => AdapterLine::Ok,
        b"z" | b"Z" => AdapterLine::Transmitted,
        _ if SlcanStatus::parse(line).is_some() => {
            AdapterLine::Status(SlcanStatus::parse(line).unwrap_or_default())
        }
        _ => match slcan::parse_received(line) {
            Ok(Command::Frame(frame)) => AdapterLine::Frame(frame),
            Ok(
                c @ (Command::Open
                | Command::ListenOnly
                | Command::Close
                | Command::Bitrate(_)
                | Command::StatusFlags),
            ) => AdapterLine::HostCommand(c),
            _ => AdapterLine::Other(String::from_utf8_lossy(line).into_owned()),
        },
    }
}

/// Splits the adapter's byte stream into [`AdapterLine`]s: lines end at `\r` (a `\n` is ignored),
/// BEL is an answer of its own, an over-long line is dropped as noise.
#[derive(Clone, Debug, Default)]
pub struct Receiver {
    line: LineBuffer,
}

impl Receiver {
    /// An empty receiver.
    pub fn new() -> Receiver {
        Receiver::default()
    }

    /// Feeds bytes; returns the complete lines they finish.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<AdapterLine> {
        let mut out = Vec::new();
        for &b in bytes {
            if b == slcan::BEL {
                self.line = LineBuffer::new();
                out.push(AdapterLine::Error);
                continue;
            }
            match self.line.push(b) {
                Some(Ok(line)) => out.push(classify(line)),
                Some(Err(_)) => out.push(AdapterLine::Other("(line too long)".into())),
                None => {}
            }
        }
        out
    }
}

/// A byte link to the adapter with a settable read timeout.
pub trait SerialLink: Read + Write {
    /// Sets how long one `read` may block.
    fn set_read_timeout(&mut self, timeout: std::time::Duration) -> std::io::Result<()>;
}

impl SerialLink for Box<dyn serialport::SerialPort> {
    fn set_read_timeout(&mut self, timeout: std::time::Duration) -> std::io::Result<()> {
        self.set_timeout(timeout).map_err(std::io::Error::from)
    }
}

/// An SLCAN adapter on a [`SerialLink`].
pub struct SlcanBus<L: SerialLink> {
    link: L,
    name: String,
    /// The port, for errors.
    port: String,
    opened: std::time::Instant,
    receiver: Receiver,
    pending: VecDeque<BusEvent>,
    /// Frames sent while nothing was heard of the far end yet ([`SetUp::Peer`]), waiting to go out
    /// (`None` once it has been heard, and with [`SetUp::Adapter`]).
    held: Option<VecDeque<CanFrame>>,
    /// The status flags ([`Bus::error_state`]).
    status: StatusPoll,
}

/// The state of the `F` requests (see the [module docs](self)).
#[derive(Clone, Copy, Debug, Default)]
struct StatusPoll {
    /// When the outstanding `F` was sent.
    asked: Option<std::time::Instant>,
    /// When the last `F` was sent.
    last_asked: Option<std::time::Instant>,
    /// The adapter refused `F`.
    refused: bool,
    /// From the answers so far (`None` before the first).
    report: Option<ErrorReport>,
}

/// How often [`Bus::error_state`] asks an SLCAN adapter for its status flags, at most.
pub const STATUS_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

/// The most frames [`SlcanBus`] holds while its far end is not there; older ones are dropped.
pub const HELD_LIMIT: usize = 64;

/// Opens the serial port `path` at `baud` and sets the adapter up for `bitrate`; the adapter must
/// answer ([`SetUp::Adapter`]).
pub fn open(
    path: &str,
    baud: u32,
    bitrate: Bitrate,
) -> Result<SlcanBus<Box<dyn serialport::SerialPort>>, BusError> {
    open_as(path, baud, bitrate, SetUp::Adapter)
}

/// Opens the serial port `path` at `baud` and sets the adapter up for `bitrate`, as `setup` says.
pub fn open_as(
    path: &str,
    baud: u32,
    bitrate: Bitrate,
    setup: SetUp,
) -> Result<SlcanBus<Box<dyn serialport::SerialPort>>, BusError> {
    let port =
        serialport::new(path, baud).timeout(std::time::Duration::from_millis(10)).open().map_err(|e| {
            BusError::Open { what: format!("serial port '{path}'"), source: std::io::Error::from(e) }
        })?;
    SlcanBus::set_up(port, bitrate, path, setup)
}

impl<L: SerialLink> SlcanBus<L> {
    /// Sets the adapter up on `link` ([`SetUp::Adapter`]; the link named `the SLCAN link` in
    /// errors). See [`SlcanBus::set_up`].
    pub fn new(link: L, bitrate: Bitrate) -> Result<SlcanBus<L>, BusError> {
        SlcanBus::set_up(link, bitrate, "the SLCAN link", SetUp::Adapter)
    }

    /// Sets the adapter on `link` (named `port` in errors) up: its input drained, then close, bit
    /// rate, open, each answered as `setup` requires (see the [module docs](self)).
    pub fn set_up(link: L, bitrate: Bitrate, port: &str, setup: SetUp) -> Result<SlcanBus<L>, BusError> {
        let mut bus = SlcanBus {
            link,
            name: "slcan0".into(),
            port: port.to_string(),
            opened: std::time::Instant::now(),
            receiver: Receiver::new(),
            pending: VecDeque::new(),
            held: (setup == SetUp::Peer).then(VecDeque::new),
            status: StatusPoll::default(),
        };
        bus.drain()?;
        let rate = bitrate_command(bitrate);
        let rate_name = ["S0", "S1", "S2", "S3", "S4", "S5", "S6", "S7", "S8"]
            .get(usize::from(rate[1].wrapping_sub(b'0')))
            .copied()
            .unwrap_or("S");
        for (name, line) in [("C", &b"C\r"[..]), (rate_name, &rate[..]), ("O", &b"O\r"[..])] {
            bus.link.write_all(line).and_then(|()| bus.link.flush()).map_err(|source| BusError::Io {
                what: format!("setting the SLCAN adapter on {port} up (`{name}`)"),
                source,
            })?;
            if setup == SetUp::Adapter {
                bus.await_answer(name)?;
            }
        }
        // The bus's clock starts once it is set up; what came during the set-up came at its start.
        bus.opened = std::time::Instant::now();
        for ev in &mut bus.pending {
            ev.at = Instant::ZERO;
        }
        Ok(bus)
    }

    /// Reads and throws away what waits in the port's input, for at most [`DRAIN_LIMIT`].
    fn drain(&mut self) -> Result<(), BusError> {
        let end = std::time::Instant::now() + DRAIN_LIMIT;
        let mut buf = [0u8; 256];
        self.link
            .set_read_timeout(DRAIN_QUIET)
            .map_err(|source| self.io("setting the serial timeout", source))?;
        while std::time::Instant::now() < end {
            match self.link.read(&mut buf) {
                Ok(0) => break,
                Ok(_) => {}
                Err(e) if is_no_data(&e) => break,
                Err(source) => return Err(self.io("draining the port's input", source)),
            }
        }
        self.receiver = Receiver::new();
        Ok(())
    }

    /// Waits for the answer to set-up command `command`: `\r`, or BEL to `C`. Frames that come
    /// meanwhile are kept: a device's frames that waited on the link (a pty pair delivers them once
    /// this end writes) are the bus's; the session judges the ones that answer an earlier run.
    fn await_answer(&mut self, command: &'static str) -> Result<(), BusError> {
        let end = std::time::Instant::now() + ANSWER_TIMEOUT;
        let mut seen: Vec<u8> = Vec::new();
        let mut buf = [0u8; 256];
        let mut answered = false;
        while !answered {
            let left = end.saturating_duration_since(std::time::Instant::now());
            if left.is_zero() {
                let reason = if seen.is_empty() {
                    NotAnAdapter::Silent { command, after: ANSWER_TIMEOUT }
                } else {
                    NotAnAdapter::Garbage { command, count: seen.len(), shown: shown(&seen) }
                };
                return Err(BusError::NotAnAdapter { port: self.port.clone(), reason });
            }
            self.link
                .set_read_timeout(left.min(std::time::Duration::from_millis(50)))
                .map_err(|source| self.io("setting the serial timeout", source))?;
            let n = match self.link.read(&mut buf) {
                Ok(n) => n,
                Err(e) if is_no_data(&e) => 0,
                Err(source) => return Err(self.io("reading the SLCAN adapter's answer", source)),
            };
            seen.extend_from_slice(&buf[..n]);
            for line in self.receiver.feed(&buf[..n]) {
                match line {
                    AdapterLine::Frame(frame) => {
                        let at = self.clock();
                        self.pending.push_back(BusEvent { at, frame, origin: Origin::Remote });
                    }
                    AdapterLine::HostCommand(c) => self.answer_peer(c)?,
                    AdapterLine::Ok if !answered => answered = true,
                    AdapterLine::Error if !answered && command == "C" => answered = true,
                    AdapterLine::Error if !answered => {
                        return Err(BusError::Refused { port: self.port.clone(), command })
                    }
                    AdapterLine::Ok
                    | AdapterLine::Error
                    | AdapterLine::Transmitted
                    | AdapterLine::Status(_)
                    | AdapterLine::Other(_) => {}
                }
            }
            if n == 0 {
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
        Ok(())
    }

    /// Writes one frame line to the link.
    fn write_frame(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        self.link
            .write_all(&slcan::frame_line(frame))
            .and_then(|()| self.link.flush())
            .map_err(|source| self.io(&format!("writing {frame} to the SLCAN adapter"), source))
    }

    /// The far end showed it is there (an adapter's answer, a peer's `O`, a frame): the frames held
    /// meanwhile go out, in order, and later ones go out at once.
    fn far_end_heard(&mut self) -> Result<(), BusError> {
        if let Some(held) = self.held.take() {
            for frame in &held {
                self.write_frame(frame)?;
            }
        }
        Ok(())
    }

    /// Answers a peer's set-up command `\r`, and its `F` `F00\r`, as an adapter would.
    fn answer_peer(&mut self, command: Command) -> Result<(), BusError> {
        let answer: &[u8] = if command == Command::StatusFlags { b"F00\r" } else { slcan::OK };
        self.link
            .write_all(answer)
            .and_then(|()| self.link.flush())
            .map_err(|source| self.io("answering the far end's set-up command", source))
    }

    fn io(&self, what: &str, source: std::io::Error) -> BusError {
        BusError::Io { what: format!("{}: {what}", self.port), source }
    }

    /// The link (tests read what was written).
    pub fn link(&self) -> &L {
        &self.link
    }

    fn clock(&self) -> Instant {
        Instant::from_micros(u64::try_from(self.opened.elapsed().as_micros()).unwrap_or(u64::MAX))
    }
}

impl<L: SerialLink> Bus for SlcanBus<L> {
    fn name(&self) -> &str {
        &self.name
    }

    fn now(&mut self) -> Instant {
        self.clock()
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        match &mut self.held {
            Some(held) => {
                if held.len() == HELD_LIMIT {
                    held.pop_front();
                }
                held.push_back(*frame);
            }
            None => self.write_frame(frame)?,
        }
        let at = self.clock();
        self.pending.push_back(BusEvent { at, frame: *frame, origin: Origin::Local });
        Ok(())
    }

    fn error_state(&mut self) -> Option<ErrorReport> {
        // A failed write shows again, as an error, at the next send or receive.
        self.poll_status().ok().flatten()
    }

    fn recv(&mut self, deadline: Instant) -> Result<Option<BusEvent>, BusError> {
        let mut buf = [0u8; 256];
        loop {
            if let Some(ev) = self.pending.pop_front() {
                return Ok(Some(ev));
            }
            let now = self.clock();
            if now >= deadline {
                return Ok(None);
            }
            let wait = std::time::Duration::from_micros((deadline - now).total_micros().max(1000));
            self.link
                .set_read_timeout(wait)
                .map_err(|source| BusError::Io { what: "setting the serial timeout".into(), source })?;
            let n = match self.link.read(&mut buf) {
                Ok(0) => {
                    // Some links report "no data" as a zero-length read; do not spin.
                    std::thread::sleep(std::time::Duration::from_millis(1));
                    0
                }
                Ok(n) => n,
                Err(e) if is_no_data(&e) => 0,
                Err(source) => {
                    return Err(BusError::Io { what: "reading from the SLCAN adapter".into(), source })
                }
            };
            let at = self.clock();
            for msg in self.receiver.feed(&buf[..n]) {
                let heard = match &msg {
                    AdapterLine::HostCommand(c) => matches!(c, Command::Open | Command::ListenOnly),
                    AdapterLine::Other(_) => false,
                    _ => true,
                };
                if let AdapterLine::HostCommand(c) = msg {
                    // Answered first: the held frames follow the answer to the peer's `O`.
                    self.answer_peer(c)?;
                }
                if heard {
                    self.far_end_heard()?;
                }
                match msg {
                    AdapterLine::Frame(frame) => {
                        self.pending.push_back(BusEvent { at, frame, origin: Origin::Remote })
                    }
                    AdapterLine::Error if self.status.asked.is_some() => {
                        self.status.asked = None;
                        self.status.refused = true;
                    }
                    AdapterLine::Error => {
                        return Err(BusError::Adapter("the SLCAN adapter refused a command (BEL)".into()))
                    }
                    AdapterLine::Status(flags) => {
                        self.status.asked = None;
                        let mut report = self.status.report.unwrap_or_default();
                        report.state = flags.state();
                        report.error_frames += u64::from(flags.0 & SlcanStatus::BUS_ERROR != 0);
                        self.status.report = Some(report);
                    }
                    AdapterLine::HostCommand(_)
                    | AdapterLine::Ok
                    | AdapterLine::Transmitted
                    | AdapterLine::Other(_) => {}
                }
            }
        }
    }
}

impl<L: SerialLink> SlcanBus<L> {
    /// The error state for [`Bus::error_state`]: asks `F` when none is outstanding (or the last
    /// went unanswered for [`STATUS_INTERVAL`]) and the last was asked [`STATUS_INTERVAL`] ago.
    fn poll_status(&mut self) -> Result<Option<ErrorReport>, BusError> {
        let due = self.held.is_none()
            && !self.status.refused
            && self.status.last_asked.is_none_or(|t| t.elapsed() >= STATUS_INTERVAL);
        if due {
            self.link
                .write_all(b"F\r")
                .and_then(|()| self.link.flush())
                .map_err(|source| self.io("asking the SLCAN adapter for its status flags (`F`)", source))?;
            let now = std::time::Instant::now();
            self.status.asked = Some(now);
            self.status.last_asked = Some(now);
        }
        Ok(self.status.report)
    }
}

/// A read that ended without data: the timeout passed, or a signal came.
fn is_no_data(e: &std::io::Error) -> bool {
    matches!(
        e.kind(),
        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock | std::io::ErrorKind::Interrupted
    )
}

/// Up to 16 of `bytes`: printable ASCII as is, the rest as `\xNN`, `\r` as `\r`.
fn shown(bytes: &[u8]) -> String {
    let mut text: String =
        bytes.iter().take(16).map(|b| std::ascii::escape_default(*b).to_string()).collect();
    if bytes.len() > 16 {
        text.push_str("...");
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::health::ErrorState;
    use rstest::rstest;

    /// A scripted adapter: what waits in its input, what it answers to each write (in order),
    /// and what it was told.
    struct FakeLink {
        input: VecDeque<u8>,
        replies: VecDeque<&'static str>,
        written: Vec<u8>,
    }

    impl FakeLink {
        fn new(waiting: &[u8], replies: &[&'static str]) -> FakeLink {
            FakeLink {
                input: waiting.iter().copied().collect(),
                replies: replies.iter().copied().collect(),
                written: Vec::new(),
            }
        }
    }

    impl Read for FakeLink {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.input.is_empty() {
                return Err(std::io::ErrorKind::TimedOut.into());
            }
            let n = buf.len().min(self.input.len()).min(5);
            for b in buf.iter_mut().take(n) {
                *b = self.input.pop_front().unwrap_or(0);
            }
            Ok(n)
        }
    }

    impl Write for FakeLink {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.written.extend_from_slice(buf);
            if let Some(reply) = self.replies.pop_front() {
                self.input.extend(reply.bytes());
            }
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl SerialLink for FakeLink {
        fn set_read_timeout(&mut self, _: std::time::Duration) -> std::io::Result<()> {
            Ok(())
        }
    }

    /// A CANable or the emulated firmware: `\r` to each set-up command.
    const ANSWERS: [&str; 3] = ["\r", "\r", "\r"];

    fn f(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::from_raw(id, data).unwrap()
    }

    #[rstest]
    #[case::explicit(f(0x42B, &[0x00, 0xCB, 0x00]), "t42B300CB00\r")]
    #[case::empty(f(0x42D, &[]), "t42D0\r")]
    #[case::low_id(f(0x005, &[0xFF]), "t0051FF\r")]
    fn encode(#[case] frame: CanFrame, #[case] text: &str) {
        assert_eq!(&slcan::frame_line(&frame)[..], text.as_bytes());
        assert_eq!(classify(text.trim_end_matches('\r').as_bytes()), AdapterLine::Frame(frame));
    }

    #[test]
    fn status_flags_are_asked_for_and_read() {
        let mut bus =
            SlcanBus::new(FakeLink::new(b"", &["\r", "\r", "\r", "F24\r", "F80\r"]), Bitrate::K250).unwrap();
        assert_eq!(bus.error_state(), None, "asked, not answered yet");
        assert!(bus.link().written.ends_with(b"O\rF\r"));
        assert_eq!(bus.recv(Instant::from_millis(20)).unwrap(), None);
        let report = bus.error_state().unwrap();
        assert_eq!((report.state, report.error_frames, report.tec), (ErrorState::Passive, 0, None));
        assert_eq!(bus.link().written.iter().filter(|&&b| b == b'F').count(), 1, "not again within a second");
    }

    #[test]
    fn an_adapter_that_refuses_status_flags_is_not_asked_again() {
        let mut bus = SlcanBus::new(FakeLink::new(b"", &["\r", "\r", "\r", "\x07"]), Bitrate::K250).unwrap();
        assert_eq!(bus.error_state(), None);
        assert_eq!(bus.recv(Instant::from_millis(20)).unwrap(), None, "the BEL to `F` is no bus error");
        bus.status.last_asked = None;
        assert_eq!(bus.error_state(), None);
        assert_eq!(bus.link().written.iter().filter(|&&b| b == b'F').count(), 1);
    }

    #[test]
    fn a_peers_status_request_is_answered_with_no_errors() {
        let mut bus =
            SlcanBus::set_up(FakeLink::new(b"F\r", &[]), Bitrate::K250, "pty", SetUp::Peer).unwrap();
        bus.link.input.extend(b"F\r".iter().copied());
        assert_eq!(bus.recv(Instant::from_millis(20)).unwrap(), None);
        assert!(bus.link().written.ends_with(b"F00\r"), "{:?}", String::from_utf8_lossy(&bus.link().written));
    }

    #[rstest]
    #[case::timestamp("t42B300CB001A2B", AdapterLine::Frame(f(0x42B, &[0x00, 0xCB, 0x00])))]
    #[case::ok("", AdapterLine::Ok)]
    #[case::tx("z", AdapterLine::Transmitted)]
    #[case::extended("T1234567810", AdapterLine::Other("T1234567810".into()))]
    #[case::remote("r42B0", AdapterLine::Other("r42B0".into()))]
    #[case::bad_dlc("t42B9", AdapterLine::Other("t42B9".into()))]
    #[case::short("t42B300CB", AdapterLine::Other("t42B300CB".into()))]
    #[case::bad_hex("t42B1GG", AdapterLine::Other("t42B1GG".into()))]
    #[case::big_id("t8001FF", AdapterLine::Other("t8001FF".into()))]
    #[case::peer_close("C", AdapterLine::HostCommand(Command::Close))]
    #[case::peer_rate("S5", AdapterLine::HostCommand(Command::Bitrate(5)))]
    #[case::version("V1013", AdapterLine::Other("V1013".into()))]
    fn lines(#[case] line: &str, #[case] msg: AdapterLine) {
        assert_eq!(classify(line.as_bytes()), msg);
    }

    #[test]
    fn parser_splits_the_stream() {
        let mut p = Receiver::new();
        assert!(p.feed(b"t42B3").is_empty());
        assert_eq!(
            p.feed(b"00CB00\r\x07z\r"),
            vec![
                AdapterLine::Frame(f(0x42B, &[0x00, 0xCB, 0x00])),
                AdapterLine::Error,
                AdapterLine::Transmitted
            ]
        );
    }

    #[test]
    fn bus_sets_up_sends_and_receives() {
        let link = FakeLink::new(b"", &["\r", "\r", "\r", "z\rt42B300CB00\r"]);
        let mut bus = SlcanBus::new(link, Bitrate::K500).unwrap();
        bus.send(&f(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00])).unwrap();
        let deadline = bus.now() + devicenet::Duration::from_secs(1);
        let echo = bus.recv(deadline).unwrap().unwrap();
        assert_eq!(echo.origin, Origin::Local);
        let rx = bus.recv(deadline).unwrap().unwrap();
        assert_eq!((rx.origin, rx.frame), (Origin::Remote, f(0x42B, &[0x00, 0xCB, 0x00])));
        assert_eq!(String::from_utf8_lossy(&bus.link().written), "C\rS6\rO\rt42E6004B03010100\r");
        // Nothing more: the deadline passes.
        let short = bus.now() + devicenet::Duration::from_millis(5);
        assert_eq!(bus.recv(short).unwrap(), None);
    }

    #[test]
    fn adapter_error_is_reported() {
        let link = FakeLink::new(b"", &["\r", "\r", "\r", "\x07"]);
        let mut bus = SlcanBus::new(link, Bitrate::K250).unwrap();
        bus.send(&f(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00])).unwrap();
        let deadline = bus.now() + devicenet::Duration::from_secs(1);
        assert_eq!(bus.recv(deadline).unwrap().map(|e| e.origin), Some(Origin::Local));
        assert!(matches!(bus.recv(deadline), Err(BusError::Adapter(_))));
    }

    #[test]
    fn what_waits_in_the_port_is_thrown_away_on_open() {
        // An interrupted run's Release answer, and half a line, wait in the port.
        let link = FakeLink::new(b"t42B200CC\rt42B30", &ANSWERS);
        let mut bus = SlcanBus::set_up(link, Bitrate::K250, "/dev/pts/9", SetUp::Adapter).unwrap();
        let deadline = bus.now() + devicenet::Duration::from_millis(20);
        assert_eq!(bus.recv(deadline).unwrap(), None);
    }

    #[test]
    fn frames_during_the_set_up_are_kept() {
        // A device's duplicate MAC ID check that waited on a pty pair, delivered once this end
        // writes; then a frame right after the answer to `O`.
        let link = FakeLink::new(b"", &["t42F700341278563412\r\r", "\r", "\rt42B200CC\r"]);
        let mut bus = SlcanBus::set_up(link, Bitrate::K250, "/dev/pts/9", SetUp::Adapter).unwrap();
        let deadline = bus.now() + devicenet::Duration::from_millis(20);
        let first = bus.recv(deadline).unwrap().map(|e| e.frame);
        assert_eq!(first, Some(f(0x42F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12])));
        assert_eq!(bus.recv(deadline).unwrap().map(|e| e.frame), Some(f(0x42B, &[0x00, 0xCC])));
    }

    #[rstest]
    #[case::canable(&ANSWERS)]
    #[case::lawicel_refuses_to_close_a_closed_channel(&["\x07", "\r", "\r"])]
    #[case::transmit_confirmation_left_over(&["z\r\r", "\r", "\r"])]
    fn adapters_that_answer_are_taken(#[case] replies: &[&'static str]) {
        let link = FakeLink::new(b"", replies);
        assert!(SlcanBus::set_up(link, Bitrate::K250, "/dev/ttyACM0", SetUp::Adapter).is_ok());
    }

    #[rstest]
    #[case::silent(&[], "/dev/ttyS7 does not answer as an SLCAN adapter: no answer to `C` within 1000 ms")]
    #[case::instrument(
        &["\x02\x41\x55\x00\x1a\x03"],
        "/dev/ttyS7 does not answer as an SLCAN adapter: `C` was answered with 6 byte(s) that are not SLCAN (\\x02AU\\x00\\x1a\\x03)"
    )]
    #[case::text(&["login: "], "`C` was answered with 7 byte(s) that are not SLCAN (login: )")]
    #[case::refused_rate(&["\r", "\x07"], "the SLCAN adapter on /dev/ttyS7 refused `S5` (BEL)")]
    #[case::refused_open(&["\r", "\r", "\x07"], "the SLCAN adapter on /dev/ttyS7 refused `O` (BEL)")]
    fn ports_that_do_not_answer_as_an_adapter_are_named(
        #[case] replies: &[&'static str],
        #[case] message: &str,
    ) {
        let link = FakeLink::new(b"", replies);
        let e = SlcanBus::set_up(link, Bitrate::K250, "/dev/ttyS7", SetUp::Adapter).err().unwrap();
        assert!(matches!(e, BusError::NotAnAdapter { .. } | BusError::Refused { .. }), "{e:?}");
        assert!(e.to_string().contains(message), "{e}");
    }

    #[test]
    fn a_peer_need_not_answer() {
        let link = FakeLink::new(b"", &[]);
        let bus = SlcanBus::set_up(link, Bitrate::K250, "/dev/pts/3", SetUp::Peer).unwrap();
        assert_eq!(String::from_utf8_lossy(&bus.link().written), "C\rS5\rO\r");
    }

    #[test]
    fn a_peer_holds_its_frames_until_the_far_end_opens() {
        let link = FakeLink::new(b"", &[]);
        let mut bus = SlcanBus::set_up(link, Bitrate::K250, "/dev/pts/3", SetUp::Peer).unwrap();
        let check = f(0x42F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]);
        bus.send(&check).unwrap();
        let deadline = bus.now() + devicenet::Duration::from_millis(20);
        assert_eq!(bus.recv(deadline).unwrap().map(|e| e.origin), Some(Origin::Local));
        assert_eq!(bus.recv(deadline).unwrap(), None);
        assert_eq!(String::from_utf8_lossy(&bus.link().written), "C\rS5\rO\r", "held: nobody there yet");
        // The master opens its end: its set-up answered, then the held frame goes out.
        bus.link.input.extend(b"C\rS5\r".iter().copied());
        let deadline = bus.now() + devicenet::Duration::from_millis(20);
        assert_eq!(bus.recv(deadline).unwrap(), None);
        assert_eq!(String::from_utf8_lossy(&bus.link().written), "C\rS5\rO\r\r\r", "still held: not open");
        bus.link.input.extend(b"O\r".iter().copied());
        let deadline = bus.now() + devicenet::Duration::from_millis(20);
        assert_eq!(bus.recv(deadline).unwrap(), None);
        let written = String::from_utf8_lossy(&bus.link().written).into_owned();
        assert_eq!(written, "C\rS5\rO\r\r\r\rt42F700341278563412\r");
        // From now on at once.
        bus.send(&f(0x42B, &[0x00, 0xCC])).unwrap();
        assert!(String::from_utf8_lossy(&bus.link().written).ends_with("t42B200CC\r"));
    }

    #[test]
    fn a_peers_set_up_commands_are_answered_as_an_adapter_would() {
        let link = FakeLink::new(b"", &[]);
        let mut bus = SlcanBus::set_up(link, Bitrate::K250, "/dev/pts/3", SetUp::Peer).unwrap();
        bus.link.input.extend(b"C\rS5\rO\r".iter().copied());
        let deadline = bus.now() + devicenet::Duration::from_millis(20);
        assert_eq!(bus.recv(deadline).unwrap(), None);
        assert_eq!(String::from_utf8_lossy(&bus.link().written), "C\rS5\rO\r\r\r\r");
    }

    proptest::proptest! {
        #[test]
        fn parser_never_panics(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..200)) {
            let _ = Receiver::new().feed(&bytes);
        }
    }
}
