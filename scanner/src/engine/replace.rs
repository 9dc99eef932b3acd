//! The scanner's ADR step ([`crate::adr`] has the rules and the records): run between scan cycles,
//! every reconnect interval, and the duplicate MAC ID checks it watches.

use super::Scanner;
use crate::adr::{identity_key, key_matches, At63, ConfigTool, Known, Pending};
use crate::events::EventKind;
use crate::model::{AdrMode, Identity, NodeStatus};
use devicenet::explicit::{GeneralStatus, Request, ServiceCode};
use devicenet::messages::{AllocationChoice, DuplicateMacCheck};
use devicenet::objects::class;
use devicenet::slave::DUP_MAC_INTERVAL;
use devicenet::{Instant, MacId};
use harness_common::error::HarnessError;
use master_core::client::Port;
use master_core::error::MasterError;
use master_core::master::Master;

/// How long a moved device may take to come on-line at its new MAC before the scanner tries the
/// MAC anyway.
const MOVE_TIMEOUT: devicenet::Duration = devicenet::Duration::from_secs(10);

/// After a device's on-line instant, before the scanner turns to it.
const ONLINE_MARGIN: devicenet::Duration = devicenet::Duration::from_millis(5);

/// The MAC a device without a stored MAC comes up at (protocol §ADR).
pub const ADR_MAC: u8 = 63;

fn ms(from: Instant, to: Instant) -> u64 {
    (to - from).total_millis()
}

impl Scanner {
    /// Gives the scanner the tool that uploads and downloads configurations (without one, ADR
    /// recovers addresses and compares CCVs but stores no configuration).
    pub fn set_config_tool(&mut self, tool: Box<dyn ConfigTool + Send>) {
        self.adr.tool = Some(tool);
    }

    /// What ADR keeps of the node at `mac` (`None`: nothing yet, or no ADR).
    #[must_use]
    pub fn known(&self, mac: u8) -> Option<&Known> {
        self.adr.known.get(&mac)
    }

    fn event(&mut self, at: Instant, mac: u8, kind: EventKind, detail: String) {
        self.events.push(at.total_micros(), mac, kind, detail);
    }

    /// The next ADR step and bring-ups at `at` at the latest.
    fn wake(&mut self, at: Instant) {
        self.next_reconnect = Some(self.next_reconnect.map_or(at, |t| t.min(at)));
        if self.adr.wakes.len() < 64 {
            self.adr.wakes.push(at);
        }
    }

    /// When the next reconnect is due after one at `now`: `regular`, or sooner for a device
    /// coming on-line that ADR waits for.
    pub(super) fn next_reconnect_after(&mut self, now: Instant, regular: Instant) -> Instant {
        self.adr.wakes.retain(|&w| w > now);
        self.adr.wakes.iter().copied().fold(regular, Instant::min)
    }

    fn adr_wanted(&self) -> bool {
        self.nodes.iter().any(|n| !n.entry.adr.is_off())
    }

    /// A duplicate MAC ID check seen at `mac` (handle_record's hook).
    pub(super) fn adr_note_check(&mut self, mac: u8, check: &DuplicateMacCheck, at: Instant) {
        if check.response || !self.adr_wanted() {
            return;
        }
        if mac == ADR_MAC {
            if self.adr.at63.is_none_or(|a| a.serial != check.serial_number) {
                self.adr.at63 = Some(At63 { serial: check.serial_number, at, handled: false });
                let detail = format!(
                    "a device (vendor 0x{:04X}, serial 0x{:08X}) checks MAC 63",
                    check.vendor_id, check.serial_number
                );
                self.event(at, mac, EventKind::AppearedAt63, detail);
                self.wake(at + DUP_MAC_INTERVAL + DUP_MAC_INTERVAL + ONLINE_MARGIN);
            }
            return;
        }
        if let Some(p) = self.adr.pending.get_mut(&mac) {
            if p.serial == check.serial_number && !p.checked {
                p.checked = true;
                p.online = Some(at + DUP_MAC_INTERVAL + DUP_MAC_INTERVAL);
                let since = p.appeared.map(|a| format!(", {} ms after it appeared at 63", ms(a, at)));
                let detail = format!(
                    "the replacement (serial 0x{:08X}) runs its duplicate MAC ID check at MAC {mac}{}",
                    check.serial_number,
                    since.unwrap_or_default()
                );
                self.event(at, mac, EventKind::DuplicateCheck, detail);
                // On-line two intervals after its first request (protocol §7.1): brought up then.
                self.wake(at + DUP_MAC_INTERVAL + DUP_MAC_INTERVAL + ONLINE_MARGIN);
            }
        }
    }

