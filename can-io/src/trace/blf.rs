//! The Vector BLF (binary logging format) reader of [`super::read_trace`].
//!
//! Written by hand on `flate2` (zlib). The `ablf` crate (0.2.1) was evaluated and not used: it
//! panics on a corrupt zlib stream or an unknown compression method and underflows on an object
//! size under 16, allocates a container's data from its untrusted size field, prints to stdout
//! and recurses once per byte on a bad signature, reads only version-1 object headers and takes
//! every timestamp as nanoseconds (the 10 µs flag ignored), and decodes neither `CAN_MESSAGE`
//! (type 1, the one python-can writes) nor the CAN FD objects (100, 101).
//!
//! # Format facts relied on
//!
//! No specification is published; python-can's `can/io/blf.py` (4.6, itself based on Toby
//! Lorenz' `vector_blf`) is the reference for everything below.
//!
//! | part | layout (little-endian) |
//! |---|---|
//! | file header | `LOGG`, header size u32 (144), application and version bytes, file size u64, uncompressed size u64, object count u32, objects read u32, measurement start and last object time as `SYSTEMTIME` (8 × u16: year, month, day of week, day, hour, minute, second, ms), at byte 40 and 56 |
//! | object | `LOBJ`, header size u16, header version u16, object size u32 (header included), object type u32; then for every type but `LOG_CONTAINER` an object header |
//! | object header v1 | flags u32, client index u16, object version u16, timestamp u64 (16 bytes) |
//! | object header v2 | flags u32, timestamp status u8, reserved u8, object version u16, timestamp u64, original timestamp u64 (24 bytes) |
//! | timestamp | since the measurement start; flags 1 = units of 10 µs, else (2) nanoseconds |
//! | `LOG_CONTAINER` (10) | compression method u16 (0 none, 2 zlib), 6 reserved, uncompressed size u32, 4 reserved, then the data: a stream of objects that may continue in the next container |
//! | padding | after a top-level object `object size % 4` bytes; inside a container it depends on the writer, so the next `LOBJ` is searched for within 8 bytes |
//! | `CAN_MESSAGE` (1), `CAN_MESSAGE2` (86) | channel u16, flags u8 (0x01 transmitted, 0x80 remote), DLC u8, ID u32 (0x80000000 extended), data 8 bytes (86 has more fields after) |
//! | `CAN_ERROR_EXT` (73) | an error frame |
//! | `CAN_FD_MESSAGE` (100) | channel u16, flags u8, DLC u8, ID u32, frame length u32, bit count u8, FD flags u8 (0x01 EDL), valid bytes u8, 5 reserved, data 64 bytes |
//! | `CAN_FD_MESSAGE_64` (101) | channel u8, DLC u8, valid bytes u8, tx count u8, ID u32, frame length u32, flags u32 (0x1000 EDL, 0x0010 remote), 4 × u32 bit timing, bit count u16, direction u8 (0 received), ext data offset u8, CRC u32, then the data |
//!
//! Not confirmed by any source: that the measurement start `SYSTEMTIME` is UTC (python-can writes
//! and reads it so; Vector's tools may write local time), and that a type-100 or type-101 object
//! with EDL clear is a classic frame (it is read as one, as python-can reads it with `is_fd` false).
//!
//! # What is read, what is skipped
//!
//! A record is a logged object, numbered 1-based in file order as python-can and the header's
//! object count count them (log containers are not numbered, the objects inside them are). The
//! timestamp is the measurement start (0 when the header holds no valid date, as python-can writes
//! for times before 1990) plus the object's time, to the nearest microsecond: writers that compute
//! nanoseconds from floating-point seconds, python-can among them, land a nanosecond short. `iface`
//! is the channel number as the file holds it (`1` for the first), and the direction is always
//! known.
//!
//! Skipped (counted, named): error frames, extended, remote and CAN FD messages, frame objects too
//! short for their fields or with a DLC over 8, frame objects with an unknown header version, log
//! containers with an unknown compression method or corrupt zlib data, and a half-written last
//! record. Objects that are not CAN frames (application text, markers, statistics, other buses)
//! are ignored without a count: they are not traffic. An unreadable file header, an object size
//! smaller than its header, or a missing `LOBJ` signature stops the reading with an error.
//!
//! No input panics the reader, and memory stays bounded: containers are inflated in fixed chunks,
//! an object continued across containers is held only up to [`MAX_OBJECT_LEN`] bytes (a larger
//! one is passed over as its bytes arrive), and no length read from the file sizes an allocation.

