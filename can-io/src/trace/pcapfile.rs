//! The pcap and pcapng reader of [`super::read_trace`]: classic pcap in either byte order with
//! microsecond or nanosecond timestamps, and pcapng, holding SocketCAN frames.
//!
//! The container formats are parsed by the `pcap-parser` crate (rusticata): it takes the whole
//! file as a slice, hands out each record's raw fields (so the timestamp arithmetic and the
//! interface options stay here, checked), and tells a record cut off by the end of the input
//! (`Incomplete`) from a corrupt one. This module reads the SocketCAN frame inside each record.
//! `pcap-file` 2.0.0 was the other candidate and was not taken: it turns an Enhanced Packet
//! Block's timestamp into nanoseconds whatever the interface's `if_tsresol` says (the default is
//! microseconds, so such files read 1000 times too early) and hides the raw units; its 3.0
//! release candidate needs Rust 1.93, above this workspace's 1.85.
//!
//! # Format facts relied on
//!
//! | fact | source |
//! |---|---|
//! | pcap file header: magic `A1B2C3D4` (µs) or `A1B23C4D` (ns) in the writer's byte order, version 2.4, link type in the last 4 bytes (its low 16 bits) | pcap draft (draft-ietf-opsawg-pcap) |
//! | pcapng: section header `0A0D0D0A` with its byte-order magic; each Enhanced Packet Block names an interface, numbered by the Interface Description Blocks of its section in order; `if_name` (option 2), `if_tsresol` (9, default 10^-6 s), `if_tsoffset` (14, seconds); EPB `epb_flags` (option 2) bits 0-1: 01 inbound, 10 outbound | pcapng draft (draft-ietf-opsawg-pcapng) |
//! | link type 227 (`LINKTYPE_CAN_SOCKETCAN`): CAN ID and flags **big-endian** (bottom 29 bits the ID, `0x80000000` extended, `0x40000000` remote, `0x20000000` error), payload length, FD flags (`CANFD_FDF` 0x04, `BRS` 0x01, `ESI` 0x02), 2 reserved bytes, payload; a 72-byte packet is a CAN FD frame when the FD flag is missing (older writers); the 0x80 bit of the length octet marks a CAN XL frame | tcpdump.org `linktypes/LINKTYPE_CAN_SOCKETCAN.html` |
//! | link type 190 (`LINKTYPE_CAN20B`) | no source found that gives its layout: its records are skipped as another link type |
//!
//! # What is read, what is skipped
//!
//! A record is numbered as Wireshark numbers frames: the n-th packet record of the file (classic
//! pcap records; pcapng Enhanced, Simple and obsolete Packet Blocks), 1-based; other pcapng blocks
//! are not numbered. Skipped (counted, named): error, CAN FD, CAN XL, extended and remote frames;
//! records too short for their SocketCAN header or their payload; a payload length over 8; records
//! of an interface whose link type is not 227; Simple Packet Blocks (they carry no timestamp); a
//! corrupt Enhanced Packet Block whose block length still fits in the file; and a half-written last
//! record (the file ends inside it). An unreadable file header, or a corrupt block that is not a
//! packet, stops the reading with an error.
//!
//! Timestamps are kept to the nearest microsecond ([`Instant::from_micros`]). `iface` is the
//! pcapng interface's `if_name`, else `if` and its number (`if0`); in classic pcap it is `pcap`.
//! The direction is read from `epb_flags` where a pcapng packet has it, else it is `None`.
//!
//! No input panics the reader: every length is checked against the bytes present, and nothing
//! is allocated from a length read in the file (the packets are borrowed from the input).

use super::entry::{LogEntry, LogError};
use super::{Direction, Sink};
use crate::pcap::LINKTYPE_CAN_SOCKETCAN;
use devicenet::{CanFrame, Instant};
use pcap_parser::nom;
use pcap_parser::pcap::{
    parse_pcap_frame, parse_pcap_frame_be, parse_pcap_frame_modified, parse_pcap_header, LegacyPcapBlock,
};
use pcap_parser::pcapng::{
    parse_block_be, parse_block_le, parse_sectionheaderblock, Block, EnhancedPacketBlock,
    InterfaceDescriptionBlock, OptionCode,
};
use pcap_parser::traits::PcapNGPacketBlock;
use pcap_parser::PcapError;

