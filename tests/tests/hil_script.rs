//! `scripts/hil --dry-run` (the hardware-in-the-loop script of issue 26): for every board it prints
//! the build, the flash with the board's chip, the instrument, the MAC ID and data rate set-up
//! where the board has no switches, and the scenarios' commands on the real bus, without building
//! or touching anything; bad arguments exit 2 naming the argument. The real run needs a board, a
//! probe, a CAN adapter and a USB-serial port.

use std::process::{Command, Output};

const SCRIPT: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/hil");
const BOARDS: [(&str, &str); 4] = [
    ("reference", "STM32F405RGTx"),
    ("olimex-p405", "STM32F405RGTx"),
    ("olimex-p405-rs485", "STM32F405RGTx"),
    ("nucleo-f446re", "STM32F446RETx"),
];

fn hil(args: &[&str]) -> Output {
    // A target directory of its own: a dry run must not create or build anything there.
    let target = std::env::temp_dir().join(format!("dnet-hil-target-{}", std::process::id()));
    Command::new("bash")
        .arg(SCRIPT)
        .args(args)
        .env("CARGO_TARGET_DIR", &target)
        .output()
        .expect("bash runs scripts/hil")
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The commands a dry run prints, without the `would run: ` prefix.
fn commands(output: &Output) -> Vec<String> {
    text(&output.stdout).lines().filter_map(|l| l.strip_prefix("would run: ")).map(str::to_string).collect()
}

#[test]
fn every_board_dry_run_prints_build_flash_instrument_and_scenarios() {
    let target = std::env::temp_dir().join(format!("dnet-hil-target-{}", std::process::id()));
    for (board, chip) in BOARDS {
        let out = hil(&["--dry-run", board]);
        let stdout = text(&out.stdout);
        assert_eq!(out.status.code(), Some(0), "{board}: {stdout}{}", text(&out.stderr));
        let cmds = commands(&out);
        let t = target.display();
        let elf = format!("{t}/thumbv7em-none-eabihf/firmware/slave-fw-firmware-{board}");
        let master = format!("{t}/debug/dnet-master");
        let bus = "--bus socketcan:can0";
        let mut expected = vec![
            format!(
                "cargo build -p slave-fw-firmware --profile firmware --target thumbv7em-none-eabihf \
                 --no-default-features --features {board} --locked"
            ),
            format!("cp {t}/thumbv7em-none-eabihf/firmware/slave-fw-firmware {elf}"),
            "cargo build -p master-harness -p soft-slave --bins --locked".to_string(),
            format!("probe-rs download --chip {chip} {elf}"),
            format!(
                "{t}/debug/dnet-sim-breaker --serial /dev/ttyUSB0 --log {t}/hil/{board}-instrument.log &"
            ),
            format!("probe-rs reset --chip {chip}"),
        ];
        if board == "reference" {
            assert!(stdout.contains("switches"), "{board}: the switch setting is named: {stdout}");
        } else {
            // No switches: MAC 5 and 125k set over the network at MAC 63, then a reset.
            expected.extend([
                format!("{master} get {bus} 5 3 1 1"),
                format!("{master} set {bus} 63 3 1 1 05"),
                format!("{master} set {bus} 63 3 1 2 00"),
                format!("probe-rs reset --chip {chip}"),
            ]);
        }
        expected.extend([
            format!("{master} connect {bus} --mac 5"),
            format!("{master} connect {bus} --mac 5 --polls 15 --output 0201"),
            format!("{master} connect {bus} --mac 5 --polls 15 --output 0102"),
            format!("{master} conformance {bus} --mac 5"),
        ]);
        assert_eq!(cmds, expected, "{board}");
        assert!(
            stdout
                .lines()
                .last()
                .unwrap()
                .starts_with(&format!("hil: dry run, board {board} ({chip}), 3 scenarios")),
            "{stdout}"
        );
        assert!(!target.exists(), "a dry run creates nothing: {}", target.display());
    }
}

#[test]
fn options_reach_the_commands() {
    let out = hil(&[
        "--dry-run",
        "--bus",
        "slcan:/dev/ttyACM0@115200",
        "--instrument",
        "/dev/ttyUSB3",
        "--probe",
        "0483:374b:066DFF485550755187121723",
        "--scenario",
        "conformance",
        "nucleo-f446re",
    ]);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let cmds = commands(&out);
    let probe = "--probe 0483:374b:066DFF485550755187121723";
    assert!(
        cmds.iter().any(|c| c.starts_with(&format!("probe-rs download --chip STM32F446RETx {probe} "))),
        "{cmds:?}"
    );
    assert!(cmds.iter().any(|c| c == &format!("probe-rs reset --chip STM32F446RETx {probe}")), "{cmds:?}");
    assert!(cmds.iter().any(|c| c.contains("dnet-sim-breaker --serial /dev/ttyUSB3 ")), "{cmds:?}");
    let master: Vec<_> = cmds.iter().filter(|c| c.contains("dnet-master")).collect();
    assert!(
        master.iter().all(|c| c.contains(" --bus slcan:/dev/ttyACM0@115200 --bitrate 125k ")),
        "{master:?}"
    );
    // Only the chosen scenario.
    assert!(master
        .last()
        .unwrap()
        .ends_with("conformance --bus slcan:/dev/ttyACM0@115200 --bitrate 125k --mac 5"));
    assert!(!master.iter().any(|c| c.contains("connect")), "{master:?}");
}

#[test]
fn bad_arguments_exit_2_naming_the_argument() {
    let cases: [(&[&str], &str); 10] = [
        (&["--dry-run"], "BOARD"),
        (&["--dry-run", "stm32-discovery"], "BOARD"),
        (&["--dry-run", "reference", "nucleo-f446re"], "BOARD"),
        (&["--dry-run", "--bus", "can0", "reference"], "--bus"),
        (&["--dry-run", "--bus", "slcan:", "reference"], "--bus"),
        (&["--dry-run", "--bus"], "--bus"),
        (&["--dry-run", "--scenario", "bus-off", "reference"], "--scenario"),
        (&["--dry-run", "--probe", "ST-LINK", "reference"], "--probe"),
        (&["--dry-run", "--instrument", "ttyUSB0", "reference"], "--instrument"),
        (&["--dry-run", "--verbose", "reference"], "--verbose"),
    ];
    for (args, named) in cases {
        let out = hil(args);
        let stderr = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.lines().next().unwrap_or("").contains(named), "{args:?} must name {named}: {stderr}");
        assert!(commands(&out).is_empty(), "{args:?}: nothing is run");
    }
}
