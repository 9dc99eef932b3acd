//! The explicit messaging connection (Connection instance 1; protocol §3.1, §4.1): only
//! the owning master may use it, every message consumed restarts its watchdog, fragmented
//! requests are reassembled and long responses are sent in acknowledged fragments.
//!
//! A whole request goes to the Message Router ([`objects`](super::objects)), which answers it.
//! Requests on the Group 2 Only port are served and answered by the same code, restricted to
//! Allocate and Release ([`Port`]).

use super::{ConnectionState, ObjectHandler, Reply, ServiceError, SlaveNode, MAX_EXPLICIT_SIZE};
use crate::explicit::{
    additional, split_message, BodyFormat, ExplicitError, GeneralStatus, Header, Request, ServiceCode,
};
use crate::fragment::{ExplicitReceive, FragmentByte, FragmentKind};
use crate::time::Instant;

/// Where a request came in, which decides the services it may ask for.
pub(super) enum Port<'h, H> {
    /// The explicit connection: every object; classes the core lacks go to the handler.
    Explicit(&'h mut H),
    /// The Group 2 Only Unconnected Explicit Request port: Allocate and Release only (protocol §3.4).
    Group2Only,
}

impl SlaveNode {
    /// A frame on our Group 2 explicit request identifier.
    pub(super) fn on_explicit<H: ObjectHandler>(&mut self, data: &[u8], now: Instant, objects: &mut H) {
        let Some(&first) = data.first() else { return };
        let header = Header::from_byte(first);
        let live =
            matches!(self.explicit.state, ConnectionState::Established | ConnectionState::DeferredDelete);
        // Only the owning master may use the explicit connection (protocol §8, JB).
        if !live || Some(header.mac) != self.master || data.len() < 2 {
            self.stats.explicit_ignored = self.stats.explicit_ignored.wrapping_add(1);
            return;
        }
        // Any message consumed restarts the inactivity timer; deferred delete -> established.
        self.explicit.state = ConnectionState::Established;
        self.explicit.restart_timer(now);
        let id = self.response_id();
        if header.fragmented {
            // `data` holds at least the header and the fragmentation byte (checked above).
            if data.get(1).is_some_and(|&b| FragmentByte::from_byte(b).kind == FragmentKind::Ack) {
                self.explicit_tx.handle_ack(data, now);
                self.pump_explicit(now);
                return;
            }
            // Matched by reference: the ack is queued from where `receive` left it, not moved
            // (firmware size).
            match &self.explicit_rx.receive(data) {
                ExplicitReceive::Ack(ack)
                | ExplicitReceive::Duplicate(ack)
                | ExplicitReceive::Rejected(ack) => {
                    self.queue_data(id, ack);
                }
                ExplicitReceive::Complete(ack) => {
                    self.queue_data(id, ack);
                    // A copy, so the request can be served while the reassembler keeps its state;
                    // the reassembler holds at most MAX_EXPLICIT_SIZE bytes, so it always fits.
                    // A plain array, not a heapless::Vec moved into place (firmware size).
                    let whole = self.explicit_rx.message();
                    let mut copy = [0u8; MAX_EXPLICIT_SIZE];
                    let Some(message) = copy.get_mut(..whole.len()) else { return };
                    message.copy_from_slice(whole);
                    // The reassembler keeps its last answer (not reset here): a repeat of the last
                    // fragment, whose ack the master missed, is acknowledged again and the request
                    // is not served twice (protocol §4.1, JB; found by the conformance suite).
                    self.serve(message, now, Port::Explicit(objects));
                }
                ExplicitReceive::Ignored(_) => {
                    self.stats.explicit_ignored = self.stats.explicit_ignored.wrapping_add(1);
                }
            }
        } else {
            // An unfragmented request resets both directions' fragmentation (JB, protocol §4.1).
            self.explicit_rx.reset();
            self.explicit_tx.reset();
            self.serve(data, now, Port::Explicit(objects));
        }
    }

    /// Serves one whole explicit request message (header + body) that came in on `port`, and
    /// queues the response.
    pub(super) fn serve<H: ObjectHandler>(&mut self, message: &[u8], now: Instant, port: Port<'_, H>) {
        let Ok((header, body)) = split_message(message) else { return };
        let Some(&service_byte) = body.first() else { return };
        let service = ServiceCode::from(service_byte);
        let mut out = [0u8; MAX_EXPLICIT_SIZE];
        out[0] = Header::new(header.xid, header.mac).to_byte();
        let result = match Request::parse(body, BodyFormat::Class8Instance8) {
            Ok(req) => {
                let mut reply = Reply::new(&mut out[2..]);
                let r = match port {
                    Port::Explicit(objects) => self.dispatch(&req, &mut reply, now, objects),
                    Port::Group2Only => self.group2_only_service(&req, header.mac, &mut reply, now),
                };
                r.map(|()| reply.len())
            }
            Err(ExplicitError::NotARequest) => {
                self.stats.explicit_ignored = self.stats.explicit_ignored.wrapping_add(1);
                return;
            }
            Err(_) => Err(match port {
                Port::Group2Only => group2_only_truncated(service),
                Port::Explicit(_) => ServiceError::NOT_ENOUGH_DATA,
            }),
        };
        let len = match result {
            Ok(n) => {
                out[1] = 0x80 | service.as_raw();
                2 + n
            }
            Err(e) => {
                out[1] = 0x80 | ServiceCode::ErrorResponse.as_raw();
                out[2] = e.general.as_raw();
                out[3] = e.additional;
                4
            }
        };
        // The reply is bounded by `out`, so the response always fits.
        let Some(response) = out.get(..len) else { return };
        if len <= 8 {
            let id = self.response_id();
            self.queue_data(id, response);
        } else if self.explicit_tx.start(response, now).is_ok() {
            self.pump_explicit(now);
        }
        self.send_pending_shutdown();
    }

    /// Queues the explicit fragment due at `now`: one at most, as the next waits for its ack or
    /// the ack timeout one second on (firmware size: no loop; the two differ only at
    /// `Instant::MAX`, where the saturated ack deadline made a loop re-send at once).
    pub(super) fn pump_explicit(&mut self, now: Instant) {
        let id = self.response_id();
        if let Some(payload) = self.explicit_tx.poll_transmit(now) {
            self.queue_data(id, &payload);
        }
    }
}

/// The error for a request on the Group 2 Only port too short to parse: 0x13 for Allocate and
/// Release, else that of any other service (protocol §3.4).
fn group2_only_truncated(service: ServiceCode) -> ServiceError {
    match service {
        ServiceCode::AllocateMasterSlave | ServiceCode::ReleaseMasterSlave => ServiceError::NOT_ENOUGH_DATA,
        _ => invalid_group2_only_request(),
    }
}

/// Any service but Allocate/Release on the Group 2 Only port: 0x02 / 0x03 (JB, protocol §3.4 and
/// §9.6).
// Out of line: the constant built at each of its uses costs some 15 bytes of flash.
#[inline(never)]
pub(super) fn invalid_group2_only_request() -> ServiceError {
    ServiceError::with_additional(GeneralStatus::ResourceUnavailable, additional::INVALID_GROUP2_ONLY_REQUEST)
}
