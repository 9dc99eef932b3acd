//! How a command that talks to one device runs, whatever the command: the bus opened (with
//! `--pcap`), the session with its stop and its `--log`, the master; then the command's own work
//! ([`DeviceRun::run`]'s body); then, however it ended, what it allocated released (not with
//! `--keep`; not when the bus itself failed), the files flushed and the result printed, as text or
//! as one JSON object.
//!
//! Exit status: the command's own, else 1 when a frame check failed; an error's own status
//! ([`HarnessError::exit_code`]) when it failed; a clean-up error's when the command succeeded.

use crate::options::{open_bus_with_pcap, GlobalOptions};
use crate::replay;
use can_io::log::LogWriter;
use can_io::trace::TraceFormat;
use devicenet::MacId;
use harness_common::console::{Console, Progress};
use harness_common::error::HarnessError;
use harness_common::table::{print_table, record_json, RecordJson};
use master_core::error::MasterError;
use master_core::master::Master;
use master_core::session::{Record, Session};
use serde_json::json;
use slave_fw::converter::ConverterConfig;
use slave_fw::description::DeviceDescription;
use std::io::Write;

/// What a command produced, for printing.
pub struct Outcome {
    /// The command's own result, as JSON (merged into the run's object).
    pub json: serde_json::Value,
    /// The command's own result, as text lines.
    pub text: String,
    /// Exit status.
    pub code: u8,
}

/// How a command's own work ended.
pub struct Ran {
    /// Its result.
    pub result: Result<Outcome, HarnessError>,
    /// What it produced before it failed or was interrupted (monitor's samples).
    pub partial: Option<Outcome>,
    /// Its own files that could not be flushed (monitor's CSV).
    pub cleanup: Vec<HarnessError>,
}

impl From<Result<Outcome, HarnessError>> for Ran {
    fn from(result: Result<Outcome, HarnessError>) -> Ran {
        Ran { result, partial: None, cleanup: Vec::new() }
    }
}

/// The device a command addresses when `--mac` is left out: the MAC of the description the
/// command was given (`monitor --description`), else of `--slave-config`'s, else 5 (the reference
/// converter's).
#[must_use]
pub fn default_device(own: Option<&DeviceDescription>, slave: Option<&DeviceDescription>) -> MacId {
    own.or(slave).map_or(MacId::from_low_bits(5), |d| d.converter.device.mac_id)
}

/// A run against one device, its defaults resolved before the bus is touched.
pub struct DeviceRun<'a> {
    /// The options of every command.
    pub opts: &'a GlobalOptions,
    /// The device addressed (`None`: the command addresses no single device, `scan`).
    pub device: Option<MacId>,
    /// The master's MAC.
    pub master_mac: MacId,
    /// `--slave-config`'s converter, for the simulated devices.
    pub slave: Option<&'a ConverterConfig>,
    /// How a replayed transcript meets its simulated device.
    pub replay_power_on: Option<replay::SimStart>,
    /// Print the frame-by-frame table even without `--frames` (connect, replay, recover).
    pub show_table: bool,
}

