//! The live sources of `decode`: standard input read line by line (`candump -L`, each frame decoded
//! as its line arrives), and a live bus opened so that it never transmits.
//!
//! An SLCAN adapter is opened in listen-only mode: the set-up is the one every program uses
//! ([`can_io::bus::slcan::SlcanBus::set_up`]: close, bit rate, open), through a [`ListenOnly`]
//! link that sends `L` (listen-only, the adapter neither transmits nor acknowledges frames) where
//! the set-up sends `O`, and refuses to pass on any transmit command (`t`, `T`, `r`, `R`): the
//! decoder cannot send a frame even by mistake. An adapter that does not know `L` refuses it with
//! BEL, and `decode` stops with that error rather than join the bus. A SocketCAN interface is
//! only read (its listen-only mode is the interface's: `ip link set can0 type can listen-only on`).

use can_io::bus::slcan::{SerialLink, SetUp, SlcanBus};
use can_io::bus::{Bitrate, Bus, BusError, BusSpec};
use std::io::{self, Read, Write};

/// A serial link that turns the adapter's `O` (open) into `L` (listen-only) and refuses every
/// transmit command (see the [module docs](self)).
pub struct ListenOnly<L> {
    link: L,
    /// The command being written, up to its `\r`.
    line: Vec<u8>,
    /// Transmit commands refused.
    pub refused: usize,
}

impl<L> ListenOnly<L> {
    /// `link`, listen-only.
    pub fn new(link: L) -> ListenOnly<L> {
        ListenOnly { link, line: Vec::new(), refused: 0 }
    }
}

impl<L: Read> Read for ListenOnly<L> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.link.read(buf)
    }
}

impl<L: Write> Write for ListenOnly<L> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        for &b in buf {
            if b != b'\r' {
                // A command is a few characters; a run without `\r` is not one.
                if self.line.len() < 64 {
                    self.line.push(b);
                }
                continue;
            }
            let line = std::mem::take(&mut self.line);
            match line.first() {
                Some(b't' | b'T' | b'r' | b'R') => {
                    self.refused += 1;
                    return Err(io::Error::new(
                        io::ErrorKind::PermissionDenied,
                        "decode listens only: a frame was not sent",
                    ));
                }
                Some(b'O') if line.len() == 1 => self.link.write_all(b"L\r")?,
                _ => {
                    self.link.write_all(&line)?;
                    self.link.write_all(b"\r")?;
                }
            }
        }
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.link.flush()
    }
}

impl<L: SerialLink> SerialLink for ListenOnly<L> {
    fn set_read_timeout(&mut self, timeout: std::time::Duration) -> io::Result<()> {
        self.link.set_read_timeout(timeout)
    }
}

/// Opens `spec` to listen: SLCAN in listen-only mode, SocketCAN read only; `sim` is refused (the
/// simulated bus has no traffic without a master).
pub fn open_listening(spec: &BusSpec, bitrate: Bitrate) -> Result<Box<dyn Bus>, BusError> {
    match spec {
        BusSpec::Slcan { path, baud } => {
            let port =
                serialport::new(path, *baud).timeout(std::time::Duration::from_millis(10)).open().map_err(
                    |e| BusError::Open { what: format!("serial port '{path}'"), source: io::Error::from(e) },
                )?;
            let bus = SlcanBus::set_up(ListenOnly::new(port), bitrate, path, SetUp::Adapter)?;
            Ok(Box::new(bus))
        }
        BusSpec::SocketCan { iface } => socketcan(iface),
        BusSpec::Sim => Err(BusError::Unavailable(
            "decode --bus sim: the simulated bus carries nothing without a master; decode a live bus \
             (--bus socketcan:IFACE or slcan:PATH) or a trace (FILE, or - for standard input)"
                .into(),
        )),
    }
}

#[cfg(target_os = "linux")]
fn socketcan(iface: &str) -> Result<Box<dyn Bus>, BusError> {
    Ok(Box::new(can_io::bus::socketcan::SocketCanBus::open(iface)?))
}

#[cfg(not(target_os = "linux"))]
fn socketcan(iface: &str) -> Result<Box<dyn Bus>, BusError> {
    Err(BusError::Unavailable(format!("socketcan:{iface}: SocketCAN is Linux only")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn open_becomes_listen_only_and_frames_are_refused() {
        let mut link = ListenOnly::new(Vec::new());
        link.write_all(b"C\rS5\rO\r").unwrap();
        assert_eq!(link.link, b"C\rS5\rL\r");
        let e = link.write_all(b"t42B10094\r").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::PermissionDenied);
        assert_eq!(link.refused, 1);
        assert_eq!(link.link, b"C\rS5\rL\r", "nothing of the frame reached the adapter");
        // Written in pieces, as a serial write may be.
        link.write_all(b"F").unwrap();
        link.write_all(b"\r").unwrap();
        assert_eq!(link.link, b"C\rS5\rL\rF\r");
    }
}