/// The size of a SocketCAN record's header (ID and flags, length, FD flags, 2 reserved bytes).
const SOCKETCAN_HEADER_LEN: usize = 8;
/// The size of a Linux `struct canfd_frame` (`CANFD_MTU`): a packet of this size is a CAN FD frame.
const CANFD_MTU: usize = 72;

const CAN_EFF_FLAG: u32 = 0x8000_0000;
const CAN_RTR_FLAG: u32 = 0x4000_0000;
const CAN_ERR_FLAG: u32 = 0x2000_0000;
const CAN_EFF_MASK: u32 = 0x1FFF_FFFF;
const CANFD_FDF: u8 = 0x04;
const CANFD_BRS_ESI: u8 = 0x03;
const CANXL_XLF: u8 = 0x80;

const PCAPNG_MAGIC: [u8; 4] = [0x0A, 0x0D, 0x0D, 0x0A];
const PCAP_FILE_HEADER_LEN: usize = 24;
const EPB_MAGIC: u32 = 0x0000_0006;
const OBSOLETE_PB_MAGIC: u32 = 0x0000_0002;

/// Reads a pcap or pcapng trace (told apart by the first 4 bytes) into `sink`.
pub fn read(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    if bytes.starts_with(&PCAPNG_MAGIC) {
        read_pcapng(bytes, sink)
    } else {
        read_pcap(bytes, sink)
    }
}

/// The SocketCAN frame in one packet, or why it is not a DeviceNet frame. `orig_len` is the
/// packet's length on the wire (a capture may keep fewer bytes).
fn socketcan_frame(packet: &[u8], orig_len: usize) -> Result<CanFrame, String> {
    let Some((header, payload)) = packet.split_first_chunk::<SOCKETCAN_HEADER_LEN>() else {
        return Err(format!(
            "truncated record: {} captured bytes, a SocketCAN header is {SOCKETCAN_HEADER_LEN}",
            packet.len()
        ));
    };
    let [i0, i1, i2, i3, len, fd_flags, _, _] = *header;
    let id_flags = u32::from_be_bytes([i0, i1, i2, i3]);
    if len & CANXL_XLF != 0 {
        return Err("CAN XL frame (0x80 set in the length octet) is not DeviceNet traffic".into());
    }
    if id_flags & CAN_ERR_FLAG != 0 {
        return Err(format!(
            "error frame (CAN_ERR_FLAG set, ID field {id_flags:08X}) is not DeviceNet traffic"
        ));
    }
    if fd_flags & CANFD_FDF != 0 || fd_flags & CANFD_BRS_ESI != 0 {
        return Err(format!("CAN FD frame (FD flags {fd_flags:02X}) is not DeviceNet traffic"));
    }
    if orig_len == CANFD_MTU || packet.len() == CANFD_MTU {
        return Err(format!("CAN FD frame ({CANFD_MTU}-byte canfd_frame) is not DeviceNet traffic"));
    }
    if id_flags & CAN_EFF_FLAG != 0 {
        return Err(format!(
            "extended frame (CAN_EFF_FLAG set, identifier {:08X}) is not DeviceNet traffic (11-bit identifiers only)",
            id_flags & CAN_EFF_MASK
        ));
    }
    if id_flags & CAN_RTR_FLAG != 0 {
        return Err(format!(
            "remote frame (CAN_RTR_FLAG set, identifier {:03X}) is not DeviceNet traffic",
            id_flags & CAN_EFF_MASK
        ));
    }
    if len > 8 {
        return Err(format!("DLC {len} > 8: a classic CAN frame holds at most 8 data bytes"));
    }
    let Some(data) = payload.get(..usize::from(len)) else {
        return Err(format!(
            "truncated record: {} captured bytes, the SocketCAN header and DLC {len} need {}",
            packet.len(),
            SOCKETCAN_HEADER_LEN + usize::from(len)
        ));
    };
    let id = u16::try_from(id_flags).ok().filter(|&id| id <= 0x7FF).ok_or_else(|| {
        format!("identifier {:X} does not fit in 11 bits (CAN_EFF_FLAG clear)", id_flags & CAN_EFF_MASK)
    })?;
    CanFrame::from_raw(id, data).map_err(|e| e.to_string())
}

/// Seconds and a fraction of `units_per_second` as microseconds, rounded to the nearest one.
fn micros(seconds: i128, fraction: u128, units_per_second: u128) -> Option<Instant> {
    let fraction_us =
        fraction.checked_mul(1_000_000)?.checked_add(units_per_second / 2)? / units_per_second.max(1);
    let total = seconds.checked_mul(1_000_000)?.checked_add(i128::try_from(fraction_us).ok()?)?;
    u64::try_from(total).ok().map(Instant::from_micros)
}

