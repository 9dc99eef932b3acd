//! The binary configuration image: a whole [`ConverterConfig`] as the device stores it and as a
//! tool downloads it over the bus (the converter's configuration object, class 0x66).
//!
//! ```text
//! offset  size  field
//! 0       4     magic "DNCI"
//! 4       1     format version (IMAGE_VERSION = 1)
//! 5       2     body length n, UINT little-endian
//! 7       n     body (below)
//! 7+n     4     CRC-32 (IEEE 802.3, as zlib) of bytes 0..7+n, UDINT little-endian
//! ```
//!
//! The body, version 1, every number little-endian (`u8` USINT, `u16` UINT, `u32` UDINT;
//! `opt(x)` is a byte 0 (absent) or 1 followed by `x`; `bytes` is a length byte then the bytes):
//!
//! ```text
//! identity   vendor_id u16, device_type u16, product_code u16, major u8, minor u8,
//!            serial_number u32, product_name bytes
//! network    mac_id u8, baud_rate u8 (0 125k, 1 250k, 2 500k), port u8,
//!            flags u8 (bit 0 bus_off_interrupt, bit 1 programmable), epr_resolution_ms u16
//! io         input_assembly u8 (0 plain = 100, 1 with_status = 101)
//! profile    kind u8 (0 framed, 1 modbus), then
//!   framed   serial, framing, status_len u8, opt(ack data_len u8, flag u8, ok_status u8),
//!            commands: count u8, then code u8, wire u8, args u8 each,
//!            sequencer: response_timeout_ms u32, retries u8, execute_first u8, on_idle, on_fault,
//!            health
//!   modbus   serial, response_timeout_ms u32, retries u8, poll_period_ms u32, input_len u16,
//!            output_len u16, order u8 (bit 0 byte order: 0 little, 1 big; bits 1-2 framing:
//!            0 RTU, 1 ASCII, 2 TCP, so older images read as RTU; bit 3: valid_bits_offset u16
//!            follows, so older images read without data-valid bits), scan: count u8, then
//!            unit u8, function u8 (bits 0-4 the Modbus code; bits 5-7 the word order: 0 the
//!            profile's byte order, so older images read unchanged, 1 abcd, 2 badc, 3 cdab,
//!            4 dcba), address u16, count u16, offset u16 (bits 0-14; bit 15: a schedule
//!            follows, so older images read unchanged) each, then the schedule if flagged:
//!            flags u8 (bit 0 period_ms u32 follows, bit 1 trigger_offset u16 follows, bits 2-3
//!            write mode 0 change, 1 cyclic, 2 trigger), then those fields,
//!            health, on_idle, on_fault
//! serial     baud u32, format u8 (bit 0 seven data bits, bits 1-2 parity 0 none 1 even 2 odd,
//!            bit 3 two stop bits)
//! framing    start u8, length u8 (0 byte, 1 fixed, 2 delimited), fixed length u8, opt(end u8),
//!            checksum u8 (0 none, 1 sum8, 2 xor8, 3 CRC-16/MODBUS), max_len u8
//! health     stale_timeout_ms u32, stale_policy u8 (0 hold, 1 clear)
//! action     opt(bytes): absent = nothing, present = send these bytes
//! ```
//!
//! Not in the image: the I/O sizes and assembly instances of [`DeviceConfig`] (derived from the
//! profile by [`ConverterConfig::device_config`], and so set by [`decode`]) and what the
//! switches read at reset (a hardware fact; only `programmable` is configuration).
//!
//! ## Why a hand-written encoding
//!
//! Measured on the board firmware (thumbv7em, `--profile firmware`, flash = text + rodata +
//! data as `scripts/firmware-size` counts it), with the firmware's start-up made to encode its
//! configuration and decode it again, against the same firmware without:
//!
//! | encoding | what it covers | flash added |
//! |---|---|---|
//! | this module | the whole configuration, header, CRC-32, `check` | 5 500 bytes (first version with an early return per field: 6 140) |
//! | postcard 1 + serde derives (`serde` feature on the configuration types) | the profile only, no identity or network, no header, no CRC, `check` | 6 496 bytes |
//!
//! postcard would also need serde on the `devicenet` types and ties the layout to serde's data
//! model (enum variant order, `Option` and sequence encoding); the layout here is written down
//! above for a tool in any language, and costs less flash for more. Base: 41 212 bytes.
//!
//! ## No-panic contract
//!
//! [`decode`] accepts any byte slice: it never panics, never allocates, and refuses anything that
//! is not a valid image with an [`ImageError`] that says what is wrong. An accepted image always
//! passes [`ConverterConfig::check`], the same value rules as the TOML device description.

