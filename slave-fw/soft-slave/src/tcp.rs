//! The instrument behind a serial device server: `--serial tcp:HOST:PORT`.
//!
//! A device server in TCP server mode (Moxa NPort "TCP Server" operating mode, Lantronix, and
//! `socat TCP-LISTEN:PORT PTY` on a bench) carries the bytes of one serial port over one TCP
//! connection, unchanged. The soft slave is its TCP client: [`TcpLine::open`] gives a
//! [`SerialLine`] whose bytes go through that connection instead of a local port, so every
//! profile works over it. The baud rate, parity and stop bits are the device server's settings
//! (its web page or console), not ours: set them to the profile's.
//!
//! ## Connection and back-off
//!
//! One thread connects, reads, and reconnects; a second writes. A connection attempt resolves
//! `HOST` again (a device server's DNS name may move) and tries every address for at most
//! [`CONNECT_TIMEOUT`]. After a failed attempt or a lost connection the next attempt waits
//! [`BACKOFF_FIRST`], doubled after each further failure up to [`BACKOFF_MAX`], and back to
//! [`BACKOFF_FIRST`] once a connection was made. Every change is reported as a
//! [`SerialEvent::Connection`] (the soft slave logs it).
//!
//! ## While the device server is away
//!
//! No bytes arrive, so the profile sees a silent instrument: its answer timeouts, retries and
//! stale policy run as they do on a cut serial cable, and the DeviceNet side keeps answering.
//! Bytes the profile sends meanwhile are dropped, not queued (a serial line with nobody on it
//! loses them too); the writer's queue is [`OUTGOING_FRAMES`] frames at most.
//!
//! ## Line silence over TCP
//!
//! TCP keeps the byte order but not the timing: a device server packs serial bytes into
//! segments by its own rules (Moxa's packing length, delimiter and force-transmit timer), so the
//! gaps seen here are not the gaps on the wire. The profiles never cut frames at a silence (the
//! framed parser looks for its start byte, length and end byte; the Modbus master delimits a
//! response by its function and byte count), so chunking does not split a frame. Bytes are
//! timestamped when a read returns them, as on a local port, and the Modbus master's transmit
//! silence counts from there; what the serial wire itself needs between frames is the device
//! server's to keep. Nagle's algorithm is off (`TCP_NODELAY`), so a request leaves at once.

use crate::clock::Clock;
use crate::serial::{ConnectionEvent, SerialEvent, SerialLine, OUTGOING_FRAMES, READ_TIMEOUT, WRITE_TIMEOUT};
use std::io::{ErrorKind, Read, Write};
use std::net::{Shutdown, SocketAddr, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// The prefix of a TCP instrument in `--serial`.
pub const PREFIX: &str = "tcp:";

/// How long one connection attempt to one address may take.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);

/// The wait before the first reconnection attempt.
pub const BACKOFF_FIRST: Duration = Duration::from_millis(500);

/// The longest wait between two connection attempts.
pub const BACKOFF_MAX: Duration = Duration::from_secs(30);

/// How often a back-off wait looks at the stop flag.
const STOP_CHECK: Duration = Duration::from_millis(20);

/// `HOST:PORT` of a device server, checked for form only (the name is resolved at each attempt).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TcpTarget {
    /// A name or an address; an IPv6 address without its brackets.
    pub host: String,
    /// The device server's TCP port, `1..=65535`.
    pub port: u16,
}

