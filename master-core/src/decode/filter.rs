//! What `decode` shows and when it stops: a frame's [`Kind`], MAC and group, the [`Filter`] that
//! selects frames by them, and the [`Pattern`] of a trigger (`mac=5,kind=explicit-error`,
//! `id=0x400/0x7C0`, `data=0094/00FF`).
//!
//! The kind of a frame is read from its identifier (protocol §1) and, for explicit messages, from
//! the service byte of an unfragmented message or of the first fragment (protocol §3: bit 7 of the
//! service code marks a response; 0x94 is the error response). A later fragment has the direction
//! of its message ID. Nothing here can panic on any frame.

use devicenet::{CanFrame, Group2Message, Identifier};
use std::fmt;
use std::str::FromStr;

/// What kind of message a frame carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A master's explicit request (Group 2 message 4), or a Group 2 Only unconnected request
    /// (message 6: Allocate, Release).
    ExplicitRequest,
    /// An explicit or unconnected response (Group 2 message 3) that is not an error.
    ExplicitResponse,
    /// An error response (service 0x94).
    ExplicitError,
    /// I/O: a slave's Group 1 production, a master's poll, bit-strobe, multicast poll, COS/cyclic
    /// acknowledge.
    Io,
    /// A duplicate MAC ID check request or response (Group 2 message 7).
    DuplicateMac,
    /// UCMM (Group 3 messages 5 and 6).
    Ucmm,
    /// Group 3 messages 0-4 (connections opened through UCMM) and Group 4 (the Offline
    /// Connection Set, broadcasts).
    Other,
}

impl Kind {
    /// Every kind.
    pub const ALL: [Kind; 7] = [
        Kind::ExplicitRequest,
        Kind::ExplicitResponse,
        Kind::ExplicitError,
        Kind::Io,
        Kind::DuplicateMac,
        Kind::Ucmm,
        Kind::Other,
    ];

    /// The name on the command line.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Kind::ExplicitRequest => "explicit-request",
            Kind::ExplicitResponse => "explicit-response",
            Kind::ExplicitError => "explicit-error",
            Kind::Io => "io",
            Kind::DuplicateMac => "dup-mac",
            Kind::Ucmm => "ucmm",
            Kind::Other => "other",
        }
    }
}

/// A kind as asked for: one kind, or `explicit` (requests, responses and errors).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KindMatch {
    /// Exactly this kind.
    One(Kind),
    /// Any explicit message.
    Explicit,
}

impl KindMatch {
    /// Whether `kind` is one asked for.
    #[must_use]
    pub fn matches(self, kind: Kind) -> bool {
        match self {
            KindMatch::One(k) => k == kind,
            KindMatch::Explicit => {
                matches!(kind, Kind::ExplicitRequest | Kind::ExplicitResponse | Kind::ExplicitError)
            }
        }
    }
}

impl FromStr for KindMatch {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "explicit" {
            return Ok(KindMatch::Explicit);
        }
        Kind::ALL.into_iter().find(|k| k.name() == s).map(KindMatch::One).ok_or_else(|| {
            let names: Vec<&str> = Kind::ALL.iter().map(|k| k.name()).collect();
            format!("unknown message kind '{s}' (one of: explicit, {})", names.join(", "))
        })
    }
}

/// Where a frame belongs: its kind, the MAC its identifier carries (none for Group 4) and its
/// group (1-4; 0 for the reserved identifiers 0x7F0-0x7FF).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Class {
    /// The kind.
    pub kind: Kind,
    /// The MAC in the identifier.
    pub mac: Option<u8>,
    /// The message group.
    pub group: u8,
}

/// The kind of an explicit frame's data sent with message ID `request` or not.
fn explicit_kind(data: &[u8], request: bool) -> Kind {
    // Header byte: bit 7 fragmented; a first fragment has count 0 after the fragmentation
    // protocol byte (protocol §4.1), and the service follows.
    let service = match data {
        [header, service, ..] if header & 0x80 == 0 => Some(*service),
        [header, 0, service, ..] if header & 0x80 != 0 => Some(*service),
        _ => None,
    };
    match service {
        Some(0x94) => Kind::ExplicitError,
        Some(s) if s & 0x80 != 0 => Kind::ExplicitResponse,
        Some(_) => Kind::ExplicitRequest,
        None if request => Kind::ExplicitRequest,
        None => Kind::ExplicitResponse,
    }
}