use super::{ConverterConfig, InputAssembly, InvalidConfig};
use crate::serial::modbus::{ByteOrder, Framing, Function, ModbusConfig, ScanEntry, WordOrder, WriteMode};
use crate::serial::{
    AckFormat, Checksum, CommandFormat, DataBits, FramedConfig, FramedProfileConfig, HealthConfig,
    IdleAction, LengthField, Parity, ProfileConfig, SequencerConfig, SerialSettings, StalePolicy, StopBits,
};
use core::fmt;
use devicenet::slave::{BaudRate, DeviceConfig, Identity, Switches};
use devicenet::text::{self, TextSink};
use devicenet::MacId;

/// The image format version this firmware writes and reads.
pub const IMAGE_VERSION: u8 = 1;
/// The largest image: the largest configuration (a Modbus profile with 16 scan entries, a 32-byte
/// product name, two 32-byte idle/fault frames, every scan entry with its own period) takes 365
/// bytes; rounded up to leave room for a later version's additions.
pub const MAX_IMAGE: usize = 384;
/// The image's leading bytes.
pub const MAGIC: [u8; 4] = *b"DNCI";
/// Header bytes: magic, version, body length.
pub const HEADER_LEN: usize = 7;
/// Trailer bytes: the CRC-32.
pub const CRC_LEN: usize = 4;

/// The image of the factory default, [`ConverterConfig::breaker_reference`] (a test holds it equal
/// to its encoding): the firmware boots from these bytes when nothing valid is stored, so it
/// carries neither an encoder nor the code that builds the reference configuration.
#[rustfmt::skip]
pub const BREAKER_REFERENCE: [u8; 98] = [
    b'D', b'N', b'C', b'I', IMAGE_VERSION, 87, 0, // header: body of 87 bytes
    0x34, 0x12, 0x0C, 0x00, 0x01, 0x00, 1, 1, // vendor 0x1234, device type 0x0C, product 1, rev 1.1
    0x78, 0x56, 0x34, 0x12, 23, // serial number 0x12345678, product name of 23 bytes
    b'S', b'e', b'r', b'i', b'a', b'l', b'-', b'D', b'e', b'v', b'i', b'c', b'e', b'N', b'e', b't',
    b' ', b'B', b'r', b'i', b'd', b'g', b'e',
    5, 1, 0, 0, 1, 0, // MAC 5, 250 kbit/s, port 0, flags 0, EPR resolution 1 ms
    0, 0, // input assembly 100; profile framed
    0x80, 0x25, 0, 0, 0, // serial 9600 baud, 8N1
    0x68, 0, 0, 1, 0x16, 1, 18, // framing: start 0x68, length byte, end 0x16, sum8, max 18
    18, 1, 2, 0x80, 0, // status 18 bytes; ack: 2 data bytes, flag 0x80, ok status 0
    4, 1, 1, 0, 2, 2, 0, 3, 3, 3, 4, 4, 0, // four commands: code, wire code, argument bytes
    0xF4, 0x01, 0, 0, 2, 1, 0, 0, // sequencer: 500 ms, 2 retries, execute first, no idle/fault frames
    0xB8, 0x0B, 0, 0, 0, // health: stale after 3000 ms, hold last value
    0xED, 0x08, 0x0D, 0x0A, // CRC-32
];

/// The CRC-32 (IEEE 802.3, zlib: `"123456789"` gives `0xCBF43926`) of `bytes`, as the image
/// trailer holds it: the firmware's one CRC-32, shared with the board's settings records.
pub use devicenet::crc32::crc32;

