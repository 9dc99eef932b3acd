//! `dnet-master scan`: every device on the network found, its identity and I/O sizes read
//! ([`dnet_scanner::scan`]), as a table.

use crate::options::{parse_u8, GlobalOptions};
use crate::run::{DeviceRun, Outcome};
use clap::Args;
use dnet_scanner::scan::{self, ScanReport};
use harness_common::console::Console;
use harness_common::error::HarnessError;
use serde_json::json;
use std::io::Write;

/// What `scan` was asked.
#[derive(Args, Clone, Debug)]
pub struct ScanArgs {
    /// First MAC ID.
    #[arg(long, default_value_t = 0, value_parser = parse_u8)]
    pub from: u8,
    /// Last MAC ID.
    #[arg(long, default_value_t = 63, value_parser = parse_u8)]
    pub to: u8,
}

/// Runs `scan`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &ScanArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let run = DeviceRun::new(opts, None, slave.as_ref())?;
    run.run(out, err, console, |master, progress, _| {
        scan::scan(master, args.from, args.to, progress).map(|r| outcome(&r)).into()
    })
}

/// The table of the devices found.
fn outcome(r: &ScanReport) -> Outcome {
    let mut text = format!(
        "{:>3}  {:<6}  {:<6}  {:>7}  {:<5}  {:<10}  {:<26}  {:<9}  status\n",
        "MAC", "vendor", "type", "product", "rev", "serial", "name", "poll i/o"
    );
    let opt16 = |v: Option<u16>| v.map_or_else(|| "-".into(), |v| format!("0x{v:04X}"));
    for d in &r.devices {
        let io = match (d.produced_size, d.consumed_size) {
            (Some(p), Some(c)) => format!("{p}/{c}"),
            _ => "-".into(),
        };
        text.push_str(&format!(
            "{:>3}  {:<6}  {:<6}  {:>7}  {:<5}  {:<10}  {:<26}  {:<9}  {}\n",
            d.mac,
            opt16(d.identity.vendor_id),
            opt16(d.identity.device_type),
            d.identity.product_code.map_or_else(|| "-".into(), |v| v.to_string()),
            d.identity.revision.clone().unwrap_or_else(|| "-".into()),
            d.identity.serial_number.map_or_else(|| "-".into(), |v| format!("0x{v:08X}")),
            d.identity.product_name.clone().unwrap_or_else(|| "-".into()),
            io,
            d.note.as_ref().map_or_else(|| d.status.clone(), |n| format!("{} ({n})", d.status))
        ));
    }
    text.push_str(&format!(
        "{} device(s) found among {} MAC IDs; scan {:.1} ms of bus time, {:.1} ms with network access",
        r.devices.len(),
        r.asked,
        r.scan_micros as f64 / 1e3,
        r.total_micros as f64 / 1e3
    ));
    Outcome { json: json!({ "scan": r }), text, code: 0 }
}
