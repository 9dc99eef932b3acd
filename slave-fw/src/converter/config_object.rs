//! The configuration object, vendor class [`CONFIG_CLASS`] 0x66, instance 1: how a tool reads the
//! configuration image in force and downloads a new one over the bus ([`super::image`]).
//!
//! | attribute | type | value |
//! |---|---|---|
//! | 1 | USINT | image format version ([`IMAGE_VERSION`]) |
//! | 2 | UINT | size of the image in force |
//! | 3 | USINT | [`ConfigState`]: 0 factory default in force, 1 stored image in force, 2 a new image is stored and applies at the next reset, 3 configuration fault (the stored image was refused, factory default in force) |
//! | 4 | UDINT | CRC-32 of the image in force (its trailer) |
//! | 5 | bytes | why the last download (or the stored image at start) was refused: a [`RefusalRecord`], no bytes if nothing was refused |
//!
//! Class attribute 1 is the revision, 1. Services (codes object-specific, protocol §3.2;
//! error codes §3.3):
//!
//! | code | service | request data | reply / errors |
//! |---|---|---|---|
//! | 0x0E | Get_Attribute_Single | attribute | 0x14 unknown attribute |
//! | 0x10 | Set_Attribute_Single | | 0x0E for attributes 1-5 (all read-only), 0x14 otherwise |
//! | 0x4B | [`READ_CHUNK`] | which USINT (0 in force, 1 pending), offset UINT, count USINT ≤ [`MAX_CHUNK`] | the bytes (fewer at the end, none past it); 0x0C which = 1 with nothing pending; 0x20 which > 1 or count > 56 |
//! | 0x4C | [`BEGIN_DOWNLOAD`] | size UINT | 0x15 size > [`MAX_IMAGE`]; 0x10 while an I/O connection is established |
//! | 0x4D | [`WRITE_CHUNK`] | offset UINT, ≤ 56 bytes | 0x0C no download begun; 0x20 offset ≠ bytes received; 0x15 past the size; 0x10 while I/O |
//! | 0x4E | [`COMMIT_DOWNLOAD`] | none | 0x0C not all bytes received; 0x09 refused, additional code ([`refusal_code`]) 1 header/version, 2 length, 3 CRC, 4 invalid configuration, also one the platform cannot run ([`PlatformCheck`]) (the reason in attribute 5) |
//!
//! An accepted image is not applied: the converter hands it to the application
//! ([`Converter::poll_new_image`](super::Converter::poll_new_image)), which stores it (firmware:
//! the settings journal; soft slave: its state file); it is in force from the next reset, when
//! the application builds the converter from it with
//! [`Converter::with_origin`](super::Converter::with_origin).
//!
//! Who may download: requests reach an object only over the explicit messaging connection of the
//! predefined master/slave set, and only the master that allocated it (its owner, DeviceNet object
//! Allocate, protocol §3.4) holds that connection; any other master's allocation is refused
//! by the node, so no other master can reach this object.

use super::image::{self, ImageError, IMAGE_VERSION, MAX_IMAGE};
use super::{ConverterConfig, InvalidConfig, KeyCode};
use crate::serial::Problem;
use core::fmt;
use devicenet::explicit::{GeneralStatus, Request, ServiceCode};
use devicenet::slave::config::MAX_PRODUCT_NAME;
use devicenet::slave::ConfigError as NodeConfigError;
use devicenet::slave::{Reply, ServiceError};
use devicenet::text::{self, TextSink};
use heapless::Vec;

/// Vendor-specific class of the configuration object, instance 1.
pub const CONFIG_CLASS: u16 = 0x66;
/// Read_Chunk: part of the image in force or of the pending image.
pub const READ_CHUNK: u8 = 0x4B;
/// Begin_Download: announces the size of a new image.
pub const BEGIN_DOWNLOAD: u8 = 0x4C;
/// Write_Chunk: the next bytes of the new image.
pub const WRITE_CHUNK: u8 = 0x4D;
/// Commit_Download: decode and check the new image, then hand it over for storage.
pub const COMMIT_DOWNLOAD: u8 = 0x4E;
/// The most image bytes in one Read_Chunk reply or Write_Chunk request.
pub const MAX_CHUNK: usize = 56;
/// The record's fixed part: kind, problem and three numbers ([`RefusalRecord`]).
pub const REFUSAL_HEADER: usize = 14;
/// The longest refusal record (attribute 5): the fixed part and a key ([`KeyCode`]).
pub const MAX_REFUSAL: usize = REFUSAL_HEADER + 4;

/// Where the configuration in force came from; the application says so when it builds the
/// converter ([`Converter::with_origin`](super::Converter::with_origin)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ConfigOrigin {
    /// The factory default (the firmware's preset, the description file), nothing stored.
    FactoryDefault,
    /// The stored image, decoded and accepted.
    Stored,
    /// The stored image was refused for this reason; the factory default is in force.
    Fault(ImageError),
}

