//! SLCAN (Lawicel) over a serial line (`slcan:PATH[@SERIALBAUD]`): the ASCII protocol of cheap
//! USB-CAN adapters, and the way the emulated firmware will be reached.
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
//! and are skipped. The codec ([`encode_frame`], [`LineParser`]) is pure; [`SlcanBus`] runs it over
//! any [`SerialLink`].

use super::{Bitrate, Bus, BusError, BusEvent, Origin};
use devicenet::{CanFrame, Instant};
use std::collections::VecDeque;
use std::io::{Read, Write};

/// The `Sn` command for a bit rate.
pub fn bitrate_command(bitrate: Bitrate) -> &'static str {
    match bitrate.bits_per_second() {
        125_000 => "S4\r",
        500_000 => "S6\r",
        _ => "S5\r",
    }
}

/// The transmit command for `frame`: `t42B3` `00CB00` `\r`.
pub fn encode_frame(frame: &CanFrame) -> String {
    let mut s = format!("t{:03X}{}", frame.id().as_raw(), frame.dlc());
    for b in frame.data() {
        s.push_str(&format!("{b:02X}"));
    }
    s.push('\r');
    s
}

/// One thing the adapter said.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SlcanMessage {
    /// A received standard data frame.
    Frame(CanFrame),
    /// `\r`: the last command was accepted.
    Ok,
    /// `z` / `Z`: a transmission was confirmed.
    Transmitted,
    /// BEL: the last command was refused.
    Error,
    /// A line that is not a standard data frame (extended, remote, version, status...).
    Other(String),
}

/// Parses a received line (without its `\r`).
pub fn parse_line(line: &str) -> SlcanMessage {
    let Some(rest) = line.strip_prefix('t') else {
        return match line {
            "" => SlcanMessage::Ok,
            "z" | "Z" => SlcanMessage::Transmitted,
            other => SlcanMessage::Other(other.to_string()),
        };
    };
    let parsed = (|| {
        let id = u16::from_str_radix(rest.get(..3)?, 16).ok()?;
        let dlc = usize::from(rest.as_bytes().get(3)?.wrapping_sub(b'0'));
        if dlc > 8 {
            return None;
        }
        let hexdata = rest.get(4..4 + 2 * dlc)?;
        let tail = &rest[4 + 2 * dlc..];
        // Optional 4-digit timestamp.
        if !(tail.is_empty() || (tail.len() == 4 && tail.bytes().all(|b| b.is_ascii_hexdigit()))) {
            return None;
        }
        let mut data = Vec::with_capacity(dlc);
        for i in 0..dlc {
            data.push(u8::from_str_radix(hexdata.get(2 * i..2 * i + 2)?, 16).ok()?);
        }
        CanFrame::from_raw(id, &data).ok()
    })();
    match parsed {
        Some(f) => SlcanMessage::Frame(f),
        None => SlcanMessage::Other(line.to_string()),
    }
}

/// Splits the adapter's byte stream into messages.
#[derive(Clone, Debug, Default)]
pub struct LineParser {
    buf: Vec<u8>,
}

/// Longest line kept; anything longer is noise and is dropped.
const MAX_LINE: usize = 64;

impl LineParser {
    /// An empty parser.
    pub fn new() -> LineParser {
        LineParser::default()
    }

    /// Feeds bytes; returns the complete messages they finish.
    pub fn feed(&mut self, bytes: &[u8]) -> Vec<SlcanMessage> {
        let mut out = Vec::new();
        for &b in bytes {
            match b {
                b'\r' | b'\n' => {
                    if b == b'\r' || !self.buf.is_empty() {
                        let line = String::from_utf8_lossy(&self.buf).into_owned();
                        out.push(parse_line(&line));
                    }
                    self.buf.clear();
                }
                0x07 => {
                    self.buf.clear();
                    out.push(SlcanMessage::Error);
                }
                _ if self.buf.len() < MAX_LINE => self.buf.push(b),
                _ => self.buf.clear(),
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
    parser: LineParser,
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
        let setup = format!("C\r{}O\r", bitrate_command(bitrate));
        link.write_all(setup.as_bytes())
            .and_then(|()| link.flush())
            .map_err(|source| BusError::Io { what: "setting the SLCAN adapter up".into(), source })?;
        Ok(SlcanBus {
            link,
            name: "slcan0".into(),
            opened: std::time::Instant::now(),
            parser: LineParser::new(),
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
        self.link.write_all(encode_frame(frame).as_bytes()).and_then(|()| self.link.flush()).map_err(
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
            for msg in self.parser.feed(&buf[..n]) {
                match msg {
                    SlcanMessage::Frame(frame) => {
                        self.pending.push_back(BusEvent { at, frame, origin: Origin::Remote })
                    }
                    SlcanMessage::Error => {
                        return Err(BusError::Adapter("the SLCAN adapter refused a command (BEL)".into()))
                    }
                    SlcanMessage::Ok | SlcanMessage::Transmitted | SlcanMessage::Other(_) => {}
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
        assert_eq!(encode_frame(&frame), text);
        assert_eq!(parse_line(text.trim_end_matches('\r')), SlcanMessage::Frame(frame));
    }

    #[rstest]
    #[case::timestamp("t42B300CB001A2B", SlcanMessage::Frame(f(0x42B, &[0x00, 0xCB, 0x00])))]
    #[case::ok("", SlcanMessage::Ok)]
    #[case::tx("z", SlcanMessage::Transmitted)]
    #[case::extended("T1234567810", SlcanMessage::Other("T1234567810".into()))]
    #[case::remote("r42B0", SlcanMessage::Other("r42B0".into()))]
    #[case::bad_dlc("t42B9", SlcanMessage::Other("t42B9".into()))]
    #[case::short("t42B300CB", SlcanMessage::Other("t42B300CB".into()))]
    #[case::bad_hex("t42B1GG", SlcanMessage::Other("t42B1GG".into()))]
    #[case::big_id("t8001FF", SlcanMessage::Other("t8001FF".into()))]
    fn lines(#[case] line: &str, #[case] msg: SlcanMessage) {
        assert_eq!(parse_line(line), msg);
    }

    #[test]
    fn parser_splits_the_stream() {
        let mut p = LineParser::new();
        assert!(p.feed(b"t42B3").is_empty());
        assert_eq!(
            p.feed(b"00CB00\r\x07z\r"),
            vec![
                SlcanMessage::Frame(f(0x42B, &[0x00, 0xCB, 0x00])),
                SlcanMessage::Error,
                SlcanMessage::Transmitted
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
            let _ = LineParser::new().feed(&bytes);
        }
    }
}