/// The class of `frame`.
#[must_use]
pub fn classify(frame: &CanFrame) -> Class {
    let data = frame.data();
    match Identifier::decode(frame.id()) {
        Identifier::Group1 { source, .. } => Class { kind: Kind::Io, mac: Some(source.as_raw()), group: 1 },
        Identifier::Group2 { mac, message } => {
            let kind = match message {
                Group2Message::ExplicitRequest | Group2Message::UnconnectedExplicitRequest => {
                    explicit_kind(data, true)
                }
                Group2Message::ExplicitResponse => explicit_kind(data, false),
                Group2Message::DuplicateMacCheck => Kind::DuplicateMac,
                Group2Message::BitStrobeCommand
                | Group2Message::MulticastPollCommand
                | Group2Message::CosCyclicAck
                | Group2Message::PollCommand => Kind::Io,
            };
            Class { kind, mac: Some(mac.as_raw()), group: 2 }
        }
        Identifier::Group3 { message, source } => {
            let kind = if message.as_raw() >= 5 { Kind::Ucmm } else { Kind::Other };
            Class { kind, mac: Some(source.as_raw()), group: 3 }
        }
        Identifier::Group4 { .. } => Class { kind: Kind::Other, mac: None, group: 4 },
        Identifier::Invalid(_) => Class { kind: Kind::Other, mac: None, group: 0 },
    }
}

/// Which frames are shown: each list given must hold the frame's value (an empty list holds
/// every value).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Filter {
    /// MACs.
    pub macs: Vec<u8>,
    /// Groups.
    pub groups: Vec<u8>,
    /// Kinds.
    pub kinds: Vec<KindMatch>,
}

impl Filter {
    /// Whether it lets every frame through.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.macs.is_empty() && self.groups.is_empty() && self.kinds.is_empty()
    }

    /// Whether a frame of class `c` is shown.
    #[must_use]
    pub fn passes(&self, c: Class) -> bool {
        (self.macs.is_empty() || c.mac.is_some_and(|m| self.macs.contains(&m)))
            && (self.groups.is_empty() || self.groups.contains(&c.group))
            && (self.kinds.is_empty() || self.kinds.iter().any(|k| k.matches(c.kind)))
    }
}

/// One term of a trigger.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Term {
    /// `mac=N`.
    Mac(u8),
    /// `group=N`.
    Group(u8),
    /// `kind=K`.
    Kind(KindMatch),
    /// `id=ID[/MASK]`: `identifier & mask == id & mask` (mask 0x7FF by default).
    Id {
        /// The identifier.
        id: u16,
        /// The bits compared.
        mask: u16,
    },
    /// `data=HEX[/MASK]`: the first bytes, each compared under its mask byte (0xFF by default);
    /// a frame with fewer bytes does not match.
    Data {
        /// The bytes.
        bytes: Vec<u8>,
        /// Their masks.
        mask: Vec<u8>,
    },
}

/// A trigger: every term must hold (`mac=5,kind=explicit-error`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pattern {
    /// The terms.
    pub terms: Vec<Term>,
    /// The text given.
    pub text: String,
}

impl fmt::Display for Pattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.text)
    }
}

fn number(s: &str) -> Option<u32> {
    match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => u32::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

fn hex_bytes(s: &str) -> Option<Vec<u8>> {
    let s = s.strip_prefix("0x").unwrap_or(s);
    if s.is_empty() || s.len() % 2 != 0 {
        return None;
    }
    (0..s.len()).step_by(2).map(|i| s.get(i..i + 2).and_then(|d| u8::from_str_radix(d, 16).ok())).collect()
}

fn term(text: &str) -> Result<Term, String> {
    let (key, value) = text.split_once('=').ok_or_else(|| format!("'{text}': expected KEY=VALUE"))?;
    let (key, value) = (key.trim(), value.trim());
    let bad = |what: &str| format!("'{text}': {what}");
    match key {
        "mac" => number(value)
            .and_then(|v| u8::try_from(v).ok())
            .filter(|&v| v <= 63)
            .map(Term::Mac)
            .ok_or_else(|| bad("a MAC ID is 0..=63")),
        "group" => number(value)
            .and_then(|v| u8::try_from(v).ok())
            .filter(|v| (1..=4).contains(v))
            .map(Term::Group)
            .ok_or_else(|| bad("a group is 1..=4")),
        "kind" => value.parse().map(Term::Kind),
        "id" => {
            let (id, mask) = value.split_once('/').unwrap_or((value, "0x7FF"));
            let eleven = |s: &str| number(s).and_then(|v| u16::try_from(v).ok()).filter(|&v| v <= 0x7FF);
            match (eleven(id), eleven(mask)) {
                (Some(id), Some(mask)) => Ok(Term::Id { id, mask }),
                _ => Err(bad("an identifier and mask are 11-bit numbers (0x400/0x7C0)")),
            }
        }
        "data" => {
            let (bytes, mask) = match value.split_once('/') {
                Some((b, m)) => (hex_bytes(b), hex_bytes(m)),
                None => (hex_bytes(value), hex_bytes(value).map(|b| vec![0xFF; b.len()])),
            };
            match (bytes, mask) {
                (Some(bytes), Some(mask)) if bytes.len() == mask.len() && bytes.len() <= 8 => {
                    Ok(Term::Data { bytes, mask })
                }
                _ => Err(bad("data is 1 to 8 hex bytes, and a mask of as many (0094/00FF)")),
            }
        }
        other => Err(bad(&format!("unknown key '{other}' (mac, group, kind, id, data)"))),
    }
}

impl FromStr for Pattern {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let terms = s.split(',').filter(|t| !t.trim().is_empty()).map(term).collect::<Result<Vec<_>, _>>()?;
        if terms.is_empty() {
            return Err("an empty trigger matches every frame: give at least one KEY=VALUE".into());
        }
        Ok(Pattern { terms, text: s.to_string() })
    }
}

