//! `dnet-master replay`: a recorded transcript replayed against the device, frame by frame
//! ([`crate::replay`]); the table, and where it diverged.

use crate::options::{parse_mac, read_input, GlobalOptions, TraceInput};
use crate::replay::{self, ReplayOptions};
use crate::run::{DeviceRun, Outcome};
use can_io::bus::BusSpec;
use can_io::log::LogEntry;
use clap::Args;
use devicenet::{Duration, MacId};
use harness_common::console::Console;
use harness_common::error::HarnessError;
use serde_json::json;
use std::io::Write;
use std::path::{Path, PathBuf};

/// What `replay` was asked.
#[derive(Args, Clone, Debug)]
pub struct ReplayArgs {
    /// The transcript (candump -L, pcap, pcapng, trc, asc, blf or csv, detected from the
    /// content; `-`: standard input).
    pub transcript: PathBuf,
    /// How the trace is read.
    #[command(flatten)]
    pub input: TraceInput,
    /// The device under test [default: the transcript's device, when it has just one].
    #[arg(long, value_parser = parse_mac)]
    pub mac: Option<MacId>,
    /// How late an expected frame may be, ms.
    #[arg(long, default_value_t = 1000)]
    pub tolerance: u64,
    /// How long to watch for extra frames after the transcript, ms.
    #[arg(long, default_value_t = 500)]
    pub settle: u64,
    /// Begin where the device is on-line, for a device that is not powered on in step with
    /// the transcript (without it, a transcript that begins with the device's power-up needs
    /// the device powered on then; on a real bus replay prints the window): `--from-online`
    /// skips the transcript's start-up (the device is on-line already); `--from-online=wait`
    /// first waits for the device's own duplicate MAC ID check (power it on after starting the
    /// replay).
    #[arg(long, value_name = "WAIT", num_args = 0..=1, require_equals = true, default_missing_value = "now")]
    pub from_online: Option<replay::FromOnline>,
    /// Data not compared: `io`, the data of the device's I/O messages (poll, bit-strobe,
    /// change-of-state/cyclic responses), which differs from a recording of live values;
    /// their identifier and length are still compared, and they are reported as not compared.
    #[arg(long, value_name = "WHAT", value_parser = ["io"])]
    pub ignore_data: Option<String>,
}

/// Runs `replay`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &ReplayArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    // Read the transcript and resolve the defaults before touching the bus.
    let entries = read_input(&args.transcript, &args.input, err)?.entries;
    let slave = opts.slave_description()?;
    let target = device(args, &entries)?;
    let master_mac = master_mac(opts, &entries)?;
    let mut run = DeviceRun::with_master(opts, Some(target), master_mac, slave.as_ref())?;
    run.replay_power_on = Some(replay::sim_start(&entries, target, args.from_online));
    run.show_table = true;
    if opts.bus != BusSpec::Sim && !opts.json {
        // A real device must be powered on in step with a transcript of its power-up: say when.
        if args.from_online.is_none() {
            if let Some(note) = replay::power_on_note(&entries, target, Duration::from_millis(args.tolerance))
            {
                let _ = writeln!(err, "{note}");
            }
        }
        // --from-online=wait may wait long: say for what, also where no progress line is shown.
        if args.from_online == Some(replay::FromOnline::Wait) && !console.stderr_terminal {
            let _ = writeln!(
                err,
                "note: waiting for MAC {target}'s duplicate MAC ID check: power it on (Ctrl-C stops)"
            );
        }
    }
    run.run(out, err, console, |master, progress, _| {
        let replay_opts = ReplayOptions {
            device: target,
            tolerance: Duration::from_millis(args.tolerance),
            settle: Duration::from_millis(args.settle),
            from_online: args.from_online,
            ignore_io_data: args.ignore_data.is_some(),
        };
        let what = match args.from_online {
            Some(replay::FromOnline::Wait) => format!(
                "replay: waiting for MAC {target}'s duplicate MAC ID check: power it on (Ctrl-C stops) ..."
            ),
            _ => format!("replay: {} frames against MAC {target} ...", entries.len()),
        };
        progress.show(&what);
        let r = replay::replay(master.session, &entries, &replay_opts).map(|s| Outcome {
            text: s.text(),
            json: json!({ "summary": s }),
            code: 0,
        });
        progress.clear();
        // What the transcript allocated stays with the device: released like any command's. A
        // device that sent nothing (never powered on during a --from-online=wait) holds nothing.
        let heard = master.session.records().iter().any(|r| {
            r.origin == can_io::bus::Origin::Remote && master_core::session::is_from_device(&r.frame, target)
        });
        if heard && !matches!(r, Err(HarnessError::NothingCompared(_))) {
            master.note_held(target, replay::held_after(&entries, target));
        }
        r.into()
    })
}

/// The device under test: `--mac`, else the transcript's one device.
fn device(args: &ReplayArgs, entries: &[LogEntry]) -> Result<MacId, HarnessError> {
    if let Some(mac) = args.mac {
        return Ok(mac);
    }
    let path = || display(&args.transcript);
    match replay::transcript_devices(entries).as_slice() {
        [one] => Ok(*one),
        [] => Err(HarnessError::TranscriptWithoutDevice { path: path() }),
        many => Err(HarnessError::TranscriptDevices { path: path(), macs: many.to_vec() }),
    }
}

/// The path as the user gave it.
fn display(path: &Path) -> String {
    path.display().to_string()
}

/// The master's MAC: `--master-mac`, else the transcript's master, else 0. A replay sends the
/// transcript's frames as recorded, so a `--master-mac` that differs from the transcript's master
/// is refused.
fn master_mac(opts: &GlobalOptions, entries: &[LogEntry]) -> Result<MacId, HarnessError> {
    match (opts.master_mac, replay::transcript_master(entries)) {
        (Some(given), Some(recorded)) if given != recorded => {
            Err(HarnessError::MasterMacNotTranscript { given, recorded })
        }
        (Some(given), _) => Ok(given),
        (None, Some(recorded)) => Ok(recorded),
        (None, None) => Ok(MacId::from_low_bits(0)),
    }
}
