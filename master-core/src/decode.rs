//! DeviceNet meaning of CAN frames: identifiers, explicit requests and responses (services,
//! objects, attributes, error codes by name; body formats 0-3 and the CIP path of format 4 with
//! class, instance and attribute segments), fragment reassembly (explicit, and I/O for the poll,
//! change-of-state/cyclic, bit-strobe and multicast poll connections), duplicate MAC ID checks,
//! heartbeat and shutdown messages, UCMM and the Offline Connection Set with every field.
//!
//! Explicit connections opened through UCMM (protocol §3.6) are followed: the Open request gives the
//! group, the Open response the body format and the message IDs, and from then on the frames on
//! those identifiers are read as that connection's explicit requests and responses (fragments
//! reassembled on it), until a Close response. An Open response whose request was not seen is
//! named but not followed (the group is unknown), and so is a connection beyond
//! [`MAX_UCMM_LINKS`].
//!
//! Explicit reassembly follows the node's rules (protocol §4.1): an unfragmented request resets
//! both directions, an unfragmented response resets the response direction. Requests on the
//! explicit connection are read in the body format its Allocate response announced; before one
//! was seen, 8/8 is assumed and the text says so. The Group 2 Only port is always 8/8.
//!
//! A [`Decoder`] reads a whole exchange in order and keeps, per device MAC, what it needs to make
//! sense of later frames: the last explicit request (to interpret its response), the message body
//! format announced by the Allocate response, and the poll connection sizes read from Connection
//! instance 2 attributes 7 and 8 (protocol §4.2: I/O fragmentation is not signalled per frame, both
//! ends know it from the size). When the sizes were not seen, poll data is taken as fragmented
//! when its fragment bytes say so: an 8-byte frame starting with `00` opens a series, the
//! fragment due or a shorter frame continues it, and once a whole series was seen every frame of
//! that connection shaped like a fragment is one.
//!
//! A broken fragment series is named, never quietly dropped or joined: a first fragment whose
//! count is not 0, a middle or last fragment without a first, a count other than the one due (a
//! missed or repeated fragment), an I/O series cut off by the next first fragment. Each is a
//! [`FragmentViolation`]: in the frame's text as `(protocol error: ...)` and in
//! [`Decoded::protocol_error`].
//!
//! All decoding uses the core's codecs; nothing here can panic on any frame.

use devicenet::explicit::{BodyFormat, Header, Request, Response, ServiceCode};
use devicenet::fragment::{ExplicitFragment, ExplicitReassembler, ExplicitReceive, FragmentKind};
use devicenet::id::{Group1MessageId, Group3MessageId};
use devicenet::messages::{
    AllocationChoice, DuplicateMacCheck, GroupSelect, UcmmCloseRequest, UcmmCloseResponse, UcmmOpenRequest,
    UcmmOpenResponse,
};
use devicenet::objects::class;
use devicenet::{CanFrame, Group2Message, Identifier};
use std::collections::HashMap;

pub mod filter;
mod fragments;
mod messages;
mod text;
pub use fragments::FragmentViolation;
use fragments::{io_data, io_data_into, IoSeries, Who};
use messages::{broadcast_text, group3, group4, group_select_text};
pub use text::{
    attribute_text, body_format_text, class_text, error_text, hex, push_hex, request_text, response_text,
    service_text, short_string, u16_of, value_text,
};
use text::{path_request, path_request_text, push_data_text, push_u8};

/// Largest explicit message reassembled by the decoder (header included).
pub const MAX_EXPLICIT_MESSAGE: usize = 1024;
/// Largest I/O message reassembled by the decoder (64 fragments of 7 bytes, protocol §4.2).
pub const MAX_IO_MESSAGE: usize = 448;

/// Most UCMM connections followed at once (a trace opening more is not followed beyond them).
pub const MAX_UCMM_LINKS: usize = 64;

/// The meaning of one frame.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Decoded {
    /// What this frame is.
    pub summary: String,
    /// The whole message this frame completed, for the last fragment of a series.
    pub message: Option<String>,
    /// The breach of the fragmentation protocol this frame is (protocol §4), also named in the
    /// summary.
    pub protocol_error: Option<FragmentViolation>,
}