impl ConfigOrigin {
    /// What runs after a reset: the stored image when there is one and it decodes
    /// ([`ConfigOrigin::Stored`]), else `factory` — as [`ConfigOrigin::FactoryDefault`] when
    /// nothing is stored, as [`ConfigOrigin::Fault`] with the reason when the stored image is
    /// refused. The one rule of the firmware, the soft slave and the simulated device.
    ///
    /// The serial number stays `factory`'s whatever runs: it is the device's own (the board's
    /// from its MCU, [`BoardFacts`](super::BoardFacts)), and a stored image's, written by a tool
    /// from a description shared by many devices, would give them all one.
    pub fn resolve(factory: &ConverterConfig, stored: Option<&[u8]>) -> (ConverterConfig, ConfigOrigin) {
        match stored.filter(|s| !s.is_empty()).map(super::image::decode) {
            None => (factory.clone(), ConfigOrigin::FactoryDefault),
            Some(Ok(mut config)) => {
                config.device.identity.serial_number = factory.device.identity.serial_number;
                (config, ConfigOrigin::Stored)
            }
            Some(Err(e)) => (factory.clone(), ConfigOrigin::Fault(e)),
        }
    }
}

/// Attribute 3 of the configuration object.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum ConfigState {
    /// 0: the factory default is in force.
    FactoryDefault = 0,
    /// 1: the stored image is in force.
    Stored = 1,
    /// 2: a new image is stored and applies at the next reset.
    Pending = 2,
    /// 3: the stored image was refused; the factory default is in force.
    Fault = 3,
}

/// The additional code of a Commit_Download refusal (general status 0x09): 1 header or version,
/// 2 length, 3 CRC, 4 invalid configuration.
pub const fn refusal_code(e: &ImageError) -> u8 {
    match e {
        ImageError::BadMagic | ImageError::UnsupportedVersion(_) => 1,
        ImageError::Truncated(_)
        | ImageError::TooLarge(_)
        | ImageError::LengthMismatch { .. }
        | ImageError::BufferTooSmall => 2,
        ImageError::CrcMismatch { .. } => 3,
        ImageError::Malformed { .. } | ImageError::Invalid(_) => 4,
    }
}

/// Attribute 5, why a download or the stored image was refused, as the device sends it: numbers,
/// not sentences nor key texts (the device carries neither; a tool words the record with the same
/// words as the description loader, [`RefusalRecord::write_text`]).
///
/// ```text
/// offset  size  field
/// 0       1     kind: 1 truncated (a = length), 2 too large (a = length), 3 not an image (bad
///               magic), 4 unsupported version (a), 5 length mismatch (a = stated, b = actual),
///               6 CRC mismatch (a = stated, b = computed), 7 malformed body (a = offset),
///               8 invalid configuration (problem, key), 9 buffer too small
/// 1       1     problem, kind 8 only: 1 out of range (a = value, b..=c the allowed range),
///               2 conflicts with another setting (a = the reason, `Conflict::code`), 3 overlaps the image bytes of entry a,
///               4 duplicates entry a, 5 not printable ASCII, 6 the node refuses the I/O
///               configuration (a = the node's error code 0..=6, b = the I/O size), 0 other
/// 2       12    a, b, c: UDINT each, 0 where unused
/// 14      4     kind 8: the key, as numbers ([`KeyCode`]: scope, number, list index)
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RefusalRecord {
    kind: u8,
    problem: u8,
    numbers: [u32; 3],
    key: Option<KeyCode>,
}

impl RefusalRecord {
    /// Writes the record for `e` into `reply` (attribute 5): the fixed part, then the key of an
    /// invalid configuration.
    pub fn write(e: &ImageError, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        reply.bytes(&RefusalRecord::header(e))?;
        let ImageError::Invalid(invalid) = e else { return Ok(()) };
        reply.bytes(&invalid.key_code().0)
    }

    /// The record's fixed part for `e`; the key, if any, follows it ([`RefusalRecord::write`]).
    fn header(e: &ImageError) -> [u8; REFUSAL_HEADER] {
        let n = |v: usize| u32::try_from(v).unwrap_or(u32::MAX);
        let (kind, problem, [a, b, c]) = match *e {
            ImageError::Truncated(len) => (1, 0, [n(len), 0, 0]),
            ImageError::TooLarge(len) => (2, 0, [n(len), 0, 0]),
            ImageError::BadMagic => (3, 0, [0; 3]),
            ImageError::UnsupportedVersion(v) => (4, 0, [v.into(), 0, 0]),
            ImageError::LengthMismatch { stated, actual } => (5, 0, [stated.into(), n(actual), 0]),
            ImageError::CrcMismatch { stated, computed } => (6, 0, [stated, computed, 0]),
            ImageError::Malformed { offset } => (7, 0, [offset.into(), 0, 0]),
            ImageError::BufferTooSmall => (9, 0, [0; 3]),
            ImageError::Invalid(ref invalid) => {
                let (problem, numbers) = match *invalid {
                    InvalidConfig::ProductNameLength(len) => (1, [n(len), 1, MAX_PRODUCT_NAME as u32]),
                    InvalidConfig::ProductNameNotAscii => (5, [0; 3]),
                    InvalidConfig::MajorRevision(v) => (1, [v.into(), 1, 127]),
                    InvalidConfig::MacId(v) => (1, [v.into(), 0, 63]),
                    InvalidConfig::BaudRate(v) => (1, [v.into(), 0, 2]),
                    InvalidConfig::EprResolutionZero => (1, [0, 1, 65_535]),
                    InvalidConfig::Profile { error, .. } => match error.problem {
                        Problem::OutOfRange { value, min, max } => (1, [value, min, max]),
                        Problem::Conflict(why) => (2, [why.code().into(), 0, 0]),
                        Problem::Overlap { other } => (3, [other.into(), 0, 0]),
                        Problem::Duplicate { other } => (4, [other.into(), 0, 0]),
                    },
                    InvalidConfig::Io(e) => {
                        let size = match e {
                            NodeConfigError::IoSizeTooLarge { size } => size,
                            _ => 0,
                        };
                        (6, [node_error_code(&e), size.into(), 0])
                    }
                };
                (8, problem, numbers)
            }
        };
        let [a0, a1, a2, a3] = a.to_le_bytes();
        let [b0, b1, b2, b3] = b.to_le_bytes();
        let [c0, c1, c2, c3] = c.to_le_bytes();
        [kind, problem, a0, a1, a2, a3, b0, b1, b2, b3, c0, c1, c2, c3]
    }
}

