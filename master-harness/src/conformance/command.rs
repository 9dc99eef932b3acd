//! The `conformance` command of `dnet-master`: runs the suite on a bus and writes its reports
//! (terminal or JSON, [`super::report`]; HTML, [`super::html`]). It takes the values of the command
//! line it needs ([`ConformanceCommand`]), not the command line itself.

use super::{html, report, SuiteOptions};
use crate::console::Progress;
use crate::error::HarnessError;
use can_io::bus::Bus;
use can_io::log::LogWriter;
use devicenet::{Duration, MacId};
use master_core::master::MasterConfig;
use master_core::session::Session;
use master_core::stop::Stop;
use std::io::Write;
use std::path::Path;

/// What the `conformance` command was asked to do, besides the device.
#[derive(Clone, Debug)]
pub struct ConformanceCommand<'a> {
    /// `--log`: every frame to this file (`candump -L`).
    pub log: Option<&'a Path>,
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
    /// The bus, in `--bus` form (for the reports).
    pub transport: String,
    /// Set by SIGINT / SIGTERM.
    pub stop: Stop,
}

/// `dnet-master conformance --mac N [--html FILE]` on `bus`: runs the suite (with `--log`), prints
/// the report (text, or JSON with `--json`), writes the HTML page. Returns the exit status: 0 when
/// no check failed, 1 otherwise.
pub fn execute(
    run: &ConformanceCommand<'_>,
    bus: &mut dyn Bus,
    mac: MacId,
    out: &mut dyn Write,
    _progress: Progress<'_>,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let mut session = Session::new(bus);
    if let Some(path) = run.log {
        let log = LogWriter::create(path)
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
        session.set_log(log);
    }
    let config = MasterConfig {
        mac: run.master_mac,
        response_timeout: run.response_timeout,
        ..MasterConfig::default()
    };
    let suite = super::run(&mut session, config, &SuiteOptions::new(mac))?;
    session.flush()?;
    if let Some(path) = run.html {
        std::fs::write(path, html::render(&suite))
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
    }
    if run.json {
        writeln!(out, "{}", report::report_json(&suite)).map_err(werr)?;
    } else {
        report::write_text(out, &suite, run.frames).map_err(werr)?;
        if let Some(path) = run.html {
            writeln!(out, "HTML report: {}", path.display()).map_err(werr)?;
        }
    }
    Ok(u8::from(suite.failed() > 0))
}