impl Decoded {
    fn frame(summary: String) -> Decoded {
        Decoded { summary, message: None, protocol_error: None }
    }

    /// The summary, followed by the completed message if any.
    pub fn text(&self) -> String {
        match &self.message {
            Some(m) => format!("{} => {m}", self.summary),
            None => self.summary.clone(),
        }
    }
}

/// The request an explicit response answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PendingRequest {
    /// Service requested.
    pub service: ServiceCode,
    /// Class.
    pub class: u16,
    /// Instance.
    pub instance: u16,
    /// Attribute, for Get/Set_Attribute_Single.
    pub attribute: Option<u8>,
    /// The allocation or release choice, for Allocate/Release_Master/Slave_Connection_Set.
    pub choice: Option<AllocationChoice>,
}

impl PendingRequest {
    /// From a parsed request.
    pub fn of(req: &Request<'_>) -> PendingRequest {
        let attribute = match req.service {
            ServiceCode::GetAttributeSingle | ServiceCode::SetAttributeSingle => req.data.first().copied(),
            _ => None,
        };
        let choice = match req.service {
            ServiceCode::AllocateMasterSlave | ServiceCode::ReleaseMasterSlave => {
                req.data.first().map(|&b| AllocationChoice::from_bits(b))
            }
            _ => None,
        };
        PendingRequest { service: req.service, class: req.class, instance: req.instance, attribute, choice }
    }
}

/// Where an explicit message travels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Channel {
    /// A request on the explicit connection (Group 2 message 4): the connection's body format.
    Request,
    /// A request on the Group 2 Only port (message 6): always 8/8 (protocol §3.1).
    Group2Only,
    /// A response (message 3).
    Response,
}

#[derive(Clone)]
struct Device {
    /// The explicit connection's body format, from its Allocate response; `None` until one is seen.
    body_format: Option<BodyFormat>,
    pending: Option<PendingRequest>,
    request_rx: ExplicitReassembler<MAX_EXPLICIT_MESSAGE>,
    response_rx: ExplicitReassembler<MAX_EXPLICIT_MESSAGE>,
    produced: Option<u16>,
    consumed: Option<u16>,
    poll_response: IoSeries,
    poll_command: IoSeries,
    /// The connections allocated, from the Allocate and Release responses seen: with change of
    /// state or cyclic but no poll, Connection 2 carries the master's COS/cyclic data and the
    /// device's zero-length acknowledgements (protocol §II.2.5).
    allocated: AllocationChoice,
    /// The other produced I/O connections (protocol §II.1-§II.3): Group 1 messages 12 (multicast
    /// poll response), 13 (change-of-state/cyclic data) and 14 (bit-strobe response), each with
    /// the produced size of its Connection instance (5, 4, 3) once read.
    other_io: [(Option<u16>, IoSeries); 3],
}

/// The Group 1 messages of [`Device::other_io`], each with the Connection instance producing it
/// (protocol §II.1-§II.3), in slot order.
const OTHER_IO: [(Group1MessageId, u16); 3] = [
    (Group1MessageId::MULTICAST_POLL_RESPONSE, 5),
    (Group1MessageId::COS_CYCLIC, 4),
    (Group1MessageId::BIT_STROBE_RESPONSE, 3),
];

/// Change of state and cyclic (allocation bits 0x10, 0x20).
const COS_OR_CYCLIC: AllocationChoice = AllocationChoice::CHANGE_OF_STATE.union(AllocationChoice::CYCLIC);

impl Device {
    /// `true` when Connection 2 consumes the master's COS/cyclic data: change of state or cyclic
    /// allocated without poll (protocol §II.2.5).
    fn cos_consumer(&self) -> bool {
        self.allocated.intersects(COS_OR_CYCLIC) && !self.allocated.contains(AllocationChoice::POLL)
    }

    fn new() -> Device {
        Device {
            body_format: None,
            pending: None,
            request_rx: ExplicitReassembler::new(),
            response_rx: ExplicitReassembler::new(),
            produced: None,
            consumed: None,
            poll_response: IoSeries::new(),
            poll_command: IoSeries::new(),
            allocated: AllocationChoice::empty(),
            other_io: [(None, IoSeries::new()), (None, IoSeries::new()), (None, IoSeries::new())],
        }
    }
}