    /// `true` while the node at `mac` is not to be brought up: a replacement moved there is
    /// still running its duplicate MAC ID check (a bring-up then would only wait out its timeout).
    pub(super) fn adr_defers(&self, mac: u8, now: Instant) -> bool {
        self.adr.pending.get(&mac).is_some_and(|p| p.appeared.is_some() && p.online.is_none_or(|o| now < o))
            && self.adr.pending.get(&mac).is_some_and(|p| p.moved_at.is_some_and(|m| now - m < MOVE_TIMEOUT))
    }

    /// Each cycle: a node with ADR that came into I/O is looked at at once ([`Scanner::adr_step`]
    /// does the rest every reconnect interval).
    pub(super) fn adr_cycle(&mut self, master: &mut Master<'_, '_>) -> Result<(), HarnessError> {
        if !self.adr_wanted() {
            return Ok(());
        }
        for i in 0..self.nodes.len() {
            self.adr_joined(master, i)?;
        }
        Ok(())
    }

    /// The ADR step: nodes joined and lost, a device at MAC 63, replacements' configurations.
    pub(super) fn adr_step(&mut self, master: &mut Master<'_, '_>, now: Instant) -> Result<(), HarnessError> {
        if !self.adr_wanted() {
            return Ok(());
        }
        for i in 0..self.nodes.len() {
            self.adr_joined(master, i)?;
        }
        let mut lost = Vec::new();
        for n in &self.nodes {
            let m = n.entry.mac;
            let gone = matches!(n.state.status, NodeStatus::TimedOut | NodeStatus::NotPresent);
            let watched = !n.entry.adr.is_off() && n.entry.enabled && self.adr.known.contains_key(&m);
            if watched && !n.in_io && gone && !self.adr.lost.contains(&m) {
                lost.push((m, n.state.detail.clone().unwrap_or_default()));
            }
        }
        for (m, why) in lost {
            self.adr.lost.insert(m);
            self.event(now, m, EventKind::NodeLost, format!("MAC {m} left I/O: {why}"));
        }
        self.adr_identical_lost(now);
        self.adr_at63(master, now)
    }

    /// Two or more lost `config+address` nodes with the same identity: address recovery is off
    /// for them (a replacement could be either), reported once per set.
    fn adr_identical_lost(&mut self, now: Instant) {
        let lost: Vec<(u8, Identity)> = self.lost_movable().into_iter().collect();
        let mut sets: Vec<Vec<u8>> = Vec::new();
        for (m, id) in &lost {
            let same: Vec<u8> =
                lost.iter().filter(|(_, o)| identity_key(o) == identity_key(id)).map(|(m, _)| *m).collect();
            if same.len() > 1 && same[0] == *m {
                sets.push(same);
            }
        }
        for set in sets {
            if self.adr.disabled.insert(set.clone()) {
                let macs: Vec<String> = set.iter().map(u8::to_string).collect();
                let detail = format!(
                    "MACs {} are lost at once and have the same identity: address recovery is off for them (a device at 63 could replace either)",
                    macs.join(", ")
                );
                self.event(now, set[0], EventKind::AdrDisabled, detail);
            }
        }
    }

    /// The lost `config+address` nodes, with the identity they had.
    fn lost_movable(&self) -> Vec<(u8, Identity)> {
        self.nodes
            .iter()
            .filter(|n| n.entry.adr == AdrMode::ConfigAddress && n.entry.enabled)
            .filter(|n| self.adr.lost.contains(&n.entry.mac) && !self.adr.pending.contains_key(&n.entry.mac))
            .filter_map(|n| self.adr.known.get(&n.entry.mac).map(|k| (n.entry.mac, k.identity.clone())))
            .collect()
    }

