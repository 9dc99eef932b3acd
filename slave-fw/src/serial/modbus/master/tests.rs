use super::*;
use crate::serial::modbus::{Function, Request, Response};
use crate::serial::{
    DataBits, Field, IdleAction, LinkState, Problem, SerialSettings, StalePolicy, StatusByte,
};
use proptest::prelude::*;
use rstest::rstest;
use std::string::ToString;
use std::vec::Vec as StdVec;

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

fn entry(unit: u8, function: Function, address: u16, count: u16, offset: u16) -> ScanEntry {
    ScanEntry {
        unit,
        function,
        address,
        count,
        offset,
        word_order: Default::default(),
        period_ms: None,
        write: Default::default(),
        trigger_offset: None,
    }
}

/// Two reads, two writes:
/// 0: unit 1 holding 0..2 → input 0..4; 1: unit 1 coils 0..10 → input 4..6;
/// 2: unit 1 registers 10..12 ← output 0..4; 3: unit 2 coil 5 ← output bit 4.0.
fn config() -> ModbusConfig {
    let scan = Vec::from_slice(&[
        entry(1, Function::ReadHoldingRegisters, 0, 2, 0),
        entry(1, Function::ReadCoils, 0, 10, 4),
        entry(1, Function::WriteMultipleRegisters, 10, 2, 0),
        entry(2, Function::WriteSingleCoil, 5, 1, 4),
    ])
    .unwrap();
    let mut c = ModbusConfig::new(scan);
    c.serial = SerialSettings::new_8e1(38400);
    c.response_timeout_ms = 100;
    c.retries = 2;
    c.poll_period_ms = 1000;
    c
}

/// A slave with 32 holding registers and 32 coils per unit address (1 and 2).
#[derive(Default)]
struct Slave {
    holding: [[u16; 32]; 3],
    coils: [[bool; 32]; 3],
    silent: bool,
    exception: Option<ExceptionCode>,
    corrupt_next: bool,
    garbage_first: StdVec<u8>,
    requests: StdVec<StdVec<u8>>,
}

impl Slave {
    fn answer(&mut self, adu: &[u8]) -> Option<StdVec<u8>> {
        self.requests.push(adu.to_vec());
        if self.silent {
            return None;
        }
        let (unit, request) = Request::parse(adu).unwrap();
        let u = usize::from(unit);
        let mut data = [0u8; 256];
        let response = if let Some(code) = self.exception {
            Response::Exception { function: request.function().code(), code }
        } else {
            match request {
                Request::ReadHoldingRegisters { address, count } => {
                    for k in 0..usize::from(count) {
                        data[2 * k..2 * k + 2]
                            .copy_from_slice(&self.holding[u][usize::from(address) + k].to_be_bytes());
                    }
                    Response::ReadHoldingRegisters(&data[..2 * usize::from(count)])
                }
                Request::ReadCoils { address, count } => {
                    for k in 0..usize::from(count) {
                        if self.coils[u][usize::from(address) + k] {
                            data[k / 8] |= 1 << (k % 8);
                        }
                    }
                    Response::ReadCoils(&data[..usize::from(count).div_ceil(8)])
                }
                Request::WriteMultipleRegisters { address, values } => {
                    for (k, v) in values.chunks(2).enumerate() {
                        self.holding[u][usize::from(address) + k] = u16::from_be_bytes([v[0], v[1]]);
                    }
                    Response::WriteMultipleRegisters { address, count: (values.len() / 2) as u16 }
                }
                Request::WriteSingleCoil { address, value } => {
                    self.coils[u][usize::from(address)] = value;
                    Response::WriteSingleCoil { address, value }
                }
                other => panic!("unexpected {other:?}"),
            }
        };
        let mut out = [0u8; 256];
        let n = response.emit(unit, &mut out).unwrap();
        let mut v = std::mem::take(&mut self.garbage_first);
        v.extend_from_slice(&out[..n]);
        if self.corrupt_next {
            self.corrupt_next = false;
            let last = v.len() - 1;
            v[last] ^= 0xFF;
        }
        Some(v)
    }
}

