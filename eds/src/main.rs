//! `dnet-eds`: parse, check and normalize DeviceNet EDS files.
//!
//! Exit status: 0 success, 1 the file has errors (syntax errors for `parse`/`format`, any error
//! diagnostic for `check`), 2 usage errors or unreadable files.

use clap::{Parser, Subcommand};
use eds::{check_file, read_file, EdsError, Summary, Writer};
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

/// Parse, check and normalize DeviceNet Electronic Data Sheets (EDS).
#[derive(Debug, Parser)]
#[command(name = "dnet-eds", version, about, long_about = None)]
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
    /// Rewrite an EDS file in the canonical, deterministic layout of the writer.
    Format {
        /// The EDS file.
        file: PathBuf,
        /// Write here instead of standard output.
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
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
            let eds = match read_file(&file) {
                Ok(eds) => eds,
                Err(error) => return failed(error),
            };
            let text = Writer::new().write(&eds);
            match output {
                Some(path) => std::fs::write(&path, text)
                    .map_err(|e| format!("cannot write {}: {e}", path.display()))?,
                None => {
                    let mut out = std::io::stdout().lock();
                    out.write_all(text.as_bytes()).map_err(|e| format!("cannot write output: {e}"))?;
                }
            }
            Ok(ExitCode::SUCCESS)
        }
    }
}
