//! [`Bridge`]: the converter between a CAN bus and the instrument's serial line, in real time.
//!
//! Each turn of [`Bridge::run`]:
//!
//! 1. serial bytes delivered by the reader thread go to
//!    [`Converter::handle_serial`](slave_fw::converter::Converter::handle_serial) with the time they
//!    arrived (never earlier than the last `now` the converter saw);
//! 2. due timers run ([`Converter::handle_timeout`](slave_fw::converter::Converter::handle_timeout)
//!    when [`poll_at`](slave_fw::converter::Converter::poll_at) has passed), and a pending Identity
//!    Reset power-cycles the converter;
//! 3. the converter is drained in the order its docs prescribe: CAN frames to the bus, serial
//!    bytes to the writer thread, then events;
//! 4. the bus is read until the converter's next deadline, at most [`POLL_SLICE`]; a frame from
//!    another node goes to
//!    [`Converter::handle_can_frame`](slave_fw::converter::Converter::handle_can_frame) at once.
//!
//! With a mutant ([`Bridge::set_mutant`], `--mutant`), every frame from the bus passes its
//! [`FaultHook`] before the converter sees it, and every frame the converter sends passes it before
//! the bus does (it may rewrite, drop, delay or add frames, or feed the converter a frame).
//!
//! The bus reports this program's own frames back ([`Origin::Local`]); they are written to the
//! log and otherwise ignored. Time is the [`Clock`]'s, the same for the bus side and the serial
//! threads; bus timestamps are not used.

use crate::clock::{format_instant, Clock};
use crate::error::SoftSlaveError;
use crate::firmware::{FirmwareDir, SoftUpdate};
use crate::serial::{SerialEvent, SerialLine};
use crate::state::{StateFile, StoredState};
use can_io::bus::{Bus, Origin};
use can_io::log::LogWriter;
use can_io::trace::Direction;
use converter_sim::mutants::{FaultHook, Mutant};
use devicenet::slave::{ConnectionKind, FaultReason, SettingChanged};
use devicenet::{CanFrame, Duration, Event, Instant, MacId};
use slave_fw::converter::{Converter, ConverterConfig};
use slave_fw::serial::{LinkState, Stats};
use slave_fw::update::BootState;
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};

/// The longest the loop waits on the bus before it looks at the serial line again.
pub const POLL_SLICE: Duration = Duration::from_millis(2);

/// The delay between an Identity Reset response and the power cycle (the response must reach
/// the bus first): the converter's own, the same on the board and in the simulation.
pub use slave_fw::converter::RESET_DELAY;

/// What a run did, for the closing report and for tests.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RunSummary {
    /// How long the bridge ran.
    pub elapsed: Duration,
    /// Frames from other nodes handed to the converter.
    pub can_received: u64,
    /// Frames the converter sent.
    pub can_sent: u64,
    /// Bytes read from the instrument.
    pub serial_bytes_received: u64,
    /// Bytes written to the instrument.
    pub serial_bytes_sent: u64,
    /// Identity Resets carried out.
    pub resets: u32,
    /// The serial side's statistics at the end.
    pub stats: Stats,
}

/// The converter, its bus, its serial line and its clock. See the [module docs](self).
pub struct Bridge {
    /// The description's configuration; what runs is it with the stored state on top.
    config: ConverterConfig,
    state: StoredState,
    state_file: Option<StateFile>,
    mac_override: Option<MacId>,
    converter: Converter,
    bus: Box<dyn Bus>,
    serial: SerialLine,
    clock: Clock,
    log: Option<(LogWriter, String)>,
    report: Box<dyn Write>,
    last_now: Instant,
    link: LinkState,
    summary: RunSummary,
    /// The deliberate fault, if any, and its hook (renewed with the converter at a reset).
    mutant: Option<(&'static Mutant, FaultHook)>,
    /// The firmware update object over its directory (`--firmware-dir`, [`crate::firmware`]).
    firmware: Option<(FirmwareDir, SoftUpdate)>,
    /// Running an applied image not yet confirmed (until the next on-line).
    trial: bool,
}

impl Bridge {
    /// A bridge for `config`; the converter is created now and powered on by [`Bridge::run`].
    pub fn new(
        config: ConverterConfig,
        bus: Box<dyn Bus>,
        serial: SerialLine,
        clock: Clock,
    ) -> Result<Bridge, SoftSlaveError> {
        let now = clock.now();
        let converter = Converter::new(config.clone(), now)?;
        let link = converter.profile().status().state;
        Ok(Bridge {
            config,
            state: StoredState::default(),
            state_file: None,
            mac_override: None,
            converter,
            bus,
            serial,
            clock,
            log: None,
            report: Box::new(std::io::sink()),
            mutant: None,
            firmware: None,
            trial: false,
            last_now: now,
            link,
            summary: RunSummary::default(),
        })
    }

