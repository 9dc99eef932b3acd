//! Scan-list changes while the scanner runs ([`ListEdit`], the console's `POST /api/scanlist/...`):
//! an entry added, edited or removed, a node enabled or disabled (maintenance). Each is an event
//! ([`crate::events::EventKind::ListChanged`]).
//!
//! An added or edited entry is checked as a scan list file's is ([`crate::list`]); an edited,
//! removed or disabled node's connections are released first. The timing computed at the start
//! (EPR, inter-scan delay) stays in force: an added node gets the same EPR. Bus and node health
//! ([`crate::health`]) follows: an added node is measured from then on, a removed one leaves the
//! statistics, a disabled one has no drop-outs counted.

use super::node::{Node, DISABLED};
use super::Scanner;
use crate::events::EventKind;
use crate::model::{ListEdit, NodeStatus, ScanEntry, ScanList};
use devicenet::messages::AllocationChoice;
use devicenet::MacId;
use harness_common::error::HarnessError;
use master_core::master::io::IoKind;
use master_core::master::Master;

/// Why a scan-list change was refused.
#[derive(Debug, thiserror::Error)]
pub enum ListEditError {
    /// Add: the MAC has an entry.
    #[error("MAC {0} is in the scan list already: edit it instead")]
    Exists(u8),
    /// Edit, remove, enable: the MAC has none.
    #[error("MAC {0} is not in the scan list")]
    Missing(u8),
    /// The entry is not one a scan list file may hold (the reason names the key).
    #[error("{0}")]
    Invalid(HarnessError),
}

impl Scanner {
    /// Carries out `edit`: checked as a scan list file's entry, connections released first, an event.
    pub fn edit(&mut self, master: &mut Master<'_, '_>, edit: ListEdit) -> Result<(), ListEditError> {
        let now = master.session.now();
        let (mac, detail) = match edit {
            ListEdit::Add(entry) => {
                let entry = self.checked(entry)?;
                let mac = entry.mac;
                if self.nodes.iter().any(|n| n.entry.mac == mac) {
                    return Err(ListEditError::Exists(mac));
                }
                let at = self.nodes.partition_point(|n| n.entry.mac < mac);
                self.nodes.insert(at, Node::new(&entry));
                self.health_follows(mac);
                (mac, format!("MAC {mac} added ({} connection)", entry.connection))
            }
            ListEdit::Edit(entry) => {
                let entry = self.checked(entry)?;
                let mac = entry.mac;
                let i = self.index(mac)?;
                self.release(master, i);
                self.nodes[i] = Node::new(&entry);
                self.health_follows(mac);
                self.adr.known.remove(&mac);
                (mac, format!("MAC {mac} edited: brought up again"))
            }
            ListEdit::Remove(mac) => {
                let i = self.index(mac)?;
                self.release(master, i);
                self.nodes.remove(i);
                self.health.untrack(mac);
                self.adr.known.remove(&mac);
                self.adr.lost.remove(&mac);
                self.adr.pending.remove(&mac);
                (mac, format!("MAC {mac} removed"))
            }
            ListEdit::Enable { mac, enabled } => {
                let i = self.index(mac)?;
                if self.nodes[i].entry.enabled == enabled {
                    return Ok(());
                }
                self.nodes[i].entry.enabled = enabled;
                self.health.set_enabled(mac, enabled);
                if enabled {
                    self.nodes[i].set(NodeStatus::Initializing, None);
                    (mac, format!("MAC {mac} enabled"))
                } else {
                    self.release(master, i);
                    self.nodes[i].set(NodeStatus::Disabled, Some(DISABLED.into()));
                    self.adr.lost.remove(&mac);
                    (mac, format!("MAC {mac} disabled (maintenance)"))
                }
            }
        };
        // Brought up at the next cycle.
        self.next_reconnect = Some(now);
        self.events.push(now.total_micros(), mac, EventKind::ListChanged, detail);
        Ok(())
    }

    /// The scan list in force, as a file holds it.
    #[must_use]
    pub fn scan_list(&self) -> ScanList {
        ScanList {
            interscan_delay_ms: None,
            expected_packet_rate_ms: None,
            nodes: self.nodes.iter().map(|n| n.entry.clone()).collect(),
        }
    }

    /// Health measures node `mac` as its entry now says (added or edited: connection, enabled).
    fn health_follows(&mut self, mac: u8) {
        if let Some(n) = self.nodes.iter().find(|n| n.entry.mac == mac) {
            self.health.track(mac, n.kind == IoKind::Strobe, n.entry.enabled);
        }
    }

    fn index(&self, mac: u8) -> Result<usize, ListEditError> {
        self.nodes.iter().position(|n| n.entry.mac == mac).ok_or(ListEditError::Missing(mac))
    }

    /// `entry` checked as a scan list file's entry is.
    fn checked(&self, entry: ScanEntry) -> Result<ScanEntry, ListEditError> {
        let one = ScanList { nodes: vec![entry], ..ScanList::default() };
        let text = crate::list::write_scan_list(&one);
        let list = crate::list::parse_scan_list_for(&text, "the entry", Some(self.state.mac))
            .map_err(ListEditError::Invalid)?;
        list.nodes.into_iter().next().ok_or(ListEditError::Missing(0))
    }

    /// Node `i` out of I/O, its connections released (a release that fails is left: the device
    /// drops them at its watchdog).
    fn release(&mut self, master: &mut Master<'_, '_>, i: usize) {
        let n = &mut self.nodes[i];
        n.engine = None;
        n.awaiting = false;
        n.in_io = false;
        if let Some(mac) = MacId::new(n.entry.mac) {
            if !n.allocated.is_empty() {
                let _ = master.release(mac, n.allocated);
            }
            master.set_held(mac, AllocationChoice::empty());
        }
        n.allocated = AllocationChoice::empty();
    }
}
