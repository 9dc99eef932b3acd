//! `--sparkplug GROUP/EDGE_NODE`: the scanner as a Sparkplug B edge node. Each DeviceNet node is a
//! Sparkplug device (`mac05`; with `--plant`, `NETWORK-mac05` under the one edge node, see
//! [`edge::device_name`]) whose metrics are its identity, its status and every input value its
//! profile decodes, with names and units. The payloads are Sparkplug B protobuf ([`proto`], the
//! Eclipse Tahu `.proto` as `prost` messages); the client is `rumqttc`'s synchronous client, over
//! TCP or TLS like [`crate::mqtt`].
//!
//! ## Messages
//!
//! | topic | when | QoS |
//! |---|---|---|
//! | `spBv1.0/G/NBIRTH/E` | on each connection, and on a Rebirth | 0 |
//! | `spBv1.0/G/DBIRTH/E/macNN` | after NBIRTH, each device; again when its metric names change | 0 |
//! | `spBv1.0/G/DDATA/E/macNN` | a metric changed (report by exception) | 0 |
//! | `spBv1.0/G/NDATA/E` | a scanner event (ADR step, scan-list change): `ADR/Last Event` ([`events`]) | 0 |
//! | `spBv1.0/G/NDEATH/E` | the MQTT will (the broker sends it when the link is lost), or before a clean disconnect | 1 |
//! | `spBv1.0/G/NCMD/E` | received: `Node Control/Rebirth` = true sends NBIRTH and every DBIRTH again | - |
//! | `spBv1.0/G/DCMD/E/macNN` | received with `--sparkplug-commands`: `Outputs/Image`, `Commands/Open`, `Commands/Close` | - |
//!
//! With `--plant` every `macNN` above is `NETWORK-macNN` ([`edge::device_name`]): one NBIRTH, one
//! bdSeq and one seq count for every network's devices.
//!
//! `bdSeq` (0..=255) is in NBIRTH and in the will NDEATH set for the same connection; it goes up by
//! one with each new MQTT session, and is kept in the store file across restarts. `seq` is 0 in
//! NBIRTH and goes up by one (255 wraps to 0) with each DBIRTH, DDATA and NDATA after it.
//!
//! ## Store and forward
//!
//! While the broker is away each DDATA is written to the [`store`] (SQLite, bounded by a number of
//! messages and an age). On the next connection the edge node sends NBIRTH and every DBIRTH with
//! the current values, then the stored DDATA oldest first with every metric flagged
//! `is_historical` and its original timestamp, then the live data. DDATA is QoS 0, as Sparkplug
//! asks: a message handed to the network in the instant the link breaks, before the client sees
//! the loss, is not kept.
//!
//! ## Threads
//!
//! The scanner's thread only updates the [`edge::Edge`] and queues the changes (never waits on
//! the network or the disk; a full queue drops and counts). A sender thread publishes or stores
//! them, the network thread turns the MQTT event loop, and with commands enabled a third carries
//! out DCMD through the scanner's command queue.

pub mod commands;
pub mod edge;
pub mod events;
pub mod proto;
pub mod store;

use crate::model::{Sample, ScannerState};
use crate::mqtt::{mqtt_options, parse_url, TlsError, TlsFiles};
use commands::{CommandLog, Dcmd, Queues};
use edge::{Change, DeviceKey, Edge};
use prost::Message as _;
use rumqttc::{Client, Event, LastWill, Packet, QoS};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};
use store::{Store, StoreError, Window};

/// The changes the scanner's thread may queue ahead of the sender before it drops.
pub const JOB_QUEUE: usize = 65_536;

/// The first and the longest wait between two connection attempts.
const RETRY_FIRST: Duration = Duration::from_millis(500);
const RETRY_MAX: Duration = Duration::from_secs(5);

/// Stored messages sent per batch on a reconnection.
const REPLAY_BATCH: usize = 200;

