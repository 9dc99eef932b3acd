//! The Modbus RTU master: walks a scan list, fills the input image, writes changed outputs.
//!
//! ## Scan cycle
//!
//! A cycle reads every read entry (functions 1–4) of the scan list in order, and starts every
//! [`poll_period_ms`](ModbusConfig::poll_period_ms) (at once when the previous cycle overran).
//! Write entries (5, 6, 15, 16) are sent whenever their bytes of the output image have changed
//! since they were last written, ahead of the next read, so outputs reach the instrument within
//! one transaction. A write that fails (no answer after retries, or an exception) stays pending
//! and is tried again in the next cycle, not sooner. That is the default; an entry's own
//! schedule (a period, a cyclic re-send, a trigger byte) and the order of everything that is due
//! are the [`schedule`](super::schedule) module's.
//!
//! Each transaction waits [`response_timeout_ms`](ModbusConfig::response_timeout_ms) after the
//! end of its transmission and is repeated up to [`retries`](ModbusConfig::retries) times after a
//! timeout or a corrupted answer. An exception is a definite answer and is not repeated.
//!
//! ## Framing: responses are delimited by length, not by silence
//!
//! RTU frames are officially delimited by 3.5 character times of silence, but byte timestamps
//! are not available everywhere this code runs (a pseudo-terminal or a USB serial adapter
//! delivers bytes in chunks). The master always knows what it asked for, so it delimits a
//! response by its function code and byte count ([`pdu::response_len`]) and checks the CRC;
//! leading bytes that cannot start the expected response (wrong unit address or function) are
//! skipped. The silence is still honoured on transmit: a request goes out only when the line has
//! been quiet for [`SerialSettings::modbus_interframe_silence`] since the last byte received
//! (the `now` passed to [`ModbusMaster::on_bytes`]) and since the end of the master's own last
//! transmission (estimated from the baud rate).
//!
//! [`SerialSettings::modbus_interframe_silence`]: crate::serial::SerialSettings::modbus_interframe_silence
//!
//! ## Image layout
//!
//! Each entry occupies [`ScanEntry::image_len`] bytes at its `offset`: registers 2 bytes each in
//! the configured [`ByteOrder`] (little-endian by default, as DeviceNet carries an INT), bits
//! packed LSB first as on the Modbus wire (unused high bits of the last byte are zero on reads
//! and ignored on writes; a single coil is bit 0).

pub use super::config::{ModbusConfig, SCAN_LIST_CAPACITY};
use super::entry::{append_crc, encode_entry, store_read};
pub use super::entry::{ByteOrder, ScanEntry, WordOrder};
use super::framing::{Framer, Framing, Received};
use super::pdu::{self, CodecError, ExceptionCode, ADU_CAPACITY};
use super::schedule::{called_for, Timetable};
use super::units::{UnitHealth, UnitRow};
use crate::serial::error::{as_u32, ConfigError};
use crate::serial::health::{Counter, LinkHealth, LinkStatus, Stats};
use crate::serial::sequencer::{CommandOutcome, OutputMode};
use crate::serial::IMAGE_CAPACITY;
use devicenet::{Duration, Instant};
use heapless::Vec;

#[derive(Clone, Copy, Debug, Default)]
struct EntryState {
    /// A write entry whose output bytes changed since they were last sent.
    dirty: bool,
    /// A write entry that failed in the current cycle: not tried again before the next.
    failed_this_cycle: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Job {
    /// Scan list entry `i`.
    Entry(usize),
    /// The idle or fault frame.
    ModeFrame,
}

#[derive(Clone, Copy, Debug)]
/// The request awaiting its response; the request itself stays in `tx` until the next one.
struct Transaction {
    job: Job,
    attempt: u8,
    deadline: Instant,
}

/// A flag that is shown for the current and the last complete scan cycle.
#[derive(Clone, Copy, Debug, Default)]
struct CycleFlag {
    current: bool,
    last: bool,
}

impl CycleFlag {
    fn roll(&mut self) {
        self.last = self.current;
        self.current = false;
    }

