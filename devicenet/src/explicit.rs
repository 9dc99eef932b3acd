//! Explicit messages: the header byte, service codes, message body formats, requests, responses
//! and error responses (protocol §3.1–§3.3).
//!
//! A *message* here is what one explicit transaction carries after reassembly: the header byte
//! followed by the *body* (service byte onward). Unfragmented messages fit in one frame (header +
//! at most 7 body bytes); longer ones travel with the acknowledged fragmentation protocol of
//! [`crate::fragment`], which re-creates the same header + body.
//!
//! No-panic contract: every `parse` takes any byte slice and returns a value or an
//! [`ExplicitError`]; every `emit` checks the buffer length first.

use crate::id::MacId;
use core::fmt;

/// Why an explicit message could not be parsed or emitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ExplicitError {
    /// The message or body is shorter than its format requires.
    Truncated {
        /// Bytes required.
        needed: usize,
        /// Bytes present.
        got: usize,
    },
    /// The output buffer is too small.
    BufferTooSmall {
        /// Bytes required.
        needed: usize,
        /// Bytes available.
        got: usize,
    },
    /// A reserved message body format code (5–15).
    ReservedBodyFormat(u8),
    /// The CIP path (body format 4) is not a supported logical class/instance path.
    UnsupportedPath,
    /// A request was expected (R/R bit 0) but the body is a response.
    NotARequest,
    /// A response was expected (R/R bit 1) but the body is a request.
    NotAResponse,
    /// A class or instance number does not fit the chosen body format.
    PathTooWide,
}

impl fmt::Display for ExplicitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ExplicitError::Truncated { needed, got } => {
                write!(f, "message truncated: needs {needed} bytes, has {got}")
            }
            ExplicitError::BufferTooSmall { needed, got } => {
                write!(f, "buffer too small: needs {needed} bytes, has {got}")
            }
            ExplicitError::ReservedBodyFormat(c) => write!(f, "reserved message body format {c}"),
            ExplicitError::UnsupportedPath => f.write_str("unsupported CIP path"),
            ExplicitError::NotARequest => f.write_str("expected a request, found a response"),
            ExplicitError::NotAResponse => f.write_str("expected a response, found a request"),
            ExplicitError::PathTooWide => {
                f.write_str("class or instance does not fit the message body format")
            }
        }
    }
}

impl core::error::Error for ExplicitError {}

/// The explicit header byte: `frag(7) | XID(6) | MAC(5–0)` (protocol §3.1).
///
/// In the Predefined Master/Slave Connection Set the MAC is always the master's (protocol §2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    /// The fragmentation bit: a fragmentation protocol byte follows.
    pub fragmented: bool,
    /// The transaction ID, echoed by the server.
    pub xid: bool,
    /// Source MAC in requests, destination MAC in responses.
    pub mac: MacId,
}

impl Header {
    /// Decodes a header byte; every byte is a valid header.
    // Always inlined: callers read one or two of its fields (some 30 bytes of the firmware's
    // flash).
    #[inline(always)]
    pub const fn from_byte(b: u8) -> Header {
        Header { fragmented: b & 0x80 != 0, xid: b & 0x40 != 0, mac: MacId::from_low_bits(b) }
    }

    /// Encodes the header byte.
    pub const fn to_byte(self) -> u8 {
        (self.fragmented as u8) << 7 | (self.xid as u8) << 6 | self.mac.as_raw()
    }

    /// An unfragmented header.
    pub const fn new(xid: bool, mac: MacId) -> Header {
        Header { fragmented: false, xid, mac }
    }
}