    /// A device on-line at MAC 63 while `config+address` nodes are lost.
    fn adr_at63(&mut self, master: &mut Master<'_, '_>, now: Instant) -> Result<(), HarnessError> {
        let Some(at63) = self.adr.at63.filter(|a| !a.handled) else { return Ok(()) };
        // On-line one interval after its second request (protocol §7.1), and a margin.
        if now < at63.at + DUP_MAC_INTERVAL + DUP_MAC_INTERVAL {
            return Ok(());
        }
        let lost = self.lost_movable();
        if lost.is_empty() {
            return Ok(());
        }
        if let Some(a) = &mut self.adr.at63 {
            a.handled = true;
        }
        let target = MacId::from_low_bits(ADR_MAC);
        let device = match read_identity(master, target) {
            Ok(d) => d,
            Err(e) => {
                let detail = format!("the device at MAC 63 could not be read: {e}");
                self.event(master.session.now(), ADR_MAC, EventKind::Failed, detail);
                return Ok(());
            }
        };
        let fits: Vec<u8> = lost
            .iter()
            .filter(|(m, had)| {
                self.nodes
                    .iter()
                    .find(|n| n.entry.mac == *m)
                    .is_some_and(|n| key_matches(&n.entry, had, &device))
            })
            .map(|(m, _)| *m)
            .collect();
        let what = describe(&device);
        let at = master.session.now();
        let mac = match fits.as_slice() {
            [] => {
                let macs: Vec<String> = lost.iter().map(|(m, _)| m.to_string()).collect();
                let detail = format!(
                    "the device at MAC 63 ({what}) matches no lost node (MAC {}): left alone",
                    macs.join(", ")
                );
                self.event(at, ADR_MAC, EventKind::KeyingMismatch, detail);
                release(master, target);
                return Ok(());
            }
            [one] => *one,
            many => {
                let macs: Vec<String> = many.iter().map(u8::to_string).collect();
                let detail = format!(
                    "the device at MAC 63 ({what}) fits MACs {}, lost at once with the same identity: address recovery is off",
                    macs.join(", ")
                );
                self.event(at, ADR_MAC, EventKind::AdrDisabled, detail);
                release(master, target);
                return Ok(());
            }
        };
        match master.set(target, class::DEVICENET, 1, 1, &[mac]) {
            Ok(_) => {}
            Err(MasterError::ErrorResponse {
                general: GeneralStatus::AttributeNotSettable, text, ..
            }) => {
                let detail = format!(
                    "the device at MAC 63 ({what}) refused MAC {mac} ({text}): its MAC is set by switches; set them to {mac}"
                );
                self.event(master.session.now(), ADR_MAC, EventKind::MoveRefused, detail);
                release(master, target);
                return Ok(());
            }
            Err(e) => {
                let detail = format!("DeviceNet object attribute 1 = {mac} at MAC 63: {e}");
                self.event(master.session.now(), ADR_MAC, EventKind::Failed, detail);
                release(master, target);
                return Ok(());
            }
        }
        let reset = Request { service: ServiceCode::Reset, class: class::IDENTITY, instance: 1, data: &[] };
        if let Err(e) = master.request_ok(target, Port::Explicit, &reset) {
            let detail = format!("Identity Reset at MAC 63 after the MAC was set: {e}");
            self.event(master.session.now(), ADR_MAC, EventKind::Failed, detail);
            release(master, target);
            return Ok(());
        }
        // The reset dropped its connections.
        master.set_held(target, AllocationChoice::empty());
        let serial = device.serial_number.unwrap_or(at63.serial);
        let moved_at = Some(master.session.now());
        self.adr
            .pending
            .insert(mac, Pending { serial, appeared: Some(at63.at), checked: false, online: None, moved_at });
        let detail = format!(
            "the device at MAC 63 ({what}) was given MAC {mac} (DeviceNet attribute 1) and reset, {} ms after it appeared",
            ms(at63.at, master.session.now())
        );
        self.event(master.session.now(), mac, EventKind::Moved, detail);
        Ok(())
    }

