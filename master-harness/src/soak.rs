//! The soak run: a scanner polling the soft slave (the real converter and the simulated breaker)
//! for hours of virtual time on the simulated bus while faults are injected, checking invariants on
//! every poll response and every command. Seconds of wall time per virtual hour.
//!
//! ## The set-up
//!
//! * The device: the reference converter with the input assembly that carries the link status
//!   (instance 101: the breaker's 18 bytes, the status byte, the freshness counter), the bus-off
//!   interrupt set (BOI = 1, protocol §7.2: a bus-off restarts the duplicate MAC ID check instead of
//!   faulting for good), attached through [`SharedDevice`] so the soak can reach the breaker.
//! * The scanner (master MAC 0): allocates through the Group 2 Only port, explicit watchdog action
//!   deferred delete, allocates the poll connection, sets the EPR, then polls every EPR. Four polls
//!   in a row without a complete response and it declares the connection lost and establishes it
//!   again (retrying every 200 ms). Through the poll output it issues breaker commands one at a
//!   time: set parameter (value = command number), close, set parameter, open, …, each with the
//!   next sequence number, and holds each until its outcome shows in the status byte.
//! * Time alternates between fault windows and quiet windows. In a fault window the bus applies
//!   [`RandomFaults`] (destroyed and retransmitted, duplicated, dropped, delayed frames, bus-off of
//!   the device) and the breaker now and then goes silent (2–8 s) or sends garbage bytes. In a quiet
//!   window there are no faults.
//!
//! ## The invariants
//!
//! | invariant | checked |
//! |---|---|
//! | every command reaches the breaker exactly once, or is reported failed | per command, once its outcome is final: the breaker's own log since the command was issued holds only that command; with outcome "ok" it arrived once — or more than once only after the converter retried a command whose acknowledgement was lost on the serial line (counted separately: the breaker protocol has no sequence number, so a lost acknowledgement makes delivery at-least-once); with outcome "failed" or "rejected" it is reported failed; "pending" after all retries, an unexpected command, or "ok" without delivery are violations |
//! | stale data is never presented as fresh | per response: the data never changes while the freshness counter stays; the counter never goes back; while the breaker has been silent for longer than the stale timeout the status byte says "link timeout", not "link ok", and the counter does not move; after the breaker speaks again "link ok" returns within two status periods |
//! | after faults stop, I/O is re-established in bounded time | per quiet window: the first complete poll response comes within [`SoakConfig::recovery_bound`], and no poll goes unanswered after it |
//! | memory stays bounded | the frames queued anywhere in the bus never exceed a small bound; the scanner keeps no per-frame history; the converter and node are fixed-size by construction; the process's resident memory is reported at the start and the end |
//! | no panic | the run completes |

use can_io::bus::{Bitrate, Bus, Origin};
use can_io::sim::fault::{FaultRates, FaultStats, RandomFaults, Rng, SharedDevice};
use can_io::sim::{PowerOn, SimBus};
use converter_sim::device::SoftSlave;
use devicenet::fragment::IoReassembler;
use devicenet::id::Group1MessageId;
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::{CanFrame, Duration, Group2Message, Identifier, Instant, MacId};
use harness_common::error::HarnessError;
use master_core::bring_up::{self, BringUp, Event, Refusal};
use master_core::client::{Link, Port, Received};
use master_core::decode;
use master_core::error::MasterError;
use master_core::session::Verdict;
use serde::Serialize;
use slave_fw::converter::{ConverterConfig, InputAssembly};
use slave_fw::serial::breaker::BreakerCommand;
use slave_fw::serial::StatusByte;
use std::cell::RefCell;
use std::rc::Rc;