/// Decodes a stream of frames. See the [module docs](self).
#[derive(Clone, Default)]
pub struct Decoder {
    /// Per MAC ID 0-63, the device's state once it was seen (a table: the decoder's hottest lookup).
    devices: Vec<Option<Device>>,
    /// Explicit connections opened through UCMM, by (server MAC, Connection instance).
    ucmm: HashMap<(u8, u16), UcmmLink>,
    /// The identifiers of [`Decoder::ucmm`]'s connections: which one, and whether it carries the
    /// client's requests (else the server's responses).
    ucmm_ids: HashMap<u16, ((u8, u16), bool)>,
    /// Open requests seen, by (client, server): the group the client asked for.
    ucmm_opens: HashMap<(u8, u8), GroupSelect>,
    /// Close requests seen, by (client, server): the Connection instance to close.
    ucmm_closes: HashMap<(u8, u8), u16>,
}

/// An explicit connection opened through UCMM (protocol §3.6): its ends, and the state of its
/// explicit messages (body format from the Open response, reassembly, the last request).
#[derive(Clone)]
struct UcmmLink {
    client: u8,
    state: Device,
}

/// Whose explicit messaging state a frame belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Target {
    /// The predefined explicit connection or the Group 2 Only port of the device at this MAC.
    Device(u8),
    /// A UCMM connection: (server MAC, Connection instance).
    Ucmm(u8, u16),
}

impl Target {
    /// The device the learned facts (sizes, body format of the predefined set) belong to.
    fn server(self) -> u8 {
        match self {
            Target::Device(mac) | Target::Ucmm(mac, _) => mac,
        }
    }
}

/// The CAN identifier of message `message` in `group` with `mac` in its MAC field (protocol §1.2);
/// `None` where the group has no such dynamic message.
fn dynamic_id(group: GroupSelect, message: u8, mac: u8) -> Option<u16> {
    let mac = u16::from(mac & 0x3F);
    match group {
        GroupSelect::Group1 if message < 16 => Some(u16::from(message) << 6 | mac),
        GroupSelect::Group2 if message < 8 => Some(0x400 | mac << 3 | u16::from(message)),
        // Group 3 messages 0-4 are the dynamic ones; 5 and 6 are UCMM's own (protocol §1.2).
        GroupSelect::Group3 if message <= 4 => Some(0x600 | u16::from(message) << 6 | mac),
        _ => None,
    }
}

impl Decoder {
    /// A decoder that has seen nothing yet.
    pub fn new() -> Decoder {
        Decoder::default()
    }

    fn device(&mut self, mac: u8) -> &mut Device {
        if self.devices.len() < 64 {
            self.devices.resize_with(64, || None);
        }
        self.devices[usize::from(mac & 0x3F)].get_or_insert_with(Device::new)
    }

    /// The poll connection sizes (produced, consumed) learned for `mac`.
    pub fn connection_sizes(&self, mac: u8) -> (Option<u16>, Option<u16>) {
        match self.devices.get(usize::from(mac)) {
            Some(Some(d)) => (d.produced, d.consumed),
            _ => (None, None),
        }
    }

    /// Tells the decoder the poll connection sizes of `mac` (when known from elsewhere).
    pub fn set_connection_sizes(&mut self, mac: u8, produced: Option<u16>, consumed: Option<u16>) {
        let d = self.device(mac);
        if produced.is_some() {
            d.produced = produced;
        }
        if consumed.is_some() {
            d.consumed = consumed;
        }
    }

    /// Decodes the next frame of the exchange.
    pub fn decode(&mut self, frame: &CanFrame) -> Decoded {
        let mut out = Decoded::default();
        self.decode_into(frame, &mut out);
        out
    }

