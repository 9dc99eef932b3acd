//! `dnet-master conformance`: the conformance suite ([`dnet_conformance`]) against the device on
//! any bus, each verdict printed as it is judged; `--self-test` proves on the simulated bus that
//! every check can fail.

use crate::options::{create_output, open_bus_with_pcap, parse_mac, GlobalOptions};
use crate::run::{default_device, DeviceRun};
use can_io::bus::BusSpec;
use can_io::trace::TraceFormat;
use clap::Args;
use devicenet::{Duration, MacId};
use dnet_conformance::command::ConformanceCommand;
use harness_common::console::{Console, Progress};
use harness_common::error::HarnessError;
use std::io::Write;
use std::path::PathBuf;

/// What `conformance` was asked.
#[derive(Args, Clone, Debug)]
pub struct ConformanceArgs {
    /// The device's MAC ID [default: the --slave-config description's, else 5].
    #[arg(long, value_parser = parse_mac)]
    pub mac: Option<MacId>,
    /// Also write a self-contained HTML report with a sequence diagram per check (with
    /// --self-test: the matrix and every mutant's finding).
    #[arg(long, value_name = "FILE")]
    pub html: Option<PathBuf>,
    /// Prove that every check can fail: run the suite on the simulated bus against the
    /// reference device and against mutant devices, each with one deliberate fault, and print
    /// the matrix check x mutant (exit 0 only when every check fails against at least one
    /// mutant, every mutant fails its target check and the reference device passes).
    #[arg(long, conflicts_with = "mac")]
    pub self_test: bool,
    /// With --self-test: print the matrix as Markdown tables (as in the guide).
    #[arg(long, requires = "self_test")]
    pub markdown: bool,
}

/// Runs `conformance` (or `conformance --self-test`); returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &ConformanceArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    if args.self_test {
        return self_test(opts, args.markdown, args.html.as_deref(), out, err, console.stderr_terminal);
    }
    let slave = opts.slave_description()?;
    let target = args.mac.unwrap_or_else(|| default_device(None, slave.as_ref()));
    // The same refusals as every command's run, before the bus is touched.
    let run = DeviceRun::new(opts, Some(target), slave.as_ref())?;
    let mut bus = open_bus_with_pcap(opts, run.slave, Some(target), None)?;
    let progress =
        if console.stderr_terminal && !opts.json { Progress::on(&mut *err) } else { Progress::off() };
    let command = ConformanceCommand {
        log: opts.log.as_deref(),
        log_format: opts.format.unwrap_or(TraceFormat::Candump),
        master_mac: run.master_mac,
        response_timeout: Duration::from_millis(opts.timeout.max(1)),
        json: opts.json,
        frames: opts.frames,
        html: args.html.as_deref(),
        keep: opts.keep,
        transport: opts.bus.to_string(),
        stop: console.stop.clone(),
    };
    dnet_conformance::command::execute(&command, bus.as_mut(), target, out, progress)
}

/// `conformance --self-test`: the suite against the reference device and every mutant, each on a
/// simulated bus of its own (`--bus sim` only: the mutants are simulated devices).
fn self_test(
    opts: &GlobalOptions,
    markdown: bool,
    html: Option<&std::path::Path>,
    out: &mut dyn Write,
    err: &mut dyn Write,
    stderr_terminal: bool,
) -> Result<u8, HarnessError> {
    use dnet_conformance::self_test;
    if opts.bus != BusSpec::Sim {
        return Err(HarnessError::SelfTestNeedsSim { bus: opts.bus.to_string() });
    }
    let unused = [
        (opts.log.is_some(), "--log"),
        (opts.pcap.is_some(), "--pcap"),
        (opts.keep, "--keep"),
        (opts.realtime, "--realtime"),
        (!opts.slave_mac.is_empty(), "--slave-mac"),
        (opts.slave_config.is_some(), "--slave-config"),
        (opts.frames, "--frames"),
    ];
    if let Some((_, flag)) = unused.iter().find(|(given, _)| *given) {
        return Err(HarnessError::NotWithSelfTest { option: flag });
    }
    if markdown && opts.json {
        return Err(HarnessError::ChooseOne { first: "--markdown", second: "--json" });
    }
    // The page's file is created before the run, so a path that cannot be written fails at once.
    let mut page = html.map(|p| create_output(p).map(|f| (f, p))).transpose()?;
    let config = opts.master_config(opts.master_mac_or_default());
    struct Shown<'e>(&'e mut dyn Write, bool);
    impl self_test::SelfTestObserver for Shown<'_> {
        fn start(&mut self, n: usize, total: usize, mutant: Option<&dnet_conformance::mutants::Mutant>) {
            if self.1 {
                let what = mutant.map_or("the reference device".to_string(), |m| format!("mutant {}", m.id));
                let _ = write!(self.0, "\r\x1b[K[{n}/{total}] {what}");
                let _ = self.0.flush();
            }
        }
    }
    let progress = stderr_terminal && !opts.json && !markdown;
    let mut shown = Shown(err, progress);
    let report = self_test::run(config, opts.bitrate, &mut shown)?;
    if progress {
        let _ = write!(shown.0, "\r\x1b[K");
    }
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    if opts.json {
        writeln!(out, "{}", self_test::report_json(&report)).map_err(werr)?;
    } else if markdown {
        write!(out, "{}", self_test::markdown(&report)).map_err(werr)?;
    } else {
        self_test::write_text(out, &report).map_err(werr)?;
    }
    if let Some((file, path)) = &mut page {
        file.write_all(self_test::render_html(&report).as_bytes())
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
    }
    Ok(if report.passed() { 0 } else { 1 })
}
