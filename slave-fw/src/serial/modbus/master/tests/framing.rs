//! The master over ASCII and Modbus TCP: the same slave as the RTU tests, its requests and
//! responses converted at the line.

use super::*;
use crate::serial::checksum::crc16_modbus;
use crate::serial::line::{Parity, StopBits};
use crate::serial::modbus::{ascii, mbap};

/// `config()` with `framing` (7E1 for ASCII, as §2.5.2.1 has it).
fn framed_config(framing: Framing) -> ModbusConfig {
    let mut c = config();
    c.framing = framing;
    if framing == Framing::Ascii {
        c.serial = SerialSettings {
            baud: 9600,
            data_bits: DataBits::Seven,
            parity: Parity::Even,
            stop_bits: StopBits::One,
        };
    }
    c
}

/// The RTU ADU (CRC appended) of an address and PDU.
fn with_crc(frame: &[u8]) -> StdVec<u8> {
    let mut v = frame.to_vec();
    v.extend_from_slice(&crc16_modbus(frame).to_le_bytes());
    v
}

/// The address and PDU of an ASCII frame, checked by an independent decoder.
fn ascii_body(wire: &[u8]) -> StdVec<u8> {
    let mut d = ascii::Decoder::default();
    let mut out = Vec::new();
    let steps: StdVec<_> = wire.iter().map(|&c| d.push(c, &mut out)).collect();
    assert_eq!(steps.last(), Some(&ascii::Step::Frame), "{:?}", core::str::from_utf8(wire));
    out.to_vec()
}

/// The slave's answer to `wire`, framed as `framing`; `mangle` may change the answer's bytes.
fn answer(slave: &mut Slave, framing: Framing, wire: &[u8]) -> Option<StdVec<u8>> {
    match framing {
        Framing::Rtu => slave.answer(wire),
        Framing::Ascii => {
            assert_eq!((wire[0], &wire[wire.len() - 2..]), (b':', &b"\r\n"[..]));
            let resp = slave.answer(&with_crc(&ascii_body(wire)))?;
            let mut out = [0; ascii::FRAME_CAPACITY];
            let n = ascii::encode(&resp[..resp.len() - 2], &mut out).unwrap();
            Some(out[..n].to_vec())
        }
        Framing::Tcp => {
            let (header, pdu) = wire.split_at(mbap::HEADER_LEN);
            assert_eq!(&header[2..4], &[0, 0], "protocol identifier");
            assert_eq!(usize::from(u16::from_be_bytes([header[4], header[5]])), 1 + pdu.len());
            let mut body = StdVec::from([header[6]]);
            body.extend_from_slice(pdu);
            let resp = slave.answer(&with_crc(&body))?;
            let mut out = [0; mbap::FRAME_CAPACITY];
            let t = u16::from_be_bytes([header[0], header[1]]);
            let n = mbap::encode(t, &resp[..resp.len() - 2], &mut out).unwrap();
            Some(out[..n].to_vec())
        }
    }
}

/// `run` for any framing, with `mangle` applied to each answer.
fn run_framed(
    m: &mut ModbusMaster,
    slave: &mut Slave,
    now: &mut Instant,
    until: Instant,
    mut mangle: impl FnMut(&mut StdVec<u8>),
) -> StdVec<StdVec<u8>> {
    let framing = m.config().framing;
    let mut sent = StdVec::new();
    for _ in 0..10_000 {
        while let Some(req) = m.poll_transmit(*now) {
            let req = req.to_vec();
            sent.push(req.clone());
            if let Some(mut resp) = answer(slave, framing, &req) {
                mangle(&mut resp);
                *now += Duration::from_millis(5);
                m.on_bytes(&resp, *now);
            }
        }
        match m.poll_at() {
            Some(t) if t <= until => *now = t.max(*now + Duration::from_micros(1)),
            _ => {
                *now = (*now).max(until);
                m.poll(*now);
                return sent;
            }
        }
    }
    panic!("no progress");
}

#[rstest]
#[case::ascii(Framing::Ascii)]
#[case::tcp(Framing::Tcp)]
fn reads_and_writes_over_the_framing(#[case] framing: Framing) {
    let mut m = master(framed_config(framing));
    let mut s = Slave::default();
    s.holding[1][0] = 0x1234;
    s.coils[1][9] = true;
    let mut now = ms(0);
    m.set_outputs(&[0x11, 0x22, 0x33, 0x44, 0x01], now);
    let sent = run_framed(&mut m, &mut s, &mut now, ms(900), |_| {});
    assert_eq!(&m.input_image()[..2], &[0x34, 0x12]);
    assert_eq!(&m.input_image()[4..], &[0x00, 0x02]);
    assert_eq!(s.holding[1][10..12], [0x2211, 0x4433]);
    assert!(s.coils[2][5]);
    assert_eq!(m.stats().frames_received, 4);
    assert_eq!((m.stats().framing_errors, m.stats().checksum_errors), (0, 0));
    match framing {
        // Unit 1, write multiple registers 10..=11 first (outputs go ahead of reads).
        Framing::Ascii => assert_eq!(sent[0], b":0110000A0002042211443335\r\n"),
        // Transactions numbered from 1, one per request.
        _ => {
            let ids: StdVec<u16> = sent.iter().map(|f| u16::from_be_bytes([f[0], f[1]])).collect();
            assert_eq!(ids, [1, 2, 3, 4]);
        }
    }
}

