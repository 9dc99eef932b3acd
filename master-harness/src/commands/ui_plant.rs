//! `dnet-master ui --plant FILE.toml`: several DeviceNet networks ([`dnet_scanner::plant`]), each
//! with its own bus, scan list and scanner loop on a thread of its own, behind one console
//! ([`dnet_scanner::ui::serve_plant`]: each network's API under `/api/net/NAME/`).
//!
//! Before any bus is touched: the plant file and every scan list are read and checked, every
//! network's bus is opened (a bus that cannot be opened is exit 2 naming the network), the
//! history files and the console's address. Then every network's scanner brings its nodes into
//! I/O and scans; the program runs until SIGINT / SIGTERM or every network did `--cycles N`, then
//! releases every node and prints each network's table (exit 0 only when every node of every
//! network ended ok).
//!
//! Each network keeps its samples in a history file of its own: `--history dnet-history.sqlite`
//! gives `dnet-history-NAME.sqlite`; the audit log (every network's commands, the network named)
//! stays in the `--history` file itself. With `--mqtt mqtt://HOST/PREFIX` each network publishes
//! under `PREFIX/NAME/` as client `dnet-master-NAME`; with `--sparkplug GROUP/EDGE_NODE` instead,
//! one edge node publishes every network's nodes as devices `NETWORK-macNN`, and a DCMD goes to
//! its network's scanner thread (`super::ui_sparkplug`). `--modbus-tcp`, `--opcua` and
//! `--project` serve one network and are refused with `--plant` (a usage error).

use super::ui_access::AccessArgs;
use super::ui_sparkplug::SparkplugArgs;
use crate::options::{open_bus, GlobalOptions};
use can_io::bus::BusSpec;
use devicenet::MacId;
use dnet_scanner::audit::{Audit, MemoryAudit};
use dnet_scanner::history::{History, Retention};
use dnet_scanner::model::{ConsoleCommand, HistoryStore, ScannerState, Shared};
use dnet_scanner::monitor::InputLayout;
use dnet_scanner::mqtt::{Publisher, TlsFiles};
use dnet_scanner::plant::{read_plant, PlantNetwork};
use dnet_scanner::report::{finish, table, Ending};
use dnet_scanner::sparkplug::commands::Queues;
use dnet_scanner::sparkplug::EdgeNode;
use dnet_scanner::ui::thinning::Thinning;
use dnet_scanner::ui::{known_descriptions, layout_for, serve_plant, ConsoleNetwork};
use dnet_scanner::{sample_values, Scanner, ScannerOptions};
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::master::Master;
use master_core::session::Session;
use slave_fw::description::DeviceDescription;
use std::collections::{HashMap, VecDeque};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{mpsc, Arc, Mutex};

/// What `ui --plant` was asked (`ui`'s options that apply to a plant).
pub struct PlantArgs<'a> {
    /// The plant file.
    pub file: &'a Path,
    /// The console's address.
    pub listen: &'a str,
    /// Accounts and TLS.
    pub access: &'a AccessArgs,
    /// Where the console's recordings go.
    pub record_dir: &'a Path,
    /// The history file (each network's beside it, the audit log in it); `None`: no history.
    pub history: Option<&'a Path>,
    /// `--mqtt URL`.
    pub mqtt: Option<&'a str>,
    /// The TLS files of `--mqtt`.
    pub tls: TlsFiles,
    /// `--sparkplug` and its options (the one edge node of every network).
    pub sparkplug: &'a SparkplugArgs,
    /// `--cycles N`.
    pub cycles: Option<u64>,
}

/// How one network's thread ended.
struct Outcome {
    name: String,
    state: Option<ScannerState>,
    ending: Ending,
    error: Option<HarnessError>,
    history_error: Option<String>,
}

/// The history file of network `name`: `--history`'s file with `-NAME` before its extension.
fn history_path(base: &Path, name: &str) -> PathBuf {
    let stem = base.file_stem().map_or_else(|| "dnet-history".into(), |s| s.to_string_lossy().into_owned());
    let file = match base.extension() {
        Some(ext) => format!("{stem}-{name}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{name}"),
    };
    base.with_file_name(file)
}