impl RefusalRecord {
    /// Reads attribute 5; `None` when nothing was refused (no bytes) or the record is shorter than
    /// its fixed part. A key shorter than its four bytes is read as none.
    pub fn parse(bytes: &[u8]) -> Option<RefusalRecord> {
        let (header, key) = bytes.split_first_chunk::<REFUSAL_HEADER>()?;
        let key = key.first_chunk::<4>().map(|k| KeyCode(*k));
        let [kind, problem, a0, a1, a2, a3, b0, b1, b2, b3, c0, c1, c2, c3] = *header;
        let numbers = [
            u32::from_le_bytes([a0, a1, a2, a3]),
            u32::from_le_bytes([b0, b1, b2, b3]),
            u32::from_le_bytes([c0, c1, c2, c3]),
        ];
        Some(RefusalRecord { kind, problem, numbers, key })
    }

    /// The reason in words, those of [`ImageError`] and of the description loader
    /// (`profile.serial.baud: 4000000 is outside the allowed range 300..=2625000`).
    pub fn write_text(&self, out: &mut impl TextSink) {
        let [a, b, c] = self.numbers;
        let short = |v: u32| u16::try_from(v).unwrap_or(u16::MAX);
        let image = match self.kind {
            1 => ImageError::Truncated(a as usize),
            2 => ImageError::TooLarge(a as usize),
            3 => ImageError::BadMagic,
            4 => ImageError::UnsupportedVersion(a as u8),
            5 => ImageError::LengthMismatch { stated: short(a), actual: b as usize },
            6 => ImageError::CrcMismatch { stated: a, computed: b },
            7 => ImageError::Malformed { offset: short(a) },
            9 => ImageError::BufferTooSmall,
            8 => {
                match self.key {
                    Some(key) => key.write_text(out),
                    None => out.text("(no key)"),
                }
                out.text(": ");
                return match self.problem {
                    1 => Problem::OutOfRange { value: a, min: b, max: c }.write_text(out),
                    2 => match crate::serial::Conflict::from_code(a) {
                        Some(why) => out.text(why.text()),
                        None => out.text("conflicts with another setting"),
                    },
                    3 => Problem::Overlap { other: short(a) }.write_text(out),
                    4 => Problem::Duplicate { other: short(a) }.write_text(out),
                    5 => out.text("must be printable ASCII"),
                    6 => match node_error(a, short(b)) {
                        Some(e) => e.write_text(out),
                        None => out.text("the node refuses the I/O configuration"),
                    },
                    _ => out.text("refused"),
                };
            }
            other => {
                out.text("refusal of unknown kind ");
                return out.decimal(other.into());
            }
        };
        image.write_text(out);
    }
}

/// The node's configuration errors in a refusal record (problem 6), in declaration order.
const NODE_ERRORS: [NodeConfigError; 7] = [
    NodeConfigError::IoSizeTooLarge { size: 0 },
    NodeConfigError::SameAssemblyInstance,
    NodeConfigError::AssemblyInstanceZero,
    NodeConfigError::PortOutOfRange,
    NodeConfigError::ZeroEprResolution,
    NodeConfigError::ProductNameNotAscii,
    NodeConfigError::MajorRevisionOutOfRange,
];

/// The index of `e`'s kind in [`NODE_ERRORS`] (a test holds the two to the same order).
// A match rather than a search of the table: LLVM makes it the enum's own tag (some 50 bytes of
// flash).
fn node_error_code(e: &NodeConfigError) -> u32 {
    match e {
        NodeConfigError::IoSizeTooLarge { .. } => 0,
        NodeConfigError::SameAssemblyInstance => 1,
        NodeConfigError::AssemblyInstanceZero => 2,
        NodeConfigError::PortOutOfRange => 3,
        NodeConfigError::ZeroEprResolution => 4,
        NodeConfigError::ProductNameNotAscii => 5,
        NodeConfigError::MajorRevisionOutOfRange => 6,
    }
}

fn node_error(code: u32, size: u16) -> Option<NodeConfigError> {
    match NODE_ERRORS.get(usize::try_from(code).ok()?)? {
        NodeConfigError::IoSizeTooLarge { .. } => Some(NodeConfigError::IoSizeTooLarge { size }),
        other => Some(*other),
    }
}