/// Why the edge node cannot start.
#[derive(Debug, thiserror::Error)]
pub enum SparkplugError {
    /// `--sparkplug` is not `GROUP/EDGE_NODE`.
    #[error("--sparkplug `{given}`: {why} (expected GROUP/EDGE_NODE, e.g. plant1/line3)")]
    Id {
        /// What was given.
        given: String,
        /// What is wrong.
        why: &'static str,
    },
    /// The broker URL is malformed.
    #[error("{0}")]
    Url(String),
    /// The TLS files.
    #[error(transparent)]
    Tls(#[from] TlsError),
    /// The store file.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A thread cannot be started.
    #[error("cannot start a Sparkplug thread: {0}")]
    Thread(#[from] std::io::Error),
}

/// Parses `GROUP/EDGE_NODE`: two non-empty MQTT topic levels without `/`, `+`, `#`.
pub fn parse_id(given: &str) -> Result<(String, String), SparkplugError> {
    let id = |why| SparkplugError::Id { given: given.to_owned(), why };
    let (group, edge) = given.split_once('/').ok_or_else(|| id("no `/`"))?;
    for part in [group, edge] {
        if part.is_empty() {
            return Err(id("an empty group or edge node ID"));
        }
        if part.contains(['/', '+', '#', '\0']) {
            return Err(id("an ID may not hold `/`, `+`, `#` or NUL"));
        }
    }
    Ok((group.to_owned(), edge.to_owned()))
}

/// What the edge node is started with.
pub struct Config {
    /// The broker: `mqtt://HOST[:PORT]` or `mqtts://` (a topic prefix is refused: Sparkplug's
    /// namespace is `spBv1.0`).
    pub url: String,
    /// `GROUP/EDGE_NODE`.
    pub id: String,
    /// TLS files for `mqtts://`.
    pub tls: TlsFiles,
    /// The store-and-forward file.
    pub store: PathBuf,
    /// How much the store keeps.
    pub window: Window,
    /// DCMD enabled: each network's scanner command queue (the key `None` without `--plant`).
    pub commands: Option<Queues>,
    /// `--plant`: device IDs are `NETWORK-macNN` ([`edge::device_name`]).
    pub plant: bool,
    /// Where DCMD are recorded.
    pub log: Option<CommandLog>,
}

/// The topics of one edge node.
#[derive(Clone, Debug)]
struct Topics {
    group: String,
    edge: String,
    plant: bool,
}

impl Topics {
    fn node(&self, kind: &str) -> String {
        format!("spBv1.0/{}/{kind}/{}", self.group, self.edge)
    }

    fn device(&self, kind: &str, key: &DeviceKey) -> String {
        format!("{}/{}", self.node(kind), edge::device_name(key))
    }
}

/// What the sender thread is asked.
enum Job {
    Change(Change),
    /// Scanner events: node-level NDATA ([`events`]).
    Events(Vec<crate::events::ScanEvent>),
    Up(Client),
    Down,
    Incoming(String, Vec<u8>),
    Stop,
}

/// The link to the broker.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Link {
    Connecting,
    Connected,
    Unreachable(String),
}

struct Shared {
    link: Mutex<Link>,
    bd_seq: AtomicU64,
    stop: AtomicBool,
    queued: AtomicUsize,
    dropped: AtomicU64,
    stored: AtomicU64,
    published: AtomicU64,
}

impl Shared {
    fn link(&self) -> MutexGuard<'_, Link> {
        self.link.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// The edge node (see the [module docs](self)).
pub struct EdgeNode {
    url: String,
    topics: Topics,
    edge: Arc<Mutex<Edge>>,
    jobs: Sender<Job>,
    shared: Arc<Shared>,
    sender: Option<std::thread::JoinHandle<()>>,
    network: Option<std::thread::JoinHandle<()>>,
}

impl std::fmt::Debug for EdgeNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EdgeNode").field("url", &self.url).field("topics", &self.topics).finish()
    }
}

