//! The Offline Connection Set (Group 4; devicenet-notes §3.8, §7.4, §II.6,
//! docs/io-connections.md): a node in Communication Faulted after a duplicate MAC ID answers Who
//! and Identify, accepts an offline owner, and takes a new MAC ID, after which it runs the
//! duplicate MAC ID check again at that MAC (DR).
//!
//! An on-line node, and a node faulted by bus-off (it is off the bus), ignore Group 4 (UNCONFIRMED,
//! II.8 item 7).

use super::{Event, FaultReason, NetworkState, SlaveNode};
use crate::id::{Group4MessageId, Identifier, MacId};
use crate::messages::{DeviceKey, FaultedSelector, OfflineMessage};
use crate::time::{Duration, Instant};

/// What the Offline Connection Set of a faulted node holds.
#[derive(Clone, Copy, Debug)]
pub(super) struct Offline {
    /// The tool that took offline ownership (its MAC ID and key).
    owner: Option<(MacId, DeviceKey)>,
    /// When the answer to a Who is due.
    pub(super) answer_at: Option<Instant>,
    /// An Identify was accepted: the Network Status LED flashes red/green.
    pub(super) identified: bool,
}

impl Offline {
    pub(super) const fn new() -> Offline {
        Offline { owner: None, answer_at: None, identified: false }
    }
}

impl SlaveNode {
    /// A Group 4 frame.
    pub(super) fn on_offline(&mut self, message: Group4MessageId, data: &[u8], now: Instant) {
        if self.network != NetworkState::CommunicationFaulted(FaultReason::DuplicateMacId) {
            return;
        }
        let Ok(request) = OfflineMessage::parse(message, data) else { return };
        let own = self.device_key();
        match request {
            OfflineMessage::WhoRequest { selector, time_delay_offset } if self.selected(selector) => {
                // Each answer waits byte `offset` of itself in milliseconds, which spreads the
                // answers of several faulted nodes (§II.6, an inference: UNCONFIRMED).
                let answer = self.who_answer();
                let delay = answer.get(usize::from(time_delay_offset)).copied().unwrap_or(0);
                self.offline.answer_at = Some(now + Duration::from_millis(u64::from(delay)));
            }
            OfflineMessage::IdentifyRequest { selector, device }
                if device.map_or(self.selected(selector), |d| d == own) =>
            {
                let answer = [selector.to_byte(), 0xCC];
                self.offline_send(Group4MessageId::COMM_FAULTED_RESPONSE, &answer);
                self.offline.identified = true;
            }
            OfflineMessage::ChangeMacIdRequest { new_mac, device } if device == own => {
                // The new MAC is taken at once and reported, to be stored like a network-set one;
                // then the duplicate MAC ID check runs again there (DR, §II.6).
                self.config.mac_id = new_mac;
                self.pending_mac = new_mac;
                self.offline = Offline::new();
                self.push_event(Event::MacIdChanged(new_mac));
                self.start_duplicate_mac_check(now);
            }
            OfflineMessage::OwnershipRequest { client, device }
                if self.offline.owner.is_none_or(|owner| owner == (client, device)) =>
            {
                // The request echoed: every faulted node sends the same frame, so the answers
                // cannot collide (docs/io-connections.md; who answers is UNCONFIRMED).
                self.offline.owner = Some((client, device));
                let mut answer = [0u8; 8];
                answer[0] = client.as_raw();
                answer[1] = 0xCB;
                answer[2..].copy_from_slice(&device.to_bytes());
                self.offline_send(Group4MessageId::OFFLINE_OWNERSHIP_RESPONSE, &answer);
            }
            _ => {}
        }
    }

    /// Sends the answer to a Who when it is due, if the node is still faulted.
    pub(super) fn step_offline(&mut self, now: Instant) {
        if self.offline.answer_at.is_some_and(|at| now >= at) {
            self.offline.answer_at = None;
            if matches!(self.network, NetworkState::CommunicationFaulted(_)) {
                let answer = self.who_answer();
                self.offline_send(Group4MessageId::COMM_FAULTED_RESPONSE, &answer);
            }
        }
    }

    /// Our vendor ID and serial number.
    fn device_key(&self) -> DeviceKey {
        let id = &self.config.identity;
        DeviceKey { vendor_id: id.vendor_id, serial_number: id.serial_number }
    }

    /// The answer to Who: `<port> <vendor LE16> <serial LE32>`.
    fn who_answer(&self) -> [u8; 7] {
        let mut answer = [0u8; 7];
        answer[0] = self.config.port;
        answer[1..].copy_from_slice(&self.device_key().to_bytes());
        answer
    }

    /// Whether `selector` selects this node: match bit set, the value is the MAC ID; clear, the
    /// value is a mask and `MAC & !mask == 0` (0x3F selects every node, ICP's `3F 4B 02`). AN's
    /// reading; the arithmetic is UNCONFIRMED (§II.6).
    fn selected(&self, selector: FaultedSelector) -> bool {
        let mac = self.config.mac_id.as_raw();
        if selector.match_flag {
            mac == selector.value
        } else {
            mac & !selector.value == 0
        }
    }

    /// Queues `data` on Group 4 message `message`.
    fn offline_send(&mut self, message: Group4MessageId, data: &[u8]) {
        self.queue_data(Identifier::Group4 { message }.encode(), data);
    }
}
