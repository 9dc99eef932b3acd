//! `contrib/wireshark/devicenet.lua` (issue 16) in tshark: captures of the master on the simulated
//! bus are written as pcap files (link type SocketCAN, as `--pcap` writes them), tshark reads them
//! with the dissector loaded, and the fields are checked frame by frame: the identifier, the
//! services, class/instance/attribute of each request, the allocation choices, the reassembled
//! 18-byte poll response and product name, error responses, and the Offline Connection Set. The
//! Info column must read exactly like the Rust decoder (`master_core::decode`) on every frame.
//!
//! Needs tshark (Debian: `tshark`; `wireshark-common` comes with it), so it is ignored in ordinary
//! runs; `scripts/check` runs it:
//! `cargo test -p system-tests --test wireshark -- --ignored`.
//! It fails, never skips, when tshark is missing or the script does not load: a run in which
//! the dissector did not decode anything must not read as a pass.

use can_io::bus::Bitrate;
use can_io::pcap::{file_header, record};
use devicenet::{CanFrame, Instant};
use master_core::decode::Decoder;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::{Record, Session};
use std::path::{Path, PathBuf};
use std::process::Command;
use system_tests::{mac, sim_bus};

/// The fields read from tshark, in this order, after `frame.number`.
const FIELDS: [&str; 20] = [
    "frame.protocols",
    "dnetx.group",
    "dnetx.msgid",
    "dnetx.mac",
    "dnetx.service",
    "dnetx.response",
    "dnetx.class",
    "dnetx.instance",
    "dnetx.attribute",
    "dnetx.alloc.choice",
    "dnetx.frag.type",
    "dnetx.frag.count",
    "dnetx.reassembled.length",
    "dnetx.fragment",
    "dnetx.value",
    "dnetx.error.general",
    "dnetx.error.additional",
    "dnetx.io.data",
    "dnetx.summary",
    "_ws.col.Info",
];

/// One frame as tshark decoded it.
#[derive(Debug)]
struct Row {
    number: u32,
    fields: Vec<String>,
}

impl Row {
    fn get(&self, field: &str) -> &str {
        let i = FIELDS.iter().position(|f| *f == field).expect("a field of FIELDS");
        &self.fields[i]
    }
}

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../contrib/wireshark/devicenet.lua")
}

/// A scratch directory of this test process.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dnetx-wireshark-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `frames` as a SocketCAN pcap file (what `--pcap` writes).
fn write_pcap(path: &Path, frames: &[(Instant, CanFrame)]) {
    let mut bytes = file_header().to_vec();
    for (at, frame) in frames {
        bytes.extend_from_slice(&record(*at, frame));
    }
    std::fs::write(path, bytes).unwrap();
}

fn records_pcap(name: &str, records: &[Record]) -> PathBuf {
    let path = scratch(name).join(format!("{name}.pcap"));
    let frames: Vec<(Instant, CanFrame)> = records.iter().map(|r| (r.at, r.frame)).collect();
    write_pcap(&path, &frames);
    path
}

/// Runs tshark on `pcap` with the dissector and returns one row per frame. Panics (the test
/// fails) when tshark cannot run, exits with an error or reports a Lua error.
fn tshark(pcap: &Path) -> Vec<Row> {
    let tshark = std::env::var("DNET_TSHARK").unwrap_or_else(|_| "tshark".into());
    // A fresh home: no personal preferences, and no installed copy of the plugin registering the
    // protocol a second time.
    let home = scratch("home");
    let mut cmd = Command::new(&tshark);
    cmd.env("HOME", &home)
        .env("XDG_CONFIG_HOME", home.join(".config"))
        .arg("-X")
        .arg(format!("lua_script:{}", script().display()))
        .arg("-r")
        .arg(pcap)
        .args(["-T", "fields", "-E", "separator=/t", "-E", "occurrence=a", "-E", "aggregator=,"])
        .args(["-e", "frame.number"]);
    for f in FIELDS {
        cmd.args(["-e", f]);
    }
    let out = cmd.output().unwrap_or_else(|e| {
        panic!("cannot run {tshark} ({e}): install it (Debian: apt-get install tshark) or set DNET_TSHARK")
    });
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "tshark failed ({}):\n{stderr}", out.status);
    assert!(
        !stderr.contains("Lua") && !stderr.to_lowercase().contains("error"),
        "tshark reported a problem with the dissector:\n{stderr}"
    );
    let rows: Vec<Row> = stdout
        .lines()
        .map(|line| {
            let mut cols = line.split('\t').map(str::to_string);
            let number = cols.next().unwrap().parse().unwrap();
            let fields: Vec<String> = cols.collect();
            assert_eq!(fields.len(), FIELDS.len(), "frame {number}: {line}");
            Row { number, fields }
        })
        .collect();
    // The dissector ran on every frame.
    for r in &rows {
        assert_eq!(
            r.get("frame.protocols"),
            "can:dnetx",
            "frame {} not decoded by the dissector: {r:?}",
            r.number
        );
        assert!(!r.get("dnetx.summary").is_empty(), "frame {}: no summary: {r:?}", r.number);
    }
    rows
}

