//! Per-unit health of a Modbus gateway ([`UnitHealth`]): which slave units answer, their
//! counters, and the optional data-valid bits in the input image.
//!
//! ## The unit table
//!
//! One row per distinct unit address of the scan list, in order of first appearance (at most
//! [`UNIT_CAPACITY`]). A row counts, wrapping:
//!
//! * **lost data**: transactions of the unit's scan entries that failed after all retries (no
//!   answer, or only corrupted ones);
//! * **retries**: repetitions sent after a timeout or a corrupted answer;
//! * **exceptions**: exception responses.
//!
//! Its [`UnitState`] at `now` is [`Lost`](UnitState::Lost) when its last transaction failed
//! after all retries or it has not answered within the stale timeout
//! ([`HealthConfig::stale_timeout_ms`](crate::serial::HealthConfig::stale_timeout_ms)),
//! [`Exception`](UnitState::Exception) when its last answer was an exception,
//! [`Ok`](UnitState::Ok) otherwise, and [`Starting`](UnitState::Starting) before its first answer
//! while the stale timeout since start-up runs. An exception is an answer: the unit is there.
//!
//! ## Data-valid bits
//!
//! With [`ModbusConfig::valid_bits_offset`] set, the input image holds one bit per scan entry
//! from that byte on: entry `k` is bit `k % 8` of byte `offset + k / 8` (LSB first), and
//! [`valid_bits_len`] bytes in all (unused high bits 0). A read entry's bit is 1 while its last
//! read succeeded and that was less than the stale timeout ago; a write entry's bit is 1 while its
//! last write succeeded and its unit has answered anything within the stale timeout. An
//! exception, or a transaction that failed after all retries, clears the bit at once. The bits are
//! refreshed as answers arrive and by [`ModbusMaster::poll`](super::ModbusMaster::poll).
//!
//! Tests: `master/tests/units.rs`, through the master and its test slave.

use super::config::{ModbusConfig, SCAN_LIST_CAPACITY};
pub use super::valid_bits::valid_bits_len;
use devicenet::{Duration, Instant};
use heapless::Vec;

/// The most units in the table: one per scan entry at most.
pub const UNIT_CAPACITY: usize = SCAN_LIST_CAPACITY;

/// A unit's state (module docs); the number is its code on the bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum UnitState {
    /// No answer yet, and the stale timeout since start-up has not run out.
    Starting = 0,
    /// Its last transaction was answered, within the stale timeout.
    Ok = 1,
    /// Its last transaction failed after all retries, or no answer within the stale timeout.
    Lost = 2,
    /// Its last answer, within the stale timeout, was an exception.
    Exception = 3,
}

impl UnitState {
    /// The state numbered `code`.
    pub fn from_code(code: u8) -> Option<UnitState> {
        [UnitState::Starting, UnitState::Ok, UnitState::Lost, UnitState::Exception]
            .get(usize::from(code))
            .copied()
    }
}

/// One row of the unit table, as read at an instant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnitRow {
    /// The unit address.
    pub unit: u8,
    /// Its state.
    pub state: UnitState,
    /// Transactions failed after all retries (wraps).
    pub lost_data: u32,
    /// Repetitions sent (wraps).
    pub retries: u32,
    /// Exception responses (wraps).
    pub exceptions: u32,
    /// Milliseconds since its last answer (saturating), `None` before the first.
    pub since_answer_ms: Option<u32>,
}

/// How a unit's last transaction ended.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Last {
    #[default]
    None,
    Answer,
    Exception,
    Lost,
}

#[derive(Clone, Copy, Debug)]
struct Unit {
    address: u8,
    last: Last,
    /// When it last answered (an exception included), if `answered`.
    answered_at: Instant,
    /// Whether it has answered since start-up (a flag beside the instant, not an `Option`: 8
    /// bytes less per unit).
    answered: bool,
    lost_data: u32,
    retries: u32,
    exceptions: u32,
}

/// The unit table and the data-valid bits of one [`ModbusMaster`](super::ModbusMaster): driven
/// by the master's transaction outcomes (module docs).
#[derive(Clone, Debug)]
pub struct UnitHealth {
    units: Vec<Unit, UNIT_CAPACITY>,
    /// Per scan entry, its row in `units`.
    entry_unit: [u8; SCAN_LIST_CAPACITY],
    /// Per scan entry, the instant its data-valid bit runs out (meaningful while set in `valid`).
    valid_until: [Instant; SCAN_LIST_CAPACITY],
    /// The data-valid bits, entry `k` bit `k`.
    valid: u16,
    /// Which entries are writes, bit `k` for entry `k`.
    writes: u16,
    entries: usize,
    bits_offset: Option<u16>,
    stale: Duration,
    started: Instant,
}

impl UnitHealth {
    /// The table for `config` (validated), started at `now`.
    pub(super) fn new(config: &ModbusConfig, now: Instant) -> Self {
        let mut units: Vec<Unit, UNIT_CAPACITY> = Vec::new();
        let mut entry_unit = [0; SCAN_LIST_CAPACITY];
        let mut writes = 0;
        for (k, (e, slot)) in config.scan.iter().zip(entry_unit.iter_mut()).enumerate() {
            let row = match units.iter().position(|u| u.address == e.unit) {
                Some(row) => row,
                None => {
                    // At most one row per entry: never full.
                    let _ = units.push(Unit {
                        address: e.unit,
                        last: Last::None,
                        answered_at: now,
                        answered: false,
                        lost_data: 0,
                        retries: 0,
                        exceptions: 0,
                    });
                    units.len() - 1
                }
            };
            *slot = row as u8;
            if e.function.is_write() {
                writes |= 1 << k;
            }
        }
        UnitHealth {
            units,
            entry_unit,
            valid_until: [now; SCAN_LIST_CAPACITY],
            valid: 0,
            writes,
            entries: config.scan.len(),
            bits_offset: config.valid_bits_offset,
            stale: config.health.stale_timeout(),
            started: now,
        }
    }