impl fmt::Display for RefusalRecord {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Staging {
    /// Nothing in the staging buffer.
    Empty,
    /// A download of this many bytes is under way.
    Downloading(u16),
    /// The staging buffer holds an accepted image, stored for the next reset.
    Pending,
}

/// What the platform itself cannot run, checked at Commit_Download after the converter's own
/// checks ([`super::image::decode`]): the firmware's USART makes fewer serial lines than the
/// converter accepts. A configuration it refuses is refused like an invalid one (additional code
/// 4, the key and reason in attribute 5), so it is never stored. Set with
/// [`Converter::set_platform_check`](super::Converter::set_platform_check).
pub type PlatformCheck = fn(&ConverterConfig) -> Result<(), InvalidConfig>;

/// The configuration object's state, owned by the converter.
#[derive(Clone, Debug)]
pub struct ConfigObject {
    in_force: Vec<u8, MAX_IMAGE>,
    origin: ConfigOrigin,
    staged: Vec<u8, MAX_IMAGE>,
    staging: Staging,
    /// The application took an accepted image since start ([`ConfigObject::take_new_image`]): it
    /// is stored and applies at the next reset, even once a later download dropped its bytes.
    stored: bool,
    /// The accepted image waits for [`ConfigObject::take_new_image`].
    handed_over: bool,
    /// Why the last download or the stored image was refused (attribute 5).
    refusal: Option<ImageError>,
    /// The platform's own check of a downloaded configuration, if it has one.
    platform_check: Option<PlatformCheck>,
}

impl ConfigObject {
    /// The object for the image in force and its origin.
    pub fn new(in_force: &[u8], origin: ConfigOrigin) -> ConfigObject {
        let mut object = ConfigObject {
            in_force: Vec::new(),
            origin,
            staged: Vec::new(),
            staging: Staging::Empty,
            stored: false,
            handed_over: false,
            refusal: None,
            platform_check: None,
        };
        // Filled in place rather than through `from_slice`'s `Result` (firmware size: a copy of the
        // buffer). Too long an image leaves it empty.
        let _ = object.in_force.extend_from_slice(in_force);
        if let ConfigOrigin::Fault(e) = origin {
            object.refusal = Some(e);
        }
        object
    }

    /// Sets the platform's own check of downloaded configurations ([`PlatformCheck`]).
    pub fn set_platform_check(&mut self, check: PlatformCheck) {
        self.platform_check = Some(check);
    }

    /// Attribute 3: 2 (pending) while an accepted image waits in the staging buffer or once the
    /// application has stored one; a new download drops an image not yet taken, and the state
    /// returns to where it was.
    pub fn state(&self) -> ConfigState {
        match self.origin {
            _ if self.stored || self.staging == Staging::Pending => ConfigState::Pending,
            ConfigOrigin::FactoryDefault => ConfigState::FactoryDefault,
            ConfigOrigin::Stored => ConfigState::Stored,
            ConfigOrigin::Fault(_) => ConfigState::Fault,
        }
    }

    /// The image in force.
    pub fn in_force(&self) -> &[u8] {
        &self.in_force
    }

    /// The accepted image not yet stored, if any (the converter's `poll_new_image`).
    #[must_use = "the downloaded image is handed out once: a dropped one is never stored"]
    pub fn take_new_image(&mut self) -> Option<&[u8]> {
        if self.handed_over && self.staging == Staging::Pending {
            self.handed_over = false;
            self.stored = true;
            Some(&self.staged)
        } else {
            None
        }
    }

    /// The pending image (accepted this run and still in the staging buffer).
    pub fn pending(&self) -> Option<&[u8]> {
        (self.staging == Staging::Pending).then_some(self.staged.as_slice())
    }

    /// The image the next change starts from: the pending one, or the one in force when nothing is
    /// pending; `None` when the pending image was stored but a later download dropped its bytes.
    pub fn base(&self) -> Option<&[u8]> {
        match self.staging {
            Staging::Pending => Some(&self.staged),
            _ if self.stored => None,
            _ => Some(&self.in_force),
        }
    }

    /// Takes `image` (already checked) as an accepted download is taken: pending, handed to the
    /// application once. A download under way is abandoned.
    pub fn stage(&mut self, image: &[u8]) {
        self.staged.clear();
        let _ = self.staged.extend_from_slice(image);
        self.accept();
    }

    fn accept(&mut self) {
        self.staging = Staging::Pending;
        self.handed_over = true;
        self.refusal = None;
    }

