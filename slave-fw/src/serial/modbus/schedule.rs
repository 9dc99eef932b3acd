//! When each scan entry is sent: its schedule keys ([`ScanEntry::period_ms`],
//! [`ScanEntry::write`], [`ScanEntry::trigger_offset`]), their checks, and the timetable the
//! master draws its next read from.
//!
//! | entry | keys | sent |
//! |---|---|---|
//! | read | none | every scan cycle ([`poll_period_ms`](super::ModbusConfig::poll_period_ms)), as before the keys existed |
//! | read | `period_ms = N` | every N ms on its own, whatever the scan cycle |
//! | read | `trigger_offset = B` | once each time output byte B changes value (not cyclically) |
//! | write | none, `write = "change"` | when its output bytes change |
//! | write | `write = "cyclic"`, `period_ms = N` | when its output bytes change, and every N ms even when they do not |
//! | write | `write = "trigger"`, `trigger_offset = B` | once each time output byte B changes value; changes of its own bytes alone send nothing |
//!
//! The first output image after start arms the triggers: a trigger fires on a change from one
//! poll's output to the next, never on the first poll. A trigger byte lies in the output image
//! and outside every write entry's bytes (a byte sent to an instrument is data, not a
//! handshake); several entries may share one trigger byte.
//!
//! ## Order
//!
//! A retry, the idle/fault frame, and the writes called for by a change (of their bytes or of
//! their trigger byte) go first, in scan-list order, as before. Everything else that is due — the
//! scan cycle's reads (due at the cycle's start), periodic reads and cyclic re-sends (due at their
//! period instant), triggered reads (due at the poll that changed the trigger byte) — goes
//! earliest due first, ties in scan-list order. So the order is deterministic and nothing starves:
//! an entry's due instant never moves while it waits, and an entry sent is due again only at a
//! later instant, behind everything that waited longer. A slow-period entry is sent once per
//! period and does not hold up the others; a period too short for the line makes its entry due at
//! every turn, still behind entries that have waited longer.
//!
//! Periods run on a fixed grid from start (the instant of the first poll), like the scan cycle: a
//! period instant missed while the line was busy makes the entry due once, and the grid restarts
//! from that moment instead of sending a burst. A periodic entry is due at once at start.

use super::entry::ScanEntry;
use crate::serial::error::{ConfigError, Conflict, Field, Problem};
use crate::serial::IMAGE_CAPACITY;
use devicenet::{Duration, Instant};

/// When a write entry is sent ([`ScanEntry::write`]); the module docs give the table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum WriteMode {
    /// When its bytes of the output image change (the default).
    #[default]
    Change,
    /// On change, and every [`ScanEntry::period_ms`] even when unchanged.
    Cyclic,
    /// Once each time the output byte at [`ScanEntry::trigger_offset`] changes value.
    Trigger,
}

impl WriteMode {
    /// Whether this is [`WriteMode::Change`], the default.
    pub fn is_change(&self) -> bool {
        *self == WriteMode::Change
    }

    /// Every mode, in image code order (bits 2-3 of a scan entry's schedule byte).
    pub const ALL: [WriteMode; 3] = [WriteMode::Change, WriteMode::Cyclic, WriteMode::Trigger];
}

/// The longest `period_ms` accepted, one hour (as the poll period).
pub const MAX_PERIOD_MS: u32 = 3_600_000;

/// An entry's schedule, from its checked keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Plan {
    /// Reads: every scan cycle. Writes: on change.
    Cycle,
    /// Reads: on their own period. Writes: on change and on the period.
    Period(Duration),
    /// On every change of this output byte.
    Trigger(usize),
}

/// The schedule of `e`, whose keys [`check`] accepted (a trigger byte comes first, then a
/// period).
pub(crate) fn plan(e: &ScanEntry) -> Plan {
    match (e.trigger_offset, e.period_ms) {
        (Some(b), _) => Plan::Trigger(usize::from(b)),
        (None, Some(p)) => Plan::Period(Duration::from_millis(u64::from(p))),
        (None, None) => Plan::Cycle,
    }
}

/// Checks the schedule keys of entry `e` of `scan`, whose output image is `output_len` bytes: a
/// key that does not apply to the entry's function, a missing companion key, a period out of
/// range, a trigger byte outside the output image or inside a write entry's bytes.
pub(crate) fn check(e: &ScanEntry, scan: &[ScanEntry], output_len: u16) -> Result<(), ConfigError> {
    let write = e.function.is_write();
    if let Some(p) = e.period_ms {
        ConfigError::check_range(Field::ScanPeriod, p, 1, MAX_PERIOD_MS)?;
    }
    match e.write {
        _ if !write && !e.write.is_change() => {
            return Err(ConfigError::conflict(Field::ScanWrite, Conflict::WriteModeOnRead));
        }
        WriteMode::Cyclic if e.period_ms.is_none() => {
            return Err(ConfigError::conflict(Field::ScanWrite, Conflict::CyclicNeedsPeriod));
        }
        WriteMode::Trigger if e.trigger_offset.is_none() => {
            return Err(ConfigError::conflict(Field::ScanWrite, Conflict::TriggerNeedsOffset));
        }
        _ => {}
    }
    if write && e.period_ms.is_some() && e.write != WriteMode::Cyclic {
        return Err(ConfigError::conflict(Field::ScanPeriod, Conflict::PeriodNeedsCyclic));
    }
    let Some(b) = e.trigger_offset else { return Ok(()) };
    if write && e.write != WriteMode::Trigger {
        return Err(ConfigError::conflict(Field::ScanTrigger, Conflict::TriggerNeedsTriggerMode));
    }
    if !write && e.period_ms.is_some() {
        return Err(ConfigError::conflict(Field::ScanTrigger, Conflict::PeriodOrTrigger));
    }
    if output_len == 0 {
        return Err(ConfigError::conflict(Field::ScanTrigger, Conflict::TriggerNeedsOutput));
    }
    ConfigError::check_range(Field::ScanTrigger, u32::from(b), 0, u32::from(output_len) - 1)?;
    let b = usize::from(b);
    match scan.iter().position(|o| o.function.is_write() && o.range().contains(&b)) {
        Some(other) => Err(ConfigError {
            field: Field::ScanTrigger,
            index: None,
            problem: Problem::Overlap { other: u16::try_from(other).unwrap_or(u16::MAX) },
        }),
        None => Ok(()),
    }
}

