//! `dnet-master ui --opcua ADDR`: the scanner's nodes served over OPC UA ([`dnet_opcua`]) beside
//! the web console: identity, status, decoded inputs with units, I/O images, and the breakers'
//! Open/Close methods for the console's operators. The address space is the guide's page
//! `docs/src/plant/opcua.md`.
//!
//! As the console: an address other than loopback is refused without `--users` (exit 2, before
//! the bus is touched). Without `--opcua-pki` only the endpoint without security is offered, and
//! it takes anonymous sessions only (browse, read, subscribe).

use clap::Args;
use dnet_opcua::{OpcUaError, OpcUaOptions, OpcUaServer};
use dnet_scanner::accounts::Users;
use dnet_scanner::model::Shared;
use harness_common::error::HarnessError;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The OPC UA options of `ui`.
#[derive(Args, Clone, Debug, Default)]
pub struct OpcUaArgs {
    /// Serve the scan list's nodes over OPC UA at `opc.tcp://HOST:PORT` or `HOST:PORT` (port 0: any
    /// free port; the endpoint URL is printed). Beyond loopback it needs --users.
    #[arg(long, value_name = "ADDR")]
    pub opcua: Option<String>,
    /// The OPC UA server's PKI directory: its certificate and key (made when missing) and the
    /// client certificates seen. Turns on the Basic256Sha256 Sign & Encrypt endpoint, the only one
    /// that takes user names (and so the only one where methods can be called).
    #[arg(long, value_name = "DIR", requires = "opcua")]
    pub opcua_pki: Option<PathBuf>,
}

impl OpcUaArgs {
    /// Starts the server on `shared` when `--opcua` is given, with the accounts of `users_file`
    /// (`ui --users`). Every refusal is a usage error (exit 2) before the bus is touched.
    pub fn start(
        &self,
        shared: &Arc<Shared>,
        users_file: Option<&Path>,
    ) -> Result<Option<OpcUaServer>, HarnessError> {
        let Some(address) = &self.opcua else { return Ok(None) };
        let users = match users_file {
            Some(path) => Some(Arc::new(Users::load(path).map_err(|e| HarnessError::InvalidValue {
                option: "--users",
                value: format!("{}: {e}", path.display()),
                expected: "a users file (dnet-master user add)",
            })?)),
            None => None,
        };
        let options = OpcUaOptions { address: address.clone(), pki_dir: self.opcua_pki.clone(), users };
        OpcUaServer::start(&options, Arc::clone(shared)).map(Some).map_err(|e| match e {
            OpcUaError::Listen { address, source } => HarnessError::Listen { address, error: source },
            OpcUaError::NeedsUsers { address } => HarnessError::InvalidValue {
                option: "--opcua",
                value: address,
                expected: "a loopback address, or --users (OPC UA beyond loopback needs accounts)",
            },
            OpcUaError::Address { address, why } => HarnessError::InvalidValue {
                option: "--opcua",
                value: format!("{address} ({why})"),
                expected: "opc.tcp://HOST:PORT or HOST:PORT",
            },
            other => HarnessError::ConsoleStart { address: address.clone(), error: other.to_string() },
        })
    }
}
