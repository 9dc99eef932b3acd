//! `dnet-master ui`: the scanner ([`dnet_scanner::Scanner`]) and its web console
//! ([`dnet_scanner::ui::serve`]) in one program, with the sample history
//! ([`dnet_scanner::history`]) and, with `--mqtt`, the publisher ([`dnet_scanner::mqtt`]).
//!
//! The console is served before the bus is touched, and its address printed on a line of its own
//! (`console at http://127.0.0.1:8080/`), so a page opened at once follows the bring-up. Then the
//! scanner's loop runs, one full scan cycle at a time; between cycles it carries out the console's
//! commands, publishes the state and the frames to the console, records the samples and publishes
//! them. On the simulated bus the simulation runs in real time (a console is watched by people),
//! or as fast as the host allows with `--sim-unpaced` (soak measurements).
//!
//! What is kept in the history: every change of a node's input image, and one sample a second while
//! it stays the same ([`SAMPLE_EVERY_MS`](dnet_scanner::ui::thinning::SAMPLE_EVERY_MS)): a poll every 10 ms of an instrument that reports once a
//! second would otherwise store a hundred copies of each report. For how long:
//! [`Retention::STANDARD`] (30 days, at most 1 GiB, one sample a minute after 6 hours).
//!
//! It runs until SIGINT / SIGTERM (exit 130 / 143) or `--cycles N` (exit 0 only when every node
//! ended ok, as `scanner`); then every node is released, the server stopped (a recording closed)
//! and the nodes' table printed. A history file or a
//! listening address that cannot be used is an error (exit 2) before the bus is touched; a broker
//! that is down is not: the console and MQTT status say so and the scanner scans on.
//!
//! `--users FILE` turns logins and roles on, `--tls-cert` / `--tls-key` TLS
//! ([`super::ui_access`]); without `--users` the console listens on loopback only (another
//! address is refused, exit 2, before the bus is touched).

use crate::options::{open_bus, GlobalOptions};
use can_io::bus::BusSpec;
use clap::Args;
use dnet_scanner::audit::MemoryAudit;
use dnet_scanner::history::{History, Retention};
use dnet_scanner::model::{HistoryStore, Shared};
use dnet_scanner::monitor::InputLayout;
use dnet_scanner::mqtt::Publisher;
use dnet_scanner::report::{finish, table, Ending};
use dnet_scanner::ui::thinning::Thinning;
use dnet_scanner::ui::{known_descriptions, layout_for, serve_with};
use dnet_scanner::{build_scan_list, read_scan_list, sample_values, Scanner, ScannerOptions};
use harness_common::console::{Console, Progress};
use harness_common::error::HarnessError;
use master_core::master::Master;
use master_core::session::Session;
use slave_fw::description::DeviceDescription;
use std::collections::HashMap;
use std::collections::VecDeque;
use std::io::Write;
use std::path::PathBuf;
use std::sync::{mpsc, Arc, Mutex};