/// Every frame's Info column is the Rust decoder's text of it.
fn assert_info_is_the_decoders(rows: &[Row], records: &[Record]) {
    assert_eq!(rows.len(), records.len(), "one row per frame");
    for (row, rec) in rows.iter().zip(records) {
        assert_eq!(
            row.get("_ws.col.Info"),
            rec.meaning,
            "frame {} (0x{:03X})",
            row.number,
            rec.frame.id().as_raw()
        );
    }
}

fn bring_up() -> Vec<Record> {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    master.connect(&ConnectOptions::default()).unwrap();
    master.release_held().unwrap();
    session.records().to_vec()
}

/// (group, message ID, identifier MAC) of each frame of the bring-up (protocol §2), and the release.
const BRING_UP_IDS: [(&str, &str, &str); 30] = [
    ("2", "0x07", "0"),
    ("2", "0x07", "0"),
    ("2", "0x07", "5"),
    ("2", "0x07", "5"),
    ("3", "0x06", "0"),
    ("3", "0x06", "0"),
    ("2", "0x06", "5"),
    ("2", "0x03", "5"),
    ("2", "0x04", "5"),
    ("2", "0x03", "5"),
    ("2", "0x04", "5"),
    ("2", "0x03", "5"),
    ("2", "0x04", "5"),
    ("2", "0x03", "5"),
    ("2", "0x04", "5"),
    ("2", "0x03", "5"),
    ("2", "0x04", "5"),
    ("2", "0x03", "5"),
    ("2", "0x04", "5"),
    ("2", "0x03", "5"),
    ("2", "0x04", "5"),
    ("2", "0x03", "5"),
    ("2", "0x04", "5"),
    ("2", "0x03", "5"),
    ("2", "0x05", "5"),
    ("1", "0x0f", "5"),
    ("1", "0x0f", "5"),
    ("1", "0x0f", "5"),
    ("2", "0x06", "5"),
    ("2", "0x03", "5"),
];

