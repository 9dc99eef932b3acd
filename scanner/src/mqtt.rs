//! `--mqtt URL`: the scanner's node status and decoded values, published to an existing MQTT
//! broker, where one bench grows into a plant (a SCADA, Node-RED, Grafana or Home Assistant
//! subscribes there).
//!
//! The client is `rumqttc`'s synchronous [`Client`] (MQTT 3.1.1, over TCP or TLS), its event loop
//! turned by a background thread of the [`Publisher`]: the scanner's thread only puts messages in
//! a bounded queue and never waits for the network.
//!
//! ## URL
//!
//! `mqtt://[USER[:PASSWORD]@]HOST[:PORT][/PREFIX]` (`tcp://` is the same): port 1883 by default,
//! topic prefix `devicenet` by default (`mqtt://broker/plant/line1` publishes under
//! `plant/line1/...`). An IPv6 host is written in brackets (`mqtt://[::1]:1883`). A malformed URL
//! is an error of [`Publisher::start`]; `ws://` is refused (no websockets in this build).
//!
//! ## TLS
//!
//! `mqtts://` (`ssl://`, `tls://` are the same) connects with TLS 1.2 or 1.3 (rustls), port 8883 by
//! default. The broker's certificate is checked against [`TlsFiles::ca`] (`--mqtt-ca FILE`, PEM)
//! when given, else against the system's trusted roots, and its name against the URL's host. With
//! [`TlsFiles::cert`] and [`TlsFiles::key`] (`--mqtt-cert`, `--mqtt-key`, PEM) the client
//! authenticates itself with a certificate too. An unreadable file is an error of
//! [`Publisher::start`]; a certificate the broker's does not match is a failed connection (the
//! status says why, and it is tried again like a broker that is down).
//!
//! ## Topics and payloads
//!
//! | topic | retained | QoS | published |
//! |---|---|---|---|
//! | `PREFIX/scanner` | yes | 1 | when the scanner's status changes, else at most once a second |
//! | `PREFIX/node/<mac>/status` | yes | 1 | when the node's status, identity or sizes change |
//! | `PREFIX/node/<mac>/values` | no | 0 | every sample given to [`Publisher::publish_samples`] |
//! | `PREFIX/events` | no | 1 | each event given to [`Publisher::publish_events`] (automatic device replacement, scan-list changes): the [`crate::events::ScanEvent`] as JSON, `{"seq":4,"time_us":12018504,"mac":5,"kind":"moved","detail":"..."}` |
//!
//! `<mac>` is the decimal MAC ID (`devicenet/node/5/status`). Every retained message is published
//! again on each (re)connection, so a broker restarted empty learns the current state at once.
//!
//! `PREFIX/scanner`:
//!
//! ```json
//! {"mac":0,"status":"running","cycles":1200,"cycle_ms":68.4,"bus_load":0.84,
//!  "interscan_delay_ms":2,"expected_packet_rate_ms":300,"nodes":63,"nodes_ok":62,
//!  "unix_ms":1714564800123}
//! ```
//!
//! `status` is the scanner's ([`ScannerStatus`], snake
//! case). When the scanner's connection to the broker is lost without a goodbye (the process
//! killed, the network cut), the broker publishes the last will `{"status":"offline"}` there,
//! retained.
//!
//! `PREFIX/node/<mac>/status`:
//!
//! ```json
//! {"mac":5,"name":"feeder 1","connection":"poll","ack_suppression":false,"status":"ok","code":0,
//!  "detail":null,"product_name":"Serial-DeviceNet breaker",
//!  "vendor_id":1234,"device_type":12,"product_code":1,"revision":"1.1",
//!  "serial_number":305419896,"input_size":18,"output_size":8}
//! ```
//!
//! `name` and `connection` are the scan list's (`name` `null` when it gives none; `poll`, `strobe`,
//! `cos`, `cyclic`); `status` and `code` are
//! [`NodeStatus::name`] and [`NodeStatus::code`] (the scanner status codes); identity fields not
//! read yet are `null`.
//!
//! `PREFIX/node/<mac>/values`:
//!
//! ```json
//! {"mac":5,"unix_ms":1714564800123,"bus_us":123456789,"input_hex":"0A0014000000",
//!  "values":{"phase_a":10.0,"phase_b":20.0,"switch":1.0}}
//! ```
//!
//! A value that is not a finite number is `null`.
//!
//! ## A broker that is down
//!
//! It is not an error: [`Publisher::start`] returns at once and the background thread keeps
//! trying (every 0.5 s, backing off to every 5 s), [`Publisher::status`] says
//! `broker unreachable: <reason>, retrying`. Meanwhile values are dropped (counted by
//! [`Publisher::dropped`]) and the latest retained messages are kept, one per topic, to be
//! published on connection. Once connected the queue holds at most [`QUEUE`] messages; when the
//! broker cannot keep up, further messages are dropped and counted, never waited for. Memory is
//! bounded: the queue, and one retained message per node and one for the scanner.
//!
//! Dropping the [`Publisher`] sends what is queued and disconnects cleanly (waiting at most 1.5 s
//! for it), so the retained state is the last one published, not the last will.

