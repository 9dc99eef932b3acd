//! The texts of the messages outside the predefined connection set: UCMM requests and responses
//! (protocol §3.6), the Offline Connection Set (§3.8, §II.6), heartbeat and shutdown (§3.7).

use super::{body_format_text, error_text, hex};
use devicenet::explicit::Response;
use devicenet::id::{Group3MessageId, Group4MessageId};
use devicenet::messages::{
    GroupSelect, OfflineMessage, UcmmCloseRequest, UcmmCloseResponse, UcmmOpenRequest, UcmmOpenResponse,
};

pub(super) fn group3(message: Group3MessageId, source: u8, data: &[u8]) -> String {
    match message {
        Group3MessageId::UNCONNECTED_REQUEST => match data.get(1) {
            Some(0x4B) => match UcmmOpenRequest::parse(data) {
                Ok(r) => format!(
                    "UCMM Open Explicit Messaging Connection request from MAC {source} to MAC {}: body format {}, group select {}, source message ID {}",
                    r.destination,
                    body_format_text(r.body_format),
                    group_select_text(r.group_select),
                    r.source_message_id
                ),
                Err(e) => format!("malformed UCMM open request from MAC {source} ({e}): {}", hex(data)),
            },
            Some(0x4C) => match UcmmCloseRequest::parse(data) {
                Ok(r) => format!(
                    "UCMM Close Connection request from MAC {source} to MAC {}: connection instance {}",
                    r.destination, r.connection_instance
                ),
                Err(e) => format!("malformed UCMM close request from MAC {source} ({e}): {}", hex(data)),
            },
            _ => format!("UCMM request from MAC {source}: {}", hex(data)),
        },
        Group3MessageId::UNCONNECTED_RESPONSE => match data.get(1) {
            Some(0xCB) => match UcmmOpenResponse::parse(data) {
                Ok(r) => format!(
                    "UCMM Open response from MAC {source} to MAC {}: body format {}, connection instance {}",
                    r.destination,
                    body_format_text(r.body_format),
                    r.connection_instance
                ),
                Err(e) => format!("malformed UCMM open response from MAC {source} ({e}): {}", hex(data)),
            },
            Some(0xCC) => match UcmmCloseResponse::parse(data) {
                Ok(r) => format!("UCMM Close response from MAC {source} to MAC {}", r.destination),
                Err(e) => format!("malformed UCMM close response from MAC {source} ({e}): {}", hex(data)),
            },
            Some(0x94) => match Response::parse(&data[1..]) {
                Ok(Response::Error { general, additional }) => {
                    format!("UCMM error response from MAC {source}: {}", error_text(general, additional))
                }
                _ => format!("UCMM response from MAC {source}: {}", hex(data)),
            },
            _ => format!("UCMM response from MAC {source}: {}", hex(data)),
        },
        _ => format!("G3 message {} from MAC {source} (dynamic connection): {}", message.as_raw(), hex(data)),
    }
}

pub(super) fn group_select_text(g: GroupSelect) -> String {
    match g {
        GroupSelect::Group1 => "group 1".into(),
        GroupSelect::Group2 => "group 2".into(),
        GroupSelect::Group3 => "group 3".into(),
        GroupSelect::NodePing => "node ping".into(),
        GroupSelect::Reserved(n) => format!("reserved ({n})"),
    }
}

/// A Communication Faulted selector byte in words (protocol §3.8, §II.6: match bit 1 = exact MAC
/// ID, 0 = MAC ID mask on the value; the arithmetic is UNCONFIRMED, so both are shown as sent).
pub(super) fn selector_text(s: devicenet::messages::FaultedSelector) -> String {
    format!(
        "match {} ({}), value {}",
        u8::from(s.match_flag),
        if s.match_flag { "exact MAC ID" } else { "mask" },
        s.value
    )
}

pub(super) fn device_text(d: &devicenet::messages::DeviceKey) -> String {
    format!("vendor 0x{:04X}, serial 0x{:08X}", d.vendor_id, d.serial_number)
}