    /// Node `i` in I/O with ADR: stored when it first joins; a replacement (another serial
    /// number) has its CCV compared and, when it differs, the stored configuration downloaded.
    fn adr_joined(&mut self, master: &mut Master<'_, '_>, i: usize) -> Result<(), HarnessError> {
        let n = &self.nodes[i];
        if n.entry.adr.is_off() || !n.in_io || n.busy() {
            return Ok(());
        }
        let mac = n.entry.mac;
        let identity = n.state.identity.clone();
        let Some(target) = MacId::new(mac) else { return Ok(()) };
        let at = master.session.now();
        let Some(known) = self.adr.known.get(&mac).cloned() else {
            let ccv = read_ccv(master, target);
            let config = match self.adr.tool.as_mut().map(|t| t.upload(master, target)) {
                Some(Ok(c)) => Some(c),
                Some(Err(e)) => {
                    self.event(
                        at,
                        mac,
                        EventKind::Failed,
                        format!("its configuration could not be read: {e}"),
                    );
                    None
                }
                None => None,
            };
            let detail = format!(
                "{}; CCV {}; configuration {}",
                describe(&identity),
                ccv.map_or("not supported (Identity attribute 9 refused)".into(), |c| format!("0x{c:04X}")),
                config.as_ref().map_or("not stored".into(), |c| format!("stored ({} bytes)", c.len()))
            );
            self.adr.known.insert(mac, Known { identity, ccv, config });
            self.event(at, mac, EventKind::ConfigStored, detail);
            return Ok(());
        };
        let serial = identity.serial_number;
        if serial == known.identity.serial_number {
            self.adr.lost.remove(&mac);
            if let Some(p) = self.adr.pending.remove(&mac) {
                self.replaced(mac, p, master.session.now());
            }
            return Ok(());
        }
        // Another device at the MAC: a replacement.
        let pending = self.adr.pending.get(&mac).copied().unwrap_or(Pending {
            serial: serial.unwrap_or(0),
            appeared: None,
            checked: false,
            online: None,
            moved_at: None,
        });
        let ccv = read_ccv(master, target);
        let show = |c: Option<u16>| c.map_or("none".to_string(), |c| format!("0x{c:04X}"));
        let mut download = false;
        if ccv.is_some() && ccv == known.ccv {
            let detail = format!("CCV {} equals the stored one: no download", show(ccv));
            self.event(master.session.now(), mac, EventKind::CcvMatch, detail);
        } else {
            let detail = format!("CCV {}, stored {}", show(ccv), show(known.ccv));
            self.event(master.session.now(), mac, EventKind::CcvDiffers, detail);
            download = known.config.is_some();
        }
        let mut record = known.clone();
        record.identity = identity;
        if download {
            let config = known.config.clone().unwrap_or_default();
            let result = match self.adr.tool.as_mut() {
                Some(t) => t.download(master, target, &config),
                None => Ok(()),
            };
            let now = master.session.now();
            match result {
                Ok(()) => {
                    let detail = format!(
                        "the stored configuration ({} bytes) was downloaded; the device reset with it",
                        config.len()
                    );
                    self.event(now, mac, EventKind::Downloaded, detail);
                    record.ccv = read_ccv(master, target).or(known.ccv);
                    // The reset ended its connection: brought up again.
                    let n = &mut self.nodes[i];
                    n.in_io = false;
                    n.allocated = AllocationChoice::empty();
                    master.set_held(target, n.allocated);
                    n.set(
                        NodeStatus::Initializing,
                        Some("configuration downloaded: brought up again".into()),
                    );
                    self.adr.pending.insert(mac, pending);
                    self.next_reconnect = Some(now);
                }
                Err(e) => {
                    self.event(
                        now,
                        mac,
                        EventKind::Failed,
                        format!("downloading the stored configuration: {e}"),
                    );
                    self.adr.pending.remove(&mac);
                }
            }
            self.adr.known.insert(mac, record);
            return Ok(());
        }
        self.adr.known.insert(mac, record);
        self.adr.lost.remove(&mac);
        self.adr.pending.remove(&mac);
        self.replaced(mac, pending, master.session.now());
        Ok(())
    }

    fn replaced(&mut self, mac: u8, p: Pending, now: Instant) {
        let since =
            p.appeared.map_or(String::new(), |a| format!(", {} ms after it appeared at 63", ms(a, now)));
        let detail = format!("the replacement (serial 0x{:08X}) is in I/O at MAC {mac}{since}", p.serial);
        self.event(now, mac, EventKind::Replaced, detail);
    }
}

/// Identity attributes 1, 2, 3, 4, 6, 7 of the device at `target` (an explicit connection is
/// allocated first).
fn read_identity(master: &mut Master<'_, '_>, target: MacId) -> Result<Identity, MasterError> {
    master.allocate(target, Port::Group2Only, AllocationChoice::EXPLICIT)?;
    let mut id = Identity::default();
    for a in [1u8, 2, 3, 4, 6, 7] {
        let (data, _) = master.get(target, class::IDENTITY, 1, a)?;
        id.take_attribute(a, &data);
    }
    Ok(id)
}

/// Identity attribute 9, the configuration consistency value (`None`: refused or not 2 bytes).
fn read_ccv(master: &mut Master<'_, '_>, target: MacId) -> Option<u16> {
    master.get(target, class::IDENTITY, 1, 9).ok().and_then(|(d, _)| master_core::decode::u16_of(&d))
}

/// Releases the explicit connection to the device at MAC 63 (it is left alone).
fn release(master: &mut Master<'_, '_>, target: MacId) {
    let _ = master.release(target, AllocationChoice::EXPLICIT);
}

fn describe(id: &Identity) -> String {
    let hex = |v: Option<u16>| v.map_or("?".into(), |v| format!("0x{v:04X}"));
    format!(
        "vendor {}, device type {}, product code {}, revision {}, serial {}",
        hex(id.vendor_id),
        hex(id.device_type),
        id.product_code.map_or("?".into(), |v| v.to_string()),
        id.revision.as_deref().unwrap_or("?"),
        id.serial_number.map_or("?".into(), |s| format!("0x{s:08X}"))
    )
}
