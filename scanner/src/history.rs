//! The sample history: every input sample the scanner takes, kept in an SQLite database (the
//! library is compiled into `dnet-master`, nothing to install), read back by the console's plots
//! ([`HistoryStore::samples`]) and exported as CSV ([`HistoryStore::export_csv`]).
//!
//! ## Schema
//!
//! One table, one row per sample; the decoded values are JSON text in the row, so a sample is
//! written and read in one piece and keeps the order of its values:
//!
//! ```sql
//! CREATE TABLE samples (
//!     id      INTEGER PRIMARY KEY,  -- insertion order
//!     unix_ms INTEGER NOT NULL,     -- wall-clock time, ms since the Unix epoch
//!     bus_us  INTEGER NOT NULL,     -- bus time, µs
//!     mac     INTEGER NOT NULL,     -- MAC ID 0-63
//!     input   BLOB    NOT NULL,     -- the input image as received
//!     decoded TEXT    NOT NULL      -- the decoded values: [["phase_a",12.5],["switch",1]]
//! );
//! CREATE INDEX samples_mac_time ON samples (mac, unix_ms);
//! CREATE INDEX samples_time ON samples (unix_ms);
//! PRAGMA user_version = 1;          -- the schema version of a dnet-master history
//! ```
//!
//! A value that is not a finite number is stored as JSON `null` and read back as NaN. The
//! database is in WAL mode (`synchronous = NORMAL`): with a file, the console's reads and exports
//! go through a second, read-only connection and never hold up the scanner's
//! [`record`](History::record), nor does recording hold up a read. Another program (`sqlite3`,
//! Python) can read the file while the scanner runs.
//!
//! ## CSV export
//!
//! ```text
//! unix_ms,time,mac,input_hex,phase_a,phase_b,phase_c,neutral,switch
//! 1714564800123,2024-05-01T12:00:00.123Z,5,0A141E000000000000F0,10,20,30,0,closed
//! ```
//!
//! `time` is the same instant in ISO 8601, UTC, with milliseconds; `input_hex` the input image in
//! upper-case hex without separators; then one column per value name of the exported samples, in
//! the order they are first seen (a sample without a name leaves its cell empty, as does a value
//! that is not a finite number); the breaker's `switch` is written as the console shows it
//! (`open`, `closed`, `unknown (0xXX)`), not as its byte (`0x0F`, `0xF0`). Rows are oldest first; lines end in `\n`; a name holding a comma,
//! a quote or a line break is quoted as RFC 4180 says. The export streams: it reads the range
//! twice (once for the names, once for the rows) and never holds more than one row in memory.
//!
//! ## Retention
//!
//! [`History::set_retention`] sets a [`Retention`]: at most `max_rows` samples, the samples of the
//! last `max_age_ms` before the newest one recorded, at most `max_bytes` of database pages (the
//! oldest go first; SQLite reuses the freed pages, so the file stops growing there), and old
//! samples thinned out ([`ThinOut`]: older than `after_ms`, one per node per `every_ms`, the
//! period's first; a change inside the period is not kept). Row and age limits apply with each
//! batch recorded, in its transaction; thinning and the size check once a minute of samples.
//! [`Retention::default`] keeps everything; `dnet-master ui` uses [`Retention::STANDARD`] (30
//! days, 1 GiB, thinned to one a minute after 6 hours).
//!
//! Growth, measured by the test `history_growth_per_node_and_hour_is_measured` (breakers with an
//! unchanging 18-byte input, decoded as the console decodes it, one sample a second, the console's
//! rate for an unchanged input): **~598 kB per node per hour** (~166 bytes a sample with its two
//! indexes): 63 nodes, ~0.9 GB a day kept whole; thinned to one a minute, ~10 kB per node per hour.
//! A node whose input changes every cycle stores every cycle: proportionally more.
//!
//! ## Errors
//!
//! Every error names the database file ([`HistoryError`]): a path that cannot be opened or
//! created, a file that is not an SQLite database, an SQLite database that is not a history.
//! Nothing here panics.

use crate::model::{HistoryStore, Sample};
use rusqlite::{params, Connection, ErrorCode, OpenFlags};
use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};

/// The schema version this code writes and reads (`PRAGMA user_version`).
pub const SCHEMA_VERSION: i64 = 1;