    fn shown(&self) -> bool {
        self.current || self.last
    }
}

/// A sans-IO Modbus RTU master over one serial line. Driven like every
/// [`Profile`](crate::serial::Profile): see the [`serial`](crate::serial) module and the
/// [module docs](self).
#[derive(Clone, Debug)]
pub struct ModbusMaster {
    config: ModbusConfig,
    health: LinkHealth,
    /// Per-unit health and the data-valid bits.
    units: UnitHealth,
    input: Vec<u8, IMAGE_CAPACITY>,
    output: [u8; IMAGE_CAPACITY],
    outputs_valid: bool,
    entries: [EntryState; SCAN_LIST_CAPACITY],
    mode: OutputMode,
    mode_frame_due: bool,
    /// The last request, in its first `tx_len` bytes (0: none). A plain buffer, not a
    /// `heapless::Vec` zero-filled before each encode (firmware size).
    tx: [u8; ADU_CAPACITY],
    tx_len: usize,
    /// The request framed for the line (ASCII, TCP) and the decoders of their responses.
    framer: Framer,
    /// Received bytes: the response being delimited (RTU), or the address and PDU (ASCII, TCP).
    rx: Vec<u8, ADU_CAPACITY>,
    awaiting: Option<Transaction>,
    /// An entry to send again, with its next attempt number.
    retry: Option<(usize, u8)>,
    cycle_running: bool,
    cycle_started: Instant,
    /// Which entries are due, and the next period instants (the [schedule](super::schedule)).
    timetable: Timetable<SCAN_LIST_CAPACITY>,
    cycles: u32,
    /// The line is quiet enough to transmit from this instant.
    quiet_at: Instant,
    unexpected_burst: bool,
    exception: CycleFlag,
    request_timeout: CycleFlag,
    write_outcome: CommandOutcome,
    /// Scan list index and raw code: decoded only when asked for (the firmware never asks).
    last_exception: Option<(usize, u8)>,
    silence: Duration,
}

impl ModbusMaster {
    /// A master for `config`, started at `now`: the first scan cycle starts at once and the stale
    /// timeout runs from here. Nothing is written before the first outputs arrive.
    pub fn new(config: ModbusConfig, now: Instant) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(ModbusMaster::build(config, now))
    }

    /// The master for `config`, which [`ModbusConfig::validate`] has accepted: nothing is checked
    /// twice, and nothing fails. Out of line: the large value is built in its return slot, not
    /// copied piece by piece through the caller's frame (firmware size budget).
    #[inline(never)]
    pub(crate) fn build(config: ModbusConfig, now: Instant) -> Self {
        let health = LinkHealth::build(config.health, now);
        let units = UnitHealth::new(&config, now);
        let mut input = Vec::new();
        // validate() bounds input_len by IMAGE_CAPACITY.
        let _ = input.resize(usize::from(config.input_len).min(IMAGE_CAPACITY), 0);
        // Only RTU frames are delimited by silence.
        let silence = if config.framing == Framing::Rtu {
            config.serial.modbus_interframe_silence()
        } else {
            Duration::from_micros(0)
        };
        let framer = Framer::new(config.framing);
        let mut master = ModbusMaster {
            config,
            health,
            units,
            input,
            output: [0; IMAGE_CAPACITY],
            outputs_valid: false,
            entries: [EntryState::default(); SCAN_LIST_CAPACITY],
            mode: OutputMode::Startup,
            mode_frame_due: false,
            tx: [0; ADU_CAPACITY],
            tx_len: 0,
            framer,
            rx: Vec::new(),
            awaiting: None,
            retry: None,
            cycle_running: false,
            cycle_started: now,
            timetable: Timetable::new(now),
            cycles: 0,
            quiet_at: now,
            unexpected_burst: false,
            exception: CycleFlag::default(),
            request_timeout: CycleFlag::default(),
            write_outcome: CommandOutcome::None,
            last_exception: None,
            silence,
        };
        master.start_cycle(now);
        master
    }

    /// The configuration.
    pub fn config(&self) -> &ModbusConfig {
        &self.config
    }

    fn entry(&self, i: usize) -> Option<ScanEntry> {
        self.config.scan.get(i).copied()
    }

    fn is_write(&self, i: usize) -> bool {
        // Through a reference, not a copy of the entry (firmware size).
        self.config.scan.get(i).is_some_and(|e| e.function.is_write())
    }

    fn poll_period(&self) -> Duration {
        Duration::from_millis(u64::from(self.config.poll_period_ms))
    }