#[test]
#[ignore = "needs tshark: run by scripts/check"]
fn the_bring_up_decodes_frame_by_frame() {
    let records = bring_up();
    let rows = tshark(&records_pcap("bringup", &records));
    assert_info_is_the_decoders(&rows, &records);
    for (row, (group, msgid, mac)) in rows.iter().zip(BRING_UP_IDS) {
        assert_eq!(
            (row.get("dnetx.group"), row.get("dnetx.msgid"), row.get("dnetx.mac")),
            (group, msgid, mac),
            "frame {}",
            row.number
        );
    }
    // Requests: frame number -> (service, class, instance, attribute); responses carry the
    // request's class/instance/attribute as generated fields.
    let requests: [(u32, &str, &str, &str, &str); 11] = [
        (7, "0x4b", "0x0003", "1", ""),
        (9, "0x10", "0x0005", "1", "12"),
        (11, "0x0e", "0x0001", "1", "1"),
        (13, "0x0e", "0x0001", "1", "2"),
        (15, "0x0e", "0x0001", "1", "3"),
        (17, "0x4b", "0x0003", "1", ""),
        (19, "0x0e", "0x0005", "2", "7"),
        (21, "0x0e", "0x0005", "2", "8"),
        (23, "0x10", "0x0005", "2", "9"),
        (29, "0x4c", "0x0003", "1", ""),
        (8, "0x4b", "0x0003", "1", ""),
    ];
    for (n, service, class, instance, attribute) in requests {
        let row = &rows[n as usize - 1];
        assert_eq!(
            (
                row.get("dnetx.service"),
                row.get("dnetx.class"),
                row.get("dnetx.instance"),
                row.get("dnetx.attribute")
            ),
            (service, class, instance, attribute),
            "frame {n}"
        );
    }
    for n in [7, 9, 11, 17, 23, 29] {
        assert_eq!(rows[n - 1].get("dnetx.response"), "0", "frame {n} is a request");
        assert_eq!(rows[n].get("dnetx.response"), "1", "frame {} is a response", n + 1);
    }
    // Allocation choices: explicit on the Group 2 Only port, then poll on the explicit connection.
    assert_eq!(rows[6].get("dnetx.alloc.choice"), "0x01");
    assert_eq!(rows[16].get("dnetx.alloc.choice"), "0x02");
    // Typed values of the responses.
    assert_eq!(rows[11].get("dnetx.value"), "0x1234 (4660)");
    assert_eq!(rows[19].get("dnetx.value"), "18 bytes");
    assert_eq!(rows[21].get("dnetx.value"), "8 bytes");
    assert_eq!(rows[23].get("dnetx.value"), "100 ms");
    assert_eq!(rows[8].get("dnetx.value"), "3 (deferred delete)");
    // The poll response: three I/O fragments (first #0, middle #1, last #2) reassembled to the
    // 18-byte input in the last one.
    let frags: Vec<(&str, &str)> =
        rows[25..28].iter().map(|r| (r.get("dnetx.frag.type"), r.get("dnetx.frag.count"))).collect();
    assert_eq!(frags, [("0", "0"), ("1", "1"), ("2", "2")]);
    let last = &rows[27];
    assert_eq!(last.get("dnetx.reassembled.length"), "18");
    assert_eq!(last.get("dnetx.fragment"), "26,27,28");
    let input = ["00"; 9].join(" ") + " 0f " + &["00"; 8].join(" ");
    assert_eq!(last.get("dnetx.io.data"), input);
    // The poll command is 8 bytes, not fragmented.
    assert_eq!(rows[24].get("dnetx.frag.type"), "");
    assert_eq!(rows[24].get("dnetx.io.data"), ["00"; 8].join(" "));
}

#[test]
#[ignore = "needs tshark: run by scripts/check"]
fn a_fragmented_product_name_and_an_error_response_decode() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    master.open_explicit(mac(5)).unwrap();
    let (name, _) = master.get(mac(5), 1, 1, 7).unwrap();
    assert!(name.len() > 7, "the product name must be long enough to fragment: {name:?}");
    let _ = master.get(mac(5), 1, 1, 42);
    master.release_held().unwrap();
    let records = session.records().to_vec();
    let rows = tshark(&records_pcap("name", &records));
    assert_info_is_the_decoders(&rows, &records);

    // The request, then the response fragments from the slave each acked by the master.
    let request = rows.iter().position(|r| r.get("dnetx.attribute") == "7" && r.get("dnetx.response") == "0");
    let request = request.expect("the Get_Attribute_Single of attribute 7");
    assert_eq!(rows[request].get("dnetx.service"), "0x0e");
    assert_eq!(rows[request].get("dnetx.class"), "0x0001");
    let fragments: Vec<&Row> =
        rows[request + 1..].iter().take_while(|r| !r.get("dnetx.frag.type").is_empty()).collect();
    let types: Vec<&str> = fragments.iter().map(|r| r.get("dnetx.frag.type")).collect();
    assert_eq!(types, ["0", "3", "1", "3", "1", "3", "1", "3", "2", "3"], "first, middles, last, each acked");
    let last = fragments[8];
    assert_eq!(last.get("dnetx.value"), "\"Serial-DeviceNet Bridge\"");
    assert_eq!(last.get("dnetx.reassembled.length"), "26");
    assert_eq!(
        (last.get("dnetx.class"), last.get("dnetx.instance"), last.get("dnetx.attribute")),
        ("0x0001", "1", "7")
    );
    let numbers: Vec<String> = fragments.iter().step_by(2).map(|r| r.number.to_string()).collect();
    assert_eq!(last.get("dnetx.fragment"), numbers.join(","));

    // Attribute 42 does not exist: an error response with its codes.
    let error = rows.iter().find(|r| !r.get("dnetx.error.general").is_empty()).expect("an error response");
    assert_eq!((error.get("dnetx.error.general"), error.get("dnetx.error.additional")), ("0x14", "0xff"));
    assert_eq!(error.get("dnetx.service"), "0x14");
}