/// What went wrong with the history database; each names the file (`:memory:` for
/// [`History::in_memory`]).
#[derive(Debug, thiserror::Error)]
pub enum HistoryError {
    /// The file cannot be opened or created (no such directory, no permission, a directory).
    #[error("cannot open or create the history database {}: {}", path.display(), open_reason(source))]
    Open {
        /// The file.
        path: PathBuf,
        /// SQLite's reason.
        source: rusqlite::Error,
    },
    /// The file exists but is not an SQLite database.
    #[error("{} is not an SQLite database (file is not a database), so not a sample history", path.display())]
    NotADatabase {
        /// The file.
        path: PathBuf,
    },
    /// The file is an SQLite database, but not one this program wrote.
    #[error("{} is an SQLite database but not a dnet-master sample history: {detail}", path.display())]
    NotAHistory {
        /// The file.
        path: PathBuf,
        /// What does not match.
        detail: String,
    },
    /// An SQL statement failed (disk full, database locked by another program, ...).
    #[error("history database {}: {what}: {source}", path.display())]
    Sql {
        /// The file.
        path: PathBuf,
        /// What was being done.
        what: &'static str,
        /// SQLite's reason.
        source: rusqlite::Error,
    },
    /// Writing the CSV export failed.
    #[error("history database {}: writing the CSV export: {source}", path.display())]
    Write {
        /// The database file.
        path: PathBuf,
        /// The output's error.
        source: std::io::Error,
    },
}

/// How much history to keep; `None` in a field: no limit of that kind. [`Retention::default`]
/// keeps everything; `dnet-master ui` uses [`Retention::STANDARD`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Retention {
    /// Keep at most this many samples (all nodes together); the oldest recorded go first.
    pub max_rows: Option<u64>,
    /// Keep the samples of this many ms before the newest sample recorded (`unix_ms`).
    pub max_age_ms: Option<i64>,
    /// Keep the samples in at most this many bytes of database pages; the oldest go first (the
    /// file stops growing there: SQLite reuses the pages freed).
    pub max_bytes: Option<u64>,
    /// Thin samples older than this out to one per node per [`ThinOut::every_ms`].
    pub thin: Option<ThinOut>,
}

/// Old samples thinned out: older than `after_ms` (before the newest recorded), a node keeps its
/// first sample of each `every_ms` period only.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ThinOut {
    /// Samples younger than this are all kept, ms.
    pub after_ms: i64,
    /// The period of which one sample per node is kept, ms.
    pub every_ms: i64,
}

impl Retention {
    /// What the console keeps: 30 days, at most 1 GiB, samples older than 6 hours thinned to one a
    /// minute per node. Measured (module docs): ~600 kB per node per hour at one sample a second,
    /// ~10 kB thinned; 63 nodes: 6 h whole ~225 MB, each older day ~15 MB, 30 days ~660 MB.
    pub const STANDARD: Retention = Retention {
        max_rows: None,
        max_age_ms: Some(30 * 24 * 3_600_000),
        max_bytes: Some(1 << 30),
        thin: Some(ThinOut { after_ms: 6 * 3_600_000, every_ms: 60_000 }),
    };
}

/// Thinning and the size check are done at most this often (sample time, ms): each looks at more
/// than the batch just recorded.
const MAINTAIN_EVERY_MS: i64 = 60_000;

/// Where the thinning and size checks are.
#[derive(Debug, Default)]
struct Upkeep {
    /// The sample time of the last thinning and size check.
    last_ms: Option<i64>,
    /// Samples before this time are thinned already.
    thinned_until: Option<i64>,
}

/// The sample history in an SQLite database (see the [module docs](self)). `Send + Sync`: the
/// scanner records and the console reads from their own threads.
pub struct History {
    path: PathBuf,
    /// The connection that writes (and, in memory, reads).
    writer: Mutex<Connection>,
    /// A read-only connection to the same file, for reads and exports (`None` in memory).
    reader: Option<Mutex<Connection>>,
    retention: Mutex<Retention>,
    upkeep: Mutex<Upkeep>,
}

impl std::fmt::Debug for History {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("History").field("path", &self.path).finish_non_exhaustive()
    }
}

