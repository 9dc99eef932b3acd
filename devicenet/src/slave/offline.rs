//! The Offline Connection Set (Group 4; protocol §3.8, §7.4, §II.6,
//! docs/src/reference/io-connections.md): a node in Communication Faulted after a duplicate MAC ID
//! answers Who
//! and Identify, accepts an offline owner, and takes a new MAC ID, after which it runs the
//! duplicate MAC ID check again at that MAC (DR).
//!
//! An on-line node, and a node faulted by bus-off (it is off the bus), ignore Group 4 (UNCONFIRMED,
//! II.8 item 7).

use super::{Event, FaultReason, NetworkState, SlaveNode};
use crate::id::{Group4MessageId, Identifier, MacId};
use crate::messages::DeviceKey;
use crate::time::{Duration, Instant};

/// What the Offline Connection Set of a faulted node holds.
#[derive(Clone, Copy, Debug)]
pub(super) struct Offline {
    /// The answer to the tool that took offline ownership: its request (MAC ID, vendor and serial
    /// number as sent) with CB for 4B.
    owner: Option<[u8; 8]>,
    /// When the answer to a Who is due ([`Instant::MAX`]: none).
    pub(super) answer_at: Instant,
    /// An Identify was accepted: the Network Status LED flashes red/green.
    pub(super) identified: bool,
}

impl Offline {
    pub(super) const fn new() -> Offline {
        Offline { owner: None, answer_at: Instant::MAX, identified: false }
    }
}

impl SlaveNode {
    /// A Group 4 frame. The requests are matched byte by byte in place of
    /// [`OfflineMessage::parse`](crate::messages::OfflineMessage::parse) (the same layouts, §II.6:
    /// the firmware's flash budget); anything else is ignored.
    #[inline(never)]
    pub(super) fn on_offline(&mut self, message: Group4MessageId, data: &[u8], now: Instant) {
        if !matches!(self.network, NetworkState::CommunicationFaulted(FaultReason::DuplicateMacId)) {
            return;
        }
        // Our vendor and serial number, as in the answer to Who.
        let answer = self.who_answer();
        let own = &answer[1..];
        let request = message == Group4MessageId::COMM_FAULTED_REQUEST;
        match data {
            // Who: `[0,match,value] 4B <time-delay offset>`.
            &[selector, 0x4B, offset] if request && self.selected(selector) => {
                // Each answer waits byte `offset` of itself in milliseconds, which spreads the
                // answers of several faulted nodes (§II.6, an inference: UNCONFIRMED).
                let delay = answer.get(usize::from(offset)).copied().unwrap_or(0);
                self.offline.answer_at = now + Duration::from_millis(u64::from(delay));
            }
            // Identify, short `[0,match,value] 4C`, or long `3F 4C <vendor> <serial>` for us.
            &[selector, 0x4C] if request && self.selected(selector) => self.identify(selector),
            [0x3F, 0x4C, key @ ..] if request && key == own => self.identify(0x3F),
            // Change MAC ID, `<new MAC> 4D <vendor> <serial>` for us: the new MAC is taken at once
            // and reported, to be stored like a network-set one; then the duplicate MAC ID check
            // runs again there (DR, §II.6).
            [new, 0x4D, key @ ..] if request && key == own => {
                let Some(mac) = MacId::new(*new) else { return };
                self.config.mac_id = mac;
                self.pending_mac = mac;
                self.offline = Offline::new();
                self.push_event(Event::MacIdChanged(mac));
                self.start_duplicate_mac_check(now);
            }
            // Offline ownership, `<client MAC> 4B <client vendor> <client serial>` on 0x7EF: the
            // request echoed with CB, so every faulted node sends the same frame and the answers
            // cannot collide (docs/src/reference/io-connections.md; who answers is UNCONFIRMED). A
            // second client
            // is not answered while the first holds it.
            &[client @ 0..=63, 0x4B, k0, k1, k2, k3, k4, k5]
                if message == Group4MessageId::OFFLINE_OWNERSHIP_REQUEST =>
            {
                let answer = [client, 0xCB, k0, k1, k2, k3, k4, k5];
                if self.offline.owner.is_none_or(|owner| owner == answer) {
                    self.offline.owner = Some(answer);
                    self.offline_send(Group4MessageId::OFFLINE_OWNERSHIP_RESPONSE, &answer);
                }
            }
            _ => {}
        }
    }

    /// Answers an Identify (`[selector] CC`) and flashes the Network Status LED red/green.
    fn identify(&mut self, selector: u8) {
        self.offline_send(Group4MessageId::COMM_FAULTED_RESPONSE, &[selector, 0xCC]);
        self.offline.identified = true;
    }

    /// Sends the answer to a Who when it is due, if the node is still faulted.
    pub(super) fn step_offline(&mut self, now: Instant) {
        if now >= self.offline.answer_at {
            self.offline.answer_at = Instant::MAX;
            if matches!(self.network, NetworkState::CommunicationFaulted(_)) {
                let answer = self.who_answer();
                self.offline_send(Group4MessageId::COMM_FAULTED_RESPONSE, &answer);
            }
        }
    }

    /// The answer to Who: `<port> <vendor LE16> <serial LE32>`, our device key after the port.
    // Out of line: one copy for the Who's answer and the key compares (firmware size).
    #[inline(never)]
    fn who_answer(&self) -> [u8; 7] {
        let id = &self.config.identity;
        let key = DeviceKey { vendor_id: id.vendor_id, serial_number: id.serial_number }.to_bytes();
        let mut answer = [0u8; 7];
        answer[0] = self.config.port;
        answer[1..].copy_from_slice(&key);
        answer
    }

    /// Whether the selector byte `[0, match, value]` selects this node: match bit set, the value
    /// is the MAC ID; clear, the value is a mask and `MAC & !mask == 0` (0x3F selects every node,
    /// ICP's `3F 4B 02`). AN's reading; the arithmetic is UNCONFIRMED (§II.6). Bit 7 is reserved
    /// and must be 0.
    fn selected(&self, selector: u8) -> bool {
        let mac = self.config.mac_id.as_raw();
        let value = selector & 0x3F;
        match selector & 0xC0 {
            0x40 => mac == value,
            0x00 => mac & !value == 0,
            _ => false,
        }
    }

    /// Queues `data` on Group 4 message `message`.
    fn offline_send(&mut self, message: Group4MessageId, data: &[u8]) {
        self.queue_data(Identifier::Group4 { message }.encode(), data);
    }
}
