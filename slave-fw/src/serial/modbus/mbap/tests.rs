use super::*;
use proptest::prelude::*;
use rstest::rstest;
use std::vec::Vec as StdVec;

fn feed(d: &mut Decoder, bytes: &[u8]) -> (StdVec<Step>, StdVec<u8>) {
    let mut out = Vec::new();
    let steps = bytes.iter().map(|&b| d.push(b, &mut out)).filter(|s| *s != Step::Pending).collect();
    (steps, out.to_vec())
}

// Implementation Guide V1.0b §3.1.3: transaction 0x0001, protocol 0, length 6 (unit and a
// five-byte PDU), unit 0x11, read holding registers 108..=110.
const REQUEST: [u8; 12] = [0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x11, 0x03, 0x00, 0x6B, 0x00, 0x03];

#[test]
fn encodes_a_request() {
    let mut out = [0; FRAME_CAPACITY];
    let n = encode(1, &[0x11, 0x03, 0x00, 0x6B, 0x00, 0x03], &mut out).unwrap();
    assert_eq!(out[..n], REQUEST);
}

#[test]
fn decodes_the_expected_transaction_and_skips_others() {
    let mut d = Decoder::default();
    d.expect(1);
    assert_eq!(
        feed(&mut d, &REQUEST),
        (std::vec![Step::Frame], std::vec![0x11, 0x03, 0x00, 0x6B, 0x00, 0x03])
    );
    d.expect(2);
    assert_eq!(feed(&mut d, &REQUEST).0, [Step::Skipped(12)]);
}

#[rstest]
#[case::protocol(&[0, 1, 0, 1, 0, 6, 0x11], MbapError::Protocol(1))]
#[case::length_zero(&[0, 1, 0, 0, 0, 0, 0x11], MbapError::Length(0))]
#[case::length_one(&[0, 1, 0, 0, 0, 1, 0x11], MbapError::Length(1))]
#[case::length_long(&[0, 1, 0, 0, 0, 255, 0x11], MbapError::Length(255))]
#[case::length_huge(&[0, 1, 0, 0, 0xFF, 0xFF, 0x11], MbapError::Length(0xFFFF))]
fn malformed_headers_are_errors(#[case] bytes: &[u8], #[case] error: MbapError) {
    let mut d = Decoder::default();
    d.expect(1);
    assert_eq!(feed(&mut d, bytes).0, [Step::Error(error)]);
    // The next header starts afresh.
    assert_eq!(feed(&mut d, &REQUEST).0, [Step::Frame]);
}

#[rstest]
#[case::no_pdu(&[0x11], FRAME_CAPACITY)]
#[case::empty(&[], FRAME_CAPACITY)]
#[case::small_buffer(&[0x11, 0x03, 0x00], 8)]
fn encode_refuses(#[case] frame: &[u8], #[case] room: usize) {
    let mut out = std::vec![0u8; room];
    assert_eq!(encode(1, frame, &mut out), None);
}

#[test]
fn encode_refuses_an_over_long_pdu() {
    let mut out = [0u8; FRAME_CAPACITY + 1];
    assert_eq!(encode(1, &[1; 2 + MAX_PDU], &mut out), None);
    assert_eq!(encode(1, &[1; 1 + MAX_PDU], &mut out), Some(FRAME_CAPACITY));
}

proptest! {
    #[test]
    fn frames_round_trip(t in any::<u16>(), frame in proptest::collection::vec(any::<u8>(), 2..=1 + MAX_PDU)) {
        let mut out = [0; FRAME_CAPACITY];
        let n = encode(t, &frame, &mut out).unwrap();
        let mut d = Decoder::default();
        d.expect(t);
        prop_assert_eq!(feed(&mut d, &out[..n]), (std::vec![Step::Frame], frame));
    }

    #[test]
    fn any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..1200)) {
        let mut d = Decoder::default();
        let mut out = Vec::new();
        for b in bytes {
            d.push(b, &mut out);
            prop_assert!(out.len() <= 1 + MAX_PDU);
        }
    }
}