/// Frames that the master does not produce on the simulated bus (protocol §3.5, §3.7, §3.8, §II.6):
/// a duplicate MAC ID response, heartbeat and shutdown, the Offline Connection Set, a fragmented
/// request, an error with an additional code, an invalid identifier.
#[test]
#[ignore = "needs tshark: run by scripts/check"]
fn offline_connection_set_and_other_messages_decode() {
    let frames: Vec<(u16, Vec<u8>)> = vec![
        (0x42F, vec![0x80, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]),
        (0x42B, vec![0x05, 0xCD, 0x01, 0x00, 0x03, 0x00, 0x00, 0x00]),
        (0x42B, vec![0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00]),
        (0x7EF, vec![0x0A, 0x4B, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01]),
        (0x7EE, vec![0x0A, 0xCB, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]),
        (0x7ED, vec![0x3F, 0x4B, 0x02]),
        (0x7EC, vec![0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]),
        (0x7ED, vec![0x45, 0x4C]),
        (0x7ED, vec![0x3F, 0x4C, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]),
        (0x7EC, vec![0x45, 0xCC]),
        (0x7ED, vec![0x07, 0x4D, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]),
        // Notes §4.1 (PICO): a fragmented request from master 0 to MAC 3, acked by the slave.
        (0x41C, vec![0x80, 0x00, 0x32, 0x64, 0x01, 0x93, 0x05, 0x00]),
        (0x41B, vec![0x80, 0xC0, 0x00]),
        (0x41C, vec![0x80, 0x81, 0x01]),
        (0x42E, vec![0x00, 0x4B, 0x03, 0x01, 0x02, 0x01]),
        (0x42B, vec![0x00, 0x94, 0x0C, 0x01]),
        (0x7F5, vec![0x01]),
    ];
    let frames: Vec<(Instant, CanFrame)> = frames
        .iter()
        .enumerate()
        .map(|(i, (id, data))| (Instant::from_millis(i as u64), CanFrame::from_raw(*id, data).unwrap()))
        .collect();
    let path = scratch("offline").join("offline.pcap");
    write_pcap(&path, &frames);
    let rows = tshark(&path);
    assert_eq!(rows.len(), frames.len());
    let mut decoder = Decoder::new();
    for (row, (_, frame)) in rows.iter().zip(&frames) {
        assert_eq!(row.get("_ws.col.Info"), decoder.decode(frame).text(), "frame {}", row.number);
    }
    assert_eq!(rows[0].get("dnetx.msgid"), "0x07");
    assert_eq!(rows[3].get("dnetx.group"), "4");
    assert_eq!(rows[3].get("dnetx.msgid"), "0x2f");
    assert_eq!(rows[5].get("dnetx.service"), "0x4b");
    assert_eq!(rows[13].get("dnetx.reassembled.length"), "8");
    assert_eq!(rows[13].get("dnetx.fragment"), "12,14");
    assert_eq!(
        (rows[15].get("dnetx.error.general"), rows[15].get("dnetx.error.additional")),
        ("0x0c", "0x01")
    );
    assert_eq!(rows[16].get("dnetx.group"), "", "0x7F5 is no DeviceNet identifier");
}