impl TcpTarget {
    /// Parses `HOST:PORT` (`[IPv6]:PORT` for an IPv6 address); `spec` is the whole argument, for
    /// the error message.
    pub fn parse(text: &str, spec: &str) -> Result<TcpTarget, String> {
        let form = "expected tcp:HOST:PORT, e.g. tcp:192.168.127.254:4001 or tcp:[::1]:4001";
        let (host, port) = text.rsplit_once(':').ok_or_else(|| format!("'{spec}': no port: {form}"))?;
        let host = match host.strip_prefix('[') {
            Some(inner) => inner
                .strip_suffix(']')
                .filter(|h| h.parse::<std::net::Ipv6Addr>().is_ok())
                .ok_or_else(|| format!("'{spec}': '{host}' is not a bracketed IPv6 address: {form}"))?,
            None if host.contains(':') => {
                return Err(format!("'{spec}': an IPv6 address goes in brackets: {form}"))
            }
            None => host,
        };
        if host.is_empty() {
            return Err(format!("'{spec}': no host: {form}"));
        }
        if let Some(c) = host.chars().find(|c| c.is_whitespace() || c.is_control() || *c == '/') {
            return Err(format!("'{spec}': the host '{host}' holds {c:?}: {form}"));
        }
        let port = port
            .parse::<u16>()
            .ok()
            .filter(|p| *p != 0)
            .ok_or_else(|| format!("'{spec}': the port '{port}' is not a number of 1..=65535"))?;
        Ok(TcpTarget { host: host.to_string(), port })
    }
}

impl std::fmt::Display for TcpTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.host.contains(':') {
            write!(f, "{PREFIX}[{}]:{}", self.host, self.port)
        } else {
            write!(f, "{PREFIX}{}:{}", self.host, self.port)
        }
    }
}

/// The wait before attempt `n + 1` after `n` failures in a row (`n >= 1`): [`BACKOFF_FIRST`]
/// doubled `n - 1` times, at most [`BACKOFF_MAX`].
pub fn backoff(failures: u32) -> Duration {
    let doublings = failures.saturating_sub(1).min(16);
    BACKOFF_FIRST.saturating_mul(1 << doublings).min(BACKOFF_MAX)
}

/// The open connection the writer uses, and why the writer gave it up.
#[derive(Default)]
struct Shared {
    stream: Option<TcpStream>,
    write_error: Option<std::io::Error>,
}

fn lock(shared: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    // A panicking thread cannot leave `Shared` half-updated: take it as it is.
    shared.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Opens [`SerialLine`]s to device servers.
#[derive(Debug)]
pub struct TcpLine;

impl TcpLine {
    /// A line to `target`; connects in the background (the first attempt at once) and keeps
    /// reconnecting until the line is dropped.
    pub fn open(target: &TcpTarget, clock: Clock) -> SerialLine {
        let (event_tx, events) = mpsc::channel();
        let (outgoing, frames) = mpsc::sync_channel::<Vec<u8>>(OUTGOING_FRAMES);
        let stop = Arc::new(AtomicBool::new(false));
        let shared = Arc::new(Mutex::new(Shared::default()));
        let reader = {
            let (target, events, stop, shared) =
                (target.clone(), event_tx.clone(), Arc::clone(&stop), Arc::clone(&shared));
            std::thread::spawn(move || connect_and_read(&target, clock, &events, &stop, &shared))
        };
        let writer = std::thread::spawn(move || write_frames(&frames, &shared));
        SerialLine::from_threads(&target.to_string(), events, outgoing, stop, vec![reader, writer])
    }
}

/// The reader thread: connect, read until the connection ends, wait, again; until `stop`.
fn connect_and_read(
    target: &TcpTarget,
    clock: Clock,
    events: &Sender<SerialEvent>,
    stop: &AtomicBool,
    shared: &Mutex<Shared>,
) {
    let mut failures = 0u32;
    while !stop.load(Ordering::Relaxed) {
        let error = match connect(target) {
            Ok((stream, peer)) => {
                failures = 0;
                let reader = stream.try_clone();
                lock(shared).stream = Some(stream);
                if events.send(SerialEvent::Connection(ConnectionEvent::Connected { peer })).is_err() {
                    return;
                }
                let error = match reader {
                    Ok(reader) => read_until_lost(reader, clock, events, stop),
                    Err(e) => Some(e),
                };
                let mut s = lock(shared);
                if let Some(stream) = s.stream.take() {
                    let _ = stream.shutdown(Shutdown::Both);
                }
                match (s.write_error.take(), error) {
                    (Some(e), _) | (None, Some(e)) => {
                        ConnectionEvent::Lost { error: e, retry_in: backoff(1) }
                    }
                    // Stopped while connected.
                    (None, None) => return,
                }
            }
            Err(error) => ConnectionEvent::Failed { error, retry_in: backoff(failures + 1) },
        };
        failures = failures.saturating_add(1);
        let wait = backoff(failures);
        if events.send(SerialEvent::Connection(error)).is_err() {
            return;
        }
        let end = std::time::Instant::now() + wait;
        while !stop.load(Ordering::Relaxed) && std::time::Instant::now() < end {
            std::thread::sleep(STOP_CHECK.min(end.saturating_duration_since(std::time::Instant::now())));
        }
    }
}

/// One connection attempt: every address `target` resolves to, in order.
fn connect(target: &TcpTarget) -> std::io::Result<(TcpStream, SocketAddr)> {
    let mut last = std::io::Error::new(ErrorKind::NotFound, "the host name resolves to no address");
    for addr in (target.host.as_str(), target.port).to_socket_addrs()? {
        match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
            Ok(stream) => {
                stream.set_nodelay(true)?;
                stream.set_read_timeout(Some(READ_TIMEOUT))?;
                stream.set_write_timeout(Some(WRITE_TIMEOUT))?;
                return Ok((stream, addr));
            }
            Err(e) => last = e,
        }
    }
    Err(last)
}

