use super::*;
use proptest::prelude::*;
use rstest::rstest;
use std::vec::Vec as StdVec;

/// Feeds `chars` and returns every step that was not `Pending`, and the buffer.
fn feed(chars: &[u8]) -> (StdVec<Step>, StdVec<u8>) {
    let mut d = Decoder::default();
    let mut out = Vec::new();
    let steps = chars.iter().map(|&c| d.push(c, &mut out)).filter(|s| *s != Step::Pending).collect();
    (steps, out.to_vec())
}

// The request of the Modicon guide's example (PI-MBUS-300): unit 17, read holding registers
// 108..=110; its LRC is 0x7E (0x11 + 0x03 + 0x6B + 0x03 = 0x82, negated).
#[rstest]
#[case::modicon_read(&[0x11, 0x03, 0x00, 0x6B, 0x00, 0x03], 0x7E)]
#[case::empty_sum(&[0x00, 0x00], 0x00)]
#[case::wraps(&[0xFF, 0x01], 0x00)]
#[case::one(&[0x01], 0xFF)]
#[case::none(&[], 0x00)]
#[case::write_coil(&[0x01, 0x05, 0x00, 0xAC, 0xFF, 0x00], 0x4F)]
fn lrc_vectors(#[case] bytes: &[u8], #[case] expected: u8) {
    assert_eq!(lrc(bytes), expected);
}

#[test]
fn encodes_the_modicon_example() {
    let mut out = [0; FRAME_CAPACITY];
    let n = encode(&[0x11, 0x03, 0x00, 0x6B, 0x00, 0x03], &mut out).unwrap();
    assert_eq!(&out[..n], b":1103006B00037E\r\n");
}

#[test]
fn decodes_the_modicon_example() {
    let (steps, out) = feed(b":1103006B00037E\r\n");
    assert_eq!(steps, [Step::Frame]);
    assert_eq!(out, [0x11, 0x03, 0x00, 0x6B, 0x00, 0x03]);
    // Lower-case digits too, and noise before the frame is skipped.
    let (steps, out) = feed(b"xy:1103006b00037e\r\n");
    assert_eq!(steps, [Step::Skipped, Step::Skipped, Step::Frame]);
    assert_eq!(out, [0x11, 0x03, 0x00, 0x6B, 0x00, 0x03]);
}

#[rstest]
#[case::lrc(b":1103006B00037F\r\n", AsciiError::Lrc { expected: 0x7E, found: 0x7F })]
#[case::bad_hex(b":11G3\r\n", AsciiError::BadHex(b'G'))]
#[case::space(b":11 03\r\n", AsciiError::BadHex(b' '))]
#[case::odd(b":110\r\n", AsciiError::OddLength)]
#[case::short(b":01FF\r\n", AsciiError::TooShort)]
#[case::empty(b":\r\n", AsciiError::TooShort)]
#[case::no_lf(b":1103006B00037E\r\r", AsciiError::MissingLf(b'\r'))]
#[case::lf_only(b":1103006B00037E\n", AsciiError::BadHex(b'\n'))]
fn malformed_frames_are_errors(#[case] chars: &[u8], #[case] error: AsciiError) {
    let (steps, _) = feed(chars);
    // The error, then the rest of the frame skipped.
    assert_eq!(steps.first(), Some(&Step::Error(error)));
    assert!(steps[1..].iter().all(|s| *s == Step::Skipped), "{steps:?}");
}

#[test]
fn a_colon_restarts_the_frame() {
    let (steps, out) = feed(b":1103:1103006B00037E\r\n");
    assert_eq!(steps, [Step::Error(AsciiError::Interrupted), Step::Frame]);
    assert_eq!(out, [0x11, 0x03, 0x00, 0x6B, 0x00, 0x03]);
}

#[test]
fn too_long_is_an_error_and_the_next_frame_decodes() {
    let mut chars = b":".to_vec();
    chars.extend(std::iter::repeat_n(b'0', 2 * MAX_DECODED + 2));
    let (steps, _) = feed(&chars);
    assert_eq!(steps, [Step::Error(AsciiError::TooLong)]);
    // The longest frame is accepted: the address, a 253-byte PDU and the LRC.
    let frame = [0x01; MAX_DECODED - 1];
    let mut out = [0; FRAME_CAPACITY];
    let n = encode(&frame, &mut out).unwrap();
    assert_eq!(n, FRAME_CAPACITY);
    let (steps, decoded) = feed(&out[..n]);
    assert_eq!((steps, decoded), (std::vec![Step::Frame], frame.to_vec()));
}

#[rstest]
#[case::empty(0, FRAME_CAPACITY)]
#[case::address_only(1, FRAME_CAPACITY)]
#[case::over_long(MAX_DECODED, FRAME_CAPACITY + 2)]
#[case::small_buffer(6, 16)]
fn encode_refuses(#[case] len: usize, #[case] room: usize) {
    let frame = std::vec![0u8; len];
    let mut out = std::vec![0u8; room];
    assert_eq!(encode(&frame, &mut out), None);
}

proptest! {
    #[test]
    fn frames_round_trip(frame in proptest::collection::vec(any::<u8>(), 2..MAX_DECODED)) {
        let mut out = [0; FRAME_CAPACITY];
        let n = encode(&frame, &mut out).unwrap();
        let (steps, decoded) = feed(&out[..n]);
        prop_assert_eq!(steps, std::vec![Step::Frame]);
        prop_assert_eq!(decoded, frame);
    }

    /// Any characters: no panic, the buffer stays within its bound, and a frame reported is one
    /// whose LRC checks.
    #[test]
    fn any_characters(chars in proptest::collection::vec(any::<u8>(), 0..1200)) {
        let mut d = Decoder::default();
        let mut out = Vec::new();
        for c in chars {
            let step = d.push(c, &mut out);
            prop_assert!(out.len() <= MAX_DECODED);
            if step == Step::Frame {
                prop_assert!(out.len() >= 2);
            }
        }
    }

    /// A single corrupted character of a valid frame is never taken for a frame with other
    /// contents.
    #[test]
    fn one_corrupted_character_is_caught(
        frame in proptest::collection::vec(any::<u8>(), 2..40),
        at in any::<prop::sample::Index>(),
        to in any::<u8>(),
    ) {
        let mut out = [0; FRAME_CAPACITY];
        let n = encode(&frame, &mut out).unwrap();
        let i = at.index(n);
        prop_assume!(out[i] != to && !(out[i].is_ascii_hexdigit() && to.is_ascii_hexdigit()
            && out[i].eq_ignore_ascii_case(&to)));
        out[i] = to;
        let (steps, decoded) = feed(&out[..n]);
        prop_assert!(!steps.contains(&Step::Frame) || decoded == frame);
    }
}