use crate::history::hex;
use crate::model::{NodeState, NodeStatus, Sample, ScannerState, ScannerStatus};
use rumqttc::{Client, ConnectionError, Event, LastWill, MqttOptions, Outgoing, Packet, QoS};
use serde_json::{json, Map, Value};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// The capacity of the queue between the caller and the network, in messages.
pub const QUEUE: usize = 256;

/// The topic prefix when the URL gives none.
pub const DEFAULT_PREFIX: &str = "devicenet";

/// How often the scanner topic is republished while its status stays the same.
const SCANNER_PERIOD: Duration = Duration::from_secs(1);

/// The first and the longest wait between two connection attempts.
const RETRY_FIRST: Duration = Duration::from_millis(500);
const RETRY_MAX: Duration = Duration::from_secs(5);

/// Where to publish: what [`parse_url`] finds in `--mqtt URL`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Endpoint {
    /// Host name or address (an IPv6 address in brackets).
    pub host: String,
    /// TCP port.
    pub port: u16,
    /// Topic prefix, without a trailing `/`.
    pub prefix: String,
    /// User name and password.
    pub credentials: Option<(String, String)>,
    /// `mqtts://`: TLS.
    pub tls: bool,
}

impl Endpoint {
    /// `mqtt://HOST:PORT/PREFIX` (`mqtts://` with TLS), without the password.
    #[must_use]
    pub fn display(&self) -> String {
        let scheme = if self.tls { "mqtts" } else { "mqtt" };
        format!("{scheme}://{}:{}/{}", self.host, self.port, self.prefix)
    }
}

/// The files of a TLS connection to the broker (see the [module docs](self#tls)).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TlsFiles {
    /// The certificate authority (PEM) the broker's certificate must chain to; `None`: the
    /// system's trusted roots.
    pub ca: Option<std::path::PathBuf>,
    /// The client's certificate chain (PEM), for a broker that asks for one.
    pub cert: Option<std::path::PathBuf>,
    /// The client's private key (PEM).
    pub key: Option<std::path::PathBuf>,
}

/// Why a TLS configuration cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    /// A PEM file cannot be read or holds no certificate / key.
    #[error("{option} {path}: {detail}")]
    File {
        /// `--mqtt-ca`, `--mqtt-cert` or `--mqtt-key`.
        option: &'static str,
        /// The file.
        path: String,
        /// Why.
        detail: String,
    },
    /// Only one of the certificate and the key is given.
    #[error("--mqtt-cert and --mqtt-key go together")]
    HalfClientAuth,
    /// TLS files given for a plain `mqtt://` URL.
    #[error("--mqtt-ca, --mqtt-cert and --mqtt-key need an mqtts:// URL")]
    NotTls,
    /// rustls refused the configuration.
    #[error("TLS: {0}")]
    Rustls(#[from] rustls::Error),
}

