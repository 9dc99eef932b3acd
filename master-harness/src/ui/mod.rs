//! `dnet-master ui --listen 127.0.0.1:8080`: the scanner's web console, served by the binary itself.
//!
//! [`serve`] binds the address at once (an address in use is an error naming it) and answers on
//! its own threads while the scanner's loop goes on; both meet in [`Shared`]. The page, its style
//! and its script (plots drawn on a canvas by a few lines of vanilla JavaScript) are compiled into
//! the binary: the console needs no internet access and nothing installed but `dnet-master`.
//!
//! The HTTP server is `tiny_http`: small, synchronous (like the rest of the program, no async
//! runtime), long maintained, with no dependencies beyond a few tiny crates. One dispatcher thread
//! takes requests and hands each to a thread of its own (at most [`MAX_IN_FLIGHT`] at a time; past
//! that `503`), so a slow or vanished client never holds up the others.
//!
//! ## The page: three views
//!
//! | view | what it shows |
//! |---|---|
//! | Network | the 64 MAC IDs, each with its status (colour and the scanner's numeric code), product name, I/O connection (poll, strobe, cos, cyclic) and I/O sizes; the scanner's state, cycle time, bus load and MQTT state |
//! | Device (click a node) | identity; the input image decoded by the device's profile (breaker: the four phase currents, the switch state, parameters 0–3; Modbus: the scan-list values; otherwise raw bytes) with the status byte and freshness counter when the input assembly carries them; a live plot of the numeric values from the history; the breaker's Open / Close / Set parameter buttons and their outcome (status bits 4–6, or the switch state with assembly 100); explicit Get / Set; the Parameter object's table |
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
//! | `GET /api/state` | the [`ScannerState`](crate::scanner::model::ScannerState) (scanner status, cycles, `cycle_ms`, `bus_load`, `nodes`), plus `mqtt` (the publisher's state or `null`), `recording` and `history` (whether samples are kept) |
//! | `GET /api/frames?after=SEQ&mac=N&kind=K&limit=L` | `{"next": SEQ, "frames": [FrameRow...]}`: the frames after `SEQ` (default 0) concerning MAC `N`, of kind `K` (`explicit`, `io`, `duplicate_mac`, `ucmm`, `offline`), the newest `L` (default 500, at most 5000); `next` is the sequence number to ask after next time |
//! | `GET /api/node/MAC` | `{"node": NodeState, "profile", "fields", "link", "note", "input_hex", "output_hex"}`: the node decoded by its profile ([`layout_for`]); `fields` each `{name, values, text}`; `link` the status byte and freshness counter decoded, or `null` |
//! | `GET /api/node/MAC/params` | `{"params": [ParamRow...], "note"}`: the Parameter object (class 0x0F) read with Get_Attribute_Single; empty with a note when the device has none |
//! | `GET /api/history?mac=N&from=MS&to=MS&limit=L` | `{"mac", "samples": [{unix_ms, bus_us, input, values: [[name, number]...]}]}` from the history database (default: the last 60 s, at most 2000 samples, the newest when there are more) |
//! | `GET /api/export.csv?mac=N&from=MS&to=MS` | the samples as a CSV download (`mac` left out: every node), at most [`MAX_EXPORT`] bytes |
//! | `POST /api/node/MAC/output` body hex (`0201000000000000`) | puts the output image (ConsoleCommand::SetOutput) |
//! | `POST /api/node/MAC/get` `{"class", "instance", "attribute"}` | Get_Attribute_Single: `{"ok", "data": hex, "text"}` |
//! | `POST /api/node/MAC/set` `{"class", "instance", "attribute", "value": hex}` | Set_Attribute_Single |
//! | `POST /api/node/MAC/breaker/open`, `/breaker/close` | the breaker's command 1 / 2 in the output image, with the next sequence number (README, "Commands through the poll output") |
//! | `POST /api/node/MAC/breaker/param` `{"id", "value"}` | command 3: parameter `id` (0–255) set to `value` (0–65535) |
//! | `POST /api/record/start`, `/api/record/stop`; `GET /api/record` | recording of the frames to `record-TIMESTAMP.log` (`candump -L`) and `.pcap` in the record directory: `{"ok", "recording", "log", "pcap", "frames"}` |
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
//! [`Shared`]: crate::scanner::model::Shared
//! [`Shared::state`]: crate::scanner::model::Shared::state
//! [`Shared::push_frames`]: crate::scanner::model::Shared::push_frames
//! [`ConsoleCommand`]: crate::scanner::model::ConsoleCommand