use super::entry::{LogEntry, LogError};
use super::{Direction, Sink};
use devicenet::{CanFrame, Instant};
use flate2::{Decompress, FlushDecompress, Status};

/// The largest object held while it continues across containers; larger ones are passed over.
pub const MAX_OBJECT_LEN: usize = 1 << 20;

const FILE_SIGNATURE: &[u8; 4] = b"LOGG";
const OBJECT_SIGNATURE: &[u8; 4] = b"LOBJ";
/// The fixed part of the file header, up to the two `SYSTEMTIME`s.
const FILE_HEADER_MIN: usize = 72;
const BASE_HEADER_LEN: usize = 16;
const CONTAINER_HEADER_LEN: usize = 16;
/// How far past an object the next `LOBJ` may start (padding).
const MAX_PADDING: usize = 8;
const INFLATE_CHUNK: usize = 16 * 1024;

const CAN_MESSAGE: u32 = 1;
const LOG_CONTAINER: u32 = 10;
const CAN_ERROR_EXT: u32 = 73;
const CAN_MESSAGE2: u32 = 86;
const CAN_FD_MESSAGE: u32 = 100;
const CAN_FD_MESSAGE_64: u32 = 101;

const NO_COMPRESSION: u16 = 0;
const ZLIB_DEFLATE: u16 = 2;
const TIME_TEN_MICS: u32 = 1;
const CAN_MSG_EXT: u32 = 0x8000_0000;
const CAN_ID_MASK: u32 = 0x1FFF_FFFF;

/// Reads a BLF trace into `sink`.
pub fn read(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    let (header_len, start) = file_header(bytes).map_err(|reason| sink.error(0, 0, reason, ""))?;
    let mut objects = Objects { pending: Vec::new(), pass_over: 0, number: 0, start, channels: Vec::new() };
    let mut pos = header_len;
    loop {
        let rest = bytes.get(pos..).unwrap_or_default();
        match next_signature(rest) {
            Next::At(padding) => pos += padding,
            Next::End => break,
            Next::Cut => return objects.half_written(sink, rest.len()),
            Next::Absent => {
                return Err(sink.error(
                    objects.number + 1,
                    0,
                    format!("no object signature LOBJ at byte {pos}"),
                    "",
                ))
            }
        }
        let rest = bytes.get(pos..).unwrap_or_default();
        let Some(base) = BaseHeader::parse(rest) else {
            return objects.half_written(sink, rest.len());
        };
        if base.size < BASE_HEADER_LEN {
            return Err(sink.error(
                objects.number + 1,
                0,
                format!(
                    "the object at byte {pos} declares {} bytes, less than its {BASE_HEADER_LEN}-byte header",
                    base.size
                ),
                "",
            ));
        }
        match rest.get(..base.size) {
            Some(object) if base.kind == LOG_CONTAINER => objects.container(object, pos, sink)?,
            Some(object) => objects.object(object, sink)?,
            None => {
                if base.kind == LOG_CONTAINER {
                    // An interrupted recording: the frames in what was written are kept.
                    objects.container(rest, pos, sink)?;
                }
                return objects.half_written(sink, rest.len());
            }
        }
        pos += base.size;
    }
    if objects.pending.iter().any(|&b| b != 0) || objects.pass_over > 0 {
        let present = objects.pending.len();
        return objects.half_written(sink, present);
    }
    Ok(())
}

/// The file header's size and the measurement start.
fn file_header(bytes: &[u8]) -> Result<(usize, u64), String> {
    if !bytes.starts_with(FILE_SIGNATURE) {
        return Err("not a BLF file: no LOGG signature".into());
    }
    let header_len = u32_at(bytes, 4).map(|n| n as usize).unwrap_or(0);
    if bytes.len() < FILE_HEADER_MIN || bytes.len() < header_len {
        return Err(format!(
            "the BLF file header is cut off: {} of {} bytes",
            bytes.len(),
            header_len.max(FILE_HEADER_MIN)
        ));
    }
    if header_len < FILE_HEADER_MIN {
        return Err(format!(
            "the BLF file header declares {header_len} bytes, less than the {FILE_HEADER_MIN} it holds"
        ));
    }
    let mut time = [0u16; 8];
    for (i, field) in time.iter_mut().enumerate() {
        *field = u16_at(bytes, 40 + 2 * i).unwrap_or(0);
    }
    Ok((header_len, systemtime_micros(time).unwrap_or(0)))
}