impl DeviceRun<'_> {
    /// A run at `device` with the master at `--master-mac` (else 0): refused when the two are the
    /// same MAC.
    pub fn new<'a>(
        opts: &'a GlobalOptions,
        device: Option<MacId>,
        slave: Option<&'a DeviceDescription>,
    ) -> Result<DeviceRun<'a>, HarnessError> {
        DeviceRun::with_master(opts, device, opts.master_mac_or_default(), slave)
    }

    /// A run at `device` with the master at `master_mac`: refused when the two are the same MAC.
    pub fn with_master<'a>(
        opts: &'a GlobalOptions,
        device: Option<MacId>,
        master_mac: MacId,
        slave: Option<&'a DeviceDescription>,
    ) -> Result<DeviceRun<'a>, HarnessError> {
        if device == Some(master_mac) {
            return Err(HarnessError::DeviceIsMaster { mac: master_mac });
        }
        Ok(DeviceRun {
            opts,
            device,
            master_mac,
            slave: slave.map(|d| &d.converter),
            replay_power_on: None,
            show_table: false,
        })
    }

    /// Opens the bus and the session, runs `body` with the master, then releases, flushes and
    /// prints (module docs). Returns the exit status; an error that ended the command is returned
    /// (and printed by the caller) in text mode, printed in the JSON object with `--json`.
    pub fn run(
        self,
        out: &mut dyn Write,
        err: &mut dyn Write,
        console: &Console,
        body: impl FnOnce(&mut Master<'_, '_>, &mut Progress<'_>, &mut dyn Write) -> Ran,
    ) -> Result<u8, HarnessError> {
        let opts = self.opts;
        let mut bus = open_bus_with_pcap(opts, self.slave, self.device, self.replay_power_on)?;
        let mut session = Session::new(bus.as_mut());
        session.set_stop(console.stop.clone());
        if let Some(path) = &opts.log {
            let log = LogWriter::create_as(path, opts.format.unwrap_or(TraceFormat::Candump))
                .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
            session.set_log(log);
        }
        let mut master = Master::new(&mut session, opts.master_config(self.master_mac));
        let mut progress =
            if console.stderr_terminal && !opts.json { Progress::on(&mut *err) } else { Progress::off() };
        let mut ran = body(&mut master, &mut progress, out);
        drop(progress);
        let interrupted = ran.result.as_ref().err().and_then(HarnessError::interrupted_by);
        let released = self.release(&mut master, &ran.result, interrupted, &mut ran.cleanup);
        let notices: Vec<String> = master.notices().to_vec();
        if let Err(e) = session.flush() {
            ran.cleanup.push(e.into());
        }
        let ended = Ended { ran, released, notices, interrupted };
        self.report(ended, &session, out, err)
    }

    /// Gives the device back what the command allocated, unless `--keep` or the bus failed; the
    /// text that says what was kept or released (empty when there is nothing to say).
    fn release(
        &self,
        master: &mut Master<'_, '_>,
        result: &Result<Outcome, HarnessError>,
        interrupted: Option<i32>,
        cleanup: &mut Vec<HarnessError>,
    ) -> String {
        // The stop is taken off the session, so the release below runs to its end.
        let _ = master.session.take_stop();
        let bus_failed = matches!(result, Err(HarnessError::Master(MasterError::Bus(_))));
        if self.opts.keep {
            return match self.device.filter(|d| !master.held(*d).is_empty()) {
                Some(d) => format!(
                    "MAC {d}: {} kept allocated to master MAC {} (--keep)",
                    master.held(d),
                    self.master_mac
                ),
                None => String::new(),
            };
        }
        if bus_failed {
            return String::new();
        }
        match master.release_held() {
            Ok(released) if !released.is_empty() && interrupted.is_some() => {
                let macs: Vec<String> = released.iter().map(ToString::to_string).collect();
                format!("released MAC {}", macs.join(", "))
            }
            Ok(_) => String::new(),
            Err(e) => {
                cleanup.push(HarnessError::Release(Box::new(e)));
                String::new()
            }
        }
    }

    /// Prints the run's end: the JSON object, or the table, the result and the errors as text.
    fn report(
        &self,
        ended: Ended,
        session: &Session<'_>,
        out: &mut dyn Write,
        err: &mut dyn Write,
    ) -> Result<u8, HarnessError> {
        let werr = |source| HarnessError::Write { path: "standard output".into(), source };
        let Ended { ran, released, notices, interrupted } = ended;
        let failures = session.failures();
        let records = session.records();
        let (mut code, error, payload) = match ran.result {
            Ok(o) => (o.code, None, Some(o)),
            Err(e) => (e.exit_code(), Some(e), ran.partial),
        };
        if failures > 0 && code == 0 {
            code = 1;
        }
        if code == 0 {
            if let Some(e) = ran.cleanup.first() {
                code = e.exit_code();
            }
        }
        for n in &notices {
            writeln!(err, "note: {n}").map_err(werr)?;
        }
        let printed = Printed { code, failures, records, payload: payload.as_ref(), error: error.as_ref() };
        if self.opts.json {
            let v = self.json(&printed, &notices, interrupted, &ran.cleanup);
            writeln!(out, "{v}").map_err(werr)?;
        } else {
            self.text(&printed, out).map_err(werr)?;
            if !released.is_empty() {
                writeln!(err, "{released}").map_err(werr)?;
            }
            for e in &ran.cleanup {
                writeln!(err, "error: {e}").map_err(werr)?;
            }
            if let Some(signal) = interrupted {
                writeln!(
                    err,
                    "interrupted by {}: {} frames recorded{}",
                    master_core::stop::signal_name(signal),
                    records.len(),
                    if self.opts.log.is_some() { ", log flushed" } else { "" }
                )
                .map_err(werr)?;
            }
        }
        match error {
            Some(e) if !self.opts.json && interrupted.is_none() => Err(e),
            _ => Ok(code),
        }
    }

    /// The run's one JSON object: `ok`, `failures`, `frames`, `version`, `notices`, the command's
    /// own keys, then `interrupted`, `error` (`divergence`) and `cleanup_errors` when there are.
    fn json(
        &self,
        p: &Printed<'_>,
        notices: &[String],
        interrupted: Option<i32>,
        cleanup: &[HarnessError],
    ) -> serde_json::Value {
        let frames: Vec<RecordJson<'_>> = p.records.iter().map(|r| record_json(r, self.device)).collect();
        let mut v = json!({
            "ok": p.code == 0,
            "failures": p.failures,
            "frames": frames,
            "version": harness_common::version(),
            "notices": notices,
        });
        if let Some(payload) = p.payload {
            if let (Some(obj), Some(extra)) = (v.as_object_mut(), payload.json.as_object()) {
                for (k, val) in extra {
                    obj.insert(k.clone(), val.clone());
                }
            }
        }
        if let Some(signal) = interrupted {
            v["interrupted"] = json!(master_core::stop::signal_name(signal));
        }
        if let Some(e) = p.error {
            v["error"] = json!(e.to_string());
            if let HarnessError::Divergence(d) = e {
                v["divergence"] = json!(d);
            }
        }
        if !cleanup.is_empty() {
            v["cleanup_errors"] = json!(cleanup.iter().map(ToString::to_string).collect::<Vec<_>>());
        }
        v
    }

    /// The text on standard output: the table (with `--frames`, or for connect, replay and
    /// recover), the command's result, the failed checks or that every check holds.
    fn text(&self, p: &Printed<'_>, out: &mut dyn Write) -> std::io::Result<()> {
        let show_table = self.opts.frames || self.show_table;
        if show_table {
            print_table(out, p.records, self.device)?;
            writeln!(out)?;
        }
        if let Some(payload) = p.payload.filter(|p| !p.text.is_empty()) {
            writeln!(out, "{}", payload.text)?;
        }
        if p.failures > 0 {
            writeln!(out, "{} frame check(s) failed:", p.failures)?;
            for r in p.records.iter().filter(|r| r.verdict.is_failure()) {
                writeln!(out, "  #{} {}: {}", r.index, r.frame, r.verdict.label())?;
            }
        } else if p.error.is_none() && show_table {
            writeln!(out, "{} frames, every check holds", p.records.len())?;
        }
        Ok(())
    }
}

/// A run that ended: the command's work, what the release said, the master's notices, the
/// signal that stopped it.
struct Ended {
    ran: Ran,
    released: String,
    notices: Vec<String>,
    interrupted: Option<i32>,
}

/// What the report prints, with the exit status worked out.
struct Printed<'a> {
    code: u8,
    failures: usize,
    records: &'a [Record],
    payload: Option<&'a Outcome>,
    error: Option<&'a HarnessError>,
}