impl EdgeNode {
    /// Checks the URL, the ID, the TLS files and the store, then starts the threads. A broker that
    /// is down is not an error (see [`EdgeNode::status`]).
    pub fn start(config: Config) -> Result<EdgeNode, SparkplugError> {
        let endpoint = parse_url(&config.url).map_err(SparkplugError::Url)?;
        if config.url.trim_end_matches('/').matches('/').count() > 2 {
            return Err(SparkplugError::Url(format!(
                "MQTT URL `{}`: no topic prefix with --sparkplug (its topics are spBv1.0/...)",
                config.url
            )));
        }
        let (group, edge_id) = parse_id(&config.id)?;
        let topics = Topics { group, edge: edge_id.clone(), plant: config.plant };
        let options = mqtt_options(&endpoint, &format!("dnet-master-{edge_id}"), &config.tls)?;
        let store = Store::open(Some(&config.store), config.window)?;
        let bd_seq = store.bd_seq()?.map_or(0, |b| (b + 1) % 256);
        let shared = Arc::new(Shared {
            link: Mutex::new(Link::Connecting),
            bd_seq: AtomicU64::new(bd_seq),
            stop: AtomicBool::new(false),
            queued: AtomicUsize::new(0),
            dropped: AtomicU64::new(0),
            stored: AtomicU64::new(store.len()?),
            published: AtomicU64::new(0),
        });
        let edge = Arc::new(Mutex::new(Edge::default()));
        let dcmd = match config.commands {
            Some(scanner) => Some(commands::spawn(Arc::clone(&edge), scanner, config.log)?),
            None => None,
        };
        let (jobs, rx) = mpsc::channel();
        let net =
            Network { options, topics: topics.clone(), jobs: jobs.clone(), shared: Arc::clone(&shared) };
        let network = std::thread::Builder::new().name("sparkplug-net".into()).spawn(move || net.run())?;
        let mut sender = Outbox {
            topics: topics.clone(),
            edge: Arc::clone(&edge),
            shared: Arc::clone(&shared),
            store,
            client: None,
            seq: 0,
            dcmd,
            last_event: events::LastEvent::default(),
        };
        let sender = std::thread::Builder::new().name("sparkplug".into()).spawn(move || sender.run(&rx))?;
        Ok(EdgeNode {
            url: format!(
                "{}://{}:{}",
                if endpoint.tls { "mqtts" } else { "mqtt" },
                endpoint.host,
                endpoint.port
            ),
            topics,
            edge,
            jobs,
            shared,
            sender: Some(sender),
            network: Some(network),
        })
    }

    /// The link in words: `connected to URL as spBv1.0/G/NBIRTH/E (bdSeq N)`, `broker unreachable:
    /// <reason>, retrying`, with the number of stored messages.
    #[must_use]
    pub fn status(&self) -> String {
        let link = match &*self.shared.link() {
            Link::Connecting => format!("connecting to {}", self.url),
            Link::Connected => format!(
                "connected to {} as {} (bdSeq {})",
                self.url,
                self.topics.node("NBIRTH"),
                self.shared.bd_seq.load(Ordering::Relaxed)
            ),
            Link::Unreachable(why) => format!("broker unreachable: {why}, retrying"),
        };
        format!("Sparkplug B {link}; {} stored", self.shared.stored.load(Ordering::Relaxed))
    }

    /// Changes dropped: the queue to the sender was full, or the store's window.
    #[must_use]
    pub fn dropped(&self) -> u64 {
        self.shared.dropped.load(Ordering::Relaxed)
    }

    /// Messages published since the start.
    #[must_use]
    pub fn published(&self) -> u64 {
        self.shared.published.load(Ordering::Relaxed)
    }

    /// Takes the scanner's state after a cycle (new devices, status, identity, images). Never
    /// blocks on the network.
    pub fn publish_state(&self, state: &ScannerState) {
        self.publish_network_state(None, state);
    }

    /// Takes the decoded samples (changed input values). Never blocks on the network.
    pub fn publish_samples(&self, samples: &[Sample]) {
        self.publish_network_samples(None, samples);
    }

    /// [`EdgeNode::publish_state`] of plant network `network` (`None`: the one network). Each
    /// network's scanner thread calls it with its own name.
    pub fn publish_network_state(&self, network: Option<&str>, state: &ScannerState) {
        let now = u64::try_from(crate::model::unix_ms_now()).unwrap_or(0);
        let changes = self
            .edge
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .update_network_state(network, state, now);
        self.queue(changes);
    }

    /// [`EdgeNode::publish_samples`] of plant network `network` (`None`: the one network).
    pub fn publish_network_samples(&self, network: Option<&str>, samples: &[Sample]) {
        let changes =
            self.edge.lock().unwrap_or_else(PoisonError::into_inner).update_network_samples(network, samples);
        self.queue(changes);
    }

