//! Bit-strobe I/O (Connection instance 3; protocol §II.1, docs/src/reference/io-connections.md): the
//! owning master's 8-byte strobe command carries one bit per MAC ID; the node keeps its own bit and
//! answers every strobe at once with the first bytes of its input image, never fragmented.

use super::{strobe_produced_size, SlaveNode};
use crate::id::{Group1MessageId, Identifier};
use crate::time::Instant;

impl SlaveNode {
    /// A bit-strobe command from the owning master (the caller checked the source MAC).
    #[inline(never)]
    pub(super) fn on_strobe(&mut self, data: &[u8], now: Instant) {
        // Only an established connection consumes, and only the whole 8-byte command: anything
        // else is ignored, the safe choice of §II.1.2 (UNCONFIRMED).
        // MAC n is byte n / 8, bit n % 8 (NI, DELTA; §II.1.2).
        let mac = self.config.mac_id.as_raw();
        let (true, 8, Some(byte)) =
            (self.strobe.is_established(), data.len(), data.get(usize::from(mac / 8)))
        else {
            self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
            return;
        };
        self.strobe_bit = byte >> (mac % 8) & 1 != 0;
        self.strobe.restart_timer(now);
        // Every strobe is answered, whatever the bit (NI, §II.1.3), with at most 8 input bytes.
        // The input image is the produced size, so it holds the response's bytes.
        let n = usize::from(strobe_produced_size(self.config.produced_size));
        let id = Identifier::group1(Group1MessageId::BIT_STROBE_RESPONSE, self.config.mac_id);
        let SlaveNode { input, tx, stats, .. } = self;
        super::queue_into(tx, stats, id, input.get(..n).unwrap_or(&[]));
    }
}