    /// [`Decoder::decode`] into `out`, reusing its summary's memory (what `dnet-master decode`
    /// does for a million frames).
    pub fn decode_into(&mut self, frame: &CanFrame, out: &mut Decoded) {
        out.summary.clear();
        out.message = None;
        out.protocol_error = None;
        let data = frame.data();
        // The I/O traffic that makes up most of a trace, written straight into `out`.
        match Identifier::decode(frame.id()) {
            Identifier::Group1 { message: Group1MessageId::POLL_RESPONSE, source }
                if self.ucmm_ids.is_empty() =>
            {
                let device = self.device(source.as_raw());
                if device.cos_consumer() && data.is_empty() {
                    out.summary.push_str("change-of-state/cyclic acknowledge from MAC ");
                    push_u8(&mut out.summary, source.as_raw());
                    return out.summary.push_str(": no data");
                }
                let produced = device.produced;
                let who = Who { name: "poll response from MAC ", mac: source.as_raw() };
                return io_data_into(&mut device.poll_response, produced, who, data, out);
            }
            Identifier::Group2 { mac, message: Group2Message::PollCommand } if self.ucmm_ids.is_empty() => {
                let device = self.device(mac.as_raw());
                let consumed = device.consumed;
                let name = if device.cos_consumer() {
                    "change-of-state/cyclic data to MAC "
                } else {
                    "poll command to MAC "
                };
                let who = Who { name, mac: mac.as_raw() };
                return io_data_into(&mut device.poll_command, consumed, who, data, out);
            }
            _ => {}
        }
        let Decoded { summary, message, protocol_error } = self.decode_other(frame);
        out.summary.push_str(&summary);
        out.message = message;
        out.protocol_error = protocol_error;
    }

    fn decode_other(&mut self, frame: &CanFrame) -> Decoded {
        let data = frame.data();
        if !self.ucmm_ids.is_empty() {
            if let Some(&(key, request)) = self.ucmm_ids.get(&frame.id().as_raw()) {
                return self.ucmm_message(key, request, data);
            }
        }
        match Identifier::decode(frame.id()) {
            Identifier::Group1 { message, source } => self.group1(message, source.as_raw(), data),
            Identifier::Group2 { mac, message } => self.group2(message, mac.as_raw(), data),
            Identifier::Group3 { message, source } => {
                Decoded::frame(self.group3(message, source.as_raw(), data))
            }
            Identifier::Group4 { message } => Decoded::frame(group4(message, data)),
            Identifier::Invalid(raw) => Decoded::frame(format!(
                "invalid identifier 0x{raw:03X} (0x7F0-0x7FF are not used): {}",
                hex(data)
            )),
        }
    }

    fn group1(&mut self, message: Group1MessageId, source: u8, data: &[u8]) -> Decoded {
        let name = match message {
            Group1MessageId::POLL_RESPONSE => "poll response from MAC ",
            Group1MessageId::COS_CYCLIC => "change-of-state/cyclic data from MAC ",
            Group1MessageId::BIT_STROBE_RESPONSE => "bit-strobe response from MAC ",
            Group1MessageId::MULTICAST_POLL_RESPONSE => "multicast poll response from MAC ",
            _ => {
                return Decoded::frame(format!(
                    "G1 message {} from MAC {source} (dynamic connection): {}",
                    message.as_raw(),
                    hex(data)
                ))
            }
        };
        let who = Who { name, mac: source };
        if message == Group1MessageId::POLL_RESPONSE {
            let device = self.device(source);
            if device.cos_consumer() && data.is_empty() {
                return Decoded::frame(format!(
                    "change-of-state/cyclic acknowledge from MAC {source}: no data"
                ));
            }
            let produced = device.produced;
            return io_data(&mut device.poll_response, produced, who, data);
        }
        match OTHER_IO.iter().position(|(m, _)| *m == message) {
            Some(slot) => {
                let (size, series) = &mut self.device(source).other_io[slot];
                io_data(series, *size, who, data)
            }
            None => Decoded::frame(format!("{name}{source}: {}", data_text(data))),
        }
    }