    /// The state kept across resets (and, with `file`, across restarts: `--state`): the converter
    /// is recreated with it now and after every Identity Reset; settings changed over the network
    /// are added to it (and saved to `file`). `mac_override` (`--mac`) wins over the stored MAC.
    pub fn set_state(
        &mut self,
        state: StoredState,
        file: Option<StateFile>,
        mac_override: Option<MacId>,
    ) -> Result<(), SoftSlaveError> {
        self.state = state;
        self.state_file = file;
        self.mac_override = mac_override;
        self.converter = self.fresh(self.now())?;
        Ok(())
    }

    /// The converter a start or a reset begins with: the stored state on the description.
    fn fresh(&self, now: Instant) -> Result<Converter, SoftSlaveError> {
        Ok(self.state.converter(&self.config, self.mac_override, now)?)
    }

    /// Serves the firmware update object (class 0x6A) over `dir` ([`crate::firmware`]).
    pub fn set_firmware(&mut self, dir: FirmwareDir) -> Result<(), SoftSlaveError> {
        let object = dir.object(BootState::Confirmed)?;
        self.firmware = Some((dir, object));
        Ok(())
    }

    /// The firmware update object, when served.
    pub fn firmware(&self) -> Option<&SoftUpdate> {
        self.firmware.as_ref().map(|(_, object)| object)
    }

    /// Runs with `mutant`'s deliberate fault (test equipment: `dnet-soft-slave --mutant`).
    pub fn set_mutant(&mut self, mutant: &'static Mutant) {
        self.mutant = Some((mutant, mutant.hook()));
    }

    /// Writes every frame seen to `log` (`path` names it in errors): received frames as `Rx`,
    /// this program's own as `Tx`, where the log's format keeps directions (trc, asc).
    pub fn set_log(&mut self, log: LogWriter, path: &str) {
        self.log = Some((log, path.to_string()));
    }

    /// Where to report what happens (on-line, connections, link state, resets): stderr for the
    /// binary, nothing by default.
    pub fn set_report(&mut self, report: Box<dyn Write>) {
        self.report = report;
    }

    /// The converter (tests and the closing report).
    pub fn converter(&self) -> &Converter {
        &self.converter
    }

    /// Powers the converter on and runs until `stop` is set or `duration` has passed. Returns
    /// what the run did; an error when the bus or the serial port fails.
    pub fn run(
        &mut self,
        stop: &AtomicBool,
        duration: Option<Duration>,
    ) -> Result<RunSummary, SoftSlaveError> {
        let start = self.now();
        let end = duration.map(|d| start + d);
        self.converter.power_on(start);
        let iface = self.bus.name().to_string();
        self.note(start, &format!("started on {iface}, MAC {}", self.converter.node().mac_id()));
        let result = loop {
            let now = self.now();
            if stop.load(Ordering::Relaxed) || end.is_some_and(|e| now >= e) {
                break Ok(());
            }
            if let Err(e) = self.turn(now, end) {
                break Err(e);
            }
        };
        let flushed = self.finish_log();
        let now = self.now();
        self.summary.elapsed = now - start;
        self.summary.stats = self.converter.profile().stats();
        result?;
        flushed?;
        Ok(self.summary.clone())
    }

    /// One turn of the loop (module docs, steps 1–4).
    fn turn(&mut self, now: Instant, end: Option<Instant>) -> Result<(), SoftSlaveError> {
        while let Some(event) = self.serial.try_event() {
            match event {
                SerialEvent::Bytes(at, bytes) => {
                    let at = at.max(self.last_now);
                    self.last_now = at;
                    self.summary.serial_bytes_received += bytes.len() as u64;
                    self.converter.handle_serial(&bytes, at);
                }
                SerialEvent::Connection(change) => {
                    let text = format!("instrument {}: {change}", self.serial.name());
                    self.note(now.max(self.last_now), &text);
                }
                SerialEvent::Failed(what, source) => {
                    return Err(SoftSlaveError::SerialIo {
                        path: self.serial.name().to_string(),
                        what,
                        source,
                    })
                }
            }
        }
        let now = now.max(self.last_now);
        self.last_now = now;
        if self.converter.poll_at().is_some_and(|at| at <= now) {
            self.converter.handle_timeout(now);
        }
        self.drain(now)?;
        let mut deadline = now + POLL_SLICE;
        let held = self.mutant.as_ref().and_then(|(_, hook)| hook.poll_at());
        let apply = self.firmware.as_ref().and_then(|(_, object)| object.poll_at());
        for at in [self.converter.poll_at(), end, held, apply].into_iter().flatten() {
            deadline = deadline.min(at.max(now));
        }
        // The bus's own clock is only used for its deadline.
        let bus_now = self.bus.now();
        let bus_deadline = bus_now + (deadline - now);
        if let Some(ev) = self.bus.recv(bus_deadline)? {
            let at = self.now().max(self.last_now);
            self.last_now = at;
            self.log_frame(at, &ev.frame, ev.origin)?;
            if ev.origin == Origin::Remote {
                self.summary.can_received += 1;
                let frame = match &mut self.mutant {
                    Some((_, hook)) => hook.receive(&ev.frame, at, self.converter.node()),
                    None => Some(ev.frame),
                };
                if let Some(frame) = frame {
                    match &mut self.firmware {
                        Some((_, object)) => self.converter.handle_can_frame_with(&frame, at, object),
                        None => self.converter.handle_can_frame(&frame, at),
                    }
                }
                self.drain(at)?;
            }
        }
        Ok(())
    }

