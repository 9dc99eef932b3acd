//! The Modbus TCP server: a listener and a tokio runtime on a thread of their own, one task per
//! connection (tokio-modbus' framing and request loop), each request answered from the scanner's
//! shared state ([`Shared::state`]) through the register map ([`crate::map`]).
//!
//! Bounds: at most [`ServerConfig::max_connections`] connections at once (one more is accepted and
//! closed at once); a connection that sends nothing, or reads nothing of its answers, for
//! [`ServerConfig::idle_timeout`] is closed; a request is at most one MBAP frame (7 + 65535 bytes,
//! the length field's limit); a read at most [`MAX_READ`](crate::map::MAX_READ) registers.
//! A frame that cannot be decoded (wrong protocol identifier, length 0, a truncated PDU, a function
//! code of 0x80 or more) closes its connection: tokio-modbus' decoder gives up on the stream, and
//! the other connections and the listener go on.

use crate::map::read_registers;
use dnet_scanner::model::Shared;
use std::future::{ready, Ready};
use std::net::{SocketAddr, TcpListener as StdListener};
use std::pin::Pin;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use thiserror::Error;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{oneshot, OwnedSemaphorePermit, Semaphore};
use tokio_io_timeout::TimeoutStream;
use tokio_modbus::prelude::{ExceptionCode, Request, Response, SlaveRequest};
use tokio_modbus::server::tcp::Server;
use tokio_modbus::server::Service;

/// The unit identifiers the server answers: 255 (MODBUS Messaging on TCP/IP Implementation Guide
/// v1.0b §4.4.2: a server addressed by its IP address takes 0xFF), 0 and 1 (the defaults of
/// common clients). Any other gets exception 0x0A, gateway path unavailable: there is no device
/// behind this server to route to.
pub const UNIT_IDS: [u8; 3] = [0, 1, 255];

/// How long a connection may stay silent (no request, or no answer read) before it is closed.
pub const IDLE_TIMEOUT: Duration = Duration::from_secs(60);

/// Connections served at once by default.
pub const MAX_CONNECTIONS: usize = 8;

/// The most connections that may be allowed (`--modbus-tcp-connections`).
pub const CONNECTIONS_LIMIT: usize = 64;

/// How the server runs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ServerConfig {
    /// Connections served at once, 1 to [`CONNECTIONS_LIMIT`].
    pub max_connections: usize,
    /// Silence after which a connection is closed.
    pub idle_timeout: Duration,
}

impl Default for ServerConfig {
    fn default() -> Self {
        ServerConfig { max_connections: MAX_CONNECTIONS, idle_timeout: IDLE_TIMEOUT }
    }
}

/// Why the server cannot start.
#[derive(Debug, Error)]
pub enum ServerError {
    /// The address cannot be listened on.
    #[error("cannot listen on {address}: {source}")]
    Listen {
        /// The address.
        address: SocketAddr,
        /// The OS error.
        source: std::io::Error,
    },
    /// The runtime or its thread cannot be made.
    #[error("cannot start the Modbus TCP server's runtime: {0}")]
    Runtime(std::io::Error),
    /// A connection limit out of range.
    #[error("{0} connections: 1 to {CONNECTIONS_LIMIT} may be served at once")]
    Connections(usize),
}

