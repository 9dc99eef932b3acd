//! `dnet-master ui --listen 127.0.0.1:8080`: the scanner's web console, served by the binary itself.
//!
//! [`serve`] binds the address at once (an address in use is an error naming it) and answers on
//! its own threads while the scanner's loop goes on; both meet in [`Shared`]. The page, its style
//! and its script (plots drawn on a canvas by a few lines of vanilla JavaScript) are compiled into
//! the binary: the console needs no internet access and nothing installed but `dnet-master`.
//!
//! The HTTP server ([`http`]) is the program's own, synchronous like the rest of it: one thread
//! accepts, a fixed pool of [`http::WORKERS`] threads answers, [`http::QUEUE`] connections may
//! wait, beyond that `503` at once; so a slow, silent or vanished client never holds up the
//! others for long, and no number of connections makes threads.
//!
//! Every request is checked first (`guard`): `Host` must name the console; a state-changing
//! request (anything but `GET` / `HEAD`) must also come from the console's own `Origin` and be
//! `Content-Type: application/json`. Then `auth` finds the caller and checks the rest: with
//! accounts ([`serve_with`], [`Access::users`], `dnet-master ui --users FILE`) a session cookie
//! ([`COOKIE`], from `POST /api/login`; `401` without one), the session's token in
//! `X-CSRF-Token` on every state-changing request, and the role ([`crate::accounts::Role::may`];
//! `403` with the reason when it may not). Without accounts every caller may do everything, with
//! the process's token (`GET /api/token`, the page's `<meta name="csrf-token">`); the program
//! then listens on loopback only. Anything refused is answered with the reason: another web page
//! open in the same browser cannot drive the console. Every state-changing request is recorded in
//! the audit log ([`crate::audit`], [`Shared::audit`]). With [`Access::tls`] the server speaks
//! TLS only ([`tls`]).
//!
//! ## The page: three views
//!
//! | view | what it shows |
//! |---|---|
//! | Network | the 64 MAC IDs, each with its status (colour and the scanner's numeric code), product name, I/O connection (poll, strobe, cos, cyclic) and I/O sizes; the scanner's state, cycle time, bus load and MQTT state; with `dnet-master ui --project FILE`, the Project panel: what of the network project was compared, what not and why, every difference ([`crate::project::console`]) |
//! | Device (click a node) | identity; for a serial converter, the Serial line panel (its line trace decoded, polled while open); the input image decoded by the device's profile (breaker: the four phase currents, the switch state, parameters 0–3; Modbus: the scan-list values; otherwise raw bytes) with the status byte and freshness counter when the input assembly carries them; a live plot of the numeric values from the history; the breaker's Open / Close / Set parameter buttons and their outcome (status bits 4–6, or the switch state with assembly 100); explicit Get / Set; the Parameter object's table |
//! | Trace | the live frames decoded as `dnet-master decode` does, filtered by MAC and message kind; Start / Stop recording with the files named |
//!
//! The page polls the API (state every 500 ms, frames every 300 ms, the plot every second): a
//! closed tab leaves nothing behind on the server.
//!
//! ## JSON API
//!
//! Everything the page does goes through this API, so it can be scripted (`curl`). Errors are
//! `{"ok": false, "error": "..."}` with a 4xx/5xx status, the reason in words; nothing a client
//! sends can stop the server. Request bodies are limited to [`MAX_BODY`] bytes.
//!
//! | request | answer |
//! |---|---|
//! | `GET /api/state` | the [`ScannerState`](crate::model::ScannerState) (scanner status, cycles, `cycle_ms`, `bus_load`, `nodes`), plus `mqtt` (the publisher's state or `null`), `recording` and `history` (whether samples are kept) |
//! | `GET /api/frames?after=SEQ&mac=N&kind=K&limit=L` | `{"next": SEQ, "frames": [FrameRow...]}`: the frames after `SEQ` (default 0) concerning MAC `N`, of kind `K` (`explicit`, `io`, `duplicate_mac`, `ucmm`, `offline`), the newest `L` (default 500, at most 5000); `next` is the sequence number to ask after next time |
//! | `GET /api/node/MAC` | `{"node": NodeState, "profile", "fields", "link", "note", "input_hex", "output_hex"}`: the node decoded by its profile ([`layout_for`]); `fields` each `{name, values, text}`; `link` the status byte and freshness counter decoded, or `null` |
//! | `GET /api/project/compare` | the network project of `--project FILE` against the running network ([`crate::project::console`]): `{"ok", "project", "compared": {nodes, scan_list, identity, configuration, parameters}, "not_compared": [{mac, what, why, wanted}], "differences": [{mac, what, expected, found}], "equal"}`; `equal` only when something was compared and nothing differs or was left out; `409` when nothing could be compared, `404` without `--project` |
//! | `GET /api/node/MAC/serial-trace?since=N` | the converter's serial-line analyzer read with Read_Trace and decoded by its profile (`serial_trace_api`): `{"ok", "converter", "profile", "next", "lines": [{n, seq, time_ms, kind, hex, decoded}], "dropped", "entries", "missed"}`; `converter: false` with a `note` for a node without the analyzer (class 0x68) |
//! | `GET /api/node/MAC/params` | `{"params": [ParamRow...], "note"}`: the Parameter object (class 0x0F) read with Get_Attribute_Single; empty with a note when the device has none |
//! | `GET /api/history?mac=N&from=MS&to=MS&limit=L` | `{"mac", "samples": [{unix_ms, bus_us, input, values: [[name, number]...]}]}` from the history database (default: the last 60 s, at most 2000 samples, the newest when there are more) |
//! | `GET /api/export.csv?mac=N&from=MS&to=MS` | the samples as a CSV download (`mac` left out: every node), at most [`MAX_EXPORT`] bytes |
//! | `GET /api/token` | `{"ok", "token"}`: the token every state-changing request carries in `X-CSRF-Token` (the session's with accounts) |
//! | `POST /api/login` `{"user", "password"}` | a session: `{"ok", "user", "role", "token", "may"}` and the cookie [`COOKIE`] (`HttpOnly; SameSite=Strict; Path=/`, `Secure` with TLS); `401` for a wrong name or password |
//! | `GET /api/session`; `POST /api/logout` | who is logged in (as the login's answer; `401` when nobody); the session ended and its cookie cleared |
//! | `GET /api/audit?limit=N` | `{"ok", "entries": [{unix_ms, user, via, mac, what, result}]}`: the audit log, newest first (default 200, at most 2000) |
//! | `POST /api/node/MAC/output` `{"data": hex}` (`"0201000000000000"`) | puts the output image (ConsoleCommand::SetOutput) |
//! | `POST /api/node/MAC/get` `{"class", "instance", "attribute"}` | Get_Attribute_Single: `{"ok", "data": hex, "text"}` |
//! | `POST /api/node/MAC/set` `{"class", "instance", "attribute", "value": hex}` | Set_Attribute_Single |
//! | `POST /api/node/MAC/breaker/open`, `/breaker/close` | the breaker's command 1 / 2 in the output image, with the next sequence number (guide: docs/src/reference/io-data.md, "Commands through the poll output") |
//! | `POST /api/node/MAC/breaker/param` `{"id", "value"}` | command 3: parameter `id` (0–255) set to `value` (0–65535) |
//! | `POST /api/record/start`, `/api/record/stop`; `GET /api/record` | recording of the frames to `record-TIMESTAMP.log` (`candump -L`) and `.pcap` in the record directory: `{"ok", "recording", "log", "pcap", "frames"}` |
//! | `GET /api/health`, `GET /api/health.csv`, `POST /api/health/clear` | bus and node health ([`crate::health`]; handlers in `health_api`): the report as JSON, its node table as CSV, the statistics cleared (then the fresh report) |
//! | `GET /api/events?since=N` | `{"ok", "events": [ScanEvent...]}`: the scanner's events after sequence number N ([`crate::events`]: automatic device replacement, scan-list changes; handlers in `scanlist_api`) |
//! | `GET /api/networks`; `/api/net/NAME/...` | with `dnet-master ui --plant` (`networks`): the plant's networks `{"ok", "networks": [{name, bus}]}`; any request above for network `NAME` (`/api/net/line-b/node/5/breaker/open`); the unprefixed API is the first network's, and `GET /api/state` carries `networks`, each network's state with its `name` and `bus` |
//! | `POST /api/scanlist/add`, `/edit` (an entry as JSON, the scan list file's keys), `/remove` `{"mac"}`, `/enable` `{"mac", "enabled"}` | the scan list changed while the scanner runs ([`ListEdit`](crate::model::ListEdit)); `400` with the reason (the key, the MAC) when refused |
//!
//! Commands wait for the scanner's answer for at most [`COMMAND_TIMEOUT`] and return
//! `{"ok": true, "data": hex}` or `{"ok": false, "error": "..."}` (the device's error response by
//! name, a node that is not ok, a timeout).
//!
//! ## What the program around it provides
//!
//! The scanner's loop updates [`Shared::state`] after each cycle, appends its frames with
//! [`Shared::push_frames`] (sequence numbers rising), carries out the [`ConsoleCommand`]s it
//! receives and answers each one; `history` and `mqtt` are filled when kept. The recording reads
//! only the frame ring.
//!
//! [`Shared`]: crate::model::Shared
//! [`Shared::state`]: crate::model::Shared::state
//! [`Shared::audit`]: crate::model::Shared::audit
//! [`Shared::push_frames`]: crate::model::Shared::push_frames
//! [`ConsoleCommand`]: crate::model::ConsoleCommand