/// What `ui` was asked.
#[derive(Args, Clone, Debug)]
pub struct UiArgs {
    /// The address to serve the console on (port 0: any free port; the URL is printed).
    #[arg(long, default_value = "127.0.0.1:8080", value_name = "ADDR")]
    pub listen: String,
    /// The scan list (TOML) [default: built from a network scan].
    #[arg(long, value_name = "FILE.toml")]
    pub scanlist: Option<PathBuf>,
    /// A plant file (TOML): several networks, each `[[network]]` with its `name`, `bus` and
    /// `scanlist`, behind one console (guide: Several networks); not with a --bus other than sim.
    #[arg(long, value_name = "FILE.toml",
          conflicts_with_all = ["scanlist", "adr", "project", "modbus_tcp", "opcua"])]
    pub plant: Option<PathBuf>,
    /// Automatic device replacement (`adr = "config+address"`) for every node of a scan list
    /// built by the network scan (a scan list file says it per node).
    #[arg(long)]
    pub adr: bool,
    /// A network project (`dnet-master project upload`) the console compares with the running
    /// network (`GET /api/project/compare`, the page's Project panel); read and checked at start.
    #[arg(long, value_name = "FILE.toml")]
    pub project: Option<PathBuf>,
    /// The sample history (SQLite; created when missing).
    #[arg(long, value_name = "FILE", default_value = "dnet-history.sqlite")]
    pub history: PathBuf,
    /// Keep no history (the device view's plot and the CSV export then have nothing).
    #[arg(long)]
    pub no_history: bool,
    /// Publish node status and decoded values to an MQTT broker: `mqtt://HOST[:PORT][/PREFIX]`.
    #[arg(long, value_name = "URL")]
    pub mqtt: Option<String>,
    /// Where the console's recordings go.
    #[arg(long, value_name = "DIR", default_value = ".")]
    pub record_dir: PathBuf,
    /// Stop after N full scan cycles (default: until SIGINT / SIGTERM).
    #[arg(long, value_name = "N")]
    pub cycles: Option<u64>,
    /// With --bus sim only (another bus: exit 2): run the simulation as fast as the host allows
    /// instead of in real time, for soak measurements. Times are then simulated: the scan cycles,
    /// the simulated devices' timers (a breaker's 1 s status frame) and the samples' bus time run
    /// on the simulated clock; wall-clock timers do not (the history's timestamps, its one sample a
    /// second of an unchanged input and its retention, Sparkplug B and audit timestamps, the MQTT
    /// keep-alive and reconnects, console sessions): they count wall time, not simulated time.
    #[arg(long, conflicts_with = "plant")]
    pub sim_unpaced: bool,
    /// Accounts and TLS: `--users`, `--tls-cert`, `--tls-key` (`super::ui_access`).
    #[command(flatten)]
    pub access: super::ui_access::AccessArgs,
    /// Modbus TCP: `--modbus-tcp ADDR` and its options (`super::ui_modbus`).
    #[command(flatten)]
    pub modbus: super::ui_modbus::ModbusArgs,
    /// OPC UA: `--opcua ADDR`, `--opcua-pki DIR` (`super::ui_opcua`).
    #[command(flatten)]
    pub opcua: super::ui_opcua::OpcUaArgs,
    /// Sparkplug B: `--sparkplug GROUP/EDGE_NODE`, its store, DCMD; TLS files of `--mqtt`
    /// (`super::ui_sparkplug`).
    #[command(flatten)]
    pub sparkplug: super::ui_sparkplug::SparkplugArgs,
}

/// What `ui` writes to besides the console, checked and opened before the bus is touched: the record
/// directory (it must exist: a mistyped path is not created), the history with
/// [`Retention::STANDARD`] (30 days, 1 GiB, thinned after 6 hours: it cannot grow without bound),
/// the MQTT publisher. Each refusal is a usage error naming what was given.
fn open_outputs(args: &UiArgs) -> Result<(Option<Arc<History>>, Option<Publisher>), HarnessError> {
    if !args.record_dir.is_dir() {
        return Err(HarnessError::NoSuchDirectory {
            option: "--record-dir",
            path: args.record_dir.display().to_string(),
        });
    }
    let history = match (!args.no_history).then_some(&args.history) {
        Some(path) => {
            let h = History::open(path).map_err(|e| HarnessError::History(Box::new(e)))?;
            h.set_retention(Retention::STANDARD);
            Some(Arc::new(h))
        }
        None => None,
    };
    // With --sparkplug the broker gets the Sparkplug edge node instead (`super::ui_sparkplug`).
    let publisher = match args.mqtt.as_ref().filter(|_| args.sparkplug.sparkplug.is_none()) {
        Some(url) => Some(
            Publisher::start_tls(url, "dnet-master", &args.sparkplug.tls_files())
                .map_err(|detail| HarnessError::Mqtt { url: url.clone(), detail })?,
        ),
        None => None,
    };
    Ok((history, publisher))
}