fn half_written(sink: &mut Sink<'_>, number: usize, present: usize, what: &str) -> Result<(), LogError> {
    sink.skip(number, 0, format!("half-written last record: the file ends {present} bytes into {what}"), "")
}

fn read_pcap(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    let (mut rest, header) = match parse_pcap_header(bytes) {
        Ok(parsed) => parsed,
        Err(nom::Err::Incomplete(_)) => {
            return Err(sink.error(
                0,
                0,
                format!("the pcap file header is cut off: {} of {PCAP_FILE_HEADER_LEN} bytes", bytes.len()),
                "",
            ))
        }
        Err(_) => {
            let magic: Vec<String> = bytes.iter().take(4).map(|b| format!("{b:02X}")).collect();
            return Err(sink.error(
                0,
                0,
                format!("not a pcap file: magic number {} (A1B2C3D4 or A1B23C4D expected)", magic.concat()),
                "",
            ));
        }
    };
    if header.version_major != 2 {
        return Err(sink.error(
            0,
            0,
            format!("pcap version {}.{} (2.4 expected)", header.version_major, header.version_minor),
            "",
        ));
    }
    // The low 16 bits are the link type; the high bits may carry the FCS length (pcap draft).
    let link_type = (header.network.0 as u32) & 0xFFFF;
    let units_per_second: u128 = if header.is_nanosecond_precision() { 1_000_000_000 } else { 1_000_000 };
    type FrameParser = fn(&[u8]) -> nom::IResult<&[u8], LegacyPcapBlock<'_>, PcapError<&[u8]>>;
    let parse: FrameParser = if header.is_modified_format() {
        parse_pcap_frame_modified
    } else if header.is_bigendian() {
        parse_pcap_frame_be
    } else {
        parse_pcap_frame
    };
    let mut number = 0;
    while !rest.is_empty() {
        number += 1;
        let record = match parse(rest) {
            Ok((next, record)) => {
                rest = next;
                record
            }
            Err(_) => return half_written(sink, number, rest.len(), "its record"),
        };
        if link_type != LINKTYPE_CAN_SOCKETCAN {
            sink.skip(number, 0, format!("link type {link_type} is not SocketCAN (227)"), "")?;
            continue;
        }
        let Some(at) = micros(record.ts_sec.into(), record.ts_usec.into(), units_per_second) else {
            sink.skip(number, 0, "timestamp out of range", "")?;
            continue;
        };
        match socketcan_frame(record.data, record.origlen as usize) {
            Ok(frame) => {
                sink.frame(LogEntry { line: number, at, iface: "pcap".into(), frame, direction: None })
            }
            Err(reason) => sink.skip(number, 0, reason, "")?,
        }
    }
    Ok(())
}

/// One interface of a pcapng section.
struct Interface {
    link_type: u32,
    name: std::sync::Arc<str>,
    /// Timestamp units per second (`if_tsresol`); `None` when the option is invalid.
    units_per_second: Option<u64>,
    /// Seconds added to every timestamp (`if_tsoffset`).
    offset: i64,
}

impl Interface {
    fn new(idb: &InterfaceDescriptionBlock<'_>, number: usize) -> Interface {
        let name = match idb.if_name() {
            Some(Ok(name)) if !name.trim_end_matches('\0').is_empty() => {
                name.trim_end_matches('\0').to_string()
            }
            _ => format!("if{number}"),
        };
        Interface {
            link_type: (idb.linktype.0 as u32) & 0xFFFF,
            name: name.into(),
            units_per_second: idb.ts_resolution(),
            offset: idb.ts_offset(),
        }
    }
}

/// The direction in `epb_flags`, if the packet has the option.
fn epb_direction(epb: &EnhancedPacketBlock<'_>) -> Option<Direction> {
    let option = epb.options.iter().find(|o| o.code == OptionCode(2))?;
    let value: [u8; 4] = option.value().get(..4)?.try_into().ok()?;
    let flags = if epb.big_endian() { u32::from_be_bytes(value) } else { u32::from_le_bytes(value) };
    match flags & 0b11 {
        0b01 => Some(Direction::Rx),
        0b10 => Some(Direction::Tx),
        _ => None,
    }
}

