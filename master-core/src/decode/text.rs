//! The texts of decoded messages: hex bytes, objects and attributes by name, values, requests,
//! responses and error codes (what [`Decoder`](super::Decoder) writes, and what other tools use to
//! show a value the way `decode` does).

use super::PendingRequest;
use devicenet::explicit::{additional, BodyFormat, GeneralStatus, Request, Response, ServiceCode};
use devicenet::messages::{AllocateRequest, AllocationInfo, ReleaseRequest};
use devicenet::objects::{self, class};

/// Hex bytes separated by spaces.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 3);
    push_hex(&mut s, bytes);
    s
}

const HEX_DIGITS: &[u8; 16] = b"0123456789ABCDEF";

/// Appends [`hex`]`(bytes)` to `out` (no allocation, no formatting machinery: `decode` writes
/// one line per frame and this is most of it).
pub fn push_hex(out: &mut String, bytes: &[u8]) {
    for (i, &b) in bytes.iter().enumerate() {
        if i > 0 {
            out.push(' ');
        }
        out.push(char::from(HEX_DIGITS[usize::from(b >> 4)]));
        out.push(char::from(HEX_DIGITS[usize::from(b & 0xF)]));
    }
}

/// Appends `n` in decimal.
pub(super) fn push_u8(out: &mut String, n: u8) {
    if n >= 100 {
        out.push(char::from(b'0' + n / 100));
    }
    if n >= 10 {
        out.push(char::from(b'0' + n / 10 % 10));
    }
    out.push(char::from(b'0' + n % 10));
}

/// Appends [`data_text`]`(data)`.
pub(super) fn push_data_text(out: &mut String, data: &[u8]) {
    if data.is_empty() {
        out.push_str("no data");
    } else {
        push_u8(out, data.len() as u8);
        out.push_str(" bytes ");
        push_hex(out, data);
    }
}

/// `Identity(1)` or `class 0x99`.
pub fn class_text(class: u16) -> String {
    match objects::class_name(class) {
        Some(name) => format!("{name}({class})"),
        None => format!("class 0x{class:02X}"),
    }
}

/// The name of `service` on an object of `class` (`Get_Attribute_Single`), or `service 0x4B` for
/// an object-specific code on a class whose services have no name here
/// ([`devicenet::objects::service_name`]: 0x4B is Allocate only on the DeviceNet object).
pub fn service_text(class: u16, service: ServiceCode) -> String {
    objects::service_name(class, service)
        .map_or_else(|| format!("service 0x{:02X}", service.as_raw()), String::from)
}

/// `attr 7 (product name)` or `attr 99`.
pub fn attribute_text(class: u16, instance: u16, attribute: u8) -> String {
    match objects::attribute_name(class, instance, attribute) {
        Some(name) => format!("attr {attribute} ({name})"),
        None => format!("attr {attribute}"),
    }
}

/// An error response by name: `attribute not supported (0x14), additional code 0xFF (none)`.
pub fn error_text(general: GeneralStatus, additional_code: u8) -> String {
    let add = match additional::name(additional_code) {
        Some(name) => format!("0x{additional_code:02X} ({name})"),
        None => format!("0x{additional_code:02X}"),
    };
    format!("{general}, additional code {add}")
}

/// The name of a message body format.
pub fn body_format_text(format: BodyFormat) -> String {
    match format {
        BodyFormat::Class8Instance8 => "8/8".into(),
        BodyFormat::Class8Instance16 => "8/16".into(),
        BodyFormat::Class16Instance16 => "16/16".into(),
        BodyFormat::Class16Instance8 => "16/8".into(),
        BodyFormat::CipPath => "CIP path".into(),
        BodyFormat::Reserved(c) => format!("reserved ({c})"),
    }
}

/// A u16 attribute value (little-endian, exactly 2 bytes).
pub fn u16_of(data: &[u8]) -> Option<u16> {
    match data {
        [a, b] => Some(u16::from_le_bytes([*a, *b])),
        _ => None,
    }
}

pub(super) fn u8_of(data: &[u8]) -> Option<u8> {
    match data {
        [a] => Some(*a),
        _ => None,
    }
}

/// A SHORT_STRING (length byte, then ASCII): `Some(text)` when the length matches.
pub fn short_string(data: &[u8]) -> Option<String> {
    let (&len, text) = data.split_first()?;
    (usize::from(len) == text.len()).then(|| text.iter().map(|&b| char::from(b)).collect())
}