/// Whether the output image `new`, replacing `old`, calls for entry `e`: a change of its trigger
/// byte (from the second output image on: `first` is true for the first), or for a write sent on
/// change, a change of its bytes (or the first output image). Reads without a trigger are never
/// called for by outputs.
pub(crate) fn called_for(
    e: &ScanEntry,
    old: &[u8; IMAGE_CAPACITY],
    new: &[u8; IMAGE_CAPACITY],
    first: bool,
) -> bool {
    match plan(e) {
        Plan::Trigger(b) => !first && old.get(b) != new.get(b),
        _ if e.function.is_write() => first || !super::entry::same_output(e, old, new),
        _ => false,
    }
}

/// The entries due to be sent and the next period instant of each, for a scan list of at most
/// `N` entries: the master's read order (module docs, "Order"). Fixed memory, no allocation.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Timetable<const N: usize> {
    /// Since when each entry is due (`None`: not due).
    due: [Option<Instant>; N],
    /// The next period instant of each periodic entry.
    next: [Instant; N],
}

impl<const N: usize> Timetable<N> {
    /// Nothing due; every periodic entry due at `now` (its first period instant).
    pub(crate) fn new(now: Instant) -> Self {
        Timetable { due: [None; N], next: [now; N] }
    }

    /// A scan cycle starts at `now`: every read of the cycle is due. Whether any is.
    pub(crate) fn start_cycle(&mut self, scan: &[ScanEntry], now: Instant) -> bool {
        let mut any = false;
        for (e, due) in scan.iter().zip(self.due.iter_mut()) {
            if !e.function.is_write() && plan(e) == Plan::Cycle {
                due.get_or_insert(now);
                any = true;
            }
        }
        any
    }

    /// Advances to `now`: a periodic entry whose period instant has come is due (since that
    /// instant), and its next instant is one period later — or one period after `now` when that
    /// has passed too (no burst after a busy line).
    pub(crate) fn poll(&mut self, scan: &[ScanEntry], now: Instant) {
        for ((e, due), next) in scan.iter().zip(self.due.iter_mut()).zip(self.next.iter_mut()) {
            let Plan::Period(p) = plan(e) else { continue };
            if now >= *next {
                due.get_or_insert(*next);
                *next = if *next + p > now { *next + p } else { now + p };
            }
        }
    }

    /// Entry `i` is due from `now` (a triggered read), unless it already is.
    pub(crate) fn trigger(&mut self, i: usize, now: Instant) {
        if let Some(due) = self.due.get_mut(i) {
            due.get_or_insert(now);
        }
    }

    /// Entry `i` was sent (or given up): no longer due.
    pub(crate) fn sent(&mut self, i: usize) {
        if let Some(due) = self.due.get_mut(i) {
            *due = None;
        }
    }

    /// The entry to send next: the earliest due, the first in the scan list among equals; write
    /// entries only when `writes` (the outputs are valid).
    pub(crate) fn next_due(&self, scan: &[ScanEntry], writes: bool) -> Option<usize> {
        let mut best: Option<(Instant, usize)> = None;
        for (i, (e, due)) in scan.iter().zip(self.due.iter()).enumerate() {
            if let Some(at) = *due {
                if (writes || !e.function.is_write()) && best.is_none_or(|(b, _)| at < b) {
                    best = Some((at, i));
                }
            }
        }
        best.map(|(_, i)| i)
    }

    /// Whether a read of the scan cycle is still due.
    pub(crate) fn cycle_pending(&self, scan: &[ScanEntry]) -> bool {
        scan.iter()
            .zip(self.due.iter())
            .any(|(e, due)| due.is_some() && !e.function.is_write() && plan(e) == Plan::Cycle)
    }

    /// The next period instant of any periodic entry.
    pub(crate) fn poll_at(&self, scan: &[ScanEntry]) -> Option<Instant> {
        scan.iter()
            .zip(self.next.iter())
            .filter(|(e, _)| matches!(plan(e), Plan::Period(_)))
            .map(|(_, &next)| next)
            .min()
    }
}

#[cfg(test)]
mod tests;