/// Why an image was refused (or could not be written).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageError {
    /// Shorter than a header and a CRC (the length received).
    Truncated(usize),
    /// Longer than [`MAX_IMAGE`] (the length received).
    TooLarge(usize),
    /// The first four bytes are not "DNCI".
    BadMagic,
    /// A format version this firmware does not read.
    UnsupportedVersion(u8),
    /// The header's body length does not match the bytes received.
    LengthMismatch {
        /// Body length in the header.
        stated: u16,
        /// Body bytes received.
        actual: usize,
    },
    /// The CRC does not match the bytes.
    CrcMismatch {
        /// The CRC in the trailer.
        stated: u32,
        /// The CRC of the bytes.
        computed: u32,
    },
    /// The body cannot be read as a configuration (at this body offset): a field runs past the
    /// end, an unknown code, or bytes left over.
    Malformed {
        /// Offset in the body.
        offset: u16,
    },
    /// The configuration is refused by [`ConverterConfig::check`].
    Invalid(InvalidConfig),
    /// [`encode`]: the output buffer is too small.
    BufferTooSmall,
}

impl ImageError {
    /// Writes the reason (the `Display` text) without `core::fmt` ([`devicenet::text`]); a tool
    /// words a refusal record with it (`RefusalRecord::write_text`).
    pub fn write_text(&self, out: &mut impl TextSink) {
        match *self {
            ImageError::Truncated(n) => {
                out.text("truncated: ");
                out.decimal(u32::try_from(n).unwrap_or(u32::MAX));
                out.text(" bytes, an image has at least 11");
            }
            ImageError::TooLarge(n) => {
                out.text("oversized: ");
                out.decimal(u32::try_from(n).unwrap_or(u32::MAX));
                out.text(" bytes, at most ");
                out.decimal(MAX_IMAGE as u32);
            }
            ImageError::BadMagic => out.text("bad magic: not a configuration image"),
            ImageError::UnsupportedVersion(v) => {
                out.text("unsupported version ");
                out.decimal(u32::from(v));
                out.text(" (this device reads ");
                out.decimal(u32::from(IMAGE_VERSION));
                out.text(")");
            }
            ImageError::LengthMismatch { stated, actual } => {
                out.text("length mismatch: header says ");
                out.decimal(u32::from(stated));
                out.text(" body bytes, ");
                out.decimal(u32::try_from(actual).unwrap_or(u32::MAX));
                out.text(" received");
            }
            ImageError::CrcMismatch { stated, computed } => {
                out.text("CRC mismatch: image ");
                out.hex8(stated);
                out.text(", computed ");
                out.hex8(computed);
            }
            ImageError::Malformed { offset } => {
                out.text("malformed body at byte ");
                out.decimal(u32::from(offset));
            }
            ImageError::Invalid(e) => e.write_text(out),
            ImageError::BufferTooSmall => out.text("output buffer too small"),
        }
    }
}

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::display(f, |out| self.write_text(out))
    }
}

impl core::error::Error for ImageError {}

impl From<InvalidConfig> for ImageError {
    fn from(e: InvalidConfig) -> Self {
        ImageError::Invalid(e)
    }
}

/// The image of `config` as a vector (host tools and tests; the device encodes into its own
/// buffer with [`encode`]).
#[cfg(any(test, feature = "std"))]
pub fn encode_to_vec(config: &ConverterConfig) -> Result<std::vec::Vec<u8>, ImageError> {
    let mut out = [0u8; MAX_IMAGE];
    let len = encode(config, &mut out)?;
    Ok(out.get(..len).unwrap_or_default().to_vec())
}

/// Writes the image of `config` into `out`; returns its length. The configuration is written as
/// it is (its I/O sizes and switch readings excepted, see the module docs); [`decode`] checks it.
pub fn encode(config: &ConverterConfig, out: &mut [u8]) -> Result<usize, ImageError> {
    let mut w = Writer { out, len: HEADER_LEN };
    if w.out.len() < HEADER_LEN {
        return Err(ImageError::BufferTooSmall);
    }
    w.body(config);
    let Writer { out, len } = w;
    let body = len.checked_sub(HEADER_LEN).and_then(|n| u16::try_from(n).ok());
    let (Some(body), Some(image)) = (body, out.get_mut(..len + CRC_LEN)) else {
        return Err(ImageError::BufferTooSmall);
    };
    let (covered, trailer) = image.split_at_mut(len);
    if let Some(header) = covered.first_chunk_mut::<HEADER_LEN>() {
        let [l0, l1] = body.to_le_bytes();
        let [m0, m1, m2, m3] = MAGIC;
        *header = [m0, m1, m2, m3, IMAGE_VERSION, l0, l1];
    }
    trailer.copy_from_slice(&crc32(covered).to_le_bytes());
    Ok(len + CRC_LEN)
}

