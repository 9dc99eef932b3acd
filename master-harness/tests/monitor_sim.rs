//! `monitor` on the simulated bus: each device decoded by its own profile (the reference breaker,
//! the Modbus meter of `--slave-config`, the status assembly), a breaker gone silent shown stale,
//! and an interrupted run that keeps its samples, its CSV rows and its JSON summary.

use can_io::bus::Bitrate;
use can_io::sim::{PowerOn, SimBus, SimDevice};
use converter_sim::SoftSlave;
use devicenet::{CanFrame, Duration, Instant, MacId};
use dnet_scanner::monitor::{self, csv_header, csv_line, InputLayout, MonitorOptions};
use harness_common::console::{Console, Progress};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use master_core::stop::Stop;
use slave_fw::description::DeviceDescription;
use std::path::PathBuf;

fn workspace(path: &str) -> String {
    format!("{}/../{path}", env!("CARGO_MANIFEST_DIR"))
}

const METER: &str = "slave-fw/descriptions/modbus-meter.toml";
const BREAKER_WITH_STATUS: &str = "slave-fw/soft-slave/tests/descriptions/breaker-with-status.toml";

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-monitor-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// `dnet-master ARGS` in-process: exit status, stdout, stderr.
fn dnet(args: &[&str]) -> (u8, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let mut all = vec!["dnet-master"];
    all.extend_from_slice(args);
    let code = master_harness::cli::run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

fn sample_lines(out: &str) -> Vec<&str> {
    // A sample line starts with its bus time: `5.006s`.
    let timed = |t: &str| t.strip_suffix('s').is_some_and(|n| n.parse::<f64>().is_ok());
    out.lines().filter(|l| l.split_whitespace().next().is_some_and(timed)).collect()
}

#[test]
fn the_modbus_meter_is_shown_with_its_scan_list_never_as_the_breaker() {
    let meter = workspace(METER);
    let csv = temp("meter.csv");
    let (code, out, err) =
        dnet(&["--slave-config", &meter, "monitor", "--count", "3", "--csv", csv.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}{err}");
    let lines = sample_lines(&out);
    assert_eq!(lines.len(), 3, "{out}");
    for l in &lines {
        assert!(l.contains("u1 fc4 @30001+4: ") && l.contains("u1 fc3 @40101+2: "), "{l}");
        assert!(!l.contains("switch"), "{l}");
        // The status byte is named (assembly 101: 12 register bytes + status + freshness).
        assert!(l.contains("| ") && l.contains("freshness "), "{l}");
    }
    assert!(out.ends_with("3 samples\n"), "{out}");
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(
        text.lines().next().unwrap(),
        "time_s,u1:30001,u1:30002,u1:30003,u1:30004,u1:40101,u1:40102,status,freshness,stale,raw"
    );
    assert_eq!(text.lines().count(), 4, "{text}");

    let (code, out, _) = dnet(&["--json", "--slave-config", &meter, "monitor", "--count", "2"]);
    assert_eq!(code, 0, "{out}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let s = &v["samples"][0];
    assert_eq!(s["fields"][0]["name"], "u1 fc4 @30001+4");
    assert_eq!(s["fields"][1]["values"].as_array().unwrap().len(), 2);
    assert_eq!(s["raw"].as_array().unwrap().len(), 14);
    assert!(s["link"]["freshness"].is_u64(), "{s}");
}

#[test]
fn the_reference_breaker_is_decoded_as_before() {
    let csv = temp("breaker.csv");
    let (code, out, err) =
        dnet(&["monitor", "--count", "15", "--output", "0201", "--csv", csv.to_str().unwrap()]);
    assert_eq!(code, 0, "{out}{err}");
    let lines = sample_lines(&out);
    assert_eq!(lines.len(), 15, "{out}");
    assert!(lines[0].ends_with("A   0 A  B   0 A  C   0 A  N   0 A  switch open"), "{}", lines[0]);
    assert!(lines[14].ends_with("A 120 A  B 118 A  C 121 A  N   3 A  switch closed"), "{}", lines[14]);
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows[0], "time_s,phase_a,phase_b,phase_c,neutral,switch,status,freshness,stale,raw");
    assert!(rows[1].contains(",0,0,0,0,open,,,,"), "{text}");
    assert!(rows[15].contains(",120,118,121,3,closed,,,,"), "{text}");
}

#[test]
fn the_status_assembly_names_the_status_byte_and_the_freshness_counter() {
    let config = workspace(BREAKER_WITH_STATUS);
    let (code, out, err) = dnet(&["--slave-config", &config, "monitor", "--count", "4", "--epr", "1000"]);
    assert_eq!(code, 0, "{out}{err}");
    let lines = sample_lines(&out);
    assert_eq!(lines.len(), 4, "{out}");
    let freshness: Vec<u32> = lines
        .iter()
        .map(|l| {
            assert!(l.contains("switch open  | link ok, command none, freshness "), "{l}");
            l.rsplit(' ').next().unwrap().parse().unwrap()
        })
        .collect();
    // The breaker sends a status frame every second: one more good frame per sample.
    assert!(freshness.windows(2).all(|w| w[1] == w[0] + 1), "{freshness:?}\n{out}");
    // The same description given to monitor alone decodes the same way.
    let (code, with_description, _) = dnet(&[
        "--slave-config",
        &config,
        "monitor",
        "--count",
        "4",
        "--epr",
        "1000",
        "--description",
        &config,
    ]);
    assert_eq!(code, 0);
    assert_eq!(with_description, out);
    // The plain reference device decoded with this description: 18 bytes are not 20, shown raw.
    let (code, out, _) = dnet(&["monitor", "--count", "1", "--description", &config]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("00 0F 00") && out.contains("(18 bytes; the description produces 20)"), "{out}");
}

/// The converter whose breaker stops sending at `silent_at` (its transmitter dead).
struct SilencedAt {
    slave: SoftSlave,
    silent_at: Instant,
}

impl SilencedAt {
    fn check(&mut self, now: Instant) {
        if now >= self.silent_at {
            self.slave.breaker_mut().set_silent(true);
        }
    }
}

impl SimDevice for SilencedAt {
    fn mac(&self) -> MacId {
        SimDevice::mac(&self.slave)
    }
    fn power_on(&mut self, now: Instant) {
        SimDevice::power_on(&mut self.slave, now);
    }
    fn handle_frame(&mut self, frame: &CanFrame, now: Instant) {
        self.check(now);
        SimDevice::handle_frame(&mut self.slave, frame, now);
    }
    fn handle_timeout(&mut self, now: Instant) {
        self.check(now);
        SimDevice::handle_timeout(&mut self.slave, now);
    }
    fn poll_transmit(&mut self) -> Option<CanFrame> {
        SimDevice::poll_transmit(&mut self.slave)
    }
    fn poll_at(&self) -> Option<Instant> {
        SimDevice::poll_at(&self.slave)
    }
}

#[test]
fn a_silent_breaker_is_shown_stale() {
    let description = DeviceDescription::load(workspace(BREAKER_WITH_STATUS).as_ref()).unwrap();
    let layout = InputLayout::from_converter(&description.converter);
    let mut bus = SimBus::new(Bitrate::K250);
    let silent_at = Instant::from_secs(8);
    let slave = SoftSlave::new(description.converter.clone()).unwrap();
    bus.attach(Box::new(SilencedAt { slave, silent_at }), PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let opts = MonitorOptions {
        connect: ConnectOptions { epr_ms: 250, ..ConnectOptions::default() },
        count: None,
        duration: Some(Duration::from_secs(8)),
        in_place: false,
        reconnect: false,
        layout: layout.clone(),
        io: master_core::io::IoOptions::default(),
    };
    let (mut out, mut csv) = (Vec::new(), Vec::new());
    let run = monitor::monitor(&mut master, &opts, &mut out, Some(&mut csv), &mut Progress::off());
    let out = String::from_utf8(out).unwrap();
    assert!(run.ended.is_none(), "{:?}\n{out}", run.ended);
    let (live, stale): (Vec<_>, Vec<_>) = run.samples.iter().partition(|s| !s.stale);
    // The breaker sends a frame a second, the last one in (7 s, 8 s]; stale 1.5 s after it, so
    // between 8.5 s and 9.5 s (seen at the next poll, 250 ms later at most), and from then on.
    let first_stale = stale.first().map(|s| s.time_us).unwrap_or(0);
    assert!((8_500_000..=9_750_000).contains(&first_stale), "{out}");
    assert!(live.iter().all(|s| s.time_us < first_stale), "{out}");
    assert!(stale.len() >= 10, "{out}");
    assert!(live.iter().all(|s| s.link.unwrap().link == "ok"), "{out}");
    // Stale policy "clear": the image is zeroed, the freshness counter stands still.
    let last = stale.last().unwrap();
    assert!(last.raw[..18].iter().all(|b| *b == 0), "{:?}", last.raw);
    assert!(stale.iter().all(|s| s.link.unwrap().freshness == last.link.unwrap().freshness), "{out}");
    // Text, CSV and JSON all say so.
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), run.samples.len(), "{out}");
    assert!(lines.last().unwrap().contains("| STALE: LINK TIMEOUT, command none, freshness "), "{out}");
    assert!(lines[0].contains("| link ok,"), "{out}");
    let csv = String::from_utf8(csv).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], csv_header(&layout));
    assert_eq!(rows.len(), run.samples.len() + 1);
    assert_eq!(rows.last().unwrap(), &csv_line(last, &layout));
    assert!(rows.last().unwrap().contains(",0x02,"), "{csv}");
    let stale_column = rows[0].split(',').position(|c| c == "stale").unwrap();
    assert_eq!(rows[1].split(',').nth(stale_column), Some("0"), "{csv}");
    assert_eq!(rows.last().unwrap().split(',').nth(stale_column), Some("1"), "{csv}");
    let v = serde_json::to_value(last).unwrap();
    assert_eq!(v["stale"], true);
    assert_eq!(v["link"]["link"], "timeout");
}

