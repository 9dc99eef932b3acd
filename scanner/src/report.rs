//! `dnet-master scanner [--scanlist FILE.toml] [--write-scanlist FILE] [--cycles N]`: the engine
//! on the command line.
//!
//! Without `--scanlist` the scan list is built from a network scan (MAC 0..=63) and, with
//! `--write-scanlist`, written out. The run goes on until `--cycles` or SIGINT / SIGTERM (exit
//! 130 / 143 with what it has); every node is released at the end. Text: a progress line while it
//! runs (on a terminal), then a table of the nodes (with each node's connection type, `(-ack)`
//! under acknowledge suppression); `--json`: one object with `cycle_ms` (the median full cycle),
//! `bus_load` and `nodes` (each with `connection` and `ack_suppression`). Exit 0 when every node ended ok, 1 otherwise, 2 for a usage
//! or scan list error.

use super::{build_scan_list, read_scan_list, write_scan_list, Scanner, ScannerOptions};
use crate::cli::{exit_code, open_bus, Cli};
use crate::console::{Console, Progress};
use crate::error::HarnessError;
use crate::monitor::InputLayout;
use can_io::bus::BusSpec;
use can_io::log::LogWriter;
use can_io::pcap::{PcapBus, PcapWriter};
use can_io::trace::TraceFormat;
use devicenet::{Duration, MacId};
use master_core::error::MasterError;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use serde_json::json;
use slave_fw::description::DeviceDescription;
use std::collections::HashMap;
use std::io::Write;
use std::path::PathBuf;

/// What `scanner` was asked.
#[derive(Clone, Debug, Default)]
pub struct ScannerArgs {
    /// `--scanlist FILE.toml`.
    pub scanlist: Option<PathBuf>,
    /// `--write-scanlist FILE`.
    pub write_scanlist: Option<PathBuf>,
    /// `--cycles N`.
    pub cycles: Option<u64>,
}

