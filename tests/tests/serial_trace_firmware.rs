//! `dnet-master serial-trace` against the exact firmware ELF of the reference board, run by
//! `exact-firmware-serve` on the stm32-emu register models behind SLCAN on a socat pty pair, its
//! instrument USART on a second pair with `dnet-sim-breaker`: the firmware's analyzer object
//! (class 0x68) serves its ring, and the breaker's status frames, the command the poll output sent
//! and the breaker's acknowledgement come back decoded.
//!
//! ```sh
//! scripts/firmware-size            # the ELF: target/thumbv7em-none-eabihf/firmware/slave-fw-firmware-reference
//! cargo build -p exact-firmware -p soft-slave -p master-harness
//! cargo test -p system-tests --test serial_trace_firmware -- --ignored
//! ```
//!
//! A missing ELF, program or socat fails the test, saying which command provides it.

use pty_rig::{bin, scratch, workspace_dir, Proc, PtyPair};
use serde_json::Value;
use std::path::PathBuf;
use std::time::Duration;

/// The ELF scripts/firmware-size leaves for the reference board.
fn elf() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace_dir().join("target"));
    let path = target.join("thumbv7em-none-eabihf/firmware/slave-fw-firmware-reference");
    assert!(path.is_file(), "{} is missing: build it with scripts/firmware-size", path.display());
    path
}

/// `dnet-master --bus BUS ARGS`, run to its end with exit 0: stdout.
fn master(bus: &str, args: &[&str], serve: &Proc) -> String {
    let mut all = vec!["--bus", bus];
    all.extend_from_slice(args);
    let mut master = Proc::spawn(bin("dnet-master"), &all);
    let status = master.wait(Duration::from_secs(60));
    assert_eq!(
        status.and_then(|s| s.code()),
        Some(0),
        "dnet-master {args:?}\n{}\n{}",
        master.dump(),
        serve.dump()
    );
    master.stdout.text()
}

#[test]
#[ignore = "needs the board ELF, socat and the programs: run by scripts/check"]
fn the_firmware_serves_its_serial_trace_decoded() {
    let ok = std::process::Command::new("socat").arg("-V").stdout(std::process::Stdio::null()).status();
    assert!(ok.is_ok_and(|s| s.success()), "socat is missing: apt-get install socat");
    let dir = scratch("serial-trace-firmware");
    let (can, serial) = (PtyPair::new(), PtyPair::new());
    let log = dir.join("breaker.log");
    let _breaker = Proc::spawn(
        bin("dnet-sim-breaker"),
        &["--serial", &serial.a, "--period", "0.3", "--log", log.to_str().unwrap()],
    );
    let elf = elf();
    let flash = dir.join("settings.flash");
    let args = [
        "--board",
        "reference",
        "--elf",
        elf.to_str().unwrap(),
        "--slcan",
        &can.a,
        "--instrument",
        &serial.b,
        "--instrument-line",
        "9600,8N1",
        "--flash",
        flash.to_str().unwrap(),
        "--mac",
        "5",
        "--rate",
        "250k",
        "--power-on",
        "now",
    ];
    let mut serve = Proc::spawn(bin("exact-firmware-serve"), &args);
    let end = std::time::Instant::now() + Duration::from_secs(20);
    while !serve.stderr.text().contains(" started: ") && std::time::Instant::now() < end {
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(
        serve.stderr.text().contains(" started: "),
        "exact-firmware-serve did not start\n{}",
        serve.dump()
    );
    // The board's duplicate MAC ID check is over before the master comes (as on a bench).
    std::thread::sleep(Duration::from_secs(3));
    let bus = format!("slcan:{}", can.b);
    let breaker = workspace_dir().join("slave-fw/descriptions/breaker.toml");
    // Close the breaker through the poll output: the firmware sends the command.
    let out = master(
        &bus,
        &[
            "monitor",
            "--mac",
            "5",
            "--output",
            "0201",
            "--epr",
            "300",
            "--count",
            "5",
            "--description",
            breaker.to_str().unwrap(),
        ],
        &serve,
    );
    assert!(out.contains("5 samples"), "{out}");
    let json: Value =
        serde_json::from_str(master(&bus, &["--json", "serial-trace", "--mac", "5"], &serve).trim())
            .unwrap_or_else(|e| panic!("serial-trace's JSON: {e}"));
    assert_eq!(json["profile"], "breaker (framed serial)", "{json}");
    let lines: Vec<(String, String, String)> = json["lines"]
        .as_array()
        .unwrap_or_else(|| panic!("no lines: {json}"))
        .iter()
        .map(|l| {
            let s = |k: &str| l[k].as_str().unwrap_or_default().to_string();
            (s("kind"), s("hex"), s("decoded"))
        })
        .collect();
    let has = |kind: &str, hex: &str, decoded: &str| {
        lines.iter().any(|l| l.0 == kind && l.1 == hex && l.2 == decoded)
    };
    assert!(has("tx", "68 01 02 02 16", "command Close"), "{lines:#?}\n{}", serve.dump());
    assert!(has("rx", "68 02 82 00 82 16", "ack of command 0x02: ok"), "{lines:#?}");
    assert!(lines.iter().any(|l| l.0 == "rx" && l.2.starts_with("status: currents")), "{lines:#?}");
    assert!(lines.iter().all(|l| !l.2.starts_with("not a")), "every frame decoded: {lines:#?}");
    serve.signal("TERM");
    let status = serve.wait(Duration::from_secs(10));
    assert_eq!(status.and_then(|s| s.code()), Some(0), "{}", serve.dump());
}
