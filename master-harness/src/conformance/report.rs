//! The suite's reports: the terminal report, the JSON document, and the `conformance` command of
//! `dnet-master` that runs the suite and writes them (and the HTML page, [`super::html`]).

use super::{Category, CheckResult, Grade, SuiteOptions, SuiteReport};
use crate::cli::{print_table, record_json, Cli, RecordJson};
use crate::error::HarnessError;
use can_io::bus::Bus;
use can_io::log::LogWriter;
use devicenet::{Duration, MacId};
use master_core::master::MasterConfig;
use master_core::session::Session;
use serde_json::json;
use std::io::{self, Write};
use std::path::Path;

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

/// `dnet-master conformance --mac N [--html FILE]` on the bus the options opened: runs the suite
/// (with `--log`), prints the report (text, or JSON with `--json`), writes the HTML page. Returns
/// the exit status: 0 when no check failed, 1 otherwise.
pub fn execute(
    cli: &Cli,
    bus: &mut dyn Bus,
    mac: MacId,
    html: Option<&Path>,
    out: &mut dyn Write,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let mut session = Session::new(bus);
    if let Some(path) = &cli.log {
        let log = LogWriter::create(path)
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
        session.set_log(log);
    }
    let config = MasterConfig {
        mac: cli.master_mac,
        response_timeout: Duration::from_millis(cli.timeout.max(1)),
        ..MasterConfig::default()
    };
    let report = super::run(&mut session, config, &SuiteOptions::new(mac))?;
    session.flush()?;
    if let Some(path) = html {
        std::fs::write(path, super::html::render(&report))
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
    }
    if cli.json {
        writeln!(out, "{}", report_json(&report)).map_err(werr)?;
    } else {
        write_text(out, &report, cli.frames).map_err(werr)?;
        if let Some(path) = html {
            writeln!(out, "HTML report: {}", path.display()).map_err(werr)?;
        }
    }
    Ok(u8::from(report.failed() > 0))
}
