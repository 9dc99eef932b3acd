//! The `conformance` command of `dnet-master`: runs the suite on a bus and writes its reports
//! (terminal or JSON, [`super::report`]; HTML, [`super::html`]). It takes the values of the command
//! line it needs ([`ConformanceCommand`]), not the command line itself.
//!
//! What it does, in order:
//!
//! 1. Creates the output files (`--log`, `--html`) before a frame is sent: a path that cannot be
//!    written is an error at once (exit status 2), and no bus time is spent.
//! 2. Runs the suite. In text mode each check's verdict line is printed on standard output as soon
//!    as the check is judged (then the summary at the end); on a terminal a progress line on
//!    standard error says which check runs and what it waits for (`[12/42] watchdog-poll-timed-out:
//!    waiting 4 x EPR …`). With `--json` only the final document is printed.
//! 3. Stops early when no device answers at the MAC after the bring-up (it sent no duplicate MAC ID
//!    check and did not answer the Allocate through the Group 2 Only port): the error names the
//!    MAC, no other check is run, exit status 1.
//! 4. On SIGINT / SIGTERM stops with the checks completed so far: the reports (text or JSON, and
//!    the HTML page) say "interrupted by SIGINT", the log is flushed, the device is released, and
//!    the exit status is 128 + the signal.
//! 5. At the end releases what the suite allocated (unless `--keep`), flushes the log, writes the
//!    HTML page.
//!
//! Timing is judged only where the transport's timestamps show it: on SLCAN (`slcan:…`, frames
//! buffered on a serial line) every timing expectation is advisory with the reason; on the
//! simulated bus and SocketCAN it passes or fails. Every report names the transport and the
//! timestamp source.
//!
//! Exit status: 0 when the suite ran to its end and no check failed (advisories allowed), 1 when a
//! check failed, no device answered or the bus failed, 2 for an output file that cannot be
//! written, 128 + the signal when interrupted.

use super::{html, report, Category, CheckResult, Observer, Stopped, SuiteOptions, CHECKS};
use can_io::bus::Bus;
use can_io::log::LogWriter;
use devicenet::{Duration, MacId};
use harness_common::console::Progress;
use harness_common::error::HarnessError;
use master_core::master::MasterConfig;
use master_core::session::{Record, Session};
use master_core::stop::Stop;
use std::io::Write;
use std::path::Path;

/// What the `conformance` command was asked to do, besides the device.
#[derive(Clone, Debug)]
pub struct ConformanceCommand<'a> {
    /// `--log`: every frame to this file.
    pub log: Option<&'a Path>,
    /// `--format`: the `--log` file's format.
    pub log_format: can_io::trace::TraceFormat,
    /// `--master-mac`.
    pub master_mac: MacId,
    /// `--timeout`: the explicit response timeout.
    pub response_timeout: Duration,
    /// `--json`: the JSON document instead of the terminal report.
    pub json: bool,
    /// `--frames`: each check's frame table in the terminal report.
    pub frames: bool,
    /// `--html FILE`: the HTML page.
    pub html: Option<&'a Path>,
    /// `--keep`: leave the device's connections allocated at the end.
    pub keep: bool,
    /// The bus, in `--bus` form (for the reports, and for what its timestamps can show).
    pub transport: String,
    /// Set by SIGINT / SIGTERM.
    pub stop: Stop,
}

/// Prints each check as it is judged (text mode) and keeps the progress line.
struct Printer<'o, 'p> {
    out: &'o mut dyn Write,
    progress: Progress<'p>,
    /// Text mode (not `--json`).
    text: bool,
    frames: bool,
    device: MacId,
    /// The check running: its number and id.
    current: (usize, &'static str),
    category: Option<Category>,
    /// The first error writing standard output.
    error: Option<std::io::Error>,
}

impl Observer for Printer<'_, '_> {
    fn start(&mut self, n: usize, id: &'static str, title: &'static str) {
        self.current = (n, id);
        self.progress.show(&format!("[{n}/{CHECKS}] {id}: {title}"));
    }

    fn wait(&mut self, what: &str) {
        let (n, id) = self.current;
        self.progress.show(&format!("[{n}/{CHECKS}] {id}: {what} ..."));
    }