/// The `--mqtt` URL of network `name`: its topics under `PREFIX/NAME`.
fn network_url(url: &str, name: &str) -> String {
    let url = url.trim_end_matches('/');
    let after_scheme = url.split_once("://").map_or(url, |(_, rest)| rest);
    if after_scheme.contains('/') {
        format!("{url}/{name}")
    } else {
        format!("{url}/{}/{name}", dnet_scanner::mqtt::DEFAULT_PREFIX)
    }
}

fn open_history(path: &Path) -> Result<Arc<History>, HarnessError> {
    let h = History::open(path).map_err(|e| HarnessError::History(Box::new(e)))?;
    h.set_retention(Retention::STANDARD);
    Ok(Arc::new(h))
}

/// What one network's thread is given.
struct Job {
    net: PlantNetwork,
    opts: GlobalOptions,
    slave: Option<DeviceDescription>,
    shared: Arc<Shared>,
    commands: mpsc::Receiver<ConsoleCommand>,
    history: Option<Arc<History>>,
    publisher: Option<Publisher>,
    sparkplug: Option<Arc<EdgeNode>>,
    cycles: Option<u64>,
}

/// Runs `ui --plant FILE`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &PlantArgs<'_>,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    let file = args.file;
    // `--bus` is a global option with a default: a bus given with `--plant` is found here.
    if opts.bus != BusSpec::Sim {
        writeln!(
            err,
            "error: --plant {}: each network's bus is in the plant file, not --bus",
            file.display()
        )
        .map_err(werr)?;
        return Ok(2);
    }
    let plant = match read_plant(file, opts.master_mac_or_default().as_raw()) {
        Ok(p) => p,
        Err(e) => {
            writeln!(err, "error: {e}").map_err(werr)?;
            return Ok(2);
        }
    };
    let access = args.access.open(args.listen)?;
    if let Some(w) = args.access.warning(args.listen) {
        writeln!(err, "warning: {w}").map_err(werr)?;
    }
    if !args.record_dir.is_dir() {
        return Err(HarnessError::NoSuchDirectory {
            option: "--record-dir",
            path: args.record_dir.display().to_string(),
        });
    }
    let audit: Arc<dyn Audit> = match args.history {
        Some(path) => open_history(path)? as Arc<dyn Audit>,
        None => Arc::new(MemoryAudit::default()),
    };
    let slave = opts.slave_description()?;
    let spb = args.sparkplug.sparkplug.is_some();
    let mut jobs = Vec::new();
    let mut console_networks = Vec::new();
    let mut queues = Queues::new();
    for net in &plant.networks {
        let history = match args.history {
            Some(path) => Some(open_history(&history_path(path, &net.name))?),
            None => None,
        };
        // With --sparkplug the broker gets the one edge node instead (started below).
        let publisher = match args.mqtt.filter(|_| !spb) {
            Some(url) => {
                let url = network_url(url, &net.name);
                let client = format!("dnet-master-{}", net.name);
                Some(
                    Publisher::start_tls(&url, &client, &args.tls)
                        .map_err(|detail| HarnessError::Mqtt { url: url.clone(), detail })?,
                )
            }
            None => None,
        };
        let (commands, command_rx) = mpsc::channel();
        queues.insert(Some(net.name.clone()), commands.clone());
        let placeholder = Scanner::new(Default::default(), net.master_mac, ScannerOptions::default());
        let shared = Arc::new(Shared {
            state: Mutex::new(placeholder.state().clone()),
            frames: Mutex::new(VecDeque::new()),
            commands: Mutex::new(commands),
            history: history.as_ref().map(|h| Box::new(Arc::clone(h)) as Box<dyn HistoryStore>),
            record_dir: args.record_dir.to_path_buf(),
            mqtt: Mutex::new(publisher.as_ref().map(Publisher::status)),
            audit: Arc::clone(&audit),
        });
        console_networks.push(ConsoleNetwork {
            name: net.name.clone(),
            bus: net.bus_text.clone(),
            shared: Arc::clone(&shared),
        });
        let net_opts = GlobalOptions {
            bus: net.bus.clone(),
            bitrate: net.bitrate.unwrap_or(opts.bitrate),
            master_mac: Some(MacId::from_low_bits(net.master_mac)),
            // The console is watched by people: a simulation runs in real time.
            realtime: true,
            ..opts.clone()
        };
        jobs.push(Job {
            net: net.clone(),
            opts: net_opts,
            slave: slave.clone(),
            shared,
            commands: command_rx,
            history,
            publisher,
            sparkplug: None,
            cycles: args.cycles,
        });
    }
    // One edge node for every network, started before any bus is touched (a refusal is exit 2).
    let sparkplug = args.sparkplug.start_plant(args.mqtt, Arc::clone(&audit), queues)?.map(Arc::new);
    if let Some(edge) = &sparkplug {
        for job in &mut jobs {
            job.sparkplug = Some(Arc::clone(edge));
            if let Ok(mut status) = job.shared.mqtt.lock() {
                *status = Some(edge.status());
            }
        }
    }
    let Some(first) = console_networks.first() else {
        return Err(HarnessError::NothingCompared("the plant file names no network".into()));
    };
    let server = serve_plant(args.listen, Arc::clone(&first.shared), access, console_networks.clone())?;
    writeln!(out, "console at {}", server.url()).map_err(werr)?;
    for n in &console_networks {
        writeln!(out, "network {} on {}", n.name, n.bus).map_err(werr)?;
    }
    out.flush().map_err(werr)?;

    // Every bus opened before any is touched: each thread opens its own (a bus is not Send), says
    // so, and waits for the word to go.
    let (opened_tx, opened_rx) = mpsc::channel::<(String, Result<(), HarnessError>)>();
    let mut go = Vec::new();
    let mut handles = Vec::new();
    for job in jobs {
        let (go_tx, go_rx) = mpsc::channel::<bool>();
        go.push(go_tx);
        let opened = opened_tx.clone();
        let stop = console.stop.clone();
        let keep = opts.keep;
        let handle = std::thread::Builder::new()
            .name(format!("network {}", job.net.name))
            .spawn(move || run_network(job, stop, keep, &opened, &go_rx))
            .map_err(|e| HarnessError::ConsoleStart { address: String::new(), error: e.to_string() })?;
        handles.push(handle);
    }
    drop(opened_tx);
    let mut refused = Vec::new();
    for _ in 0..handles.len() {
        match opened_rx.recv() {
            Ok((name, Err(e))) => refused.push(format!("network {name}: {e}")),
            Ok((_, Ok(()))) => {}
            Err(_) => refused.push("a network's thread ended before opening its bus".into()),
        }
    }
    let start = refused.is_empty();
    for g in &go {
        let _ = g.send(start);
    }
    let outcomes: Vec<Outcome> = handles.into_iter().filter_map(|h| h.join().ok().flatten()).collect();
    server.stop();
    // The last holder: NDEATH and a clean disconnect.
    drop(sparkplug);
    if !start {
        for r in &refused {
            writeln!(err, "error: {r}").map_err(werr)?;
        }
        return Ok(2);
    }
    report(&outcomes, out, err).map_err(werr)
}

