//! Shared helpers of the fuzz targets (`fuzz_targets/`): the input formats ([`steps`]) and the
//! checks every target makes on the protocol core's outputs.
//!
//! | target | what it feeds | what it checks besides "no panic" |
//! |---|---|---|
//! | `slave_node` | the group-2-only node: frames with time steps, bus-off | only the node's own identifiers are sent (protocol §8); after `handle_timeout(now)` the next deadline is later than `now` (no busy loop); queues stay within their capacity |
//! | `converter` | the converter: frames, serial bytes from the instrument, time steps, bus-off | the same, plus the serial output stays within a frame |
//! | `explicit_reassembly` | the explicit reassembler with any frames; the transmitter with any acks; a round trip | the reassembled message never exceeds its capacity; a message sent through transmitter and reassembler comes out whole |
//! | `io_reassembly` | the I/O reassembler with any frames; a round trip | the same for I/O fragmentation |
//! | `framed_parser` | the breaker's framing and any framing configuration with any bytes | frames are within `max_len`; a parsed frame re-encodes and parses to the same data |
//! | `modbus_codec` | the Modbus RTU request and response parsers | what parses re-emits to the same bytes |
//! | `eds_parse` | the EDS parser and checker | — |
//! | `candump_log` | the `candump -L` parser and the DeviceNet decoder | what parses formats and re-parses to the same frames |

pub mod steps;

use devicenet::{CanFrame, CanId, MacId};

/// The identifiers a group-2-only slave at `mac` may send (protocol §8, §II.1-§II.6): its explicit
/// response (heartbeat and shutdown included), its poll, bit-strobe and COS/cyclic responses, its
/// duplicate MAC ID check, and the Offline Connection Set's responses.
pub fn slave_may_send(mac: MacId, id: CanId) -> bool {
    use devicenet::id::{Group1MessageId, Group4MessageId};
    use devicenet::{Group2Message, Identifier};
    id == Identifier::group2(mac, Group2Message::ExplicitResponse)
        || id == Identifier::group2(mac, Group2Message::DuplicateMacCheck)
        || id == Identifier::group1(Group1MessageId::POLL_RESPONSE, mac)
        || id == Identifier::group1(Group1MessageId::BIT_STROBE_RESPONSE, mac)
        || id == Identifier::group1(Group1MessageId::COS_CYCLIC, mac)
        // The Offline Connection Set's responses (a faulted node, protocol §II.6).
        || id == Identifier::Group4 { message: Group4MessageId::COMM_FAULTED_RESPONSE }.encode()
        || id == Identifier::Group4 { message: Group4MessageId::OFFLINE_OWNERSHIP_RESPONSE }.encode()
}

/// A CAN frame from fuzz input: the identifier masked to 11 bits, at most 8 bytes.
pub fn frame(id: u16, data: &[u8]) -> Option<CanFrame> {
    CanFrame::from_raw(id & 0x7FF, &data[..data.len().min(8)]).ok()
}