/// How a soak run is set up.
#[derive(Clone, Debug, PartialEq)]
pub struct SoakConfig {
    /// Virtual time to run.
    pub duration: Duration,
    /// Seed of every random choice (faults, silences, garbage).
    pub seed: u64,
    /// The poll connection's expected packet rate, ms.
    pub epr_ms: u16,
    /// Length of each fault window.
    pub fault_window: Duration,
    /// Length of each quiet window (the run starts with one).
    pub quiet_window: Duration,
    /// Bus faults in fault windows.
    pub rates: FaultRates,
    /// Chance per second of a fault window that the breaker goes silent (for 2–8 s).
    pub silence_per_second: f64,
    /// Chance per second of a fault window that the breaker sends 1–16 garbage bytes.
    pub garbage_per_second: f64,
    /// How long I/O may take to come back once faults stop.
    pub recovery_bound: Duration,
}

impl SoakConfig {
    /// `hours` of virtual time with the default fault mix: per frame 1 % destroyed, 0.5 %
    /// duplicated, per delivery 1 % dropped and 1 % delayed by up to 20 ms, a bus-off of the device
    /// about every 30 000 of its frames; the breaker silent about every 2 minutes and sending
    /// garbage about every 10 s of a fault window; 10 min fault windows, 2 min quiet windows;
    /// recovery within 10 s.
    #[must_use]
    pub fn hours(hours: f64, seed: u64) -> SoakConfig {
        SoakConfig {
            duration: Duration::from_micros((hours * 3.6e9) as u64),
            seed,
            epr_ms: 100,
            fault_window: Duration::from_secs(600),
            quiet_window: Duration::from_secs(120),
            rates: FaultRates {
                destroy: 0.01,
                duplicate: 0.005,
                bus_off: 1.0 / 30_000.0,
                drop: 0.01,
                delay: 0.01,
                max_delay: Duration::from_millis(20),
            },
            silence_per_second: 1.0 / 120.0,
            garbage_per_second: 0.1,
            recovery_bound: Duration::from_secs(10),
        }
    }
}

/// What a soak run saw.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SoakReport {
    /// Virtual time run, hours.
    pub virtual_hours: f64,
    /// Wall time taken, seconds.
    pub wall_seconds: f64,
    /// Frames that completed on the bus.
    pub frames: u64,
    /// Bus faults applied.
    pub bus_faults: FaultStats,
    /// Times the breaker went silent.
    pub instrument_silences: u64,
    /// Garbage bursts the breaker sent.
    pub instrument_garbage_bursts: u64,
    /// Polls sent.
    pub polls: u64,
    /// Complete poll responses received.
    pub responses: u64,
    /// Times the scanner declared the connection lost.
    pub connections_lost: u64,
    /// Times it (re-)established the connection.
    pub connections_established: u64,
    /// Commands issued and resolved.
    pub commands: u64,
    /// … that reached the breaker exactly once with outcome ok.
    pub commands_exactly_once: u64,
    /// … that were reported failed (or rejected) in the status byte.
    pub commands_reported_failed: u64,
    /// … that reached the breaker more than once, each extra time a converter retry after a lost
    /// serial acknowledgement (outcome ok).
    pub commands_repeated_after_lost_ack: u64,
    /// Fault windows that ended and were followed by a quiet window.
    pub recoveries: u64,
    /// The longest time to the first complete poll response after faults stopped, ms.
    pub max_recovery_ms: f64,
    /// Invariant checks made.
    pub invariant_checks: u64,
    /// Invariant violations.
    pub violation_count: u64,
    /// The first violations, described.
    pub violations: Vec<String>,
    /// The most frames queued anywhere in the bus at once.
    pub max_queued_frames: usize,
    /// Resident memory of the process at the start and the end, KiB (Linux).
    pub rss_kib: Option<(u64, u64)>,
}