/// A Group 4 message with every field (protocol §3.8, §II.6).
pub(super) fn group4(message: Group4MessageId, data: &[u8]) -> String {
    const SET: &str = "Offline Connection Set:";
    match OfflineMessage::parse(message, data) {
        Ok(OfflineMessage::WhoRequest { selector, time_delay_offset }) => format!(
            "{SET} Who request ({}), time-delay byte offset {time_delay_offset}",
            selector_text(selector)
        ),
        Ok(OfflineMessage::WhoResponse { port, device }) => {
            format!("{SET} Who response from a faulted node: port {port}, {}", device_text(&device))
        }
        Ok(OfflineMessage::IdentifyRequest { selector, device: Some(d) }) => format!(
            "{SET} Identify request, point-to-point ({}): {}",
            selector_text(selector),
            device_text(&d)
        ),
        Ok(OfflineMessage::IdentifyRequest { selector, device: None }) => {
            format!("{SET} Identify request, multicast ({})", selector_text(selector))
        }
        Ok(OfflineMessage::IdentifyResponse { selector }) => {
            format!("{SET} Identify response ({})", selector_text(selector))
        }
        Ok(OfflineMessage::ChangeMacIdRequest { new_mac, device }) => {
            format!("{SET} Change MAC ID to {new_mac} for {}", device_text(&device))
        }
        Ok(OfflineMessage::OwnershipRequest { client, device }) => {
            format!("{SET} ownership request from tool MAC {client}: {}", device_text(&device))
        }
        Ok(OfflineMessage::OwnershipResponse { client, device }) => {
            format!("{SET} ownership response to tool MAC {client}: {}", device_text(&device))
        }
        Err(e) => format!("G4 message 0x{:02X}: {} ({e})", message.as_raw(), hex(data)),
    }
}

/// A heartbeat or shutdown message (protocol §3.7, §II.5: a response on the device's explicit
/// response identifier, header MAC = its own, exactly 8 bytes), if `body` is one; `None` for any
/// other response.
pub(super) fn broadcast_text(mac: u8, header_mac: u8, data: &[u8]) -> Option<String> {
    let body = data.get(1..)?;
    let (name, fields) = match body {
        [0xCD, il, ih, state, flags, cl, ch] => {
            let state_name = match state {
                0 => "non-existent",
                1 => "self-testing",
                2 => "standby",
                3 => "operational",
                4 => "major recoverable fault",
                5 => "major unrecoverable fault",
                _ => "unknown state",
            };
            let named = [
                (0x01, "DF device fault"),
                (0x02, "UF user fault"),
                (0x04, "SF system fault"),
                (0x08, "EV event"),
            ];
            let set: Vec<&str> = named.iter().filter(|(b, _)| flags & b != 0).map(|(_, n)| *n).collect();
            let reserved = if flags & 0xF0 != 0 {
                format!(", reserved bits 0x{:02X} set", flags & 0xF0)
            } else {
                String::new()
            };
            (
                "Device Heartbeat",
                format!(
                    "Identity instance {}, state {state} ({state_name}), flags 0x{flags:02X} ({}){reserved}, configuration consistency value 0x{:04X}",
                    u16::from_le_bytes([*il, *ih]),
                    if set.is_empty() { "none".to_string() } else { set.join(", ") },
                    u16::from_le_bytes([*cl, *ch])
                ),
            )
        }
        [0xCE, cl, ch, il, ih, kl, kh] => (
            "Device Shutdown",
            format!(
                "class 0x{:04X} instance {} code 0x{:04X}",
                u16::from_le_bytes([*cl, *ch]),
                u16::from_le_bytes([*il, *ih]),
                u16::from_le_bytes([*kl, *kh])
            ),
        ),
        [0xCD | 0xCE, ..] => {
            let name = if body[0] == 0xCD { "Device Heartbeat" } else { "Device Shutdown" };
            return Some(format!(
                "{name} from MAC {mac}, malformed: {} bytes, a heartbeat or shutdown has exactly 8: {}",
                data.len(),
                hex(data)
            ));
        }
        _ => return None,
    };
    let warning = if header_mac != mac {
        format!(" (warning: header MAC {header_mac} is not the identifier's MAC {mac}; a heartbeat or shutdown carries the sender's own MAC)")
    } else {
        String::new()
    };
    Some(format!("{name} from MAC {mac}: {fields}{warning}"))
}
