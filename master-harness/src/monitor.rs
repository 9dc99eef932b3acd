//! `monitor --mac N`: bring the device up, then poll it at the expected packet rate and show the
//! polled data decoded by the device profile — for the breaker: the four phase currents and the
//! switch state — refreshed in place on a terminal, one line per sample otherwise; `--csv FILE`
//! records every sample.
//!
//! With `--reconnect` a lost connection does not end the run: a bus error (a SocketCAN interface
//! taken down, an adapter unplugged) or a poll left unanswered is reported as `connection lost`,
//! and the master tries every [`RECONNECT_INTERVAL`] to get the connections back without a new
//! duplicate MAC ID check of its own: Allocate explicit through the Group 2 Only port (an
//! explicit connection the device still holds for this master is used as it is), Release of a
//! poll connection left over, Allocate poll, sizes and expected packet rate again, then polling
//! goes on (`reconnected`). A device that restarted is simply asked until it is on-line again.

use crate::error::HarnessError;
use converter_sim::device::{SWITCH_BYTE, SWITCH_CLOSED, SWITCH_OPEN};
use devicenet::explicit::GeneralStatus;
use devicenet::messages::AllocationChoice;
use devicenet::objects::class;
use devicenet::{Duration, Instant, MacId};
use master_core::client::Port;
use master_core::error::MasterError;
use master_core::master::{ConnectOptions, Master, MIN_POLL_TIMEOUT};
use master_core::session::Verdict;
use std::io::Write;

/// The breaker profile's view of the 18-byte poll response.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct BreakerStatus {
    /// Phase A, B, C and neutral currents (A).
    pub currents: [u8; 4],
    /// Switch state byte (`0x0F` open, `0xF0` closed).
    pub switch: u8,
}

impl BreakerStatus {
    /// Decodes the input image; `None` when it is shorter than the profile's 10 bytes.
    pub fn decode(input: &[u8]) -> Option<BreakerStatus> {
        let switch = *input.get(SWITCH_BYTE)?;
        Some(BreakerStatus { currents: [input[0], input[1], input[2], input[3]], switch })
    }

    /// `open`, `closed` or `unknown (0xXX)`.
    pub fn switch_text(&self) -> String {
        match self.switch {
            SWITCH_OPEN => "open".into(),
            SWITCH_CLOSED => "closed".into(),
            other => format!("unknown (0x{other:02X})"),
        }
    }
}

/// Options of `monitor`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MonitorOptions {
    /// Bring-up options (polls are ignored: monitor polls itself).
    pub connect: ConnectOptions,
    /// Stop after this many samples.
    pub count: Option<u64>,
    /// Stop after this much bus time of monitoring.
    pub duration: Option<Duration>,
    /// Refresh in place (terminal) instead of a line per sample.
    pub in_place: bool,
    /// Report a lost connection and get it back instead of stopping (`--reconnect`).
    pub reconnect: bool,
}

/// How often `--reconnect` tries to get a lost connection back.
pub const RECONNECT_INTERVAL: Duration = Duration::from_secs(1);

/// The poll connection as the device set it up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct PollSetup {
    produced: u16,
    consumed: u16,
    epr: Duration,
}

/// `true` for the failures `--reconnect` rides out: the bus failed, or the device did not answer.
fn is_connection_loss(e: &MasterError) -> bool {
    matches!(e, MasterError::Bus(_) | MasterError::Timeout { .. })
}

/// Marks the last frame from the device, an error response the reconnection expected, as fine.
fn accept_last_answer(master: &mut Master<'_, '_>, note: &str) {
    if let Some(i) = master.session.records().iter().rposition(|r| r.origin == can_io::bus::Origin::Remote) {
        master.session.set_verdict(i, Verdict::Ok(note.into()));
    }
}

/// One attempt to get the connections back (see the [module docs](self)).
fn reestablish(master: &mut Master<'_, '_>, target: MacId, epr_ms: u16) -> Result<PollSetup, MasterError> {
    match master.allocate(target, Port::Group2Only, AllocationChoice::EXPLICIT) {
        Ok(_) => {}
        Err(MasterError::ErrorResponse { general: GeneralStatus::AlreadyInRequestedState, .. }) => {
            accept_last_answer(master, "explicit connection still allocated to this master");
        }
        Err(e) => return Err(e),
    }
    match master.release(target, AllocationChoice::POLL) {
        Ok(()) => {}
        Err(MasterError::ErrorResponse { .. }) => accept_last_answer(master, "no poll connection left over"),
        Err(e) => return Err(e),
    }
    master.allocate(target, Port::Explicit, AllocationChoice::POLL)?;
    let produced = master.get_u16(target, class::CONNECTION, 2, 7)?.unwrap_or(0);
    let consumed = master.get_u16(target, class::CONNECTION, 2, 8)?.unwrap_or(0);
    let (data, _) = master.set(target, class::CONNECTION, 2, 9, &epr_ms.to_le_bytes())?;
    let applied = match data.as_slice() {
        [a, b] => u16::from_le_bytes([*a, *b]),
        _ => epr_ms,
    };
    Ok(PollSetup { produced, consumed, epr: Duration::from_millis(u64::from(applied.max(1))) })
}