/// An attribute value, typed by class and attribute (protocol §5.1, §6.1, §6.2); raw hex when the
/// attribute is unknown or the length does not match its type.
pub fn value_text(class_id: u16, instance: u16, attribute: u8, data: &[u8]) -> String {
    let typed: Option<String> = if instance == 0 {
        match attribute {
            1 => u16_of(data).map(|v| v.to_string()),
            _ => None,
        }
    } else {
        match (class_id, attribute) {
            (class::IDENTITY, 1..=3) => u16_of(data).map(|v| format!("0x{v:04X} ({v})")),
            (class::IDENTITY, 4) => match data {
                [maj, min] => Some(format!("{maj}.{min}")),
                _ => None,
            },
            (class::IDENTITY, 5) => u16_of(data).map(|v| format!("0x{v:04X}")),
            (class::IDENTITY, 6) => match data {
                [a, b, c, d] => Some(format!("0x{:08X}", u32::from_le_bytes([*a, *b, *c, *d]))),
                _ => None,
            },
            (class::IDENTITY, 7) => short_string(data).map(|s| format!("\"{s}\"")),
            (class::IDENTITY, 8) => u8_of(data).map(|v| {
                let name = match v {
                    0 => "non-existent",
                    1 => "self testing",
                    2 => "standby",
                    3 => "operational",
                    4 => "major recoverable fault",
                    5 => "major unrecoverable fault",
                    _ => "unknown",
                };
                format!("{v} ({name})")
            }),
            (class::DEVICENET, 5) => AllocationInfo::parse(data).ok().map(|info| match info.master {
                Some(m) => format!("allocated {} by master MAC {m}", info.choice),
                None => format!("{} (not allocated)", info.choice),
            }),
            (class::DEVICENET, 1..=4 | 6..=9) => u8_of(data).map(|v| v.to_string()),
            (class::ASSEMBLY, 4) => u16_of(data).map(|v| format!("{v} bytes")),
            (class::CONNECTION, 1) => u8_of(data)
                .map(|v| format!("{v} ({})", objects::connection_state_name(v).unwrap_or("unknown"))),
            (class::CONNECTION, 12) => u8_of(data)
                .map(|v| format!("{v} ({})", objects::watchdog_action_name(v).unwrap_or("unknown"))),
            (class::CONNECTION, 2) => u8_of(data).map(|v| match v {
                0 => "0 (explicit)".to_string(),
                1 => "1 (I/O)".to_string(),
                other => other.to_string(),
            }),
            (class::CONNECTION, 3 | 6) => u8_of(data).map(|v| format!("0x{v:02X}")),
            (class::CONNECTION, 4 | 5) => u16_of(data).map(|v| format!("0x{v:03X}")),
            (class::CONNECTION, 7 | 8) => u16_of(data).map(|v| format!("{v} bytes")),
            (class::CONNECTION, 9 | 17) => u16_of(data).map(|v| format!("{v} ms")),
            (class::CONNECTION, 13 | 15) => u16_of(data).map(|v| v.to_string()),
            _ => None,
        }
    };
    match typed {
        Some(t) => t,
        None if data.is_empty() => "(no data)".into(),
        None => hex(data),
    }
}

/// A request body in words: `Get_Attribute_Single Identity(1) inst 1 attr 1 (vendor ID)`.
pub fn request_text(req: &Request<'_>) -> String {
    let target = format!("{} inst {}", class_text(req.class), req.instance);
    let service = service_text(req.class, req.service);
    match req.service {
        ServiceCode::GetAttributeSingle => match req.data {
            [attr] => format!("{service} {target} {}", attribute_text(req.class, req.instance, *attr)),
            _ => format!("{service} {target} data {}", hex(req.data)),
        },
        ServiceCode::SetAttributeSingle => match req.data.split_first() {
            Some((&attr, value)) => format!(
                "{service} {target} {} = {}",
                attribute_text(req.class, req.instance, attr),
                value_text(req.class, req.instance, attr, value)
            ),
            None => format!("{service} {target} (no attribute)"),
        },
        ServiceCode::AllocateMasterSlave if req.class == class::DEVICENET => {
            match AllocateRequest::parse(req.data) {
                Ok(a) => format!("{service} {target}: choice {}, allocator MAC {}", a.choice, a.allocator),
                Err(e) => format!("{service} {target}: malformed ({e}): {}", hex(req.data)),
            }
        }
        ServiceCode::ReleaseMasterSlave if req.class == class::DEVICENET => {
            match ReleaseRequest::parse(req.data) {
                Ok(r) => format!("{service} {target}: choice {}", r.choice),
                Err(e) => format!("{service} {target}: malformed ({e}): {}", hex(req.data)),
            }
        }
        _ if req.data.is_empty() => format!("{service} {target}"),
        _ => format!("{service} {target} data {}", hex(req.data)),
    }
}