mod api;
mod auth;
mod guard;
mod health_api;
pub mod http;
mod networks;
mod project_api;
mod record;
mod scanlist_api;
mod serial_trace_api;
pub mod thinning;
pub mod tls;

pub use api::{known_descriptions, layout_for};
pub use auth::{COOKIE, MAX_SESSIONS, SESSION_IDLE};
pub use guard::{GuardError, TOKEN_HEADER};
pub use networks::ConsoleNetwork;

use crate::model::Shared;
use auth::Auth;
use guard::Guard;
use harness_common::error::HarnessError;
use record::Recorder;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// The largest request body accepted, bytes (an output image or an attribute value in hex fits
/// many times over); a larger one is refused unread.
pub const MAX_BODY: usize = 1024;
/// The longest a command waits for the scanner's answer.
pub const COMMAND_TIMEOUT: Duration = Duration::from_secs(5);
/// The largest CSV export, bytes: a longer range is refused with a request for a shorter one.
pub const MAX_EXPORT: usize = 64 << 20;

/// A running console server. [`UiServer::stop`] (or dropping it) stops taking requests (the port
/// is released) and ends a recording.
pub struct UiServer {
    addr: SocketAddr,
    tls: bool,
    server: http::Server,
    context: Arc<Context>,
}

/// What every request handler reaches.
pub(crate) struct Context {
    pub(crate) shared: Arc<Shared>,
    pub(crate) recorder: Mutex<Option<Recorder>>,
    pub(crate) guard: Guard,
    pub(crate) auth: Auth,
    /// The network project (its file's name and the project), from `--project FILE`.
    pub(crate) project: Option<(String, crate::project::Project)>,
    /// The plant's networks (`ui --plant`; empty: one network, [`networks`]).
    pub(crate) networks: Vec<networks::NetworkContext>,
    /// The serial-line analyzer's lines kept per node (`serial_trace_api`).
    pub(crate) serial_traces: serial_trace_api::Traces,
}

