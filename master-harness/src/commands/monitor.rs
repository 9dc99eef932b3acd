//! `dnet-master monitor`: the device brought up, then polled at its expected packet rate, the
//! data decoded by its profile ([`dnet_scanner::monitor`]), refreshed in place on a terminal;
//! `--csv FILE` records every sample.

use crate::options::{create_output, parse_mac, GlobalOptions, HexBytes, IoArgs};
use crate::run::{default_device, DeviceRun, Outcome, Ran};
use can_io::bus::BusSpec;
use clap::Args;
use devicenet::{Duration, MacId};
use dnet_scanner::monitor::{self, InputLayout, MonitorOptions};
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::io::IoKind;
use master_core::master::ConnectOptions;
use serde_json::json;
use slave_fw::description::DeviceDescription;
use std::io::Write;
use std::path::PathBuf;

/// What `monitor` was asked.
#[derive(Args, Clone, Debug)]
pub struct MonitorArgs {
    /// The device's MAC ID [default: the --description or --slave-config description's, else 5].
    #[arg(long, value_parser = parse_mac)]
    pub mac: Option<MacId>,
    /// Poll period (expected packet rate), ms.
    #[arg(long, default_value_t = 100)]
    pub epr: u16,
    /// Poll output data in hex (e.g. 0201 closes the breaker).
    #[arg(long)]
    pub output: Option<HexBytes>,
    /// Record every sample in FILE (CSV).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Stop after K samples.
    #[arg(long)]
    pub count: Option<u64>,
    /// Stop after this many seconds of monitoring (bus time; sim default 10 s unless --realtime).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Report a lost connection (bus error, poll unanswered) and reconnect instead of stopping.
    #[arg(long)]
    pub reconnect: bool,
    /// Decode the polled data with this device description (TOML) [default on sim: the
    /// --slave-config description, else the reference breaker; on a real bus: raw bytes].
    #[arg(long, value_name = "FILE")]
    pub description: Option<PathBuf>,
    /// The I/O connection.
    #[command(flatten)]
    pub io: IoArgs,
}

/// Runs `monitor`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &MonitorArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let own = args.description.as_deref().map(DeviceDescription::load).transpose()?;
    let target = args.mac.unwrap_or_else(|| default_device(own.as_ref(), slave.as_ref()));
    let run = DeviceRun::new(opts, Some(target), slave.as_ref())?;
    let duration = match crate::options::duration_secs(args.duration)? {
        None if opts.bus == BusSpec::Sim && !opts.realtime && args.count.is_none() => {
            Some(Duration::from_secs(10))
        }
        d => d,
    };
    let monitor_opts = MonitorOptions {
        connect: ConnectOptions {
            target,
            epr_ms: args.epr,
            polls: 0,
            output: args.output.clone().map(|h| h.0),
            verify_state: false,
        },
        count: args.count,
        duration,
        in_place: console.stdout_terminal && !opts.json,
        reconnect: args.reconnect,
        // A strobe response carries the first 8 input bytes only: shown raw.
        layout: if args.io.io == IoKind::Strobe {
            InputLayout::raw()
        } else {
            layout(opts, own.as_ref(), slave.as_ref())
        },
        io: args.io.options(&opts.bus),
    };
    let mut csv = args.csv.as_deref().map(create_output).transpose()?.map(std::io::BufWriter::new);
    run.run(out, err, console, |master, progress, out| {
        let mut sink = std::io::sink();
        let screen: &mut dyn Write = if opts.json { &mut sink } else { out };
        progress.show(&format!("monitor: bringing up MAC {target} ..."));
        let run = monitor::monitor(
            master,
            &monitor_opts,
            screen,
            csv.as_mut().map(|f| f as &mut dyn Write),
            progress,
        );
        progress.clear();
        let mut cleanup = Vec::new();
        if let Some(f) = &mut csv {
            if let Err(source) = f.flush() {
                cleanup.push(HarnessError::Write { path: "the CSV file".into(), source });
            }
        }
        let n = run.samples.len();
        let outcome = Outcome {
            text: format!("{n} sample{}", if n == 1 { "" } else { "s" }),
            json: json!({ "samples": run.samples }),
            code: 0,
        };
        match run.ended {
            // A run that took no sample showed nothing of the device: not a success.
            None if n == 0 => Ran {
                result: Err(HarnessError::NothingCompared(format!(
                    "monitor: no sample of MAC {target} was taken before --count or --duration ended the run"
                ))),
                partial: Some(outcome),
                cleanup,
            },
            None => Ran { result: Ok(outcome), partial: None, cleanup },
            // Interrupted or failed: the samples taken are still reported.
            Some(e) => Ran { result: Err(e), partial: Some(outcome), cleanup },
        }
    })
}

/// How `monitor` decodes the polled data: `--description`, else on the simulated bus the
/// `--slave-config` description or the reference device (which the simulated device then is), else
/// (a real bus, nothing known of the device) raw bytes. `--slave-config` describes only the
/// simulated devices, so on a real bus it does not choose the decoding.
fn layout(
    opts: &GlobalOptions,
    own: Option<&DeviceDescription>,
    slave: Option<&DeviceDescription>,
) -> InputLayout {
    match (own, slave, &opts.bus) {
        (Some(d), _, _) | (None, Some(d), BusSpec::Sim) => InputLayout::from_converter(&d.converter),
        (None, None, BusSpec::Sim) => InputLayout::from_converter(&DeviceDescription::reference().converter),
        (None, _, _) => InputLayout::raw(),
    }
}