    /// Drains the converter: CAN frames, serial bytes, then events.
    fn drain(&mut self, now: Instant) -> Result<(), SoftSlaveError> {
        while let Some(frame) = self.converter.poll_can_transmit() {
            match &mut self.mutant {
                Some((_, hook)) => {
                    hook.transmit(frame, now, self.converter.node());
                    while let Some(fed) = hook.poll_feed() {
                        self.converter.handle_can_frame(&fed, now);
                    }
                }
                None => {
                    self.bus.send(&frame)?;
                    self.summary.can_sent += 1;
                }
            }
        }
        if let Some((_, hook)) = &mut self.mutant {
            while let Some(frame) = hook.poll_transmit(now) {
                self.bus.send(&frame)?;
                self.summary.can_sent += 1;
            }
        }
        while let Some(bytes) = self.converter.poll_serial_transmit(now) {
            self.serial.write(bytes);
            self.summary.serial_bytes_sent += bytes.len() as u64;
        }
        while let Some(event) = self.converter.poll_event() {
            self.on_firmware_event(&event, now);
            self.on_event(event, now)?;
        }
        if let Some(image) = self.converter.poll_new_image() {
            let len = image.len();
            self.state.set_image(image);
            let kept = match &self.state_file {
                Some(file) => {
                    file.save(&self.state)?;
                    format!("kept in {}", file.path().display())
                }
                None => "kept until the process ends (no --state)".to_string(),
            };
            self.note(
                now,
                &format!("new configuration ({len} bytes) stored, applies at the next reset; {kept}"),
            );
        }
        // Last in the converter's drain order: the Identity Reset it says is due (RESET_DELAY after
        // the response), carried out as the board's power cycle.
        if self.converter.poll_reset(now).is_some() {
            self.converter = self.fresh(now)?;
            if let Some((m, hook)) = &mut self.mutant {
                *hook = m.hook();
            }
            self.converter.power_on(now);
            self.summary.resets += 1;
            self.note(now, "Identity Reset: the converter restarts (duplicate MAC ID check)");
            self.restart_firmware_object(now)?;
            return Ok(());
        }
        if self.firmware.as_mut().is_some_and(|(_, object)| object.poll_reset(now)) {
            // Apply's reset: the soft slave's stand-in for the bootloader's swap (crate::firmware).
            self.trial = true;
            self.converter = self.fresh(now)?;
            if let Some((m, hook)) = &mut self.mutant {
                *hook = m.hook();
            }
            self.converter.power_on(now);
            self.summary.resets += 1;
            self.restart_firmware_object(now)?;
            return Ok(());
        }
        let state = self.converter.profile().status().state;
        if state != self.link {
            self.link = state;
            let s = self.converter.profile().stats();
            let text = match state {
                LinkState::Ok => format!("instrument link ok ({} frames received)", s.frames_received),
                LinkState::Timeout => {
                    "instrument silent: input image stale, minor recoverable fault".to_string()
                }
                LinkState::Starting => "instrument link starting".to_string(),
            };
            self.note(now, &text);
        }
        Ok(())
    }

    /// The update object's share of an event: the session ends with the explicit connection,
    /// and an image on trial confirms itself once on-line.
    fn on_firmware_event(&mut self, event: &Event, now: Instant) {
        let Some((_, object)) = &mut self.firmware else { return };
        object.on_event(event);
        if *event == Event::Online && self.trial {
            object.confirm();
            self.trial = false;
            self.note(now, "firmware update: the new image is on-line and confirmed");
        }
    }

    /// A new update object after a reset, as the board's firmware starts with one: the running
    /// revision read again (`active.bin`), on trial after Apply.
    fn restart_firmware_object(&mut self, now: Instant) -> Result<(), SoftSlaveError> {
        let Some((dir, object)) = &mut self.firmware else { return Ok(()) };
        let boot = if self.trial { BootState::Trial } else { BootState::Confirmed };
        *object = dir.object(boot)?;
        if self.trial {
            let text =
                format!("firmware update applied: running revision {} on trial until on-line", dir.running());
            self.note(now, &text);
        }
        Ok(())
    }

