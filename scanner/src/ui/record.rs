//! The console's recording: the frames the ring receives, written as they come to a `candump -L`
//! log and a pcap capture. A thread follows the ring by sequence number; frames the ring dropped
//! before the thread saw them are counted as missed.

use crate::model::Shared;
use devicenet::{CanFrame, CanId, Instant};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// The interface name written in the log's lines.
const IFACE: &str = "can0";
/// How often the thread looks at the ring.
const FOLLOW_PERIOD: Duration = Duration::from_millis(100);

/// A recording in progress.
pub(crate) struct Recorder {
    /// The `candump -L` log.
    pub(crate) log: PathBuf,
    /// The pcap capture.
    pub(crate) pcap: PathBuf,
    counts: Arc<Counts>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), String>>>,
}

#[derive(Default)]
pub(crate) struct Counts {
    frames: AtomicU64,
    missed: AtomicU64,
}

/// What a recording wrote.
#[derive(Clone, Debug, serde::Serialize)]
pub(crate) struct RecordStatus {
    pub(crate) log: String,
    pub(crate) pcap: String,
    pub(crate) frames: u64,
    pub(crate) missed: u64,
    pub(crate) error: Option<String>,
}

/// Two files that do not exist yet in `dir`: `record-YYYYMMDD-HHMMSS[-N].log` / `.pcap`.
fn file_names(dir: &Path) -> (PathBuf, PathBuf) {
    let now = time::OffsetDateTime::now_utc();
    let stamp = format!(
        "{:04}{:02}{:02}-{:02}{:02}{:02}",
        now.year(),
        u8::from(now.month()),
        now.day(),
        now.hour(),
        now.minute(),
        now.second()
    );
    let mut n = 0;
    loop {
        let base = if n == 0 { format!("record-{stamp}") } else { format!("record-{stamp}-{n}") };
        let (log, pcap) = (dir.join(format!("{base}.log")), dir.join(format!("{base}.pcap")));
        if !log.exists() && !pcap.exists() {
            return (log, pcap);
        }
        n += 1;
    }
}

impl Recorder {
    /// Creates the two files and starts following the ring from its newest frame on.
    pub(crate) fn start(shared: Arc<Shared>) -> Result<Recorder, String> {
        let dir = shared.record_dir.clone();
        // Checked when the console started; never created here (a mistyped path stays an error).
        if !dir.is_dir() {
            return Err(format!("the record directory {} does not exist", dir.display()));
        }
        let (log, pcap) = file_names(&dir);
        let open = |p: &Path| File::create(p).map_err(|e| format!("cannot write {}: {e}", p.display()));
        let mut log_out = BufWriter::new(open(&log)?);
        let mut pcap_out = BufWriter::new(open(&pcap)?);
        pcap_out
            .write_all(&can_io::pcap::file_header())
            .and_then(|_| pcap_out.flush())
            .map_err(|e| format!("cannot write {}: {e}", pcap.display()))?;
        let mut after = shared.frames.lock().ok().and_then(|r| r.back().map(|f| f.seq)).unwrap_or(0);
        let counts = Arc::new(Counts::default());
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (counts, stop, log, pcap) =
                (Arc::clone(&counts), Arc::clone(&stop), log.clone(), pcap.clone());
            std::thread::Builder::new()
                .name("ui-record".into())
                .spawn(move || -> Result<(), String> {
                    loop {
                        let last = stop.load(Ordering::SeqCst);
                        let rows: Vec<_> = match shared.frames.lock() {
                            Ok(ring) => {
                                if let Some(first) = ring.front() {
                                    if first.seq > after + 1 && after > 0 {
                                        counts.missed.fetch_add(first.seq - after - 1, Ordering::Relaxed);
                                    }
                                }
                                ring.iter().filter(|r| r.seq > after).cloned().collect()
                            }
                            Err(_) => Vec::new(),
                        };
                        for row in &rows {
                            after = after.max(row.seq);
                            let Some(frame) =
                                CanId::new(row.id).and_then(|id| CanFrame::new(id, &row.data).ok())
                            else {
                                continue;
                            };
                            let at = Instant::from_micros(row.time_us);
                            writeln!(log_out, "{}", can_io::log::format_line(at, IFACE, &frame))
                                .map_err(|e| format!("cannot write {}: {e}", log.display()))?;
                            pcap_out
                                .write_all(&can_io::pcap::record(at, &frame))
                                .map_err(|e| format!("cannot write {}: {e}", pcap.display()))?;
                            counts.frames.fetch_add(1, Ordering::Relaxed);
                        }
                        log_out.flush().map_err(|e| format!("cannot write {}: {e}", log.display()))?;
                        pcap_out.flush().map_err(|e| format!("cannot write {}: {e}", pcap.display()))?;
                        if last {
                            return Ok(());
                        }
                        std::thread::sleep(FOLLOW_PERIOD);
                    }
                })
                .map_err(|e| format!("cannot start the recording: {e}"))?
        };
        Ok(Recorder { log, pcap, counts, stop, thread: Some(thread) })
    }

    /// The files and counts so far.
    pub(crate) fn status(&self) -> RecordStatus {
        let error = match &self.thread {
            Some(t) if t.is_finished() => Some("the recording stopped".to_string()),
            _ => None,
        };
        RecordStatus {
            log: self.log.display().to_string(),
            pcap: self.pcap.display().to_string(),
            frames: self.counts.frames.load(Ordering::Relaxed),
            missed: self.counts.missed.load(Ordering::Relaxed),
            error,
        }
    }

    /// Writes what the ring still has, closes the files and says what was written.
    pub(crate) fn stop(mut self) -> RecordStatus {
        self.stop.store(true, Ordering::SeqCst);
        let error = match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Ok(()))) | None => None,
            Some(Ok(Err(e))) => Some(e),
            Some(Err(_)) => Some("the recording thread failed".into()),
        };
        RecordStatus { error, ..self.status() }
    }
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
