//! `dnet-master project upload|compare|download FILE`: the network kept as a project file
//! ([`dnet_scanner::project`]): uploaded from a scan (identity, stored configuration, parameters of
//! every node), compared with the network node by node and parameter by parameter (exit 1 on any
//! difference), and downloaded back (configurations, then settable parameters; then compared
//! again, exit 0 only when the network equals the file).

use crate::configure;
use crate::options::{parse_u8, GlobalOptions};
use crate::run::{DeviceRun, Outcome};
use clap::{Args, Subcommand};
use devicenet::MacId;
use dnet_scanner::project::network::{self, Configurator};
use dnet_scanner::project::{self, Comparison, Project, ProjectError};
use dnet_scanner::scan;
use harness_common::console::{Console, Progress};
use harness_common::error::HarnessError;
use master_core::master::Master;
use serde_json::json;
use slave_fw::description::DeviceDescription;
use std::io::Write;
use std::path::{Path, PathBuf};

/// What `project` was asked.
#[derive(Args, Clone, Debug)]
pub struct ProjectArgs {
    /// What to do with the project file.
    #[command(subcommand)]
    pub action: ProjectAction,
    /// First MAC ID scanned.
    #[arg(long, default_value_t = 0, value_parser = parse_u8, global = true)]
    pub from: u8,
    /// Last MAC ID scanned.
    #[arg(long, default_value_t = 63, value_parser = parse_u8, global = true)]
    pub to: u8,
}

/// The project actions.
#[derive(Subcommand, Clone, Debug)]
pub enum ProjectAction {
    /// Scan the network and write every node (scan list entry, identity and keying, stored
    /// configuration, parameters) to FILE.
    Upload {
        /// The project file to write.
        file: PathBuf,
    },
    /// Compare the network with FILE node by node and parameter by parameter: the differences,
    /// exit 1 on any (and when nothing could be compared).
    Compare {
        /// The project file.
        file: PathBuf,
    },
    /// Restore FILE to the network: each configuration that differs downloaded (the node resets),
    /// each settable parameter that differs written; then compared again.
    Download {
        /// The project file.
        file: PathBuf,
    },
}

/// The configuration object of the converter, through [`crate::configure`].
struct ConverterConfigurator;

impl Configurator for ConverterConfigurator {
    fn read(&mut self, master: &mut Master<'_, '_>, mac: MacId) -> Result<Option<String>, HarnessError> {
        let uploaded = configure::upload(master, mac)?;
        let text = uploaded
            .description
            .to_toml()
            .map_err(|detail| HarnessError::DescriptionNotWritable { detail })?;
        Ok(Some(text))
    }

    fn download(
        &mut self,
        master: &mut Master<'_, '_>,
        mac: MacId,
        description: &str,
    ) -> Result<String, HarnessError> {
        let description = DeviceDescription::parse(description)?;
        let report = configure::download(master, mac, &description, &mut |_| {})?;
        let failed = report.failures().len();
        Ok(format!(
            "MAC {mac}: configuration downloaded ({} bytes), reset, on-line again at MAC {}{}",
            report.bytes,
            report.back_at.map_or_else(|| "?".into(), |m| m.to_string()),
            if failed == 0 { String::new() } else { format!("; {failed} check(s) failed") }
        ))
    }
}

/// Runs `project`; returns the exit status. A project file refused is a usage error (2) naming
/// the file and line, before the bus is touched.
pub fn execute(
    opts: &GlobalOptions,
    args: &ProjectArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let file = match &args.action {
        ProjectAction::Upload { file } => {
            // Created (empty) now: an unwritable path fails before the bus is touched.
            crate::options::create_output(file)?;
            None
        }
        ProjectAction::Compare { file } | ProjectAction::Download { file } => match project::read(file) {
            Ok(p) => Some(p),
            Err(e) => return Ok(refused(opts, &e, out, err)),
        },
    };
    let slave = opts.slave_description()?;
    let run = DeviceRun::new(opts, None, slave.as_ref())?;
    let (from, to) = (args.from, args.to);
    run.run(out, err, console, |master, progress, _| {
        let r = match (&args.action, &file) {
            (ProjectAction::Upload { file }, _) => upload(master, progress, (from, to), file),
            (ProjectAction::Compare { .. }, Some(p)) => read_network(master, progress, (from, to), Some(p))
                .and_then(|(network, unread)| {
                    let c = project::compare(p, &network);
                    comparison_outcome(&c, &unread, &[])
                }),
            (ProjectAction::Download { .. }, Some(p)) => download(master, progress, (from, to), p),
            (_, None) => Err(HarnessError::MissingOption { option: "a project file" }),
        };
        progress.clear();
        r.into()
    })
}