impl SoakReport {
    /// A few lines with the figures.
    pub fn summary(&self) -> String {
        let f = &self.bus_faults;
        format!(
            "soak: {:.1} virtual hours in {:.1} s of wall time, {} frames\n\
             faults: {} bus faults ({} destroyed and retransmitted, {} duplicated, {} dropped, {} delayed, {} bus-off), {} breaker silences, {} garbage bursts\n\
             I/O: {} polls, {} complete responses, connection lost {} times and established {} times; {} recoveries after faults stopped, the longest {:.0} ms\n\
             commands: {} issued: {} exactly once, {} reported failed, {} repeated after a lost serial acknowledgement\n\
             invariants: {} checks, {} violations; at most {} frames queued in the bus{}",
            self.virtual_hours,
            self.wall_seconds,
            self.frames,
            f.total(),
            f.destroyed,
            f.duplicated,
            f.dropped,
            f.delayed,
            f.bus_offs,
            self.instrument_silences,
            self.instrument_garbage_bursts,
            self.polls,
            self.responses,
            self.connections_lost,
            self.connections_established,
            self.recoveries,
            self.max_recovery_ms,
            self.commands,
            self.commands_exactly_once,
            self.commands_reported_failed,
            self.commands_repeated_after_lost_ack,
            self.invariant_checks,
            self.violation_count,
            self.max_queued_frames,
            self.rss_kib.map_or_else(String::new, |(a, b)| format!("; resident memory {a} KiB at the start, {b} KiB at the end")),
        )
    }
}

/// How long the breaker's status frames may be missing before the link is stale (the default
/// health configuration).
const STALE_TIMEOUT: Duration = Duration::from_secs(3);
/// From the first poll carrying a command to its final outcome: three attempts of 500 ms, the
/// serial transmission times, and margin.
const RESOLVE: Duration = Duration::from_millis(2000);
/// Explicit response timeout of the soak's scanner.
const EXPLICIT_TIMEOUT: Duration = Duration::from_millis(250);
/// Polls without a complete response before the connection is taken as lost.
const MISSES_LOST: u32 = 4;
/// Violations described in the report.
const VIOLATIONS_KEPT: usize = 20;

struct Previous {
    at: Instant,
    image: [u8; 18],
    fresh: u8,
}

struct Active {
    k: u64,
    command: BreakerCommand,
    output: [u8; 8],
    /// The breaker's log length when it was issued.
    log_start: usize,
    /// The converter's retry counter when it was issued.
    retried_start: u32,
    /// When a poll carrying it was first answered.
    confirmed: Option<Instant>,
}

/// The soak's scanner and its world.
struct Soak {
    cfg: SoakConfig,
    bus: SimBus,
    slave: Rc<RefCell<SoftSlave>>,
    target: MacId,
    master: MacId,
    rng: Rng,
    report: SoakReport,
    up: bool,
    misses: u32,
    prev: Option<Previous>,
    active: Option<Active>,
    next_k: u64,
    silent_since: Option<Instant>,
    silence_until: Option<Instant>,
    /// When the last silence ended.
    spoke_again: Option<Instant>,
    /// Start of the current quiet window, until I/O is back.
    recovering: Option<Instant>,
    /// Quiet window with I/O back: polls must be answered.
    stable: bool,
    faults_on: bool,
}