fn read_pcapng(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    let mut rest = bytes;
    let mut big_endian = match parse_sectionheaderblock(bytes) {
        Ok((_, shb)) => shb.big_endian(),
        Err(nom::Err::Incomplete(_)) => {
            return Err(sink.error(
                0,
                0,
                format!("the pcapng section header block is cut off ({} bytes)", bytes.len()),
                "",
            ))
        }
        Err(_) => return Err(sink.error(0, 0, "not a pcapng file: unreadable section header block", "")),
    };
    let mut interfaces: Vec<Interface> = Vec::new();
    let mut number = 0;
    while !rest.is_empty() {
        let offset = bytes.len() - rest.len();
        let parsed = if big_endian { parse_block_be(rest) } else { parse_block_le(rest) };
        let block = match parsed {
            Ok((next, block)) => {
                rest = next;
                block
            }
            Err(e) => {
                let word = |at: usize| -> Option<u32> {
                    let b: [u8; 4] = rest.get(at..at + 4)?.try_into().ok()?;
                    Some(if big_endian { u32::from_be_bytes(b) } else { u32::from_le_bytes(b) })
                };
                let Some(block_len) = word(4).map(|l| l as usize).filter(|&l| l <= rest.len()) else {
                    return half_written(sink, number + 1, rest.len(), "its block");
                };
                let block_type = word(0).unwrap_or(0);
                if block_type == EPB_MAGIC && block_len >= 12 {
                    number += 1;
                    let reason = match e {
                        nom::Err::Incomplete(_) => "its packet or options overrun the block".to_string(),
                        nom::Err::Error(PcapError::NomError(_, kind) | PcapError::OwnedNomError(_, kind))
                        | nom::Err::Failure(
                            PcapError::NomError(_, kind) | PcapError::OwnedNomError(_, kind),
                        ) => {
                            format!("its fields do not agree (parser check {kind:?})")
                        }
                        nom::Err::Error(e) | nom::Err::Failure(e) => format!("{e:?}"),
                    };
                    sink.skip(
                        number,
                        0,
                        format!("corrupt enhanced packet block at byte {offset}: {reason}"),
                        "",
                    )?;
                    rest = rest.get(block_len..).unwrap_or_default();
                    continue;
                }
                return Err(sink.error(
                    number + 1,
                    0,
                    format!(
                        "corrupt pcapng block (type {block_type:#X}, {block_len} bytes) at byte {offset}"
                    ),
                    "",
                ));
            }
        };
        match block {
            Block::SectionHeader(shb) => {
                big_endian = shb.big_endian();
                interfaces.clear();
            }
            Block::InterfaceDescription(idb) => {
                let interface = Interface::new(&idb, interfaces.len());
                interfaces.push(interface);
            }
            Block::EnhancedPacket(epb) => {
                number += 1;
                enhanced_packet(&epb, &interfaces, number, sink)?;
            }
            Block::SimplePacket(_) => {
                number += 1;
                sink.skip(number, 0, "simple packet block: it carries no timestamp", "")?;
            }
            Block::Unknown(unknown) if unknown.block_type == OBSOLETE_PB_MAGIC => {
                number += 1;
                sink.skip(number, 0, "obsolete packet block (type 2) is not read", "")?;
            }
            // Name resolution, statistics, journal, secrets, custom and unknown blocks hold no frames.
            _ => {}
        }
    }
    Ok(())
}