    /// Takes the consumed poll data received at `now`: the output image (shorter data is padded
    /// with zeros), or an empty slice for an idle poll. Write entries whose bytes changed are
    /// queued.
    pub fn set_outputs(&mut self, outputs: &[u8], now: Instant) {
        if outputs.is_empty() {
            self.enter(OutputMode::Idle);
            return;
        }
        if self.mode != OutputMode::Run {
            self.mode = OutputMode::Run;
            self.mode_frame_due = false;
        }
        let mut new = [0u8; IMAGE_CAPACITY];
        let len = usize::from(self.config.output_len).min(IMAGE_CAPACITY);
        for (slot, &b) in new.iter_mut().take(len).zip(outputs) {
            *slot = b;
        }
        for (i, (e, state)) in self.config.scan.iter().zip(self.entries.iter_mut()).enumerate() {
            if !called_for(e, &self.output, &new, !self.outputs_valid) {
                continue;
            }
            if e.function.is_write() {
                state.dirty = true;
            } else {
                self.timetable.trigger(i, now);
            }
        }
        self.output = new;
        self.outputs_valid = true;
    }

    /// The poll connection timed out at `now`.
    pub fn connection_fault(&mut self, _now: Instant) {
        self.enter(OutputMode::Fault);
    }

    fn enter(&mut self, mode: OutputMode) {
        if self.mode == mode {
            return;
        }
        self.mode = mode;
        self.mode_frame_due = self.config.mode_frame(mode).is_some();
    }

    /// Takes bytes read from the UART at `now`.
    pub fn on_bytes(&mut self, bytes: &[u8], now: Instant) {
        if bytes.is_empty() {
            return;
        }
        self.quiet_at = self.quiet_at.max(now + self.silence);
        for &b in bytes {
            match self.awaiting {
                None => self.unexpected(1),
                Some(t) if !self.framer.is_rtu() => self.on_framed_byte(t, b, now),
                Some(t) => {
                    if self.rx.push(b).is_err() {
                        // Unreachable: a response is delimited before it can exceed an ADU.
                        self.rx.clear();
                        self.health.on_framing_error();
                    }
                    self.try_complete(t, now);
                }
            }
        }
    }

    /// Takes byte `b` of the ASCII or TCP response to `t`.
    fn on_framed_byte(&mut self, t: Transaction, b: u8, now: Instant) {
        match self.framer.push(b, &mut self.rx, now) {
            Received::Pending => {}
            Received::Skipped(n) => self.health.on_discarded_bytes(as_u32(n)),
            Received::Error(e) => {
                self.awaiting = None;
                self.rx.clear();
                // The rest of the broken frame is discarded, not another framing error.
                self.unexpected_burst = true;
                if e.is_checksum() {
                    self.health.on_checksum_error();
                } else {
                    self.health.on_framing_error();
                }
                self.attempt_failed(t.job, t.attempt, false);
            }
            Received::Frame => self.complete_framed(t, now),
        }
    }

    /// Handles the address and PDU of an ASCII or TCP response in the receive buffer, which its
    /// framing has delimited and checked. Another unit's frame is dropped and the response still
    /// awaited; otherwise the frame must be exactly the response [`pdu::response_len`] delimits,
    /// checked as an RTU frame is (a CRC is appended so that the same checks serve).
    fn complete_framed(&mut self, t: Transaction, now: Instant) {
        let len = self.rx.len() + 2;
        if self.rx.first() != self.tx.first() {
            self.drop_rx_front(len - 2);
            return;
        }
        self.awaiting = None;
        let crc = crate::serial::checksum::crc16_modbus(&self.rx).to_le_bytes();
        let whole = self.rx.extend_from_slice(&crc).is_ok() && pdu::response_len(&self.rx) == Ok(Some(len));
        if whole && pdu::check_delimited_response(&self.rx).is_ok() {
            self.on_response(t, len, now);
        } else {
            self.health.on_framing_error();
            self.attempt_failed(t.job, t.attempt, false);
        }
        self.rx.clear();
    }

    /// Bytes nobody asked for: counted, one framing error per burst between transmissions.
    fn unexpected(&mut self, n: usize) {
        self.health.on_discarded_bytes(as_u32(n));
        if !self.unexpected_burst {
            self.unexpected_burst = true;
            self.health.on_framing_error();
        }
    }

    fn drop_rx_front(&mut self, n: usize) {
        let n = n.min(self.rx.len());
        crate::serial::buffer::drop_front(&mut self.rx, n);
        self.health.on_discarded_bytes(as_u32(n));
    }

