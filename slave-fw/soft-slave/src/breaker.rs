//! [`BreakerRunner`]: the simulated intelligent circuit breaker
//! ([`SimulatedBreaker`]) on a real byte stream — a serial port, one end of a pseudo-terminal pair,
//! or a Unix socket in tests — in real time, with fault knobs and an event log.
//!
//! The log has one line per event, `SECONDS EVENT`, flushed as written so a test can follow it:
//!
//! | event | when |
//! |---|---|
//! | `command open` / `command close` / `command refresh` / `command set_parameter id=N value=V` | a command frame arrived (whether or not it is obeyed) |
//! | `status open 0,0,0,0` / `status closed 120,118,121,3` | a status frame was sent (switch state, phase currents A, B, C, N) |
//! | `ack CMD status S` | an acknowledgement was sent |
//! | `garbage N bytes` | `--garbage-every`: raw bytes were sent, and the next frame's checksum is spoiled |
//! | `silent` | `--silent-after`: the breaker stopped sending (commands are still obeyed) |
//! | `line blocked: N bytes lost` | nobody drains the line (the other end of a pty is not open) |

use crate::clock::{format_instant, Clock};
use converter_sim::SimulatedBreaker;
use devicenet::{Duration, Instant};
use slave_fw::serial::breaker::{self, BreakerCommand, Message, SwitchState};
use slave_fw::serial::FrameParser;
use std::io::{ErrorKind, Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};

/// The bytes `--garbage-every` sends: a start byte with an impossible length, a stray end byte and
/// noise, so the receiver must resynchronise (framing error, discarded bytes).
pub const GARBAGE: [u8; 6] = [0x68, 0x99, 0x01, 0x16, 0xFF, 0x00];

/// The currents the breaker reports while closed unless told otherwise, the same as the
/// simulated bus's soft slave (`dnet-master --bus sim`).
pub const DEFAULT_LOAD: [u8; 4] = converter_sim::device::LOAD;

/// How the simulated breaker behaves.
#[derive(Clone, Debug, PartialEq)]
pub struct BreakerOptions {
    /// Status frame period.
    pub period: Duration,
    /// Phase A, B, C, N currents while closed.
    pub load: [u8; 4],
    /// Start closed instead of open.
    pub closed: bool,
    /// Stop sending this long after start.
    pub silent_after: Option<Duration>,
    /// Send [`GARBAGE`] and spoil the next frame's checksum this often.
    pub garbage_every: Option<Duration>,
}

impl Default for BreakerOptions {
    /// One status frame a second, [`DEFAULT_LOAD`], open, no faults.
    fn default() -> Self {
        BreakerOptions {
            period: Duration::from_secs(1),
            load: DEFAULT_LOAD,
            closed: false,
            silent_after: None,
            garbage_every: None,
        }
    }
}

/// The simulated breaker on a byte stream. See the [module docs](self).
pub struct BreakerRunner<P: Read + Write> {
    port: P,
    breaker: SimulatedBreaker,
    options: BreakerOptions,
    clock: Clock,
    start: Instant,
    log: Box<dyn Write>,
    next_garbage: Option<Instant>,
    silenced: bool,
    commands_seen: usize,
}

impl<P: Read + Write> BreakerRunner<P> {
    /// A breaker powered up now on `port`, whose reads should time out after a few milliseconds
    /// (a `TimedOut` or `WouldBlock` error) so that timers run. Events go to `log`.
    pub fn new(port: P, options: BreakerOptions, clock: Clock, log: Box<dyn Write>) -> BreakerRunner<P> {
        let start = clock.now();
        let mut breaker = SimulatedBreaker::new(start).with_period(options.period);
        breaker.set_load(options.load);
        if options.closed {
            breaker.set_switch(SwitchState::Closed);
        }
        let next_garbage = options.garbage_every.map(|d| start + d);
        BreakerRunner {
            port,
            breaker,
            options,
            clock,
            start,
            log,
            next_garbage,
            silenced: false,
            commands_seen: 0,
        }
    }

    /// The breaker (its state and every command received).
    pub fn breaker(&self) -> &SimulatedBreaker {
        &self.breaker
    }