/// The rustls client configuration of `files` (ring provider).
fn tls_config(files: &TlsFiles) -> Result<rustls::ClientConfig, TlsError> {
    use rustls::pki_types::pem::PemObject;
    use rustls::pki_types::{CertificateDer, PrivateKeyDer};
    fn file_err<'a>(
        option: &'static str,
        path: &'a std::path::Path,
    ) -> impl Fn(&dyn std::fmt::Display) -> TlsError + 'a {
        move |e| TlsError::File { option, path: path.display().to_string(), detail: e.to_string() }
    }
    let certs =
        |option: &'static str, path: &std::path::Path| -> Result<Vec<CertificateDer<'static>>, TlsError> {
            let e = file_err(option, path);
            let certs: Vec<_> = CertificateDer::pem_file_iter(path)
                .map_err(|x| e(&x))?
                .collect::<Result<_, _>>()
                .map_err(|x| e(&x))?;
            if certs.is_empty() {
                return Err(e(&"no certificate (PEM) in the file"));
            }
            Ok(certs)
        };
    let provider = std::sync::Arc::new(rustls::crypto::ring::default_provider());
    let builder =
        rustls::ClientConfig::builder_with_provider(provider).with_safe_default_protocol_versions()?;
    let mut roots = rustls::RootCertStore::empty();
    match &files.ca {
        Some(ca) => {
            for cert in certs("--mqtt-ca", ca)? {
                roots.add(cert).map_err(|x| file_err("--mqtt-ca", ca)(&x))?;
            }
        }
        None => {
            let _ = roots.add_parsable_certificates(rustls_native_certs::load_native_certs().certs);
        }
    }
    let builder = builder.with_root_certificates(roots);
    Ok(match (&files.cert, &files.key) {
        (Some(cert), Some(key)) => {
            let chain = certs("--mqtt-cert", cert)?;
            let key = PrivateKeyDer::from_pem_file(key).map_err(|x| file_err("--mqtt-key", key)(&x))?;
            builder.with_client_auth_cert(chain, key)?
        }
        (None, None) => builder.with_no_client_auth(),
        _ => return Err(TlsError::HalfClientAuth),
    })
}

/// The options of a connection to `endpoint` as `client_id`: keep-alive 10 s, clean session,
/// credentials, and TLS for `mqtts://` (see the [module docs](self#tls)).
pub fn mqtt_options(endpoint: &Endpoint, client_id: &str, tls: &TlsFiles) -> Result<MqttOptions, TlsError> {
    // rumqttc joins host and port as `HOST:PORT`: an IPv6 host keeps its brackets.
    let mut options = MqttOptions::new(client_id, endpoint.host.clone(), endpoint.port);
    options.set_keep_alive(Duration::from_secs(10)).set_clean_session(true);
    if let Some((user, pass)) = &endpoint.credentials {
        options.set_credentials(user.clone(), pass.clone());
    }
    if endpoint.tls {
        let config = tls_config(tls)?;
        options.set_transport(rumqttc::Transport::tls_with_config(rumqttc::TlsConfiguration::Rustls(
            std::sync::Arc::new(config),
        )));
    } else if *tls != TlsFiles::default() {
        return Err(TlsError::NotTls);
    }
    Ok(options)
}