impl Pattern {
    /// Whether `frame` (of class `c`) matches every term.
    #[must_use]
    pub fn matches(&self, frame: &CanFrame, c: Class) -> bool {
        let id = frame.id().as_raw();
        let data = frame.data();
        self.terms.iter().all(|t| match t {
            Term::Mac(m) => c.mac == Some(*m),
            Term::Group(g) => c.group == *g,
            Term::Kind(k) => k.matches(c.kind),
            Term::Id { id: want, mask } => id & mask == want & mask,
            Term::Data { bytes, mask } => {
                data.len() >= bytes.len()
                    && bytes.iter().zip(mask).zip(data).all(|((b, m), d)| d & m == b & m)
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use devicenet::CanId;

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::new(CanId::new(id).unwrap(), data).unwrap()
    }

    #[test]
    fn kinds_from_identifier_and_service() {
        // Group 2 message 3 from MAC 5: 10 000101 011 = 0x42B.
        assert_eq!(classify(&frame(0x42B, &[0x00, 0x94, 0x08, 0xFF])).kind, Kind::ExplicitError);
        assert_eq!(classify(&frame(0x42B, &[0x00, 0x8E, 0x01])).kind, Kind::ExplicitResponse);
        // Group 2 message 4 to MAC 5: 0x42C; message 6 (Allocate) 0x42E.
        assert_eq!(classify(&frame(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01])).kind, Kind::ExplicitRequest);
        assert_eq!(
            classify(&frame(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00])).kind,
            Kind::ExplicitRequest
        );
        // A first fragment of an error response, and a later fragment.
        assert_eq!(classify(&frame(0x42B, &[0x80, 0x00, 0x94, 0x08])).kind, Kind::ExplicitError);
        assert_eq!(classify(&frame(0x42B, &[0x80, 0x41, 0x01])).kind, Kind::ExplicitResponse);
        assert_eq!(classify(&frame(0x42F, &[0x00])).kind, Kind::DuplicateMac);
        assert_eq!(classify(&frame(0x42D, &[1, 2])).kind, Kind::Io);
        let c = classify(&frame(0x3C5, &[1, 2]));
        assert_eq!((c.kind, c.mac, c.group), (Kind::Io, Some(5), 1));
        assert_eq!(classify(&frame(0x7E0, &[])).group, 4);
    }

    #[test]
    fn triggers_parse_and_match() {
        let p: Pattern = "mac=5,kind=explicit-error".parse().unwrap();
        let error = frame(0x42B, &[0x00, 0x94, 0x08, 0xFF]);
        assert!(p.matches(&error, classify(&error)));
        let answer = frame(0x42B, &[0x00, 0x8E, 0x01]);
        assert!(!p.matches(&answer, classify(&answer)));
        let other_mac = frame(0x433, &[0x00, 0x94, 0x08, 0xFF]);
        assert!(!p.matches(&other_mac, classify(&other_mac)));
        let p: Pattern = "id=0x42B/0x7F8,data=0094/00FF".parse().unwrap();
        assert!(p.matches(&error, classify(&error)));
        assert!(!p.matches(&answer, classify(&answer)));
        let short = frame(0x42B, &[0x00]);
        assert!(!p.matches(&short, classify(&short)));
    }

    #[test]
    fn bad_triggers_say_why() {
        for (text, why) in [
            ("", "empty"),
            ("mac=64", "0..=63"),
            ("kind=loud", "unknown message kind"),
            ("colour=red", "unknown key"),
            ("id=0x800", "11-bit"),
            ("data=0094/FF", "as many"),
            ("mac", "KEY=VALUE"),
        ] {
            let e = text.parse::<Pattern>().unwrap_err();
            assert!(e.contains(why), "{text}: {e}");
        }
    }

    #[test]
    fn filters_need_every_list_given() {
        let f = Filter { macs: vec![5], groups: vec![], kinds: vec![KindMatch::Explicit] };
        let error = frame(0x42B, &[0x00, 0x94, 0x08, 0xFF]);
        assert!(f.passes(classify(&error)));
        assert!(!f.passes(classify(&frame(0x3C5, &[1]))));
        assert!(!f.passes(classify(&frame(0x433, &[0x00, 0x94, 0x08, 0xFF]))));
        assert!(Filter::default().passes(classify(&frame(0x7E0, &[]))));
    }
}