    /// Runs until `stop` is set, `duration` has passed, or the port fails (the error is
    /// returned; the end of a stream is `UnexpectedEof`).
    pub fn run(&mut self, stop: &AtomicBool, duration: Option<Duration>) -> std::io::Result<()> {
        let end = duration.map(|d| self.start + d);
        let mut buf = [0u8; 256];
        loop {
            let now = self.clock.now();
            if stop.load(Ordering::Relaxed) || end.is_some_and(|e| now >= e) {
                return self.log.flush();
            }
            self.timers(now)?;
            while let Some(bytes) = self.breaker.poll_transmit(now) {
                self.log_sent(&bytes, now)?;
                match self.port.write_all(&bytes).and_then(|()| self.port.flush()) {
                    Ok(()) => {}
                    // Nobody drains the line (the converter is not running yet): the bytes are
                    // lost, as on a wire with nobody listening.
                    Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {
                        self.event(now, &format!("line blocked: {} bytes lost", bytes.len()))?;
                    }
                    Err(e) => return Err(e),
                }
            }
            match self.port.read(&mut buf) {
                Ok(0) => return Err(std::io::Error::new(ErrorKind::UnexpectedEof, "the line was closed")),
                Ok(n) => {
                    let at = self.clock.now();
                    self.breaker.on_bytes(buf.get(..n).unwrap_or(&[]), at);
                    self.log_commands(at)?;
                }
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => {}
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    fn timers(&mut self, now: Instant) -> std::io::Result<()> {
        if !self.silenced && self.options.silent_after.is_some_and(|d| now >= self.start + d) {
            self.silenced = true;
            self.breaker.set_silent(true);
            self.event(now, "silent")?;
        }
        if let (Some(due), Some(every)) = (self.next_garbage, self.options.garbage_every) {
            if now >= due && !self.silenced {
                self.breaker.send_garbage(&GARBAGE, now);
                self.breaker.corrupt_next_frames(1);
                self.next_garbage = Some(now + every.max(Duration::from_millis(1)));
                self.event(now, &format!("garbage {} bytes", GARBAGE.len()))?;
            }
        }
        Ok(())
    }

    fn log_commands(&mut self, at: Instant) -> std::io::Result<()> {
        let new: Vec<BreakerCommand> =
            self.breaker.commands().iter().skip(self.commands_seen).copied().collect();
        self.commands_seen += new.len();
        for cmd in new {
            self.event(at, &format!("command {}", command_text(&cmd)))?;
        }
        Ok(())
    }

    fn log_sent(&mut self, bytes: &[u8], now: Instant) -> std::io::Result<()> {
        if bytes.first() != Some(&breaker::START) {
            // Garbage, logged when queued.
            return Ok(());
        }
        let mut parser = FrameParser::<32>::new(breaker::FRAMING)
            .map_err(|e| std::io::Error::new(ErrorKind::InvalidInput, e.to_string()))?;
        let mut messages = Vec::new();
        let mut spoiled = false;
        parser.push_slice(bytes, |event| match event {
            Ok(frame) => messages.push(Message::classify(frame.data())),
            Err(_) => spoiled = true,
        });
        if spoiled {
            return self.event(now, "frame with a bad checksum");
        }
        for m in messages {
            let text = match m {
                Message::Status(s) => {
                    let c = s.phase_currents();
                    let switch = match s.switch_state() {
                        SwitchState::Open => "open".to_string(),
                        SwitchState::Closed => "closed".to_string(),
                        SwitchState::Unknown(v) => format!("0x{v:02X}"),
                    };
                    format!("status {switch} {},{},{},{}", c[0], c[1], c[2], c[3])
                }
                Message::Ack(a) => format!("ack 0x{:02X} status {}", a.command, a.status),
                other => format!("frame {other:?}"),
            };
            self.event(now, &text)?;
        }
        Ok(())
    }

    fn event(&mut self, at: Instant, text: &str) -> std::io::Result<()> {
        writeln!(self.log, "{} {text}", format_instant(Instant::ZERO + (at - self.start)))?;
        self.log.flush()
    }
}

/// `open`, `close`, `refresh`, `set_parameter id=1 value=4660`.
pub fn command_text(cmd: &BreakerCommand) -> String {
    match cmd {
        BreakerCommand::Open => "open".into(),
        BreakerCommand::Close => "close".into(),
        BreakerCommand::Refresh => "refresh".into(),
        BreakerCommand::SetParameter { id, value } => format!("set_parameter id={id} value={value}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::net::UnixStream;
    use std::sync::{Arc, Mutex};

    /// A log sink the test can read.
    #[derive(Clone, Default)]
    struct Shared(Arc<Mutex<Vec<u8>>>);

    impl Write for Shared {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    fn frame(data: &[u8]) -> Vec<u8> {
        let mut out = [0u8; 32];
        let n = breaker::FRAMING.encode(data, &mut out).unwrap();
        out[..n].to_vec()
    }

    #[test]
    fn status_commands_garbage_and_silence_are_logged() {
        let (ours, mut theirs) = UnixStream::pair().unwrap();
        ours.set_read_timeout(Some(std::time::Duration::from_millis(2))).unwrap();
        let log = Shared::default();
        let options = BreakerOptions {
            period: Duration::from_millis(50),
            closed: true,
            garbage_every: Some(Duration::from_millis(120)),
            silent_after: Some(Duration::from_millis(300)),
            ..BreakerOptions::default()
        };
        let mut runner = BreakerRunner::new(ours, options, Clock::start(), Box::new(log.clone()));
        theirs.write_all(&frame(&[breaker::CMD_OPEN])).unwrap();
        theirs.write_all(&frame(&[breaker::CMD_SET_PARAMETER, 1, 0x34, 0x12])).unwrap();
        runner.run(&AtomicBool::new(false), Some(Duration::from_millis(400))).unwrap();
        assert_eq!(
            runner.breaker().commands(),
            &[BreakerCommand::Open, BreakerCommand::SetParameter { id: 1, value: 0x1234 }]
        );
        let text = String::from_utf8(log.0.lock().unwrap().clone()).unwrap();
        assert!(text.lines().next().unwrap().ends_with(" status closed 120,118,121,3"), "{text}");
        for needle in [
            " command open",
            " command set_parameter id=1 value=4660",
            " ack 0x01 status 0",
            " status open 0,0,0,0",
            " garbage 6 bytes",
            " frame with a bad checksum",
            " silent",
        ] {
            assert!(text.contains(needle), "{needle} missing in\n{text}");
        }
        let last = text.lines().last().unwrap();
        assert!(last.ends_with(" silent"), "nothing is sent once silent:\n{text}");
    }

    #[test]
    fn a_closed_line_ends_the_run() {
        let (ours, theirs) = UnixStream::pair().unwrap();
        ours.set_read_timeout(Some(std::time::Duration::from_millis(2))).unwrap();
        drop(theirs);
        let mut runner =
            BreakerRunner::new(ours, BreakerOptions::default(), Clock::start(), Box::new(std::io::sink()));
        let err = runner.run(&AtomicBool::new(false), None).unwrap_err();
        assert!(matches!(err.kind(), ErrorKind::UnexpectedEof | ErrorKind::BrokenPipe), "{err}");
    }
}