fn rss_kib() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = text.lines().find(|l| l.starts_with("VmRSS:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Runs a soak as `cfg` says. Only a failing simulation (a bug in the harness) is an error;
/// violations of the invariants are in the report.
pub fn run(cfg: &SoakConfig) -> Result<SoakReport, HarnessError> {
    let wall = std::time::Instant::now();
    let target = MacId::from_low_bits(5);
    let mut config = ConverterConfig::breaker_reference();
    config.input = InputAssembly::WithStatus;
    config.device.bus_off_interrupt = true;
    let slave = SoftSlave::new(config).map_err(HarnessError::Converter)?;
    let shared = SharedDevice::new(slave);
    let handle = shared.handle();
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(shared), PowerOn::AtStart);
    let mut soak = Soak {
        cfg: cfg.clone(),
        bus,
        slave: handle,
        target,
        master: MacId::from_low_bits(0),
        rng: Rng::new(cfg.seed),
        report: SoakReport { rss_kib: rss_kib().map(|a| (a, a)), ..SoakReport::default() },
        up: false,
        misses: 0,
        prev: None,
        active: None,
        next_k: 1,
        silent_since: None,
        silence_until: None,
        spoke_again: None,
        recovering: None,
        stable: false,
        faults_on: false,
    };
    soak.run()?;
    let mut report = soak.report;
    report.virtual_hours = cfg.duration.total_micros() as f64 / 3.6e9;
    report.wall_seconds = wall.elapsed().as_secs_f64();
    report.frames = soak.bus.frames_completed();
    report.bus_faults = soak.bus.fault_stats();
    if let (Some((a, _)), Some(b)) = (report.rss_kib, rss_kib()) {
        report.rss_kib = Some((a, b));
    }
    Ok(report)
}

impl Soak {
    fn now(&mut self) -> Instant {
        self.bus.now()
    }

    fn violation(&mut self, at: Instant, text: String) {
        self.report.violation_count += 1;
        if self.report.violations.len() < VIOLATIONS_KEPT {
            self.report.violations.push(format!("{at}: {text}"));
        }
    }

    fn check(&mut self, ok: bool, at: Instant, text: impl FnOnce() -> String) {
        self.report.invariant_checks += 1;
        if !ok {
            self.violation(at, text());
        }
    }

    /// Whether `t` is in a fault window: the run starts with a quiet window, then fault and quiet
    /// windows alternate.
    fn in_fault_window(&self, t: Instant) -> bool {
        let q = self.cfg.quiet_window.total_micros();
        let cycle = q + self.cfg.fault_window.total_micros();
        let t = t.total_micros();
        t >= q && (t - q) % cycle < self.cfg.fault_window.total_micros()
    }

    fn run(&mut self) -> Result<(), HarnessError> {
        let end = Instant::ZERO + self.cfg.duration;
        let epr = Duration::from_millis(u64::from(self.cfg.epr_ms));
        let mut next_poll = Instant::ZERO;
        let mut next_tick = Instant::ZERO;
        let mut retry_at = Instant::ZERO + Duration::from_millis(2100);
        while self.now() < end {
            let now = self.now();
            if now >= next_tick {
                self.tick(now);
                next_tick = now + Duration::from_secs(1);
            }
            if !self.up {
                self.drain_until(retry_at)?;
                if self.establish()? {
                    self.up = true;
                    self.misses = 0;
                    self.report.connections_established += 1;
                    next_poll = self.now();
                } else {
                    retry_at = self.now() + Duration::from_millis(200);
                }
                continue;
            }
            self.drain_until(next_poll)?;
            let sent = self.now();
            let wait =
                Duration::from_micros(epr.total_micros().saturating_sub(10_000).max(epr.total_micros() / 2));
            self.poll_cycle(sent, sent + wait)?;
            next_poll = sent + epr;
        }
        Ok(())
    }

    fn sample_queues(&mut self) {
        let queued = self.bus.queued_frames();
        self.report.max_queued_frames = self.report.max_queued_frames.max(queued);
    }

    /// Once a second: fault windows begin and end, the breaker goes silent or sends garbage.
    fn tick(&mut self, now: Instant) {
        let faulty = self.in_fault_window(now);
        if faulty != self.faults_on {
            self.faults_on = faulty;
            if faulty {
                let seed = self.rng.next_u64();
                self.bus.set_faults(Some(Box::new(RandomFaults::new(self.cfg.rates, seed))));
                self.recovering = None;
                self.stable = false;
            } else {
                self.bus.set_faults(None);
                self.end_silence(now);
                self.recovering = Some(now);
                self.report.recoveries += 1;
            }
        }
        if self.silence_until.is_some_and(|t| t <= now) {
            self.end_silence(now);
        }
        if !faulty {
            return;
        }
        if self.silent_since.is_none() && self.rng.chance(self.cfg.silence_per_second) {
            let length = Duration::from_millis(2000 + self.rng.below(6000));
            self.slave.borrow_mut().breaker_mut().set_silent(true);
            self.silent_since = Some(now);
            self.silence_until = Some(now + length);
            self.report.instrument_silences += 1;
        }
        if self.silent_since.is_none() && self.rng.chance(self.cfg.garbage_per_second) {
            let n = 1 + self.rng.below(16) as usize;
            let bytes: Vec<u8> = (0..n).map(|_| self.rng.next_u64() as u8).collect();
            self.slave.borrow_mut().breaker_mut().send_garbage(&bytes, now);
            self.report.instrument_garbage_bursts += 1;
        }
    }

    fn end_silence(&mut self, now: Instant) {
        if self.silent_since.take().is_some() {
            self.slave.borrow_mut().breaker_mut().set_silent(false);
            self.spoke_again = Some(now);
        }
        self.silence_until = None;
    }

    /// Lets the bus run until `t`, ignoring what arrives (late duplicates, the device's duplicate
    /// MAC ID checks).
    fn drain_until(&mut self, t: Instant) -> Result<(), HarnessError> {
        while self.bus.recv(t)?.is_some() {}
        Ok(())
    }

    /// The scanner's connection set-up on master-core's bring-up engine (explicit through the
    /// Group 2 Only port, explicit watchdog action deferred delete, poll, the EPR; a set still
    /// allocated to this master released and allocated again); `false` when a step went
    /// unanswered or was refused.
    fn establish(&mut self) -> Result<bool, HarnessError> {
        let mut node = BringUp::new(self.target, self.master, EXPLICIT_TIMEOUT);
        let now = Link::now(self);
        node.allocate(now, Port::Group2Only, AllocationChoice::EXPLICIT);
        node.set(now, (class::CONNECTION, 1, 12), &[3], Refusal::Stop);
        node.allocate(now, Port::Explicit, AllocationChoice::POLL);
        node.expected_packet_rate(now, 2, self.cfg.epr_ms);
        while let Some(event) = bring_up::drive(self, &mut node)? {
            if let Event::Failed(_) = event {
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// The command numbered `k`: set parameter, close, set parameter, open, …
    fn command(k: u64) -> (BreakerCommand, [u8; 8]) {
        let seq = k as u8;
        match k % 4 {
            1 => (BreakerCommand::Close, [2, seq, 0, 0, 0, 0, 0, 0]),
            3 => (BreakerCommand::Open, [1, seq, 0, 0, 0, 0, 0, 0]),
            _ => {
                let id = ((k / 2) % 4) as u8;
                let value = k as u16;
                let [lo, hi] = value.to_le_bytes();
                (BreakerCommand::SetParameter { id, value }, [3, seq, id, lo, hi, 0, 0, 0])
            }
        }
    }

    fn issue_next(&mut self) {
        let k = self.next_k;
        self.next_k += 1;
        let (command, output) = Self::command(k);
        let slave = self.slave.borrow();
        let log_start = slave.breaker().commands().len();
        let retried_start = slave.converter().profile().stats().commands_retried;
        drop(slave);
        self.active = Some(Active { k, command, output, log_start, retried_start, confirmed: None });
    }

    /// Sends one poll at `sent` and waits for the complete response until `until`.
    fn poll_cycle(&mut self, sent: Instant, until: Instant) -> Result<(), HarnessError> {
        if self.active.is_none() {
            self.issue_next();
        }
        let output = self.active.as_ref().map_or([0; 8], |a| a.output);
        let id = Identifier::group2(self.target, Group2Message::PollCommand);
        let frame = CanFrame::new(id, &output).map_err(HarnessError::Frame)?;
        self.bus.send(&frame)?;
        self.report.polls += 1;
        let response_id = Identifier::group1(Group1MessageId::POLL_RESPONSE, self.target);
        let mut rx: IoReassembler<{ decode::MAX_IO_MESSAGE }> = IoReassembler::new();
        let mut whole = None;
        while let Some(ev) = self.bus.recv(until)? {
            self.sample_queues();
            if ev.origin == Origin::Remote && ev.frame.id() == response_id {
                if let Ok(Some(data)) = rx.receive(ev.frame.data()) {
                    whole = Some((data.to_vec(), ev.at));
                    break;
                }
            }
        }
        match whole {
            Some((data, at)) => {
                self.misses = 0;
                self.report.responses += 1;
                self.on_response(sent, at, &data);
            }
            None => {
                self.misses += 1;
                if self.stable {
                    let now = self.now();
                    self.violation(now, "a poll went unanswered in a quiet window after I/O was back".into());
                }
                if self.misses >= MISSES_LOST {
                    self.up = false;
                    self.report.connections_lost += 1;
                }
            }
        }
        Ok(())
    }

    fn on_response(&mut self, sent: Instant, at: Instant, data: &[u8]) {
        if let Some(since) = self.recovering.take() {
            let ms = (at - since).total_micros() as f64 / 1000.0;
            self.report.max_recovery_ms = self.report.max_recovery_ms.max(ms);
            let bound = self.cfg.recovery_bound;
            self.check(at - since <= bound, at, || {
                format!("I/O back only {ms:.0} ms after the faults stopped (bound {bound})")
            });
            self.stable = true;
        }
        self.check(data.len() == 20, at, || format!("poll response of {} bytes, 20 expected", data.len()));
        let (Some(image), Some(&status), Some(&fresh)) = (data.get(..18), data.get(18), data.get(19)) else {
            return;
        };
        let mut img = [0u8; 18];
        img.copy_from_slice(image);
        self.freshness(at, img, status, fresh);
        self.commands(sent, at, status);
    }

    fn freshness(&mut self, at: Instant, image: [u8; 18], status: u8, fresh: u8) {
        if let Some(prev) = self.prev.take() {
            let same = prev.fresh == fresh;
            self.check(!same || prev.image == image, at, || {
                format!("the data changed while the freshness counter stayed at {fresh}")
            });
            let step = fresh.wrapping_sub(prev.fresh);
            if at - prev.at < Duration::from_secs(60) {
                self.check(step < 128, at, || {
                    format!("the freshness counter went back from {} to {fresh}", prev.fresh)
                });
            }
            // While the breaker is silent, no new data may be claimed (its last frame may still be
            // on the serial line for a few tens of milliseconds).
            if let Some(s) = self.silent_since {
                if prev.at >= s + Duration::from_millis(100) {
                    self.check(same, at, || {
                        format!(
                            "the freshness counter moved ({} -> {fresh}) while the breaker was silent",
                            prev.fresh
                        )
                    });
                }
            }
        }
        let link_ok = status & StatusByte::LINK_OK != 0;
        let link_timeout = status & StatusByte::LINK_TIMEOUT != 0;
        if let Some(s) = self.silent_since {
            if at >= s + STALE_TIMEOUT + Duration::from_millis(1200) {
                self.check(!link_ok && link_timeout, at, || {
                    format!(
                        "status 0x{status:02X} says link ok {:.1} s into a silence of the breaker",
                        (at - s).total_micros() as f64 / 1e6
                    )
                });
            }
        } else if let Some(e) = self.spoke_again {
            if at >= e + Duration::from_millis(2500) {
                self.check(link_ok, at, || {
                    format!("status 0x{status:02X}: no link ok 2.5 s after the breaker spoke again")
                });
                self.spoke_again = None;
            }
        }
        self.prev = Some(Previous { at, image, fresh });
    }

    fn commands(&mut self, sent: Instant, at: Instant, status: u8) {
        let Some(active) = self.active.as_mut() else { return };
        let Some(confirmed) = active.confirmed else {
            active.confirmed = Some(sent);
            return;
        };
        if sent < confirmed + RESOLVE {
            return;
        }
        let k = active.k;
        let command = active.command;
        let (log_start, retried_start) = (active.log_start, active.retried_start);
        self.active = None;
        let outcome = (status & StatusByte::COMMAND_MASK) >> StatusByte::COMMAND_SHIFT;
        let (delivered, retried) = {
            let slave = self.slave.borrow();
            let log = slave.breaker().commands();
            let mine: Vec<BreakerCommand> = log.get(log_start..).unwrap_or(&[]).to_vec();
            let retried = slave.converter().profile().stats().commands_retried.wrapping_sub(retried_start);
            (mine, retried)
        };
        self.report.commands += 1;
        let n = delivered.len() as u32;
        let foreign = delivered.iter().find(|c| **c != command).copied();
        self.check(foreign.is_none(), at, || {
            format!("command {k} ({command:?}): the breaker also received {foreign:?}")
        });
        match outcome {
            2 => {
                self.check(n >= 1, at, || {
                    format!("command {k} ({command:?}) reported ok but never reached the breaker")
                });
                self.check(n <= 1 + retried, at, || {
                    format!("command {k} ({command:?}) reached the breaker {n} times with {retried} retries")
                });
                if n == 1 {
                    self.report.commands_exactly_once += 1;
                } else if n > 1 {
                    self.report.commands_repeated_after_lost_ack += 1;
                }
            }
            3 | 4 => {
                self.report.commands_reported_failed += 1;
                self.check(n <= 1 + retried, at, || {
                    format!("command {k} ({command:?}) reached the breaker {n} times with {retried} retries")
                });
            }
            other => {
                self.check(false, at, || format!("command {k} ({command:?}): outcome {other} in the status byte {:.1} s after it was confirmed", (sent - confirmed).total_micros() as f64 / 1e6));
            }
        }
    }
}

/// The soak's bare bus as a [`Link`] for the shared transaction driver: no transcript, no verdicts,
/// no waiting for the master's own last frames; the bus queue is sampled before every wait.
impl Link for Soak {
    type Seen = ();

    fn now(&mut self) -> Instant {
        self.bus.now()
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), MasterError> {
        Ok(self.bus.send(frame)?)
    }

    fn recv(&mut self, deadline: Instant) -> Result<Option<Received<()>>, MasterError> {
        self.sample_queues();
        Ok(self.bus.recv(deadline)?.map(|ev| Received {
            seen: (),
            origin: ev.origin,
            frame: ev.frame,
            at: ev.at,
        }))
    }

    fn judged(&mut self, (): (), _verdict: Verdict) {}

    fn other(&mut self, (): ()) {}

    fn echo_wait(&self) -> Option<Duration> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_soak_without_faults_holds_every_invariant() {
        let mut cfg = SoakConfig::hours(0.05, 1);
        cfg.rates = FaultRates::default();
        cfg.silence_per_second = 0.0;
        cfg.garbage_per_second = 0.0;
        let r = run(&cfg).unwrap();
        assert_eq!(r.violation_count, 0, "{}", r.summary());
        assert_eq!(r.connections_established, 1);
        assert!(r.commands > 50, "{}", r.summary());
        assert_eq!(r.commands_exactly_once, r.commands);
        assert_eq!(r.bus_faults.total(), 0);
    }

    #[test]
    fn commands_cycle_and_carry_their_number() {
        assert_eq!(Soak::command(1).0, BreakerCommand::Close);
        assert_eq!(Soak::command(3).1[..2], [1, 3]);
        assert_eq!(Soak::command(258).0, BreakerCommand::SetParameter { id: 1, value: 258 });
        assert_eq!(Soak::command(258).1, [3, 2, 1, 2, 1, 0, 0, 0]);
    }
}