/// Runs master and slave on a virtual clock from `*now` to `until`; the slave answers 5 ms
/// after each request.
fn run(m: &mut ModbusMaster, slave: &mut Slave, now: &mut Instant, until: Instant) {
    run_unless(m, slave, None, now, until);
}

/// [`run`], with unit `mute` (when given) not answering.
fn run_unless(m: &mut ModbusMaster, slave: &mut Slave, mute: Option<u8>, now: &mut Instant, until: Instant) {
    for _ in 0..10_000 {
        while let Some(req) = m.poll_transmit(*now) {
            let req = req.to_vec();
            if let Some(resp) = slave.answer(&req).filter(|_| Some(req[0]) != mute) {
                *now += Duration::from_millis(5);
                m.on_bytes(&resp, *now);
            }
        }
        match m.poll_at() {
            Some(t) if t <= until => *now = t.max(*now + Duration::from_micros(1)),
            _ => {
                *now = (*now).max(until);
                m.poll(*now);
                return;
            }
        }
    }
    panic!("runaway");
}

/// What `Request::emit` writes for entry `e` (writes take their data from `output`).
fn emitted(e: &ScanEntry, output: &[u8], order: ByteOrder, out: &mut [u8]) -> Option<usize> {
    if let Some(read) = Request::read(e.function, e.address, e.count) {
        return read.emit(e.unit, out).ok();
    }
    let data = output.get(e.range())?;
    let word = |k: usize| {
        let (a, b) = (data.get(k).copied().unwrap_or(0), data.get(k + 1).copied().unwrap_or(0));
        match order {
            ByteOrder::BigEndian => u16::from_be_bytes([a, b]),
            ByteOrder::LittleEndian => u16::from_le_bytes([a, b]),
        }
    };
    let mut scratch = data.to_vec();
    let request = match e.function {
        Function::WriteSingleCoil => {
            Request::WriteSingleCoil { address: e.address, value: data.first().is_some_and(|b| b & 1 != 0) }
        }
        Function::WriteSingleRegister => Request::WriteSingleRegister { address: e.address, value: word(0) },
        Function::WriteMultipleCoils => {
            if let (Some(last), 1..) = (scratch.last_mut(), e.count % 8) {
                *last &= (1 << (e.count % 8)) - 1;
            }
            Request::WriteMultipleCoils { address: e.address, count: e.count, bits: &scratch }
        }
        _ => {
            for (k, pair) in scratch.chunks_exact_mut(2).enumerate() {
                pair.copy_from_slice(&word(2 * k).to_be_bytes());
            }
            Request::WriteMultipleRegisters { address: e.address, values: &scratch }
        }
    };
    request.emit(e.unit, out).ok()
}

fn master(c: ModbusConfig) -> ModbusMaster {
    ModbusMaster::new(c, ms(0)).unwrap()
}

#[rstest]
#[case::little_endian(ByteOrder::LittleEndian, [0x34, 0x12, 0xCD, 0xAB])]
#[case::big_endian(ByteOrder::BigEndian, [0x12, 0x34, 0xAB, 0xCD])]
fn reads_fill_the_input_image(#[case] order: ByteOrder, #[case] registers: [u8; 4]) {
    let mut c = config();
    c.byte_order = order;
    let mut m = master(c);
    let mut s = Slave::default();
    s.holding[1][0] = 0x1234;
    s.holding[1][1] = 0xABCD;
    s.coils[1][0] = true;
    s.coils[1][9] = true;
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(500));
    assert_eq!(&m.input_image()[..4], &registers);
    assert_eq!(&m.input_image()[4..], &[0x01, 0x02]);
    assert_eq!(m.completed_cycles(), 1);
    assert_eq!(s.requests.len(), 2, "no writes before the first outputs");
    assert_eq!(s.requests[0], [0x01, 0x03, 0x00, 0x00, 0x00, 0x02, 0xC4, 0x0B]);
    let st = m.status();
    assert_eq!((st.state, st.freshness), (LinkState::Ok, 2));
    assert_eq!(m.stats().frames_received, 2);
}