/// Why a file cannot be opened, in words (SQLite's own message repeats the path).
fn open_reason(e: &rusqlite::Error) -> String {
    match e.sqlite_error_code() {
        Some(ErrorCode::CannotOpen) => {
            "SQLite cannot open it (no such directory, no permission, or not a file)".into()
        }
        Some(ErrorCode::PermissionDenied | ErrorCode::ReadOnly) => "no permission to write it".into(),
        _ => e.to_string(),
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic elsewhere while holding the lock leaves a connection that is still usable.
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl History {
    /// Opens the history in the SQLite file `path`, creating the file and its schema when they do
    /// not exist.
    pub fn open(path: &Path) -> Result<History, HistoryError> {
        let writer =
            Connection::open(path).map_err(|source| HistoryError::Open { path: path.to_owned(), source })?;
        let mut history = History::prepare(path, writer)?;
        let reader = Connection::open_with_flags(
            path,
            OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(|source| HistoryError::Open { path: path.to_owned(), source })?;
        reader
            .busy_timeout(std::time::Duration::from_secs(5))
            .map_err(|source| history.sql("setting the busy timeout", source))?;
        history.reader = Some(Mutex::new(reader));
        Ok(history)
    }

    /// A history in memory, gone when dropped (tests, `--no-history` runs that still plot).
    pub fn in_memory() -> Result<History, HistoryError> {
        let path = Path::new(":memory:");
        let conn = Connection::open_in_memory()
            .map_err(|source| HistoryError::Open { path: path.to_owned(), source })?;
        History::prepare(path, conn)
    }

    fn prepare(path: &Path, conn: Connection) -> Result<History, HistoryError> {
        let history = History {
            path: path.to_owned(),
            writer: Mutex::new(conn),
            reader: None,
            retention: Mutex::new(Retention::default()),
            upkeep: Mutex::new(Upkeep::default()),
        };
        {
            let conn = lock(&history.writer);
            // The first statement reads the file's header: a file that is not a database fails here.
            let version: i64 = conn
                .query_row("PRAGMA user_version", [], |r| r.get(0))
                .map_err(|e| history.classify(e, "reading the schema version"))?;
            let tables: i64 = conn
                .query_row("SELECT count(*) FROM sqlite_schema", [], |r| r.get(0))
                .map_err(|e| history.classify(e, "reading the schema"))?;
            if version == 0 && tables > 0 {
                return Err(
                    history.not_a_history(format!("it has {tables} schema object(s) and no schema version"))
                );
            }
            if version != 0 && version != SCHEMA_VERSION {
                return Err(history.not_a_history(format!(
                    "schema version {version}, this program knows version {SCHEMA_VERSION}"
                )));
            }
            conn.busy_timeout(std::time::Duration::from_secs(5))
                .map_err(|e| history.classify(e, "setting the busy timeout"))?;
            // WAL: readers and the writer do not block each other ("memory" for :memory:).
            let _mode: String = conn
                .query_row("PRAGMA journal_mode = WAL", [], |r| r.get(0))
                .map_err(|e| history.classify(e, "switching to WAL mode"))?;
            conn.execute_batch(
                "PRAGMA synchronous = NORMAL;
                 CREATE TABLE IF NOT EXISTS samples (
                     id      INTEGER PRIMARY KEY,
                     unix_ms INTEGER NOT NULL,
                     bus_us  INTEGER NOT NULL,
                     mac     INTEGER NOT NULL,
                     input   BLOB    NOT NULL,
                     decoded TEXT    NOT NULL
                 );
                 CREATE INDEX IF NOT EXISTS samples_mac_time ON samples (mac, unix_ms);
                 CREATE INDEX IF NOT EXISTS samples_time ON samples (unix_ms);
                 PRAGMA user_version = 1;",
            )
            .map_err(|e| history.classify(e, "creating the schema"))?;
            // The audit log (audit.rs) lives beside the samples.
            conn.execute_batch(crate::audit::CREATE_TABLE)
                .map_err(|e| history.classify(e, "creating the audit table"))?;
        }
        Ok(history)
    }

    /// The database file (`:memory:` in memory).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Sets how much history to keep from the next [`record`](History::record) on.
    pub fn set_retention(&self, retention: Retention) {
        *lock(&self.retention) = retention;
    }

    /// Appends `samples` in one transaction (call it once per scan cycle or less often, with the
    /// cycle's samples: one transaction per sample would cost a disk sync each), then applies the
    /// [`Retention`].
    pub fn record(&self, samples: &[Sample]) -> Result<(), HistoryError> {
        if samples.is_empty() {
            return Ok(());
        }
        let retention = *lock(&self.retention);
        let mut conn = lock(&self.writer);
        let tx = conn.transaction().map_err(|e| self.classify(e, "starting a transaction"))?;
        {
            let mut insert = tx
                .prepare_cached(
                    "INSERT INTO samples (unix_ms, bus_us, mac, input, decoded)
                     VALUES (?1, ?2, ?3, ?4, ?5)",
                )
                .map_err(|e| self.classify(e, "preparing the insert"))?;
            for s in samples {
                let bus_us = i64::try_from(s.bus_us).unwrap_or(i64::MAX);
                insert
                    .execute(params![s.unix_ms, bus_us, s.mac, s.input, encode_values(&s.values)])
                    .map_err(|e| self.classify(e, "inserting a sample"))?;
            }
        }
        if let Some(max_age) = retention.max_age_ms {
            let newest = samples.iter().map(|s| s.unix_ms).max().unwrap_or(i64::MIN);
            tx.execute("DELETE FROM samples WHERE unix_ms < ?1", [newest.saturating_sub(max_age)])
                .map_err(|e| self.classify(e, "deleting samples older than the retention"))?;
        }
        if let Some(max_rows) = retention.max_rows {
            let keep = i64::try_from(max_rows).unwrap_or(i64::MAX);
            tx.execute(
                "DELETE FROM samples WHERE id <= (SELECT id FROM samples ORDER BY id DESC LIMIT 1 OFFSET ?1)",
                [keep],
            )
            .map_err(|e| self.classify(e, "deleting samples beyond the retention"))?;
        }
        let newest = samples.iter().map(|s| s.unix_ms).max().unwrap_or(i64::MIN);
        let mut upkeep = lock(&self.upkeep);
        if upkeep.last_ms.is_none_or(|last| newest.saturating_sub(last) >= MAINTAIN_EVERY_MS || newest < last)
        {
            upkeep.last_ms = Some(newest);
            if let Some(thin) = retention.thin {
                upkeep.thinned_until = Some(self.thin_out(&tx, thin, newest, upkeep.thinned_until)?);
            }
            if let Some(max_bytes) = retention.max_bytes {
                self.bound_size(&tx, max_bytes)?;
            }
        }
        tx.commit().map_err(|e| self.classify(e, "committing the samples"))
    }

    /// Keeps one sample per node per `thin.every_ms` of those older than `thin.after_ms` before
    /// `newest`, from `from` on (whole periods); returns the time thinned up to.
    fn thin_out(
        &self,
        tx: &rusqlite::Transaction<'_>,
        thin: ThinOut,
        newest: i64,
        from: Option<i64>,
    ) -> Result<i64, HistoryError> {
        let every = thin.every_ms.max(1);
        let until = newest.saturating_sub(thin.after_ms).div_euclid(every) * every;
        let from = from.map_or(i64::MIN, |f| f.div_euclid(every) * every).min(until);
        tx.execute(
            "DELETE FROM samples WHERE unix_ms >= ?1 AND unix_ms < ?2 AND id NOT IN (
                 SELECT min(id) FROM samples WHERE unix_ms >= ?1 AND unix_ms < ?2
                 GROUP BY mac, unix_ms / ?3)",
            params![from, until, every],
        )
        .map_err(|e| self.classify(e, "thinning old samples out"))?;
        Ok(until)
    }

    /// Deletes the oldest samples while the pages in use exceed `max_bytes` (down to 90 % of it).
    fn bound_size(&self, tx: &rusqlite::Transaction<'_>, max_bytes: u64) -> Result<(), HistoryError> {
        let pragma = |name: &str| -> Result<i64, HistoryError> {
            tx.query_row(&format!("PRAGMA {name}"), [], |r| r.get(0))
                .map_err(|e| self.classify(e, "reading the database size"))
        };
        let used = u64::try_from((pragma("page_count")? - pragma("freelist_count")?) * pragma("page_size")?)
            .unwrap_or(0);
        if used <= max_bytes {
            return Ok(());
        }
        let rows: i64 = tx
            .query_row("SELECT count(*) FROM samples", [], |r| r.get(0))
            .map_err(|e| self.classify(e, "counting the samples"))?;
        let target = max_bytes / 10 * 9;
        // Rows take the pages in proportion: drop the share above the target, at least one.
        let drop = ((rows as f64) * (used - target) as f64 / used as f64).ceil().max(1.0) as i64;
        tx.execute("DELETE FROM samples WHERE id IN (SELECT id FROM samples ORDER BY id LIMIT ?1)", [drop])
            .map_err(|e| self.classify(e, "deleting samples beyond the size limit"))?;
        Ok(())
    }

    /// The bytes of database pages holding data (the file's size less its free pages).
    pub fn used_bytes(&self) -> Result<u64, HistoryError> {
        let conn = self.read_conn();
        let pragma = |name: &str| -> Result<i64, HistoryError> {
            conn.query_row(&format!("PRAGMA {name}"), [], |r| r.get(0))
                .map_err(|e| self.classify(e, "reading the database size"))
        };
        Ok(u64::try_from((pragma("page_count")? - pragma("freelist_count")?) * pragma("page_size")?)
            .unwrap_or(0))
    }

    /// The number of samples kept.
    pub fn len(&self) -> Result<u64, HistoryError> {
        let conn = self.read_conn();
        conn.query_row("SELECT count(*) FROM samples", [], |r| r.get::<_, i64>(0))
            .map(|n| u64::try_from(n).unwrap_or(0))
            .map_err(|e| self.classify(e, "counting the samples"))
    }

    /// Whether no sample is kept.
    pub fn is_empty(&self) -> Result<bool, HistoryError> {
        Ok(self.len()? == 0)
    }

    /// [`HistoryStore::samples`] with the error typed.
    pub fn query(
        &self,
        mac: u8,
        from_ms: i64,
        to_ms: i64,
        limit: usize,
    ) -> Result<Vec<Sample>, HistoryError> {
        let conn = self.read_conn();
        let mut stmt = conn
            .prepare_cached(
                "SELECT mac, unix_ms, bus_us, input, decoded FROM samples
                 WHERE mac = ?1 AND unix_ms BETWEEN ?2 AND ?3
                 ORDER BY unix_ms DESC, id DESC LIMIT ?4",
            )
            .map_err(|e| self.classify(e, "preparing the query"))?;
        let limit = i64::try_from(limit).unwrap_or(i64::MAX);
        let rows = stmt
            .query_map(params![mac, from_ms, to_ms, limit], |r| {
                Ok(Sample {
                    mac: r.get(0)?,
                    unix_ms: r.get(1)?,
                    bus_us: u64::try_from(r.get::<_, i64>(2)?).unwrap_or(0),
                    input: r.get(3)?,
                    values: decode_values(&r.get::<_, String>(4)?),
                })
            })
            .map_err(|e| self.classify(e, "reading samples"))?;
        let mut samples =
            rows.collect::<Result<Vec<_>, _>>().map_err(|e| self.classify(e, "reading samples"))?;
        samples.reverse();
        Ok(samples)
    }

    /// [`HistoryStore::export_csv`] with the error typed.
    pub fn write_csv(
        &self,
        mac: Option<u8>,
        from_ms: i64,
        to_ms: i64,
        out: &mut dyn Write,
    ) -> Result<usize, HistoryError> {
        let mut conn = self.read_conn();
        // One read transaction: both passes see the same rows.
        let tx = conn.transaction().map_err(|e| self.classify(e, "starting the export"))?;
        let filter = "WHERE (?1 IS NULL OR mac = ?1) AND unix_ms BETWEEN ?2 AND ?3";
        // Pass 1: the value names, in first-seen order.
        let mut names: Vec<String> = Vec::new();
        {
            let mut stmt = tx
                .prepare(&format!("SELECT decoded FROM samples {filter} ORDER BY unix_ms, id"))
                .map_err(|e| self.classify(e, "preparing the export"))?;
            let mut rows = stmt
                .query(params![mac, from_ms, to_ms])
                .map_err(|e| self.classify(e, "reading the value names"))?;
            while let Some(row) = rows.next().map_err(|e| self.classify(e, "reading the value names"))? {
                let text: String = row.get(0).map_err(|e| self.classify(e, "reading the value names"))?;
                for (name, _) in decode_values(&text) {
                    if !names.contains(&name) {
                        names.push(name);
                    }
                }
            }
        }
        let io = |source| HistoryError::Write { path: self.path.clone(), source };
        let mut line = String::from("unix_ms,time,mac,input_hex");
        for name in &names {
            line.push(',');
            line.push_str(&csv_field(name));
        }
        line.push('\n');
        out.write_all(line.as_bytes()).map_err(io)?;
        // Pass 2: the rows.
        let mut count = 0;
        {
            let mut stmt = tx
                .prepare(&format!(
                    "SELECT unix_ms, mac, input, decoded FROM samples {filter} ORDER BY unix_ms, id"
                ))
                .map_err(|e| self.classify(e, "preparing the export"))?;
            let mut rows =
                stmt.query(params![mac, from_ms, to_ms]).map_err(|e| self.classify(e, "reading samples"))?;
            while let Some(row) = rows.next().map_err(|e| self.classify(e, "reading samples"))? {
                let get = |e| self.classify(e, "reading samples");
                let unix_ms: i64 = row.get(0).map_err(get)?;
                let mac: u8 = row.get(1).map_err(get)?;
                let input: Vec<u8> = row.get(2).map_err(get)?;
                let values = decode_values(&row.get::<_, String>(3).map_err(get)?);
                line.clear();
                let _ = write!(line, "{unix_ms},{},{mac},{}", iso8601_ms(unix_ms), hex(&input));
                for name in &names {
                    line.push(',');
                    if let Some((_, v)) = values.iter().find(|(n, _)| n == name) {
                        line.push_str(&csv_value(name, *v));
                    }
                }
                line.push('\n');
                out.write_all(line.as_bytes()).map_err(io)?;
                count += 1;
            }
        }
        out.flush().map_err(io)?;
        Ok(count)
    }

    fn read_conn(&self) -> MutexGuard<'_, Connection> {
        lock(self.reader.as_ref().unwrap_or(&self.writer))
    }

    fn sql(&self, what: &'static str, source: rusqlite::Error) -> HistoryError {
        HistoryError::Sql { path: self.path.clone(), what, source }
    }

    fn not_a_history(&self, detail: String) -> HistoryError {
        HistoryError::NotAHistory { path: self.path.clone(), detail }
    }

    /// Names a file that is not a database as such; every other failure as what was being done.
    fn classify(&self, source: rusqlite::Error, what: &'static str) -> HistoryError {
        match source.sqlite_error_code() {
            Some(ErrorCode::NotADatabase) => HistoryError::NotADatabase { path: self.path.clone() },
            Some(ErrorCode::CannotOpen) => HistoryError::Open { path: self.path.clone(), source },
            _ => self.sql(what, source),
        }
    }
}

impl History {
    /// An SQL failure of the audit table, naming the file and what was being done.
    fn audit_error(&self, what: &'static str, source: rusqlite::Error) -> crate::audit::AuditError {
        crate::audit::AuditError::Database { path: self.path.clone(), what, source }
    }
}

/// The audit log in the table `audit` (see [`crate::audit`]), kept to the newest
/// [`audit::MAX_ROWS`](crate::audit::MAX_ROWS) entries.
impl crate::audit::Audit for History {
    fn record(&self, entry: &crate::audit::AuditEntry) -> Result<(), crate::audit::AuditError> {
        let conn = lock(&self.writer);
        crate::audit::insert(&conn, entry, crate::audit::MAX_ROWS)
            .map_err(|source| self.audit_error("recording an audit entry", source))
    }

    fn recent(&self, limit: usize) -> Result<Vec<crate::audit::AuditEntry>, crate::audit::AuditError> {
        crate::audit::select(&self.read_conn(), limit)
            .map_err(|source| self.audit_error("reading the audit log", source))
    }
}

impl HistoryStore for History {
    fn samples(&self, mac: u8, from_ms: i64, to_ms: i64, limit: usize) -> Result<Vec<Sample>, String> {
        self.query(mac, from_ms, to_ms, limit).map_err(|e| e.to_string())
    }

    fn export_csv(
        &self,
        mac: Option<u8>,
        from_ms: i64,
        to_ms: i64,
        out: &mut dyn Write,
    ) -> Result<usize, String> {
        self.write_csv(mac, from_ms, to_ms, out).map_err(|e| e.to_string())
    }
}

/// The values as stored: a JSON array of `[name, value]` pairs (`null` for a non-finite value).
fn encode_values(values: &[(String, f64)]) -> String {
    let pairs: Vec<(&str, Option<f64>)> =
        values.iter().map(|(n, v)| (n.as_str(), v.is_finite().then_some(*v))).collect();
    serde_json::to_string(&pairs).unwrap_or_else(|_| "[]".into())
}

/// The stored values back; text that is not such an array gives no values.
fn decode_values(text: &str) -> Vec<(String, f64)> {
    serde_json::from_str::<Vec<(String, Option<f64>)>>(text)
        .map(|pairs| pairs.into_iter().map(|(n, v)| (n, v.unwrap_or(f64::NAN))).collect())
        .unwrap_or_default()
}

/// Upper-case hex without separators (`0A1B`), as in the CSV and the MQTT payloads.
#[must_use]
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02X}");
    }
    s
}