/// Who may use the console and how it is reached: the accounts (`None`: no logins, loopback
/// only) and the TLS configuration (`None`: plain HTTP).
#[derive(Default)]
pub struct Access {
    /// The accounts, from `--users FILE`.
    pub users: Option<crate::accounts::Users>,
    /// The TLS configuration, from `--tls-cert` / `--tls-key` ([`tls::server_config`]).
    pub tls: Option<Arc<rustls::ServerConfig>>,
    /// The network project `GET /api/project/compare` compares with the network (the file's
    /// name, the project), from `dnet-master ui --project FILE`.
    pub project: Option<(String, crate::project::Project)>,
}

impl UiServer {
    /// The address it listens on (with the port the system chose for port 0).
    #[must_use]
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's URL, `http://127.0.0.1:8080/` (`https://` with TLS).
    #[must_use]
    pub fn url(&self) -> String {
        format!("{}://{}/", if self.tls { "https" } else { "http" }, self.addr)
    }

    /// The token a state-changing request carries in [`TOKEN_HEADER`] (the page has it too)
    /// without a users file; empty with one (each session has its own).
    #[must_use]
    pub fn token(&self) -> &str {
        self.context.auth.page_token()
    }

    /// Stops the server: no new requests; a recording is closed. Requests being answered finish
    /// on their own threads.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.server.stop();
        let networks = self.context.networks.iter().map(|n| &n.context);
        for context in std::iter::once(&self.context).chain(networks) {
            if let Ok(mut recorder) = context.recorder.lock() {
                if let Some(r) = recorder.take() {
                    let _ = r.stop();
                }
            }
        }
    }
}