/// A project file refused: the error, as text or JSON; exit status 2.
fn refused(opts: &GlobalOptions, e: &ProjectError, out: &mut dyn Write, err: &mut dyn Write) -> u8 {
    if opts.json {
        let _ = writeln!(out, "{}", json!({ "ok": false, "error": e.to_string() }));
    }
    let _ = writeln!(err, "error: {e}");
    2
}

/// Scans `from..=to` and reads every node found.
fn read_network(
    master: &mut Master<'_, '_>,
    progress: &mut Progress<'_>,
    (from, to): (u8, u8),
    file: Option<&Project>,
) -> Result<(Project, Vec<String>), HarnessError> {
    let report = scan::scan(master, from, to, progress)?;
    progress.show("project: reading configurations and parameters ...");
    network::read(master, &report.devices, file, &mut ConverterConfigurator)
}

fn upload(
    master: &mut Master<'_, '_>,
    progress: &mut Progress<'_>,
    range: (u8, u8),
    path: &Path,
) -> Result<Outcome, HarnessError> {
    let (network, unread) = read_network(master, progress, range, None)?;
    if network.node.is_empty() {
        return Err(HarnessError::NothingCompared(format!(
            "no node answered on MAC {}..={}: nothing to write to {}",
            range.0,
            range.1,
            path.display()
        )));
    }
    let header = format!(
        "DeviceNet network project, written by dnet-master {} project upload.\n\
         Compare: dnet-master project compare FILE; restore: dnet-master project download FILE.",
        harness_common::version()
    );
    let text = project::write(&network, &header);
    std::fs::write(path, &text)
        .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
    let mut lines: Vec<String> = network
        .node
        .iter()
        .map(|n| {
            format!(
                "MAC {:>2}  {:<26} configuration {:<8} {} parameter(s)",
                n.mac,
                n.identity.product_name,
                if n.configuration.is_some() { "stored" } else { "none" },
                n.param.len()
            )
        })
        .collect();
    lines.extend(unread.iter().map(|u| format!("not written: {u}")));
    lines.push(format!("{} node(s) written to {}", network.node.len(), path.display()));
    Ok(Outcome {
        text: lines.join("\n"),
        json: json!({ "project": { "file": path, "nodes": network.node.len(), "unread": unread } }),
        code: 0,
    })
}

fn download(
    master: &mut Master<'_, '_>,
    progress: &mut Progress<'_>,
    range: (u8, u8),
    file: &Project,
) -> Result<Outcome, HarnessError> {
    let (network, _) = read_network(master, progress, range, Some(file))?;
    let before = project::compare(file, &network);
    if before.compared == 0 {
        return Err(nothing_compared(file));
    }
    progress.show("project: downloading ...");
    let done = network::download(master, file, &network, &mut ConverterConfigurator)?;
    progress.show("project: comparing again ...");
    // The scan allocates afresh: what this master still holds is released first.
    master.release_held()?;
    let (after, unread) = read_network(master, progress, range, Some(file))?;
    let c = project::compare(file, &after);
    comparison_outcome(&c, &unread, &done)
}

fn nothing_compared(file: &Project) -> HarnessError {
    let macs: Vec<String> = file.node.iter().map(|n| n.mac.to_string()).collect();
    HarnessError::NothingCompared(format!(
        "no node of the project (MAC {}) answered: nothing compared",
        macs.join(", ")
    ))
}

/// The differences (and what a download did) as the outcome: exit 1 on any difference; an error
/// when no node of the file was compared.
fn comparison_outcome(c: &Comparison, unread: &[String], done: &[String]) -> Result<Outcome, HarnessError> {
    if c.compared == 0 {
        return Err(HarnessError::NothingCompared(format!(
            "no node of the project answered{}",
            c.differences.first().map_or_else(String::new, |d| format!(" ({d})"))
        )));
    }
    let mut lines: Vec<String> = done.to_vec();
    lines.extend(unread.iter().map(|u| format!("not compared: {u}")));
    lines.extend(c.differences.iter().map(ToString::to_string));
    lines.push(format!(
        "{} node(s) compared ({} parameter(s), {} configuration key(s)): {}",
        c.compared,
        c.params_compared,
        c.configuration_keys_compared,
        if c.differences.is_empty() {
            "the network equals the project".to_string()
        } else {
            format!("{} difference(s)", c.differences.len())
        }
    ));
    Ok(Outcome {
        text: lines.join("\n"),
        json: json!({ "comparison": c, "done": done, "unread": unread }),
        code: u8::from(!c.differences.is_empty()),
    })
}
