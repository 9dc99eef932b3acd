//! The instrument's serial line: opened with the profile's settings, read by one thread and
//! written by another, so the main loop (and with it every poll response) never waits on it.
//!
//! The reader thread timestamps each chunk with the shared [`Clock`] as it arrives; the converter
//! gets the bytes with that time (the Modbus master measures line silence from it). The writer
//! thread takes whole frames from a channel of at most [`OUTGOING_FRAMES`] (more are dropped, as
//! on a line nobody drains). Either thread reports a failed port once through the same channel as
//! the bytes ([`SerialEvent::Failed`]) and stops. An instrument behind a device server
//! (`--serial tcp:HOST:PORT`) is a line too, with its own threads (`crate::tcp`).

use crate::clock::Clock;
use crate::error::SoftSlaveError;
use devicenet::Instant;
use slave_fw::serial::{DataBits, Parity, SerialSettings, StopBits};
use std::io::{ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TryRecvError};
use std::sync::Arc;
use std::thread::JoinHandle;

/// How long one read may block before the reader thread looks at its stop flag again.
pub const READ_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(20);

/// How long a write may block before its frame is given up (a line nobody drains).
pub const WRITE_TIMEOUT: std::time::Duration = std::time::Duration::from_millis(500);

/// The most frames queued for the writer thread; more are dropped until it catches up.
pub const OUTGOING_FRAMES: usize = 16;

/// What the serial threads report.
#[derive(Debug)]
pub enum SerialEvent {
    /// Bytes read from the port, and when they arrived.
    Bytes(Instant, Vec<u8>),
    /// The port failed (`reading` or `writing`); the thread that saw it has stopped.
    Failed(&'static str, std::io::Error),
    /// A line over TCP connected, lost its connection or failed to connect (it keeps trying).
    Connection(ConnectionEvent),
}

/// A change of a TCP line's connection (`--serial tcp:HOST:PORT`).
#[derive(Debug)]
pub enum ConnectionEvent {
    /// Connected to `peer`.
    Connected {
        /// The address the connection went to.
        peer: std::net::SocketAddr,
    },
    /// The connection ended; the next attempt comes after `retry_in`.
    Lost {
        /// Why (`UnexpectedEof`: the device server closed it).
        error: std::io::Error,
        /// The back-off wait before the next attempt.
        retry_in: std::time::Duration,
    },
    /// An attempt to connect failed; the next comes after `retry_in`.
    Failed {
        /// Why (refused, timed out, the name did not resolve).
        error: std::io::Error,
        /// The back-off wait before the next attempt.
        retry_in: std::time::Duration,
    },
}

impl std::fmt::Display for ConnectionEvent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConnectionEvent::Connected { peer } => write!(f, "connected to {peer}"),
            ConnectionEvent::Lost { error, retry_in } => {
                write!(f, "connection lost ({error}): reconnecting in {:.1} s", retry_in.as_secs_f64())
            }
            ConnectionEvent::Failed { error, retry_in } => {
                write!(f, "cannot connect ({error}): next attempt in {:.1} s", retry_in.as_secs_f64())
            }
        }
    }
}

/// `9600 8N1`, `19200 8E1`: the settings as a bench engineer writes them.
pub fn settings_text(s: &SerialSettings) -> String {
    let data = match s.data_bits {
        DataBits::Seven => '7',
        DataBits::Eight => '8',
    };
    let parity = match s.parity {
        Parity::None => 'N',
        Parity::Even => 'E',
        Parity::Odd => 'O',
    };
    let stop = match s.stop_bits {
        StopBits::One => '1',
        StopBits::Two => '2',
    };
    format!("{} {data}{parity}{stop}", s.baud)
}

/// The profile's character format in `serialport`'s terms.
pub fn character_format(
    s: &SerialSettings,
) -> (serialport::DataBits, serialport::Parity, serialport::StopBits) {
    let data = match s.data_bits {
        DataBits::Seven => serialport::DataBits::Seven,
        DataBits::Eight => serialport::DataBits::Eight,
    };
    let parity = match s.parity {
        Parity::None => serialport::Parity::None,
        Parity::Even => serialport::Parity::Even,
        Parity::Odd => serialport::Parity::Odd,
    };
    let stop = match s.stop_bits {
        StopBits::One => serialport::StopBits::One,
        StopBits::Two => serialport::StopBits::Two,
    };
    (data, parity, stop)
}