/// A `SYSTEMTIME` (taken as UTC) as microseconds since 1970; `None` for no valid date.
fn systemtime_micros(t: [u16; 8]) -> Option<u64> {
    let [year, month, _, day, hour, minute, second, millis] = t.map(u64::from);
    let valid = (1970..=9999).contains(&year)
        && (1..=12).contains(&month)
        && (1..=31).contains(&day)
        && hour < 24
        && minute < 60
        && second < 60
        && millis < 1000;
    if !valid {
        return None;
    }
    // Days from the civil date (H. Hinnant's algorithm), in March-based years.
    let (y, m) = if month <= 2 { (year - 1, month + 9) } else { (year, month - 3) };
    let era = y / 400;
    let yoe = y % 400;
    let doy = (153 * m + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    let days = (era * 146_097 + doe).checked_sub(719_468)?;
    let seconds = days * 86_400 + hour * 3600 + minute * 60 + second;
    Some(seconds * 1_000_000 + millis * 1000)
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at.checked_add(2)?)?.try_into().ok()?))
}

fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at.checked_add(4)?)?.try_into().ok()?))
}

fn u64_at(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at.checked_add(8)?)?.try_into().ok()?))
}

/// Where the next object starts.
#[derive(Debug, PartialEq, Eq)]
enum Next {
    /// After this many bytes of padding.
    At(usize),
    /// Nothing follows but zero padding.
    End,
    /// The bytes end before a signature could be found.
    Cut,
    /// No signature where one must be.
    Absent,
}

fn next_signature(rest: &[u8]) -> Next {
    if let Some(at) = rest.windows(4).take(MAX_PADDING).position(|w| w == OBJECT_SIGNATURE) {
        return Next::At(at);
    }
    if rest.len() >= MAX_PADDING + OBJECT_SIGNATURE.len() - 1 {
        Next::Absent
    } else if rest.iter().all(|&b| b == 0) {
        Next::End
    } else {
        Next::Cut
    }
}

/// The fields every object starts with.
struct BaseHeader {
    version: u16,
    size: usize,
    kind: u32,
}

impl BaseHeader {
    /// `None` when fewer than 16 bytes are present.
    fn parse(b: &[u8]) -> Option<BaseHeader> {
        Some(BaseHeader { version: u16_at(b, 6)?, size: u32_at(b, 8)? as usize, kind: u32_at(b, 12)? })
    }
}

/// The objects of a file, read from the top level and from containers, in order.
struct Objects {
    /// The start of an object that continues in the next container.
    pending: Vec<u8>,
    /// Bytes still to pass over of an object larger than [`MAX_OBJECT_LEN`].
    pass_over: usize,
    /// Objects seen so far.
    number: usize,
    /// The measurement start, in microseconds.
    start: u64,
    /// The channel names given out so far (entries of one channel share it).
    channels: Vec<(u16, std::sync::Arc<str>)>,
}

impl Objects {
    fn channel_name(&mut self, channel: u16) -> std::sync::Arc<str> {
        if let Some((_, name)) = self.channels.iter().find(|(c, _)| *c == channel) {
            return std::sync::Arc::clone(name);
        }
        let name: std::sync::Arc<str> = channel.to_string().into();
        self.channels.push((channel, std::sync::Arc::clone(&name)));
        name
    }

    fn half_written(&mut self, sink: &mut Sink<'_>, present: usize) -> Result<(), LogError> {
        self.pending.clear();
        sink.skip(
            self.number + 1,
            0,
            format!("half-written last record: the file ends {present} bytes into it"),
            "",
        )
    }