macro_rules! code_enum {
    (
        $(#[$meta:meta])*
        pub enum $name:ident {
            $( $(#[$vmeta:meta])* $variant:ident = $value:literal => $text:literal, )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        // Each known variant's tag is its code, so the conversions to and from `u8` compile to a
        // range check instead of two jump tables (firmware size budget).
        #[repr(u8)]
        pub enum $name {
            $( $(#[$vmeta])* $variant = $value, )*
            /// A code this crate has no name for, kept as received.
            Unknown(u8),
        }

        impl From<u8> for $name {
            fn from(raw: u8) -> $name {
                match raw {
                    $( $value => $name::$variant, )*
                    other => $name::Unknown(other),
                }
            }
        }

        impl From<$name> for u8 {
            fn from(v: $name) -> u8 {
                match v {
                    $( $name::$variant => $value, )*
                    $name::Unknown(raw) => raw,
                }
            }
        }

        impl $name {
            /// The code as a number.
            pub fn as_raw(self) -> u8 {
                u8::from(self)
            }

            /// The name the specification gives the code, if known.
            pub fn name(self) -> Option<&'static str> {
                match self {
                    $( $name::$variant => Some($text), )*
                    $name::Unknown(_) => None,
                }
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                match self.name() {
                    Some(n) => write!(f, "{} (0x{:02X})", n, self.as_raw()),
                    None => write!(f, "unknown (0x{:02X})", self.as_raw()),
                }
            }
        }
    };
}

code_enum! {
    /// A service code, without the R/R bit (protocol §3.2). Codes 0x4B–0x4E are object-specific: the
    /// names below are those of the DeviceNet object; UCMM and Group 4 reuse the numbers.
    pub enum ServiceCode {
        /// 0x01
        GetAttributesAll = 0x01 => "Get_Attributes_All",
        /// 0x02
        SetAttributesAll = 0x02 => "Set_Attributes_All",
        /// 0x03
        GetAttributeList = 0x03 => "Get_Attribute_List",
        /// 0x04
        SetAttributeList = 0x04 => "Set_Attribute_List",
        /// 0x05
        Reset = 0x05 => "Reset",
        /// 0x06
        Start = 0x06 => "Start",
        /// 0x07
        Stop = 0x07 => "Stop",
        /// 0x08
        Create = 0x08 => "Create",
        /// 0x09
        Delete = 0x09 => "Delete",
        /// 0x0A
        MultipleServicePacket = 0x0A => "Multiple_Service_Packet",
        /// 0x0D
        ApplyAttributes = 0x0D => "Apply_Attributes",
        /// 0x0E
        GetAttributeSingle = 0x0E => "Get_Attribute_Single",
        /// 0x10
        SetAttributeSingle = 0x10 => "Set_Attribute_Single",
        /// 0x11
        FindNextObjectInstance = 0x11 => "Find_Next_Object_Instance",
        /// 0x14, sent as 0x94
        ErrorResponse = 0x14 => "Error_Response",
        /// 0x15
        Restore = 0x15 => "Restore",
        /// 0x16
        Save = 0x16 => "Save",
        /// 0x17
        Nop = 0x17 => "NOP",
        /// 0x18
        GetMember = 0x18 => "Get_Member",
        /// 0x19
        SetMember = 0x19 => "Set_Member",
        /// 0x1A
        InsertMember = 0x1A => "Insert_Member",
        /// 0x1B
        RemoveMember = 0x1B => "Remove_Member",
        /// 0x1C
        GroupSync = 0x1C => "Group_Sync",
        /// 0x4B: DeviceNet object Allocate (UCMM: Open Explicit Messaging Connection)
        AllocateMasterSlave = 0x4B => "Allocate_Master/Slave_Connection_Set",
        /// 0x4C: DeviceNet object Release (UCMM: Close Connection)
        ReleaseMasterSlave = 0x4C => "Release_Master/Slave_Connection_Set",
        /// 0x4D: Device Heartbeat (Group 4: Change MAC ID)
        DeviceHeartbeat = 0x4D => "Device_Heartbeat",
        /// 0x4E: Device Shutdown
        DeviceShutdown = 0x4E => "Device_Shutdown",
    }
}

code_enum! {
    /// A CIP general status code (protocol §3.3).
    pub enum GeneralStatus {
        /// 0x00
        Success = 0x00 => "success",
        /// 0x01
        ConnectionFailure = 0x01 => "connection failure",
        /// 0x02
        ResourceUnavailable = 0x02 => "resource unavailable",
        /// 0x03
        InvalidParameterValue = 0x03 => "invalid parameter value",
        /// 0x04
        PathSegmentError = 0x04 => "path segment error",
        /// 0x05
        PathDestinationUnknown = 0x05 => "path destination unknown",
        /// 0x06
        PartialTransfer = 0x06 => "partial transfer",
        /// 0x07
        ConnectionLost = 0x07 => "connection lost",
        /// 0x08
        ServiceNotSupported = 0x08 => "service not supported",
        /// 0x09
        InvalidAttributeValue = 0x09 => "invalid attribute value",
        /// 0x0A
        AttributeListError = 0x0A => "attribute list error",
        /// 0x0B
        AlreadyInRequestedState = 0x0B => "already in requested mode/state",
        /// 0x0C
        ObjectStateConflict = 0x0C => "object state conflict",
        /// 0x0D
        ObjectAlreadyExists = 0x0D => "object already exists",
        /// 0x0E
        AttributeNotSettable = 0x0E => "attribute not settable",
        /// 0x0F
        PrivilegeViolation = 0x0F => "privilege violation",
        /// 0x10
        DeviceStateConflict = 0x10 => "device state conflict",
        /// 0x11
        ReplyDataTooLarge = 0x11 => "reply data too large",
        /// 0x12
        FragmentationOfPrimitive = 0x12 => "fragmentation of a primitive value",
        /// 0x13
        NotEnoughData = 0x13 => "not enough data",
        /// 0x14
        AttributeNotSupported = 0x14 => "attribute not supported",
        /// 0x15
        TooMuchData = 0x15 => "too much data",
        /// 0x16
        ObjectDoesNotExist = 0x16 => "object does not exist",
        /// 0x17
        FragmentationOutOfSequence = 0x17 => "service fragmentation sequence not in progress",
        /// 0x18
        NoStoredAttributeData = 0x18 => "no stored attribute data",
        /// 0x19
        StoreOperationFailure = 0x19 => "store operation failure",
        /// 0x1A
        RequestTooLarge = 0x1A => "routing failure, request packet too large",
        /// 0x1B
        ResponseTooLarge = 0x1B => "routing failure, response packet too large",
        /// 0x1C
        MissingAttributeListEntry = 0x1C => "missing attribute list entry data",
        /// 0x1D
        InvalidAttributeValueList = 0x1D => "invalid attribute value list",
        /// 0x1E
        EmbeddedServiceError = 0x1E => "embedded service error",
        /// 0x1F
        VendorSpecific = 0x1F => "vendor specific error",
        /// 0x20
        InvalidParameter = 0x20 => "invalid parameter",
        /// 0x21
        WriteOnceAlreadyWritten = 0x21 => "write-once value or medium already written",
        /// 0x22
        InvalidReplyReceived = 0x22 => "invalid reply received",
        /// 0x25
        KeyFailureInPath = 0x25 => "key failure in path",
        /// 0x26
        PathSizeInvalid = 0x26 => "path size invalid",
        /// 0x27
        UnexpectedAttributeInList = 0x27 => "unexpected attribute in list",
        /// 0x28
        InvalidMemberId = 0x28 => "invalid member ID",
        /// 0x29
        MemberNotSettable = 0x29 => "member not settable",
        /// 0x2A
        Group2OnlyServerFailure = 0x2A => "Group 2 only server general failure",
    }
}

/// Additional status codes used with the Predefined Master/Slave Connection Set (protocol §3.3, §3.4).
pub mod additional {
    /// No additional information.
    pub const NONE: u8 = 0xFF;
    /// Allocation conflict: the set is owned by another master.
    pub const ALLOCATION_CONFLICT: u8 = 0x01;
    /// Invalid allocation or release choice.
    pub const INVALID_CHOICE: u8 = 0x02;
    /// Invalid request on the Group 2 Only Unconnected port.
    pub const INVALID_GROUP2_ONLY_REQUEST: u8 = 0x03;
    /// A resource needed for the requested connections is unavailable.
    pub const RESOURCE_UNAVAILABLE: u8 = 0x04;

    /// A human name for an additional code returned with a Predefined Set error.
    pub fn name(code: u8) -> Option<&'static str> {
        match code {
            NONE => Some("no additional code"),
            ALLOCATION_CONFLICT => Some("allocation conflict"),
            INVALID_CHOICE => Some("invalid allocation/release choice"),
            INVALID_GROUP2_ONLY_REQUEST => Some("invalid request on the Group 2 Only port"),
            RESOURCE_UNAVAILABLE => Some("resource unavailable for the requested connections"),
            _ => None,
        }
    }
}

/// The message body format: the widths of the class and instance IDs in a request (protocol §3.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BodyFormat {
    /// 0: 8-bit class, 8-bit instance.
    Class8Instance8,
    /// 1: 8-bit class, 16-bit instance.
    Class8Instance16,
    /// 2: 16-bit class, 16-bit instance.
    Class16Instance16,
    /// 3: 16-bit class, 8-bit instance.
    Class16Instance8,
    /// 4: a CIP path (size in words, then logical segments).
    CipPath,
    /// 5–15: reserved.
    Reserved(u8),
}

impl BodyFormat {
    /// The format for a 4-bit code.
    pub const fn from_code(code: u8) -> BodyFormat {
        match code & 0xF {
            0 => BodyFormat::Class8Instance8,
            1 => BodyFormat::Class8Instance16,
            2 => BodyFormat::Class16Instance16,
            3 => BodyFormat::Class16Instance8,
            4 => BodyFormat::CipPath,
            other => BodyFormat::Reserved(other),
        }
    }

    /// The 4-bit code.
    pub const fn code(self) -> u8 {
        match self {
            BodyFormat::Class8Instance8 => 0,
            BodyFormat::Class8Instance16 => 1,
            BodyFormat::Class16Instance16 => 2,
            BodyFormat::Class16Instance8 => 3,
            BodyFormat::CipPath => 4,
            BodyFormat::Reserved(c) => c & 0xF,
        }
    }

    /// Bytes taken by the class and instance fields in the fixed formats.
    const fn widths(self) -> Option<(usize, usize)> {
        match self {
            BodyFormat::Class8Instance8 => Some((1, 1)),
            BodyFormat::Class8Instance16 => Some((1, 2)),
            BodyFormat::Class16Instance16 => Some((2, 2)),
            BodyFormat::Class16Instance8 => Some((2, 1)),
            _ => None,
        }
    }
}

/// Writes `bytes` to the front of `buf`; the caller has checked that they fit (an emit's
/// `BufferTooSmall` check), so none is dropped.
fn write_front(buf: &mut [u8], bytes: impl IntoIterator<Item = u8>) {
    for (out, byte) in buf.iter_mut().zip(bytes) {
        *out = byte;
    }
}

/// A little-endian class or instance ID of 1 or 2 bytes.
fn read_le(bytes: &[u8]) -> u16 {
    match bytes {
        [a] => u16::from(*a),
        [a, b] => u16::from_le_bytes([*a, *b]),
        _ => 0,
    }
}

/// An explicit request body: service, class, instance and service data (protocol §3.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Request<'a> {
    /// The service requested.
    pub service: ServiceCode,
    /// The class ID.
    pub class: u16,
    /// The instance ID (0 addresses the class itself).
    pub instance: u16,
    /// Service data: attribute ID, value, and so on.
    pub data: &'a [u8],
}

impl<'a> Request<'a> {
    /// Parses a request body (service byte onward) in `format`.
    // Inlined: a caller's constant body format folds the other formats away (some 45 bytes of
    // the firmware's flash).
    #[inline]
    pub fn parse(body: &'a [u8], format: BodyFormat) -> Result<Request<'a>, ExplicitError> {
        let (&service, rest) = body.split_first().ok_or(ExplicitError::Truncated { needed: 1, got: 0 })?;
        if service & 0x80 != 0 {
            return Err(ExplicitError::NotARequest);
        }
        let service = ServiceCode::from(service);
        match format.widths() {
            Some((cw, iw)) => {
                let truncated = ExplicitError::Truncated { needed: 1 + cw + iw, got: body.len() };
                let (class, rest) = rest.split_at_checked(cw).ok_or(truncated)?;
                let (instance, data) = rest.split_at_checked(iw).ok_or(truncated)?;
                Ok(Request { service, class: read_le(class), instance: read_le(instance), data })
            }
            None => match format {
                BodyFormat::CipPath => Self::parse_path(service, rest),
                BodyFormat::Reserved(c) => Err(ExplicitError::ReservedBodyFormat(c)),
                _ => Err(ExplicitError::UnsupportedPath),
            },
        }
    }

    /// Body format 4: `<path size in words> <logical class segment> <logical instance segment>`.
    fn parse_path(service: ServiceCode, rest: &'a [u8]) -> Result<Request<'a>, ExplicitError> {
        let (&words, path) = rest.split_first().ok_or(ExplicitError::Truncated { needed: 2, got: 1 })?;
        let len = usize::from(words) * 2;
        if path.len() < len {
            return Err(ExplicitError::Truncated { needed: 2 + len, got: 1 + rest.len() });
        }
        let (mut segments, data) = path.split_at(len);
        let mut class = None;
        let mut instance = None;
        while let Some((&seg, tail)) = segments.split_first() {
            let (value, rest) = match (seg, tail) {
                (0x20 | 0x24, [v, rest @ ..]) => (u16::from(*v), rest),
                (0x21 | 0x25, [_pad, lo, hi, rest @ ..]) => (u16::from_le_bytes([*lo, *hi]), rest),
                _ => return Err(ExplicitError::UnsupportedPath),
            };
            match seg {
                0x20 | 0x21 if class.is_none() => class = Some(value),
                0x24 | 0x25 if class.is_some() && instance.is_none() => instance = Some(value),
                _ => return Err(ExplicitError::UnsupportedPath),
            }
            segments = rest;
        }
        match (class, instance) {
            (Some(class), Some(instance)) => Ok(Request { service, class, instance, data }),
            _ => Err(ExplicitError::UnsupportedPath),
        }
    }

    /// Bytes [`Request::emit`] writes in `format`; `None` for formats this crate does not emit.
    pub fn buffer_len(&self, format: BodyFormat) -> Option<usize> {
        format.widths().map(|(cw, iw)| 1 + cw + iw + self.data.len())
    }

    /// Writes the body into `buf`, returning its length.
    pub fn emit(&self, format: BodyFormat, buf: &mut [u8]) -> Result<usize, ExplicitError> {
        let (cw, iw) = match format {
            BodyFormat::Reserved(c) => return Err(ExplicitError::ReservedBodyFormat(c)),
            other => other.widths().ok_or(ExplicitError::UnsupportedPath)?,
        };
        if (cw == 1 && self.class > 0xFF) || (iw == 1 && self.instance > 0xFF) {
            return Err(ExplicitError::PathTooWide);
        }
        let needed = 1 + cw + iw + self.data.len();
        if buf.len() < needed {
            return Err(ExplicitError::BufferTooSmall { needed, got: buf.len() });
        }
        // Service, then the low `cw` bytes of the class and `iw` of the instance, then the data.
        let body = [self.service.as_raw() & 0x7F]
            .into_iter()
            .chain(self.class.to_le_bytes().into_iter().take(cw))
            .chain(self.instance.to_le_bytes().into_iter().take(iw))
            .chain(self.data.iter().copied());
        write_front(buf, body);
        Ok(needed)
    }
}

/// An explicit response body (protocol §3.2, §3.3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Response<'a> {
    /// `<service | 0x80> <data…>`.
    Success {
        /// The service being answered.
        service: ServiceCode,
        /// Service response data.
        data: &'a [u8],
    },
    /// `94 <general status> <additional code>`; `FF` means no additional code.
    Error {
        /// The general status.
        general: GeneralStatus,
        /// The additional code ([`additional::NONE`] when there is none).
        additional: u8,
    },
}

impl<'a> Response<'a> {
    /// Parses a response body (service byte onward).
    ///
    /// An error response shorter than 3 bytes is accepted with the missing codes reported as
    /// `Unknown`/`NONE`, since some devices send `94 <general>` alone.
    pub fn parse(body: &'a [u8]) -> Result<Response<'a>, ExplicitError> {
        let (&service, data) = body.split_first().ok_or(ExplicitError::Truncated { needed: 1, got: 0 })?;
        if service & 0x80 == 0 {
            return Err(ExplicitError::NotAResponse);
        }
        let service = ServiceCode::from(service & 0x7F);
        if service == ServiceCode::ErrorResponse {
            let general = match data.first() {
                Some(&g) => GeneralStatus::from(g),
                None => return Err(ExplicitError::Truncated { needed: 2, got: 1 }),
            };
            let additional = data.get(1).copied().unwrap_or(additional::NONE);
            Ok(Response::Error { general, additional })
        } else {
            Ok(Response::Success { service, data })
        }
    }

    /// Bytes [`Response::emit`] writes.
    pub fn buffer_len(&self) -> usize {
        match self {
            Response::Success { data, .. } => 1 + data.len(),
            Response::Error { .. } => 3,
        }
    }

    /// Writes the body into `buf`, returning its length.
    pub fn emit(&self, buf: &mut [u8]) -> Result<usize, ExplicitError> {
        let needed = self.buffer_len();
        if buf.len() < needed {
            return Err(ExplicitError::BufferTooSmall { needed, got: buf.len() });
        }
        match self {
            Response::Success { service, data } => {
                write_front(buf, [0x80 | service.as_raw()].into_iter().chain(data.iter().copied()));
            }
            Response::Error { general, additional } => {
                let error = 0x80 | ServiceCode::ErrorResponse.as_raw();
                write_front(buf, [error, general.as_raw(), *additional]);
            }
        }
        Ok(needed)
    }

    /// `true` for an error response.
    pub fn is_error(&self) -> bool {
        matches!(self, Response::Error { .. })
    }
}

/// Splits a whole explicit message (header + body) into its header and body.
pub fn split_message(message: &[u8]) -> Result<(Header, &[u8]), ExplicitError> {
    match message.split_first() {
        Some((&h, body)) if !body.is_empty() => Ok((Header::from_byte(h), body)),
        _ => Err(ExplicitError::Truncated { needed: 2, got: message.len() }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    fn mac(n: u8) -> MacId {
        MacId::new(n).unwrap()
    }

    #[rstest]
    #[case::master0(0x00, Header { fragmented: false, xid: false, mac: mac(0) })]
    #[case::xid_set(0x40, Header { fragmented: false, xid: true, mac: mac(0) })]
    #[case::fragmented_mac3(0x83, Header { fragmented: true, xid: false, mac: mac(3) })]
    #[case::all_bits(0xFF, Header { fragmented: true, xid: true, mac: mac(63) })]
    #[case::icp_master_0a(0x0A, Header { fragmented: false, xid: false, mac: mac(10) })]
    fn header_codec(#[case] byte: u8, #[case] header: Header) {
        assert_eq!(Header::from_byte(byte), header);
        assert_eq!(header.to_byte(), byte);
    }

    #[rstest]
    #[case::get_vendor_id(&[0x0E, 0x01, 0x01, 0x01], BodyFormat::Class8Instance8, ServiceCode::GetAttributeSingle, 1, 1, &[0x01])]
    #[case::set_watchdog_action(&[0x10, 0x05, 0x01, 0x0C, 0x03], BodyFormat::Class8Instance8, ServiceCode::SetAttributeSingle, 5, 1, &[0x0C, 0x03])]
    #[case::allocate(&[0x4B, 0x03, 0x01, 0x01, 0x00], BodyFormat::Class8Instance8, ServiceCode::AllocateMasterSlave, 3, 1, &[0x01, 0x00])]
    #[case::format_8_16(&[0x0E, 0x04, 0x34, 0x12, 0x03], BodyFormat::Class8Instance16, ServiceCode::GetAttributeSingle, 4, 0x1234, &[0x03])]
    #[case::format_16_16(&[0x0E, 0x64, 0x00, 0x01, 0x00, 0x02], BodyFormat::Class16Instance16, ServiceCode::GetAttributeSingle, 0x64, 1, &[0x02])]
    #[case::format_16_8(&[0x01, 0x00, 0x01, 0x07], BodyFormat::Class16Instance8, ServiceCode::GetAttributesAll, 0x100, 7, &[])]
    #[case::unknown_service(&[0x33, 0x01, 0x01], BodyFormat::Class8Instance8, ServiceCode::Unknown(0x33), 1, 1, &[])]
    fn request_codec(
        #[case] bytes: &[u8],
        #[case] format: BodyFormat,
        #[case] service: ServiceCode,
        #[case] class: u16,
        #[case] instance: u16,
        #[case] data: &[u8],
    ) {
        let req = Request::parse(bytes, format).unwrap();
        assert_eq!(req, Request { service, class, instance, data });
        let mut buf = [0u8; 16];
        let n = req.emit(format, &mut buf).unwrap();
        assert_eq!(&buf[..n], bytes);
        assert_eq!(req.buffer_len(format), Some(n));
    }

    #[rstest]
    #[case::empty(&[], BodyFormat::Class8Instance8, ExplicitError::Truncated { needed: 1, got: 0 })]
    #[case::no_instance(&[0x0E, 0x01], BodyFormat::Class8Instance8, ExplicitError::Truncated { needed: 3, got: 2 })]
    #[case::short_16_16(&[0x0E, 0x01, 0x00, 0x01], BodyFormat::Class16Instance16, ExplicitError::Truncated { needed: 5, got: 4 })]
    #[case::response_bit(&[0x8E, 0x01, 0x01], BodyFormat::Class8Instance8, ExplicitError::NotARequest)]
    #[case::reserved_format(&[0x0E, 0x01, 0x01], BodyFormat::Reserved(7), ExplicitError::ReservedBodyFormat(7))]
    fn request_errors(#[case] bytes: &[u8], #[case] format: BodyFormat, #[case] err: ExplicitError) {
        assert_eq!(Request::parse(bytes, format), Err(err));
    }

    #[rstest]
    #[case::eight_bit(&[0x0E, 0x02, 0x20, 0x01, 0x24, 0x01, 0x07], 1, 1, &[0x07])]
    #[case::sixteen_bit(&[0x0E, 0x04, 0x21, 0x00, 0x00, 0x01, 0x25, 0x00, 0x02, 0x00, 0x03], 0x100, 2, &[0x03])]
    fn cip_path_requests(
        #[case] bytes: &[u8],
        #[case] class: u16,
        #[case] instance: u16,
        #[case] data: &[u8],
    ) {
        let req = Request::parse(bytes, BodyFormat::CipPath).unwrap();
        assert_eq!((req.class, req.instance, req.data), (class, instance, data));
    }

    #[rstest]
    #[case::no_instance(&[0x0E, 0x01, 0x20, 0x01])]
    #[case::attribute_segment(&[0x0E, 0x02, 0x30, 0x01, 0x24, 0x01])]
    #[case::size_beyond_data(&[0x0E, 0x05, 0x20, 0x01])]
    #[case::no_size(&[0x0E])]
    fn cip_path_errors(#[case] bytes: &[u8]) {
        assert!(Request::parse(bytes, BodyFormat::CipPath).is_err());
    }

    #[test]
    fn emit_checks_widths_and_buffer() {
        let req = Request { service: ServiceCode::GetAttributeSingle, class: 0x100, instance: 1, data: &[1] };
        assert_eq!(req.emit(BodyFormat::Class8Instance8, &mut [0; 8]), Err(ExplicitError::PathTooWide));
        assert_eq!(
            req.emit(BodyFormat::Class16Instance8, &mut [0; 3]),
            Err(ExplicitError::BufferTooSmall { needed: 5, got: 3 })
        );
    }

    #[rstest]
    #[case::allocate_ok(&[0xCB, 0x00], Response::Success { service: ServiceCode::AllocateMasterSlave, data: &[0x00] })]
    #[case::set_ok(&[0x90], Response::Success { service: ServiceCode::SetAttributeSingle, data: &[] })]
    #[case::vendor(&[0x8E, 0x34, 0x12], Response::Success { service: ServiceCode::GetAttributeSingle, data: &[0x34, 0x12] })]
    #[case::release_ok(&[0xCC], Response::Success { service: ServiceCode::ReleaseMasterSlave, data: &[] })]
    #[case::allocation_conflict(&[0x94, 0x0C, 0x01], Response::Error { general: GeneralStatus::ObjectStateConflict, additional: 0x01 })]
    #[case::service_not_supported(&[0x94, 0x08, 0xFF], Response::Error { general: GeneralStatus::ServiceNotSupported, additional: additional::NONE })]
    #[case::group2_port(&[0x94, 0x02, 0x03], Response::Error { general: GeneralStatus::ResourceUnavailable, additional: 0x03 })]
    #[case::unknown_status(&[0x94, 0xD5, 0x00], Response::Error { general: GeneralStatus::Unknown(0xD5), additional: 0x00 })]
    fn response_codec(#[case] bytes: &[u8], #[case] resp: Response<'static>) {
        assert_eq!(Response::parse(bytes), Ok(resp));
        let mut buf = [0u8; 8];
        let n = resp.emit(&mut buf).unwrap();
        assert_eq!(&buf[..n], bytes);
    }

    #[test]
    fn short_error_response_is_tolerated() {
        assert_eq!(
            Response::parse(&[0x94, 0x08]),
            Ok(Response::Error { general: GeneralStatus::ServiceNotSupported, additional: additional::NONE })
        );
        assert_eq!(Response::parse(&[0x94]), Err(ExplicitError::Truncated { needed: 2, got: 1 }));
        assert_eq!(Response::parse(&[0x0E]), Err(ExplicitError::NotAResponse));
        assert_eq!(Response::parse(&[]), Err(ExplicitError::Truncated { needed: 1, got: 0 }));
    }

    #[test]
    fn every_code_round_trips() {
        for raw in 0..=0xFFu8 {
            assert_eq!(ServiceCode::from(raw).as_raw(), raw);
            assert_eq!(GeneralStatus::from(raw).as_raw(), raw);
        }
        assert_eq!(GeneralStatus::from(0x0C).name(), Some("object state conflict"));
        assert_eq!(ServiceCode::from(0x4B).name(), Some("Allocate_Master/Slave_Connection_Set"));
    }

    #[test]
    fn body_format_codes() {
        for code in 0..16u8 {
            assert_eq!(BodyFormat::from_code(code).code(), code);
        }
        assert_eq!(BodyFormat::from_code(9), BodyFormat::Reserved(9));
    }

    #[test]
    fn message_split() {
        let (h, body) = split_message(&[0x00, 0x0E, 0x01, 0x01, 0x01]).unwrap();
        assert_eq!(h, Header::new(false, mac(0)));
        assert_eq!(body, &[0x0E, 0x01, 0x01, 0x01]);
        assert!(split_message(&[0x00]).is_err());
    }
}
