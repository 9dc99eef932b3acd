//! How a scanner run ends and what it reports (`dnet-master scanner` and `ui` alike): the release
//! of every node ([`finish`]), the node table ([`table`]) and the `--json` summary
//! ([`summary_json`]).

use crate::engine::Scanner;
use crate::model::ScannerState;
use harness_common::error::HarnessError;
use master_core::error::MasterError;
use master_core::master::Master;
use serde_json::json;

/// `scanner --json`'s one object: the scanner's figures and every node (module docs).
pub fn summary_json(
    state: Option<&ScannerState>,
    code: u8,
    written: Option<&str>,
    interrupted: Option<i32>,
    result: &Result<(), HarnessError>,
    cleanup: &[HarnessError],
) -> serde_json::Value {
    let mut v = json!({
        "ok": code == 0,
        "version": harness_common::version(),
    });
    if let Some(s) = state {
        v["scanner"] = json!(s.status);
        v["cycles"] = json!(s.cycles);
        v["cycle_ms"] = json!(s.cycle_ms);
        v["bus_load"] = json!(s.bus_load);
        v["interscan_delay_ms"] = json!(s.interscan_delay_ms);
        v["expected_packet_rate_ms"] = json!(s.expected_packet_rate_ms);
        v["nodes"] = json!(s
            .nodes
            .iter()
            .map(|n| json!({
                "mac": n.mac,
                "name": n.name,
                "connection": n.connection,
                "ack_suppression": n.ack_suppression,
                "status": n.status.name(),
                "code": n.code,
                "detail": n.detail,
                "vendor_id": n.identity.vendor_id,
                "device_type": n.identity.device_type,
                "product_code": n.identity.product_code,
                "revision": n.identity.revision,
                "product_name": n.identity.product_name,
                "input_size": n.input_size,
                "output_size": n.output_size,
                "exchanges": n.exchanges,
            }))
            .collect::<Vec<_>>());
    }
    if let Some(w) = written {
        v["scanlist_written"] = json!(w);
    }
    if let Some(sig) = interrupted {
        v["interrupted"] = json!(master_core::stop::signal_name(sig));
    }
    if let Err(e) = result {
        if interrupted.is_none() {
            v["error"] = json!(e.to_string());
        }
    }
    if !cleanup.is_empty() {
        v["cleanup_errors"] = json!(cleanup.iter().map(ToString::to_string).collect::<Vec<_>>());
    }
    v
}

/// The node table and the summary line.
#[must_use]
pub fn table(s: &ScannerState) -> String {
    // The scan list's names, as wide as the longest.
    let name_width =
        s.nodes.iter().filter_map(|n| n.name.as_ref()).map(|n| n.chars().count()).max().unwrap_or(1).max(4);
    let mut t = format!(
        "{:>3}  {:<21}  {:>4}  {:<13}  {:<26}  {:<name_width$}  {:>9}  detail\n",
        "MAC", "status", "code", "connection", "product", "name", "in/out"
    );
    for n in &s.nodes {
        let io = match (n.input_size, n.output_size) {
            (Some(i), Some(o)) => format!("{i}/{o}"),
            _ => "-".into(),
        };
        let connection =
            if n.ack_suppression { format!("{} (-ack)", n.connection) } else { n.connection.clone() };
        t.push_str(&format!(
            "{:>3}  {:<21}  {:>4}  {:<13}  {:<26}  {:<name_width$}  {:>9}  {}\n",
            n.mac,
            n.status.name(),
            n.code,
            connection,
            n.identity.product_name.as_deref().unwrap_or("-"),
            n.name.as_deref().unwrap_or("-"),
            io,
            n.detail.as_deref().unwrap_or("")
        ));
    }
    t.push_str(&format!(
        "scanner {:?} at MAC {}: {} cycle(s), median cycle {:.2} ms, bus load {:.0} %, inter-scan delay {} ms, EPR {} ms\n",
        s.status,
        s.mac,
        s.cycles,
        s.cycle_ms,
        s.bus_load * 100.0,
        s.interscan_delay_ms,
        s.expected_packet_rate_ms
    ));
    t
}

/// How a scanner run ended (`scanner` and `ui` alike).
pub struct Ending {
    /// The signal that stopped it (SIGINT, SIGTERM), if one did.
    pub interrupted: Option<i32>,
    /// What went wrong while releasing the nodes and flushing the log.
    pub cleanup: Vec<HarnessError>,
    /// The exit status: 0 only when every node ended ok (in I/O with data exchanged) and the
    /// clean-up went through; else the run's error's own status, or 1.
    pub code: u8,
}

/// Ends a scanner run that gave `result`: unless the bus failed or `keep`, every node is released
/// (through the scanner, or the connections held when it never started); the session's log is
/// flushed; the exit status is worked out.
pub fn finish(
    master: &mut Master<'_, '_>,
    mut scanner: Option<&mut Scanner>,
    result: &Result<(), HarnessError>,
    keep: bool,
) -> Ending {
    let interrupted = match result {
        Err(HarnessError::Master(MasterError::Interrupted { signal })) => Some(*signal),
        _ => None,
    };
    // The stop is taken off the session, so the release below runs to its end.
    let _ = master.session.take_stop();
    let bus_failed = matches!(result, Err(HarnessError::Master(MasterError::Bus(_))));
    let mut cleanup: Vec<HarnessError> = Vec::new();
    if !bus_failed && !keep {
        if let Some(s) = scanner.as_mut() {
            if let Err(e) = s.stop(master) {
                cleanup.push(e);
            }
        } else if let Err(e) = master.release_held() {
            cleanup.push(HarnessError::Release(Box::new(e)));
        }
    }
    if let Err(e) = master.session.flush() {
        cleanup.push(e.into());
    }
    let all_ok = scanner
        .as_ref()
        .is_some_and(|s| !s.state().nodes.is_empty() && s.state().nodes.iter().all(|n| n.code == 0));
    let code = match result {
        Ok(()) if cleanup.is_empty() => u8::from(!all_ok),
        Ok(()) => 1,
        Err(e) => e.exit_code(),
    };
    Ending { interrupted, cleanup, code }
}
