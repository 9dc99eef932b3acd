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
//!
//! The adapter answers commands with `\r` (ok) or BEL (`\x07`, error), confirms transmissions with
//! `z\r` on some firmwares, and reports received frames as `tIIILDD..` lines, optionally followed
//! by a 4-digit timestamp. Extended (`T`) and remote (`r`, `R`) frames are not DeviceNet traffic
//! and are skipped. [`Receiver`] turns the adapter's byte stream into [`AdapterLine`]s;
//! [`SlcanBus`] runs it over any [`SerialLink`].

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
    /// A line that is not a standard data frame (extended, remote, version, status, noise).
    Other(String),
}

/// Classifies one line from the adapter (without its `\r`).
pub fn classify(line: &[u8]) -> AdapterLine {
    match line {
        b"" => AdapterLine::Ok,
        b"z" | b"Z" => AdapterLine::Transmitted,
        _ => match slcan::parse_received(line) {
            Ok(Command::Frame(frame)) => AdapterLine::Frame(frame),
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
    opened: std::time::Instant,
    receiver: Receiver,
    pending: VecDeque<BusEvent>,
}

/// Opens the serial port `path` at `baud` and sets the adapter up for `bitrate`.
pub fn open(
    path: &str,
    baud: u32,
    bitrate: Bitrate,
) -> Result<SlcanBus<Box<dyn serialport::SerialPort>>, BusError> {
    let port =
        serialport::new(path, baud).timeout(std::time::Duration::from_millis(10)).open().map_err(|e| {
            BusError::Open { what: format!("serial port '{path}'"), source: std::io::Error::from(e) }
        })?;
    SlcanBus::new(port, bitrate)
}

impl<L: SerialLink> SlcanBus<L> {
    /// Sets the adapter up on `link`: close, bit rate, open. The adapter's answers are not
    /// required (some adapters stay silent); a BEL is an error.
    pub fn new(mut link: L, bitrate: Bitrate) -> Result<SlcanBus<L>, BusError> {
        let mut setup = b"C\r".to_vec();
        setup.extend_from_slice(&bitrate_command(bitrate));
        setup.extend_from_slice(b"O\r");
        link.write_all(&setup)
            .and_then(|()| link.flush())
            .map_err(|source| BusError::Io { what: "setting the SLCAN adapter up".into(), source })?;
        Ok(SlcanBus {
            link,
            name: "slcan0".into(),
            opened: std::time::Instant::now(),
            receiver: Receiver::new(),
            pending: VecDeque::new(),
        })
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
        self.link.write_all(&slcan::frame_line(frame)).and_then(|()| self.link.flush()).map_err(
            |source| BusError::Io { what: format!("writing {frame} to the SLCAN adapter"), source },
        )?;
        let at = self.clock();
        self.pending.push_back(BusEvent { at, frame: *frame, origin: Origin::Local });
        Ok(())
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
                Err(e)
                    if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) =>
                {
                    0
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => 0,
                Err(source) => {
                    return Err(BusError::Io { what: "reading from the SLCAN adapter".into(), source })
                }
            };
            let at = self.clock();
            for msg in self.receiver.feed(&buf[..n]) {
                match msg {
                    AdapterLine::Frame(frame) => {
                        self.pending.push_back(BusEvent { at, frame, origin: Origin::Remote })
                    }
                    AdapterLine::Error => {
                        return Err(BusError::Adapter("the SLCAN adapter refused a command (BEL)".into()))
                    }
                    AdapterLine::Ok | AdapterLine::Transmitted | AdapterLine::Other(_) => {}
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    /// A scripted adapter: what it will say, and what it was told.
    struct FakeLink {
        input: VecDeque<u8>,
        written: Vec<u8>,
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
        let link =
            FakeLink { input: b"\r\r\rz\rt42B300CB00\r".iter().copied().collect(), written: Vec::new() };
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
        let link = FakeLink { input: b"\x07".iter().copied().collect(), written: Vec::new() };
        let mut bus = SlcanBus::new(link, Bitrate::K250).unwrap();
        let deadline = bus.now() + devicenet::Duration::from_secs(1);
        assert!(matches!(bus.recv(deadline), Err(BusError::Adapter(_))));
    }

    proptest::proptest! {
        #[test]
        fn parser_never_panics(bytes in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..200)) {
            let _ = Receiver::new().feed(&bytes);
        }
    }
}
