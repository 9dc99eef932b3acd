//! `dnet-eds`: generate, parse, check and normalize DeviceNet EDS files, and check a device on
//! the bus against its EDS.
//!
//! Exit status, as for every program of this project (guide: docs/src/reference/exit-status.md): 0
//! success; 1 a failed
//! check (syntax errors for `parse`/`format`, any error diagnostic for `check`, a device that
//! disagrees with the EDS) or a device or bus error (no answer, a bus that cannot be opened); 2 a
//! usage or configuration error (bad option, unreadable input file, refused description).

use can_io::bus::{Bitrate, BusSpec};
use clap::{Parser, Subcommand};
use devicenet::{Duration, MacId};
use eds::generate::{generate_text, GenerateOptions, DEFAULT_DATE, DEFAULT_REVISION};
use eds::value::{Date, Revision};
use eds::{check_file, format_file, read_file, EdsError, Summary};
use eds_tool::device::{check_on_bus, BusOptions, CheckOptions, DeviceError};
use master_core::error::MasterError;
use slave_fw::description::DeviceDescription;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// The package version and the git commit it was built from.
const VERSION: &str = git_version::git_version!(
    prefix = "0.1.0 (",
    suffix = ")",
    args = ["--always", "--dirty=-modified", "--abbrev=12"],
    fallback = "0.1.0 (unknown commit)"
);

/// Generate, parse, check and normalize DeviceNet Electronic Data Sheets (EDS); check a device
/// against its EDS.
#[derive(Debug, Parser)]
#[command(name = "dnet-eds", version = VERSION, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Parse an EDS file and print a summary: identity, I/O, parameters, enums, groups, and
    /// the unknown sections and keywords kept.
    Parse {
        /// The EDS file.
        file: PathBuf,
        /// Print the summary as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Check an EDS file: syntax, required sections and keys, duplicates, cross references,
    /// ranges, data types. Exit status 0 without errors (warnings allowed), 1 with errors.
    Check {
        /// The EDS file.
        file: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Rewrite an EDS file in the canonical, deterministic layout of the writer, keeping its `$`
    /// comments beside their sections and entries and its encoding (Latin-1 bytes stay as they
    /// are).
    Format {
        /// The EDS file.
        file: PathBuf,
        /// Write here instead of standard output.
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
    /// Generate the EDS of the converter a device description (TOML) describes: identity, poll
    /// I/O sizes and paths, the settings and serial link statistics as parameters. The same
    /// description and options always give the same bytes.
    Generate {
        /// The device description file (see slave-fw/descriptions/).
        description: PathBuf,
        /// Write here instead of standard output.
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// CreateDate and ModDate, MM-DD-YYYY. A fixed default keeps the output independent of
        /// the day it is generated; give the release date when publishing.
        #[arg(long, value_name = "MM-DD-YYYY", default_value_t = DEFAULT_DATE, value_parser = parse_date)]
        date: Date,
        /// `[File]` Revision of the EDS file itself, MAJOR.MINOR.
        #[arg(long, help = "[File] Revision of the EDS file itself, MAJOR.MINOR", value_name = "MAJOR.MINOR", default_value_t = DEFAULT_REVISION, value_parser = parse_revision)]
        revision: Revision,
    },
    /// Read a device's identity and poll connection sizes over the bus and report every
    /// disagreement with an EDS (electronic keying: vendor, device type, product code, major
    /// revision; produced and consumed sizes and paths; connection types and the sizes the
    /// bit-strobe, COS and cyclic connections produce). Exit status 0 when
    /// everything agrees, 1 on a disagreement or when the device cannot be checked, 2 for usage
    /// and file errors.
    CheckDevice {
        /// The EDS file.
        #[arg(long)]
        eds: PathBuf,
        /// The device's MAC ID (0..=63).
        #[arg(long, value_parser = parse_mac)]
        mac: MacId,
        /// The bus: sim, socketcan:IFACE or `slcan:PATH[@SERIALBAUD]`.
        #[arg(
            long,
            help = "The bus: sim, socketcan:IFACE or slcan:PATH[@SERIALBAUD]",
            default_value = "sim"
        )]
        bus: BusSpec,
        /// CAN bit rate, 125k, 250k or 500k [default: sim: the simulated device's; slcan: 250k].
        #[arg(long)]
        bitrate: Option<Bitrate>,
        /// sim: the device description the simulated device runs [default: the reference
        /// device, slave-fw/descriptions/breaker.toml].
        #[arg(long, value_name = "FILE")]
        slave_config: Option<PathBuf>,
        /// The master's MAC ID.
        #[arg(long, default_value = "0", value_parser = parse_mac)]
        master_mac: MacId,
        /// Explicit response timeout, ms.
        #[arg(long, default_value_t = 1000, value_name = "MS")]
        timeout: u64,
        /// Also read every parameter's attribute: not served or of another size disagrees, a
        /// value other than the default is a note.
        #[arg(long)]
        params: bool,
        /// Write every frame to FILE, in the format its extension names (.asc, .trc, .csv; any
        /// other name: candump -L).
        #[arg(long, value_name = "FILE")]
        log: Option<PathBuf>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
}

fn parse_date(text: &str) -> Result<Date, String> {
    Date::parse(text).ok_or_else(|| format!("'{text}' is not a date MM-DD-YYYY"))
}

fn parse_revision(text: &str) -> Result<Revision, String> {
    Revision::parse(text).ok_or_else(|| format!("'{text}' is not a revision MAJOR.MINOR (each 0..=255)"))
}

/// A MAC ID, decimal or `0x` hex, `0..=63`.
fn parse_mac(text: &str) -> Result<MacId, String> {
    eds::value::parse_int(text)
        .and_then(|v| u8::try_from(v).ok())
        .and_then(MacId::new)
        .ok_or_else(|| format!("MAC ID {text} is out of range 0..=63 (decimal, or hex with 0x)"))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli.command) {
        Ok(code) => code,
        Err(message) => {
            eprintln!("dnet-eds: {message}");
            ExitCode::from(2)
        }
    }
}