    /// Delimits the response to `t` in the receive buffer and handles it once complete.
    fn try_complete(&mut self, t: Transaction, now: Instant) {
        // A transaction awaits the answer to the request in `tx` (two bytes at least: its CRC).
        let [unit, function, ..] = self.tx;
        let function = function & 0x7F;
        loop {
            let skip = self.rx.iter().position(|&b| b == unit).unwrap_or(self.rx.len());
            if skip > 0 {
                self.drop_rx_front(skip);
            }
            match self.rx.get(1) {
                None => return,
                Some(&code) if code & 0x7F != function => {
                    self.drop_rx_front(1);
                    continue;
                }
                Some(_) => {}
            }
            let len = match pdu::response_len(&self.rx) {
                Ok(None) => return,
                Ok(Some(len)) => len,
                Err(_) => {
                    self.drop_rx_front(1);
                    continue;
                }
            };
            if self.rx.len() < len {
                return;
            }
            self.awaiting = None;
            match pdu::check_delimited_response(self.rx.get(..len).unwrap_or(&[])) {
                Ok(()) => self.on_response(t, len, now),
                Err(CodecError::Crc) => {
                    self.health.on_checksum_error();
                    self.attempt_failed(t.job, t.attempt, false);
                }
                Err(_) => {
                    self.health.on_framing_error();
                    self.attempt_failed(t.job, t.attempt, false);
                }
            }
            // Handled where it was received, then dropped with anything after it: the buffer is
            // not moved out to be read (a 260-byte copy, firmware size).
            self.rx.clear();
            return;
        }
    }

    /// Handles the response to the transaction `t` in the first `len` bytes of the receive buffer
    /// (`adu`), one that [`pdu::Response::parse`] accepts and that starts with `t`'s unit and
    /// function. Read from its bytes rather than from the parsed [`pdu::Response`]: the values are
    /// at fixed places, and matching on the parsed enum costs flash.
    fn on_response(&mut self, t: Transaction, len: usize, now: Instant) {
        let adu = self.rx.get(..len).unwrap_or(&[]);
        let Job::Entry(i) = t.job else {
            // The idle/fault frame: any well-formed answer will do.
            self.health.on_frame(now);
            return;
        };
        let (Some(entry), &[_, function, byte2, ..]) = (self.entry(i), adu) else {
            return;
        };
        let write = entry.function.is_write();
        if function & 0x80 != 0 {
            // An exception: byte 2 is its code (§7).
            self.health.on_frame(now);
            self.health.count(Counter::ModbusExceptions);
            self.units.on_exception(i, now, &mut self.input);
            self.exception.current = true;
            self.last_exception = Some((i, byte2));
            if write {
                self.health.count(Counter::CommandsRejected);
                self.write_outcome = CommandOutcome::Rejected(byte2);
                self.write_failed(i);
            } else {
                self.finish_read(i);
            }
            return;
        }
        // What `Response::answers` checks, against the request still in `tx` instead of parsing
        // it again: the same unit and function, then the byte count (byte 2) the entry's quantity
        // calls for, or the echo of the written address and value or quantity (§6.5, §6.6,
        // §6.11, §6.12: the first six bytes of the request).
        let echo = if write { 6 } else { 2 };
        let answers =
            adu.get(..echo) == self.tx.get(..echo) && (write || usize::from(byte2) == entry.image_len());
        if !answers {
            self.health.on_framing_error();
            self.attempt_failed(t.job, t.attempt, false);
            return;
        }
        self.health.on_frame(now);
        if write {
            self.write_outcome = CommandOutcome::Ok;
        } else {
            let data = adu.get(3..3 + usize::from(byte2)).unwrap_or(&[]);
            store_read(&mut self.input, &entry, data, self.config.byte_order);
        }
        self.units.on_answer(i, now, &mut self.input);
        if !write {
            self.finish_read(i);
        }
    }

    /// Attempt `attempt` of `job` ended without a valid answer: retry, or give the transaction
    /// up. The transaction's fields, not the transaction: passed in registers (firmware size).
    fn attempt_failed(&mut self, job: Job, attempt: u8, timed_out: bool) {
        let Job::Entry(i) = job else {
            return;
        };
        if timed_out {
            self.health.count(Counter::Timeouts);
        }
        if attempt <= self.config.retries {
            self.retry = Some((i, attempt.saturating_add(1)));
        } else {
            self.request_timeout.current = true;
            self.units.on_lost(i, &mut self.input);
            if self.is_write(i) {
                self.health.count(Counter::CommandsFailed);
                self.write_outcome = CommandOutcome::Failed;
                self.write_failed(i);
            } else {
                self.finish_read(i);
            }
        }
    }

