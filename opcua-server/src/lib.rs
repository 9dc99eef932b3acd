//! # dnet-opcua
//!
//! An OPC UA server over the DeviceNet scanner's state, for SCADA systems and HMIs: what
//! `dnet-master ui --opcua ADDR` serves beside the web console. It is built on
//! [async-opcua](https://docs.rs/async-opcua) and reads the same [`Shared`] state the console
//! reads; commands go through the same queue and land in the same audit log.
//!
//! | module | what it holds |
//! |---|---|
//! | [`endpoint`] | the address given (`opc.tcp://HOST:PORT` or `HOST:PORT`), loopback or not |
//! | [`auth`] | anonymous sessions and the console's accounts (UserName tokens), and who may call methods |
//! | [`values`] | the variables of the scanner and of each node, computed from its state |
//! | [`nodes`] | the node manager: objects added as nodes appear, values copied on change, the methods |
//!
//! ## Threads and bounds
//!
//! The scanner's loop is synchronous; the server runs on a tokio runtime of its own with
//! [`WORKER_THREADS`] workers and at most [`BLOCKING_THREADS`] blocking threads (argon2 checks,
//! commands waiting for the scanner's answer), at most [`MAX_SESSIONS`] sessions and
//! [`MAX_MONITORED_ITEMS`] monitored items in a subscription. A task copies
//! the state into the address space every [`SYNC_EVERY`]; subscriptions are notified of each
//! value that changed.
//!
//! ## Security
//!
//! Two endpoints at the same URL: SecurityPolicy None (anonymous sessions only: browse, read,
//! subscribe) and, with a PKI directory ([`OpcUaOptions::pki_dir`]), Basic256Sha256 Sign &
//! Encrypt, which also takes the console's accounts as UserName tokens. The methods need an
//! operator or engineer account, so they can be called only over the encrypted endpoint.

pub mod auth;
pub mod endpoint;
pub mod nodes;
pub mod values;

use auth::Accounts;
use dnet_scanner::accounts::Users;
use dnet_scanner::model::Shared;
use endpoint::Endpoint;
use nodes::{DnetNodeManager, DnetNodes, Synced, NAMESPACE};
use opcua::crypto::SecurityPolicy;
use opcua::server::address_space::AddressSpace;
use opcua::server::node_manager::memory::InMemoryNodeManagerBuilder;
use opcua::server::node_manager::ServerContext;
use opcua::server::{ServerBuilder, ServerHandle, ANONYMOUS_USER_TOKEN_ID};
use opcua::types::MessageSecurityMode;
use std::path::PathBuf;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// Worker threads of the server's runtime.
pub const WORKER_THREADS: usize = 2;
/// Blocking threads of the server's runtime, at most.
pub const BLOCKING_THREADS: usize = 4;
/// Sessions open at once, at most.
pub const MAX_SESSIONS: usize = 16;
/// Monitored items in one subscription, at most: every variable of 63 nodes (about 30 each for
/// a breaker) fits in one.
pub const MAX_MONITORED_ITEMS: usize = 4096;
/// How often the address space is brought in step with the scanner's state.
pub const SYNC_EVERY: Duration = Duration::from_millis(100);

