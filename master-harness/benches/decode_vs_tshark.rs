//! `dnet-master decode` end to end against tshark's DeviceNet dissector, side by side in one run
//! (`cargo bench -p master-harness --bench decode_vs_tshark`; reported, never asserted).
//!
//! One million frames of a realistic exchange (bring-up, a fragmented product-name read, polls
//! with fragmented responses) are written to a `candump -L` log and, the same frames, to a
//! SocketCAN pcap. Then, each as a program reading its file and writing its text to a file:
//!
//! * `dnet-master decode trace.log > decode.txt` (the release binary), three runs, the median;
//! * `tshark -n -r trace.pcap -d can.subdissector=devicenet > tshark.txt` (its one-line summary
//!   per frame, Wireshark's own DeviceNet dissector), one run (tshark takes tens of seconds).
//!
//! Set `DNET_BENCH_FRAMES` for another size. Without tshark on the PATH only our figure is given.

use can_io::log::format_line;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

fn frames() -> usize {
    std::env::var("DNET_BENCH_FRAMES").ok().and_then(|v| v.parse().ok()).unwrap_or(1_000_000)
}

fn write_files(dir: &Path, n: usize) -> (PathBuf, PathBuf) {
    let frames = common::generated_frames(n);
    let log = dir.join("trace.log");
    let pcap = dir.join("trace.pcap");
    let mut l = std::io::BufWriter::new(std::fs::File::create(&log).expect("create the log"));
    let mut p = std::io::BufWriter::new(std::fs::File::create(&pcap).expect("create the pcap"));
    p.write_all(&can_io::pcap::file_header()).expect("write the pcap");
    for (at, frame) in &frames {
        writeln!(l, "{}", format_line(*at, "can0", frame)).expect("write the log");
        p.write_all(&can_io::pcap::record(*at, frame)).expect("write the pcap");
    }
    l.flush().expect("write the log");
    p.flush().expect("write the pcap");
    (log, pcap)
}

/// Runs `command` with its standard output into `out`; the wall time.
fn timed(command: &mut Command, out: &Path) -> Duration {
    let file = std::fs::File::create(out).expect("create the output");
    let start = Instant::now();
    let status = command.stdout(file).stderr(Stdio::inherit()).status().expect("start the program");
    let elapsed = start.elapsed();
    assert!(status.success(), "{command:?} failed: {status}");
    elapsed
}

fn main() {
    let n = frames();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("decode-vs-tshark");
    std::fs::create_dir_all(&dir).expect("create the bench folder");
    let (log, pcap) = write_files(&dir, n);
    let mb = |p: &Path| std::fs::metadata(p).map_or(0.0, |m| m.len() as f64 / 1e6);
    let per_s = |d: Duration| n as f64 / d.as_secs_f64();

    let dnet = env!("CARGO_BIN_EXE_dnet-master");
    let mut runs: Vec<Duration> =
        (0..3).map(|_| timed(Command::new(dnet).arg("decode").arg(&log), &dir.join("decode.txt"))).collect();
    runs.sort();
    let ours = runs[1];
    println!(
        "decode: {n} frames ({:.0} MB candump log -> {:.0} MB of text) in {:.0} ms: {:.2} M frames/s end to end (median of 3, one core)",
        mb(&log),
        mb(&dir.join("decode.txt")),
        ours.as_secs_f64() * 1e3,
        per_s(ours) / 1e6
    );

    if Command::new("tshark").arg("--version").stdout(Stdio::null()).status().is_err() {
        println!("tshark: not installed, no comparison");
        return;
    }
    let theirs = timed(
        Command::new("tshark").args(["-n", "-r"]).arg(&pcap).args(["-d", "can.subdissector=devicenet"]),
        &dir.join("tshark.txt"),
    );
    println!(
        "tshark: the same {n} frames ({:.0} MB pcap -> {:.0} MB of text) in {:.0} ms: {:.2} M frames/s",
        mb(&pcap),
        mb(&dir.join("tshark.txt")),
        theirs.as_secs_f64() * 1e3,
        per_s(theirs) / 1e6
    );
    println!("decode is {:.1}x tshark", theirs.as_secs_f64() / ours.as_secs_f64());
}
