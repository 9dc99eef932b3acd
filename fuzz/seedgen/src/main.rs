//! Writes the seed corpora of the fuzz targets into `fuzz/seeds/<target>/` (the argument, or
//! `fuzz/seeds`), from the project's own transcripts:
//!
//! * the reference bring-up of protocol §2 and every check of the conformance suite run
//!   against the soft slave on the simulated bus: the master's frames with their timing (node and
//!   converter targets), explicit fragments and poll responses (reassemblers), the logs
//!   (`candump -L` target);
//! * the breaker's frames (status, acknowledgements, commands) and Modbus RTU requests and
//!   responses (serial parsers);
//! * the configuration images of the two description files (configuration image target);
//! * the EDS files of `eds/tests` (EDS target).
//!
//! Run from the repository root: `cargo run --manifest-path fuzz/Cargo.toml -p seedgen`.

#[allow(dead_code)]
#[path = "../../src/steps.rs"]
mod steps;

use devicenet::reference::{Direction, BRING_UP, INPUT_IMAGE};
use devicenet::MacId;
use can_io::sim::{PowerOn, SimBus};
use can_io::bus::{Bitrate, Origin};
use dnet_conformance::{self as conformance, SuiteOptions};
use can_io::log::format_line;
use master_core::master::MasterConfig;
use master_core::session::{Record, Session};
use converter_sim::device::SoftSlave;
use slave_fw::serial::breaker::{Ack, StatusData, SwitchState, FRAMING};
use slave_fw::serial::checksum::crc16_modbus;
use std::path::{Path, PathBuf};
use steps::Step;

fn write(dir: &Path, target: &str, name: &str, bytes: &[u8]) -> std::io::Result<()> {
    let d = dir.join(target);
    std::fs::create_dir_all(&d)?;
    std::fs::write(d.join(name), bytes)
}

/// The master's frames of `records` as node/converter input, with their timing.
fn master_steps(records: &[Record], serial: &[Vec<u8>]) -> Vec<u8> {
    let mut out = Vec::new();
    let mut last = records.first().map(|r| r.at);
    for (k, r) in records.iter().filter(|r| r.origin == Origin::Local).enumerate() {
        let dt = last.map_or(0, |l| (r.at - l).total_millis());
        last = Some(r.at);
        steps::encode(&mut out, dt, Step::Frame(r.frame.id().as_raw(), r.frame.data()));
        if let Some(s) = serial.get(k % serial.len().max(1)) {
            if k % 5 == 0 {
                steps::encode(&mut out, 0, Step::Serial(s));
            }
        }
    }
    out
}

fn breaker_frames() -> Vec<Vec<u8>> {
    let mut frames = Vec::new();
    let mut push = |data: &[u8]| {
        let mut out = [0u8; 32];
        if let Ok(n) = FRAMING.encode(data, &mut out) {
            frames.push(out[..n].to_vec());
        }
    };
    push(StatusData::new([0; 4], SwitchState::Open).as_bytes());
    push(StatusData::new([120, 118, 121, 3], SwitchState::Closed).as_bytes());
    push(&Ack { command: 2, status: 0 }.to_data());
    push(&Ack { command: 3, status: 2 }.to_data());
    push(&[0x02]);
    push(&[0x03, 0x01, 0x34, 0x12]);
    frames
}