/// A running server; dropping it (or [`ModbusServer::stop`]) stops it and joins its thread.
#[derive(Debug)]
pub struct ModbusServer {
    address: SocketAddr,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl ModbusServer {
    /// Listens on `address` (port 0: any free port, see [`ModbusServer::local_addr`]) and serves
    /// `shared`'s state from a thread of its own. The address is bound here, so an address in use
    /// is an error before anything else starts.
    pub fn start(
        address: SocketAddr,
        config: ServerConfig,
        shared: Arc<Shared>,
    ) -> Result<Self, ServerError> {
        if !(1..=CONNECTIONS_LIMIT).contains(&config.max_connections) {
            return Err(ServerError::Connections(config.max_connections));
        }
        let listen = |source| ServerError::Listen { address, source };
        let std_listener = StdListener::bind(address).map_err(listen)?;
        std_listener.set_nonblocking(true).map_err(listen)?;
        let local = std_listener.local_addr().map_err(listen)?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_io()
            .enable_time()
            .build()
            .map_err(ServerError::Runtime)?;
        let listener = {
            let _guard = runtime.enter();
            TcpListener::from_std(std_listener).map_err(listen)?
        };
        let (stop, stopped) = oneshot::channel();
        let thread = std::thread::Builder::new()
            .name("modbus-tcp".into())
            .spawn(move || runtime.block_on(serve(listener, config, shared, stopped)))
            .map_err(ServerError::Runtime)?;
        Ok(ModbusServer { address: local, stop: Some(stop), thread: Some(thread) })
    }

    /// The address listened on.
    #[must_use]
    pub fn local_addr(&self) -> SocketAddr {
        self.address
    }

    /// Stops listening, closes every connection and joins the thread.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for ModbusServer {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// The accept loop until `stopped`. An accept error (out of file descriptors) does not end it:
/// tokio-modbus' loop returns on one, and is started again after a pause.
async fn serve(
    listener: TcpListener,
    config: ServerConfig,
    shared: Arc<Shared>,
    mut stopped: oneshot::Receiver<()>,
) {
    let server = Server::new(listener);
    let places = Arc::new(Semaphore::new(config.max_connections));
    let on_connected = |stream: TcpStream, _peer: SocketAddr| {
        let connection = Arc::clone(&places).try_acquire_owned().ok().map(|permit| {
            let _ = stream.set_nodelay(true);
            let mut stream = TimeoutStream::new(stream);
            stream.set_read_timeout(Some(config.idle_timeout));
            stream.set_write_timeout(Some(config.idle_timeout));
            (Tables { shared: Arc::clone(&shared), _place: permit }, Box::pin(stream))
        });
        // None: over the limit, the stream is dropped (closed) and the listener goes on.
        ready(Ok::<_, std::io::Error>(connection))
    };
    loop {
        tokio::select! {
            _ = &mut stopped => return,
            result = server.serve(&on_connected, |_error| {}) => {
                if result.is_err() {
                    tokio::time::sleep(Duration::from_millis(100)).await;
                }
            }
        }
    }
}

/// One connection's service: the shared state, and its place among the connections (given back
/// when the connection ends and the service is dropped).
struct Tables {
    shared: Arc<Shared>,
    _place: OwnedSemaphorePermit,
}

/// The transport of a connection: the TCP stream with its idle timeouts.
type Transport = Pin<Box<TimeoutStream<TcpStream>>>;

const _: fn() = || {
    fn transport<T: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin + Send>() {}
    transport::<Transport>();
};

impl Service for Tables {
    type Request = SlaveRequest<'static>;
    type Response = Response;
    type Exception = ExceptionCode;
    type Future = Ready<Result<Response, ExceptionCode>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        ready(answer(&self.shared, req.slave, &req.request))
    }
}

/// The answer to one request: FC 03 and 04 read the map; every other function, writes included,
/// is exception 01 (the server is read-only: Modbus TCP carries no user to authorise a write).
pub fn answer(shared: &Shared, unit: u8, request: &Request<'_>) -> Result<Response, ExceptionCode> {
    if !UNIT_IDS.contains(&unit) {
        return Err(ExceptionCode::GatewayPathUnavailable);
    }
    let (address, quantity, holding) = match *request {
        Request::ReadInputRegisters(a, q) => (a, q, false),
        Request::ReadHoldingRegisters(a, q) => (a, q, true),
        _ => return Err(ExceptionCode::IllegalFunction),
    };
    let state = shared.state.lock().map_err(|_| ExceptionCode::ServerDeviceFailure)?;
    let registers =
        read_registers(&state, address, quantity).map_err(|e| ExceptionCode::new(e.exception_code()))?;
    drop(state);
    Ok(if holding {
        Response::ReadHoldingRegisters(registers)
    } else {
        Response::ReadInputRegisters(registers)
    })
}

#[cfg(test)]
mod tests;