/// Why the server did not start.
#[derive(Debug, thiserror::Error)]
pub enum OpcUaError {
    /// The address given cannot be used.
    #[error("--opcua {address}: {why}")]
    Address {
        /// The text given.
        address: String,
        /// Why.
        why: String,
    },
    /// A listener beyond loopback without accounts (the console's rule).
    #[error("--opcua {address}: not a loopback address; serving it needs --users")]
    NeedsUsers {
        /// The text given.
        address: String,
    },
    /// The address cannot be bound.
    #[error("--opcua {address}: cannot listen: {source}")]
    Listen {
        /// The text given.
        address: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The PKI directory or the server's certificate cannot be made.
    #[error("--opcua-pki {dir}: {why}")]
    Pki {
        /// The directory.
        dir: String,
        /// Why.
        why: String,
    },
    /// The server or its runtime cannot be built.
    #[error("--opcua {address}: cannot start the server: {why}")]
    Start {
        /// The text given.
        address: String,
        /// Why.
        why: String,
    },
}

/// What the server is asked.
#[derive(Clone, Debug)]
pub struct OpcUaOptions {
    /// `opc.tcp://HOST:PORT` or `HOST:PORT` (port 0: any free port, see [`OpcUaServer::url`]).
    pub address: String,
    /// Where the server keeps its certificate (`own/cert.der`, `private/private.pem`, made when
    /// missing) and the client certificates it has seen; `None`: no encrypted endpoint.
    pub pki_dir: Option<PathBuf>,
    /// The console's accounts (`ui --users`); `None`: anonymous sessions only.
    pub users: Option<Arc<Users>>,
}

/// The running server; [`OpcUaServer::stop`] (or dropping it) stops it.
pub struct OpcUaServer {
    url: String,
    handle: ServerHandle,
    thread: Option<JoinHandle<()>>,
    temporary_pki: Option<PathBuf>,
}

impl OpcUaServer {
    /// Checks the options, binds the address and starts the server on its own runtime. Every
    /// refusal (a bad address, a listener beyond loopback without accounts, a port in use, a
    /// certificate that cannot be made) is returned before anything runs.
    pub fn start(options: &OpcUaOptions, shared: Arc<Shared>) -> Result<OpcUaServer, OpcUaError> {
        let address = options.address.clone();
        let endpoint = Endpoint::parse(&address)?;
        if !endpoint.is_loopback() && options.users.is_none() {
            return Err(OpcUaError::NeedsUsers { address });
        }
        let listener = std::net::TcpListener::bind(endpoint.addr)
            .and_then(|l| l.set_nonblocking(true).map(|()| l))
            .map_err(|source| OpcUaError::Listen { address: address.clone(), source })?;
        let port = listener
            .local_addr()
            .map_err(|source| OpcUaError::Listen { address: address.clone(), source })?
            .port();
        let (pki_dir, temporary_pki) = match &options.pki_dir {
            Some(dir) => (dir.clone(), None),
            // No encrypted endpoint, but the library still wants a store: a private one, removed
            // at stop.
            None => {
                let dir = std::env::temp_dir().join(format!("dnet-opcua-{}-{port}", std::process::id()));
                (dir.clone(), Some(dir))
            }
        };
        let accounts = Arc::new(Accounts::new(options.users.clone()));
        let builder = server_builder(&endpoint, port, &pki_dir, options.pki_dir.is_some())
            .with_authenticator(accounts.clone());
        let manager_shared = Arc::clone(&shared);
        let builder = builder.with_node_manager(InMemoryNodeManagerBuilder::new(
            move |context: ServerContext, space: &mut AddressSpace| {
                let ns = opcua::server::address_space::add_namespaces(&context, space, &[NAMESPACE])[0];
                DnetNodes::new(ns, manager_shared, accounts)
            },
        ));
        let start_error = |why: String| OpcUaError::Start { address: address.clone(), why };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(WORKER_THREADS)
            .max_blocking_threads(BLOCKING_THREADS)
            .thread_name("opcua")
            .enable_all()
            .build()
            .map_err(|e| start_error(e.to_string()))?;
        // The server starts tasks of its own while it is built: inside its runtime.
        let (server, handle) = {
            let _entered = runtime.enter();
            builder.build().map_err(start_error)?
        };
        if options.pki_dir.is_some() && handle.info().server_certificate.is_none() {
            return Err(OpcUaError::Pki {
                dir: pki_dir.display().to_string(),
                why: "cannot read or make the server's certificate and key".into(),
            });
        }
        let manager = handle
            .node_managers()
            .get_of_type::<DnetNodeManager>()
            .ok_or_else(|| start_error("the node manager was not built".into()))?;
        let subscriptions = Arc::clone(handle.subscriptions());
        let token = handle.token().clone();
        let thread = std::thread::Builder::new()
            .name("opcua-server".into())
            .spawn(move || {
                runtime.block_on(async move {
                    let Ok(listener) = tokio::net::TcpListener::from_std(listener) else { return };
                    tokio::spawn(async move {
                        let mut synced = Synced::default();
                        let mut tick = tokio::time::interval(SYNC_EVERY);
                        loop {
                            tick.tick().await;
                            nodes::sync(&manager, &subscriptions, &mut synced);
                        }
                    });
                    tokio::select! {
                        _ = server.run_with(listener) => {}
                        () = token.cancelled() => {}
                    }
                });
                runtime.shutdown_timeout(Duration::from_secs(1));
            })
            .map_err(|e| start_error(e.to_string()))?;
        let host = if endpoint.host.contains(':') { format!("[{}]", endpoint.host) } else { endpoint.host };
        Ok(OpcUaServer {
            url: format!("opc.tcp://{host}:{port}/"),
            handle,
            thread: Some(thread),
            temporary_pki,
        })
    }

    /// The endpoint URL (`opc.tcp://127.0.0.1:4840/`), with the port bound.
    #[must_use]
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Stops the server: sessions are closed, the runtime's threads end.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.handle.cancel();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        if let Some(dir) = self.temporary_pki.take() {
            let _ = std::fs::remove_dir_all(dir);
        }
    }
}

impl Drop for OpcUaServer {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// The server's configuration: its names, the endpoints, the limits.
fn server_builder(
    endpoint: &Endpoint,
    port: u16,
    pki_dir: &std::path::Path,
    encrypted: bool,
) -> ServerBuilder {
    let tokens = [ANONYMOUS_USER_TOKEN_ID];
    let mut builder = ServerBuilder::new()
        .application_name("dnet-master scanner")
        .application_uri("urn:dnet-master:scanner")
        .product_uri("urn:dnet-master")
        .host(endpoint.host.clone())
        .port(port)
        .pki_dir(pki_dir)
        .create_sample_keypair(encrypted)
        // Client certificates authorise no one (accounts do): any client may open the encrypted
        // channel, and its certificate is kept under pki/trusted.
        .trust_client_certs(true)
        .max_sessions(MAX_SESSIONS)
        .diagnostics_enabled(false)
        .add_endpoint("none", ("/", SecurityPolicy::None, MessageSecurityMode::None, &tokens as &[&str]))
        .discovery_urls(vec![format!("opc.tcp://{}:{port}/", endpoint.host)]);
    builder.limits_mut().subscriptions.max_monitored_items_per_sub = MAX_MONITORED_ITEMS;
    if encrypted {
        builder = builder.add_endpoint(
            "basic256sha256_sign_encrypt",
            ("/", SecurityPolicy::Basic256Sha256, MessageSecurityMode::SignAndEncrypt, &tokens as &[&str]),
        );
    }
    builder
}