fn modbus(body: &[u8]) -> Vec<u8> {
    let mut v = body.to_vec();
    v.extend_from_slice(&crc16_modbus(body).to_le_bytes());
    v
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args().nth(1).map_or_else(|| PathBuf::from("fuzz/seeds"), PathBuf::from);
    let serial = breaker_frames();

    // The conformance suite's transcript, check by check (the bring-up first).
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(SoftSlave::reference(MacId::from_low_bits(5))), PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let report =
        conformance::run(&mut session, MasterConfig::default(), &SuiteOptions::new(MacId::from_low_bits(5)))?;
    for (k, check) in report.checks.iter().enumerate() {
        // At most 120 frames per seed: small seeds keep the fuzzer fast.
        let all = report.frames_of(check);
        let records = &all[..all.len().min(120)];
        if records.is_empty() {
            continue;
        }
        let name = format!("{k:02}-{}", check.id);
        // Node and converter: the master's frames; the converter also gets breaker bytes.
        let mut node = Vec::new();
        if k == 0 {
            // Before the bring-up's frames, let the node finish its duplicate MAC ID check.
            steps::encode(&mut node, 2100, Step::Serial(&[]));
        }
        node.extend(master_steps(records, &[]));
        write(&dir, "slave_node", &name, &node)?;
        let mut conv = vec![u8::from(k % 2 == 1)];
        if k == 0 {
            steps::encode(&mut conv, 2100, Step::Serial(&serial[0]));
        }
        conv.extend(master_steps(records, &serial));
        write(&dir, "converter", &name, &conv)?;
        // candump -L text.
        let log: String = records.iter().map(|r| format_line(r.at, "sim", &r.frame) + "\n").collect();
        write(&dir, "candump_log", &format!("{name}.log"), log.as_bytes())?;
        // Explicit fragments (both directions) and poll responses, as reassembler input.
        let mut explicit = vec![0u8];
        let mut io = vec![0u8];
        for r in records {
            let id = r.frame.id().as_raw();
            let d = r.frame.data();
            if (id & 0x607) == 0x403 || (id & 0x607) == 0x404 {
                if d.first().is_some_and(|h| h & 0x80 != 0) {
                    steps::encode_chunk(&mut explicit, d);
                }
            } else if id & 0x7C0 == 0x3C0 {
                steps::encode_chunk(&mut io, d);
            }
        }
        if explicit.len() > 1 {
            write(&dir, "explicit_reassembly", &name, &explicit)?;
        }
        if io.len() > 1 {
            write(&dir, "io_reassembly", &name, &io)?;
        }
    }

    // The reference bring-up's master frames alone.
    let mut node = Vec::new();
    steps::encode(&mut node, 2100, Step::Serial(&[]));
    for f in BRING_UP.iter().filter(|f| f.direction == Direction::MasterToSlave) {
        steps::encode(&mut node, 20, Step::Frame(f.id, f.data));
    }
    write(&dir, "slave_node", "reference-bring-up", &node)?;

    // Round trips: a fragmented explicit message, the reference input image.
    let mut msg = vec![2u8, 0x00, 0x10, 0x04, 0x96, 0x03];
    msg.extend_from_slice(&INPUT_IMAGE);
    write(&dir, "explicit_reassembly", "roundtrip-25-bytes", &msg)?;
    let mut img = vec![1u8];
    img.extend_from_slice(&INPUT_IMAGE);
    write(&dir, "io_reassembly", "roundtrip-input-image", &img)?;

    // Serial frames: the breaker's framing, and a configuration byte set with its frames.
    let mut all = vec![0u8];
    for f in &serial {
        all.extend_from_slice(&[0x00, 0x68]);
        all.extend_from_slice(f);
    }
    write(&dir, "framed_parser", "breaker-frames", &all)?;
    let mut custom = vec![1u8, 0x02, 0x82, 0x00, 0x03, 0x01, 0x20];
    custom.extend_from_slice(b"\x02HELLO\x1e\x03");
    write(&dir, "framed_parser", "delimited-ascii", &custom)?;

    // Modbus RTU (the specification's examples).
    for (name, body) in [
        ("read-holding-request", &[0x01u8, 0x03, 0x00, 0x6B, 0x00, 0x03][..]),
        ("read-holding-response", &[0x01, 0x03, 0x06, 0x02, 0x2B, 0x00, 0x00, 0x00, 0x64]),
        ("write-single-request", &[0x01, 0x06, 0x00, 0x01, 0x00, 0x03]),
        ("write-multiple-request", &[0x01, 0x10, 0x00, 0x01, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01, 0x02]),
        ("write-multiple-response", &[0x01, 0x10, 0x00, 0x01, 0x00, 0x02]),
        ("read-coils-response", &[0x01, 0x01, 0x03, 0xCD, 0x6B, 0x05]),
        ("exception", &[0x01, 0x83, 0x02]),
    ] {
        write(&dir, "modbus_codec", name, &modbus(body))?;
    }

    // Configuration images of the description files.
    for name in ["breaker", "modbus-meter"] {
        let path = format!("slave-fw/descriptions/{name}.toml");
        let description = slave_fw::description::DeviceDescription::load(Path::new(&path))?;
        let mut out = [0u8; slave_fw::image::MAX_IMAGE];
        let n = slave_fw::image::encode(&description.converter, &mut out)?;
        write(&dir, "config_image", name, &out[..n])?;
    }

    // EDS: the parser's own test files.
    for sub in ["eds/tests/corpus", "eds/tests/golden"] {
        if let Ok(entries) = std::fs::read_dir(sub) {
            for e in entries.flatten() {
                let p = e.path();
                if p.extension().is_some_and(|x| x == "eds") {
                    let name = p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                    write(&dir, "eds_parse", &name, &std::fs::read(&p)?)?;
                }
            }
        }
    }
    println!("seeds written to {}", dir.display());
    Ok(())
}