/// `2024-05-01T12:00:00.123Z`; empty for an instant `time` cannot represent.
#[must_use]
pub fn iso8601_ms(unix_ms: i64) -> String {
    let nanos = i128::from(unix_ms) * 1_000_000;
    match time::OffsetDateTime::from_unix_timestamp_nanos(nanos) {
        Ok(t) => format!(
            "{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:03}Z",
            t.year(),
            u8::from(t.month()),
            t.day(),
            t.hour(),
            t.minute(),
            t.second(),
            t.millisecond()
        ),
        Err(_) => String::new(),
    }
}

/// A value's CSV cell: a number, empty when not finite; the breaker's `switch` as the console
/// shows it (`open`, `closed`, `unknown (0xXX)`), not its byte.
#[must_use]
pub fn csv_value(name: &str, v: f64) -> String {
    if !v.is_finite() {
        return String::new();
    }
    if name == "switch" && v.fract() == 0.0 && (0.0..=255.0).contains(&v) {
        let status = crate::monitor::BreakerStatus { currents: [0; 4], switch: v as u8 };
        return status.switch_text();
    }
    v.to_string()
}

/// A CSV field, quoted when it holds a comma, a quote or a line break (RFC 4180).
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_owned()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[rstest]
    #[case::epoch(0, "1970-01-01T00:00:00.000Z")]
    #[case::ms(1_714_564_800_123, "2024-05-01T12:00:00.123Z")]
    #[case::before_epoch(-1, "1969-12-31T23:59:59.999Z")]
    #[case::out_of_range(i64::MAX, "")]
    fn iso8601(#[case] unix_ms: i64, #[case] text: &str) {
        assert_eq!(iso8601_ms(unix_ms), text);
    }

    #[rstest]
    #[case::plain("phase_a", "phase_a")]
    #[case::comma("a,b", "\"a,b\"")]
    #[case::quote("say \"hi\"", "\"say \"\"hi\"\"\"")]
    fn csv_fields(#[case] text: &str, #[case] field: &str) {
        assert_eq!(csv_field(text), field);
    }

    #[rstest]
    #[case::closed("switch", 240.0, "closed")]
    #[case::open("switch", 15.0, "open")]
    #[case::unknown("switch", 1.0, "unknown (0x01)")]
    #[case::number("phase_a", 240.0, "240")]
    #[case::fraction("phase_a", 12.5, "12.5")]
    #[case::not_finite("switch", f64::NAN, "")]
    fn csv_values(#[case] name: &str, #[case] v: f64, #[case] cell: &str) {
        assert_eq!(csv_value(name, v), cell);
    }

    #[test]
    fn values_round_trip_and_non_finite_is_nan() {
        let text = encode_values(&[("a".into(), 1.5), ("b".into(), f64::INFINITY)]);
        assert_eq!(text, r#"[["a",1.5],["b",null]]"#);
        let back = decode_values(&text);
        assert_eq!(back[0], ("a".into(), 1.5));
        assert!(back[1].1.is_nan());
        assert!(decode_values("not json").is_empty());
    }
}