    /// A log container (`object` may be cut off at the end of the file).
    fn container(&mut self, object: &[u8], pos: usize, sink: &mut Sink<'_>) -> Result<(), LogError> {
        let method = u16_at(object, BASE_HEADER_LEN).unwrap_or(NO_COMPRESSION);
        let data = object.get(BASE_HEADER_LEN + CONTAINER_HEADER_LEN..).unwrap_or_default();
        match method {
            NO_COMPRESSION => data.chunks(INFLATE_CHUNK).try_for_each(|chunk| self.feed(chunk, sink)),
            ZLIB_DEFLATE => self.inflate(data, pos, sink),
            other => {
                self.pending.clear();
                self.pass_over = 0;
                sink.skip(
                    self.number + 1,
                    0,
                    format!("the log container at byte {pos} has unknown compression method {other} (0 or 2 expected)"),
                    "",
                )
            }
        }
    }

    fn inflate(&mut self, mut data: &[u8], pos: usize, sink: &mut Sink<'_>) -> Result<(), LogError> {
        let mut z = Decompress::new(true);
        let mut chunk = vec![0u8; INFLATE_CHUNK];
        loop {
            let (before_in, before_out) = (z.total_in(), z.total_out());
            let status = z.decompress(data, &mut chunk, FlushDecompress::None);
            let consumed = usize::try_from(z.total_in() - before_in).unwrap_or(data.len());
            let produced = usize::try_from(z.total_out() - before_out).unwrap_or(0);
            data = data.get(consumed..).unwrap_or_default();
            self.feed(chunk.get(..produced).unwrap_or_default(), sink)?;
            match status {
                Ok(Status::StreamEnd) => return Ok(()),
                // The input ran out (a container cut off by the end of the file).
                Ok(_) if consumed == 0 && produced == 0 => return Ok(()),
                Ok(_) => {}
                Err(e) => {
                    self.pending.clear();
                    self.pass_over = 0;
                    return sink.skip(
                        self.number + 1,
                        0,
                        format!("the log container at byte {pos} holds corrupt zlib data ({e}); its objects are lost"),
                        "",
                    );
                }
            }
        }
    }

    /// Bytes of the object stream inside containers.
    fn feed(&mut self, data: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
        let passed = self.pass_over.min(data.len());
        self.pass_over -= passed;
        let data = data.get(passed..).unwrap_or_default();
        if self.pending.is_empty() {
            let rest = self.parse_stream(data, sink)?;
            self.pending.extend_from_slice(rest);
        } else {
            let mut pending = std::mem::take(&mut self.pending);
            pending.extend_from_slice(data);
            let rest_len = self.parse_stream(&pending, sink)?.len();
            pending.drain(..pending.len() - rest_len);
            self.pending = pending;
        }
        Ok(())
    }

    /// Reads the whole objects in `stream`; returns what is left (the start of an object).
    fn parse_stream<'b>(&mut self, mut stream: &'b [u8], sink: &mut Sink<'_>) -> Result<&'b [u8], LogError> {
        loop {
            if self.pass_over > 0 {
                return Ok(&[]);
            }
            match next_signature(stream) {
                Next::At(padding) => stream = stream.get(padding..).unwrap_or_default(),
                Next::End | Next::Cut => return Ok(stream),
                Next::Absent => {
                    return Err(sink.error(
                        self.number + 1,
                        0,
                        "no object signature LOBJ inside a log container",
                        "",
                    ))
                }
            }
            let Some(base) = BaseHeader::parse(stream) else {
                return Ok(stream);
            };
            if base.size < BASE_HEADER_LEN {
                return Err(sink.error(
                    self.number + 1,
                    0,
                    format!(
                        "an object inside a log container declares {} bytes, less than its header",
                        base.size
                    ),
                    "",
                ));
            }
            if base.size > MAX_OBJECT_LEN {
                self.number += 1;
                if is_frame_object(base.kind) {
                    sink.skip(
                        self.number,
                        0,
                        format!("a CAN object of {} bytes (corrupt size)", base.size),
                        "",
                    )?;
                }
                let present = stream.len().min(base.size);
                self.pass_over = base.size - present;
                stream = stream.get(present..).unwrap_or_default();
                continue;
            }
            let Some(object) = stream.get(..base.size) else {
                return Ok(stream);
            };
            self.object(object, sink)?;
            stream = stream.get(base.size..).unwrap_or_default();
        }
    }