/// Waits until `deadline` on a bus that may be failing: errors are ridden out, with a short real
/// pause so a bus that fails at once every time is not spun on.
fn wait_through_errors(master: &mut Master<'_, '_>, deadline: Instant) {
    while master.session.now() < deadline {
        if master.idle_until(deadline).is_err() {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }
}

/// One sample.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Sample {
    /// Bus time, microseconds.
    pub time_us: u64,
    /// Decoded status, when the data fits the profile.
    pub status: Option<BreakerStatus>,
    /// The raw input data.
    pub raw: Vec<u8>,
}

/// The CSV header written by `--csv`.
pub const CSV_HEADER: &str = "time_s,phase_a,phase_b,phase_c,neutral,switch,raw";

/// One CSV line for a sample.
pub fn csv_line(s: &Sample) -> String {
    let raw = master_core::decode::hex(&s.raw).replace(' ', "");
    let t = format!("{}.{:06}", s.time_us / 1_000_000, s.time_us % 1_000_000);
    match &s.status {
        Some(b) => format!(
            "{t},{},{},{},{},{},{raw}",
            b.currents[0],
            b.currents[1],
            b.currents[2],
            b.currents[3],
            b.switch_text()
        ),
        None => format!("{t},,,,,,{raw}"),
    }
}

/// Bus time in seconds with milliseconds: `5.100s`.
fn seconds_text(us: u64) -> String {
    format!("{}.{:03}s", us / 1_000_000, (us / 1000) % 1000)
}

fn display_line(s: &Sample) -> String {
    let t = seconds_text(s.time_us);
    match &s.status {
        Some(b) => format!(
            "{t:>10}  A {:>3} A  B {:>3} A  C {:>3} A  N {:>3} A  switch {}",
            b.currents[0],
            b.currents[1],
            b.currents[2],
            b.currents[3],
            b.switch_text()
        ),
        None => format!("{t:>10}  {} (not the breaker profile)", master_core::decode::hex(&s.raw)),
    }
}