/// Runs `scanner`; returns the exit status (errors before the bus is touched are returned).
pub fn execute(
    cli: &Cli,
    args: &ScannerArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let master_mac = cli.master_mac.unwrap_or(MacId::from_low_bits(0));
    let given = args.scanlist.as_deref().map(|p| read_scan_list(p, master_mac.as_raw())).transpose()?;
    let slave = cli.slave_config.as_deref().map(DeviceDescription::load).transpose()?;
    let mut bus = open_bus(cli, slave.as_ref().map(|d| &d.converter), None, None)?;
    if let Some(path) = &cli.pcap {
        let pcap = PcapWriter::create(path)
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
        bus = Box::new(PcapBus::new(bus, pcap));
    }
    let mut session = Session::new(bus.as_mut());
    session.set_stop(console.stop.clone());
    if let Some(path) = &cli.log {
        let log = LogWriter::create_as(path, cli.format.unwrap_or(TraceFormat::Candump))
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
        session.set_log(log);
    }
    let config = MasterConfig {
        mac: master_mac,
        response_timeout: Duration::from_millis(cli.timeout.max(1)),
        ..MasterConfig::default()
    };
    let mut master = Master::new(&mut session, config);
    let mut progress =
        if console.stderr_terminal && !cli.json { Progress::on(&mut *err) } else { Progress::off() };
    // On the simulated bus the devices are known: their images are decoded.
    let sim_layout = match (&cli.bus, &slave) {
        (BusSpec::Sim, Some(d)) => Some(InputLayout::from_converter(&d.converter)),
        (BusSpec::Sim, None) => Some(InputLayout::from_converter(&DeviceDescription::reference().converter)),
        _ => None,
    };
    let mut scanner: Option<Scanner> = None;
    let mut written: Option<String> = None;
    let result = (|| -> Result<(), HarnessError> {
        let list = match given.clone() {
            Some(l) => l,
            None => {
                progress.show("scanner: building the scan list from a network scan ...");
                let l = build_scan_list(&mut master, 0, 63)?;
                if let Some(path) = &args.write_scanlist {
                    std::fs::write(path, write_scan_list(&l))
                        .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
                    written = Some(path.display().to_string());
                }
                l
            }
        };
        if let (Some(path), Some(_)) = (&args.write_scanlist, &given) {
            std::fs::write(path, write_scan_list(&list))
                .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
            written = Some(path.display().to_string());
        }
        if list.nodes.is_empty() {
            // A scan list file without a node is refused where it is read (exit 2); this is a
            // network scan that found no device to keep in I/O.
            return Err(HarnessError::NothingCompared(
                "the network scan found no device with an I/O connection: no node to scan".into(),
            ));
        }
        let layouts: HashMap<u8, InputLayout> = match &sim_layout {
            Some(l) => list.nodes.iter().map(|n| (n.mac, l.clone())).collect(),
            None => HashMap::new(),
        };
        let options = ScannerOptions { cycles: args.cycles, bitrate: cli.bitrate, layouts };
        let s = scanner.insert(Scanner::new(list, master_mac.as_raw(), options));
        progress.show(&format!("scanner: bringing {} node(s) into I/O ...", s.state().nodes.len()));
        s.start(&mut master)?;
        loop {
            if args.cycles.is_some_and(|c| s.state().cycles >= c) {
                return Ok(());
            }
            s.cycle(&mut master)?;
            // Nobody reads frames or samples here: drop them as they come.
            let _ = s.take_samples();
            let st = s.state();
            if st.cycles % 10 == 1 || progress.enabled() && st.cycles < 10 {
                let ok = st.nodes.iter().filter(|n| n.code == 0).count();
                progress.show(&format!(
                    "scanner: cycle {}, {:.1} ms, bus load {:.0} %, {ok}/{} node(s) ok",
                    st.cycles,
                    st.cycle_ms,
                    st.bus_load * 100.0,
                    st.nodes.len()
                ));
            }
        }
    })();
    progress.clear();
    drop(progress);
    let Ending { interrupted, cleanup, code } = finish(&mut master, scanner.as_mut(), &result, cli.keep);
    let state = scanner.as_ref().map(|s| s.state().clone());
    if cli.json {
        let v = summary_json(state.as_ref(), code, written.as_deref(), interrupted, &result, &cleanup);
        writeln!(out, "{v}").map_err(werr)?;
    } else {
        if let Some(s) = &state {
            write!(out, "{}", table(s)).map_err(werr)?;
        }
        if let Some(w) = &written {
            writeln!(err, "scan list written to {w}").map_err(werr)?;
        }
        if let Some(sig) = interrupted {
            writeln!(err, "interrupted by {}: every node released", master_core::stop::signal_name(sig))
                .map_err(werr)?;
        } else if let Err(e) = &result {
            writeln!(err, "error: {e}").map_err(werr)?;
        }
        for e in &cleanup {
            writeln!(err, "error: {e}").map_err(werr)?;
        }
    }
    Ok(code)
}

/// `scanner --json`'s one object: the scanner's figures and every node (module docs).
fn summary_json(
    state: Option<&super::model::ScannerState>,
    code: u8,
    written: Option<&str>,
    interrupted: Option<i32>,
    result: &Result<(), HarnessError>,
    cleanup: &[HarnessError],
) -> serde_json::Value {
    let mut v = json!({
        "ok": code == 0,
        "version": crate::version(),
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
pub fn table(s: &super::model::ScannerState) -> String {
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
pub(crate) struct Ending {
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
pub(crate) fn finish(
    master: &mut Master<'_, '_>,
    mut scanner: Option<&mut Scanner>,
    result: &Result<(), HarnessError>,
    keep: bool,
) -> Ending {
    let interrupted = match result {
        Err(HarnessError::Master(MasterError::Interrupted { signal })) => Some(*signal),
        _ => None,
    };
    master.session.take_stop();
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
        Err(e) => exit_code(e),
    };
    Ending { interrupted, cleanup, code }
}