    /// One whole object that is not a container.
    fn object(&mut self, object: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
        self.number += 1;
        let number = self.number;
        let Some(base) = BaseHeader::parse(object) else {
            return Ok(());
        };
        if !is_frame_object(base.kind) {
            return Ok(());
        }
        let name = object_name(base.kind);
        let header_len = match base.version {
            1 => 16,
            2 => 24,
            v => return sink.skip(number, 0, format!("{name} with unknown object header version {v}"), ""),
        };
        let (Some(flags), Some(time)) =
            (u32_at(object, BASE_HEADER_LEN), u64_at(object, BASE_HEADER_LEN + 8))
        else {
            return sink.skip(
                number,
                0,
                format!("{name} of {} bytes is too short for its object header", object.len()),
                "",
            );
        };
        let offset = if flags == TIME_TEN_MICS {
            time.checked_mul(10)
        } else {
            time.checked_add(500).map(|t| t / 1000)
        };
        let Some(at) = offset.and_then(|o| o.checked_add(self.start)).map(Instant::from_micros) else {
            return sink.skip(number, 0, "timestamp out of range", "");
        };
        let body = object.get(BASE_HEADER_LEN + header_len..).unwrap_or_default();
        match frame(base.kind, body) {
            Ok((channel, frame, direction)) => {
                sink.frame(LogEntry {
                    line: number,
                    at,
                    iface: self.channel_name(channel),
                    frame,
                    direction: Some(direction),
                });
                Ok(())
            }
            Err(reason) => sink.skip(number, 0, reason, ""),
        }
    }
}

fn is_frame_object(kind: u32) -> bool {
    matches!(kind, CAN_MESSAGE | CAN_ERROR_EXT | CAN_MESSAGE2 | CAN_FD_MESSAGE | CAN_FD_MESSAGE_64)
}

fn object_name(kind: u32) -> &'static str {
    match kind {
        CAN_MESSAGE => "CAN_MESSAGE",
        CAN_ERROR_EXT => "CAN_ERROR_EXT",
        CAN_MESSAGE2 => "CAN_MESSAGE2",
        CAN_FD_MESSAGE => "CAN_FD_MESSAGE",
        CAN_FD_MESSAGE_64 => "CAN_FD_MESSAGE_64",
        _ => "object",
    }
}

