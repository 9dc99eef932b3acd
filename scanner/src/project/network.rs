//! The network as a project ([`read`]) and the file restored to it ([`download`]).
//!
//! The configuration image is read and downloaded through a [`Configurator`]: the converter's
//! configuration object (class 0x66) is the bench master's (`dnet-master configure`), which
//! implements it; parameters are this crate's ([`crate::params`]).

use super::{compare, Keying, NodeIdentity, Project, ProjectNode, ProjectParam, FORMAT};
use crate::params::{self, ParamRow};
use crate::scan::ScannedDevice;
use devicenet::messages::AllocationChoice;
use devicenet::MacId;
use harness_common::error::HarnessError;
use master_core::error::MasterError;
use master_core::master::Master;

/// Reads and writes a node's stored configuration as device description text.
pub trait Configurator {
    /// The configuration in force at `mac` as description text; `None` when the node has no
    /// configuration object (it answers the request with an error).
    fn read(&mut self, master: &mut Master<'_, '_>, mac: MacId) -> Result<Option<String>, HarnessError>;
    /// Downloads `description` to `mac` and applies it; a line saying what was done.
    fn download(
        &mut self,
        master: &mut Master<'_, '_>,
        mac: MacId,
        description: &str,
    ) -> Result<String, HarnessError>;
}

/// Whether `e` is the device's error response (it has no such object), not a failure of the bus.
fn refused(e: &HarnessError) -> bool {
    matches!(e, HarnessError::Master(MasterError::ErrorResponse { .. }))
}

/// Opens the explicit connection to `mac` unless this master holds it already (a second Allocate
/// would be refused with 0x0B, and released and made again).
fn ensure_explicit(master: &mut Master<'_, '_>, mac: MacId) -> Result<(), HarnessError> {
    if !master.held(mac).contains(AllocationChoice::EXPLICIT) {
        master.open_explicit(mac)?;
    }
    Ok(())
}

/// The Parameter object's instances at `mac` (none when the node has no Parameter object).
fn read_params(master: &mut Master<'_, '_>, mac: MacId) -> Result<Vec<ParamRow>, HarnessError> {
    match params::read_device(master, mac) {
        Ok(rows) => Ok(rows),
        Err(e) if refused(&e) => Ok(Vec::new()),
        Err(e) => Err(e),
    }
}

fn project_param(r: &ParamRow) -> ProjectParam {
    ProjectParam {
        number: r.number,
        name: r.name.clone(),
        value: r.value,
        raw: if r.value.is_none() { Some(r.raw.clone()) } else { None },
        units: r.units.clone(),
        read_only: r.read_only,
    }
}

/// The identity a scan read; `None` when an attribute of the key is missing.
fn identity(d: &ScannedDevice) -> Option<NodeIdentity> {
    let id = &d.identity;
    let (major, minor) = id.revision.as_deref()?.split_once('.')?;
    Some(NodeIdentity {
        vendor_id: id.vendor_id?,
        device_type: id.device_type?,
        product_code: id.product_code?,
        major_revision: major.parse().ok()?,
        minor_revision: minor.parse().ok()?,
        product_name: id.product_name.clone().unwrap_or_default(),
        serial_number: id.serial_number,
    })
}

/// The network as a project: every device `devices` found (a scan) with its identity, and its
/// configuration and parameters read. `file` gives what the network cannot show: a node's
/// connection (other than poll: its sizes too), name and keying; without it each node is polled,
/// keyed exactly and named by its product name. A device whose identity could not be read is
/// left out and named in the second list with why.
pub fn read(
    master: &mut Master<'_, '_>,
    devices: &[ScannedDevice],
    file: Option<&Project>,
    configurator: &mut dyn Configurator,
) -> Result<(Project, Vec<String>), HarnessError> {
    let mut project = Project { format: FORMAT, node: Vec::new() };
    let mut unread = Vec::new();
    for d in devices {
        let (Some(identity), Some(mac)) = (identity(d), MacId::new(d.mac)) else {
            unread.push(format!("MAC {}: identity not read ({})", d.mac, d.status));
            continue;
        };
        let template = file.and_then(|p| p.node.iter().find(|n| n.mac == d.mac));
        let connection = template.map_or_else(|| "poll".to_string(), |t| t.connection.clone());
        let (input_size, output_size) = match (template, d.produced_size, d.consumed_size) {
            (Some(t), _, _) if t.connection != "poll" => (t.input_size, t.output_size),
            (_, Some(p), Some(c)) => (p, c),
            (Some(t), _, _) => (t.input_size, t.output_size),
            (None, _, _) => (0, 0),
        };
        let configuration = match configurator.read(master, mac) {
            Ok(c) => c,
            Err(e) if refused(&e) => None,
            Err(e) => return Err(e),
        };
        ensure_explicit(master, mac)?;
        let param = read_params(master, mac)?.iter().map(project_param).collect();
        project.node.push(ProjectNode {
            mac: d.mac,
            connection,
            input_size,
            output_size,
            name: template.map_or_else(|| Some(identity.product_name.clone()), |t| t.name.clone()),
            keying: template.map_or(Keying::Exact, |t| t.keying),
            identity,
            configuration,
            param,
        });
    }
    Ok((project, unread))
}

/// Restores `file` to the network read as `network`: for each node on both, the configuration
/// downloaded when any key of it differs (the device resets and applies it), then each parameter
/// whose value differs written (read-only ones reported, not written). Returns what was done,
/// one line each. The caller reads the network again and compares, to say whether it worked.
pub fn download(
    master: &mut Master<'_, '_>,
    file: &Project,
    network: &Project,
    configurator: &mut dyn Configurator,
) -> Result<Vec<String>, HarnessError> {
    let mut done = Vec::new();
    for f in &file.node {
        let (Some(n), Some(mac)) = (network.node.iter().find(|n| n.mac == f.mac), MacId::new(f.mac)) else {
            continue;
        };
        let one = |node: &ProjectNode| Project { format: FORMAT, node: vec![node.clone()] };
        let c = compare(&one(f), &one(n));
        if let Some(config) = &f.configuration {
            if c.differences.iter().any(|d| d.what.starts_with("configuration")) {
                // The download allocates its own connection: what the read left open is released.
                master.release_held()?;
                done.push(configurator.download(master, mac, config)?);
            }
        }
        if f.param.is_empty() {
            continue;
        }
        ensure_explicit(master, mac)?;
        let rows = read_params(master, mac)?;
        for p in &f.param {
            let Some(row) = rows.iter().find(|r| r.number == p.number) else {
                done.push(format!("MAC {mac}: parameter {} ({}) not on the device", p.number, p.name));
                continue;
            };
            let Some(value) = p.value else { continue };
            if row.value == Some(value) {
                continue;
            }
            if row.read_only {
                done.push(format!(
                    "MAC {mac}: parameter {} ({}) is read-only: {} not written",
                    p.number, p.name, value
                ));
                continue;
            }
            params::set(master, mac, &rows, &row.name, value)?;
            done.push(format!(
                "MAC {mac}: parameter {} ({}) set to {value} (was {})",
                p.number,
                row.name,
                row.value.map_or_else(|| row.raw.clone(), |v| v.to_string())
            ));
        }
    }
    Ok(done)
}