#[test]
fn writes_only_when_outputs_change() {
    let mut m = master(config());
    let mut s = Slave::default();
    let mut now = ms(0);
    for k in 0..100u64 {
        m.set_outputs(&[0x01, 0x00, 0x02, 0x00, 0x01], now);
        run(&mut m, &mut s, &mut now, ms(k * 50));
    }
    let writes = |s: &Slave, f: u8| s.requests.iter().filter(|r| r[1] == f).count();
    assert_eq!((writes(&s, 0x10), writes(&s, 0x05)), (1, 1));
    assert_eq!((s.holding[1][10], s.holding[1][11], s.coils[2][5]), (1, 2, true));
    assert_eq!(m.stats().commands_sent, 2);
    assert_eq!(m.status().command, CommandOutcome::Ok);

    // A change in bits the coil entry ignores writes nothing; a register change rewrites
    // only the register entry.
    m.set_outputs(&[0x01, 0x00, 0x02, 0x00, 0xFF], now);
    let until = now + Duration::from_millis(50);
    run(&mut m, &mut s, &mut now, until);
    m.set_outputs(&[0x05, 0x00, 0x02, 0x00, 0xFF], now);
    let until = now + Duration::from_millis(50);
    run(&mut m, &mut s, &mut now, until);
    assert_eq!((writes(&s, 0x10), writes(&s, 0x05)), (2, 1));
    assert_eq!(s.holding[1][10], 5);
    let last_write = s.requests.iter().rev().find(|r| r[1] == 0x10).unwrap();
    assert_eq!(&last_write[..11], &[0x01, 0x10, 0x00, 0x0A, 0x00, 0x02, 0x04, 0x00, 0x05, 0x00, 0x02]);
}

#[test]
fn write_goes_out_before_the_next_read() {
    let mut m = master(config());
    m.set_outputs(&[0, 0, 0, 0, 1], ms(0));
    let first = m.poll_transmit(ms(0)).unwrap().to_vec();
    assert_eq!(first[1], 0x10);
}

#[test]
fn exception_is_counted_and_shown_until_a_clean_cycle() {
    let mut m = master(config());
    let mut s = Slave { exception: Some(ExceptionCode::IllegalDataAddress), ..Slave::default() };
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(500));
    assert_eq!(m.stats().modbus_exceptions, 2);
    assert_eq!(m.last_exception(), Some((1, ExceptionCode::IllegalDataAddress)));
    assert_eq!(s.requests.len(), 2, "exceptions are not retried");
    let b = m.status().status_byte();
    assert!(b.contains(StatusByte::EXCEPTION | StatusByte::LINK_OK));
    s.exception = None;
    run(&mut m, &mut s, &mut now, ms(1005));
    assert!(m.status().status_byte().contains(StatusByte::EXCEPTION), "cycle 2 is still running");
    run(&mut m, &mut s, &mut now, ms(1500));
    assert!(!m.status().status_byte().contains(StatusByte::EXCEPTION), "cycle 2 was clean");
}

#[test]
fn rejected_write_is_reported_and_retried_next_cycle() {
    let mut m = master(config());
    let mut s = Slave { exception: Some(ExceptionCode::IllegalDataValue), ..Slave::default() };
    let mut now = ms(0);
    m.set_outputs(&[1, 0, 0, 0, 0], now);
    run(&mut m, &mut s, &mut now, ms(500));
    assert_eq!(m.status().command, CommandOutcome::Rejected(3));
    assert_eq!(m.stats().commands_rejected, 2);
    let writes = s.requests.iter().filter(|r| r[1] == 0x10).count();
    assert_eq!(writes, 1);
    s.exception = None;
    run(&mut m, &mut s, &mut now, ms(1500));
    assert_eq!(s.requests.iter().filter(|r| r[1] == 0x10).count(), 2);
    assert_eq!(m.status().command, CommandOutcome::Ok);
}

