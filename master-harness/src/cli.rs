//! The `dnet-master` command line: the options every command shares ([`crate::options`]), one
//! subcommand per module of [`crate::commands`], and the dispatch between them. How a command that
//! talks to a device runs and reports is [`crate::run`]'s.
//!
//! Exit status: 0 when every check holds, 1 when a check failed, the device diverged, timed out
//! or answered with an error, or a replay compared nothing; 2 for a usage or configuration error
//! (bad option, unknown bus, bad or unwritable file); 130 / 143 when SIGINT / SIGTERM stopped the
//! command ([`harness_common::console`]).
//!
//! Every command ends the same way, however it ended: the connections it allocated are released
//! through the Group 2 Only port (not with `--keep`; not when the bus itself failed), then the CSV
//! and the log are flushed and the result printed (with `"interrupted"` in the JSON when a signal
//! stopped it). Output files are created before the bus is touched.

use crate::commands::{
    completions, configure, conformance, connect, decode, explicit, firmware_update, man, monitor, params,
    project, recover, replay, scan, scanner, serial_trace, sign_firmware, ui, units, user,
};
use crate::options::GlobalOptions;
use can_io::trace::write::log_format;
use clap::{CommandFactory, Parser, Subcommand};
use harness_common::console::Console;
use harness_common::error::HarnessError;
use serde_json::json;
use std::ffi::OsString;
use std::io::Write;

/// `dnet-master`: a bench DeviceNet master.
#[derive(Debug, Parser)]
#[command(name = "dnet-master", version = harness_common::version(), about = "A bench DeviceNet master: brings a device up like a scanner and verifies every frame, replays transcripts, scans, reads and writes attributes, monitors polled data, decodes traces of every common format.", long_about = None)]
pub struct Cli {
    /// The options of every command.
    #[command(flatten)]
    pub options: GlobalOptions,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// The full bring-up of protocol §2, every frame checked.
    Connect(connect::ConnectArgs),
    /// Find a node that is Communication Faulted after a duplicate MAC ID (Offline Connection
    /// Set: Who, then the answers listed); with --to give it a new MAC ID (long Identify, offline
    /// ownership, Change MAC ID) and watch it come on-line there.
    Recover(recover::RecoverArgs),
    /// Replay a candump -L transcript against the device at MAC N.
    Replay(replay::ReplayArgs),
    /// Find every device: identity and I/O sizes.
    Scan(scan::ScanArgs),
    /// Keep every node of a scan list in I/O, as a DeviceNet scanner does (without --scanlist:
    /// a scan list from a network scan); a table of the nodes' status at the end.
    Scanner(scanner::ScannerArgs),
    /// The scanner with its web console: `--listen ADDR` serves the network, device and trace
    /// views (and their JSON API) while every node of the scan list is kept in I/O; samples go to
    /// an SQLite history, and with --mqtt to a broker.
    Ui(Box<ui::UiArgs>),
    /// The console's accounts: `user add FILE NAME --role viewer|operator|engineer` (the password
    /// one line on standard input, stored as an argon2 hash), `user remove FILE NAME`,
    /// `user list FILE`.
    User(user::UserArgs),
    /// Get_Attribute_Single.
    Get(explicit::GetArgs),
    /// Set_Attribute_Single.
    Set(explicit::SetArgs),
    /// Connect, then show the polled data decoded by the device profile.
    Monitor(monitor::MonitorArgs),
    /// Download a device description to the device: checked, downloaded, read back, reset, and
    /// the device checked against it; with --read, upload the configuration in force as a
    /// description file.
    Configure(configure::ConfigureArgs),
    /// Read (and with --set write) every parameter of the device: its Parameter object, or the
    /// `[Params]` of an EDS through their link paths.
    Params(params::ParamsArgs),
    /// Update the device's firmware over DeviceNet (update object, class 0x6A): the signed FILE
    /// checked against the device (board, size, key; the signature with --public-key), sent in
    /// 128-byte chunks, verified and applied; then the device is awaited and its new revision and
    /// whether the image confirmed are reported. Run again with the same file to resume an
    /// interrupted transfer. Only the master that holds the device's explicit connection can
    /// update it (the device refuses everyone else), and not while an I/O connection is
    /// established.
    FirmwareUpdate(firmware_update::FirmwareUpdateArgs),
    /// Sign a firmware image for firmware-update: the ELF's loadable segments (or a flat binary)
    /// followed by the 128-byte trailer signed with the Ed25519 seed in --key; refused when the
    /// image-info block at 0x200 is missing or names another board than --board.
    SignFirmware(sign_firmware::SignFirmwareArgs),
    /// Pretty-print a trace as DeviceNet messages (candump -L, pcap, pcapng, PCAN trc, Vector
    /// asc and blf, csv).
    Decode(decode::DecodeArgs),
    /// Read the converter's serial-line analyzer (vendor class 0x68): the last bytes each way on
    /// the instrument's line and the line events, decoded by its profile; --follow keeps reading.
    SerialTrace(serial_trace::SerialTraceArgs),
    /// Read a Modbus gateway's unit table (vendor class 0x69): per unit its state, lost data,
    /// retries, exceptions and the time since its last answer.
    Units(units::UnitsArgs),
    /// Network projects: upload the network to a TOML file (scan list, identity and keying,
    /// stored configuration, parameters), compare the network with it, download it back.
    Project(project::ProjectArgs),
    /// The conformance suite against a group-2-only slave: network access, connection set,
    /// explicit messaging, connections, timing (exit 0 only when no check fails).
    Conformance(conformance::ConformanceArgs),
    /// Print the shell completion script for SHELL (bash, zsh, fish, elvish, powershell) on
    /// standard output.
    Completions(completions::CompletionsArgs),
    /// Write the manual pages (roff), one for dnet-master and one per command, into DIR.
    Man(man::ManArgs),
}

