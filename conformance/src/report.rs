//! The suite's reports: the terminal report and the JSON document (the HTML page is
//! [`super::html`]'s; the command that writes them is [`super::command`]'s).
//!
//! The terminal report is written in pieces so that the command can print it as the run goes:
//! [`write_header`] before the first check, [`write_check`] (after [`write_category`] when a new
//! category begins) as each check is judged, [`write_footer`] at the end. [`write_text`] writes the
//! whole report of a finished run the same way.

use super::{Category, CheckResult, Grade, Stopped, SuiteReport, Timestamps};
use devicenet::{Duration, MacId};
use harness_common::table::{print_table, record_json, RecordJson};
use master_core::session::Record;
use serde_json::json;
use std::io::{self, Write};

/// The whole report as JSON: tool version, transport and timestamp source, device identity,
/// summary, why the run ended early (`stopped`, `interrupted`), every check with its
/// expectations, measurements and frames.
pub fn report_json(report: &SuiteReport) -> serde_json::Value {
    let checks: Vec<serde_json::Value> = report
        .checks
        .iter()
        .map(|c| {
            let mut v = serde_json::to_value(c).unwrap_or_else(|_| json!({}));
            let frames: Vec<RecordJson<'_>> =
                report.frames_of(c).iter().map(|r| record_json(r, Some(report.target))).collect();
            v["frames"] = json!(frames);
            v
        })
        .collect();
    let interrupted = match &report.stopped {
        Some(Stopped::Interrupted(s)) => json!(master_core::stop::signal_name(*s)),
        _ => serde_json::Value::Null,
    };
    json!({
        "ok": report.passed(),
        "version": harness_common::version(),
        "started": report.started,
        "device": report.target.as_raw(),
        "master": report.master.as_raw(),
        "second_master": report.second_master.as_raw(),
        "bus": report.bus,
        "transport": report.transport,
        "timestamps": {
            "source": report.timestamps,
            "description": report.timestamps.description(),
            "timing_judged": report.timestamps.timing_advisory().is_none(),
        },
        "identity": report.identity,
        "stopped": report.stopped.as_ref().map(Stopped::text),
        "interrupted": interrupted,
        "release": report.release,
        "bus_time_us": report.duration.total_micros(),
        "summary": {
            "checks": report.checks.len(),
            "of": super::CHECKS,
            "pass": report.count(Grade::Pass),
            "advisory": report.count(Grade::Advisory),
            "fail": report.count(Grade::Fail),
            "frames": report.records.len(),
        },
        "checks": checks,
        "not_exercised": super::NOT_EXERCISED,
    })
}

/// A bus time in seconds.
pub(crate) fn seconds(d: Duration) -> String {
    format!("{:.1} s", d.total_micros() as f64 / 1e6)
}

/// The one-line summary.
#[must_use]
pub fn summary_line(report: &SuiteReport) -> String {
    format!(
        "conformance of MAC {} on {}, master MAC {} (second master {}): {} of {} checks run, {} pass, {} advisory, {} fail; {} frames, {} of bus time",
        report.target,
        report.transport,
        report.master,
        report.second_master,
        report.checks.len(),
        super::CHECKS,
        report.count(Grade::Pass),
        report.count(Grade::Advisory),
        report.count(Grade::Fail),
        report.records.len(),
        seconds(report.duration)
    )
}

/// The lines before the first check: what runs against what, with which tool, on which transport
/// and with which timestamps.
pub fn write_header(
    out: &mut dyn Write,
    target: MacId,
    master: MacId,
    transport: &str,
    timestamps: Timestamps,
) -> io::Result<()> {
    writeln!(
        out,
        "dnet-master {} conformance: device MAC {target}, master MAC {master}, transport {transport}",
        harness_common::version()
    )?;
    writeln!(out, "timestamps: {}", timestamps.description())
}

/// The heading of a category.
pub fn write_category(out: &mut dyn Write, category: Category) -> io::Result<()> {
    writeln!(out, "\n{}", category.title())
}

/// One check's verdict line, what did not pass, its timing measurements and (with `frames`) its
/// frame table.
pub fn write_check(
    out: &mut dyn Write,
    c: &CheckResult,
    records: &[Record],
    device: MacId,
    frames: bool,
) -> io::Result<()> {
    writeln!(out, "  {:<9} {:<30} {}  [{}]", c.grade.label(), c.id, c.title, c.section)?;
    for e in c.findings() {
        writeln!(out, "  {:<9}   - {}: {}", "", e.grade.label().to_lowercase(), e.text)?;
    }
    for m in &c.measurements {
        if c.category == Category::Timing || m.unit == "ms" && c.id.starts_with("watchdog") {
            writeln!(out, "  {:<9}   · {}: {:.3} {}", "", m.name, m.value, m.unit)?;
        }
    }
    if frames && !records.is_empty() {
        print_table(out, records, Some(device))?;
        writeln!(out)?;
    }
    Ok(())
}

/// The lines after the last check: the summary, how the run ended, what was released, and the
/// result.
pub fn write_footer(out: &mut dyn Write, report: &SuiteReport) -> io::Result<()> {
    writeln!(out)?;
    writeln!(out, "{}", summary_line(report))?;
    writeln!(out, "started {}; {}", report.started, report.release)?;
    for n in super::NOT_EXERCISED {
        writeln!(out, "not checked: {} ({}): {}", n.section, n.rule, n.why)?;
    }
    let failed = report.failed();
    let names: Vec<&str> = report.checks.iter().filter(|c| c.grade == Grade::Fail).map(|c| c.id).collect();
    match &report.stopped {
        Some(s @ Stopped::Interrupted(_)) => writeln!(
            out,
            "result: {}: {} of {} checks completed, {failed} failed{}",
            s.text(),
            report.checks.len(),
            super::CHECKS,
            if names.is_empty() { String::new() } else { format!(" ({})", names.join(", ")) }
        ),
        Some(s @ Stopped::NoDevice { .. }) => writeln!(out, "result: stopped: {}", s.text()),
        None if failed == 0 => writeln!(
            out,
            "result: no check failed ({} advisory: see the notes sections cited)",
            report.count(Grade::Advisory)
        ),
        None => writeln!(out, "result: {failed} check(s) failed: {}", names.join(", ")),
    }
}

/// The terminal report of a run: the header, every check by category with what did not pass (and,
/// with `frames`, each check's frame table), the footer.
pub fn write_text(out: &mut dyn Write, report: &SuiteReport, frames: bool) -> io::Result<()> {
    write_header(out, report.target, report.master, &report.transport, report.timestamps)?;
    let mut category = None;
    for c in &report.checks {
        if category != Some(c.category) {
            write_category(out, c.category)?;
            category = Some(c.category);
        }
        write_check(out, c, report.frames_of(c), report.target, frames)?;
    }
    write_footer(out, report)
}