    fn group2(&mut self, message: Group2Message, mac: u8, data: &[u8]) -> Decoded {
        match message {
            Group2Message::DuplicateMacCheck => Decoded::frame(match DuplicateMacCheck::parse(data) {
                Ok(d) => format!(
                    "duplicate MAC ID check {} for MAC {mac}: port {}, vendor 0x{:04X}, serial 0x{:08X}",
                    if d.response { "response" } else { "request" },
                    d.port,
                    d.vendor_id,
                    d.serial_number
                ),
                Err(e) => format!("malformed duplicate MAC ID check for MAC {mac} ({e}): {}", hex(data)),
            }),
            Group2Message::ExplicitRequest => {
                self.explicit(Target::Device(mac), data, Channel::Request, "explicit request to MAC")
            }
            Group2Message::UnconnectedExplicitRequest => self.explicit(
                Target::Device(mac),
                data,
                Channel::Group2Only,
                "Group 2 Only unconnected request to MAC",
            ),
            Group2Message::ExplicitResponse => {
                self.explicit(Target::Device(mac), data, Channel::Response, "explicit response from MAC")
            }
            Group2Message::PollCommand => {
                let device = self.device(mac);
                let name = if device.cos_consumer() {
                    "change-of-state/cyclic data to MAC "
                } else {
                    "poll command to MAC "
                };
                let who = Who { name, mac };
                let consumed = device.consumed;
                io_data(&mut device.poll_command, consumed, who, data)
            }
            Group2Message::BitStrobeCommand => {
                Decoded::frame(format!("bit-strobe command from master MAC {mac}: {}", data_text(data)))
            }
            Group2Message::MulticastPollCommand => {
                Decoded::frame(format!("multicast poll command, group MAC {mac}: {}", data_text(data)))
            }
            Group2Message::CosCyclicAck => Decoded::frame(format!(
                "change-of-state/cyclic acknowledge to MAC {mac}: {}",
                data_text(data)
            )),
        }
    }

    /// The explicit connection's state for `target`.
    fn state(&mut self, target: Target) -> &mut Device {
        match target {
            Target::Device(mac) => self.device(mac),
            Target::Ucmm(server, instance) => {
                &mut self
                    .ucmm
                    .entry((server, instance))
                    .or_insert_with(|| UcmmLink { client: 0, state: Device::new() })
                    .state
            }
        }
    }

    /// A frame of a UCMM connection: explicit messaging in the body format its Open response gave.
    fn ucmm_message(&mut self, key: (u8, u16), request: bool, data: &[u8]) -> Decoded {
        let (server, instance) = key;
        let client = self.ucmm.get(&key).map_or(0, |l| l.client);
        let (channel, what) = if request {
            (
                Channel::Request,
                format!("explicit request on UCMM connection {instance} (from MAC {client}) to MAC"),
            )
        } else {
            (
                Channel::Response,
                format!("explicit response on UCMM connection {instance} (to MAC {client}) from MAC"),
            )
        };
        self.explicit(Target::Ucmm(server, instance), data, channel, &what)
    }

    fn explicit(&mut self, target: Target, data: &[u8], channel: Channel, what: &str) -> Decoded {
        let mac = target.server();
        let request = channel != Channel::Response;
        let Some(&first) = data.first() else {
            return Decoded::frame(format!("{what} {mac}: empty frame"));
        };
        let header = Header::from_byte(first);
        let mut head = String::with_capacity(160);
        head.push_str(what);
        head.push(' ');
        push_u8(&mut head, mac);
        head.push_str(if header.xid { " [XID 1, master MAC " } else { " [master MAC " });
        push_u8(&mut head, header.mac.as_raw());
        head.push(']');
        if !header.fragmented {
            if !request && matches!(target, Target::Device(_)) {
                if let Some(text) = broadcast_text(mac, header.mac.as_raw(), data) {
                    return Decoded::frame(text);
                }
            }
            let body = &data[1..];
            let device = self.state(target);
            if request {
                // An unfragmented request resets fragmentation both ways (protocol §4.1).
                device.request_rx.reset();
                device.response_rx.reset();
            } else {
                // So does a complete response: a fragment after it begins nothing (the master
                // waits for one response per request, protocol §4.1), so a later last fragment
                // cannot join an earlier first one into a message nobody sent.
                device.response_rx.reset();
            }
            head.push(' ');
            head.push_str(&self.message_body(target, body, channel));
            return Decoded::frame(head);
        }
        let frag = match ExplicitFragment::parse(data) {
            Ok(f) => f,
            Err(e) => return Decoded::frame(format!("{head} malformed fragment ({e}): {}", hex(data))),
        };
        if frag.fragment.kind == FragmentKind::Ack {
            let status = frag.ack_status().map_or_else(|| "no status".to_string(), |s| s.to_string());
            return Decoded::frame(format!("{head} fragment ack #{} status {status}", frag.fragment.count));
        }
        let summary = format!(
            "{head} fragment {} #{} ({} body bytes): {}",
            frag.fragment.kind,
            frag.fragment.count,
            frag.body.len(),
            hex(frag.body)
        );
        let device = self.state(target);
        let rx = if request { &mut device.request_rx } else { &mut device.response_rx };
        match rx.receive(data) {
            ExplicitReceive::Complete(_) => {
                let whole = rx.message().to_vec();
                rx.reset();
                let body = whole.get(1..).unwrap_or(&[]);
                let text = format!(
                    "reassembled {} bytes: {}",
                    whole.len(),
                    self.message_body(target, body, channel)
                );
                Decoded { summary, message: Some(text), protocol_error: None }
            }
            ExplicitReceive::Ignored(e) => {
                match FragmentViolation::of(e, frag.fragment.kind, frag.fragment.count) {
                    Some(v) => {
                        let mut summary = summary;
                        v.push(&mut summary);
                        Decoded { summary, message: None, protocol_error: Some(v) }
                    }
                    None => Decoded::frame(format!("{summary} (dropped: {e})")),
                }
            }
            ExplicitReceive::Rejected(_) => Decoded::frame(format!("{summary} (dropped: message too long)")),
            ExplicitReceive::Duplicate(_) => Decoded::frame(format!("{summary} (repeated)")),
            ExplicitReceive::Ack(_) => Decoded::frame(summary),
        }
    }

