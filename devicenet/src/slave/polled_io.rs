//! Polled I/O (Connection instance 2; devicenet-notes §4.2, §5.2): a poll command replaces the
//! output image (a zero-length one means the master is idle) and is answered at once with the
//! input image, both fragmented above 8 bytes.

use super::{Event, SlaveNode, MAX_IO_SIZE};
use crate::fragment::io_fragments;
use crate::time::Instant;

impl SlaveNode {
    /// A frame on our Group 2 poll command identifier.
    pub(super) fn on_poll(&mut self, data: &[u8], now: Instant) {
        // A poll command in any state other than established is ignored (JB).
        if !self.poll.is_established() {
            self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
            return;
        }
        let consumed = usize::from(self.config.consumed_size);
        let mut command = [0u8; MAX_IO_SIZE];
        let len = if consumed > 8 {
            match self.poll_rx.receive(data) {
                Ok(Some(whole)) if whole.len() <= consumed => {
                    command[..whole.len()].copy_from_slice(whole);
                    whole.len()
                }
                Ok(None) => {
                    self.poll.restart_timer(now);
                    return;
                }
                Ok(Some(_)) | Err(_) => {
                    self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
                    return;
                }
            }
        } else if data.len() <= consumed {
            command[..data.len()].copy_from_slice(data);
            data.len()
        } else {
            self.stats.polls_ignored = self.stats.polls_ignored.wrapping_add(1);
            return;
        };
        self.poll.restart_timer(now);
        if len == 0 {
            self.io_idle = true;
            self.push_event(Event::Idle);
        } else {
            self.io_idle = false;
            self.output.clear();
            let _ = self.output.extend_from_slice(&command[..len]);
            self.push_event(Event::OutputReceived);
        }
        self.send_poll_response();
    }

    /// Answers at once from the input image, fragmented when the produced size exceeds 8.
    fn send_poll_response(&mut self) {
        let id = self.poll_response_id();
        let input = self.input.clone();
        if input.len() > 8 {
            for payload in io_fragments(&input) {
                self.queue_data(id, &payload);
            }
        } else {
            self.queue_data(id, &input);
        }
    }
}