#[test]
fn timeout_retries_then_reports_and_goes_stale() {
    let mut c = config();
    c.health.stale_policy = StalePolicy::Clear;
    c.health.stale_timeout_ms = 2000;
    let mut m = master(c);
    let mut s = Slave::default();
    s.holding[1][0] = 0x1234;
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(500));
    assert_eq!(m.input_image()[0], 0x34);
    s.silent = true;
    let before = s.requests.len();
    run(&mut m, &mut s, &mut now, ms(1900));
    assert_eq!(s.requests.len() - before, 6, "two reads, 1 + 2 retries each");
    assert_eq!(m.stats().timeouts, 6);
    assert!(m.status().request_timeout);
    assert!(m.status().status_byte().contains(StatusByte::REQUEST_TIMEOUT));
    assert_eq!(m.input_image()[0], 0x34, "not stale yet");
    run(&mut m, &mut s, &mut now, ms(3000));
    assert_eq!(m.status().state, LinkState::Timeout);
    assert_eq!(m.input_image(), &[0u8; 6], "cleared by policy");
    assert_eq!(m.stats().link_timeouts, 1);
}

#[test]
fn response_timeout_counts_from_end_of_transmission() {
    let mut m = master(config());
    let req = m.poll_transmit(ms(0)).unwrap().len();
    let tx = SerialSettings::new_8e1(38400).transmit_time(req);
    assert_eq!(m.poll_at(), Some(ms(100) + tx));
}

#[test]
fn corrupted_response_is_retried_after_the_silence() {
    let mut m = master(config());
    let mut s = Slave { corrupt_next: true, ..Slave::default() };
    s.holding[1][1] = 7;
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(500));
    assert_eq!(m.stats().checksum_errors, 1);
    assert_eq!(s.requests[0], s.requests[1], "same request again");
    assert_eq!(m.input_image()[2], 7);
    assert!(!m.status().request_timeout);
}

#[test]
fn garbage_before_a_response_is_skipped() {
    let mut m = master(config());
    let mut s = Slave { garbage_first: std::vec![0x00, 0xFF, 0x01, 0x07], ..Slave::default() };
    s.holding[1][0] = 0x0102;
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(500));
    assert_eq!(&m.input_image()[..2], &[0x02, 0x01]);
    assert_eq!(m.stats().discarded_bytes, 4);
    assert_eq!(s.requests.len(), 2);
}

// Well-formed responses that do not answer the request: a framing error, and the same
// request again.
#[rstest]
#[case::read_byte_count(false, &[0x01, 0x03, 0x02, 0x00, 0x07])]
#[case::write_address(true, &[0x01, 0x10, 0x00, 0x0B, 0x00, 0x02])]
#[case::write_quantity(true, &[0x01, 0x10, 0x00, 0x0A, 0x00, 0x01])]
fn response_that_does_not_answer_is_retried(#[case] write: bool, #[case] body: &[u8]) {
    let mut m = master(config());
    if write {
        m.set_outputs(&[1, 0, 0, 0, 0], ms(0));
    }
    let request = m.poll_transmit(ms(0)).unwrap().to_vec();
    let mut response = body.to_vec();
    response.extend_from_slice(&crate::serial::checksum::crc16_modbus(body).to_le_bytes());
    m.on_bytes(&response, ms(5));
    assert_eq!((m.stats().framing_errors, m.stats().frames_received), (1, 0));
    assert_eq!(m.poll_transmit(ms(10)), Some(request.as_slice()));
}