    fn unit_of(&mut self, entry: usize) -> Option<&mut Unit> {
        let row = *self.entry_unit.get(entry)?;
        self.units.get_mut(usize::from(row))
    }

    /// Entry `entry` was sent again (attempt 2 or later).
    pub(super) fn on_retry(&mut self, entry: usize) {
        if let Some(u) = self.unit_of(entry) {
            u.retries = u.retries.wrapping_add(1);
        }
    }

    /// Entry `entry` got a valid, non-exception answer at `now`.
    pub(super) fn on_answer(&mut self, entry: usize, now: Instant, input: &mut [u8]) {
        let until = now + self.stale;
        let Some(u) = self.unit_of(entry) else { return };
        u.last = Last::Answer;
        u.answered_at = now;
        u.answered = true;
        if let Some(slot) = self.valid_until.get_mut(entry) {
            *slot = until;
            self.valid |= 1 << entry;
        }
        // Its unit is there: the bits of its succeeded writes stay valid.
        let row = self.entry_unit.get(entry).copied();
        for k in 0..self.entries {
            if self.writes & self.valid & (1 << k) != 0 && self.entry_unit.get(k).copied() == row {
                if let Some(slot) = self.valid_until.get_mut(k) {
                    *slot = until;
                }
            }
        }
        self.write_bits(input);
    }

    /// Entry `entry` got an exception response at `now`.
    pub(super) fn on_exception(&mut self, entry: usize, now: Instant, input: &mut [u8]) {
        if let Some(u) = self.unit_of(entry) {
            u.last = Last::Exception;
            u.answered_at = now;
            u.answered = true;
            u.exceptions = u.exceptions.wrapping_add(1);
        }
        self.invalidate(entry, input);
    }

    /// Entry `entry`'s transaction failed after all retries.
    pub(super) fn on_lost(&mut self, entry: usize, input: &mut [u8]) {
        if let Some(u) = self.unit_of(entry) {
            u.last = Last::Lost;
            u.lost_data = u.lost_data.wrapping_add(1);
        }
        self.invalidate(entry, input);
    }

    fn invalidate(&mut self, entry: usize, input: &mut [u8]) {
        self.valid &= !(1u16.checked_shl(entry as u32).unwrap_or(0));
        self.write_bits(input);
    }

    /// Clears the bits that ran out by `now`.
    pub(super) fn poll(&mut self, now: Instant, input: &mut [u8]) {
        let expired = self
            .valid_until
            .iter()
            .enumerate()
            .filter(|&(k, &t)| self.valid & (1 << k) != 0 && now >= t)
            .fold(0u16, |m, (k, _)| m | 1 << k);
        if expired != 0 {
            self.valid &= !expired;
            self.write_bits(input);
        }
    }

    /// When a data-valid bit runs out next.
    pub(super) fn poll_at(&self) -> Option<Instant> {
        self.bits_offset?;
        self.valid_until
            .iter()
            .enumerate()
            .filter(|&(k, _)| self.valid & (1 << k) != 0)
            .map(|(_, &t)| t)
            .min()
    }

    /// Writes the data-valid bits into the input image, if configured.
    fn write_bits(&self, input: &mut [u8]) {
        let Some(offset) = self.bits_offset.map(usize::from) else { return };
        let bytes = self.valid.to_le_bytes();
        for (dst, src) in input.iter_mut().skip(offset).take(valid_bits_len(self.entries)).zip(bytes) {
            *dst = src;
        }
    }

    /// The data-valid bits, entry `k` bit `k`, as last written (configured or not).
    pub fn valid_bits(&self) -> u16 {
        self.valid
    }

    /// The number of units.
    pub fn len(&self) -> usize {
        self.units.len()
    }

    /// Whether the table is empty (never, for a validated configuration).
    pub fn is_empty(&self) -> bool {
        self.units.is_empty()
    }

    /// Row `row` (0-based, in order of first appearance in the scan list) at `now`.
    pub fn row(&self, row: usize, now: Instant) -> Option<UnitRow> {
        let u = self.units.get(row)?;
        let since = u.answered.then(|| now.saturating_duration_since(u.answered_at));
        let stale = since.is_none_or(|d| d >= self.stale);
        let state = match (u.last, u.answered) {
            (Last::Lost, _) => UnitState::Lost,
            (_, false) if now.saturating_duration_since(self.started) < self.stale => UnitState::Starting,
            _ if stale => UnitState::Lost,
            (Last::Exception, _) => UnitState::Exception,
            _ => UnitState::Ok,
        };
        Some(UnitRow {
            unit: u.address,
            state,
            lost_data: u.lost_data,
            retries: u.retries,
            exceptions: u.exceptions,
            since_answer_ms: since.map(|d| u32::try_from(d.total_millis()).unwrap_or(u32::MAX)),
        })
    }
}
