//! `dnet-master --bus sim conformance --self-test`: proves that every check of the suite can fail.
//!
//! The suite runs on the simulated bus against the reference soft slave (every check must pass or
//! be advisory), then against each mutant of [`MUTANTS`] (the reference device with one deliberate
//! fault, [`super::mutants`]), and the result is a matrix, check × mutant: which checks failed
//! against which mutant. The self-test passes only when
//!
//! - the reference device passes (no check fails, the run completes),
//! - every mutant fails its target check ("caught"), and
//! - every check of the suite fails against at least one mutant.
//!
//! A check that no mutant makes fail is one that has only ever been seen to pass: nobody can tell
//! it apart from a check that cannot fail.
//!
//! ```
//! use master_core::master::MasterConfig;
//! use dnet_conformance::self_test;
//! use can_io::bus::Bitrate;
//!
//! let report = self_test::run(MasterConfig::default(), Bitrate::K250, &mut ()).unwrap();
//! assert!(report.passed(), "{:?}", report.uncaught_checks());
//! ```

use super::mutants::{Mutant, MUTANTS};
use super::{run as run_suite, Grade, SuiteOptions, SuiteReport};
use can_io::bus::Bitrate;
use can_io::sim::{PowerOn, SimBus, SimDevice};
use converter_sim::device::SoftSlave;
use devicenet::MacId;
use harness_common::error::HarnessError;
use master_core::master::MasterConfig;
use master_core::session::Session;
use serde_json::{json, Value};
use std::io::{self, Write};

/// The MAC of the device under test in the self-test.
pub const DEVICE_MAC: u8 = 5;

/// The suite's run against one device: what failed, what was advisory, whether it completed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunSummary {
    /// The checks run, in order.
    pub checks: Vec<&'static str>,
    /// The checks that failed.
    pub failed: Vec<&'static str>,
    /// The checks graded advisory.
    pub advisory: Vec<&'static str>,
    /// Why the run ended early, if it did.
    pub stopped: Option<String>,
    /// Frames of the run.
    pub frames: usize,
    /// Bus time of the run.
    pub bus_time: devicenet::Duration,
    /// For each failed check, the texts of its failed expectations.
    pub findings: Vec<(&'static str, Vec<String>)>,
}

impl RunSummary {
    fn of(report: &SuiteReport) -> RunSummary {
        let ids = |g: Grade| report.checks.iter().filter(|c| c.grade == g).map(|c| c.id).collect();
        RunSummary {
            checks: report.checks.iter().map(|c| c.id).collect(),
            failed: ids(Grade::Fail),
            advisory: ids(Grade::Advisory),
            stopped: report.stopped.as_ref().map(|s| s.text()),
            frames: report.records.len(),
            bus_time: report.duration,
            findings: report
                .checks
                .iter()
                .filter(|c| c.grade == Grade::Fail)
                .map(|c| {
                    let texts =
                        c.expectations.iter().filter(|e| e.grade == Grade::Fail).map(|e| e.text.clone());
                    (c.id, texts.collect())
                })
                .collect(),
        }
    }
}

/// One mutant and how the suite judged it.
#[derive(Clone, Debug)]
pub struct MutantOutcome {
    /// The mutant.
    pub mutant: &'static Mutant,
    /// The suite's run against it.
    pub run: RunSummary,
}

impl MutantOutcome {
    /// Its target check failed.
    #[must_use]
    pub fn caught(&self) -> bool {
        self.run.failed.contains(&self.mutant.target)
    }

    /// Why its target check failed: the texts of the failed expectations.
    #[must_use]
    pub fn evidence(&self) -> &[String] {
        self.run.findings.iter().find(|(c, _)| *c == self.mutant.target).map_or(&[], |(_, t)| t.as_slice())
    }
}

/// The whole self-test.
#[derive(Clone, Debug)]
pub struct SelfTestReport {
    /// The suite against the reference device.
    pub reference: RunSummary,
    /// The suite against each mutant, in [`MUTANTS`] order.
    pub mutants: Vec<MutantOutcome>,
}

impl SelfTestReport {
    /// The checks of the suite, in order (as run against the reference device).
    #[must_use]
    pub fn checks(&self) -> &[&'static str] {
        &self.reference.checks
    }