/// Reads an image: checks its length, magic, version, body length and CRC, reads the body, and
/// checks the configuration ([`ConverterConfig::check`]). The returned configuration's I/O sizes
/// and assembly instances are derived from its profile.
pub fn decode(bytes: &[u8]) -> Result<ConverterConfig, ImageError> {
    decode_with_layout(bytes).map(|(config, _)| config)
}

/// Where the values a Parameter object Set changes lie in an image
/// ([`decode_with_layout`]): offsets from the image's first byte.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Layout {
    /// The serial settings: baud u32, then the format byte.
    pub serial: u16,
    /// The input assembly byte (0 plain = 100, 1 with status = 101).
    pub input: u16,
    /// The response timeout u32, then the retries u8, then (Modbus only) the poll period u32.
    pub timing: u16,
    /// The health settings: stale timeout u32, then the stale policy byte (0 hold, 1 clear).
    pub health: u16,
}

/// [`decode`], and where the settings the Parameter object edits lie in `bytes`
/// ([`Layout`]): a Set writes the new value there, [`reseal`]s the image and decodes it again, so
/// the device needs no encoder (`converter::parameters`).
pub fn decode_with_layout(bytes: &[u8]) -> Result<(ConverterConfig, Layout), ImageError> {
    if bytes.len() < HEADER_LEN + CRC_LEN {
        return Err(ImageError::Truncated(bytes.len()));
    }
    if bytes.len() > MAX_IMAGE {
        return Err(ImageError::TooLarge(bytes.len()));
    }
    let (Some((header, _)), Some((covered, trailer))) =
        (bytes.split_first_chunk::<HEADER_LEN>(), bytes.split_last_chunk::<CRC_LEN>())
    else {
        return Err(ImageError::Truncated(bytes.len()));
    };
    let [m0, m1, m2, m3, version, l0, l1] = *header;
    if [m0, m1, m2, m3] != MAGIC {
        return Err(ImageError::BadMagic);
    }
    if version != IMAGE_VERSION {
        return Err(ImageError::UnsupportedVersion(version));
    }
    let stated = u16::from_le_bytes([l0, l1]);
    let actual = bytes.len() - HEADER_LEN - CRC_LEN;
    if usize::from(stated) != actual {
        return Err(ImageError::LengthMismatch { stated, actual });
    }
    let stated = u32::from_le_bytes(*trailer);
    let computed = crc32(covered);
    if stated != computed {
        return Err(ImageError::CrcMismatch { stated, computed });
    }
    let body = covered.get(HEADER_LEN..).unwrap_or_default();
    let mut reader = Reader { body, pos: 0, bad: None, invalid: None, layout: Layout::default() };
    let config = reader.config();
    if let Some(offset) = reader.bad {
        return Err(ImageError::Malformed { offset: u16::try_from(offset).unwrap_or(u16::MAX) });
    }
    if let Some(e) = reader.invalid {
        return Err(ImageError::Invalid(e));
    }
    // The reader derived the device half's I/O values (`Reader::config`).
    config.check_derived()?;
    Ok((config, reader.layout))
}

/// The serial settings' format byte: bit 0 seven data bits, bits 1-2 parity (0 none, 1 even,
/// 2 odd), bit 3 two stop bits (the encoder's, and a Parameter object Set's).
pub fn serial_format(s: &SerialSettings) -> u8 {
    let parity = match s.parity {
        Parity::None => 0,
        Parity::Even => 1,
        Parity::Odd => 2,
    };
    u8::from(s.data_bits == DataBits::Seven) | parity << 1 | u8::from(s.stop_bits == StopBits::Two) << 3
}

/// The input assembly byte: 0 plain (100), 1 with status (101).
pub const fn input_code(input: InputAssembly) -> u8 {
    match input {
        InputAssembly::Plain => 0,
        InputAssembly::WithStatus => 1,
    }
}