#[test]
fn an_interrupted_monitor_keeps_its_samples_csv_and_json() {
    let csv = temp("interrupted.csv");
    let log = temp("interrupted.log");
    let stop = Stop::new();
    let console = Console { stop: stop.clone(), ..Console::plain() };
    // A stop asked from another thread once the CSV (flushed row by row) holds three samples.
    let watcher = {
        let csv = csv.clone();
        std::thread::spawn(move || {
            let end = std::time::Instant::now() + std::time::Duration::from_secs(60);
            while std::time::Instant::now() < end {
                let rows = std::fs::read_to_string(&csv).map(|t| t.lines().count()).unwrap_or(0);
                if rows >= 4 {
                    stop.request(master_core::stop::SIGINT);
                    return rows - 1;
                }
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
            0
        })
    };
    let args = [
        "dnet-master",
        "--realtime",
        "--json",
        "--log",
        log.to_str().unwrap(),
        "monitor",
        "--epr",
        "50",
        "--csv",
        csv.to_str().unwrap(),
    ];
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = master_harness::cli::run_with(args, &mut out, &mut err, &console);
    let seen = watcher.join().unwrap();
    let out = String::from_utf8(out).unwrap();
    let err = String::from_utf8(err).unwrap();
    assert_eq!(code, 130, "{out}{err}");
    assert!(seen >= 3, "the rows were on disk while the monitor ran");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["interrupted"], "SIGINT", "{v}");
    assert_eq!(v["ok"], false);
    let samples = v["samples"].as_array().unwrap();
    assert!(samples.len() >= seen, "{} samples, {seen} rows seen", samples.len());
    assert_eq!(samples[0]["fields"][4]["text"], "open");
    let rows: Vec<String> = std::fs::read_to_string(&csv).unwrap().lines().map(String::from).collect();
    assert_eq!(rows.len(), samples.len() + 1, "every sample has its row");
    assert!(rows[1..].iter().all(|r| r.contains(",0,0,0,0,open,")), "{rows:#?}");
    let logged = std::fs::read_to_string(&log).unwrap();
    assert!(logged.lines().count() > 28, "{logged}");
    // The device got its connections back: the last frames release them.
    assert!(logged.contains("#004C03"), "{logged}");
}