    /// A whole explicit body, remembering requests and learning sizes and the body format from
    /// responses.
    fn message_body(&mut self, target: Target, body: &[u8], channel: Channel) -> String {
        let device = self.state(target);
        if channel != Channel::Response {
            // The Group 2 Only port always uses 8/8; the explicit connection the format its
            // Allocate response announced, 8/8 assumed (and said) before one was seen (protocol §3.1).
            let (format, assumed) = match (channel, device.body_format) {
                (Channel::Group2Only, _) => (BodyFormat::Class8Instance8, false),
                (_, Some(f)) => (f, false),
                (_, None) => (BodyFormat::Class8Instance8, true),
            };
            let note = if assumed { " [body format 8/8 assumed: no Allocate response seen]" } else { "" };
            if format == BodyFormat::CipPath {
                return match path_request(body) {
                    Ok((req, attribute)) => {
                        let (text, pending) = path_request_text(&req, attribute);
                        device.pending = Some(pending);
                        text
                    }
                    Err(why) => {
                        device.pending = None;
                        format!("malformed request ({why}): {}", hex(body))
                    }
                };
            }
            match Request::parse(body, format) {
                Ok(req) => {
                    device.pending = Some(PendingRequest::of(&req));
                    format!("{}{note}", request_text(&req))
                }
                Err(e) => {
                    device.pending = None;
                    format!("malformed request ({e}){note}: {}", hex(body))
                }
            }
        } else {
            let pending = device.pending.take();
            // What a response teaches belongs to the device, whichever connection carried it.
            let device = self.device(target.server());
            if let (Some(p), Ok(Response::Success { data, .. })) = (pending, Response::parse(body)) {
                match (p.service, p.class, p.instance, p.attribute) {
                    (ServiceCode::GetAttributeSingle, class::CONNECTION, 2, Some(7)) => {
                        device.produced = u16_of(data)
                    }
                    (ServiceCode::GetAttributeSingle, class::CONNECTION, 2, Some(8)) => {
                        device.consumed = u16_of(data)
                    }
                    (ServiceCode::GetAttributeSingle, class::CONNECTION, 3..=5, Some(7)) => {
                        let slot = OTHER_IO.iter().position(|(_, inst)| *inst == p.instance);
                        if let Some(slot) = slot {
                            device.other_io[slot].0 = u16_of(data);
                        }
                    }
                    (ServiceCode::AllocateMasterSlave, class::DEVICENET, _, _) => {
                        if let [fmt] = data {
                            device.body_format = Some(BodyFormat::from_code(*fmt));
                        }
                        if let Some(choice) = p.choice {
                            device.allocated = device.allocated.union(choice);
                        }
                    }
                    (ServiceCode::ReleaseMasterSlave, class::DEVICENET, _, _) => {
                        if let Some(choice) = p.choice {
                            device.allocated = device.allocated.difference(choice);
                            if device.allocated.intersection(COS_OR_CYCLIC).is_empty() {
                                device.allocated =
                                    device.allocated.difference(AllocationChoice::ACK_SUPPRESSION);
                            }
                        }
                    }
                    _ => {}
                }
            }
            response_text(body, pending.as_ref())
        }
    }
}