    fn judged(&mut self, check: &CheckResult, frames: &[Record]) {
        if !self.text || self.error.is_some() {
            return;
        }
        self.progress.clear();
        let mut write = || -> std::io::Result<()> {
            if self.category != Some(check.category) {
                report::write_category(self.out, check.category)?;
                self.category = Some(check.category);
            }
            report::write_check(self.out, check, frames, self.device, self.frames)?;
            self.out.flush()
        };
        if let Err(e) = write() {
            self.error = Some(e);
        }
    }
}

/// `dnet-master conformance --mac N [--html FILE]` on `bus`: see the [module docs](self). Returns
/// the exit status; an error is returned for an output file that cannot be written, a failing
/// bus and a device that does not answer ([`HarnessError::NoDevice`]).
pub fn execute(
    run: &ConformanceCommand<'_>,
    bus: &mut dyn Bus,
    mac: MacId,
    out: &mut dyn Write,
    progress: Progress<'_>,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let file_err = |path: &Path| {
        let path = path.display().to_string();
        move |source| HarnessError::Write { path, source }
    };
    // The output files first: a path that cannot be written is an error before any frame is sent.
    let log = match run.log {
        Some(path) => Some(LogWriter::create_as(path, run.log_format).map_err(file_err(path))?),
        None => None,
    };
    let mut html_file = match run.html {
        Some(path) => Some(std::fs::File::create(path).map_err(file_err(path))?),
        None => None,
    };
    let mut session = Session::new(bus);
    session.set_stop(run.stop.clone());
    if let Some(log) = log {
        session.set_log(log);
    }
    let config = MasterConfig {
        mac: run.master_mac,
        response_timeout: run.response_timeout,
        ..MasterConfig::default()
    };
    let opts =
        SuiteOptions { transport: Some(run.transport.clone()), keep: run.keep, ..SuiteOptions::new(mac) };
    let timestamps = super::Timestamps::of_transport(&run.transport);
    if !run.json {
        report::write_header(out, mac, run.master_mac, &run.transport, timestamps).map_err(werr)?;
    }
    let mut printer = Printer {
        out: &mut *out,
        progress,
        text: !run.json,
        frames: run.frames,
        device: mac,
        current: (0, ""),
        category: None,
        error: None,
    };
    let suite = super::run_observed(&mut session, config, &opts, &mut printer);
    printer.progress.clear();
    let printed = printer.error.take();
    drop(printer);
    // The stop is taken off the session: what follows (the flush, the reports) is not cut short.
    let _ = session.take_stop();
    let flushed = session.flush();
    let suite = match suite {
        Ok(s) => s,
        Err(e) => {
            // Nothing to report (the bus failed): no empty page is left behind.
            if let (Some(path), Some(file)) = (run.html, html_file.take()) {
                drop(file);
                let _ = std::fs::remove_file(path);
            }
            flushed?;
            return Err(e);
        }
    };
    flushed?;
    if let (Some(path), Some(file)) = (run.html, &mut html_file) {
        file.write_all(html::render(&suite).as_bytes()).map_err(file_err(path))?;
    }
    if let Some(e) = printed {
        return Err(werr(e));
    }
    let no_device = match &suite.stopped {
        Some(Stopped::NoDevice { mac, detail }) => {
            Some(HarnessError::NoDevice { mac: *mac, detail: detail.clone() })
        }
        _ => None,
    };
    if run.json {
        // No device: the error document is the command line's (`{"ok": false, "error": …}`).
        if no_device.is_none() {
            writeln!(out, "{}", report::report_json(&suite)).map_err(werr)?;
        }
    } else {
        report::write_footer(out, &suite).map_err(werr)?;
        if let Some(path) = run.html {
            writeln!(out, "HTML report: {}", path.display()).map_err(werr)?;
        }
    }
    match (&suite.stopped, no_device) {
        (_, Some(e)) => Err(e),
        (Some(Stopped::Interrupted(signal)), _) => Ok(master_core::stop::exit_status(*signal)),
        _ => Ok(u8::from(suite.failed() > 0)),
    }
}