    /// Serves a request to [`CONFIG_CLASS`]; `io_established` says whether an I/O (poll)
    /// connection is established.
    pub fn handle(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        io_established: bool,
    ) -> Result<(), ServiceError> {
        let service = req.service.as_raw();
        // `matches!` on the ranges, not `RangeInclusive::contains`: that was an out-of-line call
        // (some 120 bytes of flash).
        match (req.instance, req.service, req.data) {
            (1, ServiceCode::GetAttributeSingle, &[attr]) => return self.get(attr, reply),
            (1, ServiceCode::GetAttributeSingle, data) => return Err(ServiceError::wrong_length(data, 1)),
            (1, ServiceCode::SetAttributeSingle, [attr, ..]) => {
                return Err(if matches!(attr, 1..=5) {
                    ServiceError::ATTRIBUTE_NOT_SETTABLE
                } else {
                    ServiceError::ATTRIBUTE_NOT_SUPPORTED
                })
            }
            (1, ServiceCode::SetAttributeSingle, []) => return Err(ServiceError::NOT_ENOUGH_DATA),
            (1, _, _) if matches!(service, READ_CHUNK..=COMMIT_DOWNLOAD) => {}
            (1, _, _) => return Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => return Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        }
        let data = req.data;
        match service {
            READ_CHUNK => {
                let &[which, lo, hi, count] = data else {
                    return Err(ServiceError::wrong_length(data, 4));
                };
                let image = match which {
                    0 => self.in_force.as_slice(),
                    1 => self.pending().ok_or(ServiceError::OBJECT_STATE_CONFLICT)?,
                    _ => return Err(ServiceError::INVALID_PARAMETER),
                };
                if usize::from(count) > MAX_CHUNK {
                    return Err(ServiceError::INVALID_PARAMETER);
                }
                let start = usize::from(u16::from_le_bytes([lo, hi])).min(image.len());
                let end = (start + usize::from(count)).min(image.len());
                reply.bytes(image.get(start..end).unwrap_or_default())
            }
            BEGIN_DOWNLOAD => {
                let &[lo, hi] = data else {
                    return Err(ServiceError::wrong_length(data, 2));
                };
                let size = u16::from_le_bytes([lo, hi]);
                if io_established {
                    return Err(ServiceError::DEVICE_STATE_CONFLICT);
                }
                if usize::from(size) > MAX_IMAGE {
                    return Err(ServiceError::TOO_MUCH_DATA);
                }
                self.staged.clear();
                self.staging = Staging::Downloading(size);
                self.handed_over = false;
                Ok(())
            }
            WRITE_CHUNK => {
                let (offset, bytes) = data.split_first_chunk::<2>().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
                if io_established {
                    return Err(ServiceError::DEVICE_STATE_CONFLICT);
                }
                let Staging::Downloading(size) = self.staging else {
                    return Err(ServiceError::OBJECT_STATE_CONFLICT);
                };
                if usize::from(u16::from_le_bytes(*offset)) != self.staged.len() {
                    return Err(ServiceError::INVALID_PARAMETER);
                }
                if bytes.len() > MAX_CHUNK || self.staged.len() + bytes.len() > usize::from(size) {
                    return Err(ServiceError::TOO_MUCH_DATA);
                }
                // Fits: the size was at most MAX_IMAGE (Begin_Download), checked above.
                let _ = self.staged.extend_from_slice(bytes);
                Ok(())
            }
            _ => {
                if !data.is_empty() {
                    return Err(ServiceError::TOO_MUCH_DATA);
                }
                match self.staging {
                    Staging::Downloading(size) if usize::from(size) == self.staged.len() => {}
                    _ => return Err(ServiceError::OBJECT_STATE_CONFLICT),
                }
                match self.check(&self.staged) {
                    Ok(()) => {
                        self.accept();
                        Ok(())
                    }
                    Err(e) => {
                        self.refusal = Some(e);
                        self.staged.clear();
                        self.staging = Staging::Empty;
                        Err(ServiceError::with_additional(
                            GeneralStatus::InvalidAttributeValue,
                            refusal_code(&e),
                        ))
                    }
                }
            }
        }
    }

    /// Whether `image` may be stored: it decodes ([`image::decode`], which checks the
    /// configuration) and the platform can run it ([`PlatformCheck`]).
    pub fn check(&self, image: &[u8]) -> Result<(), ImageError> {
        // `decode_with_layout`, the firmware's one decoder (the Parameter object calls it too),
        // and the configuration read through a reference to its `Result`, not moved out of it
        // nor through `?` (firmware size).
        let decoded = image::decode_with_layout(image);
        let config = match &decoded {
            Ok((config, _)) => config,
            Err(e) => return Err(*e),
        };
        match self.platform_check {
            Some(check) => check(config).map_err(ImageError::Invalid),
            None => Ok(()),
        }
    }