    fn on_event(&mut self, event: Event, now: Instant) -> Result<(), SoftSlaveError> {
        if let Some(text) = event_text(&event) {
            self.note(now, &text);
        }
        // A MAC ID taken through the Offline Connection Set is kept like a network-set one.
        let change = match &event {
            Event::SettingChanged(change) => Some(*change),
            Event::MacIdChanged(mac) => Some(SettingChanged::MacId(*mac)),
            _ => None,
        };
        if let Some(change) = &change {
            if self.state.note(change) {
                if let Some(file) = &self.state_file {
                    file.save(&self.state)?;
                    let text = format!("kept in {}", file.path().display());
                    self.note(now, &text);
                }
            }
        }
        Ok(())
    }

    fn note(&mut self, at: Instant, text: &str) {
        // Reporting is best effort: a closed stderr must not stop the converter.
        let _ = writeln!(self.report, "[{:>12}] {text}", format_instant(at));
    }

    fn log_frame(&mut self, at: Instant, frame: &CanFrame, origin: Origin) -> Result<(), SoftSlaveError> {
        let iface = self.bus.name().to_string();
        let direction = match origin {
            Origin::Local => Direction::Tx,
            Origin::Remote => Direction::Rx,
        };
        if let Some((log, path)) = &mut self.log {
            // Flushed frame by frame: whoever reads the log while the soft slave runs (a test, a
            // user's `tail -f`) sees every frame it has handled.
            log.write_dir(at, &iface, direction, frame)
                .and_then(|()| log.flush())
                .map_err(|source| SoftSlaveError::Log { path: path.clone(), source })?;
        }
        Ok(())
    }

    /// Ends the log: the format's footer (asc's `End TriggerBlock`), then flushed.
    fn finish_log(&mut self) -> Result<(), SoftSlaveError> {
        if let Some((log, path)) = &mut self.log {
            log.finish().map_err(|source| SoftSlaveError::Log { path: path.clone(), source })?;
        }
        Ok(())
    }

    fn now(&self) -> Instant {
        self.clock.now()
    }
}

/// How an event reads in the report; `None` for the ones that come with every poll.
pub fn event_text(event: &Event) -> Option<String> {
    let kind = |k: &ConnectionKind| match k {
        ConnectionKind::Explicit => "explicit",
        ConnectionKind::Poll => "poll",
        ConnectionKind::Strobe => "bit-strobe",
        ConnectionKind::ChangeOfState => "change-of-state/cyclic",
    };
    Some(match event {
        Event::OutputReceived | Event::Idle => return None,
        Event::Online => "on-line (duplicate MAC ID check passed)".into(),
        Event::CommunicationFaulted(FaultReason::DuplicateMacId) => {
            "communication faulted: another node has this MAC ID".into()
        }
        Event::CommunicationFaulted(FaultReason::BusOff) => "communication faulted: bus-off".into(),
        Event::ResetCanController => "bus-off: the CAN controller restarts".into(),
        Event::Allocated { choice, master } => format!("allocated to master MAC {master}: {choice}"),
        Event::Released { choice, owned } => {
            format!("released: {choice}{}", if *owned { "" } else { " (no connection left)" })
        }
        Event::ConnectionEstablished(k) => format!("{} connection established", kind(k)),
        Event::ConnectionTimedOut(k) => format!("{} connection timed out", kind(k)),
        Event::ConnectionDeleted(k) => format!("{} connection deleted by its watchdog", kind(k)),
        Event::ResetRequested(t) => format!("Identity Reset (type {t}) requested"),
        Event::SettingChanged(s) => {
            format!("setting changed over the network: {s:?} (applies at the next reset)")
        }
        Event::ExplicitTransferAborted => "fragmented explicit response abandoned".into(),
        Event::RetryLimitReached => {
            "change-of-state/cyclic production unacknowledged through the retry limit".into()
        }
        Event::MacIdChanged(mac) => {
            format!("MAC ID changed to {mac} through the Offline Connection Set: duplicate MAC ID check")
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use devicenet::messages::AllocationChoice;
    use devicenet::MacId;

    #[test]
    fn event_texts() {
        let master = MacId::new(0).unwrap();
        let text = event_text(&Event::Allocated { choice: AllocationChoice::POLL, master }).unwrap();
        assert!(text.starts_with("allocated to master MAC 0: "), "{text}");
        assert_eq!(
            event_text(&Event::ConnectionTimedOut(ConnectionKind::Poll)).as_deref(),
            Some("poll connection timed out")
        );
        assert_eq!(event_text(&Event::OutputReceived), None);
    }
}