fn enhanced_packet(
    epb: &EnhancedPacketBlock<'_>,
    interfaces: &[Interface],
    number: usize,
    sink: &mut Sink<'_>,
) -> Result<(), LogError> {
    let Some(interface) = usize::try_from(epb.if_id).ok().and_then(|i| interfaces.get(i)) else {
        return sink.skip(
            number,
            0,
            format!(
                "the packet names interface {}, which no interface description block declares",
                epb.if_id
            ),
            "",
        );
    };
    if interface.link_type != LINKTYPE_CAN_SOCKETCAN {
        return sink.skip(
            number,
            0,
            format!("link type {} is not SocketCAN (227), interface {}", interface.link_type, interface.name),
            "",
        );
    }
    let Some(units_per_second) = interface.units_per_second else {
        return sink.skip(number, 0, format!("interface {} has an invalid if_tsresol", interface.name), "");
    };
    let units = (u64::from(epb.ts_high) << 32) | u64::from(epb.ts_low);
    let units_per_second = u128::from(units_per_second);
    let seconds = i128::from(units) / units_per_second as i128 + i128::from(interface.offset);
    let Some(at) = micros(seconds, u128::from(units) % units_per_second, units_per_second) else {
        return sink.skip(number, 0, "timestamp out of range", "");
    };
    match socketcan_frame(epb.packet_data(), epb.origlen as usize) {
        Ok(frame) => {
            sink.frame(LogEntry {
                line: number,
                at,
                iface: std::sync::Arc::clone(&interface.name),
                frame,
                direction: epb_direction(epb),
            });
            Ok(())
        }
        Err(reason) => sink.skip(number, 0, reason, ""),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pcap::{file_header, record};
    use rstest::rstest;

    fn read_all(bytes: &[u8]) -> Result<super::super::Trace, LogError> {
        let mut sink = Sink::new("t", false);
        read(bytes, &mut sink)?;
        Ok(sink.finish(super::super::TraceFormat::Pcap))
    }

    fn socketcan(id_flags: u32, len: u8, fd_flags: u8, data: &[u8]) -> Vec<u8> {
        let mut p = id_flags.to_be_bytes().to_vec();
        p.extend([len, fd_flags, 0, 0]);
        p.extend(data);
        p
    }

    #[rstest]
    #[case::error(socketcan(0x2000_0004, 8, 0, &[0; 8]), "error frame")]
    #[case::extended(socketcan(0x8000_042B, 1, 0, &[0; 8]), "extended frame")]
    #[case::remote(socketcan(0x4000_042B, 0, 0, &[0; 8]), "remote frame")]
    #[case::fd_flag(socketcan(0x42B, 8, CANFD_FDF, &[0; 8]), "CAN FD frame")]
    #[case::fd_size(socketcan(0x42B, 8, 0, &[0; 64]), "72-byte canfd_frame")]
    #[case::xl(socketcan(0x42B, 0x80, 0, &[0; 8]), "CAN XL")]
    #[case::dlc(socketcan(0x42B, 9, 0, &[0; 8]), "DLC 9 > 8")]
    #[case::short_header(vec![0, 0, 4], "3 captured bytes")]
    #[case::short_payload(socketcan(0x42B, 5, 0, &[1, 2]), "DLC 5 need 13")]
    #[case::wide_id(socketcan(0x0000_0800, 0, 0, &[0; 8]), "does not fit in 11 bits")]
    fn not_devicenet(#[case] packet: Vec<u8>, #[case] reason: &str) {
        let err = socketcan_frame(&packet, packet.len()).unwrap_err();
        assert!(err.contains(reason), "{err}");
    }

    #[test]
    fn classic_frame_with_short_capture() {
        // A capture may keep only the header and the payload (no zero padding).
        let f = socketcan_frame(&socketcan(0x42B, 3, 0, &[0x00, 0xCB, 0x00]), 16).unwrap();
        assert_eq!(f, CanFrame::from_raw(0x42B, &[0x00, 0xCB, 0x00]).unwrap());
    }

    #[test]
    fn our_writer_round_trips() {
        let frame = CanFrame::from_raw(0x407, &[0, 1, 0, 4, 3, 2, 1]).unwrap();
        let mut file = file_header().to_vec();
        file.extend(record(Instant::from_micros(1_000_423), &frame));
        let trace = read_all(&file).unwrap();
        assert_eq!(trace.entries.len(), 1);
        assert_eq!(trace.entries[0].frame, frame);
        assert_eq!(trace.entries[0].at, Instant::from_micros(1_000_423));
        assert_eq!((trace.entries[0].line, trace.entries[0].iface.as_ref()), (1, "pcap"));
    }

    #[test]
    fn nanoseconds_round_to_the_microsecond() {
        assert_eq!(micros(2, 999_999_600, 1_000_000_000), Some(Instant::from_micros(3_000_000)));
        assert_eq!(micros(0, 422_999_999, 1_000_000_000), Some(Instant::from_micros(423_000)));
        assert_eq!(micros(-1, 0, 1_000_000), None);
    }

    #[test]
    fn other_link_type_is_named() {
        let mut file = file_header().to_vec();
        file[20] = 1; // Ethernet
        file.extend(record(Instant::from_micros(0), &CanFrame::from_raw(0x407, &[]).unwrap()));
        let trace = read_all(&file).unwrap();
        assert_eq!(trace.skipped[0].reason, "link type 1 is not SocketCAN (227)");
    }

    #[rstest]
    #[case::empty(&[][..], "cut off: 0 of 24")]
    #[case::short(&[0xD4, 0xC3, 0xB2, 0xA1, 2, 0][..], "cut off: 6 of 24")]
    #[case::magic(&[0u8; 24][..], "not a pcap file: magic number 00000000")]
    #[case::version(&[0xD4, 0xC3, 0xB2, 0xA1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 16, 0, 0, 0, 227, 0, 0, 0][..], "pcap version 1.0")]
    #[case::pcapng(&[0x0A, 0x0D, 0x0D, 0x0A, 12, 0, 0, 0][..], "section header block is cut off")]
    fn bad_headers(#[case] bytes: &[u8], #[case] reason: &str) {
        let err = read_all(bytes).unwrap_err();
        assert!(err.reason.contains(reason), "{err}");
    }

    fn block(kind: u32, body: &[u8]) -> Vec<u8> {
        let len = (12 + body.len()) as u32;
        let mut b = kind.to_le_bytes().to_vec();
        b.extend(len.to_le_bytes());
        b.extend(body);
        b.extend(len.to_le_bytes());
        b
    }

    fn epb(caplen: u32, packet: &[u8]) -> Vec<u8> {
        let mut body = vec![0u8; 4];
        body.extend([0, 0, 0, 0, 0x40, 0x42, 0x0F, 0]); // 1 s in µs
        body.extend(caplen.to_le_bytes());
        body.extend((packet.len() as u32).to_le_bytes());
        body.extend(packet);
        block(EPB_MAGIC, &body)
    }

    fn pcapng(blocks: &[Vec<u8>]) -> Vec<u8> {
        let mut shb = 0x1A2B_3C4Du32.to_le_bytes().to_vec();
        shb.extend([1, 0, 0, 0]);
        shb.extend((-1i64).to_le_bytes());
        let mut file = block(0x0A0D_0D0A, &shb);
        file.extend(block(1, &[227, 0, 0, 0, 0, 0, 0, 0]));
        for b in blocks {
            file.extend(b);
        }
        file
    }

    #[test]
    fn corrupt_packet_block_is_skipped_and_reading_goes_on() {
        let packet = socketcan(0x407, 1, 0, &[9, 0, 0, 0, 0, 0, 0, 0]);
        let file = pcapng(&[epb(200, &packet), epb(16, &packet)]);
        let trace = read_all(&file).unwrap();
        assert_eq!(trace.entries.len(), 1);
        assert_eq!((trace.entries[0].line, trace.entries[0].iface.as_ref()), (2, "if0"));
        assert_eq!(trace.entries[0].at, Instant::from_micros(1_000_000));
        assert_eq!(trace.skipped[0].line, 1);
        assert!(
            trace.skipped[0].reason.starts_with("corrupt enhanced packet block at byte 48"),
            "{:?}",
            trace.skipped
        );
    }

    #[test]
    fn packet_of_an_undeclared_interface_is_skipped() {
        let mut bad = epb(16, &socketcan(0x407, 0, 0, &[0; 8]));
        bad[8] = 3;
        let trace = read_all(&pcapng(&[bad])).unwrap();
        assert!(
            trace.skipped[0].reason.contains("interface 3, which no interface description"),
            "{:?}",
            trace.skipped
        );
    }

    #[test]
    fn corrupt_block_that_is_not_a_packet_stops_the_reading() {
        let mut idb = block(1, &[227, 0, 0, 0, 0, 0, 0, 0]);
        let len = idb.len();
        idb[len - 4] = 0; // trailing length differs from the leading one
        let err = read_all(&pcapng(&[idb])).unwrap_err();
        assert!(err.reason.starts_with("corrupt pcapng block (type 0x1, 20 bytes) at byte 48"), "{err}");
    }

    #[test]
    fn half_written_record() {
        let mut file = file_header().to_vec();
        file.extend(record(Instant::from_micros(0), &CanFrame::from_raw(0x407, &[1]).unwrap()));
        file.extend(&record(Instant::from_micros(1), &CanFrame::from_raw(0x407, &[2]).unwrap())[..20]);
        let trace = read_all(&file).unwrap();
        assert_eq!(trace.entries.len(), 1);
        assert_eq!(trace.skipped[0].line, 2);
        assert!(trace.skipped[0].reason.starts_with("half-written last record"), "{:?}", trace.skipped);
    }
}