/// Runs `dnet-master` with `args` (the program name first), writing to `out` and `err`; returns
/// the exit status. `terminal` says whether `out` is a terminal (monitor refreshes in place). No
/// progress lines, and only [`Stop::request`](master_core::stop::Stop::request) stops it: see
/// [`run_with`].
pub fn run<I, T>(args: I, out: &mut dyn Write, err: &mut dyn Write, terminal: bool) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    run_with(args, out, err, &Console { stdout_terminal: terminal, ..Console::plain() })
}

/// Runs `dnet-master` in `console` (the binary: terminals as they are, SIGINT / SIGTERM setting
/// its stop).
pub fn run_with<I, T>(args: I, out: &mut dyn Write, err: &mut dyn Write, console: &Console) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let mut cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) => {
            let text = e.render().to_string();
            let code = u8::try_from(e.exit_code()).unwrap_or(2);
            let _ = if code == 0 { write!(out, "{text}") } else { write!(err, "{text}") };
            return code;
        }
    };
    // The --log file's format, for every command that writes it: --format, else the file's
    // extension, else candump (the rule of every program with --log).
    let opts = &mut cli.options;
    let result = match opts.log.as_deref().map(|path| log_format(path, opts.format)).transpose() {
        Ok(format) => {
            opts.format = format.or(opts.format);
            execute(&cli, out, err, console)
        }
        Err(e) => Err(HarnessError::from(e)),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            if cli.options.json {
                let _ = writeln!(out, "{}", json!({ "ok": false, "error": e.to_string() }));
            }
            let _ = writeln!(err, "error: {e}");
            e.exit_code()
        }
    }
}

/// Runs the command `cli` names.
pub fn execute(
    cli: &Cli,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let opts = &cli.options;
    opts.check_log_format()?;
    match &cli.command {
        Command::Connect(args) => connect::execute(opts, args, out, err, console),
        Command::Recover(args) => recover::execute(opts, args, out, err, console),
        Command::Replay(args) => replay::execute(opts, args, out, err, console),
        Command::Scan(args) => scan::execute(opts, args, out, err, console),
        Command::Scanner(args) => scanner::execute(opts, args, out, err, console),
        Command::Ui(args) => ui::execute(opts, args, out, err, console),
        Command::User(args) => user::execute(args, &mut std::io::stdin().lock(), out, err),
        Command::Get(args) => explicit::get(opts, args, out, err, console),
        Command::Set(args) => explicit::set(opts, args, out, err, console),
        Command::Monitor(args) => monitor::execute(opts, args, out, err, console),
        Command::Configure(args) => configure::execute(opts, args, out, err, console),
        Command::Params(args) => params::execute(opts, args, out, err, console),
        Command::FirmwareUpdate(args) => firmware_update::execute(opts, args, out, err, console),
        Command::SignFirmware(args) => sign_firmware::execute(opts, args, out, err),
        Command::Decode(args) => decode::execute(opts, args, out, err, console),
        Command::SerialTrace(args) => serial_trace::execute(opts, args, out, err, console),
        Command::Units(args) => units::execute(opts, args, out, err, console),
        Command::Project(args) => project::execute(opts, args, out, err, console),
        Command::Conformance(args) => conformance::execute(opts, args, out, err, console),
        Command::Completions(args) => completions::execute(args, Cli::command(), out),
        Command::Man(args) => man::execute(args, Cli::command(), out),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }
}
