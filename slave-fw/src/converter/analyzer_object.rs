//! The serial-line analyzer object, vendor class [`ANALYZER_CLASS`] 0x68, instance 1: how a tool
//! reads the converter's [`Trace`] (the last bytes each way on the instrument's line and the line
//! events) over the bus. Ours, not a spec object: the class, its attributes and its service are
//! this converter's.
//!
//! | attribute | type | value |
//! |---|---|---|
//! | 1 | UDINT | the sequence number the next entry will get ([`Trace::next_seq`]) |
//! | 2 | USINT | entries the ring holds ([`ENTRIES`]) |
//! | 3 | USINT | bytes one entry holds ([`CHUNK`]) |
//!
//! Class attribute 1 is the revision, 1. Services (codes object-specific, protocol §3.2; error
//! codes §3.3):
//!
//! | code | service | request data | reply / errors |
//! |---|---|---|---|
//! | 0x0E | Get_Attribute_Single | attribute | 0x14 unknown attribute |
//! | 0x10 | Set_Attribute_Single | | 0x0E for attributes 1-3, 0x14 otherwise |
//! | 0x4B | [`READ_TRACE`] | from UDINT: the first sequence number wanted | first UDINT, next UDINT, then whole entries (the [`TraceEntry`] wire form) with sequence numbers first, first+1, …, at most [`MAX_REPLY`] bytes in all; 0x13 / 0x15 for less / more than 4 bytes |
//!
//! `first` is `from` when that entry is still held (or is the next one), else the oldest entry
//! held: `first − from` entries were overwritten before the reader asked (a `from` ahead of
//! `next`, a reader's number from before a restart, also starts at the oldest). A reader asks
//! again from `first + entries read` until that reaches `next`. Reading closes the newest entry
//! ([`Trace::seal`]), so an entry once read never grows.

use crate::serial::trace::{Trace, TraceEntry, CHUNK, ENTRIES, MAX_ENCODED_LEN};
use devicenet::explicit::{Request, ServiceCode};
use devicenet::slave::config::MAX_EXPLICIT_SIZE;
use devicenet::slave::{Reply, ServiceError};

/// Vendor-specific class of the serial-line analyzer object, instance 1.
pub const ANALYZER_CLASS: u16 = 0x68;
/// Read_Trace: the entries from a sequence number on.
pub const READ_TRACE: u8 = 0x4B;
/// The most bytes in one Read_Trace reply: the two sequence numbers and the entries. Within an
/// explicit message of the node (64 bytes with header and service); two full entries always fit.
pub const MAX_REPLY: usize = 56;
const _: () = assert!(MAX_REPLY >= 8 + 2 * MAX_ENCODED_LEN && MAX_REPLY + 2 <= MAX_EXPLICIT_SIZE);

/// Serves a request to [`ANALYZER_CLASS`] instance 1 (class instance 0 is the node's, which
/// answers the revision from `class_revision`).
pub fn handle(trace: &mut Trace, req: &Request<'_>, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
    if req.instance != 1 {
        return Err(ServiceError::OBJECT_DOES_NOT_EXIST);
    }
    match (req.service, req.data) {
        (ServiceCode::GetAttributeSingle, &[1]) => reply.u32(trace.next_seq()),
        (ServiceCode::GetAttributeSingle, &[2]) => reply.u8(ENTRIES as u8),
        (ServiceCode::GetAttributeSingle, &[3]) => reply.u8(CHUNK as u8),
        (ServiceCode::GetAttributeSingle, &[_]) => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        (ServiceCode::GetAttributeSingle, data) => Err(ServiceError::wrong_length(data, 1)),
        (ServiceCode::SetAttributeSingle, &[1..=3, ..]) => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
        (ServiceCode::SetAttributeSingle, &[_, ..]) => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        (ServiceCode::SetAttributeSingle, []) => Err(ServiceError::NOT_ENOUGH_DATA),
        (service, &[a, b, c, d]) if service.as_raw() == READ_TRACE => {
            read_trace(trace, u32::from_le_bytes([a, b, c, d]), reply)
        }
        (service, data) if service.as_raw() == READ_TRACE => Err(ServiceError::wrong_length(data, 4)),
        _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
    }
}

