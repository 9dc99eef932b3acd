//! The audit log: every command sent to the plant through the console (and through the other
//! plant interfaces: Sparkplug DCMD, OPC UA methods, Modbus TCP writes), with who sent it, when,
//! to which node, what it was and how it ended.
//!
//! Whoever carries out a command records it with [`Audit::record`] on the [`Audit`] in
//! [`Shared::audit`](crate::model::Shared::audit); the console reads it back with
//! [`Audit::recent`] (`GET /api/audit`). Refused commands are recorded too (their
//! [`AuditEntry::result`] says why), so the log shows attempts as well as actions.
//!
//! Two stores:
//! - the SQLite history ([`History`](crate::history::History)): a table `audit` beside the samples,
//!   kept to the newest [`MAX_ROWS`] entries:
//!
//!   ```sql
//!   CREATE TABLE audit (
//!       id      INTEGER PRIMARY KEY,  -- insertion order
//!       unix_ms INTEGER NOT NULL,     -- wall-clock time, ms since the Unix epoch
//!       user    TEXT    NOT NULL,     -- the account ("-" when logins are off)
//!       via     TEXT    NOT NULL,     -- console, sparkplug, opcua, modbus-tcp
//!       mac     INTEGER,              -- the node's MAC ID, NULL for none
//!       what    TEXT    NOT NULL,     -- "close", "output 0x01 0x00", "set 0x64/1/3 = 0A00"
//!       result  TEXT    NOT NULL      -- "ok", "refused: ...", "failed: ..."
//!   );
//!   ```
//! - [`MemoryAudit`]: the newest [`MAX_ROWS`] entries in memory, when no history is kept.
//!
//! Recording never fails a command: a store that cannot write reports it through
//! [`Audit::record`]'s error, and the caller carries on.

use std::collections::VecDeque;
use std::sync::{Mutex, PoisonError};

/// How many entries a store keeps (the oldest go first). At about 100 bytes an entry, ~10 MB.
pub const MAX_ROWS: usize = 100_000;

/// The longest `user`, `what` or `result` text stored, in characters (longer is cut).
pub const MAX_TEXT: usize = 256;

/// Through which interface a command came.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Via {
    /// The web console (`dnet-master ui`).
    Console,
    /// A Sparkplug B DCMD.
    Sparkplug,
    /// An OPC UA method call or write.
    OpcUa,
    /// A Modbus TCP write.
    ModbusTcp,
}

impl Via {
    /// The interface in words, as stored (`console`, `sparkplug`, `opcua`, `modbus-tcp`).
    pub fn name(self) -> &'static str {
        match self {
            Via::Console => "console",
            Via::Sparkplug => "sparkplug",
            Via::OpcUa => "opcua",
            Via::ModbusTcp => "modbus-tcp",
        }
    }

    /// The interface named `text`, if any.
    pub fn from_name(text: &str) -> Option<Via> {
        [Via::Console, Via::Sparkplug, Via::OpcUa, Via::ModbusTcp].into_iter().find(|v| v.name() == text)
    }
}

/// One command, as the log keeps it.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct AuditEntry {
    /// When it was carried out (or refused): ms since the Unix epoch, wall clock.
    pub unix_ms: i64,
    /// The account that sent it (`-` when logins are off).
    pub user: String,
    /// Through which interface (see [`Via::name`]).
    pub via: &'static str,
    /// The node it was for, if any.
    pub mac: Option<u8>,
    /// What it was, in words (`close`, `output 0x01 0x00`, `set 0x64/1/3 = 0A00`).
    pub what: String,
    /// How it ended: `ok`, `refused: REASON` or `failed: REASON`.
    pub result: String,
}

impl AuditEntry {
    /// An entry stamped with the current wall-clock time; texts longer than [`MAX_TEXT`] are cut.
    pub fn now(user: &str, via: Via, mac: Option<u8>, what: &str, result: &str) -> AuditEntry {
        AuditEntry {
            unix_ms: unix_ms_now(),
            user: cut(user),
            via: via.name(),
            mac,
            what: cut(what),
            result: cut(result),
        }
    }
}

/// The wall-clock time in ms since the Unix epoch (0 before 1970).
pub fn unix_ms_now() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_millis()).unwrap_or(i64::MAX))
}

/// `text` cut to [`MAX_TEXT`] characters.
pub(crate) fn cut(text: &str) -> String {
    text.chars().take(MAX_TEXT).collect()
}

/// Why the audit log could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum AuditError {
    /// The history database failed (disk full, locked by another program, ...).
    #[error("history database {}: {what}: {source}", path.display())]
    Database {
        /// The history file.
        path: std::path::PathBuf,
        /// What was being done.
        what: &'static str,
        /// SQLite's reason.
        source: rusqlite::Error,
    },
}

/// Where audit entries go: the history's `audit` table or [`MemoryAudit`]. `Send + Sync`: the
/// console's threads, the scanner's loop and the plant interfaces record from their own threads.
pub trait Audit: Send + Sync {
    /// Appends `entry` (dropping the oldest beyond [`MAX_ROWS`]).
    fn record(&self, entry: &AuditEntry) -> Result<(), AuditError>;
    /// The newest `limit` entries, newest first.
    fn recent(&self, limit: usize) -> Result<Vec<AuditEntry>, AuditError>;
}

impl<T: Audit + ?Sized> Audit for std::sync::Arc<T> {
    fn record(&self, entry: &AuditEntry) -> Result<(), AuditError> {
        (**self).record(entry)
    }

    fn recent(&self, limit: usize) -> Result<Vec<AuditEntry>, AuditError> {
        (**self).recent(limit)
    }
}