    fn queue(&self, changes: Vec<Change>) {
        for c in changes {
            if self.shared.queued.load(Ordering::Relaxed) >= JOB_QUEUE {
                self.shared.dropped.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            self.shared.queued.fetch_add(1, Ordering::Relaxed);
            let _ = self.jobs.send(Job::Change(c));
        }
    }
}

impl Drop for EdgeNode {
    /// Sends what is queued, NDEATH, and disconnects (waiting at most 3 s).
    fn drop(&mut self) {
        let _ = self.jobs.send(Job::Stop);
        let until = Instant::now() + Duration::from_secs(3);
        let wait = |thread: Option<std::thread::JoinHandle<()>>| {
            if let Some(t) = thread {
                while !t.is_finished() && Instant::now() < until {
                    std::thread::sleep(Duration::from_millis(20));
                }
            }
        };
        wait(self.sender.take());
        // Connected: the network thread ends once the disconnect is written. Not: it is waiting
        // for a broker, and ends at the stop.
        if *self.shared.link() == Link::Connected {
            wait(self.network.take());
        }
        self.shared.stop.store(true, Ordering::Relaxed);
    }
}

/// The network thread: one MQTT session after another, each with its own will.
struct Network {
    options: rumqttc::MqttOptions,
    topics: Topics,
    jobs: Sender<Job>,
    shared: Arc<Shared>,
}

impl Network {
    fn run(self) {
        let mut retry = RETRY_FIRST;
        while !self.shared.stop.load(Ordering::Relaxed) {
            let bd_seq = self.shared.bd_seq.load(Ordering::Relaxed);
            let mut options = self.options.clone();
            let will = edge::ndeath(bd_seq).encode_to_vec();
            options.set_last_will(LastWill::new(self.topics.node("NDEATH"), will, QoS::AtLeastOnce, false));
            // A new client per session: what was queued for a lost session is not sent ahead of the
            // next session's NBIRTH.
            let (client, mut connection) = Client::new(options, 256);
            let _ = client.try_subscribe(self.topics.node("NCMD"), QoS::AtLeastOnce);
            let _ = client.try_subscribe(format!("{}/+", self.topics.node("DCMD")), QoS::AtLeastOnce);
            let mut session = false;
            while let Ok(event) = connection.recv() {
                match event {
                    Ok(Event::Incoming(Packet::ConnAck(_))) => {
                        session = true;
                        retry = RETRY_FIRST;
                        *self.shared.link() = Link::Connected;
                        let _ = self.jobs.send(Job::Up(client.clone()));
                    }
                    Ok(Event::Incoming(Packet::Publish(p))) => {
                        let _ = self.jobs.send(Job::Incoming(p.topic, p.payload.to_vec()));
                    }
                    Ok(Event::Outgoing(rumqttc::Outgoing::Disconnect)) => return,
                    Ok(_) => {}
                    Err(e) => {
                        if self.shared.stop.load(Ordering::Relaxed) {
                            return;
                        }
                        *self.shared.link() = Link::Unreachable(e.to_string());
                        let _ = self.jobs.send(Job::Down);
                        self.wait(retry);
                        retry = (retry * 2).min(RETRY_MAX);
                        if session {
                            // The next session has its own bdSeq (and so its own will).
                            self.shared.bd_seq.store((bd_seq + 1) % 256, Ordering::Relaxed);
                            break;
                        }
                    }
                }
                if self.shared.stop.load(Ordering::Relaxed) {
                    return;
                }
            }
        }
    }