/// Runs `ui`; returns the exit status (errors before the bus is touched are returned).
pub fn execute(
    opts: &GlobalOptions,
    args: &UiArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    if let Some(file) = &args.plant {
        let plant = super::ui_plant::PlantArgs {
            file,
            listen: &args.listen,
            access: &args.access,
            record_dir: &args.record_dir,
            history: (!args.no_history).then_some(args.history.as_path()),
            mqtt: args.mqtt.as_deref(),
            tls: args.sparkplug.tls_files(),
            sparkplug: &args.sparkplug,
            cycles: args.cycles,
        };
        return super::ui_plant::execute(opts, &plant, out, err, console);
    }
    let werr = |source| HarnessError::Write { path: "standard output".into(), source };
    // Everything that can be refused, before the bus is touched.
    if args.sim_unpaced && opts.bus != BusSpec::Sim {
        writeln!(
            err,
            "error: --sim-unpaced runs the simulated bus unpaced: it needs --bus sim, not {}",
            opts.bus
        )
        .map_err(werr)?;
        return Ok(2);
    }
    let master_mac = opts.master_mac_or_default();
    let given = args.scanlist.as_deref().map(|p| read_scan_list(p, master_mac.as_raw())).transpose()?;
    let project = match args.project.as_deref().map(|f| dnet_scanner::project::read(f).map(|p| (f, p))) {
        None => None,
        Some(Ok((f, p))) => Some((f.display().to_string(), p)),
        Some(Err(e)) => {
            writeln!(err, "error: {e}").map_err(werr)?;
            return Ok(2);
        }
    };
    let mut access = args.access.open(&args.listen)?;
    access.project = project;
    if let Some(w) = args.access.warning(&args.listen) {
        writeln!(err, "warning: {w}").map_err(werr)?;
    }
    let (history, publisher) = open_outputs(args)?;
    let slave = opts.slave_description()?;
    let (commands, command_rx) = mpsc::channel();
    let placeholder = Scanner::new(Default::default(), master_mac.as_raw(), ScannerOptions::default());
    let shared = Arc::new(Shared {
        state: Mutex::new(placeholder.state().clone()),
        frames: Mutex::new(VecDeque::new()),
        commands: Mutex::new(commands),
        history: history.as_ref().map(|h| Box::new(Arc::clone(h)) as Box<dyn HistoryStore>),
        record_dir: args.record_dir.clone(),
        mqtt: Mutex::new(publisher.as_ref().map(Publisher::status)),
        audit: match &history {
            Some(h) => Arc::clone(h) as Arc<dyn dnet_scanner::audit::Audit>,
            None => Arc::new(MemoryAudit::default()),
        },
    });
    let modbus = args.modbus.start(&shared)?;
    let opcua = args.opcua.start(&shared, args.access.users.as_deref())?;
    let sparkplug = args.sparkplug.start(args.mqtt.as_deref(), &shared)?;
    let server = serve_with(&args.listen, Arc::clone(&shared), access)?;
    writeln!(out, "console at {}", server.url()).map_err(werr)?;
    if let Some(m) = &modbus {
        writeln!(out, "modbus tcp at {}", m.local_addr()).map_err(werr)?;
    }
    if let Some(o) = &opcua {
        writeln!(out, "opc ua at {}", o.url()).map_err(werr)?;
    }
    out.flush().map_err(werr)?;

    // The console is watched by people: its simulation runs in real time, unless a soak
    // measurement asks for it unpaced.
    let realtime = GlobalOptions { realtime: !args.sim_unpaced, ..opts.clone() };
    let mut bus = open_bus(&realtime, slave.as_ref().map(|d| &d.converter), None, None)?;
    let mut session = Session::new(bus.as_mut());
    session.set_stop(console.stop.clone());
    let mut master = Master::new(&mut session, opts.master_config(master_mac));
    let mut progress = if console.stderr_terminal { Progress::on(&mut *err) } else { Progress::off() };
    let sim_layout = match (&opts.bus, &slave) {
        (BusSpec::Sim, Some(d)) => Some(InputLayout::from_converter(&d.converter)),
        (BusSpec::Sim, None) => Some(InputLayout::from_converter(&DeviceDescription::reference().converter)),
        _ => None,
    };
    let mut scanner: Option<Scanner> = None;
    let mut thinning = Thinning::default();
    let mut history_error: Option<String> = None;
    // The last event published on MQTT (its sequence number).
    let mut events_seen: u64 = 0;
    let mut sparkplug_events_seen: u64 = 0;
    let result = (|| -> Result<(), HarnessError> {
        let list = match given.clone() {
            Some(l) => l,
            None => {
                progress.show("ui: building the scan list from a network scan ...");
                let mut l = build_scan_list(&mut master, 0, 63)?;
                if args.adr {
                    for n in &mut l.nodes {
                        n.adr = dnet_scanner::model::AdrMode::ConfigAddress;
                    }
                }
                l
            }
        };
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
        s.set_config_tool(Box::new(super::scanner::Configure));
        progress.show(&format!("ui: bringing {} node(s) into I/O ...", s.state().nodes.len()));
        s.start(&mut master)?;
        progress.clear();
        loop {
            if let Ok(mut state) = shared.state.lock() {
                state.clone_from(s.state());
            }
            shared.push_frames(s.take_frames(&mut master));
            if args.cycles.is_some_and(|c| s.state().cycles >= c) {
                return Ok(());
            }
            s.cycle(&mut master)?;
            while let Ok(command) = command_rx.try_recv() {
                s.command(&mut master, command);
            }
            let mut samples = thinning.keep(s.take_samples());
            // Where the bus gave no profile (a real bus), the node's identity does: the values of a
            // known device are decoded for the history and MQTT as for the device view.
            for sample in samples.iter_mut().filter(|x| x.values.is_empty()) {
                if let Some(node) = s.state().nodes.iter().find(|n| n.mac == sample.mac) {
                    let layout = layout_for(node, known_descriptions());
                    sample.values = sample_values(&layout, &sample.input);
                }
            }
            if let (Some(h), false) = (&history, samples.is_empty()) {
                match h.record(&samples) {
                    Ok(()) => history_error = None,
                    // A full disk must not stop the scanner: said once, tried again next cycle.
                    Err(e) if history_error.is_none() => {
                        progress.show(&format!("ui: the history cannot record: {e}"));
                        history_error = Some(e.to_string());
                    }
                    Err(_) => {}
                }
            }
            if let Some(p) = &publisher {
                p.publish_state(s.state());
                p.publish_samples(&samples);
                // The events since the last cycle (automatic device replacement, scan-list changes).
                let events = s.events().since(events_seen);
                events_seen = events.last().map_or(events_seen, |e| e.seq);
                p.publish_events(&events);
                if let Ok(mut status) = shared.mqtt.lock() {
                    *status = Some(p.status());
                }
            }
            if let Some(e) = &sparkplug {
                e.publish_state(s.state());
                e.publish_samples(&samples);
                let events = s.events().since(sparkplug_events_seen);
                sparkplug_events_seen = events.last().map_or(sparkplug_events_seen, |e| e.seq);
                e.publish_events(&events);
                if let Ok(mut status) = shared.mqtt.lock() {
                    *status = Some(e.status());
                }
            }
        }
    })();
    progress.clear();
    drop(progress);
    server.stop();
    drop(modbus);
    drop(opcua);
    // As `scanner`: 0 only when every node ended ok (in I/O with data exchanged).
    let Ending { interrupted, cleanup, code } = finish(&mut master, scanner.as_mut(), &result, opts.keep);
    drop(publisher);
    drop(sparkplug);
    if let Some(s) = &scanner {
        write!(out, "{}", table(s.state())).map_err(werr)?;
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
    if let Some(e) = history_error {
        writeln!(err, "warning: the history could not record every sample: {e}").map_err(werr)?;
    }
    Ok(code)
}