/// Broken fragment series (issue 33, item 10): the dissector names each breach of the
/// fragmentation protocol exactly as the Rust decoder does, as a protocol error, instead of
/// dropping or joining the fragments quietly: a first fragment whose count is not 0, middle and
/// last fragments without a first, a missed fragment, a series cut off by the next first
/// fragment; I/O with and without the connection size, and explicit.
#[test]
#[ignore = "needs tshark: run by scripts/check"]
fn broken_fragment_series_are_protocol_errors() {
    let frames: Vec<(u16, Vec<u8>)> = vec![
        // MAC 6: the poll response size unknown. A whole series (the connection is fragmented),
        // then a first fragment with count 5 and a middle without a first.
        (0x3C6, vec![0x00, 0, 1, 2, 3, 4, 5, 6]),
        (0x3C6, vec![0x41, 7, 8, 9, 10, 11, 12, 13]),
        (0x3C6, vec![0x82, 14, 15, 16, 17]),
        (0x3C6, vec![0x05, 0, 1, 2, 3, 4, 5, 6]),
        (0x3C6, vec![0x41, 7, 8, 9, 10, 11, 12, 13]),
        // A missed middle fragment, then a series cut off by the next first fragment.
        (0x3C6, vec![0x00, 0, 1, 2, 3, 4, 5, 6]),
        (0x3C6, vec![0x82, 14, 15, 16, 17]),
        (0x3C6, vec![0x00, 0, 1, 2, 3, 4, 5, 6]),
        (0x3C6, vec![0x41, 7, 8, 9, 10, 11, 12, 13]),
        (0x3C6, vec![0x00, 0, 1, 2, 3, 4, 5, 6]),
        // MAC 5: the size read (18 bytes), then a last fragment without a first.
        (0x42C, vec![0x00, 0x0E, 0x05, 0x02, 0x07]),
        (0x42B, vec![0x00, 0x8E, 0x12, 0x00]),
        (0x3C5, vec![0x82, 14, 15, 16, 17]),
        // Explicit: a first fragment with count 3, a middle without a first, a missed fragment.
        (0x42C, vec![0x00, 0x0E, 0x01, 0x01, 0x07]),
        (0x42B, vec![0x80, 0x03, 0x8E, 1, 2, 3, 4, 5]),
        (0x42B, vec![0x80, 0x41, 1, 2, 3, 4, 5, 6]),
        (0x42B, vec![0x80, 0x00, 0x8E, 0x17, b'S', b'e', b'r', b'i']),
        (0x42B, vec![0x80, 0x42, b'i', b'c', b'e', b'N', b'e', b't']),
        // Plain 8-byte bit-strobe responses of MAC 7 (size unknown): no protocol error.
        (0x387, vec![0x00, 0, 0, 0, 0, 0, 0, 0]),
        (0x387, vec![0x00, 0, 0, 0, 0, 0, 0, 0]),
        (0x387, vec![0x78, 118, 121, 3, 0, 0, 0, 0]),
    ];
    let frames: Vec<(Instant, CanFrame)> = frames
        .iter()
        .enumerate()
        .map(|(i, (id, data))| (Instant::from_millis(i as u64), CanFrame::from_raw(*id, data).unwrap()))
        .collect();
    let path = scratch("fragments").join("fragments.pcap");
    write_pcap(&path, &frames);
    let rows = tshark(&path);
    assert_eq!(rows.len(), frames.len());
    let mut decoder = Decoder::new();
    let mut errors = Vec::new();
    for (row, (_, frame)) in rows.iter().zip(&frames) {
        let decoded = decoder.decode(frame);
        assert_eq!(row.get("_ws.col.Info"), decoded.text(), "frame {}", row.number);
        if decoded.protocol_error.is_some() {
            errors.push(row.number);
            assert!(row.get("_ws.col.Info").contains("(protocol error: "), "frame {}: {row:?}", row.number);
        }
    }
    assert_eq!(errors, [4, 5, 7, 10, 13, 15, 16, 18], "the frames named as protocol errors");
    // The whole series still reassembles.
    assert_eq!(rows[2].get("dnetx.reassembled.length"), "18");
}