/// Parses `mqtt://[USER[:PASSWORD]@]HOST[:PORT][/PREFIX]` (see the [module docs](self)).
pub fn parse_url(url: &str) -> Result<Endpoint, String> {
    let bad = |why: &str| format!("malformed MQTT URL `{url}`: {why} (expected mqtt://HOST[:PORT][/PREFIX])");
    let (scheme, rest) = url.split_once("://").ok_or_else(|| bad("no scheme"))?;
    let tls = match scheme.to_ascii_lowercase().as_str() {
        "mqtt" | "tcp" => false,
        "mqtts" | "ssl" | "tls" => true,
        "ws" | "wss" => {
            return Err(format!(
                "MQTT URL `{url}`: {scheme}:// is not supported (no websockets in this build): use \
                 mqtt:// or mqtts://"
            ))
        }
        _ => return Err(bad(&format!("unknown scheme `{scheme}`"))),
    };
    if rest.contains('?') {
        return Err(bad("a query is not allowed"));
    }
    let (authority, path) = rest.split_once('/').unwrap_or((rest, ""));
    let (userinfo, hostport) = match authority.rsplit_once('@') {
        Some((u, h)) => (Some(u), h),
        None => (None, authority),
    };
    let credentials = userinfo.map(|u| match u.split_once(':') {
        Some((user, pass)) => (user.to_owned(), pass.to_owned()),
        None => (u.to_owned(), String::new()),
    });
    let (host, port) = if let Some(v6) = hostport.strip_prefix('[') {
        let (addr, after) = v6.split_once(']').ok_or_else(|| bad("unclosed `[`"))?;
        let port = match after {
            "" => None,
            p => Some(p.strip_prefix(':').ok_or_else(|| bad("text after `]`"))?),
        };
        (format!("[{addr}]"), port)
    } else {
        match hostport.split_once(':') {
            Some((h, p)) => (h.to_owned(), Some(p)),
            None => (hostport.to_owned(), None),
        }
    };
    if host.is_empty() || host == "[]" {
        return Err(bad("no host"));
    }
    if host.chars().any(|c| c.is_whitespace() || c.is_control() || c == '#') {
        return Err(bad("a space, `#` or control character in the host"));
    }
    let port = match port {
        None if tls => 8883,
        None => 1883,
        Some(p) => match p.parse::<u16>() {
            Ok(n) if n > 0 => n,
            _ => return Err(bad(&format!("port `{p}` is not 1-65535"))),
        },
    };
    let prefix = path.trim_end_matches('/');
    if prefix.contains(['+', '#', '?', '\0']) {
        return Err(bad("the topic prefix may not hold `+`, `#`, `?` or NUL"));
    }
    let prefix = if prefix.is_empty() { DEFAULT_PREFIX } else { prefix };
    Ok(Endpoint { host, port, prefix: prefix.to_owned(), credentials, tls })
}

/// The state of the link to the broker.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Link {
    Connecting,
    Connected,
    Unreachable(String),
}

/// What the caller's thread and the background thread share.
struct Inner {
    link: Link,
    /// The latest payload of every retained topic (bounded: 64 nodes and the scanner).
    retained: BTreeMap<String, Vec<u8>>,
    /// The scanner topic: the status last sent and when.
    scanner_sent: Option<(ScannerStatus, Instant)>,
}

struct Shared {
    inner: Mutex<Inner>,
    dropped: AtomicU64,
    stop: AtomicBool,
}

impl Shared {
    fn lock(&self) -> MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// Publishes the scanner's state and samples to an MQTT broker (see the [module docs](self)).
/// No method blocks on the network; the publisher never panics.
pub struct Publisher {
    endpoint: Endpoint,
    client: Client,
    shared: Arc<Shared>,
    /// Says when the background thread has ended.
    done: Option<mpsc::Receiver<()>>,
}

impl std::fmt::Debug for Publisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Publisher").field("endpoint", &self.endpoint.display()).finish()
    }
}

impl Publisher {
    /// Parses `url` and starts the background connection as `client_id` (empty: `dnet-master`).
    /// A malformed URL is an error; a broker that is down is not (see [`Publisher::status`]).
    pub fn start(url: &str, client_id: &str) -> Result<Publisher, String> {
        Publisher::start_tls(url, client_id, &TlsFiles::default())
    }