    fn get(&self, attr: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        match attr {
            1 => reply.u8(IMAGE_VERSION),
            2 => reply.u16(self.in_force.len() as u16),
            3 => reply.u8(self.state() as u8),
            // The image's own trailer: the CRC-32 of its header and body.
            4 => reply.u32(self.in_force.last_chunk::<4>().map_or(0, |c| u32::from_le_bytes(*c))),
            5 => match &self.refusal {
                Some(e) => RefusalRecord::write(e, reply),
                None => Ok(()),
            },
            _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::converter::ConverterConfig;
    use devicenet::slave::config::MAX_EXPLICIT_SIZE;
    use rstest::rstest;
    use std::string::{String, ToString};
    use std::vec::Vec;

    fn image_of(config: &ConverterConfig) -> Vec<u8> {
        image::encode_to_vec(config).unwrap()
    }

    fn object() -> ConfigObject {
        ConfigObject::new(&image_of(&ConverterConfig::breaker_reference()), ConfigOrigin::FactoryDefault)
    }

    /// Runs one request: `Ok(reply bytes)` or `Err((general status, additional code))`.
    fn call(
        o: &mut ConfigObject,
        instance: u16,
        service: u8,
        data: &[u8],
        io: bool,
    ) -> Result<Vec<u8>, (u8, u8)> {
        let req = Request { service: ServiceCode::from(service), class: CONFIG_CLASS, instance, data };
        let mut buf = [0u8; MAX_EXPLICIT_SIZE];
        let mut reply = Reply::new(&mut buf);
        match o.handle(&req, &mut reply, io) {
            Ok(()) => {
                let n = reply.len();
                Ok(buf[..n].to_vec())
            }
            Err(e) => Err((e.general.as_raw(), e.additional)),
        }
    }

    fn download(o: &mut ConfigObject, bytes: &[u8]) -> Result<Vec<u8>, (u8, u8)> {
        let size = (bytes.len() as u16).to_le_bytes();
        call(o, 1, BEGIN_DOWNLOAD, &size, false)?;
        for (k, chunk) in bytes.chunks(MAX_CHUNK).enumerate() {
            let mut req = ((k * MAX_CHUNK) as u16).to_le_bytes().to_vec();
            req.extend_from_slice(chunk);
            call(o, 1, WRITE_CHUNK, &req, false)?;
        }
        call(o, 1, COMMIT_DOWNLOAD, &[], false)
    }

    #[test]
    fn a_stored_image_keeps_the_devices_serial_number() {
        let factory = ConverterConfig::breaker_reference();
        let mut described = factory.clone();
        described.device.identity.serial_number = 0x00C0_FFEE;
        described.device.identity.product_code = 42;
        let (config, origin) = ConfigOrigin::resolve(&factory, Some(&image_of(&described)));
        assert_eq!(origin, ConfigOrigin::Stored);
        assert_eq!(config.device.identity.product_code, 42, "the image runs");
        assert_eq!(config.device.identity.serial_number, factory.device.identity.serial_number);
    }

    #[rstest]
    // Class instance 0 is the node's (`VendorObjects::class_revision`; the converter's tests).
    #[case::class_instance(0, 0x0E, &[1], Err((0x16, 0xFF)))]
    #[case::version(1, 0x0E, &[1], Ok(std::vec![IMAGE_VERSION]))]
    #[case::size(1, 0x0E, &[2], Ok(std::vec![98, 0]))]
    #[case::state(1, 0x0E, &[3], Ok(std::vec![0]))]
    #[case::refusal_none(1, 0x0E, &[5], Ok(std::vec![]))]
    #[case::unknown_attribute(1, 0x0E, &[6], Err((0x14, 0xFF)))]
    #[case::set_read_only(1, 0x10, &[3, 1], Err((0x0E, 0xFF)))]
    #[case::set_unknown(1, 0x10, &[9, 1], Err((0x14, 0xFF)))]
    #[case::instance_2(2, 0x0E, &[1], Err((0x16, 0xFF)))]
    #[case::other_service(1, 0x05, &[], Err((0x08, 0xFF)))]
    #[case::read_first_bytes(1, READ_CHUNK, &[0, 0, 0, 5], Ok(b"DNCI\x01".to_vec()))]
    #[case::read_at_end(1, READ_CHUNK, &[0, 96, 0, 56], Ok(Vec::new()))] // checked against the image below
    #[case::read_past_end(1, READ_CHUNK, &[0, 200, 0, 10], Ok(Vec::new()))]
    #[case::read_too_many(1, READ_CHUNK, &[0, 0, 0, 57], Err((0x20, 0xFF)))]
    #[case::read_bad_which(1, READ_CHUNK, &[2, 0, 0, 1], Err((0x20, 0xFF)))]
    #[case::read_nothing_pending(1, READ_CHUNK, &[1, 0, 0, 1], Err((0x0C, 0xFF)))]
    #[case::read_short(1, READ_CHUNK, &[0, 0, 0], Err((0x13, 0xFF)))]
    #[case::begin_too_large(1, BEGIN_DOWNLOAD, &[0x81, 0x01], Err((0x15, 0xFF)))]
    #[case::write_without_begin(1, WRITE_CHUNK, &[0, 0, 1], Err((0x0C, 0xFF)))]
    #[case::commit_without_begin(1, COMMIT_DOWNLOAD, &[], Err((0x0C, 0xFF)))]
    fn services(
        #[case] instance: u16,
        #[case] service: u8,
        #[case] data: &[u8],
        #[case] expected: Result<Vec<u8>, (u8, u8)>,
    ) {
        let mut o = object();
        let got = call(&mut o, instance, service, data, false);
        if instance == 1 && service == READ_CHUNK && data == [0, 96, 0, 56] {
            // The last two bytes of the 98-byte image: its CRC's high half.
            assert_eq!(got.unwrap(), o.in_force()[96..].to_vec());
        } else {
            assert_eq!(got, expected);
        }
    }

    #[test]
    fn crc_attribute_is_the_image_trailer() {
        let mut o = object();
        let trailer = o.in_force()[94..].to_vec();
        assert_eq!(call(&mut o, 1, 0x0E, &[4], false), Ok(trailer));
    }

    #[test]
    fn download_is_refused_while_io_is_established() {
        let mut o = object();
        assert_eq!(call(&mut o, 1, BEGIN_DOWNLOAD, &[10, 0], true), Err((0x10, 0xFF)));
        assert_eq!(call(&mut o, 1, BEGIN_DOWNLOAD, &[10, 0], false), Ok(Vec::new()));
        assert_eq!(call(&mut o, 1, WRITE_CHUNK, &[0, 0, 1], true), Err((0x10, 0xFF)));
    }

    #[test]
    fn write_chunk_checks_offset_and_size() {
        let mut o = object();
        call(&mut o, 1, BEGIN_DOWNLOAD, &[4, 0], false).unwrap();
        assert_eq!(call(&mut o, 1, WRITE_CHUNK, &[1, 0, 1], false), Err((0x20, 0xFF)));
        assert_eq!(call(&mut o, 1, WRITE_CHUNK, &[0, 0, 1, 2, 3, 4, 5], false), Err((0x15, 0xFF)));
        assert_eq!(call(&mut o, 1, WRITE_CHUNK, &[0], false), Err((0x13, 0xFF)));
        assert_eq!(call(&mut o, 1, WRITE_CHUNK, &[0, 0, 1, 2], false), Ok(Vec::new()));
        assert_eq!(call(&mut o, 1, COMMIT_DOWNLOAD, &[], false), Err((0x0C, 0xFF)), "2 of 4 bytes");
        let mut big = std::vec![0, 0];
        big.extend_from_slice(&[0; MAX_CHUNK + 1]);
        call(&mut o, 1, BEGIN_DOWNLOAD, &[0x40, 0x01], false).unwrap();
        assert_eq!(call(&mut o, 1, WRITE_CHUNK, &big, false), Err((0x15, 0xFF)));
    }

    #[test]
    fn accepted_download_is_pending_readable_and_handed_over_once() {
        let mut o = object();
        let mut config = ConverterConfig::breaker_reference();
        config.device.identity.product_code = 9;
        let new = image_of(&config);
        assert_eq!(download(&mut o, &new), Ok(Vec::new()));
        assert_eq!(o.state(), ConfigState::Pending);
        assert_eq!(call(&mut o, 1, READ_CHUNK, &[1, 0, 0, 56], false), Ok(new[..56].to_vec()));
        assert_eq!(o.take_new_image(), Some(new.as_slice()));
        assert_eq!(o.take_new_image(), None);
        // The image in force is unchanged until the next reset.
        assert_eq!(o.in_force(), image_of(&ConverterConfig::breaker_reference()).as_slice());
    }

    #[rstest]
    #[case::version(|b: &mut Vec<u8>| b[4] = 9, 1, "unsupported version 9")]
    #[case::length(|b: &mut Vec<u8>| b[5] = 0, 2, "length mismatch")]
    #[case::crc(|b: &mut Vec<u8>| b[20] ^= 1, 3, "CRC mismatch")]
    fn refused_downloads_say_why(#[case] damage: fn(&mut Vec<u8>), #[case] code: u8, #[case] text: &str) {
        let mut o = object();
        let mut bytes = image_of(&ConverterConfig::breaker_reference());
        damage(&mut bytes);
        assert_eq!(download(&mut o, &bytes), Err((0x09, code)));
        let reason = reason(&mut o);
        assert!(reason.starts_with(text), "{reason}");
        assert_eq!(o.state(), ConfigState::FactoryDefault);
        assert_eq!(o.take_new_image(), None);
    }

    #[test]
    fn an_invalid_configuration_is_refused_with_its_key() {
        let mut o = object();
        let mut config = ConverterConfig::breaker_reference();
        config.device.identity.major_revision = 0;
        assert_eq!(download(&mut o, &image_of(&config)), Err((0x09, 4)));
        assert_eq!(reason(&mut o), "identity.major_revision: 0 is outside the allowed range 1..=127");
    }

    #[test]
    fn a_configuration_the_platform_cannot_run_is_refused_with_its_key() {
        fn no_odd_parity(config: &ConverterConfig) -> Result<(), InvalidConfig> {
            match config.profile.serial().parity {
                crate::serial::Parity::Odd => Err(InvalidConfig::Profile {
                    modbus: false,
                    error: crate::serial::ConfigError::conflict(
                        crate::serial::Field::SerialParity,
                        crate::serial::Conflict::SevenBitsNeedParity,
                    ),
                }),
                _ => Ok(()),
            }
        }
        let mut o = object();
        o.set_platform_check(no_odd_parity);
        let mut config = ConverterConfig::breaker_reference();
        assert_eq!(download(&mut o, &image_of(&config)), Ok(Vec::new()), "even parity runs");
        assert_eq!(o.take_new_image().map(<[u8]>::len), Some(image_of(&config).len()));
        let crate::serial::ProfileConfig::Framed(framed) = &mut config.profile else { unreachable!() };
        framed.serial.parity = crate::serial::Parity::Odd;
        assert_eq!(download(&mut o, &image_of(&config)), Err((0x09, 4)));
        assert_eq!(reason(&mut o), "profile.serial.parity: 7 data bits need parity on this USART");
        assert_eq!(o.take_new_image(), None, "nothing to store");
    }

    #[test]
    fn a_refused_stored_image_is_a_fault_with_its_reason() {
        let e = ImageError::Invalid(crate::converter::InvalidConfig::Profile {
            modbus: true,
            error: crate::serial::ConfigError::out_of_range(crate::serial::Field::ScanOffset, 30, 0, 4)
                .at(15),
        });
        let mut o =
            ConfigObject::new(&image_of(&ConverterConfig::breaker_reference()), ConfigOrigin::Fault(e));
        assert_eq!(o.state(), ConfigState::Fault);
        assert_eq!(reason(&mut o), "profile.modbus.scan[15].offset: 30 is outside the allowed range 0..=4");
        assert_eq!(reason(&mut o), e.to_string(), "the words of the image error itself");
    }

    /// Attribute 5, worded.
    fn reason(o: &mut ConfigObject) -> String {
        let record = call(o, 1, 0x0E, &[5], false).unwrap();
        assert!(record.len() + 2 <= MAX_EXPLICIT_SIZE, "one explicit message");
        RefusalRecord::parse(&record).expect("a record").to_string()
    }

    /// Every refusal the device can make, encoded, sent and worded again: the words of
    /// `ImageError`'s own text, except where the record keeps numbers only (the loader's own
    /// phrasing of identity and network values).
    #[rstest]
    #[case::truncated(ImageError::Truncated(3))]
    #[case::too_large(ImageError::TooLarge(400))]
    #[case::bad_magic(ImageError::BadMagic)]
    #[case::version(ImageError::UnsupportedVersion(9))]
    #[case::length(ImageError::LengthMismatch { stated: 80, actual: 81 })]
    #[case::crc(ImageError::CrcMismatch { stated: 0xDEAD_BEEF, computed: 0x0123_4567 })]
    #[case::malformed(ImageError::Malformed { offset: 43 })]
    #[case::buffer(ImageError::BufferTooSmall)]
    #[case::overlap(ImageError::Invalid(InvalidConfig::Profile {
        modbus: true,
        error: crate::serial::ConfigError { field: crate::serial::Field::ScanOffset, index: Some(2), problem: Problem::Overlap { other: 0 } },
    }))]
    #[case::duplicate(ImageError::Invalid(InvalidConfig::Profile {
        modbus: false,
        error: crate::serial::ConfigError { field: crate::serial::Field::CommandsCode, index: Some(3), problem: Problem::Duplicate { other: 1 } },
    }))]
    #[case::not_ascii(ImageError::Invalid(InvalidConfig::ProductNameNotAscii))]
    #[case::conflict(ImageError::Invalid(InvalidConfig::Profile {
        modbus: true,
        error: crate::serial::ConfigError::conflict(crate::serial::Field::SerialDataBits, crate::serial::Conflict::ModbusDataBits),
    }))]
    #[case::io_size(ImageError::Invalid(InvalidConfig::Io(NodeConfigError::IoSizeTooLarge { size: 300 })))]
    #[case::io_instances(ImageError::Invalid(InvalidConfig::Io(NodeConfigError::SameAssemblyInstance)))]
    fn a_record_is_worded_as_the_error(#[case] e: ImageError) {
        assert_eq!(RefusalRecord::parse(&record(&e)).unwrap().to_string(), e.to_string());
    }

    #[rstest]
    #[case::mac(InvalidConfig::MacId(70), "network.mac_id: 70 is outside the allowed range 0..=63")]
    #[case::baud(InvalidConfig::BaudRate(3), "network.baud_rate: 3 is outside the allowed range 0..=2")]
    #[case::name(
        InvalidConfig::ProductNameLength(40),
        "identity.product_name: 40 is outside the allowed range 1..=32"
    )]
    #[case::epr(
        InvalidConfig::EprResolutionZero,
        "network.epr_resolution_ms: 0 is outside the allowed range 1..=65535"
    )]
    #[case::conflict(
        InvalidConfig::Profile { modbus: false, error: crate::serial::ConfigError::conflict(crate::serial::Field::FramingEnd, crate::serial::Conflict::NoEndDelimiter) },
        "profile.framing.end: a delimited frame needs an end byte"
    )]
    fn identity_network_and_conflicts_are_worded_from_their_numbers(
        #[case] e: InvalidConfig,
        #[case] text: &str,
    ) {
        assert_eq!(RefusalRecord::parse(&record(&ImageError::Invalid(e))).unwrap().to_string(), text);
    }

    /// The record the device sends for `e`.
    fn record(e: &ImageError) -> Vec<u8> {
        let mut buf = [0u8; MAX_EXPLICIT_SIZE];
        let mut reply = Reply::new(&mut buf);
        RefusalRecord::write(e, &mut reply).unwrap();
        let n = reply.len();
        buf[..n].to_vec()
    }

    #[rstest]
    #[case::empty(&[], None)]
    #[case::short(&[8, 1, 0], None)]
    #[case::unknown_kind(&[42, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], Some("refusal of unknown kind 42"))]
    #[case::no_key(&[8, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0], Some("(no key): a delimited frame needs an end byte"))]
    #[case::short_key(&[8, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 5], Some("(no key): a delimited frame needs an end byte"))]
    #[case::indexed_key(
        &[8, 1, 5, 0, 0, 0, 1, 0, 0, 0, 4, 0, 0, 0, 2, 26, 3, 0],
        Some("profile.modbus.scan[3].offset: 5 is outside the allowed range 1..=4")
    )]
    #[case::unknown_conflict(&[8, 2, 99, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0xFF, 0xFF], Some("profile.serial.baud: conflicts with another setting"))]
    #[case::unknown_node_error(&[8, 6, 99, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 5, 0xFF, 0xFF], Some("io: the node refuses the I/O configuration"))]
    #[case::unknown_top_key(&[8, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 9, 0xFF, 0xFF], Some("(unknown key 9): a delimited frame needs an end byte"))]
    #[case::unknown_profile_key(&[8, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 200, 0xFF, 0xFF], Some("profile.modbus.(unknown key 200): a delimited frame needs an end byte"))]
    #[case::unknown_scope(&[8, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 7, 0, 0xFF, 0xFF], Some("(key of unknown scope 7): a delimited frame needs an end byte"))]
    fn any_record_bytes_are_worded_or_refused(#[case] bytes: &[u8], #[case] text: Option<&str>) {
        assert_eq!(RefusalRecord::parse(bytes).map(|r| r.to_string()).as_deref(), text);
    }

    #[test]
    fn node_error_codes_follow_the_table() {
        for (i, e) in NODE_ERRORS.iter().enumerate() {
            assert_eq!(node_error_code(e), i as u32, "{e:?}");
            assert_eq!(node_error(i as u32, 0), Some(*e));
        }
    }
}
