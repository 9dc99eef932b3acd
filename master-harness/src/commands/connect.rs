//! `dnet-master connect`: the full bring-up of protocol §2 at one device, every frame checked, with
//! the I/O connection `--io` names; the frame table and a summary of the device.

use crate::options::{parse_mac, GlobalOptions, HexBytes, IoArgs};
use crate::run::{default_device, DeviceRun, Outcome};
use clap::Args;
use devicenet::MacId;
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::decode;
use master_core::io::{IoKind, IoSummary};
use master_core::master::{ConnectOptions, DeviceSummary};
use serde_json::json;
use std::io::Write;

/// What `connect` was asked.
#[derive(Args, Clone, Debug)]
pub struct ConnectArgs {
    /// The device's MAC ID [default: the --slave-config description's, else 5].
    #[arg(long, value_parser = parse_mac)]
    pub mac: Option<MacId>,
    /// Expected packet rate of the poll connection, ms.
    #[arg(long, default_value_t = 100)]
    pub epr: u16,
    /// Poll cycles after the connection is established.
    #[arg(long, default_value_t = 1)]
    pub polls: u32,
    /// Poll output data in hex (default: zeros of the consumed size).
    #[arg(long)]
    pub output: Option<HexBytes>,
    /// Read the connection states back and check the 4 x EPR watchdog (adds frames).
    #[arg(long)]
    pub verify_state: bool,
    /// The I/O connection.
    #[command(flatten)]
    pub io: IoArgs,
}

/// Runs `connect`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &ConnectArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let target = args.mac.unwrap_or_else(|| default_device(None, slave.as_ref()));
    let mut run = DeviceRun::new(opts, Some(target), slave.as_ref())?;
    run.show_table = true;
    run.run(out, err, console, |master, progress, _| {
        let connect = ConnectOptions {
            target,
            epr_ms: args.epr,
            polls: args.polls,
            output: args.output.clone().map(|h| h.0),
            verify_state: args.verify_state,
        };
        progress.show(&format!("connect: bringing up MAC {target} ({}) ...", args.io.io));
        let r = master
            .connect_io(&connect, &args.io.options(&opts.bus))
            .map(|s| outcome(&s))
            .map_err(HarnessError::from);
        progress.clear();
        r.into()
    })
}

/// The device's summary: identity, sizes, EPR, the last input; the I/O connection's line.
fn outcome(s: &DeviceSummary) -> Outcome {
    let hex16 = |v: Option<u16>| v.map_or_else(|| "?".into(), |v| format!("0x{v:04X}"));
    let num = |v: Option<u16>| v.map_or_else(|| "?".into(), |v| v.to_string());
    let kind = match &s.io {
        None => "poll".to_string(),
        Some(io) if io.ack_suppression => format!("{} (acknowledge suppression)", io.kind),
        Some(io) => io.kind.to_string(),
    };
    let mut text = format!(
        "device MAC {}: {}vendor {}, device type {}, product code {}; {kind} produced {} / consumed {} bytes, EPR {} ms{}",
        s.mac,
        if s.ucmm_capable { "UCMM-capable, " } else { "group-2-only, " },
        hex16(s.vendor_id),
        hex16(s.device_type),
        num(s.product_code),
        num(s.produced_size),
        num(s.consumed_size),
        num(s.expected_packet_rate_ms),
        s.last_input.as_ref().map_or_else(String::new, |i| format!("; last input {}", decode::hex(i)))
    );
    if let Some(io) = &s.io {
        text.push_str(&io_text(io));
    }
    Outcome { json: json!({ "device": s }), text, code: 0 }
}

/// The second line of `connect --io strobe|cos|cyclic`: identifiers, settings, what was exchanged.
#[must_use]
pub fn io_text(io: &IoSummary) -> String {
    let id = |v: Option<u16>| v.map_or_else(|| "?".into(), |v| format!("0x{v:03X}"));
    let mut parts = vec![format!(
        "Connection {}: produced ID {}, consumed ID {}",
        io.instance,
        id(io.produced_id),
        id(io.consumed_id)
    )];
    if let Some(p) = io.inhibit_time_ms {
        parts.push(format!("inhibit time {p} ms"));
    }
    if let (Some(t), Some(n)) = (io.ack_timer_ms, io.retry_limit) {
        parts.push(format!("acknowledge timer {t} ms, retry limit {n}"));
    }
    if io.kind == IoKind::Strobe {
        parts.push(format!("{} strobe response(s)", io.strobe_responses));
    } else {
        let mut p = format!("{} production(s), {} acknowledged by the master", io.productions, io.acks_sent);
        if io.re_sent > 0 {
            p.push_str(&format!(", {} re-sent by the device", io.re_sent));
        }
        parts.push(p);
        if let (Some(lo), Some(hi)) = (io.interval_min_ms, io.interval_max_ms) {
            parts.push(format!("interval {lo:.1}-{hi:.1} ms"));
        }
        if io.outputs_sent > 0 {
            parts.push(format!(
                "master data sent {} time(s), {} acknowledged",
                io.outputs_sent, io.outputs_acknowledged
            ));
        }
    }
    format!("\n{}", parts.join("; "))
}