/// The `serialport` builder for a path and the profile's settings (no flow control).
pub fn port_builder(path: &str, s: &SerialSettings) -> serialport::SerialPortBuilder {
    let (data, parity, stop) = character_format(s);
    serialport::new(path, s.baud)
        .data_bits(data)
        .parity(parity)
        .stop_bits(stop)
        .flow_control(serialport::FlowControl::None)
        .timeout(READ_TIMEOUT)
}

/// Opens `path` with the profile's settings.
pub fn open_port(path: &str, s: &SerialSettings) -> Result<Box<dyn serialport::SerialPort>, SoftSlaveError> {
    port_builder(path, s).open().map_err(|source| SoftSlaveError::SerialOpen {
        path: path.to_string(),
        settings: settings_text(s),
        source,
    })
}

/// The instrument's serial line, served by a reader and a writer thread.
pub struct SerialLine {
    name: String,
    events: Receiver<SerialEvent>,
    outgoing: Option<SyncSender<Vec<u8>>>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl std::fmt::Debug for SerialLine {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialLine").field("name", &self.name).finish()
    }
}

impl SerialLine {
    /// Opens the serial port `path` with the profile's settings.
    pub fn open(path: &str, settings: &SerialSettings, clock: Clock) -> Result<SerialLine, SoftSlaveError> {
        let reader = open_port(path, settings)?;
        let open_error = |source| SoftSlaveError::SerialOpen {
            path: path.to_string(),
            settings: settings_text(settings),
            source,
        };
        let mut writer = reader.try_clone().map_err(open_error)?;
        // `serialport` has one timeout per handle, for reads and writes alike.
        writer.set_timeout(WRITE_TIMEOUT).map_err(open_error)?;
        Ok(SerialLine::from_parts(path, reader, writer, clock))
    }

    /// A line over a Unix stream (tests, or a bridge to another process). Reads time out after
    /// [`READ_TIMEOUT`] so the reader can stop.
    pub fn from_stream(
        stream: std::os::unix::net::UnixStream,
        name: &str,
        clock: Clock,
    ) -> std::io::Result<SerialLine> {
        stream.set_read_timeout(Some(READ_TIMEOUT))?;
        stream.set_write_timeout(Some(WRITE_TIMEOUT))?;
        let reader = stream.try_clone()?;
        Ok(SerialLine::from_parts(name, reader, stream, clock))
    }

    /// A line over any reader and writer. The reader should time out now and then (a
    /// `TimedOut` or `WouldBlock` error) so that the line can be shut down.
    pub fn from_parts<R, W>(name: &str, mut reader: R, mut writer: W, clock: Clock) -> SerialLine
    where
        R: Read + Send + 'static,
        W: Write + Send + 'static,
    {
        let (event_tx, events) = mpsc::channel();
        let (outgoing, frames) = mpsc::sync_channel::<Vec<u8>>(OUTGOING_FRAMES);
        let stop = Arc::new(AtomicBool::new(false));
        let read_events = event_tx.clone();
        let read_stop = Arc::clone(&stop);
        let read = std::thread::spawn(move || {
            let mut buf = [0u8; 256];
            while !read_stop.load(Ordering::Relaxed) {
                match reader.read(&mut buf) {
                    // End of file: a pty whose other side is gone for good, or a closed stream.
                    Ok(0) => {
                        let _ = read_events.send(SerialEvent::Failed(
                            "reading",
                            std::io::Error::new(ErrorKind::UnexpectedEof, "the line was closed"),
                        ));
                        return;
                    }
                    Ok(n) => {
                        let at = clock.now();
                        let bytes = buf.get(..n).unwrap_or(&[]).to_vec();
                        if read_events.send(SerialEvent::Bytes(at, bytes)).is_err() {
                            return;
                        }
                    }
                    Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {}
                    Err(e) if e.kind() == ErrorKind::Interrupted => {}
                    Err(e) => {
                        let _ = read_events.send(SerialEvent::Failed("reading", e));
                        return;
                    }
                }
            }
        });
        let write = std::thread::spawn(move || {
            // Ends when the line is dropped (the sender goes away).
            while let Ok(frame) = frames.recv() {
                match writer.write_all(&frame).and_then(|()| writer.flush()) {
                    Ok(()) => {}
                    // Nobody drains the line (a pty whose other end is not open): the frame is
                    // lost, as it would be on a wire with nobody listening; the profile's
                    // timeouts and retries deal with it.
                    Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {}
                    Err(e) => {
                        let _ = event_tx.send(SerialEvent::Failed("writing", e));
                        return;
                    }
                }
            }
        });
        SerialLine::from_threads(name, events, outgoing, stop, vec![read, write])
    }