    fn write_failed(&mut self, i: usize) {
        if let Some(s) = self.entries.get_mut(i) {
            s.dirty = true;
            s.failed_this_cycle = true;
        }
    }

    /// Read entry `i` is done (answered or given up): the cycle is complete once none of its
    /// reads is due. Called for reads only, whose callers know the entry's kind (firmware size);
    /// a write is done once sent or failed.
    fn finish_read(&mut self, i: usize) {
        self.timetable.sent(i);
        if self.cycle_running && !self.timetable.cycle_pending(&self.config.scan) {
            self.complete_cycle();
        }
    }

    fn start_cycle(&mut self, now: Instant) {
        self.cycle_running = true;
        self.cycle_started = now;
        for s in self.entries.iter_mut() {
            s.failed_this_cycle = false;
        }
        if !self.timetable.start_cycle(&self.config.scan, now) {
            self.complete_cycle();
        }
    }

    fn complete_cycle(&mut self) {
        self.cycle_running = false;
        self.cycles = self.cycles.wrapping_add(1);
        self.exception.roll();
        self.request_timeout.roll();
    }

    /// Advances timers to `now`: response timeouts and retries, cycle starts, stale detection.
    pub fn poll(&mut self, now: Instant) {
        if self.health.poll(now) {
            self.health.apply_stale_policy(&mut self.input);
        }
        self.units.poll(now, &mut self.input);
        if let (Some(_), Some(t)) = (self.framer.poll(now), self.awaiting) {
            self.awaiting = None;
            self.rx.clear();
            self.health.on_framing_error();
            self.attempt_failed(t.job, t.attempt, false);
        }
        if let Some(t) = self.awaiting {
            if now >= t.deadline {
                self.awaiting = None;
                self.rx.clear();
                self.attempt_failed(t.job, t.attempt, true);
            }
        }
        if !self.cycle_running && now >= self.cycle_started + self.poll_period() {
            self.start_cycle(now);
        }
        self.timetable.poll(&self.config.scan, now);
    }

    /// The next transaction, regardless of line silence: a retry, the idle/fault frame, a write
    /// called for by a change, then the earliest due entry of the [timetable](super::schedule).
    fn next_job(&self) -> Option<(Job, u8)> {
        if self.awaiting.is_some() {
            return None;
        }
        if let Some((i, attempt)) = self.retry {
            return Some((Job::Entry(i), attempt));
        }
        if self.mode_frame_due {
            return Some((Job::ModeFrame, 1));
        }
        if self.outputs_valid {
            let write = self
                .config
                .scan
                .iter()
                .zip(self.entries.iter())
                .position(|(e, s)| e.function.is_write() && s.dirty && !s.failed_this_cycle);
            if let Some(i) = write {
                return Some((Job::Entry(i), 1));
            }
        }
        self.timetable.next_due(&self.config.scan, self.outputs_valid).map(|i| (Job::Entry(i), 1))
    }

    /// Advances to `now` and returns the next request to write to the UART, if the line is free
    /// and quiet. Call until `None`.
    #[must_use = "the bytes are handed out once: dropped ones are never sent"]
    pub fn poll_transmit(&mut self, now: Instant) -> Option<&[u8]> {
        self.poll(now);
        loop {
            let (job, attempt) = self.next_job()?;
            if now < self.quiet_at {
                return None;
            }
            if let Job::Entry(i) = job {
                self.timetable.sent(i);
            }
            if !self.encode(job) {
                // Only reachable with a configuration that bypassed `validate`.
                match job {
                    Job::ModeFrame => self.mode_frame_due = false,
                    Job::Entry(_) => {
                        self.retry = None;
                        self.attempt_failed(job, u8::MAX, false);
                    }
                }
                continue;
            }
            let tx_done = now + self.config.serial.transmit_time(self.request().len());
            self.awaiting = Some(Transaction {
                job,
                attempt,
                deadline: tx_done + Duration::from_millis(u64::from(self.config.response_timeout_ms)),
            });
            self.quiet_at = tx_done + self.silence;
            self.rx.clear();
            self.unexpected_burst = false;
            match job {
                Job::ModeFrame => self.mode_frame_due = false,
                Job::Entry(i) => {
                    // `next_job` takes a pending retry first: if there is one, it is this entry.
                    self.retry = None;
                    if self.is_write(i) {
                        if let Some(s) = self.entries.get_mut(i) {
                            s.dirty = false;
                        }
                        if attempt <= 1 {
                            self.health.count(Counter::CommandsSent);
                            self.write_outcome = CommandOutcome::Pending;
                        } else {
                            self.health.count(Counter::CommandsRetried);
                        }
                    }
                    if attempt > 1 {
                        self.units.on_retry(i);
                    }
                }
            }
            self.health.count(Counter::FramesSent);
            return Some(self.request());
        }
    }

