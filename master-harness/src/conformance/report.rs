//! The suite's reports: the terminal report and the JSON document (the HTML page is
//! [`super::html`]'s; the command that writes them is [`super::command`]'s).

use super::{Category, CheckResult, Grade, SuiteReport};
use crate::table::{print_table, record_json, RecordJson};
use devicenet::Duration;
use serde_json::json;
use std::io::{self, Write};

/// The whole report as JSON: summary, every check with its expectations, measurements and frames.
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
    json!({
        "ok": report.failed() == 0,
        "device": report.target.as_raw(),
        "master": report.master.as_raw(),
        "second_master": report.second_master.as_raw(),
        "bus": report.bus,
        "bus_time_us": report.duration.total_micros(),
        "summary": {
            "checks": report.checks.len(),
            "pass": report.count(Grade::Pass),
            "advisory": report.count(Grade::Advisory),
            "fail": report.count(Grade::Fail),
            "frames": report.records.len(),
        },
        "checks": checks,
    })
}

/// A bus time in seconds.
pub(crate) fn seconds(d: Duration) -> String {
    format!("{:.1} s", d.total_micros() as f64 / 1e6)
}

/// The one-line summary.
pub fn summary_line(report: &SuiteReport) -> String {
    format!(
        "conformance of MAC {} on {}, master MAC {} (second master {}): {} checks, {} pass, {} advisory, {} fail; {} frames, {} of bus time",
        report.target,
        report.bus,
        report.master,
        report.second_master,
        report.checks.len(),
        report.count(Grade::Pass),
        report.count(Grade::Advisory),
        report.count(Grade::Fail),
        report.records.len(),
        seconds(report.duration)
    )
}

fn write_check(out: &mut dyn Write, report: &SuiteReport, c: &CheckResult, frames: bool) -> io::Result<()> {
    writeln!(out, "  {:<9} {:<30} {}  [{}]", c.grade.label(), c.id, c.title, c.section)?;
    for e in c.findings() {
        writeln!(out, "  {:<9}   - {}: {}", "", e.grade.label().to_lowercase(), e.text)?;
    }
    for m in &c.measurements {
        if c.category == Category::Timing || m.unit == "ms" && c.id.starts_with("watchdog") {
            writeln!(out, "  {:<9}   · {}: {:.3} {}", "", m.name, m.value, m.unit)?;
        }
    }
    if frames {
        let recs = report.frames_of(c);
        if !recs.is_empty() {
            print_table(out, recs, Some(report.target))?;
            writeln!(out)?;
        }
    }
    Ok(())
}

/// The terminal report: a summary, then every check by category with what did not pass (and, with
/// `frames`, each check's frame table).
pub fn write_text(out: &mut dyn Write, report: &SuiteReport, frames: bool) -> io::Result<()> {
    writeln!(out, "{}", summary_line(report))?;
    for cat in Category::ALL {
        let checks: Vec<&CheckResult> = report.checks.iter().filter(|c| c.category == cat).collect();
        if checks.is_empty() {
            continue;
        }
        writeln!(out, "\n{}", cat.title())?;
        for c in checks {
            write_check(out, report, c, frames)?;
        }
    }
    let failed = report.failed();
    writeln!(out)?;
    if failed == 0 {
        writeln!(
            out,
            "result: no check failed ({} advisory: see the notes sections cited)",
            report.count(Grade::Advisory)
        )
    } else {
        let names: Vec<&str> =
            report.checks.iter().filter(|c| c.grade == Grade::Fail).map(|c| c.id).collect();
        writeln!(out, "result: {failed} check(s) failed: {}", names.join(", "))
    }
}