/// Reports a read/parse failure: syntax errors exit 1, I/O errors 2.
fn failed(error: EdsError) -> Result<ExitCode, String> {
    match error {
        EdsError::Parse(error) => {
            eprintln!("{error}");
            Ok(ExitCode::from(1))
        }
        io => Err(io.to_string()),
    }
}

fn print(text: &str) -> Result<(), String> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{text}").map_err(|e| format!("cannot write output: {e}"))
}

fn run(command: Command) -> Result<ExitCode, String> {
    match command {
        Command::Parse { file, json } => {
            let eds = match read_file(&file) {
                Ok(eds) => eds,
                Err(error) => return failed(error),
            };
            let summary = Summary::of(&eds);
            if json {
                print(&serde_json::to_string_pretty(&summary).map_err(|e| e.to_string())?)?;
            } else {
                print(&format!("{}\n{summary}", file.display()))?;
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Check { file, json } => {
            let report = check_file(&file).map_err(|e| e.to_string())?;
            if json {
                print(&serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?)?;
            } else {
                print(&report.to_string())?;
            }
            Ok(if report.has_errors() { ExitCode::from(1) } else { ExitCode::SUCCESS })
        }
        Command::Format { file, output } => {
            let bytes = match format_file(&file) {
                Ok(bytes) => bytes,
                Err(error) => return failed(error),
            };
            write_bytes(output.as_deref(), &bytes)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::Generate { description, output, date, revision } => {
            let loaded = DeviceDescription::load(&description).map_err(|e| e.to_string())?;
            let source = description.file_name().map(|n| n.to_string_lossy().into_owned());
            let text = generate_text(&loaded, &GenerateOptions { date, revision, source });
            write_text(output.as_deref(), &text)?;
            Ok(ExitCode::SUCCESS)
        }
        Command::CheckDevice {
            eds,
            mac,
            bus,
            bitrate,
            slave_config,
            master_mac,
            timeout,
            params,
            log,
            json,
        } => {
            let model = read_file(&eds).map_err(|e| e.to_string())?;
            let bus = BusOptions { bus, bitrate, mac, slave_config };
            let options = CheckOptions {
                master_mac,
                response_timeout: Duration::from_millis(timeout.clamp(1, 600_000)),
                params,
            };
            let report = match check_on_bus(&model, &bus, &options, log.as_deref()) {
                Ok(report) => report,
                Err(
                    e @ (DeviceError::Usage(_)
                    | DeviceError::Description(_)
                    | DeviceError::Master(MasterError::Usage(_))),
                ) => return Err(e.to_string()),
                Err(e) => {
                    if json {
                        let value = serde_json::json!({ "ok": false, "error": e.to_string() });
                        print(&value.to_string())?;
                    }
                    eprintln!("dnet-eds: cannot check the device at MAC {mac}: {e}");
                    return Ok(ExitCode::from(1));
                }
            };
            if json {
                let value = serde_json::json!({ "ok": report.agrees(), "eds": eds, "report": report });
                print(&serde_json::to_string_pretty(&value).map_err(|e| e.to_string())?)?;
            } else {
                print(&format!("{} against the device at MAC {mac}\n{report}", eds.display()))?;
            }
            Ok(if report.agrees() { ExitCode::SUCCESS } else { ExitCode::from(1) })
        }
    }
}

/// Writes `text` to `path`, or to standard output.
fn write_text(path: Option<&Path>, text: &str) -> Result<(), String> {
    write_bytes(path, text.as_bytes())
}

/// Writes `bytes` to `path`, or to standard output.
fn write_bytes(path: Option<&Path>, bytes: &[u8]) -> Result<(), String> {
    match path {
        Some(path) => {
            std::fs::write(path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))
        }
        None => {
            let mut out = std::io::stdout().lock();
            out.write_all(bytes).map_err(|e| format!("cannot write output: {e}"))
        }
    }
}
