//! The bus thread: one thread owns the bus, the session and the master for the life of a
//! `dnet.Master`; each Python call is a job sent to it, and the caller waits for the answer with
//! the GIL released.
//!
//! The master ([`Master`]) borrows its session, which borrows the bus, so the three live together
//! on the thread's stack rather than in a Python object. A job that fails leaves the master as it
//! was (what it holds allocated is still known), so the next call goes on where it stopped. When
//! the `dnet.Master` is closed (or dropped), the job channel closes: the thread gives back every
//! connection the master holds ([`Master::release_held`]), flushes the log and ends.

use crate::error::CallError;
use can_io::bus::{Bitrate, BusSpec};
use can_io::log::LogWriter;
use can_io::trace::TraceFormat;
use converter_sim::{OpenError, SimSetup};
use devicenet::{Duration, Instant, MacId};
use dnet_scanner::monitor::InputLayout;
use master_core::error::MasterError;
use master_core::io::IoKind;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::mpsc;
use std::thread::JoinHandle;

/// What the bus thread opens.
pub struct BusSetup {
    /// The bus.
    pub spec: BusSpec,
    /// Its bit rate.
    pub bitrate: Bitrate,
    /// The simulated devices (used on `sim` only).
    pub sim: SimSetup,
    /// The master's identity and timing.
    pub config: MasterConfig,
    /// How polled data is decoded by default (the simulated device's profile, else raw bytes).
    pub layout: InputLayout,
    /// Every frame written to this file (candump -L).
    pub log: Option<PathBuf>,
}

/// The I/O connection a `connect` left to a device, for `poll` and `monitor`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IoSetup {
    /// Its kind.
    pub kind: IoKind,
    /// The device's produced size (bytes the master receives).
    pub produced: u16,
    /// The device's consumed size (bytes the master sends).
    pub consumed: u16,
    /// The expected packet rate the device applied.
    pub epr: Duration,
    /// When the next poll or bit-strobe is due: one EPR after the previous one.
    pub due: Instant,
}

/// What the bus thread keeps between calls, next to the master.
pub struct State {
    /// Per device MAC, its I/O connection.
    pub io: HashMap<u8, IoSetup>,
    /// The default decoding of polled data.
    pub layout: InputLayout,
    /// Whether the bus judges frame timing (not SLCAN, whose frames arrive in bursts).
    pub judge_timing: bool,
}

/// A job: runs on the bus thread with the master.
type Job = Box<dyn FnOnce(&mut Master<'_, '_>, &mut State) + Send>;

/// Why the bus could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// The bus or the simulated devices could not be set up.
    #[error(transparent)]
    Open(#[from] OpenError),
    /// The log file could not be created.
    #[error("log {path}: {source}")]
    Log {
        /// The file.
        path: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// The thread could not be started, or stopped before it said.
    #[error("the bus thread: {0}")]
    Thread(String),
}

/// The handle on the bus thread.
pub struct Worker {
    jobs: Option<mpsc::Sender<Job>>,
    thread: Option<JoinHandle<Result<Vec<MacId>, MasterError>>>,
}

impl Worker {
    /// Opens the bus on a new thread; returns once it is open (or could not be).
    pub fn start(setup: BusSetup) -> Result<Worker, StartError> {
        let (jobs, rx) = mpsc::channel::<Job>();
        let (ready_tx, ready_rx) = mpsc::sync_channel::<Result<(), StartError>>(1);
        let thread = std::thread::Builder::new()
            .name("dnet-bus".into())
            .spawn(move || run(setup, &rx, &ready_tx))
            .map_err(|e| StartError::Thread(e.to_string()))?;
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(Worker { jobs: Some(jobs), thread: Some(thread) }),
            Ok(Err(e)) => {
                let _ = thread.join();
                Err(e)
            }
            Err(_) => {
                let _ = thread.join();
                Err(StartError::Thread("stopped while opening the bus".into()))
            }
        }
    }

    /// Runs `f` on the bus thread with the master; waits for its result.
    pub fn call<T: Send + 'static>(
        &self,
        f: impl FnOnce(&mut Master<'_, '_>, &mut State) -> Result<T, CallError> + Send + 'static,
    ) -> Result<T, CallError> {
        let jobs = self.jobs.as_ref().ok_or(CallError::Closed)?;
        let (tx, rx) = mpsc::sync_channel(1);
        jobs.send(Box::new(move |master, state| {
            let _ = tx.send(f(master, state));
        }))
        .map_err(|_| CallError::Closed)?;
        rx.recv().map_err(|_| CallError::Closed)?
    }

    /// Closes the bus: the thread releases what the master holds and ends. Returns the devices
    /// released. A second close does nothing.
    pub fn close(&mut self) -> Result<Vec<MacId>, CallError> {
        self.jobs = None;
        match self.thread.take() {
            Some(t) => match t.join() {
                Ok(r) => Ok(r?),
                Err(_) => Err(CallError::Closed),
            },
            None => Ok(Vec::new()),
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        // A master never closed still gives its connections back; nobody is left to tell of a
        // failure.
        let _ = self.close();
    }
}

/// The bus thread's body: open, serve jobs until the channel closes, release, flush.
fn run(
    setup: BusSetup,
    jobs: &mpsc::Receiver<Job>,
    ready: &mpsc::SyncSender<Result<(), StartError>>,
) -> Result<Vec<MacId>, MasterError> {
    let opened = converter_sim::open_bus(&setup.spec, setup.bitrate, &setup.sim).map_err(StartError::from);
    let log = match &setup.log {
        Some(path) => LogWriter::create_as(path, TraceFormat::Candump)
            .map(Some)
            .map_err(|source| StartError::Log { path: path.display().to_string(), source }),
        None => Ok(None),
    };
    let (mut bus, log) = match (opened, log) {
        (Ok(bus), Ok(log)) => (bus, log),
        (Err(e), _) | (_, Err(e)) => {
            let _ = ready.send(Err(e));
            return Ok(Vec::new());
        }
    };
    let mut session = Session::new(bus.as_mut());
    if let Some(log) = log {
        session.set_log(log);
    }
    let mut master = Master::new(&mut session, setup.config);
    let mut state = State {
        io: HashMap::new(),
        layout: setup.layout,
        judge_timing: !matches!(setup.spec, BusSpec::Slcan { .. }),
    };
    let _ = ready.send(Ok(()));
    while let Ok(job) = jobs.recv() {
        job(&mut master, &mut state);
    }
    let released = master.release_held();
    let flushed = master.session.flush();
    let released = released?;
    flushed?;
    Ok(released)
}
