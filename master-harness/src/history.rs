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
//! 1714564800123,2024-05-01T12:00:00.123Z,5,0A00140000000000000001,10,20,0,0,1
//! ```
//!
//! `time` is the same instant in ISO 8601, UTC, with milliseconds; `input_hex` the input image in
//! upper-case hex without separators; then one column per value name of the exported samples, in
//! the order they are first seen (a sample without a name leaves its cell empty, as does a value
//! that is not a finite number). Rows are oldest first; lines end in `\n`; a name holding a comma,
//! a quote or a line break is quoted as RFC 4180 says. The export streams: it reads the range
//! twice (once for the names, once for the rows) and never holds more than one row in memory.
//!
//! ## Retention
//!
//! By default every sample is kept. A scanner of 63 nodes recording every 70 ms cycle writes
//! about 900 rows a second, some 8 GB a day: set a [`Retention`] with
//! [`History::set_retention`] to keep at most `max_rows` samples and / or the samples of the last
//! `max_age_ms` before the newest one recorded. The oldest go first, in the same transaction as
//! the batch that made them too many.
//!
//! ## Errors
//!
//! Every error names the database file ([`HistoryError`]): a path that cannot be opened or
//! created, a file that is not an SQLite database, an SQLite database that is not a history.
//! Nothing here panics.

use crate::scanner::model::{HistoryStore, Sample};
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

/// How much history to keep; `None` in a field: no limit of that kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Retention {
    /// Keep at most this many samples (all nodes together); the oldest recorded go first.
    pub max_rows: Option<u64>,
    /// Keep the samples of this many ms before the newest sample recorded (`unix_ms`).
    pub max_age_ms: Option<i64>,
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
        tx.commit().map_err(|e| self.classify(e, "committing the samples"))
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
                        if v.is_finite() {
                            let _ = write!(line, "{v}");
                        }
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
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02X}");
    }
    s
}

/// `2024-05-01T12:00:00.123Z`; empty for an instant `time` cannot represent.
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