/// A request in body format 4 (protocol §3.1: `<service> <path size in words> <EPATH> <data>`): the
/// request with the class and instance of its logical segments, and the attribute of an attribute
/// segment. Segments (8-bit `20`/`24`/`30 xx`, 16-bit `21`/`25`/`31 00 lo hi`): class first, then
/// instance, then an optional attribute; anything else is refused with its reason.
pub(super) fn path_request(body: &[u8]) -> Result<(Request<'_>, Option<u16>), String> {
    let [service, words, rest @ ..] = body else {
        return Err("truncated: no path size".into());
    };
    if service & 0x80 != 0 {
        return Err("not a request (bit 7 of the service set)".into());
    }
    let len = usize::from(*words) * 2;
    if rest.len() < len {
        return Err(format!("path of {words} words, only {} bytes follow", rest.len()));
    }
    let (mut path, data) = rest.split_at(len);
    let mut ids: [Option<u16>; 3] = [None; 3];
    while let Some((&seg, tail)) = path.split_first() {
        let (value, tail) = match (seg, tail) {
            (0x20 | 0x24 | 0x30, [v, tail @ ..]) => (u16::from(*v), tail),
            (0x21 | 0x25 | 0x31, [_pad, lo, hi, tail @ ..]) => (u16::from_le_bytes([*lo, *hi]), tail),
            _ => return Err(format!("unsupported path segment 0x{seg:02X} in {}", hex(&rest[..len]))),
        };
        // Class, then instance, then attribute, each once.
        let slot = match seg {
            0x20 | 0x21 => 0,
            0x24 | 0x25 => 1,
            _ => 2,
        };
        if ids[slot].is_some() || ids[..slot].iter().any(Option::is_none) {
            return Err(format!(
                "path segments out of order (class, instance, attribute): {}",
                hex(&rest[..len])
            ));
        }
        ids[slot] = Some(value);
        path = tail;
    }
    match ids {
        [Some(class), Some(instance), attribute] => {
            Ok((Request { service: ServiceCode::from(*service), class, instance, data }, attribute))
        }
        _ => Err(format!("path without class and instance: {}", hex(&rest[..len]))),
    }
}

/// [`request_text`] of a body-format-4 request whose path may end in an attribute segment, and
/// the request its response answers.
pub(super) fn path_request_text(req: &Request<'_>, attribute: Option<u16>) -> (String, PendingRequest) {
    let single = matches!(req.service, ServiceCode::GetAttributeSingle | ServiceCode::SetAttributeSingle);
    match attribute.map(u8::try_from) {
        // The attribute segment read as the attribute ID of an 8/8 request.
        Some(Ok(attr)) if single => {
            let mut data = vec![attr];
            data.extend_from_slice(req.data);
            let whole = Request { data: &data, ..*req };
            (format!("{} (CIP path)", request_text(&whole)), PendingRequest::of(&whole))
        }
        Some(_) => {
            let attr = attribute.unwrap_or(0);
            let service = req
                .service
                .name()
                .map_or_else(|| format!("service 0x{:02X}", req.service.as_raw()), String::from);
            let data = if req.data.is_empty() { String::new() } else { format!(" data {}", hex(req.data)) };
            let pending = PendingRequest { attribute: u8::try_from(attr).ok(), ..PendingRequest::of(req) };
            (
                format!(
                    "{service} {} inst {} attr {attr}{data} (CIP path)",
                    class_text(req.class),
                    req.instance
                ),
                pending,
            )
        }
        None => (format!("{} (CIP path)", request_text(req)), PendingRequest::of(req)),
    }
}

/// A response body in words, interpreted with the request it answers when known.
pub fn response_text(body: &[u8], pending: Option<&PendingRequest>) -> String {
    match Response::parse(body) {
        Ok(Response::Error { general, additional }) => {
            format!("Error_Response: {}", error_text(general, additional))
        }
        Ok(Response::Success { service, data }) => {
            let matching = pending.filter(|p| p.service == service);
            let name = match matching {
                Some(p) => service_text(p.class, service),
                None => {
                    service.name().map_or_else(|| format!("service 0x{:02X}", service.as_raw()), String::from)
                }
            };
            match (service, matching) {
                (ServiceCode::GetAttributeSingle, Some(p)) => {
                    let attr = p.attribute.unwrap_or(0);
                    format!(
                        "{name} response: {} inst {} {} = {}",
                        class_text(p.class),
                        p.instance,
                        attribute_text(p.class, p.instance, attr),
                        value_text(p.class, p.instance, attr, data)
                    )
                }
                (ServiceCode::SetAttributeSingle, Some(p)) if !data.is_empty() => {
                    let attr = p.attribute.unwrap_or(0);
                    format!(
                        "{name} response: success, {} applied = {}",
                        attribute_text(p.class, p.instance, attr),
                        value_text(p.class, p.instance, attr, data)
                    )
                }
                (ServiceCode::AllocateMasterSlave, _) => match data {
                    [fmt] => format!(
                        "{name} response: success, message body format {}",
                        body_format_text(BodyFormat::from_code(*fmt))
                    ),
                    _ => format!("{name} response: success, data {}", hex(data)),
                },
                _ if data.is_empty() => format!("{name} response: success"),
                _ => format!("{name} response: success, data {}", hex(data)),
            }
        }
        Err(e) => format!("malformed response ({e}): {}", hex(body)),
    }
}