/// Seals an image whose body was changed in place (same length): writes the CRC of everything
/// before the trailer into the trailer. Too short an image is left as it is.
pub fn reseal(image: &mut [u8]) {
    if let Some((covered, trailer)) = image.split_last_chunk_mut::<CRC_LEN>() {
        *trailer = crc32(covered).to_le_bytes();
    }
}

/// The body writer: bytes past the end of `out` are counted, not written, so [`encode`] can
/// report a short buffer once.
struct Writer<'a> {
    out: &'a mut [u8],
    len: usize,
}

impl Writer<'_> {
    // Out of line: one call per field instead of a bounds-checked store inlined at each.
    #[inline(never)]
    fn u8(&mut self, v: u8) {
        if let Some(b) = self.out.get_mut(self.len) {
            *b = v;
        }
        self.len += 1;
    }

    fn bytes(&mut self, v: &[u8]) {
        for &b in v {
            self.u8(b);
        }
    }

    fn u16(&mut self, v: u16) {
        self.bytes(&v.to_le_bytes());
    }

    fn u32(&mut self, v: u32) {
        self.bytes(&v.to_le_bytes());
    }

    fn flag(&mut self, present: bool) {
        self.u8(u8::from(present));
    }

    /// A length byte and the bytes (every list here is at most 32 bytes).
    fn list(&mut self, v: &[u8]) {
        self.u8(u8::try_from(v.len()).unwrap_or(u8::MAX));
        self.bytes(v);
    }

    fn body(&mut self, c: &ConverterConfig) {
        let d = &c.device;
        let id = &d.identity;
        self.u16(id.vendor_id);
        self.u16(id.device_type);
        self.u16(id.product_code);
        self.u8(id.major_revision);
        self.u8(id.minor_revision);
        self.u32(id.serial_number);
        self.list(id.product_name.as_bytes());
        self.u8(d.mac_id.as_raw());
        self.u8(d.baud_rate.attribute_value());
        self.u8(d.port);
        self.u8(u8::from(d.bus_off_interrupt) | u8::from(d.switches.programmable) << 1);
        self.u16(d.epr_resolution_ms);
        self.u8(input_code(c.input));
        match &c.profile {
            ProfileConfig::Framed(p) => {
                self.u8(0);
                self.serial(&p.serial);
                self.framing(&p.framing);
                self.u8(p.status_len);
                self.flag(p.ack.is_some());
                if let Some(a) = p.ack {
                    self.bytes(&[a.data_len, a.flag, a.ok_status]);
                }
                self.u8(p.commands.len() as u8);
                for c in &p.commands {
                    self.bytes(&[c.code, c.wire, c.args]);
                }
                let s = &p.sequencer;
                self.u32(s.response_timeout_ms);
                self.u8(s.retries);
                self.u8(u8::from(s.execute_first));
                self.action(&s.on_idle);
                self.action(&s.on_fault);
                self.health(&p.health);
            }
            ProfileConfig::Modbus(m) => {
                self.u8(1);
                self.serial(&m.serial);
                self.u32(m.response_timeout_ms);
                self.u8(m.retries);
                self.u32(m.poll_period_ms);
                self.u16(m.input_len);
                self.u16(m.output_len);
                let framing = match m.framing {
                    Framing::Rtu => 0,
                    Framing::Ascii => 1,
                    Framing::Tcp => 2,
                };
                let bits = u8::from(m.valid_bits_offset.is_some()) << 3;
                self.u8(bits | framing << 1 | u8::from(m.byte_order == ByteOrder::BigEndian));
                if let Some(offset) = m.valid_bits_offset {
                    self.u16(offset);
                }
                self.u8(m.scan.len() as u8);
                for e in &m.scan {
                    self.u8(e.unit);
                    let order = WordOrder::ALL.iter().position(|&w| w == e.word_order).unwrap_or(0) as u8;
                    self.u8(order << 5 | e.function.code());
                    self.u16(e.address);
                    self.u16(e.count);
                    self.schedule(e);
                }
                self.health(&m.health);
                self.action(&m.on_idle);
                self.action(&m.on_fault);
            }
        }
    }

    /// A scan entry's offset, with bit 15 set and the schedule after it when it has one.
    fn schedule(&mut self, e: &ScanEntry) {
        let mode = WriteMode::ALL.iter().position(|&w| w == e.write).unwrap_or(0) as u8;
        let flags = u8::from(e.period_ms.is_some()) | u8::from(e.trigger_offset.is_some()) << 1 | mode << 2;
        self.u16(e.offset & 0x7FFF | u16::from(flags != 0) << 15);
        if flags == 0 {
            return;
        }
        self.u8(flags);
        if let Some(p) = e.period_ms {
            self.u32(p);
        }
        if let Some(b) = e.trigger_offset {
            self.u16(b);
        }
    }

    fn serial(&mut self, s: &SerialSettings) {
        self.u32(s.baud);
        self.u8(serial_format(s));
    }

    fn framing(&mut self, f: &FramedConfig) {
        self.u8(f.start);
        let (kind, fixed) = match f.length {
            LengthField::Byte => (0, 0),
            LengthField::Fixed(n) => (1, n),
            LengthField::Delimited => (2, 0),
        };
        self.bytes(&[kind, fixed]);
        self.flag(f.end.is_some());
        if let Some(end) = f.end {
            self.u8(end);
        }
        self.u8(match f.checksum {
            Checksum::None => 0,
            Checksum::Sum8 => 1,
            Checksum::Xor8 => 2,
            Checksum::Crc16Modbus => 3,
        });
        self.u8(f.max_len);
    }

    fn health(&mut self, h: &HealthConfig) {
        self.u32(h.stale_timeout_ms);
        self.u8(match h.stale_policy {
            StalePolicy::HoldLastValue => 0,
            StalePolicy::Clear => 1,
        });
    }

    fn action(&mut self, a: &IdleAction) {
        self.flag(a.frame().is_some());
        if let Some(frame) = a.frame() {
            self.list(frame);
        }
    }
}