    /// The mutants against which `check` failed.
    #[must_use]
    pub fn caught_by(&self, check: &str) -> Vec<&'static str> {
        self.mutants.iter().filter(|m| m.run.failed.contains(&check)).map(|m| m.mutant.id).collect()
    }

    /// The checks no mutant made fail.
    #[must_use]
    pub fn uncaught_checks(&self) -> Vec<&'static str> {
        self.checks().iter().copied().filter(|c| self.caught_by(c).is_empty()).collect()
    }

    /// The mutants whose target check did not fail.
    #[must_use]
    pub fn surviving_mutants(&self) -> Vec<&'static str> {
        self.mutants.iter().filter(|m| !m.caught()).map(|m| m.mutant.id).collect()
    }

    /// The reference device passed the whole suite.
    #[must_use]
    pub fn reference_passed(&self) -> bool {
        self.reference.stopped.is_none() && self.reference.failed.is_empty()
    }

    /// The self-test passed: the reference passes, every mutant is caught by its target, every
    /// check is caught by at least one mutant.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.reference_passed() && self.surviving_mutants().is_empty() && self.uncaught_checks().is_empty()
    }
}

/// Follows the self-test run by run.
pub trait SelfTestObserver {
    /// Run `n` of `total` starts: the reference (`None`) or a mutant.
    fn start(&mut self, _n: usize, _total: usize, _mutant: Option<&Mutant>) {}
}

impl SelfTestObserver for () {}