    /// [`Publisher::start`] with the files of a TLS connection (`mqtts://`). An unreadable file
    /// is an error.
    pub fn start_tls(url: &str, client_id: &str, tls: &TlsFiles) -> Result<Publisher, String> {
        let endpoint = parse_url(url)?;
        let client_id = if client_id.is_empty() { "dnet-master" } else { client_id };
        let mut options = mqtt_options(&endpoint, client_id, tls).map_err(|e| e.to_string())?;
        options.set_last_will(LastWill::new(
            format!("{}/scanner", endpoint.prefix),
            r#"{"status":"offline"}"#,
            QoS::AtLeastOnce,
            true,
        ));
        let (client, mut connection) = Client::new(options, QUEUE);
        let shared = Arc::new(Shared {
            inner: Mutex::new(Inner {
                link: Link::Connecting,
                retained: BTreeMap::new(),
                scanner_sent: None,
            }),
            dropped: AtomicU64::new(0),
            stop: AtomicBool::new(false),
        });
        let (done_tx, done) = mpsc::channel();
        let thread_shared = Arc::clone(&shared);
        let thread_client = client.clone();
        std::thread::Builder::new()
            .name("mqtt".into())
            .spawn(move || {
                run(&mut connection, &thread_client, &thread_shared);
                let _ = done_tx.send(());
            })
            .map_err(|e| format!("cannot start the MQTT thread: {e}"))?;
        Ok(Publisher { endpoint, client, shared, done: Some(done) })
    }

    /// The broker, `mqtt://HOST:PORT/PREFIX`.
    #[must_use]
    pub fn url(&self) -> String {
        self.endpoint.display()
    }

    /// The topic prefix.
    #[must_use]
    pub fn prefix(&self) -> &str {
        &self.endpoint.prefix
    }

    /// The link in words: `connected to mqtt://...`, `broker unreachable: <reason>, retrying`,
    /// or `connecting to mqtt://...` before the first attempt ends.
    #[must_use]
    pub fn status(&self) -> String {
        match &self.shared.lock().link {
            Link::Connecting => format!("connecting to {}", self.url()),
            Link::Connected => format!("connected to {}", self.url()),
            Link::Unreachable(why) => format!("broker unreachable: {why}, retrying"),
        }
    }

    /// Whether the broker has accepted the connection (and it has not been lost since).
    #[must_use]
    pub fn is_connected(&self) -> bool {
        self.shared.lock().link == Link::Connected
    }

    /// Messages dropped so far: values published while the broker was unreachable, and messages
    /// that found the queue full.
    #[must_use]
    pub fn dropped(&self) -> u64 {
        self.shared.dropped.load(Ordering::Relaxed)
    }

    /// Publishes the scanner topic and each node's status topic, retained, those that changed
    /// (see the [module docs](self)). Never blocks.
    pub fn publish_state(&self, state: &ScannerState) {
        let mut inner = self.shared.lock();
        let connected = inner.link == Link::Connected;
        for node in &state.nodes {
            let topic = format!("{}/node/{}/status", self.endpoint.prefix, node.mac);
            let payload = node_status_payload(node);
            if inner.retained.get(&topic) != Some(&payload) {
                if connected {
                    self.send(&topic, QoS::AtLeastOnce, true, payload.clone());
                }
                inner.retained.insert(topic, payload);
            }
        }
        let topic = format!("{}/scanner", self.endpoint.prefix);
        let payload = scanner_payload(state);
        let now = Instant::now();
        let due = match inner.scanner_sent {
            Some((status, at)) => status != state.status || now.duration_since(at) >= SCANNER_PERIOD,
            None => true,
        };
        if due {
            if connected {
                self.send(&topic, QoS::AtLeastOnce, true, payload.clone());
            }
            inner.scanner_sent = Some((state.status, now));
        }
        inner.retained.insert(topic, payload);
    }