impl Drop for UiServer {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Starts the console on `listen` (`127.0.0.1:8080`; port 0: any free port, see
/// [`UiServer::addr`]). The address is bound before this returns: an address in use or not
/// available is a [`HarnessError::Listen`] naming it.
pub fn serve(listen: &str, shared: Arc<Shared>) -> Result<UiServer, HarnessError> {
    serve_with(listen, shared, Access::default())
}

/// [`serve`] with accounts and / or TLS ([`Access`]).
pub fn serve_with(listen: &str, shared: Arc<Shared>, access: Access) -> Result<UiServer, HarnessError> {
    serve_plant(listen, shared, access, Vec::new())
}

/// [`serve_with`] for several networks (`dnet-master ui --plant`): each network's API under
/// `/api/net/NAME/`, the unprefixed API `shared`'s (the first network's); see `networks`.
pub fn serve_plant(
    listen: &str,
    shared: Arc<Shared>,
    access: Access,
    plant: Vec<ConsoleNetwork>,
) -> Result<UiServer, HarnessError> {
    let (listener, addr) =
        http::bind(listen).map_err(|error| HarnessError::Listen { address: listen.to_string(), error })?;
    let token = guard::new_token().map_err(|e| HarnessError::ConsoleStart {
        address: String::new(),
        error: format!("no random token: {e}"),
    })?;
    let tls = access.tls.is_some();
    let networks = plant
        .into_iter()
        .map(|n| networks::NetworkContext {
            name: n.name,
            bus: n.bus,
            context: Arc::new(Context {
                shared: n.shared,
                recorder: Mutex::new(None),
                guard: Guard::new(addr, tls),
                auth: Auth::new(None, token.clone(), tls),
                project: None,
                networks: Vec::new(),
                serial_traces: Default::default(),
            }),
        })
        .collect();
    let context = Arc::new(Context {
        shared,
        recorder: Mutex::new(None),
        guard: Guard::new(addr, tls),
        auth: Auth::new(access.users, token, tls),
        project: access.project,
        networks,
        serial_traces: Default::default(),
    });
    let handler = {
        let context = Arc::clone(&context);
        Arc::new(move |r: &http::Request| api::handle(&context, r)) as Arc<http::Handler>
    };
    let server = http::Server::start(listener, handler, api::error_response, MAX_BODY, access.tls)
        .map_err(|e| HarnessError::ConsoleStart { address: listen.to_string(), error: e.to_string() })?;
    Ok(UiServer { addr, tls, server, context })
}