#[test]
fn unsolicited_bytes_are_one_framing_error_per_burst() {
    let mut m = master(config());
    m.on_bytes(&[1, 2, 3], ms(0));
    m.on_bytes(&[4], ms(1));
    assert_eq!((m.stats().framing_errors, m.stats().discarded_bytes), (1, 4));
    assert!(m.status().frame_errors);
}

#[test]
fn request_waits_for_the_line_to_be_quiet() {
    let mut m = master(config());
    // Noise on the line at 10 ms: the first request waits 1750 µs (38400 baud) after it.
    m.on_bytes(&[0x55], ms(10));
    assert!(m.poll_transmit(ms(10)).is_none());
    assert_eq!(m.poll_at(), Some(ms(10) + Duration::from_micros(1750)));
    assert!(m.poll_transmit(ms(10) + Duration::from_micros(1749)).is_none());
    assert!(m.poll_transmit(ms(10) + Duration::from_micros(1750)).is_some());
}

#[test]
fn next_request_waits_the_silence_after_a_response() {
    let mut m = master(config());
    let req = m.poll_transmit(ms(0)).unwrap().to_vec();
    let mut s = Slave::default();
    let resp = s.answer(&req).unwrap();
    m.on_bytes(&resp, ms(20));
    assert_eq!(m.poll_at(), Some(ms(20) + Duration::from_micros(1750)));
    assert!(m.poll_transmit(ms(21)).is_none());
    assert!(m.poll_transmit(ms(22)).is_some());
}

#[test]
fn cycles_follow_the_poll_period() {
    let mut m = master(config());
    let mut s = Slave::default();
    let mut now = ms(0);
    run(&mut m, &mut s, &mut now, ms(3500));
    assert_eq!(m.completed_cycles(), 4, "cycles at 0, 1000, 2000, 3000 ms");
    assert_eq!(s.requests.len(), 8);
}

#[test]
fn idle_frame_once_per_entry_with_crc() {
    let mut c = config();
    c.on_idle = IdleAction::send(&[0x02, 0x05, 0x00, 0x05, 0x00, 0x00]).unwrap();
    let mut m = master(c);
    let mut s = Slave::default();
    let mut now = ms(0);
    for k in 0..10 {
        m.set_outputs(&[], now);
        run(&mut m, &mut s, &mut now, ms(k * 10));
    }
    let idle: StdVec<_> = s.requests.iter().filter(|r| r[0] == 2).collect();
    assert_eq!(idle.len(), 1);
    assert_eq!(Request::parse(idle[0]), Ok((2, Request::WriteSingleCoil { address: 5, value: false })));
}

fn config_with(f: impl FnOnce(&mut ModbusConfig)) -> ModbusConfig {
    let mut c = config();
    f(&mut c);
    c
}

#[rstest]
#[case::data_bits(config_with(|c| c.serial.data_bits = DataBits::Seven), "serial.data_bits", None)]
#[case::timeout(config_with(|c| c.response_timeout_ms = 0), "response_timeout_ms", None)]
#[case::retries(config_with(|c| c.retries = 11), "retries", None)]
#[case::period(config_with(|c| c.poll_period_ms = 3_600_001), "poll_period_ms", None)]
#[case::input_len(config_with(|c| c.input_len = 65), "input_len", None)]
#[case::empty_scan(config_with(|c| c.scan.clear()), "scan", None)]
#[case::unit_zero(config_with(|c| c.scan[0].unit = 0), "scan.unit", Some(0))]
#[case::unit_high(config_with(|c| c.scan[1].unit = 248), "scan.unit", Some(1))]
#[case::count_zero(config_with(|c| c.scan[0].count = 0), "scan.count", Some(0))]
#[case::count_too_many_registers(config_with(|c| { c.input_len = 64; c.scan[0].count = 33 }), "scan.count", Some(0))]
#[case::single_coil_count(config_with(|c| c.scan[3].count = 2), "scan.count", Some(3))]
#[case::address_wraps(config_with(|c| c.scan[0].address = 0xFFFF), "scan.address", Some(0))]
#[case::offset(config_with(|c| c.scan[1].offset = 5), "scan.offset", Some(1))]
#[case::overlap(config_with(|c| { c.input_len = 8; c.scan[1].offset = 3 }), "scan.offset", Some(1))]
#[case::idle_too_short(config_with(|c| c.on_idle = IdleAction::send(&[1]).unwrap()), "on_idle", None)]
#[case::health(config_with(|c| c.health.stale_timeout_ms = 0), "health.stale_timeout_ms", None)]
fn validate_rejects(#[case] c: ModbusConfig, #[case] field: &str, #[case] index: Option<u16>) {
    let e = c.validate().unwrap_err();
    assert_eq!((e.field.key(), e.index), (field, index), "{e}");
    assert!(ModbusMaster::new(c, ms(0)).is_err());
}