    /// Publishes each sample on its node's values topic, not retained. Never blocks: while the
    /// broker is unreachable, or when the queue is full, samples are dropped and counted.
    pub fn publish_samples(&self, samples: &[Sample]) {
        let connected = self.shared.lock().link == Link::Connected;
        for sample in samples {
            if !connected {
                self.shared.dropped.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            let topic = format!("{}/node/{}/values", self.endpoint.prefix, sample.mac);
            self.send(&topic, QoS::AtMostOnce, false, values_payload(sample));
        }
    }

    /// Publishes each event on the events topic, not retained (see the [module docs](self)). Never
    /// blocks: while the broker is unreachable they are dropped and counted.
    pub fn publish_events(&self, events: &[crate::events::ScanEvent]) {
        let connected = self.shared.lock().link == Link::Connected;
        for event in events {
            if !connected {
                self.shared.dropped.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            let topic = format!("{}/events", self.endpoint.prefix);
            let payload = serde_json::to_vec(event).unwrap_or_default();
            self.send(&topic, QoS::AtLeastOnce, false, payload);
        }
    }

    fn send(&self, topic: &str, qos: QoS, retain: bool, payload: Vec<u8>) {
        if self.client.try_publish(topic, qos, retain, payload).is_err() {
            self.shared.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl Drop for Publisher {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        // Queued behind what was published: sent once they are, then the thread ends.
        let _ = self.client.try_disconnect();
        if let Some(done) = self.done.take() {
            // A thread still waiting on a connection attempt ends on its own when it gives up.
            let _ = done.recv_timeout(Duration::from_millis(1500));
        }
    }
}

/// The background thread: turns the event loop, keeps the link state, republishes the retained
/// messages on each connection, waits between attempts.
fn run(connection: &mut rumqttc::Connection, client: &Client, shared: &Shared) {
    let mut retry = RETRY_FIRST;
    while let Ok(event) = connection.recv() {
        let stopping = shared.stop.load(Ordering::Relaxed);
        match event {
            Ok(Event::Incoming(Packet::ConnAck(_))) => {
                retry = RETRY_FIRST;
                let mut inner = shared.lock();
                inner.link = Link::Connected;
                for (topic, payload) in &inner.retained {
                    if client.try_publish(topic, QoS::AtLeastOnce, true, payload.clone()).is_err() {
                        shared.dropped.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
            Ok(Event::Outgoing(Outgoing::Disconnect)) if stopping => return,
            Ok(_) => {}
            Err(e) => {
                if stopping {
                    return;
                }
                shared.lock().link = Link::Unreachable(reason(&e));
                // Wait before the next attempt, in slices so that a stop is seen.
                let until = Instant::now() + retry;
                while Instant::now() < until {
                    if shared.stop.load(Ordering::Relaxed) {
                        return;
                    }
                    std::thread::sleep(Duration::from_millis(50));
                }
                retry = (retry * 2).min(RETRY_MAX);
            }
        }
    }
}

/// The reason of a failed or lost connection, in words.
fn reason(e: &ConnectionError) -> String {
    match e {
        ConnectionError::Io(io) => io.to_string(),
        ConnectionError::NetworkTimeout => "no answer (timed out)".into(),
        ConnectionError::MqttState(state) => format!("connection lost ({state})"),
        ConnectionError::ConnectionRefused(code) => format!("the broker refused: {code:?}"),
        other => other.to_string(),
    }
}

/// `PREFIX/node/<mac>/status`.
fn node_status_payload(node: &NodeState) -> Vec<u8> {
    let status: NodeStatus = node.status;
    let id = &node.identity;
    json!({
        "mac": node.mac,
        "name": node.name,
        "connection": node.connection,
        "ack_suppression": node.ack_suppression,
        "status": status.name(),
        "code": node.code,
        "detail": node.detail,
        "product_name": id.product_name,
        "vendor_id": id.vendor_id,
        "device_type": id.device_type,
        "product_code": id.product_code,
        "revision": id.revision,
        "serial_number": id.serial_number,
        "input_size": node.input_size,
        "output_size": node.output_size,
    })
    .to_string()
    .into_bytes()
}

/// `PREFIX/scanner`.
fn scanner_payload(state: &ScannerState) -> Vec<u8> {
    let ok = state.nodes.iter().filter(|n| n.status == NodeStatus::Ok).count();
    json!({
        "mac": state.mac,
        "status": serde_json::to_value(state.status).unwrap_or(Value::Null),
        "cycles": state.cycles,
        "cycle_ms": state.cycle_ms,
        "bus_load": state.bus_load,
        "interscan_delay_ms": state.interscan_delay_ms,
        "expected_packet_rate_ms": state.expected_packet_rate_ms,
        "nodes": state.nodes.len(),
        "nodes_ok": ok,
        "unix_ms": crate::model::unix_ms_now(),
    })
    .to_string()
    .into_bytes()
}

/// `PREFIX/node/<mac>/values`.
fn values_payload(sample: &Sample) -> Vec<u8> {
    let mut values = Map::new();
    for (name, value) in &sample.values {
        values.entry(name.clone()).or_insert_with(|| json!(value));
    }
    json!({
        "mac": sample.mac,
        "unix_ms": sample.unix_ms,
        "bus_us": sample.bus_us,
        "input_hex": hex(&sample.input),
        "values": values,
    })
    .to_string()
    .into_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn ep(host: &str, port: u16, prefix: &str) -> Endpoint {
        Endpoint { host: host.into(), port, prefix: prefix.into(), credentials: None, tls: false }
    }

    #[rstest]
    #[case::defaults("mqtt://broker", ep("broker", 1883, "devicenet"))]
    #[case::port("mqtt://127.0.0.1:1884", ep("127.0.0.1", 1884, "devicenet"))]
    #[case::prefix("mqtt://b:1883/plant/line1/", ep("b", 1883, "plant/line1"))]
    #[case::tcp("tcp://b", ep("b", 1883, "devicenet"))]
    #[case::ipv6("mqtt://[::1]:1885/x", ep("[::1]", 1885, "x"))]
    #[case::tls("mqtts://b", Endpoint { tls: true, ..ep("b", 8883, "devicenet") })]
    #[case::tls_port("ssl://b:8884", Endpoint { tls: true, ..ep("b", 8884, "devicenet") })]
    fn urls(#[case] url: &str, #[case] endpoint: Endpoint) {
        assert_eq!(parse_url(url), Ok(endpoint));
    }

    #[test]
    fn url_with_credentials() {
        let e = parse_url("mqtt://scada:s3cret@b").unwrap();
        assert_eq!(e.credentials, Some(("scada".into(), "s3cret".into())));
        assert_eq!(e.display(), "mqtt://b:1883/devicenet");
    }

    #[rstest]
    #[case::no_scheme("broker:1883", "no scheme")]
    #[case::scheme("http://b", "unknown scheme `http`")]
    #[case::websocket("ws://b", "not supported")]
    #[case::no_host("mqtt://:1883", "no host")]
    #[case::port_text("mqtt://b:abc", "port `abc`")]
    #[case::port_zero("mqtt://b:0", "port `0`")]
    #[case::port_big("mqtt://b:70000", "port `70000`")]
    #[case::wildcard("mqtt://b/plant/#", "topic prefix")]
    #[case::plus("mqtt://b/+/x", "topic prefix")]
    #[case::v6("mqtt://[::1", "unclosed")]
    #[case::space("mqtt://my host", "space")]
    fn bad_urls(#[case] url: &str, #[case] says: &str) {
        let e = parse_url(url).unwrap_err();
        assert!(e.contains(says) && e.contains(url), "{e}");
    }

    #[test]
    fn values_payload_names_values_and_nulls_non_finite() {
        let s = Sample {
            mac: 5,
            unix_ms: 1000,
            bus_us: 7,
            input: vec![0x0A, 0xFF],
            values: vec![("a".into(), 1.5), ("b".into(), f64::NAN)],
        };
        let v: Value = serde_json::from_slice(&values_payload(&s)).unwrap();
        assert_eq!(
            v,
            json!({"mac":5,"unix_ms":1000,"bus_us":7,"input_hex":"0AFF","values":{"a":1.5,"b":null}})
        );
    }
}