/// Read_Trace from `from` (module docs).
fn read_trace(trace: &mut Trace, from: u32, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
    trace.seal();
    let first = trace.start_from(from);
    let next = trace.next_seq();
    // The entries, after the two sequence numbers.
    let mut body = [0u8; MAX_REPLY - 8];
    let mut len = 0;
    let mut seq = first;
    while seq != next {
        let Some(entry) = trace.get(seq) else { break };
        let Some(n) = body.get_mut(len..).and_then(|rest| TraceEntry::encode(entry, rest)) else { break };
        len += n;
        seq = seq.wrapping_add(1);
    }
    reply.u32(first)?;
    reply.u32(next)?;
    reply.bytes(body.get(..len).unwrap_or(&[]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serial::trace::TraceKind;
    use devicenet::Instant;
    use rstest::rstest;
    use std::vec::Vec;

    /// Runs one request: `Ok(reply bytes)` or `Err((general status, additional code))`.
    fn call(t: &mut Trace, instance: u16, service: u8, data: &[u8]) -> Result<Vec<u8>, (u8, u8)> {
        let req = Request { service: ServiceCode::from(service), class: ANALYZER_CLASS, instance, data };
        // The node's reply room: the explicit message less its header and service bytes.
        let mut buf = [0u8; MAX_EXPLICIT_SIZE - 2];
        let mut reply = Reply::new(&mut buf);
        match handle(t, &req, &mut reply) {
            Ok(()) => {
                let n = reply.len();
                Ok(buf[..n].to_vec())
            }
            Err(e) => Err((e.general.as_raw(), e.additional)),
        }
    }

    fn read(t: &mut Trace, from: u32) -> (u32, u32, Vec<TraceEntry>) {
        let r = call(t, 1, READ_TRACE, &from.to_le_bytes()).unwrap();
        assert!(r.len() <= MAX_REPLY);
        let first = u32::from_le_bytes(r[..4].try_into().unwrap());
        let next = u32::from_le_bytes(r[4..8].try_into().unwrap());
        let mut entries = Vec::new();
        let mut rest = &r[8..];
        while !rest.is_empty() {
            let (e, n) = TraceEntry::parse(rest).unwrap();
            entries.push(e);
            rest = &rest[n..];
        }
        (first, next, entries)
    }

    fn ms(n: u64) -> Instant {
        Instant::from_millis(n)
    }

    #[rstest]
    #[case::next_seq(&[1], Ok(std::vec![3, 0, 0, 0]))]
    #[case::entries(&[2], Ok(std::vec![ENTRIES as u8]))]
    #[case::chunk(&[3], Ok(std::vec![CHUNK as u8]))]
    #[case::unknown(&[4], Err((0x14, 0xFF)))]
    #[case::zero(&[0], Err((0x14, 0xFF)))]
    #[case::no_attribute(&[], Err((0x13, 0xFF)))]
    #[case::two_bytes(&[1, 0], Err((0x15, 0xFF)))]
    fn get_attribute(#[case] data: &[u8], #[case] expected: Result<Vec<u8>, (u8, u8)>) {
        let mut t = Trace::new();
        for i in 0..3 {
            t.record_event(TraceKind::DriverOn, ms(i));
        }
        assert_eq!(call(&mut t, 1, 0x0E, data), expected);
    }

    #[rstest]
    #[case::other_instance(2, 0x0E, &[1], (0x16, 0xFF))]
    #[case::instance_zero(0, READ_TRACE, &[0, 0, 0, 0], (0x16, 0xFF))]
    #[case::set_known(1, 0x10, &[1, 0, 0, 0, 0], (0x0E, 0xFF))]
    #[case::set_unknown(1, 0x10, &[9, 0], (0x14, 0xFF))]
    #[case::set_nothing(1, 0x10, &[], (0x13, 0xFF))]
    #[case::read_short(1, READ_TRACE, &[0, 0, 0], (0x13, 0xFF))]
    #[case::read_long(1, READ_TRACE, &[0, 0, 0, 0, 0], (0x15, 0xFF))]
    #[case::read_nothing(1, READ_TRACE, &[], (0x13, 0xFF))]
    #[case::other_service(1, 0x4C, &[0], (0x08, 0xFF))]
    #[case::reset(1, 0x05, &[], (0x08, 0xFF))]
    fn malformed_requests_are_error_responses(
        #[case] instance: u16,
        #[case] service: u8,
        #[case] data: &[u8],
        #[case] error: (u8, u8),
    ) {
        let mut t = Trace::new();
        t.record_bytes(TraceKind::Receive, &[1, 2, 3], ms(0));
        assert_eq!(call(&mut t, instance, service, data), Err(error));
    }

    #[test]
    fn empty_trace_reads_no_entries() {
        assert_eq!(read(&mut Trace::new(), 0), (0, 0, Vec::new()));
        assert_eq!(read(&mut Trace::new(), 77), (0, 0, Vec::new()));
    }

    #[test]
    fn reads_every_entry_in_order_over_several_replies() {
        let mut t = Trace::new();
        let mut recorded = Vec::new();
        for i in 0..10u8 {
            let bytes = [i; CHUNK];
            t.record_bytes(
                if i % 2 == 0 { TraceKind::Transmit } else { TraceKind::Receive },
                &bytes,
                ms(i.into()),
            );
            t.record_event(TraceKind::Checksum, ms(i.into()));
            recorded.push(TraceEntry::new(i.into(), t.get(t.next_seq() - 2).unwrap().kind, &bytes).unwrap());
            recorded.push(TraceEntry::new(i.into(), TraceKind::Checksum, &[]).unwrap());
        }
        let mut from = 0;
        let mut got = Vec::new();
        let mut replies = 0;
        while from != t.next_seq() {
            let (first, next, entries) = read(&mut t, from);
            assert_eq!((first, next), (from, 20));
            // Full entries (22 bytes) and events (6 bytes): at least two a reply.
            assert!(entries.len() >= 2, "{entries:?}");
            from += entries.len() as u32;
            got.extend(entries);
            replies += 1;
        }
        assert_eq!(got, recorded);
        assert!(replies > 2);
    }

    #[test]
    fn reader_behind_the_ring_learns_what_it_missed() {
        let mut t = Trace::new();
        for i in 0..(ENTRIES as u64 + 10) {
            t.record_event(TraceKind::UartOverrun, ms(i));
        }
        let (first, next, entries) = read(&mut t, 3);
        assert_eq!((first, next), (10, ENTRIES as u32 + 10));
        assert_eq!(entries[0].time_ms, 10);
        assert_eq!(entries.len(), (MAX_REPLY - 8) / 6);
    }

    #[test]
    fn reading_closes_the_newest_entry() {
        let mut t = Trace::new();
        t.record_bytes(TraceKind::Receive, &[1], ms(5));
        let (_, next, entries) = read(&mut t, 0);
        assert_eq!((next, entries.len()), (1, 1));
        t.record_bytes(TraceKind::Receive, &[2], ms(5));
        let (first, next, entries) = read(&mut t, next);
        assert_eq!((first, next), (1, 2));
        assert_eq!(entries[0].bytes(), [2]);
    }

    /// The converter records what it hands to and takes from the UART, and the profile's
    /// checksum errors.
    #[test]
    fn converter_records_its_serial_traffic() {
        use crate::converter::{Converter, ConverterConfig};
        use crate::serial::breaker::{self, StatusData, SwitchState};
        let mut c = Converter::new(ConverterConfig::breaker_reference(), ms(0)).unwrap();
        c.power_on(ms(0));
        let mut wire = [0u8; 32];
        let n = breaker::FRAMING
            .encode(StatusData::new([1, 2, 3, 4], SwitchState::Open).as_bytes(), &mut wire)
            .unwrap();
        c.handle_serial(&wire[..n], ms(10));
        wire[n - 2] ^= 0xFF; // the checksum
        c.handle_serial(&wire[..n], ms(50));
        c.record_line_event(TraceKind::DriverOn, ms(60));
        let t = c.trace();
        let entries: Vec<(TraceKind, Vec<u8>)> = (t.oldest_seq()..t.next_seq())
            .map(|s| t.get(s).unwrap())
            .map(|e| (e.kind, e.bytes().to_vec()))
            .collect();
        let mut bad = wire[..n].to_vec();
        wire[n - 2] ^= 0xFF;
        let good = &wire[..n];
        assert_eq!(
            entries,
            [
                (TraceKind::Receive, good[..CHUNK].to_vec()),
                (TraceKind::Receive, good[CHUNK..].to_vec()),
                (TraceKind::Receive, bad.drain(..CHUNK).collect()),
                (TraceKind::Receive, bad),
                (TraceKind::Checksum, Vec::new()),
                (TraceKind::DriverOn, Vec::new()),
            ]
        );
    }

    /// A Modbus master's requests, as handed to the UART, are recorded as sent.
    #[test]
    fn converter_records_what_it_transmits() {
        use crate::converter::{Converter, ConverterConfig};
        use crate::serial::modbus::{Function, ModbusConfig, ScanEntry};
        use crate::serial::ProfileConfig;
        let scan = heapless::Vec::from_slice(&[ScanEntry {
            unit: 1,
            function: Function::ReadInputRegisters,
            address: 7,
            count: 1,
            offset: 0,
            word_order: Default::default(),
            period_ms: None,
            write: Default::default(),
            trigger_offset: None,
        }])
        .unwrap();
        let config = ConverterConfig {
            profile: ProfileConfig::Modbus(ModbusConfig::new(scan)),
            ..ConverterConfig::breaker_reference()
        };
        let mut c = Converter::new(config, ms(0)).unwrap();
        c.power_on(ms(0));
        let mut sent = Vec::new();
        for t in (0..2000).step_by(10) {
            while let Some(f) = c.poll_serial_transmit(ms(t)) {
                sent.extend_from_slice(f);
            }
        }
        assert!(sent.starts_with(&[1, 4, 0, 7, 0, 1]), "{sent:?}");
        let t = c.trace();
        let recorded: Vec<u8> = (t.oldest_seq()..t.next_seq())
            .map(|s| t.get(s).unwrap())
            .inspect(|e| assert_eq!(e.kind, TraceKind::Transmit))
            .flat_map(|e| e.bytes().to_vec())
            .collect();
        assert!(sent.ends_with(&recorded) && recorded.len() >= 8, "{sent:?} {recorded:?}");
    }

    proptest::proptest! {
        #[test]
        fn any_request_is_answered_without_panic(
            instance in 0u16..3,
            service in proptest::prelude::any::<u8>(),
            data in proptest::collection::vec(proptest::prelude::any::<u8>(), 0..8),
        ) {
            let mut t = Trace::new();
            t.record_bytes(TraceKind::Transmit, &[1; 40], ms(1));
            let _ = call(&mut t, instance, service, &data);
        }
    }
}