    /// The last request encoded, framed for the line (empty when it could not be).
    fn request(&self) -> &[u8] {
        if self.framer.is_rtu() {
            self.tx.get(..self.tx_len).unwrap_or(&[])
        } else {
            self.framer.wire()
        }
    }

    /// Encodes `job` into `self.tx`.
    fn encode(&mut self, job: Job) -> bool {
        let n = match job {
            Job::ModeFrame => {
                let body = self.config.mode_frame(self.mode).unwrap_or(&[]);
                self.tx.get_mut(..body.len()).map(|out| out.copy_from_slice(body)).map(|()| body.len())
            }
            Job::Entry(i) => self
                .config
                .scan
                .get(i)
                .and_then(|e| encode_entry(e, &self.output, self.config.byte_order, &mut self.tx)),
        };
        // At least the CRC's two bytes when encoded.
        self.tx_len = n.and_then(|n| append_crc(&mut self.tx, n)).unwrap_or(0);
        if !self.framer.is_rtu() {
            // The address and PDU, without the CRC.
            let frame = self.tx.get(..self.tx_len.saturating_sub(2)).unwrap_or(&[]);
            return !self.framer.wrap(frame).is_empty();
        }
        self.tx_len != 0
    }

    /// When to call [`poll_transmit`](Self::poll_transmit) next: a response deadline, the end of
    /// the line silence when a transaction is waiting, the next cycle start, the stale deadline,
    /// the end of a data-valid bit.
    pub fn poll_at(&self) -> Option<Instant> {
        let own = if let Some(t) = self.awaiting {
            Some(self.framer.poll_at().map_or(t.deadline, |c| c.min(t.deadline)))
        } else if self.next_job().is_some() {
            Some(self.quiet_at)
        } else if !self.cycle_running {
            Some(self.cycle_started + self.poll_period())
        } else {
            None
        };
        let own = own.into_iter().chain(self.timetable.poll_at(&self.config.scan)).min();
        [self.health.poll_at(), self.units.poll_at()].into_iter().fold(own, |a, b| match (a, b) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        })
    }

    /// The input image (`input_len` bytes).
    pub fn input_image(&self) -> &[u8] {
        &self.input
    }

    /// The output image as last set (`output_len` bytes).
    pub fn output_image(&self) -> &[u8] {
        self.output.get(..usize::from(self.config.output_len)).unwrap_or(&[])
    }

    /// The link status; the command field is the outcome of the last write.
    pub fn status(&self) -> LinkStatus {
        self.health.status(self.write_outcome, self.exception.shown(), self.request_timeout.shown())
    }

    /// The statistics.
    pub fn stats(&self) -> Stats {
        self.health.stats()
    }

    /// The statistics as a table indexed by [`Counter`].
    pub fn counts(&self) -> &[u32; Counter::COUNT] {
        self.health.counts()
    }

    /// The last exception: scan list index and code.
    pub fn last_exception(&self) -> Option<(usize, ExceptionCode)> {
        self.last_exception.map(|(i, code)| (i, ExceptionCode::from(code)))
    }

    /// The per-unit health table and the data-valid bits.
    pub fn units(&self) -> &UnitHealth {
        &self.units
    }

    /// Row `row` of the unit table at `now` ([`UnitHealth::row`]).
    pub fn unit_row(&self, row: usize, now: Instant) -> Option<UnitRow> {
        self.units.row(row, now)
    }

    /// Read cycles completed since start-up (wraps).
    pub fn completed_cycles(&self) -> u32 {
        self.cycles
    }
}

#[cfg(test)]
mod tests;