    /// A line served by `threads`, which deliver `events`, take frames from `outgoing`'s
    /// receiver and end once `stop` is set and `outgoing` is dropped.
    pub(crate) fn from_threads(
        name: &str,
        events: Receiver<SerialEvent>,
        outgoing: SyncSender<Vec<u8>>,
        stop: Arc<AtomicBool>,
        threads: Vec<JoinHandle<()>>,
    ) -> SerialLine {
        SerialLine { name: name.to_string(), events, outgoing: Some(outgoing), stop, threads }
    }

    /// The port's name (its path, or `tcp:HOST:PORT`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Queues bytes for the writer thread; never blocks. Dropped when [`OUTGOING_FRAMES`] frames
    /// are already waiting.
    pub fn write(&self, bytes: &[u8]) {
        if let Some(tx) = &self.outgoing {
            // A full queue loses the frame, as a line nobody drains would; a stopped writer has
            // reported its error through the event channel.
            let _ = tx.try_send(bytes.to_vec());
        }
    }

    /// The next event from the threads, if one is waiting.
    pub fn try_event(&self) -> Option<SerialEvent> {
        match self.events.try_recv() {
            Ok(e) => Some(e),
            Err(TryRecvError::Empty) | Err(TryRecvError::Disconnected) => None,
        }
    }

    /// Waits up to `timeout` for the next event.
    pub fn wait_event(&self, timeout: std::time::Duration) -> Option<SerialEvent> {
        self.events.recv_timeout(timeout).ok()
    }
}

impl Drop for SerialLine {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Closing the channel ends the writer once it has written what was queued.
        self.outgoing = None;
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;
    use std::os::unix::net::UnixStream;

    #[rstest]
    #[case::breaker(SerialSettings::new_8n1(9600), "9600 8N1", serialport::Parity::None)]
    #[case::modbus(SerialSettings::new_8e1(19200), "19200 8E1", serialport::Parity::Even)]
    #[case::seven_odd_two(
        SerialSettings { baud: 1200, data_bits: DataBits::Seven, parity: Parity::Odd, stop_bits: StopBits::Two },
        "1200 7O2",
        serialport::Parity::Odd
    )]
    fn settings(#[case] s: SerialSettings, #[case] text: &str, #[case] parity: serialport::Parity) {
        assert_eq!(settings_text(&s), text);
        let (data, p, stop) = character_format(&s);
        assert_eq!(p, parity);
        assert_eq!(u8::from(data), if s.data_bits == DataBits::Seven { 7 } else { 8 });
        assert_eq!(u8::from(stop), if s.stop_bits == StopBits::Two { 2 } else { 1 });
    }

    #[test]
    fn missing_port_is_named_with_its_settings() {
        let err = open_port("/dev/does-not-exist", &SerialSettings::new_8n1(9600)).unwrap_err();
        let text = err.to_string();
        assert!(text.starts_with("cannot open the serial port '/dev/does-not-exist' (9600 8N1): "), "{text}");
    }

    #[test]
    fn bytes_both_ways_with_timestamps() {
        let clock = Clock::start();
        let (ours, mut theirs) = UnixStream::pair().unwrap();
        let line = SerialLine::from_stream(ours, "pair", clock).unwrap();
        line.write(&[1, 2, 3]);
        let mut got = [0u8; 3];
        theirs.read_exact(&mut got).unwrap();
        assert_eq!(got, [1, 2, 3]);
        let before = clock.now();
        theirs.write_all(&[9, 8]).unwrap();
        match line.wait_event(std::time::Duration::from_secs(2)) {
            Some(SerialEvent::Bytes(at, bytes)) => {
                assert_eq!(bytes, vec![9, 8]);
                assert!(at >= before);
            }
            other => panic!("{other:?}"),
        }
        drop(theirs);
        match line.wait_event(std::time::Duration::from_secs(2)) {
            Some(SerialEvent::Failed("reading", e)) => assert_eq!(e.kind(), ErrorKind::UnexpectedEof),
            other => panic!("{other:?}"),
        }
    }
}