/// Brings the device up and monitors it. Samples are shown on `out` and written to `csv`.
pub fn monitor(
    master: &mut Master<'_, '_>,
    opts: &MonitorOptions,
    out: &mut dyn Write,
    mut csv: Option<&mut dyn Write>,
) -> Result<Vec<Sample>, HarnessError> {
    let target = opts.connect.target;
    let mut connect = opts.connect.clone();
    connect.polls = 0;
    connect.verify_state = false;
    let summary = master.connect(&connect)?;
    let consumed = summary.consumed_size.unwrap_or(0);
    let epr_ms = summary.expected_packet_rate_ms.unwrap_or(connect.epr_ms).max(1);
    let mut setup = PollSetup {
        produced: summary.produced_size.unwrap_or(0),
        consumed,
        epr: Duration::from_millis(u64::from(epr_ms)),
    };
    let output = connect.output.clone().unwrap_or_else(|| vec![0; usize::from(consumed)]);
    let write_err = |source| HarnessError::Write { path: "the output".into(), source };
    if let Some(w) = csv.as_deref_mut() {
        writeln!(w, "{CSV_HEADER}").map_err(write_err)?;
    }
    let start = master.session.now();
    let end: Option<Instant> = opts.duration.map(|d| start + d);
    let mut samples = Vec::new();
    let mut next = start;
    loop {
        if opts.count.is_some_and(|c| samples.len() as u64 >= c) || end.is_some_and(|e| next > e) {
            break;
        }
        let timeout = if setup.epr > MIN_POLL_TIMEOUT { setup.epr } else { MIN_POLL_TIMEOUT };
        let mut polled = master.session.now();
        let cycle = master.idle_until(next).and_then(|()| {
            polled = master.session.now();
            master.poll(target, &output, setup.produced, setup.consumed, timeout)
        });
        let raw = match cycle {
            Ok(raw) => raw,
            Err(e) if opts.reconnect && is_connection_loss(&e) => {
                let lost = master.session.now();
                let at = |t: Instant| seconds_text(t.total_micros());
                writeln!(
                    out,
                    "{}connection lost at {}: {e}",
                    if opts.in_place { "\n" } else { "" },
                    at(lost)
                )
                .map_err(write_err)?;
                let mut attempts = 0u32;
                loop {
                    attempts += 1;
                    let tried = master.session.now();
                    if end.is_some_and(|e| tried > e) {
                        writeln!(out, "not reconnected before the end of the run").map_err(write_err)?;
                        return Ok(samples);
                    }
                    match reestablish(master, target, connect.epr_ms) {
                        Ok(s) => {
                            setup = s;
                            break;
                        }
                        Err(e)
                            if is_connection_loss(&e) || matches!(e, MasterError::ErrorResponse { .. }) =>
                        {
                            wait_through_errors(master, tried + RECONNECT_INTERVAL);
                        }
                        Err(e) => return Err(e.into()),
                    }
                }
                let back = master.session.now();
                writeln!(out, "reconnected at {} after {attempts} attempt(s)", at(back))
                    .map_err(write_err)?;
                next = back;
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        let sample = Sample { time_us: polled.total_micros(), status: BreakerStatus::decode(&raw), raw };
        if opts.in_place {
            write!(out, "\r\x1b[2K{}", display_line(&sample)).map_err(write_err)?;
        } else {
            writeln!(out, "{}", display_line(&sample)).map_err(write_err)?;
        }
        out.flush().map_err(write_err)?;
        if let Some(w) = csv.as_deref_mut() {
            writeln!(w, "{}", csv_line(&sample)).map_err(write_err)?;
        }
        samples.push(sample);
        next = polled + setup.epr;
    }
    if opts.in_place {
        writeln!(out).map_err(write_err)?;
    }
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use super::*;
    use can_io::bus::Bus;
    use devicenet::reference::INPUT_IMAGE;

    #[test]
    fn reference_image_is_an_open_breaker() {
        let s = BreakerStatus::decode(&INPUT_IMAGE).unwrap();
        assert_eq!(s.currents, [0; 4]);
        assert_eq!(s.switch_text(), "open");
        assert_eq!(BreakerStatus::decode(&[0; 9]), None);
    }

    /// A bus whose interface goes down between `from` and `until`: sending fails, the first read
    /// reports the error (as a SocketCAN socket does with ENETDOWN), frames do not pass.
    struct Outage {
        inner: can_io::sim::SimBus,
        from: Instant,
        until: Instant,
        reported: bool,
    }

    impl Outage {
        fn down(&mut self) -> bool {
            let now = self.inner.now();
            now >= self.from && now < self.until
        }
        fn error() -> can_io::bus::BusError {
            can_io::bus::BusError::Io {
                what: "sim0".into(),
                source: std::io::Error::other("network is down"),
            }
        }
    }

    impl can_io::bus::Bus for Outage {
        fn name(&self) -> &str {
            "sim0"
        }
        fn now(&mut self) -> Instant {
            self.inner.now()
        }
        fn send(&mut self, frame: &devicenet::CanFrame) -> Result<(), can_io::bus::BusError> {
            if self.down() {
                return Err(Outage::error());
            }
            self.inner.send(frame)
        }
        fn recv(
            &mut self,
            deadline: Instant,
        ) -> Result<Option<can_io::bus::BusEvent>, can_io::bus::BusError> {
            if self.down() && !std::mem::replace(&mut self.reported, true) {
                return Err(Outage::error());
            }
            self.inner.recv(deadline)
        }
    }

    fn monitor_through_outage(reconnect: bool) -> (Result<Vec<Sample>, HarnessError>, String, usize) {
        use can_io::sim::{PowerOn, SimBus};
        let mut sim = SimBus::new(can_io::bus::Bitrate::K250);
        sim.attach(
            Box::new(converter_sim::device::SoftSlave::reference(MacId::from_low_bits(5))),
            PowerOn::WhenMasterOnline,
        );
        let mut bus =
            Outage { inner: sim, from: Instant::from_secs(7), until: Instant::from_secs(9), reported: false };
        let mut session = master_core::session::Session::new(&mut bus);
        let mut master = Master::new(&mut session, master_core::master::MasterConfig::default());
        let opts = MonitorOptions {
            connect: ConnectOptions::default(),
            count: None,
            duration: Some(Duration::from_secs(8)),
            in_place: false,
            reconnect,
        };
        let mut out = Vec::new();
        let r = monitor(&mut master, &opts, &mut out, None);
        let failures = master.session.failures();
        (r, String::from_utf8_lossy(&out).into_owned(), failures)
    }

    #[test]
    fn reconnect_rides_out_an_outage() {
        let (r, out, failures) = monitor_through_outage(true);
        let samples = r.unwrap();
        assert!(out.contains("connection lost at 7."), "{out}");
        assert!(out.contains("reconnected at 9."), "{out}");
        let after = samples.iter().filter(|s| s.time_us > 9_000_000).count();
        assert!(after > 20, "polling goes on after the outage: {after} samples\n{out}");
        assert!(samples.iter().all(|s| s.raw == INPUT_IMAGE), "{out}");
        assert_eq!(failures, 0, "{out}");
    }

    #[test]
    fn without_reconnect_the_loss_ends_the_run() {
        let (r, out, _) = monitor_through_outage(false);
        let e = r.unwrap_err();
        assert!(matches!(e, HarnessError::Master(MasterError::Bus(_))), "{e}");
        assert!(!out.contains("connection lost"), "{out}");
    }

    #[test]
    fn csv_lines() {
        let s = Sample {
            time_us: 5_100_000,
            status: BreakerStatus::decode(&INPUT_IMAGE),
            raw: INPUT_IMAGE.to_vec(),
        };
        assert_eq!(csv_line(&s), "5.100000,0,0,0,0,open,0000000000000000000F0000000000000000");
        let short = Sample { time_us: 1, status: None, raw: vec![1, 2] };
        assert_eq!(csv_line(&short), "0.000001,,,,,,0102");
    }
}
