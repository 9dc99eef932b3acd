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
//!
//! Automatic device replacement ([`dnet_scanner::adr`]): per scan-list entry (`adr = ...`), or with
//! `--adr` for every node of a list built by the scan; configurations are uploaded and downloaded
//! with `configure`'s functions ([`crate::configure`]). The events ([`dnet_scanner::events`]) are
//! printed after the node table, and are `events` in the `--json` object.

use crate::options::{open_bus_with_pcap, GlobalOptions};
use can_io::bus::BusSpec;
use can_io::log::LogWriter;
use can_io::trace::TraceFormat;
use clap::Args;
use devicenet::MacId;
use dnet_scanner::adr::ConfigTool;
use dnet_scanner::model::AdrMode;
use dnet_scanner::monitor::InputLayout;
use dnet_scanner::report::{finish, summary_json, table, Ending};
use dnet_scanner::{build_scan_list, read_scan_list, write_scan_list, Scanner, ScannerOptions};
use harness_common::console::{Console, Progress};
use harness_common::error::HarnessError;
use master_core::master::Master;
use master_core::session::Session;
use slave_fw::description::DeviceDescription;
use std::collections::HashMap;
use std::io::Write;
use std::path::PathBuf;

/// What `scanner` was asked.
#[derive(Args, Clone, Debug)]
pub struct ScannerArgs {
    /// The scan list (TOML).
    #[arg(long, value_name = "FILE.toml")]
    pub scanlist: Option<PathBuf>,
    /// Write the scan list in force (built by the network scan) to FILE.
    #[arg(long, value_name = "FILE")]
    pub write_scanlist: Option<PathBuf>,
    /// Stop after N full scan cycles (default: until SIGINT / SIGTERM).
    #[arg(long, value_name = "N")]
    pub cycles: Option<u64>,
    /// Automatic device replacement (`adr = "config+address"`) for every node of a scan list
    /// built by the network scan (a scan list file says it per node).
    #[arg(long)]
    pub adr: bool,
}

/// The scanner's configuration tool: `configure`'s upload and download ([`crate::configure`]).
pub(crate) struct Configure;

impl ConfigTool for Configure {
    /// The image in force read over the node's explicit connection, which the scanner holds
    /// (`configure::upload` would allocate it again and wait for the device: long enough for the
    /// other nodes' connections to time out).
    fn upload(&mut self, master: &mut Master<'_, '_>, mac: MacId) -> Result<String, HarnessError> {
        use crate::configure::{read_image, CONFIGURATION_CLASS};
        let size = master.get_u16(mac, CONFIGURATION_CLASS, 1, 2)?.ok_or_else(|| {
            master_core::error::MasterError::Protocol {
                what: "configuration size".into(),
                reason: "not a UINT".into(),
            }
        })?;
        let image = read_image(master, mac, 0, usize::from(size))?;
        let converter = slave_fw::image::decode(&image)
            .map_err(|e| HarnessError::ImageUndecodable { mac, detail: e.to_string() })?;
        let description = DeviceDescription { converter, vendor_name: String::new(), catalog: String::new() };
        description.to_toml().map_err(|detail| HarnessError::DescriptionNotWritable { detail })
    }

    fn download(
        &mut self,
        master: &mut Master<'_, '_>,
        mac: MacId,
        config: &str,
    ) -> Result<(), HarnessError> {
        let description = DeviceDescription::parse(config)?;
        crate::configure::download(master, mac, &description, &mut |_| {})?;
        Ok(())
    }
}

/// Runs `scanner`; returns the exit status (errors before the bus is touched are returned).
pub fn execute(
    opts: &GlobalOptions,
    args: &ScannerArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let master_mac = opts.master_mac_or_default();
    let given = args.scanlist.as_deref().map(|p| read_scan_list(p, master_mac.as_raw())).transpose()?;
    let slave = opts.slave_config.as_deref().map(DeviceDescription::load).transpose()?;
    let mut bus = open_bus_with_pcap(opts, slave.as_ref().map(|d| &d.converter), None, None)?;
    let mut session = Session::new(bus.as_mut());
    session.set_stop(console.stop.clone());
    if let Some(path) = &opts.log {
        let log = LogWriter::create_as(path, opts.format.unwrap_or(TraceFormat::Candump))
            .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
        session.set_log(log);
    }
    let mut master = Master::new(&mut session, opts.master_config(master_mac));
    let mut progress =
        if console.stderr_terminal && !opts.json { Progress::on(&mut *err) } else { Progress::off() };
    // On the simulated bus the devices are known: their images are decoded.
    let sim_layout = match (&opts.bus, &slave) {
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
                let mut l = build_scan_list(&mut master, 0, 63)?;
                if args.adr {
                    for n in &mut l.nodes {
                        n.adr = AdrMode::ConfigAddress;
                    }
                }
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
        let options = ScannerOptions { cycles: args.cycles, bitrate: opts.bitrate, layouts };
        let s = scanner.insert(Scanner::new(list, master_mac.as_raw(), options));
        s.set_config_tool(Box::new(Configure));
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
    let Ending { interrupted, cleanup, code } = finish(&mut master, scanner.as_mut(), &result, opts.keep);
    let state = scanner.as_ref().map(|s| s.state().clone());
    if opts.json {
        let mut v = summary_json(state.as_ref(), code, written.as_deref(), interrupted, &result, &cleanup);
        if let Some(s) = &scanner {
            v["events"] = serde_json::json!(s.events().all());
        }
        if let Some(s) = &scanner {
            dnet_scanner::health::merge_json(&mut v, &s.health().latest_report());
        }
        writeln!(out, "{v}").map_err(werr)?;
    } else {
        if let Some(s) = &state {
            write!(out, "{}", table(s)).map_err(werr)?;
        }
        for e in scanner.as_ref().map(|s| s.events().all()).unwrap_or_default() {
            let t = e.time_us as f64 / 1e6;
            writeln!(out, "{t:10.3} s  MAC {:2}  {:<16} {}", e.mac, e.kind.name(), e.detail).map_err(werr)?;
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
