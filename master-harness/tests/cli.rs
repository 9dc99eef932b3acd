//! The `dnet-master` binary: exit status, table, JSON, log files, and clear errors.

use std::path::PathBuf;
use std::process::{Command, Output};

fn dnet(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dnet-master")).args(args).output().expect("run dnet-master")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnet-master-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn connect_prints_the_table_and_exits_zero() {
    let o = dnet(&["--bus", "sim", "connect", "--mac", "5"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    let out = stdout(&o);
    let rows: Vec<&str> = out.lines().filter(|l| l.contains(" M-> ") || l.contains(" S-> ")).collect();
    // The 28 frames of protocol §2, then the connections given back through the Group 2 Only port.
    assert_eq!(rows.len(), 30, "{out}");
    assert!(rows[27].contains("3C5  82 00 00 00 00") && rows[27].ends_with("ok"), "{}", rows[27]);
    assert!(rows[28].contains("42E  00 4C 03 01 03") && rows[28].ends_with("sent"), "{}", rows[28]);
    assert!(rows[29].contains("42B  00 CC") && rows[29].ends_with("ok"), "{}", rows[29]);
    assert!(out.contains("30 frames, every check holds"), "{out}");
    // --keep: exactly the 28 frames, the device left allocated (and said so).
    let o = dnet(&["--bus", "sim", "--keep", "connect", "--mac", "5"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("28 frames, every check holds"), "{}", stdout(&o));
    assert!(
        stderr(&o).contains("MAC 5: explicit|poll kept allocated to master MAC 0 (--keep)"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn log_is_candump_and_replays() {
    let log = temp("connect.log");
    let o = dnet(&["--keep", "connect", "--log", log.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0));
    let text = std::fs::read_to_string(&log).unwrap();
    assert_eq!(text.lines().count(), 28);
    assert!(text.lines().next().unwrap().ends_with(" sim 407#00010004030201"), "{text}");
    let o = dnet(&["replay", log.to_str().unwrap(), "--mac", "5"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("replay held: 28 frames, 14 from the device compared byte for byte"));
    // One wrong byte: exit 1 with the divergence report on stderr.
    let bad = temp("bad.log");
    std::fs::write(&bad, text.replace("42B#008E0100", "42B#008E0200")).unwrap();
    let o = dnet(&["replay", bad.to_str().unwrap(), "--mac", "5"]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(err.contains("replay diverged at transcript line 16"), "{err}");
    assert!(err.contains("expected: 42B#008E0200") && err.contains("actual:   42B#008E0100"), "{err}");
    assert!(err.contains("frames before it:"), "{err}");
}

#[test]
fn json_result() {
    let o = dnet(&["--json", "connect"]);
    assert_eq!(o.status.code(), Some(0));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["ok"], true);
    assert_eq!(v["frames"].as_array().unwrap().len(), 30);
    assert!(v["version"].as_str().unwrap().starts_with("0.1.0 ("), "{v}");
    assert_eq!(v["frames"][7]["data"], "00CB00");
    assert_eq!(v["device"]["produced_size"], 18);
}

#[test]
fn malformed_transcript_names_the_line() {
    let bad = temp("malformed.log");
    std::fs::write(
        &bad,
        "(0.000436) sim 407#00010004030201\n(1.000436) sim 407#000100040302\n(2.0) sim 42F\n",
    )
    .unwrap();
    // --strict: the line is an error, named with its column.
    let o = dnet(&["replay", "--strict", bad.to_str().unwrap(), "--mac", "5"]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(err.contains("malformed.log:3:11: invalid frame '42F': expected ID#DATA"), "{err}");
    // By default it is skipped and named, and the rest is replayed.
    let o = dnet(&["replay", bad.to_str().unwrap(), "--mac", "5"]);
    let err = stderr(&o);
    assert!(err.contains("malformed.log: 1 line skipped, not DeviceNet traffic"), "{err}");
    assert!(err.contains("malformed.log:3: invalid frame '42F': expected ID#DATA"), "{err}");
}

#[test]
fn unknown_bus_is_a_usage_error() {
    let o = dnet(&["--bus", "can0", "connect"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("unknown bus 'can0': expected sim, socketcan:IFACE or slcan:PATH[@SERIALBAUD]")
    );
}

#[test]
fn the_device_at_the_masters_mac_is_a_usage_error() {
    let o = dnet(&["--bus", "sim", "connect", "--mac", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("the device's MAC 0 is the master's own MAC"), "{}", stderr(&o));
}

#[test]
fn missing_slcan_port_is_named() {
    let o = dnet(&["--bus", "slcan:/nonexistent/ttyACM9", "scan"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("cannot open serial port '/nonexistent/ttyACM9'"), "{}", stderr(&o));
}

#[test]
fn a_device_that_never_answers() {
    // The simulated device stays at 5; nothing answers at 9.
    let o = dnet(&["--slave-mac", "5", "connect", "--mac", "9"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("no answer from MAC 9 within 1000ms (explicit response timeout)"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn get_fragmented_and_error_response() {
    let o = dnet(&["get", "5", "1", "1", "7"]);
    assert_eq!(o.status.code(), Some(0));
    assert!(stdout(&o).contains("\"Serial-DeviceNet Bridge\" (fragmented response)"), "{}", stdout(&o));
    let o = dnet(&["get", "5", "0x01", "1", "99"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("attribute not supported (0x14), additional code 0xFF"), "{}", stderr(&o));
    let o = dnet(&["set", "5", "4", "150", "3", "01 02 03 04 05 06 07 08", "--frames"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("fragment last #1"), "{}", stdout(&o));
}

#[test]
fn scan_several_slaves() {
    let o = dnet(&["--slave-mac", "2,5,40", "--bitrate", "500k", "scan", "--timeout", "200"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let out = stdout(&o);
    assert!(out.contains("3 device(s) found among 63 MAC IDs"), "{out}");
    assert!(
        out.contains(" 40  0x1234  0x000C        1  1.1    0x1234569B  Serial-DeviceNet Bridge"),
        "{out}"
    );
}

#[test]
fn monitor_records_csv() {
    let csv = temp("monitor.csv");
    // The close command reaches the breaker at once; its next status frame (once a second)
    // shows the switch closed and the load.
    let o = dnet(&["monitor", "--count", "15", "--output", "0201", "--csv", csv.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_eq!(stdout(&o).lines().filter(|l| l.contains("switch")).count(), 15);
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "time_s,phase_a,phase_b,phase_c,neutral,switch,status,freshness,stale,raw");
    assert_eq!(lines.len(), 16);
    assert!(lines[1].contains(",open,"), "{text}");
    assert!(lines[15].contains("120,118,121,3,closed,"), "{text}");
}

#[test]
fn decode_a_log() {
    let log = temp("decode.log");
    let o = dnet(&["get", "5", "1", "1", "7", "--log", log.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0));
    let o = dnet(&["decode", log.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0));
    assert!(stdout(&o).contains("=> reassembled 26 bytes: Get_Attribute_Single response: Identity(1) inst 1 attr 7 (product name)"), "{}", stdout(&o));
    let o = dnet(&["--json", "decode", log.to_str().unwrap()]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(v["frames"].as_array().unwrap().iter().any(|f| f["message"].is_string()));
}

#[test]
fn slave_config_descriptions() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../slave-fw/descriptions");
    // The shipped breaker description is the reference device: the 28 frames hold.
    let o = dnet(&["--slave-config", &format!("{dir}/breaker.toml"), "connect"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // The Modbus gateway sits at MAC 7 and produces 14 bytes.
    let o = dnet(&["--slave-config", &format!("{dir}/modbus-meter.toml"), "get", "7", "4", "101", "4"]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert!(stdout(&o).contains("0E 00"), "{}", stdout(&o));
    // A bad file: exit 2 with the file and the key.
    let bad = temp("bad-device.toml");
    let text =
        std::fs::read_to_string(format!("{dir}/breaker.toml")).unwrap().replace("mac_id = 5", "mac_id = 99");
    std::fs::write(&bad, text).unwrap();
    let o = dnet(&["--slave-config", bad.to_str().unwrap(), "connect"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("bad-device.toml: line 17: network.mac_id: 99 is outside 0..=63"),
        "{}",
        stderr(&o)
    );
    let o = dnet(&["--slave-config", "/nonexistent.toml", "connect"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot read"), "{}", stderr(&o));
}

#[test]
fn help_everywhere() {
    for sub in ["connect", "replay", "scan", "get", "set", "monitor", "decode"] {
        let o = dnet(&[sub, "--help"]);
        assert_eq!(o.status.code(), Some(0), "{sub}");
        assert!(stdout(&o).contains("Usage: dnet-master"), "{sub}");
    }
}

#[test]
fn version_names_the_package_version_and_the_commit() {
    let o = dnet(&["--version"]);
    assert_eq!(o.status.code(), Some(0));
    let text = stdout(&o);
    assert!(text.starts_with(concat!("dnet-master ", env!("CARGO_PKG_VERSION"), " (")), "{text}");
    assert_eq!(text.trim_end(), format!("dnet-master {}", harness_common::version()));
}

fn workspace_file(path: &str) -> String {
    pty_rig::workspace_dir().join(path).to_str().unwrap().to_string()
}

#[test]
fn the_simulated_device_is_where_the_command_asks() {
    // At --mac 63, keeping the reference identity (serial 0x12345678).
    let o = dnet(&["--bus", "sim", "get", "63", "1", "1", "6"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("0x12345678"), "{}", stdout(&o));
    // --slave-config without --mac: the description's MAC (7 for the meter).
    let meter = workspace_file("slave-fw/descriptions/modbus-meter.toml");
    let o = dnet(&["--bus", "sim", "--slave-config", &meter, "connect"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("device MAC 7:"), "{}", stdout(&o));
}

#[test]
fn replay_takes_the_device_and_master_from_the_transcript() {
    let log = temp("mac63.log");
    let o = dnet(&[
        "--bus",
        "sim",
        "--master-mac",
        "2",
        "connect",
        "--mac",
        "63",
        "--log",
        log.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    // No --mac, no --master-mac: both from the transcript; the simulated device is placed at 63.
    let o = dnet(&["--bus", "sim", "replay", log.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("replay held: 30 frames, 15 from the device compared"), "{}", stdout(&o));
    let o = dnet(&["--bus", "sim", "replay", log.to_str().unwrap(), "--mac", "63"]);
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    // The same transcript on standard input.
    let o = dnet_with_stdin(&["--bus", "sim", "replay", "-"], &std::fs::read(&log).unwrap());
    assert_eq!(o.status.code(), Some(0), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("replay held: 30 frames, 15 from the device compared"), "{}", stdout(&o));
}

#[test]
fn a_replay_that_compares_nothing_fails() {
    let log = temp("mac5.log");
    let o = dnet(&["--keep", "connect", "--log", log.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(0));
    let o = dnet(&["--json", "replay", log.to_str().unwrap(), "--mac", "7"]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["ok"], false);
    let error = v["error"].as_str().unwrap();
    assert!(error.contains("nothing compared: the transcript has no frame from MAC 7"), "{error}");
    assert!(error.contains("the transcript's device is MAC 5 (--mac 5)"), "{error}");
}

#[test]
fn an_unwritable_csv_is_refused_before_the_bus_is_touched() {
    let log = temp("unwritable-csv.log");
    let o =
        dnet(&["monitor", "--count", "2", "--csv", "/nonexistent/dir/x.csv", "--log", log.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("cannot write /nonexistent/dir/x.csv"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&log).unwrap_or_default(), "", "no frame was sent");
}

#[test]
fn a_stop_request_ends_the_command_with_everything_kept() {
    use harness_common::console::Console;
    let console = Console::plain();
    let stop = console.stop.clone();
    let log = temp("stopped.log");
    let asker = std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_millis(3500));
        stop.request(master_core::stop::SIGTERM);
    });
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let args = [
        "dnet-master",
        "--json",
        "--realtime",
        "--slave-power-on",
        "start",
        "--log",
        log.to_str().unwrap(),
        "connect",
        "--polls",
        "1000000",
    ];
    let code = master_harness::cli::run_with(args, &mut out, &mut err, &console);
    asker.join().unwrap();
    let out = String::from_utf8_lossy(&out);
    assert_eq!(code, 143, "{out}{}", String::from_utf8_lossy(&err));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["interrupted"], "SIGTERM");
    let frames = v["frames"].as_array().unwrap();
    assert!(frames.len() > 28, "polls were recorded: {}", frames.len());
    assert_eq!(
        std::fs::read_to_string(&log).unwrap().lines().count(),
        frames.len(),
        "the log holds every frame"
    );
    // The last exchange gives the device back.
    assert_eq!(frames[frames.len() - 2]["data"], "004C030103");
    assert_eq!(frames[frames.len() - 1]["data"], "00CC");
}

/// `dnet-master args` with `input` on standard input.
fn dnet_with_stdin(args: &[&str], input: &[u8]) -> Output {
    use std::io::Write as _;
    let mut child = Command::new(env!("CARGO_BIN_EXE_dnet-master"))
        .args(args)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run dnet-master");
    child.stdin.take().unwrap().write_all(input).unwrap();
    child.wait_with_output().unwrap()
}

#[test]
fn decode_reads_standard_input_given_as_dash() {
    let log = "(0.000100) can0 42C#000E010101\n(0.000300) can0 42B#008E3412\n";
    let out = dnet_with_stdin(&["decode", "-"], log.as_bytes());
    assert!(out.status.success(), "{}{}", stdout(&out), stderr(&out));
    assert!(stdout(&out).contains("Identity(1) inst 1 attr 1 (vendor ID) = 0x1234"), "{}", stdout(&out));
    // A bad line is named as on standard input; with nothing else there, nothing was decoded.
    let out = dnet_with_stdin(&["decode", "-"], b"(0.1) can0 42C#0\n");
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("standard input:1: odd number of hex digits"), "{}", stderr(&out));
    assert!(stderr(&out).contains("standard input: no DeviceNet frames"), "{}", stderr(&out));
    // Read line by line, the skipped lines are counted and named as those of a file are.
    let log = b"(0.1) can0 42C#0\n(0.000100) can0 42C#000E010101\n(0.2) can0 42C#1\n";
    let out = dnet_with_stdin(&["decode", "-"], log);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("standard input: 2 lines skipped, not DeviceNet traffic")
            && stderr(&out).contains("standard input:3: odd number of hex digits"),
        "{}",
        stderr(&out)
    );
    let out = dnet_with_stdin(&["decode", "--strict", "-"], b"(0.1) can0 42C#0\n");
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("standard input:1:"), "{}", stderr(&out));
}

#[test]
fn decode_reads_every_format_by_its_content() {
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/../can-io/tests/data");
    for (file, format) in [
        ("binary/bring-up.pcapng", "pcapng"),
        ("binary/bring-up.blf", "blf"),
        ("text/bring-up-v11.trc", "trc"),
        ("text/bring-up.asc", "asc"),
        ("text/bring-up.csv", "csv"),
    ] {
        // Copied to a name without the extension: the content tells the format.
        let copy = temp(&format!("no-extension-{format}"));
        std::fs::copy(format!("{data}/{file}"), &copy).unwrap();
        let o = dnet(&["--json", "decode", copy.to_str().unwrap()]);
        assert!(o.status.success(), "{file}: {}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(stdout(&o).trim()).unwrap();
        assert_eq!(v["format"], format, "{file}");
        assert_eq!(v["frames"].as_array().unwrap().len(), 30, "{file}");
        assert!(
            v["frames"][27]["message"].as_str().unwrap().contains("poll response from MAC 5, 18 bytes"),
            "{file}: {v}"
        );
    }
    // Foreign records: decoded around, counted and named; the JSON says how many.
    let o = dnet(&["--json", "decode", &format!("{data}/binary/foreign.blf")]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("4 records skipped, not DeviceNet traffic"), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(stdout(&o).trim()).unwrap();
    assert_eq!(v["skipped"], 4);
    assert_eq!(
        v["skipped_first"][0]["reason"],
        "error frame (CAN_ERROR_EXT object) is not DeviceNet traffic"
    );
    assert_eq!(v["frames"][0]["direction"], "Rx");
    // A named format overrides detection; a wrong one reads nothing and says so.
    let o = dnet(&["decode", "--input-format", "asc", &format!("{data}/text/bring-up.csv")]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("no DeviceNet frames in this asc trace"), "{}", stderr(&o));
    let o = dnet(&["decode", "--input-format", "xls", &format!("{data}/text/bring-up.csv")]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("unknown trace format 'xls' (one of: candump, pcap, pcapng, trc, asc, blf, csv)"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn format_names_the_log_files_format() {
    let asc = temp("format.asc");
    let o =
        dnet(&["--bus", "sim", "--log", asc.to_str().unwrap(), "--format", "asc", "connect", "--mac", "5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&asc).unwrap();
    assert!(text.starts_with("date ") && text.trim_end().ends_with("End TriggerBlock"), "{text}");
    assert!(
        text.contains("42E             Tx   d 6 00 4B 03 01 01 00"),
        "the master's own frames are Tx: {text}"
    );
    let o = dnet(&["--bus", "sim", "--format", "asc", "connect", "--mac", "5"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--format names the format of the --log file"), "{}", stderr(&o));
    let o = dnet(&["--bus", "sim", "--log", asc.to_str().unwrap(), "--format", "pcapng", "connect"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--log writes candump, trc, asc or csv"), "{}", stderr(&o));
}