/// The body reader. A read past the end or an unknown code gives 0 and records where the body
/// first went wrong ([`Reader::bad`]); [`decode`] checks that once at the end, which keeps the
/// reader free of a branch per field (a quarter of the flash of an early-return reader).
struct Reader<'a> {
    body: &'a [u8],
    pos: usize,
    /// The offset of the first unreadable field.
    bad: Option<usize>,
    /// The first value that reads but cannot be held (a product name that is not UTF-8, a MAC
    /// ID or baud rate code out of range): reported after [`Reader::bad`]. Recorded instead of
    /// returned, so the configuration is not moved through a `Result`.
    invalid: Option<InvalidConfig>,
    /// Where the Parameter object's settings were read.
    layout: Layout,
}

impl Reader<'_> {
    /// The image offset of the next field (for [`Layout`]).
    fn here(&self) -> u16 {
        u16::try_from(HEADER_LEN + self.pos).unwrap_or(u16::MAX)
    }

    // Out of line: one call at each unreadable field instead of the `get_or_insert`.
    #[inline(never)]
    fn fail(&mut self, at: usize) {
        self.bad.get_or_insert(at);
    }

    // Out of line, as `Writer::u8`.
    #[inline(never)]
    fn u8(&mut self) -> u8 {
        let b = self.body.get(self.pos).copied();
        if b.is_none() {
            self.fail(self.pos);
        }
        self.pos += 1;
        b.unwrap_or(0)
    }

    fn u16(&mut self) -> u16 {
        self.uint(2) as u16
    }

    fn u32(&mut self) -> u32 {
        self.uint(4)
    }

    /// A little-endian number of `n` bytes (2 or 4). A loop, not one call per byte (firmware size).
    #[inline(never)]
    fn uint(&mut self, n: u32) -> u32 {
        (0..n).fold(0, |v, i| v | u32::from(self.u8()) << (8 * i))
    }

    /// A byte that must be below `limit` (an enumeration code); 0 if it is not.
    fn code(&mut self, limit: u8) -> u8 {
        let v = self.u8();
        if v < limit {
            v
        } else {
            self.fail(self.pos - 1);
            0
        }
    }

    fn flag(&mut self) -> bool {
        self.code(2) == 1
    }

    /// A length byte and that many bytes, at most `N` (more is unreadable).
    fn list<const N: usize>(&mut self) -> heapless::Vec<u8, N> {
        let n = self.u8();
        let mut v = heapless::Vec::new();
        for _ in 0..n {
            let b = self.u8();
            if v.push(b).is_err() {
                self.fail(self.pos - 1);
            }
        }
        v
    }

    // Out of line, like `framed` and `modbus`: the configuration is built in the return slot, not
    // copied piece by piece through `decode` (firmware size budget).
    #[inline(never)]
    fn config(&mut self) -> ConverterConfig {
        let vendor_id = self.u16();
        let device_type = self.u16();
        let product_code = self.u16();
        let major_revision = self.u8();
        let minor_revision = self.u8();
        let serial_number = self.u32();
        let name: heapless::Vec<u8, { devicenet::slave::config::MAX_PRODUCT_NAME }> = self.list();
        let mac = self.u8();
        let baud = self.u8();
        let port = self.u8();
        let flags = self.code(4);
        let epr_resolution_ms = self.u16();
        self.layout.input = self.here();
        let input = if self.flag() { InputAssembly::WithStatus } else { InputAssembly::Plain };
        let profile = if self.flag() { ProfileConfig::Modbus(self.modbus()) } else { self.framed() };
        if self.pos != self.body.len() {
            self.fail(self.body.len().min(self.pos));
        }
        // Not ASCII is not printable ASCII: refused with the loader's words (control characters
        // are left to `check`). Byte by byte, so no UTF-8 validation is linked in.
        let mut product_name = heapless::String::new();
        for &b in &name {
            if b.is_ascii() {
                let _ = product_name.push(char::from(b));
            } else {
                self.invalid.get_or_insert(InvalidConfig::ProductNameNotAscii);
            }
        }
        let mac_id = MacId::new(mac).unwrap_or_else(|| {
            self.invalid.get_or_insert(InvalidConfig::MacId(mac));
            MacId::MAX
        });
        let baud_rate = BaudRate::from_attribute_value(baud).unwrap_or_else(|| {
            self.invalid.get_or_insert(InvalidConfig::BaudRate(baud));
            BaudRate::Kbps125
        });
        let mut device = DeviceConfig {
            identity: Identity {
                vendor_id,
                device_type,
                product_code,
                major_revision,
                minor_revision,
                serial_number,
                product_name,
            },
            mac_id,
            baud_rate,
            port,
            bus_off_interrupt: flags & 1 != 0,
            switches: Switches { programmable: flags & 2 != 0, ..Switches::default() },
            // Derived below.
            input_assembly: 0,
            output_assembly: 0,
            produced_size: 0,
            consumed_size: 0,
            epr_resolution_ms,
        };
        // Derived in place, not through `device_config`'s copy of the device (firmware size).
        super::derive_io(&mut device, &profile, input);
        ConverterConfig { device, profile, input }
    }

    #[inline(never)]
    fn framed(&mut self) -> ProfileConfig {
        let serial = self.serial();
        let framing = self.framing();
        let status_len = self.u8();
        let ack = if self.flag() {
            Some(AckFormat { data_len: self.u8(), flag: self.u8(), ok_status: self.u8() })
        } else {
            None
        };
        let mut commands = heapless::Vec::new();
        for _ in 0..self.u8() {
            let c = CommandFormat { code: self.u8(), wire: self.u8(), args: self.u8() };
            if commands.push(c).is_err() {
                self.fail(self.pos - 3);
            }
        }
        self.layout.timing = self.here();
        let sequencer = SequencerConfig {
            response_timeout_ms: self.u32(),
            retries: self.u8(),
            execute_first: self.flag(),
            on_idle: self.action(),
            on_fault: self.action(),
        };
        let health = self.health();
        ProfileConfig::Framed(FramedProfileConfig {
            serial,
            framing,
            status_len,
            ack,
            commands,
            sequencer,
            health,
        })
    }

    #[inline(never)]
    fn modbus(&mut self) -> ModbusConfig {
        let serial = self.serial();
        self.layout.timing = self.here();
        let response_timeout_ms = self.u32();
        let retries = self.u8();
        let poll_period_ms = self.u32();
        let input_len = self.u16();
        let output_len = self.u16();
        // Bit 0 the byte order, bits 1-2 the framing (0..=2), bit 3 the data-valid bits.
        let order = self.code(14);
        if order & 6 == 6 {
            self.fail(self.pos - 1);
        }
        let valid_bits_offset = (order & 8 != 0).then(|| self.u16());
        let byte_order = if order & 1 != 0 { ByteOrder::BigEndian } else { ByteOrder::LittleEndian };
        let framing = match (order >> 1) & 3 {
            0 => Framing::Rtu,
            1 => Framing::Ascii,
            _ => Framing::Tcp,
        };
        let mut scan = heapless::Vec::new();
        for _ in 0..self.u8() {
            let start = self.pos;
            let unit = self.u8();
            let code = self.u8();
            let (function, word_order) =
                match (Function::from_code(code & 0x1F), WordOrder::ALL.get(usize::from(code >> 5))) {
                    (Some(f), Some(&w)) => (f, w),
                    _ => {
                        self.fail(self.pos - 1);
                        (Function::ReadCoils, WordOrder::Registers)
                    }
                };
            let (address, count, offset) = (self.u16(), self.u16(), self.u16());
            let (period_ms, write, trigger_offset) = self.schedule(offset);
            let offset = offset & 0x7FFF;
            let e = ScanEntry {
                unit,
                function,
                address,
                count,
                offset,
                word_order,
                period_ms,
                write,
                trigger_offset,
            };
            if scan.push(e).is_err() {
                self.fail(start);
            }
        }
        ModbusConfig {
            serial,
            response_timeout_ms,
            retries,
            poll_period_ms,
            input_len,
            output_len,
            byte_order,
            framing,
            scan,
            health: self.health(),
            on_idle: self.action(),
            on_fault: self.action(),
            valid_bits_offset,
        }
    }

    /// A scan entry's schedule, present when bit 15 of its `offset` field is set.
    fn schedule(&mut self, offset: u16) -> (Option<u32>, WriteMode, Option<u16>) {
        if offset & 0x8000 == 0 {
            return (None, WriteMode::Change, None);
        }
        // Bits 0-1 the fields that follow, bits 2-3 the write mode (0..=2).
        let flags = self.code(12);
        let period = (flags & 1 != 0).then(|| self.u32());
        let trigger = (flags & 2 != 0).then(|| self.u16());
        let mode = WriteMode::ALL.get(usize::from(flags >> 2)).copied().unwrap_or(WriteMode::Change);
        (period, mode, trigger)
    }

    fn serial(&mut self) -> SerialSettings {
        self.layout.serial = self.here();
        let baud = self.u32();
        let format = self.code(16);
        let parity = match (format >> 1) & 3 {
            0 => Parity::None,
            1 => Parity::Even,
            2 => Parity::Odd,
            _ => {
                self.fail(self.pos - 1);
                Parity::None
            }
        };
        SerialSettings {
            baud,
            data_bits: if format & 1 != 0 { DataBits::Seven } else { DataBits::Eight },
            parity,
            stop_bits: if format & 8 != 0 { StopBits::Two } else { StopBits::One },
        }
    }

    fn framing(&mut self) -> FramedConfig {
        let start = self.u8();
        let kind = self.code(3);
        let fixed = self.u8();
        let length = match kind {
            0 => LengthField::Byte,
            1 => LengthField::Fixed(fixed),
            _ => LengthField::Delimited,
        };
        let end = if self.flag() { Some(self.u8()) } else { None };
        let checksum = match self.code(4) {
            0 => Checksum::None,
            1 => Checksum::Sum8,
            2 => Checksum::Xor8,
            _ => Checksum::Crc16Modbus,
        };
        FramedConfig { start, length, end, checksum, max_len: self.u8() }
    }

    fn health(&mut self) -> HealthConfig {
        self.layout.health = self.here();
        let stale_timeout_ms = self.u32();
        let stale_policy = if self.flag() { StalePolicy::Clear } else { StalePolicy::HoldLastValue };
        HealthConfig { stale_timeout_ms, stale_policy }
    }

    fn action(&mut self) -> IdleAction {
        if self.flag() {
            IdleAction::Send(self.list())
        } else {
            IdleAction::Nothing
        }
    }
}

#[cfg(test)]
mod tests;