/// The classic frame in a frame object's body: (channel, frame, direction), or why it is not one.
fn frame(kind: u32, body: &[u8]) -> Result<(u16, CanFrame, Direction), String> {
    let name = object_name(kind);
    let short = |need: usize| format!("{name} body of {} bytes is too short ({need} expected)", body.len());
    let field8 = |at: usize| body.get(at).copied();
    let (channel, dlc, id, remote, fd, tx, data_at) = match kind {
        CAN_ERROR_EXT => return Err("error frame (CAN_ERROR_EXT object) is not DeviceNet traffic".into()),
        CAN_MESSAGE | CAN_MESSAGE2 => {
            let (Some(channel), Some(flags), Some(dlc), Some(id)) =
                (u16_at(body, 0), field8(2), field8(3), u32_at(body, 4))
            else {
                return Err(short(16));
            };
            (channel, dlc, id, flags & 0x80 != 0, false, flags & 0x01 != 0, 8)
        }
        CAN_FD_MESSAGE => {
            let (Some(channel), Some(flags), Some(dlc), Some(id), Some(fd_flags)) =
                (u16_at(body, 0), field8(2), field8(3), u32_at(body, 4), field8(13))
            else {
                return Err(short(84));
            };
            (channel, dlc, id, flags & 0x80 != 0, fd_flags & 0x01 != 0, flags & 0x01 != 0, 20)
        }
        CAN_FD_MESSAGE_64 => {
            let (Some(channel), Some(dlc), Some(id), Some(flags), Some(dir)) =
                (field8(0), field8(1), u32_at(body, 4), u32_at(body, 12), field8(34))
            else {
                return Err(short(40));
            };
            (u16::from(channel), dlc, id, flags & 0x0010 != 0, flags & 0x1000 != 0, dir != 0, 40)
        }
        _ => return Err(format!("object type {kind} is not a CAN frame")),
    };
    if fd {
        return Err(format!("CAN FD frame ({name} object, EDL set) is not DeviceNet traffic"));
    }
    if id & CAN_MSG_EXT != 0 {
        return Err(format!(
            "extended frame (identifier {:08X}) is not DeviceNet traffic (11-bit identifiers only)",
            id & CAN_ID_MASK
        ));
    }
    if remote {
        return Err(format!("remote frame (identifier {:03X}) is not DeviceNet traffic", id & CAN_ID_MASK));
    }
    if dlc > 8 {
        return Err(format!("DLC {dlc} > 8: a classic CAN frame holds at most 8 data bytes"));
    }
    let Some(data) = body.get(data_at..data_at + usize::from(dlc)) else {
        return Err(short(data_at + usize::from(dlc)));
    };
    let raw = u16::try_from(id).ok().filter(|&id| id <= 0x7FF).ok_or_else(|| {
        format!("identifier {:X} does not fit in 11 bits (extended bit clear)", id & CAN_ID_MASK)
    })?;
    let frame = CanFrame::from_raw(raw, data).map_err(|e| e.to_string())?;
    Ok((channel, frame, if tx { Direction::Tx } else { Direction::Rx }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::{Trace, TraceFormat};
    use rstest::rstest;
    use std::io::Write;

    fn file_header_bytes() -> Vec<u8> {
        let mut h = vec![0u8; 144];
        h[..4].copy_from_slice(b"LOGG");
        h[4..8].copy_from_slice(&144u32.to_le_bytes());
        h
    }

    /// An object with a v1 (or v2) header, nanosecond time, padded as python-can pads.
    fn object(kind: u32, version: u16, flags: u32, time: u64, body: &[u8]) -> Vec<u8> {
        let header_len: usize = if version == 2 { 40 } else { 32 };
        let size = header_len + body.len();
        let mut o = b"LOBJ".to_vec();
        o.extend((header_len as u16).to_le_bytes());
        o.extend(version.to_le_bytes());
        o.extend((size as u32).to_le_bytes());
        o.extend(kind.to_le_bytes());
        o.extend(flags.to_le_bytes());
        o.extend([0u8; 4]);
        o.extend(time.to_le_bytes());
        if version == 2 {
            o.extend([0u8; 8]);
        }
        o.extend(body);
        o.extend(vec![0u8; body.len() % 4]);
        o
    }

    fn can_message(channel: u16, flags: u8, dlc: u8, id: u32, data: [u8; 8]) -> Vec<u8> {
        let mut b = channel.to_le_bytes().to_vec();
        b.extend([flags, dlc]);
        b.extend(id.to_le_bytes());
        b.extend(data);
        b
    }

    fn container(method: u16, stream: &[u8]) -> Vec<u8> {
        let data = if method == ZLIB_DEFLATE {
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(stream).unwrap();
            z.finish().unwrap()
        } else {
            stream.to_vec()
        };
        let size = 32 + data.len();
        let mut o = b"LOBJ".to_vec();
        o.extend(16u16.to_le_bytes());
        o.extend(1u16.to_le_bytes());
        o.extend((size as u32).to_le_bytes());
        o.extend(LOG_CONTAINER.to_le_bytes());
        o.extend(method.to_le_bytes());
        o.extend([0u8; 6]);
        o.extend((stream.len() as u32).to_le_bytes());
        o.extend([0u8; 4]);
        o.extend(data);
        o.extend(vec![0u8; size % 4]);
        o
    }

    fn read_all(bytes: &[u8], strict: bool) -> Result<Trace, LogError> {
        let mut sink = Sink::new("t.blf", strict);
        read(bytes, &mut sink)?;
        Ok(sink.finish(TraceFormat::Blf))
    }

    fn stream() -> Vec<u8> {
        let mut s =
            object(CAN_MESSAGE, 1, 2, 423_000, &can_message(1, 0, 3, 0x42B, [0, 0xCB, 0, 0, 0, 0, 0, 0]));
        s.extend(object(65, 1, 2, 0, b"app text, ignored"));
        s.extend(object(CAN_MESSAGE2, 2, TIME_TEN_MICS, 100, &can_message(2, 1, 0, 0x7FF, [0; 8])));
        s
    }

    #[rstest]
    #[case::uncompressed(NO_COMPRESSION)]
    #[case::zlib(ZLIB_DEFLATE)]
    fn messages_in_containers(#[case] method: u16) {
        let mut file = file_header_bytes();
        file.extend(container(method, &stream()));
        let trace = read_all(&file, true).unwrap();
        let e = &trace.entries;
        assert_eq!(e.len(), 2);
        assert_eq!((e[0].line, e[0].iface.as_ref(), e[0].direction), (1, "1", Some(Direction::Rx)));
        assert_eq!(e[0].at, Instant::from_micros(423));
        assert_eq!(e[0].frame, CanFrame::from_raw(0x42B, &[0, 0xCB, 0]).unwrap());
        // Version-2 header, 10 µs units, transmitted.
        assert_eq!((e[1].line, e[1].iface.as_ref(), e[1].direction), (3, "2", Some(Direction::Tx)));
        assert_eq!(e[1].at, Instant::from_micros(1000));
        assert_eq!(trace.skipped_count, 0);
    }

    #[test]
    fn objects_span_containers() {
        let s = stream();
        let mut file = file_header_bytes();
        for piece in s.chunks(7) {
            file.extend(container(ZLIB_DEFLATE, piece));
        }
        let trace = read_all(&file, true).unwrap();
        assert_eq!(trace.entries.len(), 2);
    }

    #[test]
    fn top_level_objects_and_measurement_start() {
        let mut file = file_header_bytes();
        // 2024-04-26 18:52:20.500 UTC
        for (i, v) in [2024u16, 4, 5, 26, 18, 52, 20, 500].iter().enumerate() {
            file[40 + 2 * i..42 + 2 * i].copy_from_slice(&v.to_le_bytes());
        }
        file.extend(object(CAN_MESSAGE, 1, 2, 1_000, &can_message(1, 0, 0, 0x407, [0; 8])));
        let trace = read_all(&file, true).unwrap();
        assert_eq!(trace.entries[0].at, Instant::from_micros(1_714_157_540_500_001));
    }

    fn fd64(flags: u32, dlc: u8) -> Vec<u8> {
        let mut b = vec![1, dlc, dlc, 0];
        b.extend(0x42Bu32.to_le_bytes());
        b.extend(0u32.to_le_bytes());
        b.extend(flags.to_le_bytes());
        b.extend([0u8; 16 + 2]);
        b.extend([1, 0]); // direction Tx, no ext data
        b.extend([0u8; 4]);
        b.extend([0xAA; 8]);
        b
    }

    fn fd(fd_flags: u8) -> Vec<u8> {
        let mut b = 1u16.to_le_bytes().to_vec();
        b.extend([0, 2]);
        b.extend(0x42Bu32.to_le_bytes());
        b.extend([0u8; 5]);
        b.extend([fd_flags, 2, 0, 0, 0, 0, 0]);
        b.extend([0x55; 64]);
        b
    }

    #[rstest]
    #[case::error(CAN_ERROR_EXT, vec![0u8; 32], Err("error frame"))]
    #[case::extended(CAN_MESSAGE, can_message(1, 0, 1, 0x8000_042B, [0; 8]), Err("extended frame (identifier 0000042B)"))]
    #[case::remote(CAN_MESSAGE, can_message(1, 0x80, 0, 0x42B, [0; 8]), Err("remote frame"))]
    #[case::dlc(CAN_MESSAGE, can_message(1, 0, 9, 0x42B, [0; 8]), Err("DLC 9 > 8"))]
    #[case::wide(CAN_MESSAGE2, can_message(1, 0, 0, 0x800, [0; 8]), Err("does not fit in 11 bits"))]
    #[case::short(CAN_MESSAGE, vec![1, 0, 0], Err("too short"))]
    #[case::fd(CAN_FD_MESSAGE, fd(1), Err("CAN FD frame (CAN_FD_MESSAGE object"))]
    #[case::fd_classic(CAN_FD_MESSAGE, fd(0), Ok((0x42B, 2, Direction::Rx)))]
    #[case::fd64(CAN_FD_MESSAGE_64, fd64(0x1000, 8), Err("CAN FD frame (CAN_FD_MESSAGE_64"))]
    #[case::fd64_remote(CAN_FD_MESSAGE_64, fd64(0x0010, 0), Err("remote frame"))]
    #[case::fd64_classic(CAN_FD_MESSAGE_64, fd64(0, 8), Ok((0x42B, 8, Direction::Tx)))]
    fn frame_objects(
        #[case] kind: u32,
        #[case] body: Vec<u8>,
        #[case] expected: Result<(u16, usize, Direction), &str>,
    ) {
        match (frame(kind, &body), expected) {
            (Ok((_, f, d)), Ok((id, len, dir))) => {
                assert_eq!((f.id().as_raw(), f.data().len(), d), (id, len, dir))
            }
            (Err(reason), Err(part)) => assert!(reason.contains(part), "{reason}"),
            (got, want) => panic!("{got:?} vs {want:?}"),
        }
    }

    #[rstest]
    #[case::no_signature(b"LOGX".to_vec(), "no LOGG signature")]
    #[case::cut(b"LOGG\x90\0\0\0".to_vec(), "cut off: 8 of 144")]
    #[case::small(
        { let mut h = file_header_bytes(); h[4] = 16; h },
        "declares 16 bytes"
    )]
    #[case::garbage({ let mut h = file_header_bytes(); h.extend([0x11; 32]); h }, "no object signature LOBJ at byte 144")]
    #[case::tiny_object({ let mut h = file_header_bytes(); h.extend(b"LOBJ\x10\0\x01\0\x04\0\0\0\x01\0\0\0"); h }, "declares 4 bytes")]
    fn file_errors(#[case] bytes: Vec<u8>, #[case] reason: &str) {
        let err = read_all(&bytes, false).unwrap_err();
        assert!(err.reason.contains(reason), "{err}");
    }

    #[test]
    fn unknown_compression_and_corrupt_zlib_are_skipped() {
        let mut file = file_header_bytes();
        let mut bad_method = container(NO_COMPRESSION, &stream());
        bad_method[16] = 7;
        file.extend(bad_method);
        let mut corrupt = container(ZLIB_DEFLATE, &stream());
        let len = corrupt.len();
        corrupt[40..len - 8].fill(0xFF);
        file.extend(corrupt);
        file.extend(container(ZLIB_DEFLATE, &stream()));
        let trace = read_all(&file, false).unwrap();
        assert_eq!(trace.entries.len(), 2);
        assert!(trace.skipped[0].reason.contains("unknown compression method 7"), "{:?}", trace.skipped);
        assert!(trace.skipped[1].reason.contains("corrupt zlib data"), "{:?}", trace.skipped);
        let err = read_all(&file, true).unwrap_err();
        assert!(err.reason.contains("unknown compression method 7"), "{err}");
    }

    #[test]
    fn half_written_container_keeps_its_whole_objects() {
        let mut file = file_header_bytes();
        file.extend(container(NO_COMPRESSION, &stream()));
        file.truncate(file.len() - 30);
        let trace = read_all(&file, false).unwrap();
        assert_eq!(trace.entries.len(), 1);
        assert_eq!(trace.skipped[0].line, 3);
        assert!(trace.skipped[0].reason.starts_with("half-written last record"), "{:?}", trace.skipped);
    }

    #[test]
    fn oversized_objects_are_passed_over() {
        let mut s = b"LOBJ\x20\0\x01\0".to_vec();
        s.extend(((MAX_OBJECT_LEN + 100) as u32).to_le_bytes());
        s.extend(65u32.to_le_bytes());
        s.resize(MAX_OBJECT_LEN + 100, 0);
        s.extend(stream());
        let mut file = file_header_bytes();
        for piece in s.chunks(100_000) {
            file.extend(container(ZLIB_DEFLATE, piece));
        }
        let trace = read_all(&file, true).unwrap();
        assert_eq!(trace.entries.len(), 2);
        assert_eq!(trace.entries[0].line, 2);
    }

    #[test]
    fn systemtime() {
        assert_eq!(systemtime_micros([1970, 1, 4, 1, 0, 0, 0, 0]), Some(0));
        assert_eq!(systemtime_micros([2000, 3, 3, 1, 0, 0, 1, 2]), Some(951_868_801_002_000));
        assert_eq!(systemtime_micros([0; 8]), None);
        assert_eq!(systemtime_micros([2024, 13, 0, 1, 0, 0, 0, 0]), None);
    }
}