/// The audit log in memory: the newest [`MAX_ROWS`] entries (when no history is kept).
#[derive(Debug, Default)]
pub struct MemoryAudit {
    entries: Mutex<VecDeque<AuditEntry>>,
}

impl Audit for MemoryAudit {
    fn record(&self, entry: &AuditEntry) -> Result<(), AuditError> {
        let mut entries = self.entries.lock().unwrap_or_else(PoisonError::into_inner);
        if entries.len() >= MAX_ROWS {
            entries.pop_front();
        }
        entries.push_back(entry.clone());
        Ok(())
    }

    fn recent(&self, limit: usize) -> Result<Vec<AuditEntry>, AuditError> {
        let entries = self.entries.lock().unwrap_or_else(PoisonError::into_inner);
        Ok(entries.iter().rev().take(limit).cloned().collect())
    }
}

/// The SQL that creates the history's `audit` table (run by the history when it opens).
pub(crate) const CREATE_TABLE: &str = "CREATE TABLE IF NOT EXISTS audit (
     id      INTEGER PRIMARY KEY,
     unix_ms INTEGER NOT NULL,
     user    TEXT    NOT NULL,
     via     TEXT    NOT NULL,
     mac     INTEGER,
     what    TEXT    NOT NULL,
     result  TEXT    NOT NULL
 );";

/// Appends `entry` to the `audit` table of `conn` and drops the entries beyond `max_rows`.
pub(crate) fn insert(
    conn: &rusqlite::Connection,
    entry: &AuditEntry,
    max_rows: usize,
) -> Result<(), rusqlite::Error> {
    conn.execute(
        "INSERT INTO audit (unix_ms, user, via, mac, what, result) VALUES (?1, ?2, ?3, ?4, ?5, ?6)",
        rusqlite::params![entry.unix_ms, entry.user, entry.via, entry.mac, entry.what, entry.result],
    )?;
    let id = conn.last_insert_rowid();
    let keep_from = id.saturating_sub(i64::try_from(max_rows).unwrap_or(i64::MAX)) + 1;
    // Ids grow by one per insert: this keeps the newest `max_rows` (an index lookup, no count).
    conn.execute("DELETE FROM audit WHERE id < ?1", [keep_from])?;
    Ok(())
}

/// The newest `limit` entries of the `audit` table of `conn`, newest first.
pub(crate) fn select(conn: &rusqlite::Connection, limit: usize) -> Result<Vec<AuditEntry>, rusqlite::Error> {
    let mut stmt = conn.prepare_cached(
        "SELECT unix_ms, user, via, mac, what, result FROM audit ORDER BY id DESC LIMIT ?1",
    )?;
    let limit = i64::try_from(limit).unwrap_or(i64::MAX);
    let rows = stmt.query_map([limit], |r| {
        let via: String = r.get(2)?;
        Ok(AuditEntry {
            unix_ms: r.get(0)?,
            user: r.get(1)?,
            via: Via::from_name(&via).map_or("unknown", Via::name),
            mac: r.get(3)?,
            what: r.get(4)?,
            result: r.get(5)?,
        })
    })?;
    rows.collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(i: i64) -> AuditEntry {
        AuditEntry {
            unix_ms: i,
            user: "alice".into(),
            via: Via::Console.name(),
            mac: Some(5),
            what: format!("close {i}"),
            result: "ok".into(),
        }
    }

    #[test]
    fn memory_keeps_the_newest() {
        let audit = MemoryAudit::default();
        for i in 0..(MAX_ROWS as i64 + 3) {
            audit.record(&entry(i)).unwrap();
        }
        let recent = audit.recent(2).unwrap();
        assert_eq!(recent, [entry(MAX_ROWS as i64 + 2), entry(MAX_ROWS as i64 + 1)]);
        assert_eq!(audit.recent(usize::MAX).unwrap().len(), MAX_ROWS);
        assert_eq!(audit.recent(usize::MAX).unwrap().last(), Some(&entry(3)));
    }

    #[test]
    fn sqlite_keeps_the_newest_and_reads_back() {
        let conn = rusqlite::Connection::open_in_memory().unwrap();
        conn.execute_batch(CREATE_TABLE).unwrap();
        for i in 0..10 {
            insert(&conn, &entry(i), 4).unwrap();
        }
        let mut none = entry(10);
        none.mac = None;
        none.via = Via::OpcUa.name();
        insert(&conn, &none, 4).unwrap();
        let all = select(&conn, 100).unwrap();
        assert_eq!(all, [none, entry(9), entry(8), entry(7)]);
    }

    #[test]
    fn the_history_keeps_the_audit_log_across_a_reopen() {
        let dir = std::env::temp_dir().join(format!("dnet-audit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("history.sqlite");
        let _ = std::fs::remove_file(&path);
        {
            let history = crate::history::History::open(&path).unwrap();
            let audit: &dyn Audit = &history;
            audit.record(&entry(1)).unwrap();
            audit.record(&entry(2)).unwrap();
        }
        let history = crate::history::History::open(&path).unwrap();
        assert_eq!(Audit::recent(&history, 10).unwrap(), [entry(2), entry(1)]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn long_texts_are_cut() {
        let e = AuditEntry::now(&"u".repeat(1000), Via::Console, None, &"w".repeat(1000), "ok");
        assert_eq!(e.user.chars().count(), MAX_TEXT);
        assert_eq!(e.what.chars().count(), MAX_TEXT);
        assert!(e.unix_ms > 1_600_000_000_000);
    }
}