#[test]
fn overlap_names_the_other_entry() {
    let e = config_with(|c| {
        c.input_len = 8;
        c.scan[1].offset = 3;
    })
    .validate()
    .unwrap_err();
    assert_eq!(e.problem, Problem::Overlap { other: 0 });
    assert_eq!(e.to_string(), "scan[1].offset: overlaps the image bytes of entry 0");
}

#[test]
fn new_sizes_the_images() {
    let c = config();
    assert_eq!((c.input_len, c.output_len), (6, 5));
    c.validate().unwrap();
}

proptest! {
    #[test]
    fn arbitrary_input_never_panics(
        steps in proptest::collection::vec((proptest::collection::vec(any::<u8>(), 0..40), proptest::collection::vec(any::<u8>(), 0..8), 0u64..400, any::<bool>()), 0..60)
    ) {
        let mut m = master(config());
        let mut now = ms(0);
        for (bytes, outputs, dt, fault) in steps {
            now += Duration::from_millis(dt);
            m.on_bytes(&bytes, now);
            if fault { m.connection_fault(now) } else { m.set_outputs(&outputs, now) }
            let mut sent = 0;
            while let Some(req) = m.poll_transmit(now) {
                prop_assert!(Request::parse(req).is_ok());
                sent += 1;
                prop_assert!(sent < 5);
            }
            prop_assert_eq!(m.input_image().len(), 6);
        }
    }

    // `encode_entry` writes what `Request::emit` writes for the entry, and refuses what it
    // refuses.
    #[test]
    fn encode_entry_is_request_emit(
        unit in any::<u8>(),
        code in prop::sample::select(&[1u8, 2, 3, 4, 5, 6, 15, 16][..]),
        address in any::<u16>(),
        count in prop_oneof![0u16..140, 0u16..2100],
        offset in 0u16..70,
        output in any::<[u8; IMAGE_CAPACITY]>(),
        little_endian in any::<bool>(),
    ) {
        let e = entry(unit, Function::from_code(code).unwrap(), address, count, offset);
        let order = if little_endian { ByteOrder::LittleEndian } else { ByteOrder::BigEndian };
        let mut out = [0u8; ADU_CAPACITY];
        let n = encode_entry(&e, &output, order, &mut out).and_then(|n| append_crc(&mut out, n));
        let mut expected = [0u8; ADU_CAPACITY];
        let m = emitted(&e, &output, order, &mut expected);
        prop_assert_eq!(n.map(|n| &out[..n]), m.map(|m| &expected[..m]));
    }

    // A valid response split at any point is understood.
    #[test]
    fn response_in_two_chunks(split in 0usize..9) {
        let mut m = master(config());
        let req = m.poll_transmit(ms(0)).unwrap().to_vec();
        let mut s = Slave::default();
        s.holding[1][0] = 0xBEEF;
        let resp = s.answer(&req).unwrap();
        let split = split.min(resp.len());
        m.on_bytes(&resp[..split], ms(5));
        m.on_bytes(&resp[split..], ms(6));
        prop_assert_eq!(&m.input_image()[..2], &[0xEF, 0xBE]);
    }
}

mod framing;
mod units;