#[test]
fn ascii_lrc_error_is_a_checksum_error_and_retried() {
    let mut m = master(framed_config(Framing::Ascii));
    let mut s = Slave::default();
    s.holding[1][0] = 7;
    let mut first = true;
    let mut now = ms(0);
    let sent = run_framed(&mut m, &mut s, &mut now, ms(900), |resp| {
        if std::mem::take(&mut first) {
            // The LRC's last digit.
            let i = resp.len() - 3;
            resp[i] = if resp[i] == b'0' { b'1' } else { b'0' };
        }
    });
    assert_eq!(m.stats().checksum_errors, 1);
    assert_eq!(sent.len(), 3, "the first read once more, then the second");
    assert_eq!(m.input_image()[0], 7);
}

#[rstest]
#[case::bad_hex(b":01G3\r\n", 1)]
#[case::missing_lf(b":0103\rX", 1)]
#[case::too_short(b":01\r\n", 1)]
#[case::noise_then_nothing(b"xyz", 0)]
fn ascii_malformed_responses_are_framing_errors(#[case] resp: &[u8], #[case] errors: u32) {
    let mut c = framed_config(Framing::Ascii);
    c.retries = 0;
    let mut m = master(c);
    let now = ms(0);
    assert!(m.poll_transmit(now).is_some());
    m.on_bytes(resp, ms(5));
    assert_eq!(m.stats().framing_errors, errors);
    if errors == 0 {
        assert_eq!(m.stats().discarded_bytes, 3);
    }
}

#[test]
fn ascii_inter_character_timeout_ends_the_frame() {
    let mut c = framed_config(Framing::Ascii);
    c.response_timeout_ms = 5000;
    let mut m = master(c);
    let first = m.poll_transmit(ms(0)).unwrap().to_vec();
    m.on_bytes(b":0103", ms(100));
    // Within one second of the last character, nothing happens.
    assert_eq!(m.poll_at(), Some(ms(100) + ascii::CHAR_TIMEOUT));
    assert!(m.poll_transmit(ms(1099)).is_none());
    assert_eq!(m.stats().framing_errors, 0);
    // Then the frame is lost, counted, and the request is repeated long before the response
    // timeout.
    let again = m.poll_transmit(ms(1100)).map(<[u8]>::to_vec);
    assert_eq!(m.stats().framing_errors, 1);
    assert_eq!(again, Some(first));
}

#[test]
fn tcp_answer_to_another_transaction_is_skipped() {
    let mut m = master(framed_config(Framing::Tcp));
    let req = m.poll_transmit(ms(0)).unwrap().to_vec();
    let mut s = Slave::default();
    s.holding[1][0] = 0x0102;
    let good = answer(&mut s, Framing::Tcp, &req).unwrap();
    let mut stale = good.clone();
    stale[1] ^= 0x55;
    m.on_bytes(&stale, ms(3));
    assert_eq!((m.stats().frames_received, m.stats().discarded_bytes), (0, stale.len() as u32));
    m.on_bytes(&good, ms(4));
    assert_eq!(m.stats().frames_received, 1);
    assert_eq!(&m.input_image()[..2], &[0x02, 0x01]);
}

#[rstest]
#[case::protocol(2, 0x01)]
#[case::length(5, 0x00)]
fn tcp_bad_header_is_a_framing_error(#[case] at: usize, #[case] value: u8) {
    let mut c = framed_config(Framing::Tcp);
    c.retries = 0;
    let mut m = master(c);
    let req = m.poll_transmit(ms(0)).unwrap().to_vec();
    let mut resp = answer(&mut Slave::default(), Framing::Tcp, &req).unwrap();
    resp[at] = value;
    m.on_bytes(&resp, ms(3));
    assert_eq!((m.stats().framing_errors, m.stats().frames_received), (1, 0));
}

#[test]
fn another_units_frame_is_dropped_and_the_answer_still_awaited() {
    let mut m = master(framed_config(Framing::Ascii));
    let req = m.poll_transmit(ms(0)).unwrap().to_vec();
    let mut other = [0; ascii::FRAME_CAPACITY];
    let n = ascii::encode(&[0x09, 0x03, 0x02, 0x00, 0x01], &mut other).unwrap();
    m.on_bytes(&other[..n], ms(2));
    let good = answer(&mut Slave::default(), Framing::Ascii, &req).unwrap();
    m.on_bytes(&good, ms(4));
    assert_eq!((m.stats().frames_received, m.stats().framing_errors), (1, 0));
}

#[rstest]
#[case::rtu(Framing::Rtu, false)]
#[case::ascii(Framing::Ascii, true)]
#[case::tcp(Framing::Tcp, false)]
fn seven_data_bits_only_for_ascii(#[case] framing: Framing, #[case] ok: bool) {
    let mut c = config();
    c.framing = framing;
    c.serial = SerialSettings {
        baud: 9600,
        data_bits: DataBits::Seven,
        parity: Parity::Even,
        stop_bits: StopBits::One,
    };
    assert_eq!(c.validate().is_ok(), ok);
    if !ok {
        assert_eq!(c.validate().unwrap_err().field, Field::SerialDataBits);
    }
}

proptest! {
    /// Any bytes while a response is awaited, in any framing: no panic, the input image keeps
    /// its length.
    #[test]
    fn arbitrary_framed_input_never_panics(
        framing in prop_oneof![Just(Framing::Ascii), Just(Framing::Tcp)],
        chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..80), 0..12),
    ) {
        let mut m = master(framed_config(framing));
        let mut now = ms(0);
        for chunk in chunks {
            let _ = m.poll_transmit(now).map(<[u8]>::to_vec);
            now += Duration::from_millis(7);
            m.on_bytes(&chunk, now);
            prop_assert_eq!(m.input_image().len(), 6);
        }
    }
}
