//! Timing: poll response latency and explicit response latency, with the limits a scanner applies
//! (its own choices: protocol §9, FREE).

use super::super::runner::{g2, percentile, Check, Runner};
use super::super::{Basis, Category};
use devicenet::objects::class;
use devicenet::{Duration, Group2Message};
use harness_common::error::HarnessError;
use master_core::error::MasterError;

const TM: Category = Category::Timing;

pub(super) fn run(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    r.run(
        "poll-latency",
        "poll response latency (end of poll command to end of the complete response)",
        TM,
        "§9 (FREE: the scanner's poll timeout)",
        poll_latency,
    )?;
    r.run(
        "explicit-latency",
        "explicit response latency (end of request to end of response)",
        TM,
        "§9.4 (FREE: the scanner's response timeout)",
        explicit_latency,
    )
}

fn ms(d: Duration) -> f64 {
    d.total_micros() as f64 / 1000.0
}

/// Adds min/median/p99/max of `samples` (ms); with a limit, grades the 99th percentile against
/// it, else only reports.
fn summarise(c: &mut Check, what: &str, mut samples: Vec<f64>, limit: Option<(Duration, &str)>) {
    samples.sort_by(f64::total_cmp);
    let (min, med, p99, max) = (
        samples.first().copied().unwrap_or(0.0),
        percentile(&samples, 50.0),
        percentile(&samples, 99.0),
        samples.last().copied().unwrap_or(0.0),
    );
    c.measure(format!("{what} min"), min, "ms");
    c.measure(format!("{what} median"), med, "ms");
    c.measure(format!("{what} p99"), p99, "ms");
    c.measure(format!("{what} max"), max, "ms");
    let text = format!(
        "{what} over {} samples: min {min:.3} ms, median {med:.3} ms, p99 {p99:.3} ms, max {max:.3} ms",
        samples.len()
    );
    match limit {
        Some((limit, why)) => {
            c.measure(format!("{what} limit"), ms(limit), "ms");
            c.timed(
                Basis::Free,
                p99 <= ms(limit),
                format!("{text}; limit {:.0} ms ({why})", ms(limit)),
                None,
            );
        }
        None => {
            c.timed(Basis::Normative, true, text, None);
        }
    }
}

fn poll_latency(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    let epr = r.opts.epr_ms;
    let applied = r.fresh_poll(epr, None)?;
    let epr_d = Duration::from_millis(u64::from(applied.max(1)));
    let limit = Duration::from_millis(u64::from(applied.max(100)));
    let output = r.output();
    let poll_id = g2(r.dut(), Group2Message::PollCommand);
    let rsp = r.poll_response_id();
    let mut complete = Vec::new();
    let mut first = Vec::new();
    let mut missing = 0u32;
    let mut next = r.now();
    r.waiting(&format!("timing {} polls, one per EPR ({applied} ms)", r.opts.latency_polls));
    for _ in 0..r.opts.latency_polls {
        r.m.idle_until(next)?;
        next += epr_d;
        let start = r.mark();
        match r.poll(&output, limit) {
            Ok(_) => {}
            Err(HarnessError::Master(MasterError::Timeout { .. })) => {
                missing += 1;
                continue;
            }
            Err(e) => return Err(e),
        }
        let Some(p) = r.last_sent(poll_id, start) else { continue };
        let t0 = r.rec(p).0;
        let times: Vec<_> =
            r.m.session.records()[start..].iter().filter(|x| x.frame.id() == rsp).map(|x| x.at).collect();
        if let (Some(&a), Some(&b)) = (times.first(), times.last()) {
            first.push(ms(a - t0));
            complete.push(ms(b - t0));
        }
    }
    c.firm(
        missing == 0,
        format!("{} of {} polls answered", r.opts.latency_polls - missing, r.opts.latency_polls),
        None,
    );
    if !first.is_empty() {
        summarise(c, "first fragment", first, None);
    }
    if !complete.is_empty() {
        let why = "a scanner waits one EPR, at least 100 ms, as this harness does";
        summarise(c, "complete response", complete, Some((limit, why)));
    }
    Ok(())
}

fn explicit_latency(r: &mut Runner<'_, '_>, c: &mut Check) -> Result<(), HarnessError> {
    r.fresh_explicit()?;
    let limit = r.m.config.response_timeout;
    let req_id = r.explicit_request_id();
    let mut samples = Vec::new();
    for _ in 0..r.opts.latency_requests {
        let start = r.mark();
        let a = r.get(class::IDENTITY, 1, 1)?;
        if let (Some(i), Some(q)) = (a.record, r.last_sent(req_id, start)) {
            samples.push(ms(r.rec(i).0 - r.rec(q).0));
        }
    }
    summarise(
        c,
        "explicit response",
        samples,
        Some((limit, "the explicit response timeout, --timeout (JB: 1 s)")),
    );
    Ok(())
}
