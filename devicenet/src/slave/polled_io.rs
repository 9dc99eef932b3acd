//! Polled I/O (Connection instance 2; protocol §4.2, §5.2): a poll command replaces the
//! output image (a zero-length one means the master is idle) and is answered at once with the
//! input image, both fragmented above 8 bytes.
//!
//! When change of state or cyclic is allocated without poll, Connection 2 consumes the master's
//! COS/cyclic data on the same identifier instead, and answers it with a zero-length
//! acknowledgement, or nothing under acknowledge suppression (§II.2.1, §II.2.5).

use super::{Event, SlaveNode};
use crate::fragment::{FragmentByte, FragmentKind, IO_FRAGMENT_DATA};
use crate::frame::CanId;
use crate::messages::AllocationChoice;
use crate::time::Instant;

impl SlaveNode {
    /// A frame on our Group 2 poll command identifier.
    // Out of line: inlined into `handle_frame_with` the firmware's flash is some 25 bytes larger.
    #[inline(never)]
    pub(super) fn on_poll(&mut self, data: &[u8], now: Instant) {
        // A poll command in any state other than established is ignored (JB).
        if !self.poll.is_established() {
            self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
            return;
        }
        let consumed = usize::from(self.config.consumed_size);
        // The command is read in place (from the frame or the reassembler) and copied into the
        // output image only when it is accepted and not empty. validate() bounds the consumed
        // size by MAX_IO_SIZE, so an accepted command always fits.
        let command = if consumed > 8 {
            match self.poll_rx.receive(data) {
                Ok(Some(whole)) if whole.len() <= consumed => Some(whole),
                Ok(None) => {
                    self.poll.restart_timer(now);
                    return;
                }
                Ok(Some(_)) | Err(_) => None,
            }
        } else if data.len() <= consumed {
            Some(data)
        } else {
            None
        };
        let Some(command) = command else {
            self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
            return;
        };
        let idle = command.is_empty();
        if !idle {
            self.output.clear();
            let _ = self.output.extend_from_slice(command);
        }
        self.poll.restart_timer(now);
        self.io_idle = idle;
        self.push_event(if idle { Event::Idle } else { Event::OutputReceived });
        let id = self.poll_response_id();
        if self.allocation.contains(AllocationChoice::POLL) {
            self.send_input(id);
        } else if !self.ack_suppressed() {
            // The master's COS/cyclic data, acknowledged with a zero-length frame; it also keeps
            // Connection 4 alive (docs/src/reference/io-connections.md).
            self.queue_data(id, &[]);
            self.cos.restart_timer(now);
        }
    }

    /// Sends the input image on `id` at once, fragmented when the produced size exceeds 8 (notes
    /// §4.2): a poll response or a COS/cyclic production.
    pub(super) fn send_input(&mut self, id: CanId) {
        // The frames go to the queue while the image is read in place (no copy of it).
        let SlaveNode { input, tx, stats, .. } = self;
        if input.len() <= 8 {
            super::queue_into(tx, stats, id, input);
            return;
        }
        // The frames of `io_fragments` (test: `fragments_as_io_fragments`), each written into one
        // frame buffer, not built as a `Payload` and copied (firmware size). At most
        // MAX_IO_SIZE / 7 fragments, so the count never wraps.
        let last = (input.len() - 1) / IO_FRAGMENT_DATA;
        for (i, chunk) in input.chunks(IO_FRAGMENT_DATA).enumerate() {
            let kind = match i {
                0 => FragmentKind::First,
                _ if i == last => FragmentKind::Last,
                _ => FragmentKind::Middle,
            };
            let mut frame = [FragmentByte { kind, count: i as u8 }.to_byte(), 0, 0, 0, 0, 0, 0, 0];
            // A chunk holds at most 7 bytes, so it always fits after the fragment byte.
            let Some(data) = frame.get_mut(1..=chunk.len()) else { return };
            data.copy_from_slice(chunk);
            super::queue_into(tx, stats, id, frame.get(..=chunk.len()).unwrap_or(&[]));
        }
    }
}