/// Each network's table and errors; the exit status (the first network's that is not 0).
fn report(outcomes: &[Outcome], out: &mut dyn Write, err: &mut dyn Write) -> std::io::Result<u8> {
    let mut code = 0;
    for o in outcomes {
        if let Some(s) = &o.state {
            writeln!(out, "network {}:", o.name)?;
            write!(out, "{}", table(s))?;
        }
        if let Some(sig) = o.ending.interrupted {
            writeln!(
                err,
                "network {}: interrupted by {}: every node released",
                o.name,
                master_core::stop::signal_name(sig)
            )?;
        } else if let Some(e) = &o.error {
            writeln!(err, "error: network {}: {e}", o.name)?;
        }
        for e in &o.ending.cleanup {
            writeln!(err, "error: network {}: {e}", o.name)?;
        }
        if let Some(e) = &o.history_error {
            writeln!(err, "warning: network {}: the history could not record every sample: {e}", o.name)?;
        }
        if code == 0 {
            code = o.ending.code;
        }
    }
    Ok(code)
}

/// One network's thread: opens the bus, reports, waits for the word, then scans as `ui` does.
/// `None` when it was told not to go.
fn run_network(
    job: Job,
    stop: master_core::stop::Stop,
    keep: bool,
    opened: &mpsc::Sender<(String, Result<(), HarnessError>)>,
    go: &mpsc::Receiver<bool>,
) -> Option<Outcome> {
    let Job { net, opts, slave, shared, commands, history, publisher, sparkplug, cycles } = job;
    let mut bus = match open_bus(&opts, slave.as_ref().map(|d| &d.converter), None, None) {
        Ok(b) => {
            let _ = opened.send((net.name.clone(), Ok(())));
            b
        }
        Err(e) => {
            let _ = opened.send((net.name.clone(), Err(e)));
            return None;
        }
    };
    if go.recv() != Ok(true) {
        return None;
    }
    let mut session = Session::new(bus.as_mut());
    session.set_stop(stop);
    let mut master = Master::new(&mut session, opts.master_config(MacId::from_low_bits(net.master_mac)));
    let layouts: HashMap<u8, InputLayout> = match (&opts.bus, &slave) {
        (BusSpec::Sim, d) => {
            let converter =
                d.as_ref().map_or_else(|| DeviceDescription::reference().converter, |d| d.converter.clone());
            let l = InputLayout::from_converter(&converter);
            net.scan_list.nodes.iter().map(|n| (n.mac, l.clone())).collect()
        }
        _ => HashMap::new(),
    };
    let options = ScannerOptions { cycles, bitrate: opts.bitrate, layouts };
    let mut scanner = Scanner::new(net.scan_list.clone(), net.master_mac, options);
    scanner.set_config_tool(Box::new(super::scanner::Configure));
    let mut thinning = Thinning::default();
    let mut history_error: Option<String> = None;
    let mut events_seen: u64 = 0;
    let result = (|| -> Result<(), HarnessError> {
        scanner.start(&mut master)?;
        loop {
            if let Ok(mut state) = shared.state.lock() {
                state.clone_from(scanner.state());
            }
            shared.push_frames(scanner.take_frames(&mut master));
            if cycles.is_some_and(|c| scanner.state().cycles >= c) {
                return Ok(());
            }
            scanner.cycle(&mut master)?;
            while let Ok(command) = commands.try_recv() {
                scanner.command(&mut master, command);
            }
            let mut samples = thinning.keep(scanner.take_samples());
            for sample in samples.iter_mut().filter(|x| x.values.is_empty()) {
                if let Some(node) = scanner.state().nodes.iter().find(|n| n.mac == sample.mac) {
                    sample.values = sample_values(&layout_for(node, known_descriptions()), &sample.input);
                }
            }
            if let (Some(h), false) = (&history, samples.is_empty()) {
                match History::record(h, &samples) {
                    Ok(()) => history_error = None,
                    Err(e) => history_error = Some(e.to_string()),
                }
            }
            let events = scanner.events().since(events_seen);
            events_seen = events.last().map_or(events_seen, |e| e.seq);
            if let Some(p) = &publisher {
                p.publish_state(scanner.state());
                p.publish_samples(&samples);
                p.publish_events(&events);
                if let Ok(mut status) = shared.mqtt.lock() {
                    *status = Some(p.status());
                }
            }
            if let Some(e) = &sparkplug {
                e.publish_network_state(Some(&net.name), scanner.state());
                e.publish_network_samples(Some(&net.name), &samples);
                if let Ok(mut status) = shared.mqtt.lock() {
                    *status = Some(e.status());
                }
            }
        }
    })();
    let ending = finish(&mut master, Some(&mut scanner), &result, keep);
    drop(publisher);
    drop(sparkplug);
    Some(Outcome {
        name: net.name,
        state: Some(scanner.state().clone()),
        ending,
        error: result.err(),
        history_error,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_network_has_its_history_file() {
        assert_eq!(
            history_path(Path::new("/d/dnet-history.sqlite"), "a"),
            Path::new("/d/dnet-history-a.sqlite")
        );
        assert_eq!(history_path(Path::new("h"), "line-b"), Path::new("h-line-b"));
    }

    #[test]
    fn each_network_publishes_under_its_name() {
        assert_eq!(network_url("mqtt://127.0.0.1:1883", "a"), "mqtt://127.0.0.1:1883/devicenet/a");
        assert_eq!(network_url("mqtt://u:p@h/plant/x/", "b"), "mqtt://u:p@h/plant/x/b");
    }
}
