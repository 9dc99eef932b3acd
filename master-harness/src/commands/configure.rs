//! `dnet-master configure`: a device description downloaded to the device, read back, applied by
//! a reset and the device checked against it ([`crate::configure`]); `--read FILE` uploads the
//! configuration in force as a description file.

use crate::configure;
use crate::options::{parse_mac, GlobalOptions};
use crate::run::{DeviceRun, Outcome};
use clap::Args;
use devicenet::MacId;
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::master::Master;
use serde_json::json;
use slave_fw::description::DeviceDescription;
use std::io::Write;
use std::path::{Path, PathBuf};

/// What `configure` was asked.
#[derive(Args, Clone, Debug)]
pub struct ConfigureArgs {
    /// The device's MAC ID.
    #[arg(long, value_parser = parse_mac)]
    pub mac: MacId,
    /// The device description (TOML) to download.
    #[arg(required_unless_present = "read", conflicts_with = "read")]
    pub description: Option<PathBuf>,
    /// Upload: write the configuration in force to FILE as a description (`-`: standard
    /// output).
    #[arg(long, value_name = "FILE")]
    pub read: Option<PathBuf>,
}

/// Runs `configure`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &ConfigureArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let own = args.description.as_deref().map(|p| DeviceDescription::load(p).map(|d| (p, d))).transpose()?;
    let run = DeviceRun::new(opts, Some(args.mac), slave.as_ref())?;
    let mac = args.mac;
    match (own, &args.read) {
        (Some((path, description)), _) => run.run(out, err, console, |master, progress, _| {
            progress.show(&format!("configure: downloading {} to MAC {mac} ...", path.display()));
            let r = configure::download(master, mac, &description, &mut |note| {
                progress.show(&format!("configure: {note}"));
            });
            progress.clear();
            r.map(|report| download_outcome(&report, path)).into()
        }),
        (None, Some(path)) => run.run(out, err, console, |master, progress, _| {
            progress.show(&format!("configure: reading the configuration of MAC {mac} ..."));
            let r = upload(master, mac, path);
            progress.clear();
            r.into()
        }),
        (None, None) => Err(HarnessError::MissingOption { option: "a description file or --read FILE" }),
    }
}

/// `--read FILE`: the configuration in force written as a description (`-`: in the result).
fn upload(master: &mut Master<'_, '_>, mac: MacId, path: &Path) -> Result<Outcome, HarnessError> {
    let configure::Uploaded { description, serial_number } = configure::upload(master, mac)?;
    let text = description.to_toml().map_err(|detail| HarnessError::DescriptionNotWritable { detail })?;
    let header = format!(
        "# The configuration in force at MAC {mac}, read by dnet-master {} configure --read.\n\
         # identity.vendor_name and identity.catalog are EDS-only: the device does not keep them.\n\
         # identity.serial_number is the image's: the device keeps its own, {serial_number}.\n\n",
        harness_common::version()
    );
    let whole = header + &text;
    if path.as_os_str() == "-" {
        return Ok(Outcome {
            text: whole.trim_end().to_string(),
            json: json!({ "description": whole }),
            code: 0,
        });
    }
    std::fs::write(path, &whole)
        .map_err(|source| HarnessError::Write { path: path.display().to_string(), source })?;
    Ok(Outcome {
        text: format!("MAC {mac}: the configuration in force written to {}", path.display()),
        json: json!({ "description": whole, "file": path }),
        code: 0,
    })
}

/// The download's report: the master's notes, then every check of the device against the description.
fn download_outcome(r: &configure::DownloadReport, path: &std::path::Path) -> Outcome {
    // What the master said before the reset comes first.
    let mut text: String = r.notes.iter().map(|n| format!("note: {n}\n")).collect();
    text += &format!(
        "MAC {}: {} downloaded ({} bytes in {} chunks), read back and verified; reset; on-line again at MAC {} after {} ms",
        r.mac,
        path.display(),
        r.bytes,
        r.chunks,
        r.back_at.map_or_else(|| "?".into(), |m| m.to_string()),
        r.back_online_ms.map_or_else(|| "?".into(), |m| m.to_string()),
    );
    for c in &r.checks {
        let mark = if c.holds() { "ok  " } else { "FAIL" };
        text.push_str(&format!(
            "\n  {mark} {:<24} {}",
            c.what,
            if c.holds() {
                c.actual.clone()
            } else {
                format!("expected {}, device has {}", c.expected, c.actual)
            }
        ));
    }
    let failed = r.failures().len();
    text.push_str(&if failed == 0 {
        "\nthe device runs the description".to_string()
    } else {
        format!("\n{failed} check(s) failed: the device does not run the description")
    });
    Outcome { json: json!({ "configure": r }), text, code: u8::from(failed > 0) }
}