/// Reads until the connection ends (its error; end of stream is `UnexpectedEof`) or `stop`
/// (`None`).
fn read_until_lost(
    mut stream: TcpStream,
    clock: Clock,
    events: &Sender<SerialEvent>,
    stop: &AtomicBool,
) -> Option<std::io::Error> {
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::Relaxed) {
        match stream.read(&mut buf) {
            Ok(0) => {
                return Some(std::io::Error::new(ErrorKind::UnexpectedEof, "closed by the device server"))
            }
            Ok(n) => {
                let bytes = buf.get(..n).unwrap_or(&[]).to_vec();
                if events.send(SerialEvent::Bytes(clock.now(), bytes)).is_err() {
                    return None;
                }
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) => {}
            Err(e) => return Some(e),
        }
    }
    None
}

/// The writer thread: each frame to the open connection, or dropped when there is none. A
/// failed write (a peer that took nothing for [`WRITE_TIMEOUT`] included) ends the connection;
/// the reader reports it and reconnects.
fn write_frames(frames: &Receiver<Vec<u8>>, shared: &Mutex<Shared>) {
    // Ends when the line is dropped (the sender goes away).
    while let Ok(frame) = frames.recv() {
        let mut s = lock(shared);
        let Some(stream) = s.stream.as_mut() else { continue };
        if let Err(e) = stream.write_all(&frame).and_then(|()| stream.flush()) {
            let _ = stream.shutdown(Shutdown::Both);
            s.stream = None;
            s.write_error = Some(e);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;
    use std::net::TcpListener;

    #[rstest]
    #[case::ipv4("127.0.0.1:4001", "127.0.0.1", 4001)]
    #[case::name("nport-3.plant.example:950", "nport-3.plant.example", 950)]
    #[case::ipv6("[::1]:4001", "::1", 4001)]
    fn targets(#[case] text: &str, #[case] host: &str, #[case] port: u16) {
        let t = TcpTarget::parse(text, text).unwrap();
        assert_eq!((t.host.as_str(), t.port), (host, port));
        assert_eq!(t.to_string(), format!("tcp:{text}"));
    }

    #[rstest]
    #[case::no_port("host", "no port")]
    #[case::empty_port("host:", "the port '' is not a number of 1..=65535")]
    #[case::zero_port("host:0", "the port '0' is not")]
    #[case::big_port("host:65536", "the port '65536' is not")]
    #[case::no_host(":4001", "no host")]
    #[case::bare_ipv6("::1:4001", "an IPv6 address goes in brackets")]
    #[case::bad_brackets("[nport]:4001", "not a bracketed IPv6 address")]
    #[case::space("my host:4001", "holds ' '")]
    fn refused_targets(#[case] text: &str, #[case] msg: &str) {
        let spec = format!("tcp:{text}");
        let e = TcpTarget::parse(text, &spec).unwrap_err();
        assert!(e.starts_with(&format!("'{spec}': ")), "{e}");
        assert!(e.contains(msg), "{e}");
    }

    #[test]
    fn backoff_doubles_from_half_a_second_to_thirty() {
        let waits: Vec<u128> = (1..=9).map(|n| backoff(n).as_millis()).collect();
        assert_eq!(waits, [500, 1000, 2000, 4000, 8000, 16000, 30000, 30000, 30000]);
        assert_eq!(backoff(u32::MAX), BACKOFF_MAX);
    }

    fn next_connection_event(line: &SerialLine) -> ConnectionEvent {
        let end = std::time::Instant::now() + Duration::from_secs(10);
        while std::time::Instant::now() < end {
            if let Some(SerialEvent::Connection(e)) = line.wait_event(Duration::from_millis(100)) {
                return e;
            }
        }
        panic!("no connection event within 10 s");
    }

    #[test]
    fn bytes_both_ways_a_lost_connection_and_a_reconnection() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let target = TcpTarget::parse(&format!("127.0.0.1:{port}"), "test").unwrap();
        let clock = Clock::start();
        let line = TcpLine::open(&target, clock);
        assert_eq!(line.name(), format!("tcp:127.0.0.1:{port}"));
        let (mut server, _) = listener.accept().unwrap();
        assert!(matches!(next_connection_event(&line), ConnectionEvent::Connected { .. }));
        line.write(&[1, 2, 3]);
        let mut got = [0u8; 3];
        server.read_exact(&mut got).unwrap();
        assert_eq!(got, [1, 2, 3]);
        server.write_all(&[9, 8]).unwrap();
        match line.wait_event(Duration::from_secs(2)) {
            Some(SerialEvent::Bytes(_, bytes)) => assert_eq!(bytes, vec![9, 8]),
            other => panic!("{other:?}"),
        }
        // The device server closes: reported, then a new connection after the first back-off.
        drop(server);
        let lost_at = std::time::Instant::now();
        match next_connection_event(&line) {
            ConnectionEvent::Lost { error, retry_in } => {
                assert_eq!(error.kind(), ErrorKind::UnexpectedEof);
                assert_eq!(retry_in, BACKOFF_FIRST);
            }
            other => panic!("{other:?}"),
        }
        let (mut server, _) = listener.accept().unwrap();
        assert!(lost_at.elapsed() >= BACKOFF_FIRST - Duration::from_millis(50), "{:?}", lost_at.elapsed());
        assert!(matches!(next_connection_event(&line), ConnectionEvent::Connected { .. }));
        line.write(&[4]);
        let mut got = [0u8; 1];
        server.read_exact(&mut got).unwrap();
        assert_eq!(got, [4]);
    }

    #[test]
    fn refused_attempts_back_off_and_bytes_are_dropped_meanwhile() {
        // A port nobody listens on: bind, note it, close.
        let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let target = TcpTarget::parse(&format!("127.0.0.1:{port}"), "test").unwrap();
        let line = TcpLine::open(&target, Clock::start());
        for _ in 0..1000 {
            line.write(&[0; 64]);
        }
        let waits: Vec<Duration> = (0..2)
            .map(|_| match next_connection_event(&line) {
                ConnectionEvent::Failed { error, retry_in } => {
                    assert_eq!(error.kind(), ErrorKind::ConnectionRefused);
                    retry_in
                }
                other => panic!("{other:?}"),
            })
            .collect();
        assert_eq!(waits, [BACKOFF_FIRST, BACKOFF_FIRST * 2]);
        let started = std::time::Instant::now();
        drop(line);
        assert!(started.elapsed() < Duration::from_secs(1), "the back-off wait stops with the line");
    }
}
