//! Store-and-forward: the DDATA made while the broker is away, kept in an SQLite file in the order
//! they were made, bounded by a number of messages and an age, and taken back oldest first once
//! the broker is there again. The file also keeps the last `bdSeq`, so that a restarted edge node
//! goes on counting.
//!
//! ```sql
//! CREATE TABLE pending (
//!     id      INTEGER PRIMARY KEY,  -- the order they were made
//!     unix_ms INTEGER NOT NULL,     -- when the values were taken
//!     mac     INTEGER NOT NULL,     -- the device (DeviceNet MAC ID)
//!     payload BLOB    NOT NULL,     -- the DDATA payload without seq (protobuf)
//!     network TEXT                  -- the plant network (NULL without --plant)
//! );
//! CREATE TABLE meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);  -- 'bd_seq'
//! ```

use super::edge::DeviceKey;
use rusqlite::{params, Connection, OptionalExtension};
use std::path::{Path, PathBuf};

/// Why the store cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The file cannot be opened or is not a store.
    #[error("the Sparkplug store {path}: {source}")]
    Open {
        /// The file.
        path: PathBuf,
        /// Why.
        source: rusqlite::Error,
    },
    /// A read or write failed (a full disk).
    #[error("the Sparkplug store: {0}")]
    Sql(#[from] rusqlite::Error),
}

/// How much the store keeps: the newest `max_messages` made within `max_age_ms` of the newest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    /// At most this many messages (the oldest go first).
    pub max_messages: u64,
    /// Only messages at most this old (ms) relative to the newest stored.
    pub max_age_ms: u64,
}

/// A stored DDATA.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Stored {
    /// Its row, for [`Store::remove_through`].
    pub id: i64,
    /// The device.
    pub key: DeviceKey,
    /// The DDATA payload without seq.
    pub payload: Vec<u8>,
}

/// The store (see the [module docs](self)).
#[derive(Debug)]
pub struct Store {
    conn: Connection,
    window: Window,
    /// Messages dropped because the window was full.
    pub dropped: u64,
}

