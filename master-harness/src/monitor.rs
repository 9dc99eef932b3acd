//! `monitor --mac N`: bring the device up, then poll it at the expected packet rate and show the
//! polled data decoded by the device profile — for the breaker: the four phase currents and the
//! switch state — refreshed in place on a terminal, one line per sample otherwise; `--csv FILE`
//! records every sample.

use crate::error::HarnessError;
use crate::master::{ConnectOptions, Master, MIN_POLL_TIMEOUT};
use crate::soft_slave::{SWITCH_BYTE, SWITCH_CLOSED, SWITCH_OPEN};
use devicenet::{Duration, Instant};
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
    let raw = crate::decode::hex(&s.raw).replace(' ', "");
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

fn display_line(s: &Sample) -> String {
    let t = format!("{}.{:03}s", s.time_us / 1_000_000, (s.time_us / 1000) % 1000);
    match &s.status {
        Some(b) => format!(
            "{t:>10}  A {:>3} A  B {:>3} A  C {:>3} A  N {:>3} A  switch {}",
            b.currents[0],
            b.currents[1],
            b.currents[2],
            b.currents[3],
            b.switch_text()
        ),
        None => format!("{t:>10}  {} (not the breaker profile)", crate::decode::hex(&s.raw)),
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
    let produced = summary.produced_size.unwrap_or(0);
    let consumed = summary.consumed_size.unwrap_or(0);
    let epr_ms = summary.expected_packet_rate_ms.unwrap_or(connect.epr_ms).max(1);
    let epr = Duration::from_millis(u64::from(epr_ms));
    let timeout = if epr > MIN_POLL_TIMEOUT { epr } else { MIN_POLL_TIMEOUT };
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
        master.idle_until(next)?;
        let polled = master.session.now();
        let raw = master.poll(target, &output, produced, consumed, timeout)?;
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
        next = polled + epr;
    }
    if opts.in_place {
        writeln!(out).map_err(write_err)?;
    }
    Ok(samples)
}

#[cfg(test)]
mod tests {
    use super::*;
    use devicenet::reference::INPUT_IMAGE;

    #[test]
    fn reference_image_is_an_open_breaker() {
        let s = BreakerStatus::decode(&INPUT_IMAGE).unwrap();
        assert_eq!(s.currents, [0; 4]);
        assert_eq!(s.switch_text(), "open");
        assert_eq!(BreakerStatus::decode(&[0; 9]), None);
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
