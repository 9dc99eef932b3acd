//! The scanner's event log: each step of an automatic device replacement ([`crate::adr`]) and
//! each scan-list change, with the bus time, the MAC it concerns, its kind and a detail in words.
//! Shown by `scanner --json` (`events`), the console (`GET /api/events`) and MQTT.
//!
//! The log is bounded: it keeps the newest [`EVENTS_KEPT`] events; each event has a sequence
//! number, so a reader asks for what came after the last one it saw ([`EventLog::since`]).

use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// Events kept (the newest).
pub const EVENTS_KEPT: usize = 1000;

/// What happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EventKind {
    /// A node with ADR stored its identity, CCV and configuration when it joined.
    ConfigStored,
    /// A node with ADR left I/O.
    NodeLost,
    /// A device ran its duplicate MAC ID check at MAC 63.
    #[serde(rename = "appeared_at_63")]
    AppearedAt63,
    /// The device at MAC 63 was told its new MAC (DeviceNet object attribute 1) and reset.
    Moved,
    /// The device at MAC 63 refused the new MAC: its MAC is set by switches.
    MoveRefused,
    /// The device at MAC 63 matches no lost node: left alone.
    KeyingMismatch,
    /// Two or more lost nodes have the same identity: address recovery is off for them.
    AdrDisabled,
    /// The moved device ran its duplicate MAC ID check at the lost MAC.
    DuplicateCheck,
    /// The replacement's configuration consistency value equals the stored one.
    CcvMatch,
    /// The replacement's configuration consistency value differs from the stored one.
    CcvDiffers,
    /// The stored configuration was downloaded to the replacement.
    Downloaded,
    /// A step of the replacement failed (the detail says which).
    Failed,
    /// The replacement is in I/O at the lost MAC.
    Replaced,
    /// A scan-list entry was added, removed, edited, enabled or disabled.
    ListChanged,
}

impl EventKind {
    /// The kind's name (as serialized).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            EventKind::ConfigStored => "config_stored",
            EventKind::NodeLost => "node_lost",
            EventKind::AppearedAt63 => "appeared_at_63",
            EventKind::Moved => "moved",
            EventKind::MoveRefused => "move_refused",
            EventKind::KeyingMismatch => "keying_mismatch",
            EventKind::AdrDisabled => "adr_disabled",
            EventKind::DuplicateCheck => "duplicate_check",
            EventKind::CcvMatch => "ccv_match",
            EventKind::CcvDiffers => "ccv_differs",
            EventKind::Downloaded => "downloaded",
            EventKind::Failed => "failed",
            EventKind::Replaced => "replaced",
            EventKind::ListChanged => "list_changed",
        }
    }
}

/// One event.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ScanEvent {
    /// Sequence number, from 1.
    pub seq: u64,
    /// Bus time, µs.
    pub time_us: u64,
    /// The MAC it concerns.
    pub mac: u8,
    /// What happened.
    pub kind: EventKind,
    /// In words.
    pub detail: String,
}

/// The bounded log. See the [module docs](self).
#[derive(Clone, Debug, Default)]
pub struct EventLog {
    events: VecDeque<ScanEvent>,
    next_seq: u64,
}

impl EventLog {
    /// Adds an event; the oldest is forgotten beyond [`EVENTS_KEPT`].
    pub fn push(&mut self, time_us: u64, mac: u8, kind: EventKind, detail: String) {
        if self.events.len() >= EVENTS_KEPT {
            self.events.pop_front();
        }
        self.next_seq += 1;
        self.events.push_back(ScanEvent { seq: self.next_seq, time_us, mac, kind, detail });
    }

    /// The events kept, oldest first.
    #[must_use]
    pub fn all(&self) -> Vec<ScanEvent> {
        self.events.iter().cloned().collect()
    }

    /// The events after sequence number `seq`, oldest first.
    #[must_use]
    pub fn since(&self, seq: u64) -> Vec<ScanEvent> {
        self.events.iter().filter(|e| e.seq > seq).cloned().collect()
    }

    /// The events of `kind`, oldest first.
    #[must_use]
    pub fn of(&self, kind: EventKind) -> Vec<&ScanEvent> {
        self.events.iter().filter(|e| e.kind == kind).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_log_keeps_the_newest_and_numbers_them() {
        let mut log = EventLog::default();
        for i in 0..(EVENTS_KEPT as u64 + 5) {
            log.push(i, 5, EventKind::NodeLost, format!("{i}"));
        }
        let all = log.all();
        assert_eq!(all.len(), EVENTS_KEPT);
        assert_eq!(all[0].seq, 6);
        assert_eq!(all[0].detail, "5");
        assert_eq!(log.since(EVENTS_KEPT as u64 + 3).len(), 2);
    }

    #[test]
    fn kinds_serialize_as_their_names() {
        for k in [EventKind::AppearedAt63, EventKind::MoveRefused, EventKind::ListChanged] {
            assert_eq!(serde_json::to_value(k).unwrap(), serde_json::json!(k.name()));
        }
    }
}