impl Store {
    /// Opens or creates the store at `path` (`None`: in memory, for tests).
    pub fn open(path: Option<&Path>, window: Window) -> Result<Store, StoreError> {
        let open_err =
            |source| StoreError::Open { path: path.map(Path::to_path_buf).unwrap_or_default(), source };
        let conn = match path {
            Some(p) => Connection::open(p),
            None => Connection::open_in_memory(),
        }
        .map_err(open_err)?;
        conn.execute_batch(
            "PRAGMA journal_mode = WAL; PRAGMA synchronous = NORMAL;
             CREATE TABLE IF NOT EXISTS pending (id INTEGER PRIMARY KEY, unix_ms INTEGER NOT NULL,
                 mac INTEGER NOT NULL, payload BLOB NOT NULL, network TEXT);
             CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value INTEGER NOT NULL);",
        )
        .map_err(open_err)?;
        // A store written before plants had no network column: its rows are the one network's.
        let has_network: i64 = conn
            .query_row("SELECT COUNT(*) FROM pragma_table_info('pending') WHERE name = 'network'", [], |r| {
                r.get(0)
            })
            .map_err(open_err)?;
        if has_network == 0 {
            conn.execute_batch("ALTER TABLE pending ADD COLUMN network TEXT").map_err(open_err)?;
        }
        Ok(Store { conn, window, dropped: 0 })
    }

    /// Appends a DDATA made at `unix_ms`, then drops what falls outside the window.
    pub fn push(&mut self, key: &DeviceKey, unix_ms: u64, payload: &[u8]) -> Result<(), StoreError> {
        let tx = self.conn.transaction()?;
        tx.execute(
            "INSERT INTO pending (unix_ms, mac, payload, network) VALUES (?1, ?2, ?3, ?4)",
            params![i64::try_from(unix_ms).unwrap_or(i64::MAX), key.mac, payload, key.network],
        )?;
        let oldest = i64::try_from(unix_ms.saturating_sub(self.window.max_age_ms)).unwrap_or(0);
        let mut gone = tx.execute("DELETE FROM pending WHERE unix_ms < ?1", params![oldest])?;
        gone += tx.execute(
            "DELETE FROM pending WHERE id <= (SELECT MAX(id) FROM pending) - ?1",
            params![i64::try_from(self.window.max_messages).unwrap_or(i64::MAX)],
        )?;
        tx.commit()?;
        self.dropped += gone as u64;
        Ok(())
    }

    /// The oldest `limit` stored messages, oldest first.
    pub fn oldest(&self, limit: usize) -> Result<Vec<Stored>, StoreError> {
        let mut stmt =
            self.conn.prepare_cached("SELECT id, mac, payload, network FROM pending ORDER BY id LIMIT ?1")?;
        let rows = stmt.query_map(params![i64::try_from(limit).unwrap_or(i64::MAX)], |r| {
            Ok(Stored {
                id: r.get(0)?,
                key: DeviceKey { network: r.get(3)?, mac: r.get(1)? },
                payload: r.get(2)?,
            })
        })?;
        Ok(rows.collect::<Result<_, _>>()?)
    }

    /// Removes the stored messages up to and with `id` (sent).
    pub fn remove_through(&mut self, id: i64) -> Result<(), StoreError> {
        self.conn.execute("DELETE FROM pending WHERE id <= ?1", params![id])?;
        Ok(())
    }

    /// How many messages wait.
    pub fn len(&self) -> Result<u64, StoreError> {
        let n: i64 = self.conn.query_row("SELECT COUNT(*) FROM pending", [], |r| r.get(0))?;
        Ok(u64::try_from(n).unwrap_or(0))
    }

    /// Whether nothing waits.
    pub fn is_empty(&self) -> Result<bool, StoreError> {
        Ok(self.len()? == 0)
    }

    /// The `bdSeq` of the last session, when one was kept.
    pub fn bd_seq(&self) -> Result<Option<u64>, StoreError> {
        let v: Option<i64> = self
            .conn
            .query_row("SELECT value FROM meta WHERE key = 'bd_seq'", [], |r| r.get(0))
            .optional()?;
        Ok(v.and_then(|v| u64::try_from(v).ok()))
    }

    /// Keeps `bdSeq`.
    pub fn set_bd_seq(&mut self, bd_seq: u64) -> Result<(), StoreError> {
        self.conn.execute(
            "INSERT INTO meta (key, value) VALUES ('bd_seq', ?1)
             ON CONFLICT(key) DO UPDATE SET value = excluded.value",
            params![i64::try_from(bd_seq).unwrap_or(0)],
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keeps_order_and_window() {
        let mut s = Store::open(None, Window { max_messages: 3, max_age_ms: 1000 }).unwrap();
        for (i, t) in [100u64, 200, 300, 400].iter().enumerate() {
            s.push(&DeviceKey::single(i as u8), *t, &[i as u8]).unwrap();
        }
        let macs: Vec<u8> = s.oldest(10).unwrap().iter().map(|r| r.key.mac).collect();
        assert_eq!(macs, [1, 2, 3], "the oldest beyond 3 messages dropped");
        assert_eq!(s.dropped, 1);
        s.push(&DeviceKey::of(Some("line-b"), 9), 1350, &[9]).unwrap();
        let keys: Vec<DeviceKey> = s.oldest(10).unwrap().into_iter().map(|r| r.key).collect();
        assert_eq!(keys, [DeviceKey::single(3), DeviceKey::of(Some("line-b"), 9)], "the network is kept");
        let macs: Vec<u8> = keys.iter().map(|k| k.mac).collect();
        assert_eq!(macs, [3, 9], "older than 1000 ms before the newest dropped");
        let first = s.oldest(1).unwrap()[0].id;
        s.remove_through(first).unwrap();
        assert_eq!(s.len().unwrap(), 1);
    }

    /// A store file from before plants (no network column) opens, its rows the one network's.
    #[test]
    fn a_store_without_the_network_column_is_migrated() {
        let dir = std::env::temp_dir().join(format!("dnet-spb-store-old-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("old.sqlite");
        let old = Connection::open(&path).unwrap();
        old.execute_batch(
            "CREATE TABLE pending (id INTEGER PRIMARY KEY, unix_ms INTEGER NOT NULL,
                 mac INTEGER NOT NULL, payload BLOB NOT NULL);
             INSERT INTO pending (unix_ms, mac, payload) VALUES (5, 7, x'01');",
        )
        .unwrap();
        drop(old);
        let mut s = Store::open(Some(&path), Window { max_messages: 10, max_age_ms: 1000 }).unwrap();
        s.push(&DeviceKey::of(Some("a"), 7), 6, &[2]).unwrap();
        let keys: Vec<DeviceKey> = s.oldest(10).unwrap().into_iter().map(|r| r.key).collect();
        assert_eq!(keys, [DeviceKey::single(7), DeviceKey::of(Some("a"), 7)]);
        drop(s);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bd_seq_is_kept_in_the_file() {
        let dir = std::env::temp_dir().join(format!("dnet-spb-store-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("s.sqlite");
        let window = Window { max_messages: 10, max_age_ms: 10 };
        let mut s = Store::open(Some(&path), window).unwrap();
        assert_eq!(s.bd_seq().unwrap(), None);
        s.set_bd_seq(7).unwrap();
        drop(s);
        assert_eq!(Store::open(Some(&path), window).unwrap().bd_seq().unwrap(), Some(7));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