#[test]
fn an_interrupted_monitor_in_text_mode_says_how_many_samples() {
    let stop = Stop::new();
    let console = Console { stop: stop.clone(), ..Console::plain() };
    /// Standard output that asks for the stop after the fifth sample line (like Ctrl-C).
    struct Screen {
        text: Vec<u8>,
        stop: Stop,
    }
    impl std::io::Write for Screen {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.text.extend_from_slice(buf);
            if String::from_utf8_lossy(&self.text).matches("switch open").count() >= 5 {
                self.stop.request(master_core::stop::SIGTERM);
            }
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let mut out = Screen { text: Vec::new(), stop };
    let mut err = Vec::new();
    let code = master_harness::cli::run_with(["dnet-master", "monitor"], &mut out, &mut err, &console);
    let out = String::from_utf8(out.text).unwrap();
    let err = String::from_utf8(err).unwrap();
    assert_eq!(code, 143, "{out}{err}");
    assert!(out.ends_with("\n5 samples\n"), "{out}");
    assert!(err.contains("released MAC 5"), "{err}");
    assert!(err.contains("interrupted by SIGTERM"), "{err}");
}

/// A run that took no sample compared nothing of the device: exit 1, never a success, whatever
/// the connection.
#[test]
fn a_monitor_run_without_a_sample_is_not_a_success() {
    for io in ["poll", "strobe", "cos", "cyclic"] {
        let (code, out, err) = dnet(&["--bus", "sim", "monitor", "--io", io, "--count", "0"]);
        assert_eq!(code, 1, "{io}: {out}\n{err}");
        assert!(out.contains("0 samples"), "{io}: {out}");
        assert!(err.contains("nothing compared: monitor: no sample of MAC 5"), "{io}: {err}");
    }
    let (code, out, _) = dnet(&["--bus", "sim", "monitor", "--io", "cos", "--count", "1"]);
    assert_eq!(code, 0, "{out}");
}

/// `--reconnect` waits for a device that is not there when the run starts (issue 33, item 4):
/// it says so, gets the connection once the device is on-line, and samples until the end.
#[test]
fn reconnect_waits_for_a_device_absent_at_the_start() {
    let (code, out, err) =
        dnet(&["--slave-power-on", "6000", "monitor", "--reconnect", "--duration", "12", "--epr", "200"]);
    assert_eq!(code, 0, "{out}\n{err}");
    assert!(out.contains("MAC 5 does not answer: "), "{out}");
    assert!(out.contains("waiting for it (--reconnect)"), "{out}");
    let connected = out.lines().position(|l| l.starts_with("connected at ")).expect("connected");
    let samples = sample_lines(&out);
    assert!(samples.len() > 5, "{out}");
    assert!(samples.iter().all(|l| l.contains("switch open")), "{out}");
    assert!(out.lines().skip(connected).filter(|l| samples.contains(l)).count() == samples.len(), "{out}");
    assert!(!out.contains("check(s) failed"), "{out}");
    // Without --reconnect the same start ends the run: the device does not answer.
    let (code, _, err) = dnet(&["--slave-power-on", "6000", "monitor", "--duration", "12"]);
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("no answer from MAC 5"), "{err}");
}

/// A run that ends before its first sample, stopped or failed, leaves a CSV file with its header
/// (issue 33, item 7), not an empty file.
#[test]
fn a_run_ended_before_its_first_sample_leaves_the_csv_header() {
    // Failed: the device never comes on-line.
    let csv = temp("absent.csv");
    let (code, _, err) =
        dnet(&["--slave-power-on", "600000", "monitor", "--duration", "5", "--csv", csv.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text, "time_s,phase_a,phase_b,phase_c,neutral,switch,status,freshness,stale,raw\n");
    // Stopped: a stop asked before the run started, as a Ctrl-C during the network access.
    let csv = temp("stopped.csv");
    let stop = Stop::new();
    stop.request(master_core::stop::SIGINT);
    let console = Console { stop, ..Console::plain() };
    let args = ["dnet-master", "monitor", "--csv", csv.to_str().unwrap()];
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = master_harness::cli::run_with(args, &mut out, &mut err, &console);
    assert_eq!(code, 130, "{}", String::from_utf8_lossy(&err));
    let text = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(text, "time_s,phase_a,phase_b,phase_c,neutral,switch,status,freshness,stale,raw\n");
}
