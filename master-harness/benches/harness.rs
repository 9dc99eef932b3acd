//! Benchmarks of the harness, reported and never asserted (`cargo bench -p master-harness`):
//!
//! * `decode` throughput on a large generated `candump -L` log (frames per second), parsing and
//!   decoding with fragment reassembly;
//! * `scan` of 63 simulated devices (MAC 1..=63, master at 0) at 500 kbit/s, in simulated bus time.

use can_io::bus::Bitrate;
use can_io::log::parse_log;
use can_io::sim::{PowerOn, SimBus};
use converter_sim::device::SoftSlave;
use devicenet::MacId;
use dnet_scanner::scan::scan;
use master_core::decode::Decoder;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use std::hint::black_box;

mod common;
use common::generated_log;

fn decode_bench() {
    const FRAMES: usize = 1_000_000;
    let text = generated_log(FRAMES);
    let mut runs = Vec::new();
    for _ in 0..3 {
        let start = std::time::Instant::now();
        let entries = parse_log(&text, "bench").expect("generated log parses");
        let parsed = start.elapsed();
        let mut decoder = Decoder::new();
        let mut messages = 0usize;
        for e in &entries {
            if decoder.decode(&e.frame).message.is_some() {
                messages += 1;
            }
        }
        let total = start.elapsed();
        black_box(messages);
        runs.push((parsed, total, messages));
    }
    runs.sort_by_key(|r| r.1);
    let (parsed, total, messages) = runs[1];
    let per_s = |d: std::time::Duration| FRAMES as f64 / d.as_secs_f64();
    println!(
        "decode: {FRAMES} frames ({} MB of log, {messages} reassembled messages) in {:.0} ms: {:.2} M frames/s parse+decode (parse alone {:.2} M frames/s, decode alone {:.2} M frames/s); median of 3",
        text.len() / 1_000_000,
        total.as_secs_f64() * 1e3,
        per_s(total) / 1e6,
        per_s(parsed) / 1e6,
        per_s(total - parsed) / 1e6
    );
}

fn scan_bench() {
    let mut bus = SimBus::new(Bitrate::K500);
    for mac in 1..=63u8 {
        bus.attach(Box::new(SoftSlave::reference(MacId::from_low_bits(mac))), PowerOn::WhenMasterOnline);
    }
    let wall = std::time::Instant::now();
    let mut session = Session::new(&mut bus);
    let report = scan(
        &mut Master::new(&mut session, MasterConfig::default()),
        0,
        63,
        &mut harness_common::console::Progress::off(),
    )
    .expect("scan");
    let wall = wall.elapsed();
    let frames = session.records().len();
    println!(
        "scan: {} of 63 simulated devices found at 500 kbit/s in {:.1} ms of bus time ({:.1} ms with the master's duplicate MAC check and the devices' start-up); {frames} frames; {:.0} ms of wall time to simulate",
        report.devices.len(),
        report.scan_micros as f64 / 1e3,
        report.total_micros as f64 / 1e3,
        wall.as_secs_f64() * 1e3
    );
    let busy: u64 = session
        .records()
        .iter()
        .filter(|r| r.at.total_micros() >= report.total_micros - report.scan_micros)
        .map(|r| u64::from(can_io::sim::frame_bits(&r.frame)) * 2)
        .sum();
    println!(
        "scan: bus load during the scan {:.0} %",
        100.0 * busy as f64 / report.scan_micros.max(1) as f64
    );
}

fn main() {
    decode_bench();
    scan_bench();
}
