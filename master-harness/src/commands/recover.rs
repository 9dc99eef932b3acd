//! `dnet-master recover`: a node Communication Faulted after a duplicate MAC ID found through the
//! Offline Connection Set (Who, the answers listed) and, with `--to`, given a new MAC ID (long
//! Identify, offline ownership, Change MAC ID) and watched coming on-line there (protocol §II.6).

use crate::options::{judges_timing, parse_mac, parse_number, GlobalOptions};
use crate::run::{DeviceRun, Outcome};
use clap::Args;
use devicenet::{Duration, MacId};
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::recovery::{RecoverOptions, RecoveryReport};
use serde_json::json;
use std::io::Write;

/// What `recover` was asked.
#[derive(Args, Clone, Debug)]
pub struct RecoverArgs {
    /// The MAC ID at which the node faulted.
    #[arg(long, value_parser = parse_mac)]
    pub mac: MacId,
    /// The MAC ID to give it [default: only list the faulted nodes].
    #[arg(long, value_parser = parse_mac)]
    pub to: Option<MacId>,
    /// The serial number of the node to recover, when several answer (decimal or 0x hex).
    #[arg(long, value_parser = parse_number)]
    pub serial: Option<u32>,
    /// How long the answers to Who are collected, ms.
    #[arg(long, default_value_t = 500, value_name = "MS")]
    pub window: u64,
    /// Who's time-delay byte offset (0-6): each node answers after byte N of its answer in ms.
    #[arg(long, default_value_t = master_core::recovery::TIME_DELAY_OFFSET, value_parser = clap::value_parser!(u8).range(0..=6))]
    pub delay_byte: u8,
    /// How many times Who is sent, 1 s apart, while no node answers.
    #[arg(long, default_value_t = master_core::recovery::WHO_ATTEMPTS, value_parser = clap::value_parser!(u8).range(1..))]
    pub attempts: u8,
}

/// Runs `recover`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &RecoverArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let mut run = DeviceRun::new(opts, Some(args.mac), slave.as_ref())?;
    run.show_table = true;
    run.run(out, err, console, |master, progress, _| {
        let recover = RecoverOptions {
            mac: args.mac,
            to: args.to,
            serial: args.serial,
            window: Duration::from_millis(args.window),
            time_delay_offset: args.delay_byte,
            attempts: args.attempts,
            judge_timing: judges_timing(&opts.bus),
        };
        progress.show(&format!("recover: asking who is Communication Faulted at MAC {} ...", args.mac));
        let r = master.recover(&recover).map(|r| outcome(&r)).map_err(HarnessError::from);
        progress.clear();
        r.into()
    })
}

/// What Who found and what the recovery did, as text and JSON.
fn outcome(r: &RecoveryReport) -> Outcome {
    let mut lines = vec![format!(
        "Who {} for MAC {}: {} Communication Faulted node(s) answered",
        r.who,
        r.mac,
        r.found.len()
    )];
    for n in &r.found {
        lines.push(format!("  {} (answered after {:.1} ms)", n.text(), n.answered_after_ms));
    }
    match (r.chosen, r.new_mac) {
        (Some(node), Some(to)) => {
            let yes = |b: Option<bool>| if b == Some(true) { "answered" } else { "NOT answered" };
            lines.push(format!("recovered {}:", node.text()));
            lines.push(format!(
                "  long Identify {}; offline ownership {}",
                yes(r.identified),
                yes(r.ownership)
            ));
            lines.push(format!(
                "  Change MAC ID to {to}: duplicate MAC ID requests at MAC {to} after {} ms",
                r.dup_mac_requests_ms.iter().map(|t| format!("{t:.0}")).collect::<Vec<_>>().join(" and ")
            ));
            lines.push(format!(
                "  on-line at MAC {to}: explicit connection allocated, serial number {}",
                r.serial_at_new_mac.map_or_else(|| "?".into(), |s| format!("0x{s:08X}"))
            ));
        }
        _ => lines.push("nothing changed (give --to MAC to recover a node)".into()),
    }
    for n in &r.notes {
        lines.push(format!("note: {n}"));
    }
    for f in &r.findings {
        lines.push(format!("finding: {f}"));
    }
    Outcome { json: json!({ "recover": r }), text: lines.join("\n"), code: u8::from(!r.findings.is_empty()) }
}
