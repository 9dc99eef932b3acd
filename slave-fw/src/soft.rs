//! The soft slave as test equipment: a [`Converter`] wired to a [`SimulatedBreaker`] on one
//! virtual clock, with serial bytes crossing the "wire" in their transmission time at the
//! configured baud rate. The master harness attaches it to its simulated CAN bus; the system
//! tests drive it directly.

use crate::converter::{Converter, ConverterConfig, ConverterConfigError};
use crate::sim::SimulatedBreaker;
use devicenet::{CanFrame, Duration, Event, Instant};
use std::collections::VecDeque;

/// The delay between an Identity Reset response and the simulated power cycle.
pub const RESET_DELAY: Duration = Duration::from_millis(10);

/// A converter and its simulated breaker. Sans-IO on the CAN side, like the node.
pub struct SoftSlave {
    config: ConverterConfig,
    converter: Converter,
    reset_at: Option<Instant>,
    events: VecDeque<Event>,
    breaker: SimulatedBreaker,
    /// Bytes on the serial wire towards the breaker / the converter, with arrival times.
    to_breaker: VecDeque<(Instant, Vec<u8>)>,
    to_converter: VecDeque<(Instant, Vec<u8>)>,
    char_time: Duration,
    powered: bool,
}

impl SoftSlave {
    /// A powered-off soft slave for `config` with a breaker that starts sending at `now`.
    pub fn new(config: ConverterConfig, now: Instant) -> Result<SoftSlave, ConverterConfigError> {
        let char_time = config.profile.serial().char_time();
        Ok(SoftSlave {
            converter: Converter::new(config.clone(), now)?,
            config,
            reset_at: None,
            events: VecDeque::new(),
            breaker: SimulatedBreaker::new(now),
            to_breaker: VecDeque::new(),
            to_converter: VecDeque::new(),
            char_time,
            powered: false,
        })
    }

    /// The reference converter (devicenet-notes §2 device, breaker profile).
    pub fn reference(now: Instant) -> SoftSlave {
        // The reference configuration is valid by construction (tested).
        match SoftSlave::new(ConverterConfig::breaker_reference(), now) {
            Ok(s) => s,
            Err(e) => unreachable!("reference configuration: {e}"),
        }
    }

    /// Power-on: the node starts its duplicate MAC ID check.
    pub fn power_on(&mut self, now: Instant) {
        if self.powered {
            // A second power-on is a power cycle: the converter starts afresh.
            if let Ok(fresh) = Converter::new(self.config.clone(), now) {
                self.converter = fresh;
            }
        }
        self.powered = true;
        self.reset_at = None;
        self.converter.power_on(now);
    }

    /// `true` after [`SoftSlave::power_on`].
    pub fn is_powered(&self) -> bool {
        self.powered
    }

    /// A CAN frame reached the node.
    pub fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.run_serial(now);
        if self.powered {
            self.converter.handle_can_frame(frame, now);
        }
        self.run_serial(now);
    }

    /// The CAN controller went bus-off at `now` (devicenet-notes §7.2): the node applies its bus-off
    /// interrupt setting (BOI 0: Communication Faulted; 1: restart the duplicate MAC ID check).
    pub fn handle_bus_off(&mut self, now: Instant) {
        self.run_serial(now);
        if self.powered {
            self.converter.handle_bus_off(now);
        }
        self.run_serial(now);
    }

    /// Runs both sides' timers and the serial wire up to `now`. An Identity Reset power-cycles
    /// the converter [`RESET_DELAY`] after its response (the breaker keeps running).
    pub fn handle_timeout(&mut self, now: Instant) {
        if self.reset_at.is_some_and(|at| at <= now) {
            self.reset_at = None;
            if let Ok(fresh) = Converter::new(self.config.clone(), now) {
                self.converter = fresh;
                self.converter.power_on(now);
            }
        }
        self.run_serial(now);
    }

    /// The configuration the converter runs with.
    pub fn config(&self) -> &ConverterConfig {
        &self.config
    }

    /// The converter's events (outputs received, settings changed, resets), oldest first; at most
    /// the last 64 are kept.
    pub fn poll_event(&mut self) -> Option<Event> {
        self.events.pop_front()
    }

    /// The next CAN frame the node transmits.
    pub fn poll_transmit(&mut self) -> Option<CanFrame> {
        self.converter.poll_can_transmit()
    }

    /// The earliest instant anything happens: node, profile, breaker or a byte arriving.
    pub fn poll_at(&self) -> Option<Instant> {
        let node = if self.powered { self.converter.poll_at() } else { None };
        [
            node,
            self.reset_at,
            self.breaker.poll_at(),
            self.to_breaker.front().map(|(at, _)| *at),
            self.to_converter.front().map(|(at, _)| *at),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    /// The converter.
    pub fn converter(&self) -> &Converter {
        &self.converter
    }

    /// The breaker.
    pub fn breaker(&self) -> &SimulatedBreaker {
        &self.breaker
    }

    /// The breaker, to inject faults (silence, garbage, rejections).
    pub fn breaker_mut(&mut self) -> &mut SimulatedBreaker {
        &mut self.breaker
    }

    fn wire_time(&self, len: usize) -> Duration {
        Duration::from_micros(self.char_time.total_micros().saturating_mul(len as u64))
    }

    /// Moves everything due by `now`, in time order, until both sides are quiet.
    fn run_serial(&mut self, now: Instant) {
        for _ in 0..10_000 {
            let mut moved = false;
            if self.powered {
                if self.converter.poll_at().is_some_and(|at| at <= now) {
                    self.converter.handle_timeout(now);
                }
                while let Some(bytes) = self.converter.poll_serial_transmit(now) {
                    let bytes = bytes.to_vec();
                    let at = now + self.wire_time(bytes.len());
                    self.to_breaker.push_back((at, bytes));
                    moved = true;
                }
            }
            while let Some(bytes) = self.breaker.poll_transmit(now) {
                let at = now + self.wire_time(bytes.len());
                self.to_converter.push_back((at, bytes));
                moved = true;
            }
            while self.to_breaker.front().is_some_and(|(at, _)| *at <= now) {
                if let Some((at, bytes)) = self.to_breaker.pop_front() {
                    self.breaker.on_bytes(&bytes, at);
                    moved = true;
                }
            }
            while self.to_converter.front().is_some_and(|(at, _)| *at <= now) {
                if let Some((at, bytes)) = self.to_converter.pop_front() {
                    if self.powered {
                        self.converter.handle_serial(&bytes, at);
                    }
                    moved = true;
                }
            }
            while let Some(event) = self.converter.poll_event() {
                if let Event::ResetRequested(_) = event {
                    self.reset_at = Some(now + RESET_DELAY);
                }
                if self.events.len() == 64 {
                    self.events.pop_front();
                }
                self.events.push_back(event);
            }
            if !moved {
                return;
            }
        }
    }
}