/// The suite on a fresh simulated bus at `bitrate` with `device` at [`DEVICE_MAC`].
fn run_against(
    device: Box<dyn SimDevice>,
    config: MasterConfig,
    bitrate: Bitrate,
) -> Result<RunSummary, HarnessError> {
    let mut bus = SimBus::new(bitrate);
    bus.attach(device, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let report = run_suite(&mut session, config, &SuiteOptions::new(device_mac()))?;
    Ok(RunSummary::of(&report))
}

fn device_mac() -> MacId {
    MacId::from_low_bits(DEVICE_MAC)
}

/// Runs the suite against the reference device and every mutant, as a master with `config`.
pub fn run(
    config: MasterConfig,
    bitrate: Bitrate,
    observer: &mut dyn SelfTestObserver,
) -> Result<SelfTestReport, HarnessError> {
    let all: Vec<&Mutant> = MUTANTS.iter().collect();
    run_mutants(config, bitrate, &all, observer)
}

/// Runs the suite against the reference device and the given mutants (a subset of [`MUTANTS`]: a
/// check none of them catches is reported uncaught).
pub fn run_mutants(
    config: MasterConfig,
    bitrate: Bitrate,
    mutants: &[&'static Mutant],
    observer: &mut dyn SelfTestObserver,
) -> Result<SelfTestReport, HarnessError> {
    if config.mac == device_mac() {
        return Err(HarnessError::SelfTestMasterMac { mac: device_mac() });
    }
    let total = mutants.len() + 1;
    observer.start(1, total, None);
    let reference = run_against(Box::new(SoftSlave::reference(device_mac())), config.clone(), bitrate)?;
    let mut outcomes = Vec::new();
    for (k, &mutant) in mutants.iter().enumerate() {
        observer.start(k + 2, total, Some(mutant));
        let run = run_against(Box::new(mutant.device(device_mac())), config.clone(), bitrate)?;
        outcomes.push(MutantOutcome { mutant, run });
    }
    Ok(SelfTestReport { reference, mutants: outcomes })
}

/// The terminal report: the reference run, each mutant with what it made fail, each check with
/// the mutants that catch it, and the verdict.
pub fn write_text(out: &mut dyn Write, report: &SelfTestReport) -> io::Result<()> {
    let r = &report.reference;
    writeln!(
        out,
        "reference device (MAC {DEVICE_MAC}): {} checks, {} fail, {} advisory{}",
        r.checks.len(),
        r.failed.len(),
        r.advisory.len(),
        r.stopped.as_ref().map(|s| format!(", stopped: {s}")).unwrap_or_default()
    )?;
    if !r.failed.is_empty() {
        writeln!(out, "  FAILED against the reference device: {}", r.failed.join(", "))?;
    }
    writeln!(out, "\nmutants ({}): each must fail its target check", report.mutants.len())?;
    let width = report.mutants.iter().map(|m| m.mutant.id.len()).max().unwrap_or(0);
    for (k, m) in report.mutants.iter().enumerate() {
        let others: Vec<&str> = m.run.failed.iter().copied().filter(|c| *c != m.mutant.target).collect();
        writeln!(
            out,
            "{:>3} {:<6} {:<width$}  {} -> {}{}",
            k + 1,
            if m.caught() { "caught" } else { "ALIVE" },
            m.mutant.id,
            m.mutant.fault,
            m.mutant.target,
            if others.is_empty() { String::new() } else { format!(" (also fails: {})", others.join(", ")) },
        )?;
        if let Some(first) = m.evidence().first() {
            writeln!(out, "    {:<6} {:<width$}  {first}", "", "")?;
        }
    }
    write_matrix(out, report)?;
    writeln!(out, "\nchecks ({}): each must fail against at least one mutant", report.checks().len())?;
    let width = report.checks().iter().map(|c| c.len()).max().unwrap_or(0);
    for check in report.checks() {
        let by = report.caught_by(check);
        writeln!(
            out,
            "  {:<9} {check:<width$}  {}",
            if by.is_empty() { "NOT CAUGHT" } else { "caught" },
            if by.is_empty() { "no mutant makes it fail".to_string() } else { by.join(", ") }
        )?;
    }
    let surviving = report.surviving_mutants();
    let uncaught = report.uncaught_checks();
    let runs = std::iter::once(&report.reference).chain(report.mutants.iter().map(|m| &m.run));
    let (frames, micros) = runs.fold((0, 0), |(f, t), r| (f + r.frames, t + r.bus_time.total_micros()));
    writeln!(
        out,
        "\n{} suite runs: {frames} frames, {:.0} s of bus time",
        report.mutants.len() + 1,
        micros as f64 / 1e6
    )?;
    writeln!(
        out,
        "self-test: {} of {} checks caught, {} of {} mutants caught by their target, reference {}",
        report.checks().len() - uncaught.len(),
        report.checks().len(),
        report.mutants.len() - surviving.len(),
        report.mutants.len(),
        if report.reference_passed() { "passes" } else { "FAILS" },
    )?;
    if !uncaught.is_empty() {
        writeln!(out, "checks no mutant makes fail: {}", uncaught.join(", "))?;
    }
    if !surviving.is_empty() {
        writeln!(out, "mutants their target check does not catch: {}", surviving.join(", "))?;
    }
    writeln!(out, "result: {}", if report.passed() { "every check can fail" } else { "FAILED" })
}

/// The matrix, check x mutant: a column per mutant (numbered as listed), `#` where the check is the
/// mutant's target and fails, `X` where another check fails, `!` where the target check passes
/// (the mutant is not caught), `.` where the check passes.
fn write_matrix(out: &mut dyn Write, report: &SelfTestReport) -> io::Result<()> {
    let width = report.checks().iter().map(|c| c.len()).max().unwrap_or(0).max(6);
    writeln!(
        out,
        "\nmatrix, check x mutant (#: its target check fails, X: another check fails, !: its target passes)"
    )?;
    for digit in [100, 10, 1] {
        if report.mutants.len() < digit && digit > 1 {
            continue;
        }
        let row: String = (1..=report.mutants.len())
            .map(|n| if n >= digit || digit == 1 { char::from(b'0' + (n / digit % 10) as u8) } else { ' ' })
            .collect();
        writeln!(out, "  {:<width$}  {row}", if digit == 1 { "mutant" } else { "" })?;
    }
    for check in report.checks() {
        let row: String = report
            .mutants
            .iter()
            .map(|m| match (m.mutant.target == *check, m.run.failed.contains(check)) {
                (true, true) => '#',
                (true, false) => '!',
                (false, true) => 'X',
                (false, false) => '.',
            })
            .collect();
        writeln!(out, "  {check:<width$}  {row}")?;
    }
    Ok(())
}

/// The JSON document: the reference run, every mutant, and per check the mutants that catch it.
#[must_use]
pub fn report_json(report: &SelfTestReport) -> Value {
    let run = |r: &RunSummary| {
        json!({
            "checks": r.checks.len(),
            "failed": r.failed,
            "advisory": r.advisory,
            "stopped": r.stopped,
            "frames": r.frames,
            "bus_time_us": r.bus_time.total_micros(),
        })
    };
    json!({
        "ok": report.passed(),
        "reference": {
            "mac": DEVICE_MAC,
            "passed": report.reference_passed(),
            "run": run(&report.reference),
        },
        "mutants": report.mutants.iter().map(|m| json!({
            "id": m.mutant.id,
            "fault": m.mutant.fault,
            "target": m.mutant.target,
            "caught": m.caught(),
            "evidence": m.evidence(),
            "run": run(&m.run),
        })).collect::<Vec<_>>(),
        "checks": report.checks().iter().map(|c| json!({
            "id": c,
            "caught_by": report.caught_by(c),
        })).collect::<Vec<_>>(),
        "uncaught_checks": report.uncaught_checks(),
        "surviving_mutants": report.surviving_mutants(),
    })
}

/// The matrix as the guide shows it (docs/src/test-engineer/conformance-self-test.md) (Markdown):
/// per check, the mutants that make it fail; per
/// mutant, its fault and every check that fails against it.
#[must_use]
pub fn markdown(report: &SelfTestReport) -> String {
    let mut s = String::new();
    s.push_str("| check | caught by (mutants against which it fails) |\n|---|---|\n");
    for check in report.checks() {
        let by = report.caught_by(check);
        let cell = if by.is_empty() {
            "**not caught**".to_string()
        } else {
            by.iter().map(|m| format!("`{m}`")).collect::<Vec<_>>().join(", ")
        };
        s.push_str(&format!("| `{check}` | {cell} |\n"));
    }
    s.push_str("\n| mutant | fault | target | checks that fail |\n|---|---|---|---|\n");
    for m in &report.mutants {
        let failed = m.run.failed.iter().map(|c| format!("`{c}`")).collect::<Vec<_>>().join(", ");
        s.push_str(&format!(
            "| `{}` | {} | `{}` {} | {} |\n",
            m.mutant.id,
            m.mutant.fault,
            m.mutant.target,
            if m.caught() { "caught" } else { "**alive**" },
            failed
        ));
    }
    s
}

/// The self-test as a stand-alone HTML page: the verdict, the matrix (a row per check, a column
/// per mutant, each cell saying whether the check failed against the mutant), and per mutant its
/// fault, its target and the finding that caught it.
pub fn render_html(report: &SelfTestReport) -> String {
    use super::html::{escape, STYLE};
    use std::fmt::Write as _;
    let mut s = String::new();
    let title = "DeviceNet conformance suite: self-test against mutant devices";
    let _ = write!(
        s,
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\"><title>{title}</title><style>{STYLE}\
         table.matrix td{{padding:0;width:1.3em;text-align:center;font-family:ui-monospace,monospace}}\
         td.t{{background:#2e7d32;color:#fff}} td.x{{background:#c5e1a5}} td.alive{{background:#c62828;color:#fff}}\
         tr.uncaught th{{color:#c62828}}</style></head><body><h1>{title}</h1>"
    );
    let verdict = if report.passed() { ("pass", "PASS: every check can fail") } else { ("fail", "FAIL") };
    let _ = write!(
        s,
        "<p class=\"verdict\"><span class=\"grade {}\">{}</span> {} of {} checks caught by at least one mutant; {} of {} mutants caught by their target check; the reference device {}.</p>",
        verdict.0,
        verdict.1,
        report.checks().len() - report.uncaught_checks().len(),
        report.checks().len(),
        report.mutants.len() - report.surviving_mutants().len(),
        report.mutants.len(),
        if report.reference_passed() { "passes every check" } else { "FAILS" },
    );
    let _ = write!(
        s,
        "<p class=\"section\">dnet-master {} on the simulated bus; the device at MAC {DEVICE_MAC}. Each mutant is the reference device with one deliberate fault. A green cell: the mutant's target check fails against it; a light cell: another check fails against it; a red cell: its target check passed (the mutant is not caught).</p>",
        escape(harness_common::version())
    );
    s.push_str("<h2>Matrix</h2><table class=\"matrix\"><tr><th>check</th>");
    for (k, m) in report.mutants.iter().enumerate() {
        let _ = write!(s, "<th title=\"{}: {}\">{}</th>", escape(m.mutant.id), escape(m.mutant.fault), k + 1);
    }
    s.push_str("</tr>");
    for check in report.checks() {
        let uncaught = report.caught_by(check).is_empty();
        let _ = write!(
            s,
            "<tr{}><th><code>{}</code></th>",
            if uncaught { " class=\"uncaught\"" } else { "" },
            escape(check)
        );
        for m in &report.mutants {
            let (class, mark) = match (m.mutant.target == *check, m.run.failed.contains(check)) {
                (true, true) => ("t", "#"),
                (true, false) => ("alive", "!"),
                (false, true) => ("x", "X"),
                (false, false) => ("", ""),
            };
            let _ = write!(s, "<td class=\"{class}\" title=\"{}\">{mark}</td>", escape(m.mutant.id));
        }
        s.push_str("</tr>");
    }
    s.push_str("</table><h2>Mutants</h2><table><tr><th>#</th><th>mutant</th><th>fault</th><th>target</th><th>finding</th><th>also fails</th></tr>");
    for (k, m) in report.mutants.iter().enumerate() {
        let others: Vec<&str> = m.run.failed.iter().copied().filter(|c| *c != m.mutant.target).collect();
        let _ = write!(
            s,
            "<tr><td>{}</td><td><code>{}</code></td><td>{}</td><td><code>{}</code> <span class=\"grade {}\">{}</span></td><td>{}</td><td>{}</td></tr>",
            k + 1,
            escape(m.mutant.id),
            escape(m.mutant.fault),
            escape(m.mutant.target),
            if m.caught() { "pass" } else { "fail" },
            if m.caught() { "caught" } else { "ALIVE" },
            escape(m.evidence().first().map_or("", String::as_str)),
            escape(&others.join(", ")),
        );
    }
    s.push_str("</table></body></html>\n");
    s
}