    fn wait(&self, how_long: Duration) {
        let until = Instant::now() + how_long;
        while Instant::now() < until && !self.shared.stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

/// The sender thread: publishes births and data while connected, stores data while not.
struct Outbox {
    topics: Topics,
    edge: Arc<Mutex<Edge>>,
    shared: Arc<Shared>,
    store: Store,
    client: Option<Client>,
    seq: u8,
    dcmd: Option<mpsc::SyncSender<Dcmd>>,
    last_event: events::LastEvent,
}

impl Outbox {
    fn run(&mut self, rx: &Receiver<Job>) {
        while let Ok(job) = rx.recv() {
            match job {
                Job::Change(c) => {
                    self.shared.queued.fetch_sub(1, Ordering::Relaxed);
                    self.change(c);
                }
                Job::Events(e) => self.events(e),
                Job::Up(client) => {
                    self.client = Some(client);
                    let bd_seq = self.shared.bd_seq.load(Ordering::Relaxed);
                    let _ = self.store.set_bd_seq(bd_seq);
                    self.births();
                    self.replay();
                }
                Job::Down => self.client = None,
                Job::Incoming(topic, payload) => self.incoming(&topic, payload),
                Job::Stop => {
                    if let Some(client) = self.client.take() {
                        let bd_seq = self.shared.bd_seq.load(Ordering::Relaxed);
                        let death = edge::ndeath(bd_seq).encode_to_vec();
                        let _ = client.publish(self.topics.node("NDEATH"), QoS::AtLeastOnce, false, death);
                        let _ = client.disconnect();
                    }
                    return;
                }
            }
        }
    }

    fn now() -> u64 {
        u64::try_from(crate::model::unix_ms_now()).unwrap_or(0)
    }

    /// Publishes; `false` when the client is gone (the link was lost).
    fn publish(&mut self, topic: String, payload: &proto::Payload) -> bool {
        let Some(client) = &self.client else { return false };
        if client.publish(topic, QoS::AtMostOnce, false, payload.encode_to_vec()).is_err() {
            self.client = None;
            return false;
        }
        self.shared.published.fetch_add(1, Ordering::Relaxed);
        true
    }

    fn next_seq(&mut self) -> u8 {
        self.seq = self.seq.wrapping_add(1);
        self.seq
    }

    /// NBIRTH (seq 0) and every DBIRTH.
    fn births(&mut self) {
        let now = Self::now();
        let bd_seq = self.shared.bd_seq.load(Ordering::Relaxed);
        let (mut nbirth, keys) = {
            let edge = self.edge.lock().unwrap_or_else(PoisonError::into_inner);
            (edge.nbirth(bd_seq, now), edge.devices.keys().cloned().collect::<Vec<_>>())
        };
        nbirth.metrics.push(self.last_event.birth(now));
        self.seq = 0;
        if !self.publish(self.topics.node("NBIRTH"), &nbirth) {
            return;
        }
        for key in keys {
            if !self.dbirth(&key, now) {
                return;
            }
        }
    }

    fn dbirth(&mut self, key: &DeviceKey, now: u64) -> bool {
        let seq = self.next_seq();
        let payload = self.edge.lock().unwrap_or_else(PoisonError::into_inner).dbirth(key, now, seq);
        match payload {
            Some(p) => self.publish(self.topics.device("DBIRTH", key), &p),
            None => true,
        }
    }

    fn change(&mut self, change: Change) {
        match change {
            Change::Birth(key) => {
                if self.client.is_some() {
                    self.dbirth(&key, Self::now());
                }
            }
            Change::Data { key, unix_ms, metrics } => {
                if self.client.is_some() {
                    let seq = self.next_seq();
                    if self.publish(
                        self.topics.device("DDATA", &key),
                        &edge::ddata(&metrics, unix_ms, seq, false),
                    ) {
                        return;
                    }
                }
                let payload = edge::ddata(&metrics, unix_ms, 0, false);
                let before = self.store.dropped;
                if self.store.push(&key, unix_ms, &payload.encode_to_vec()).is_err() {
                    self.shared.dropped.fetch_add(1, Ordering::Relaxed);
                }
                self.shared.dropped.fetch_add(self.store.dropped - before, Ordering::Relaxed);
                self.shared.stored.store(self.store.len().unwrap_or(0), Ordering::Relaxed);
            }
        }
    }

    /// The stored DDATA, oldest first, flagged historical; each batch removed once handed over.
    fn replay(&mut self) {
        while self.client.is_some() {
            let Ok(rows) = self.store.oldest(REPLAY_BATCH) else { return };
            if rows.is_empty() {
                break;
            }
            let mut sent = None;
            for row in rows {
                let Ok(mut payload) = proto::Payload::decode(row.payload.as_slice()) else {
                    sent = Some(row.id);
                    continue;
                };
                payload.seq = Some(u64::from(self.next_seq()));
                for m in &mut payload.metrics {
                    m.is_historical = Some(true);
                }
                if !self.publish(self.topics.device("DDATA", &row.key), &payload) {
                    break;
                }
                sent = Some(row.id);
            }
            if let Some(id) = sent {
                let _ = self.store.remove_through(id);
            }
        }
        self.shared.stored.store(self.store.len().unwrap_or(0), Ordering::Relaxed);
    }

    fn incoming(&mut self, topic: &str, payload: Vec<u8>) {
        if topic == self.topics.node("NCMD") {
            let rebirth = proto::Payload::decode(payload.as_slice()).is_ok_and(|p| {
                p.metrics.iter().any(|m| {
                    m.name.as_deref() == Some(edge::REBIRTH)
                        && m.value == Some(proto::Value::BooleanValue(true))
                })
            });
            if rebirth && self.client.is_some() {
                self.births();
            }
            return;
        }
        let device = topic.strip_prefix(&format!("{}/", self.topics.node("DCMD")));
        let key = device.and_then(|d| edge::device_key(d, self.topics.plant));
        if let (Some(key), Some(dcmd)) = (key, &self.dcmd) {
            // A full queue of commands: the host is flooding; the DCMD is not carried out.
            let _ = dcmd.try_send(Dcmd { key, payload });
        }
    }
}