fn data_text(data: &[u8]) -> String {
    if data.is_empty() {
        "no data".into()
    } else {
        format!("{} bytes {}", data.len(), hex(data))
    }
}

impl Decoder {
    /// UCMM requests and responses (protocol §3.6); an Open response opens a connection that later
    /// frames are read on, a Close response closes it.
    fn group3(&mut self, message: Group3MessageId, source: u8, data: &[u8]) -> String {
        match message {
            Group3MessageId::UNCONNECTED_REQUEST => self.ucmm_request(source, data),
            Group3MessageId::UNCONNECTED_RESPONSE => self.ucmm_response(source, data),
            _ => format!(
                "G3 message {} from MAC {source} (dynamic connection, not opened in this trace): {}",
                message.as_raw(),
                hex(data)
            ),
        }
    }

    fn ucmm_request(&mut self, source: u8, data: &[u8]) -> String {
        if let Ok(r) = UcmmOpenRequest::parse(data) {
            self.ucmm_opens.insert((source, r.destination.as_raw()), r.group_select);
        }
        if let Ok(r) = UcmmCloseRequest::parse(data) {
            self.ucmm_closes.insert((source, r.destination.as_raw()), r.connection_instance);
        }
        group3(Group3MessageId::UNCONNECTED_REQUEST, source, data)
    }

    fn ucmm_response(&mut self, server: u8, data: &[u8]) -> String {
        let text = group3(Group3MessageId::UNCONNECTED_RESPONSE, server, data);
        if let Ok(r) = UcmmOpenResponse::parse(data) {
            let client = r.destination.as_raw();
            let Some(group) = self.ucmm_opens.remove(&(client, server)) else {
                return format!("{text} (its Open request was not seen: the group is unknown, the connection is not followed)");
            };
            // In Groups 1 and 3 the identifier carries the sender's MAC, in Group 2 the server's
            // (protocol §1.2): the client's requests go on the message ID the server consumes, the
            // server's responses on the one it produces (CIP Vol 3 3-5.5; which response field is
            // which is UNCONFIRMED beyond the field names).
            let (request_mac, response_mac) = match group {
                GroupSelect::Group2 => (server, server),
                _ => (client, server),
            };
            let ids = dynamic_id(group, r.destination_message_id, request_mac).zip(dynamic_id(
                group,
                r.source_message_id,
                response_mac,
            ));
            let Some((request_id, response_id)) = ids else {
                return format!(
                    "{text} (message IDs outside the dynamic range of {}: not followed)",
                    group_select_text(group)
                );
            };
            let key = (server, r.connection_instance);
            self.close_link(key);
            if self.ucmm.len() >= MAX_UCMM_LINKS {
                return format!("{text} (already {MAX_UCMM_LINKS} UCMM connections open: not followed)");
            }
            let mut state = Device::new();
            state.body_format = Some(r.body_format);
            self.ucmm.insert(key, UcmmLink { client, state });
            self.ucmm_ids.insert(request_id, (key, true));
            self.ucmm_ids.insert(response_id, (key, false));
            return format!(
                "{text}; requests on 0x{request_id:03X}, responses on 0x{response_id:03X} ({})",
                group_select_text(group)
            );
        }
        if let Ok(r) = UcmmCloseResponse::parse(data) {
            if let Some(instance) = self.ucmm_closes.remove(&(r.destination.as_raw(), server)) {
                self.close_link((server, instance));
                return format!("{text}: connection {instance} closed");
            }
        }
        text
    }

    fn close_link(&mut self, key: (u8, u16)) {
        if self.ucmm.remove(&key).is_some() {
            self.ucmm_ids.retain(|_, (k, _)| *k != key);
        }
    }
}

#[cfg(test)]
mod tests;