mod api;
pub mod command;
mod record;

pub use api::{known_descriptions, layout_for};

use crate::error::HarnessError;
use crate::scanner::model::Shared;
use record::Recorder;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// The largest request body accepted, bytes (an output image or an attribute value in hex fits
/// many times over). `tiny_http` reads bodies this small before the request is handed over.
pub const MAX_BODY: usize = 1024;
/// The longest a command waits for the scanner's answer.
pub const COMMAND_TIMEOUT: Duration = Duration::from_secs(5);
/// The largest CSV export, bytes: a longer range is refused with a request for a shorter one.
pub const MAX_EXPORT: usize = 64 << 20;
/// Requests handled at once; more are answered `503` at once.
pub const MAX_IN_FLIGHT: usize = 64;

/// A running console server. [`UiServer::stop`] (or dropping it) stops taking requests, ends a
/// recording and joins the dispatcher.
pub struct UiServer {
    addr: SocketAddr,
    stop: Arc<AtomicBool>,
    dispatcher: Option<JoinHandle<()>>,
    context: Arc<Context>,
}

/// What every request handler reaches.
pub(crate) struct Context {
    pub(crate) shared: Arc<Shared>,
    pub(crate) recorder: Mutex<Option<Recorder>>,
    in_flight: AtomicUsize,
}

impl UiServer {
    /// The address it listens on (with the port the system chose for port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The page's URL, `http://127.0.0.1:8080/`.
    pub fn url(&self) -> String {
        format!("http://{}/", self.addr)
    }

    /// Stops the server: no new requests; a recording is closed. Requests being answered finish
    /// on their own threads.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(handle) = self.dispatcher.take() {
            let _ = handle.join();
        }
        if let Ok(mut recorder) = self.context.recorder.lock() {
            if let Some(r) = recorder.take() {
                let _ = r.stop();
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
/// available is a [`HarnessError::Usage`] naming it.
pub fn serve(listen: &str, shared: Arc<Shared>) -> Result<UiServer, HarnessError> {
    let server = tiny_http::Server::http(listen)
        .map_err(|e| HarnessError::Usage(format!("cannot listen on {listen}: {e}")))?;
    let addr = server
        .server_addr()
        .to_ip()
        .ok_or_else(|| HarnessError::Usage(format!("cannot listen on {listen}: not an IP address")))?;
    let context = Arc::new(Context { shared, recorder: Mutex::new(None), in_flight: AtomicUsize::new(0) });
    let stop = Arc::new(AtomicBool::new(false));
    let dispatcher = {
        let context = Arc::clone(&context);
        let stop = Arc::clone(&stop);
        std::thread::Builder::new()
            .name("ui-dispatch".into())
            .spawn(move || dispatch(&server, &context, &stop))
            .map_err(|e| HarnessError::Usage(format!("cannot start the console on {listen}: {e}")))?
    };
    Ok(UiServer { addr, stop, dispatcher: Some(dispatcher), context })
}

/// Takes requests until `stop`, each answered on a thread of its own.
fn dispatch(server: &tiny_http::Server, context: &Arc<Context>, stop: &AtomicBool) {
    while !stop.load(Ordering::SeqCst) {
        let request = match server.recv_timeout(Duration::from_millis(100)) {
            Ok(Some(r)) => r,
            Ok(None) => continue,
            Err(_) => {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        if context.in_flight.fetch_add(1, Ordering::SeqCst) >= MAX_IN_FLIGHT {
            context.in_flight.fetch_sub(1, Ordering::SeqCst);
            // Answered from a thread of its own all the same: the response may block.
            let _ = std::thread::Builder::new().spawn(move || {
                let _ = request.respond(api::error_response(503, "too many requests at once; try again"));
            });
            continue;
        }
        let ctx = Arc::clone(context);
        let spawned = std::thread::Builder::new().name("ui-request".into()).spawn(move || {
            api::handle(&ctx, request);
            ctx.in_flight.fetch_sub(1, Ordering::SeqCst);
        });
        if spawned.is_err() {
            context.in_flight.fetch_sub(1, Ordering::SeqCst);
        }
    }
}
