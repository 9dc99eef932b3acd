//! `exact-firmware-serve`: one board's exact firmware ELF on the stm32-emu models, served on real
//! interfaces: an SLCAN adapter on one pty, the instrument USART on another, the settings flash
//! in a file, in wall time (`exact_firmware::serve` says how). SIGINT or SIGTERM stops it: the
//! flash file is saved and a summary printed on stderr; exit 0. Exit 1 when the machine stopped
//! (a fault) or an interface failed, 2 for bad arguments.

use clap::Parser;
use devicenet::slave::BaudRate;
use devicenet::MacId;
use exact_firmware::board::BoardKind;
use exact_firmware::serve::line::LineSpec;
use exact_firmware::serve::{serve, PowerOn, ServeOptions};
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The exact firmware ELF of one board on the stm32-emu register models, served on real
/// interfaces: an SLCAN adapter on a pty (dnet-master, slcand or python-can on the other end of
/// the pair), the instrument USART on a pty (dnet-sim-breaker or a Modbus server on the other
/// end), the settings flash in a file. SIGINT/SIGTERM saves the flash file and stops; a power
/// cycle is a stop and a start on the same file.
#[derive(Parser, Debug)]
#[command(name = "exact-firmware-serve", version)]
struct Args {
    /// The board: reference, olimex-p405, olimex-p405-rs485 or nucleo-f446re.
    #[arg(long, value_parser = parse_board)]
    board: BoardKind,
    /// The board's firmware ELF (scripts/firmware-size leaves it in
    /// target/thumbv7em-none-eabihf/firmware/slave-fw-firmware-BOARD).
    #[arg(long)]
    elf: PathBuf,
    /// The board's bootloader ELF (scripts/build-bootloader leaves it in
    /// target/thumbv7em-none-eabihf/firmware/bootloader-BOARD), flashed beside the firmware.
    #[arg(long)]
    bootloader: Option<PathBuf>,
    /// The pty the SLCAN adapter answers on (one end of a socat pty pair; the host opens the other).
    #[arg(long)]
    slcan: String,
    /// The pty of the instrument line (one end of a pair; the instrument opens the other).
    #[arg(long)]
    instrument: String,
    /// The line the instrument side runs, BAUD,FORMAT (9600,8N1 for dnet-sim-breaker, 19200,8E1
    /// for the Modbus meter description). The USART's characters are sampled at it: a firmware
    /// line that does not match garbles the bytes.
    #[arg(long, default_value = "9600,8N1")]
    instrument_line: LineSpec,
    /// The settings flash file (the board's two settings sectors); created when missing.
    #[arg(long)]
    flash: PathBuf,
    /// The MAC ID: the switches of a board with switches (default 5); on a board without, the
    /// record a new flash file starts with (else it starts erased).
    #[arg(long, value_parser = parse_mac)]
    mac: Option<MacId>,
    /// The data rate, 125k, 250k or 500k: as --mac (switches default 125k).
    #[arg(long, value_parser = parse_rate)]
    rate: Option<BaudRate>,
    /// When the board is powered on: `now`, or `master-online` (1 s after the host's master sent
    /// its second duplicate MAC ID check request, as in the reference capture).
    #[arg(long, default_value = "now", value_parser = parse_power_on)]
    power_on: PowerOn,
}

fn parse_board(s: &str) -> Result<BoardKind, String> {
    BoardKind::by_name(s).ok_or_else(|| {
        let names: Vec<_> = BoardKind::all().iter().map(|b| b.name).collect();
        format!("no board called '{s}' (the boards: {})", names.join(", "))
    })
}

fn parse_mac(s: &str) -> Result<MacId, String> {
    s.parse::<u8>().ok().and_then(MacId::new).ok_or_else(|| format!("'{s}' is not a MAC ID (0 to 63)"))
}

fn parse_rate(s: &str) -> Result<BaudRate, String> {
    match s {
        "125k" => Ok(BaudRate::Kbps125),
        "250k" => Ok(BaudRate::Kbps250),
        "500k" => Ok(BaudRate::Kbps500),
        _ => Err(format!("'{s}' is not a DeviceNet data rate (125k, 250k or 500k)")),
    }
}

fn parse_power_on(s: &str) -> Result<PowerOn, String> {
    match s {
        "now" => Ok(PowerOn::Now),
        "master-online" => Ok(PowerOn::MasterOnline),
        _ => Err(format!("'{s}' is not now or master-online")),
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    if let Err(e) = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed)) {
        eprintln!("exact-firmware-serve: error: cannot handle SIGINT/SIGTERM: {e}");
        return ExitCode::from(1);
    }
    let options = ServeOptions {
        board: args.board,
        elf: args.elf,
        bootloader: args.bootloader,
        slcan: args.slcan,
        instrument: args.instrument,
        instrument_line: args.instrument_line,
        flash: args.flash,
        mac: args.mac,
        rate: args.rate,
        power_on: args.power_on,
    };
    let mut started = |line: &str| eprintln!("exact-firmware-serve: {line}");
    match serve(&options, &stop, &mut started) {
        Ok(summary) => {
            eprintln!(
                "exact-firmware-serve: stopped after {summary}; flash saved to {}",
                options.flash.display()
            );
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("exact-firmware-serve: error: {e}");
            ExitCode::from(1)
        }
    }
}
