//! `dnet-master ui --mqtt URL --sparkplug GROUP/EDGE_NODE`: the scanner as a Sparkplug B edge
//! node ([`dnet_scanner::sparkplug`]), and the TLS files of `--mqtt` (plain JSON or Sparkplug).
//! Topics, metrics, DCMD and store-and-forward: the guide's page `docs/src/plant/mqtt.md`.
//!
//! DCMD (outputs and breaker commands) is carried out only with `--sparkplug-commands`, through
//! the scanner's command queue like the console's, and each one is recorded in the audit log
//! (via `sparkplug`). With `--plant` the one edge node publishes every network's nodes
//! (`NETWORK-macNN`), a DCMD goes to its network's scanner, and its audit entry names the
//! network (`net NAME: ...`, as the console's do).

use clap::Args;
use dnet_scanner::audit::{Audit, AuditEntry, Via};
use dnet_scanner::model::Shared;
use dnet_scanner::mqtt::TlsFiles;
use dnet_scanner::sparkplug::commands::{CommandRecord, Queues};
use dnet_scanner::sparkplug::store::Window;
use dnet_scanner::sparkplug::{Config, EdgeNode};
use harness_common::error::HarnessError;
use std::path::PathBuf;
use std::sync::Arc;

/// The Sparkplug B and MQTT TLS options of `ui`.
#[derive(Args, Clone, Debug)]
pub struct SparkplugArgs {
    /// Publish to --mqtt as a Sparkplug B edge node GROUP/EDGE_NODE (instead of plain JSON): one
    /// device per node (`mac05`; `NETWORK-mac05` with --plant), births, data by exception, store
    /// and forward.
    #[arg(long, value_name = "GROUP/EDGE_NODE", requires = "mqtt")]
    pub sparkplug: Option<String>,
    /// Carry out Sparkplug DCMD: writes of `Outputs/Image`, the breakers' `Commands/Open` and
    /// `Commands/Close` (each recorded in the audit log).
    #[arg(long, requires = "sparkplug")]
    pub sparkplug_commands: bool,
    /// Where DDATA are kept while the broker is away (SQLite; created when missing).
    #[arg(long, value_name = "FILE", default_value = "dnet-sparkplug.sqlite")]
    pub sparkplug_store: PathBuf,
    /// Store and forward: at most N messages kept while the broker is away (the oldest go first).
    #[arg(long, value_name = "N", default_value_t = 100_000,
          value_parser = clap::value_parser!(u64).range(1..=100_000_000))]
    pub sparkplug_buffer: u64,
    /// Store and forward: only messages at most SECONDS older than the newest are kept.
    #[arg(long, value_name = "SECONDS", default_value_t = 3600,
          value_parser = clap::value_parser!(u64).range(1..=31_536_000))]
    pub sparkplug_buffer_secs: u64,
    /// mqtts://: the certificate authority (PEM) of the broker's certificate [default: the
    /// system's trusted roots].
    #[arg(long, value_name = "FILE", requires = "mqtt")]
    pub mqtt_ca: Option<PathBuf>,
    /// mqtts://: this client's certificate chain (PEM), for a broker that asks for one.
    #[arg(long, value_name = "FILE", requires = "mqtt_key")]
    pub mqtt_cert: Option<PathBuf>,
    /// mqtts://: this client's private key (PEM).
    #[arg(long, value_name = "FILE", requires = "mqtt_cert")]
    pub mqtt_key: Option<PathBuf>,
}

impl SparkplugArgs {
    /// The TLS files of `--mqtt` (either form).
    #[must_use]
    pub fn tls_files(&self) -> TlsFiles {
        TlsFiles { ca: self.mqtt_ca.clone(), cert: self.mqtt_cert.clone(), key: self.mqtt_key.clone() }
    }

    /// Starts the edge node on `url` when `--sparkplug` is given (URL, ID, TLS files and the store
    /// checked here: a refusal is a usage error, exit 2, before the bus is touched).
    pub fn start(&self, url: Option<&str>, shared: &Arc<Shared>) -> Result<Option<EdgeNode>, HarnessError> {
        let (Some(_), Some(url)) = (&self.sparkplug, url) else { return Ok(None) };
        let queue = shared
            .commands
            .lock()
            .map_err(|_| mqtt_err(url, "the command queue is poisoned".into()))?
            .clone();
        let edge = self.start_edge(url, Arc::clone(&shared.audit), Queues::from([(None, queue)]), false)?;
        if let (Some(edge), Ok(mut status)) = (&edge, shared.mqtt.lock()) {
            *status = Some(edge.status());
        }
        Ok(edge)
    }

    /// `ui --plant`: starts the one edge node of every network (`queues`: each network's scanner
    /// command queue by name; `audit`: the plant's audit log) when `--sparkplug` is given.
    pub fn start_plant(
        &self,
        url: Option<&str>,
        audit: Arc<dyn Audit>,
        queues: Queues,
    ) -> Result<Option<EdgeNode>, HarnessError> {
        match url {
            Some(url) => self.start_edge(url, audit, queues, true),
            None => Ok(None),
        }
    }

    fn start_edge(
        &self,
        url: &str,
        audit: Arc<dyn Audit>,
        queues: Queues,
        plant: bool,
    ) -> Result<Option<EdgeNode>, HarnessError> {
        let Some(id) = &self.sparkplug else { return Ok(None) };
        let log = move |r: &CommandRecord| {
            let what = match &r.network {
                Some(net) => format!("net {net}: {}", r.what),
                None => r.what.clone(),
            };
            // A log that cannot write does not stop the command (it was carried out).
            let _ = audit.record(&AuditEntry::now(&r.user, Via::Sparkplug, Some(r.mac), &what, &r.result));
        };
        let commands = self.sparkplug_commands.then_some(queues);
        let config = Config {
            url: url.to_owned(),
            id: id.clone(),
            tls: self.tls_files(),
            store: self.sparkplug_store.clone(),
            window: Window {
                max_messages: self.sparkplug_buffer,
                max_age_ms: self.sparkplug_buffer_secs * 1000,
            },
            commands,
            plant,
            log: Some(Box::new(log)),
        };
        let edge = EdgeNode::start(config).map_err(|e| mqtt_err(url, e.to_string()))?;
        Ok(Some(edge))
    }
}

fn mqtt_err(url: &str, detail: String) -> HarnessError {
    HarnessError::Mqtt { url: url.to_owned(), detail }
}
