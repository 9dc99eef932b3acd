//! `dnet-master params`: every parameter of the device read, and with `--set` written
//! ([`dnet_scanner::params`]): its Parameter object, or the `[Params]` of an EDS through their link
//! paths.

use crate::options::{parse_mac, GlobalOptions};
use crate::run::{DeviceRun, Outcome};
use clap::Args;
use devicenet::MacId;
use dnet_scanner::params;
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::master::Master;
use serde_json::json;
use std::io::Write;
use std::path::PathBuf;

/// What `params` was asked.
#[derive(Args, Clone, Debug)]
pub struct ParamsArgs {
    /// The device's MAC ID.
    #[arg(long, value_parser = parse_mac)]
    pub mac: MacId,
    /// Take the parameter list from this EDS.
    #[arg(long, value_name = "FILE")]
    pub eds: Option<PathBuf>,
    /// Write a parameter first: NAME=VALUE (repeatable).
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
}

/// Runs `params`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &ParamsArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let run = DeviceRun::new(opts, Some(args.mac), slave.as_ref())?;
    run.run(out, err, console, |master, _, _| {
        read_and_set(master, args.mac, args.eds.as_deref(), &args.set).into()
    })
}

/// The `--set`s parsed and the EDS read, then the parameters read, set and read again.
fn read_and_set(
    master: &mut Master<'_, '_>,
    mac: MacId,
    eds_file: Option<&std::path::Path>,
    set: &[String],
) -> Result<Outcome, HarnessError> {
    let assignments: Vec<(String, i64)> = set
        .iter()
        .map(|a| params::parse_assignment(a))
        .collect::<Result<_, _>>()
        .map_err(|detail| HarnessError::ParamValue { detail })?;
    let listed: Option<Vec<(u32, eds::model::Param)>> = match eds_file {
        Some(path) => {
            let model = eds::read_file(path)
                .map_err(|e| HarnessError::Eds { path: path.display().to_string(), error: Box::new(e) })?;
            Some(model.params().map(|(n, p)| (n, p.clone())).collect())
        }
        None => None,
    };
    master.open_explicit(mac)?;
    let read = |master: &mut Master<'_, '_>| match &listed {
        Some(list) => params::read_eds(master, mac, list),
        None => params::read_device(master, mac),
    };
    let mut rows = read(master)?;
    if !assignments.is_empty() {
        for (name, value) in &assignments {
            params::set(master, mac, &rows, name, *value)?;
        }
        rows = read(master)?;
    }
    if rows.is_empty() {
        return Err(HarnessError::NothingCompared(format!("MAC {mac} has no parameters to read")));
    }
    Ok(Outcome { text: params::table(&rows), json: json!({ "params": rows }), code: 0 })
}
