use super::*;
use proptest::prelude::*;
use rstest::rstest;
use std::vec::Vec;

fn p(bytes: &[u8]) -> Payload {
    Payload::from_slice(bytes).unwrap()
}

fn ms(n: u64) -> Instant {
    Instant::from_millis(n)
}

#[rstest]
#[case::first_0(0x00, FragmentKind::First, 0)]
#[case::single(0x3F, FragmentKind::First, 63)]
#[case::middle_1(0x41, FragmentKind::Middle, 1)]
#[case::middle_63(0x7F, FragmentKind::Middle, 63)]
#[case::last_1(0x81, FragmentKind::Last, 1)]
#[case::last_2(0x82, FragmentKind::Last, 2)]
#[case::ack_0(0xC0, FragmentKind::Ack, 0)]
#[case::ack_1(0xC1, FragmentKind::Ack, 1)]
#[case::ack_single(0xFF, FragmentKind::Ack, 63)]
fn fragment_byte_codec(#[case] byte: u8, #[case] kind: FragmentKind, #[case] count: u8) {
    let fb = FragmentByte { kind, count };
    assert_eq!(FragmentByte::from_byte(byte), fb);
    assert_eq!(fb.to_byte(), byte);
    assert_eq!(FragmentByte::new(kind, count), Some(fb));
}

#[test]
fn fragment_byte_checks_and_counts() {
    assert_eq!(FragmentByte::new(FragmentKind::Middle, 64), None);
    for b in 0..=0xFFu8 {
        assert_eq!(FragmentByte::from_byte(b).to_byte(), b);
    }
    assert_eq!(next_count(0), 1);
    // Rollover target UNCONFIRMED (protocol §9.4); this crate wraps 63 -> 0 like AN.
    assert_eq!(next_count(63), 0);
    assert!(FragmentByte::from_byte(0x3F).is_single());
    assert!(!FragmentByte::from_byte(0x7F).is_single());
}

#[rstest]
#[case::success(0x00, AckStatus::Success)]
#[case::too_much_data(0x01, AckStatus::TooMuchData)]
#[case::reserved(0x02, AckStatus::Unknown(0x02))]
#[case::reserved_ff(0xFF, AckStatus::Unknown(0xFF))]
fn ack_status_codec(#[case] raw: u8, #[case] status: AckStatus) {
    assert_eq!(AckStatus::from(raw), status);
    assert_eq!(u8::from(status), raw);
}

#[rstest]
#[case::master0_count0(0x80, 0, AckStatus::Success, &[0x80, 0xC0, 0x00])]
#[case::xid_count1(0xC0, 1, AckStatus::Success, &[0xC0, 0xC1, 0x00])]
#[case::frag_bit_forced(0x0A, 2, AckStatus::TooMuchData, &[0x8A, 0xC2, 0x01])]
fn ack_frames(#[case] header: u8, #[case] count: u8, #[case] status: AckStatus, #[case] bytes: &[u8]) {
    assert_eq!(ack_frame(Header::from_byte(header), count, status), p(bytes));
    let frag = ExplicitFragment::parse(bytes).unwrap();
    assert_eq!(frag.ack_status(), Some(status));
    assert_eq!(frag.to_payload(), p(bytes));
}

#[test]
fn to_payload_forces_the_fragmentation_bit() {
    // A fragment built by hand from an unfragmented header still goes out as a fragment
    // (protocol §3.1: bit 7 of the header is the Frag bit).
    let frag = ExplicitFragment {
        header: Header::from_byte(0x0A),
        fragment: FragmentByte::from_byte(0x41),
        body: &[1, 2],
    };
    assert_eq!(frag.to_payload(), p(&[0x8A, 0x41, 1, 2]));
}

/// protocol §4.1, PICO worked exchange: master MAC 0 (header 80 both ways), slave MAC 3; the
/// master sends on 0x41C, the slave answers on 0x41B.
#[test]
fn pico_worked_exchange() {
    // The manual does not show the data bytes of the master's last fragment: `01 00` is ours.
    let request = [0x00, 0x32, 0x64, 0x01, 0x93, 0x05, 0x00, 0x01, 0x00];
    let response = [0x00, 0xB2, 0xC2, 0x05, 0x00, 0x05, 0x09, 0x0D, 0x05, 0x04];
    let mut master_tx = ExplicitTransmitter::<32>::new();
    let mut master_rx = ExplicitReassembler::<32>::new();
    let mut slave_tx = ExplicitTransmitter::<32>::new();
    let mut slave_rx = ExplicitReassembler::<32>::new();
    let t = ms(5);

    master_tx.start(&request, t).unwrap();
    assert_eq!(master_tx.poll_at(), Some(t));
    let f = master_tx.poll_transmit(t).unwrap();
    assert_eq!(f, [0x80, 0x00, 0x32, 0x64, 0x01, 0x93, 0x05, 0x00]); // 41C
    assert_eq!(master_tx.poll_transmit(t), None);
    let ack = ExplicitReceive::Ack(p(&[0x80, 0xC0, 0x00])); // 41B
    assert_eq!(slave_rx.receive(&f), ack);
    assert!(slave_rx.in_progress());
    assert_eq!(master_tx.handle_ack(&[0x80, 0xC0, 0x00], t), AckOutcome::Progress);
    let f = master_tx.poll_transmit(t).unwrap();
    assert_eq!(f, [0x80, 0x81, 0x01, 0x00]); // 41C, last fragment count 1
    assert_eq!(slave_rx.receive(&f), ExplicitReceive::Complete(p(&[0x80, 0xC1, 0x00]))); // 41B
    assert_eq!(slave_rx.message(), request);
    assert_eq!(master_tx.handle_ack(&[0x80, 0xC1, 0x00], t), AckOutcome::Done);
    assert_eq!(master_tx.poll_event(t), Some(TransmitEvent::Completed));
    assert_eq!(master_tx.poll_event(t), None);
    assert_eq!(master_tx.poll_at(), None);

    slave_tx.start(&response, t).unwrap();
    let f = slave_tx.poll_transmit(t).unwrap();
    assert_eq!(f, [0x80, 0x00, 0xB2, 0xC2, 0x05, 0x00, 0x05, 0x09]); // 41B
    assert_eq!(master_rx.receive(&f), ExplicitReceive::Ack(p(&[0x80, 0xC0, 0x00]))); // 41C
    assert_eq!(slave_tx.handle_ack(&[0x80, 0xC0, 0x00], t), AckOutcome::Progress);
    let f = slave_tx.poll_transmit(t).unwrap();
    assert_eq!(f, [0x80, 0x81, 0x0D, 0x05, 0x04]); // 41B
    assert_eq!(master_rx.receive(&f), ExplicitReceive::Complete(p(&[0x80, 0xC1, 0x00]))); // 41C
    assert_eq!(master_rx.message(), response);
    assert_eq!(slave_tx.handle_ack(&[0x80, 0xC1, 0x00], t), AckOutcome::Done);
    assert_eq!(slave_tx.poll_event(t), Some(TransmitEvent::Completed));
    assert!(!slave_tx.is_active());
}

const MSG_20: [u8; 20] = [0x40, 0x8E, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18];

#[test]
fn ack_timeout_resends_once_then_aborts() {
    let mut tx = ExplicitTransmitter::<32>::new();
    tx.start(&MSG_20, ms(0)).unwrap();
    let first = tx.poll_transmit(ms(0)).unwrap();
    assert_eq!(first, [0xC0, 0x00, 0x8E, 1, 2, 3, 4, 5]);
    assert_eq!(tx.poll_at(), Some(ms(1000)));
    assert_eq!(tx.poll_transmit(ms(999)), None);
    assert_eq!(tx.poll_event(ms(999)), None);
    assert_eq!(tx.poll_transmit(ms(1000)), Some(first.clone()));
    assert_eq!(tx.poll_transmit(ms(1000)), None);
    assert_eq!(tx.poll_at(), Some(ms(2000)));
    assert_eq!(tx.poll_transmit(ms(1999)), None);
    assert_eq!(tx.poll_transmit(ms(2000)), None);
    assert_eq!(tx.poll_event(ms(2000)), Some(TransmitEvent::Aborted(AbortReason::AckTimeout)));
    assert!(!tx.is_active());
    assert_eq!(tx.poll_at(), None);
    assert_eq!(tx.handle_ack(&[0xC0, 0xC0, 0x00], ms(2001)), AckOutcome::Ignored);
}

#[test]
fn each_fragment_gets_its_own_retry() {
    let mut tx = ExplicitTransmitter::<32>::new();
    tx.start(&MSG_20, ms(0)).unwrap();
    tx.poll_transmit(ms(0)).unwrap();
    assert!(tx.poll_transmit(ms(1000)).is_some()); // re-send of the first fragment
    assert_eq!(tx.handle_ack(&[0xC0, 0xC0, 0x00], ms(1500)), AckOutcome::Progress);
    assert_eq!(tx.poll_at(), Some(ms(1500)));
    let second = tx.poll_transmit(ms(1500)).unwrap();
    assert_eq!(second, [0xC0, 0x41, 6, 7, 8, 9, 10, 11]);
    assert_eq!(tx.poll_transmit(ms(2500)), Some(second));
    assert_eq!(tx.handle_ack(&[0xC0, 0xC1, 0x00], ms(3000)), AckOutcome::Progress);
    assert_eq!(tx.poll_transmit(ms(3000)).unwrap(), [0xC0, 0x42, 12, 13, 14, 15, 16, 17]);
    assert_eq!(tx.handle_ack(&[0xC0, 0xC2, 0x00], ms(3000)), AckOutcome::Progress);
    assert_eq!(tx.poll_transmit(ms(3000)).unwrap(), [0xC0, 0x83, 18]);
    assert_eq!(tx.handle_ack(&[0xC0, 0xC3, 0x00], ms(3001)), AckOutcome::Done);
    assert_eq!(tx.poll_event(ms(3001)), Some(TransmitEvent::Completed));
}

#[test]
fn a_header_with_the_fragmentation_bit_set_keeps_it_in_every_fragment() {
    // `start` expects the bit clear; given it set, the frames still read `[header | 0x80, ..]`.
    let mut message = MSG_20;
    message[0] = 0xC0;
    let mut tx = ExplicitTransmitter::<32>::new();
    tx.start(&message, ms(0)).unwrap();
    assert_eq!(tx.poll_transmit(ms(0)).unwrap(), [0xC0, 0x00, 0x8E, 1, 2, 3, 4, 5]);
    assert_eq!(tx.handle_ack(&[0xC0, 0xC0, 0x00], ms(0)), AckOutcome::Progress);
    assert_eq!(tx.poll_transmit(ms(0)).unwrap(), [0xC0, 0x41, 6, 7, 8, 9, 10, 11]);
}

#[rstest]
#[case::too_much_data(0x01, AckStatus::TooMuchData)]
#[case::reserved(0x07, AckStatus::Unknown(0x07))]
fn ack_with_error_status_aborts(#[case] raw: u8, #[case] status: AckStatus) {
    let mut tx = ExplicitTransmitter::<32>::new();
    tx.start(&MSG_20, ms(0)).unwrap();
    tx.poll_transmit(ms(0)).unwrap();
    assert_eq!(tx.handle_ack(&[0xC0, 0xC0, raw], ms(10)), AckOutcome::Aborted(status));
    assert!(!tx.is_active());
    assert_eq!(tx.poll_transmit(ms(10)), None);
    assert_eq!(tx.poll_event(ms(10)), Some(TransmitEvent::Aborted(AbortReason::Rejected(status))));
    assert_eq!(tx.poll_event(ms(10)), None);
}

#[rstest]
#[case::wrong_count(&[0xC0, 0xC1, 0x00])]
#[case::not_ack_type(&[0xC0, 0x40, 0x00])]
#[case::no_status(&[0xC0, 0xC0])]
#[case::unfragmented(&[0x40, 0xC0, 0x00])]
#[case::empty(&[])]
#[case::too_long(&[0xC0, 0xC0, 0, 0, 0, 0, 0, 0, 0])]
fn unrelated_acks_are_ignored(#[case] frame: &[u8]) {
    let mut tx = ExplicitTransmitter::<32>::new();
    assert_eq!(tx.handle_ack(&[0xC0, 0xC0, 0x00], ms(0)), AckOutcome::Ignored); // idle
    tx.start(&MSG_20, ms(0)).unwrap();
    assert_eq!(tx.handle_ack(&[0xC0, 0xC0, 0x00], ms(0)), AckOutcome::Ignored); // not sent yet
    tx.poll_transmit(ms(0)).unwrap();
    assert_eq!(tx.handle_ack(frame, ms(1)), AckOutcome::Ignored);
    assert!(tx.is_active());
}

#[rstest]
#[case::fits_in_one_frame(&[0x00, 0x0E, 1, 1, 1, 0, 0, 0], FragmentError::FitsInOneFrame(8))]
#[case::empty(&[], FragmentError::FitsInOneFrame(0))]
#[case::too_long(&[0; 33], FragmentError::MessageTooLong { len: 33, max: 32 })]
fn start_errors(#[case] message: &[u8], #[case] err: FragmentError) {
    let mut tx = ExplicitTransmitter::<32>::new();
    assert_eq!(tx.start(message, ms(0)), Err(err));
    assert!(!tx.is_active());
}

#[test]
fn one_transfer_at_a_time() {
    let mut tx = ExplicitTransmitter::<32>::new();
    tx.start(&MSG_20, ms(0)).unwrap();
    assert_eq!(tx.start(&MSG_20, ms(0)), Err(FragmentError::Busy));
    tx.reset();
    assert_eq!(tx.poll_at(), None);
    assert_eq!(tx.start(&MSG_20, ms(0)), Ok(()));
}

#[test]
fn duplicate_fragment_is_reacked_not_appended() {
    let mut rx = ExplicitReassembler::<32>::new();
    let first = [0x80, 0x00, 0x8E, 1, 2, 3, 4, 5];
    let middle = [0x80, 0x41, 6, 7, 8, 9, 10, 11];
    let last = [0x80, 0x82, 12];
    assert_eq!(rx.receive(&first), ExplicitReceive::Ack(p(&[0x80, 0xC0, 0x00])));
    assert_eq!(rx.receive(&middle), ExplicitReceive::Ack(p(&[0x80, 0xC1, 0x00])));
    assert_eq!(rx.receive(&middle), ExplicitReceive::Duplicate(p(&[0x80, 0xC1, 0x00])));
    assert!(rx.in_progress());
    assert_eq!(rx.receive(&last), ExplicitReceive::Complete(p(&[0x80, 0xC2, 0x00])));
    assert_eq!(rx.message(), [0x00, 0x8E, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
    // The last ack was lost and the sender repeats the last fragment.
    assert_eq!(rx.receive(&last), ExplicitReceive::Duplicate(p(&[0x80, 0xC2, 0x00])));
    assert_eq!(rx.message(), [0x00, 0x8E, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12]);
}

#[test]
fn repeated_first_fragment_restarts() {
    let mut rx = ExplicitReassembler::<32>::new();
    let first = [0x80, 0x00, 0x8E, 1, 2, 3, 4, 5];
    assert_eq!(rx.receive(&first), ExplicitReceive::Ack(p(&[0x80, 0xC0, 0x00])));
    assert_eq!(rx.receive(&first), ExplicitReceive::Ack(p(&[0x80, 0xC0, 0x00])));
    assert_eq!(rx.receive(&[0x80, 0x81, 6]), ExplicitReceive::Complete(p(&[0x80, 0xC1, 0x00])));
    assert_eq!(rx.message(), [0x00, 0x8E, 1, 2, 3, 4, 5, 6]);
}

#[test]
fn out_of_sequence_resets() {
    let mut rx = ExplicitReassembler::<32>::new();
    assert_eq!(rx.receive(&[0x80, 0x00, 0x8E, 1, 2, 3, 4, 5]), ExplicitReceive::Ack(p(&[0x80, 0xC0, 0x00])));
    assert_eq!(
        rx.receive(&[0x80, 0x42, 6, 7]),
        ExplicitReceive::Ignored(FragmentError::OutOfSequence { expected: 1, got: 2 })
    );
    assert!(!rx.in_progress());
    assert_eq!(rx.receive(&[0x80, 0x81, 6]), ExplicitReceive::Ignored(FragmentError::NoFirstFragment));
    assert!(rx.message().is_empty());
}

#[test]
fn too_much_data_is_rejected() {
    let mut rx = ExplicitReassembler::<12>::new();
    assert_eq!(rx.receive(&[0x80, 0x00, 0x8E, 1, 2, 3, 4, 5]), ExplicitReceive::Ack(p(&[0x80, 0xC0, 0x00])));
    let middle = [0x80, 0x41, 6, 7, 8, 9, 10, 11];
    assert_eq!(rx.receive(&middle), ExplicitReceive::Rejected(p(&[0x80, 0xC1, 0x01])));
    assert!(!rx.in_progress());
    assert_eq!(rx.receive(&middle), ExplicitReceive::Duplicate(p(&[0x80, 0xC1, 0x01])));
    assert_eq!(rx.receive(&[0x80, 0x82, 12]), ExplicitReceive::Ignored(FragmentError::NoFirstFragment));
    // A first fragment alone too large for the buffer.
    let mut tiny = ExplicitReassembler::<4>::new();
    assert_eq!(tiny.receive(&[0x80, 0x00, 0x8E, 1, 2, 3]), ExplicitReceive::Rejected(p(&[0x80, 0xC0, 0x01])));
    assert!(tiny.message().is_empty());
}

#[test]
fn rejection_aborts_the_sender() {
    let mut tx = ExplicitTransmitter::<32>::new();
    let mut rx = ExplicitReassembler::<12>::new();
    tx.start(&MSG_20, ms(0)).unwrap();
    let ExplicitReceive::Ack(ack) = rx.receive(&tx.poll_transmit(ms(0)).unwrap()) else { panic!() };
    assert_eq!(tx.handle_ack(&ack, ms(0)), AckOutcome::Progress);
    let ExplicitReceive::Rejected(ack) = rx.receive(&tx.poll_transmit(ms(0)).unwrap()) else { panic!() };
    assert_eq!(tx.handle_ack(&ack, ms(0)), AckOutcome::Aborted(AckStatus::TooMuchData));
}

#[rstest]
#[case::middle_without_first(&[0x80, 0x41, 1], FragmentError::NoFirstFragment)]
#[case::last_without_first(&[0x80, 0x81, 1], FragmentError::NoFirstFragment)]
#[case::first_count_1(&[0x80, 0x01, 1], FragmentError::FirstCountNotZero(1))]
#[case::ack_type(&[0x80, 0xC0, 0x00], FragmentError::UnexpectedAck)]
#[case::header_only(&[0x80], FragmentError::FrameTooShort(1))]
#[case::empty(&[], FragmentError::FrameTooShort(0))]
#[case::not_fragmented(&[0x00, 0x0E, 1, 1, 1], FragmentError::NotFragmented)]
#[case::nine_bytes(&[0x80, 0x00, 1, 2, 3, 4, 5, 6, 7], FragmentError::FrameTooLong(9))]
fn explicit_fragments_ignored(#[case] frame: &[u8], #[case] err: FragmentError) {
    let mut rx = ExplicitReassembler::<32>::new();
    assert_eq!(rx.receive(frame), ExplicitReceive::Ignored(err));
    assert!(!rx.in_progress());
}

#[test]
fn first_fragment_with_bad_count_resets_series() {
    let mut rx = ExplicitReassembler::<32>::new();
    rx.receive(&[0x80, 0x00, 0x8E, 1, 2, 3, 4, 5]);
    assert_eq!(rx.receive(&[0x80, 0x05, 1]), ExplicitReceive::Ignored(FragmentError::FirstCountNotZero(5)));
    assert!(!rx.in_progress());
}

#[test]
fn single_frame_first_fragment_is_whole_message() {
    let mut rx = ExplicitReassembler::<32>::new();
    assert_eq!(
        rx.receive(&[0xC3, 0x3F, 0x8E, 0x34, 0x12]),
        ExplicitReceive::Complete(p(&[0xC3, 0xFF, 0x00]))
    );
    assert_eq!(rx.message(), [0x43, 0x8E, 0x34, 0x12]);
    assert!(!rx.in_progress());
}

#[test]
fn counts_wrap_63_to_0() {
    // 1 header + 400 body bytes: 67 fragments, counts 0..=63 then 0, 1, 2.
    let mut message = [0u8; 401];
    for (i, b) in message.iter_mut().enumerate() {
        *b = i as u8;
    }
    let (frames, event, rx) = transfer::<512>(&message);
    assert_eq!(event, TransmitEvent::Completed);
    assert_eq!(frames.len(), 67);
    assert_eq!(frames[63][1], 0x7F);
    assert_eq!(frames[64][1], 0x40);
    assert_eq!(frames[66][1], 0x82);
    assert_eq!(rx.message(), message);
}

/// Runs one transfer over a lossless bus on a frozen clock; returns the fragment frames sent.
fn transfer<const N: usize>(message: &[u8]) -> (Vec<Payload>, TransmitEvent, ExplicitReassembler<N>) {
    let mut tx = ExplicitTransmitter::<N>::new();
    let mut rx = ExplicitReassembler::<N>::new();
    let now = ms(0);
    tx.start(message, now).unwrap();
    let mut frames = Vec::new();
    loop {
        while let Some(f) = tx.poll_transmit(now) {
            frames.push(f.clone());
            match rx.receive(&f) {
                ExplicitReceive::Ack(a) => assert_eq!(tx.handle_ack(&a, now), AckOutcome::Progress),
                ExplicitReceive::Complete(a) => assert_eq!(tx.handle_ack(&a, now), AckOutcome::Done),
                other => panic!("unexpected {other:?}"),
            }
        }
        if let Some(event) = tx.poll_event(now) {
            return (frames, event, rx);
        }
    }
}

#[rstest]
#[case::poll_response_18(
    &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17],
    &[&[0x00, 0, 1, 2, 3, 4, 5, 6][..], &[0x41, 7, 8, 9, 10, 11, 12, 13][..], &[0x82, 14, 15, 16, 17][..]]
)]
#[case::icp_10(
    &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10],
    &[&[0x00, 1, 2, 3, 4, 5, 6, 7][..], &[0x81, 8, 9, 10][..]]
)]
#[case::eight(&[1, 2, 3, 4, 5, 6, 7, 8], &[&[0x00, 1, 2, 3, 4, 5, 6, 7][..], &[0x81, 8][..]])]
#[case::fourteen(
    &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14],
    &[&[0x00, 1, 2, 3, 4, 5, 6, 7][..], &[0x81, 8, 9, 10, 11, 12, 13, 14][..]]
)]
#[case::single_seven(&[1, 2, 3, 4, 5, 6, 7], &[&[0x3F, 1, 2, 3, 4, 5, 6, 7][..]])]
#[case::single_two(&[0xAA, 0xBB], &[&[0x3F, 0xAA, 0xBB][..]])]
#[case::empty(&[], &[&[0x3F][..]])]
fn io_fragmentation(#[case] data: &[u8], #[case] frames: &[&[u8]]) {
    let made: Vec<Payload> = io_fragments(data).collect();
    assert_eq!(made.len(), frames.len());
    assert_eq!(io_fragments(data).len(), frames.len());
    assert_eq!(io_fragment_count(data.len()), frames.len());
    for (m, f) in made.iter().zip(frames) {
        assert_eq!(m, *f);
    }
    let mut rx = IoReassembler::<32>::new();
    let (last, init) = frames.split_last().unwrap();
    for f in init {
        assert_eq!(rx.receive(f), Ok(None));
        assert!(rx.in_progress());
    }
    assert_eq!(rx.receive(last), Ok(Some(data)));
    assert!(!rx.in_progress());
}

#[test]
fn io_fragments_report_the_frames_still_to_come() {
    // 18 bytes: three frames (protocol §2, frames 25–27); the exact size shrinks by one per frame.
    let data: Vec<u8> = (0..18).collect();
    let mut frames = io_fragments(&data);
    for left in (0..=3).rev() {
        assert_eq!(frames.len(), left);
        assert_eq!(frames.size_hint(), (left, Some(left)));
        assert_eq!(frames.next().is_some(), left > 0);
    }
}

#[test]
fn io_out_of_sequence_discards_series() {
    let mut rx = IoReassembler::<32>::new();
    assert_eq!(rx.receive(&[0x00, 0, 1, 2, 3, 4, 5, 6]), Ok(None));
    assert_eq!(
        rx.receive(&[0x82, 14, 15, 16, 17]),
        Err(FragmentError::OutOfSequence { expected: 1, got: 2 })
    );
    assert!(!rx.in_progress());
    assert_eq!(rx.receive(&[0x41, 7, 8, 9, 10, 11, 12, 13]), Err(FragmentError::NoFirstFragment));
    // A duplicated middle fragment also loses the series.
    assert_eq!(rx.receive(&[0x00, 0, 1, 2, 3, 4, 5, 6]), Ok(None));
    assert_eq!(rx.receive(&[0x41, 7, 8, 9, 10, 11, 12, 13]), Ok(None));
    assert_eq!(
        rx.receive(&[0x41, 7, 8, 9, 10, 11, 12, 13]),
        Err(FragmentError::OutOfSequence { expected: 2, got: 1 })
    );
}

#[test]
fn io_first_fragment_restarts_series() {
    let mut rx = IoReassembler::<32>::new();
    assert_eq!(rx.receive(&[0x00, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE]), Ok(None));
    assert_eq!(rx.receive(&[0x41, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE, 0xEE]), Ok(None));
    assert_eq!(rx.receive(&[0x00, 1, 2, 3, 4, 5, 6, 7]), Ok(None));
    assert_eq!(rx.receive(&[0x81, 8, 9, 10]), Ok(Some(&[1, 2, 3, 4, 5, 6, 7, 8, 9, 10][..])));
}

#[test]
fn io_overflow_discards_series() {
    let mut rx = IoReassembler::<10>::new();
    assert_eq!(rx.receive(&[0x00, 0, 1, 2, 3, 4, 5, 6]), Ok(None));
    assert_eq!(rx.receive(&[0x41, 7, 8, 9, 10, 11, 12, 13]), Err(FragmentError::Overflow { max: 10 }));
    assert!(!rx.in_progress());
    let mut tiny = IoReassembler::<4>::new();
    assert_eq!(tiny.receive(&[0x3F, 1, 2, 3, 4, 5]), Err(FragmentError::Overflow { max: 4 }));
    assert_eq!(tiny.receive(&[0x00, 1, 2, 3, 4, 5]), Err(FragmentError::Overflow { max: 4 }));
    assert_eq!(tiny.receive(&[0x3F, 1, 2, 3, 4]), Ok(Some(&[1, 2, 3, 4][..])));
}

#[rstest]
#[case::ack_type(&[0xC0, 1, 2], FragmentError::UnexpectedAck)]
#[case::ack_type_mid_series(&[0xC1], FragmentError::UnexpectedAck)]
#[case::first_count_nonzero(&[0x02, 1, 2], FragmentError::FirstCountNotZero(2))]
#[case::empty(&[], FragmentError::FrameTooShort(0))]
#[case::nine_bytes(&[0x41, 1, 2, 3, 4, 5, 6, 7, 8], FragmentError::FrameTooLong(9))]
fn io_fragments_rejected(#[case] frame: &[u8], #[case] err: FragmentError) {
    let mut rx = IoReassembler::<32>::new();
    assert_eq!(rx.receive(&[0x00, 0, 1, 2, 3, 4, 5, 6]), Ok(None));
    assert_eq!(rx.receive(frame), Err(err));
    assert!(!rx.in_progress());
}

#[test]
fn errors_display() {
    assert_eq!(
        std::format!("{}", FragmentError::OutOfSequence { expected: 1, got: 2 }),
        "fragment count 2 out of sequence, expected 1"
    );
    assert_eq!(std::format!("{}", FragmentByte::from_byte(0x82)), "last #2");
    assert_eq!(std::format!("{}", AckStatus::TooMuchData), "too much data (0x01)");
}

proptest! {
    #[test]
    fn random_frames_never_panic(
        frames in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..=10), 0..48),
        small in proptest::collection::vec((0u8..4, 0u8..4, proptest::collection::vec(any::<u8>(), 0..=7)), 0..48),
    ) {
        let mut explicit = ExplicitReassembler::<20>::new();
        let mut io = IoReassembler::<20>::new();
        let mut tx = ExplicitTransmitter::<20>::new();
        tx.start(&[0u8; 20], ms(0)).unwrap();
        // Structured frames (few types and counts) reach the deeper states more often.
        let structured = small.iter().map(|(kind, count, body)| {
            let mut f = Vec::from([0x80, kind << 6 | count]);
            f.extend_from_slice(body);
            f
        });
        for (i, f) in frames.iter().cloned().chain(structured).enumerate() {
            let now = ms(i as u64 * 300);
            match explicit.receive(&f) {
                ExplicitReceive::Ack(a) | ExplicitReceive::Complete(a)
                | ExplicitReceive::Rejected(a) | ExplicitReceive::Duplicate(a) => prop_assert_eq!(a.len(), 3),
                ExplicitReceive::Ignored(_) => {}
            }
            prop_assert!(explicit.message().len() <= 20);
            if let Ok(Some(data)) = io.receive(&f) {
                prop_assert!(data.len() <= 20);
            }
            if let Ok(Some(data)) = io.receive(f.get(1..).unwrap_or(&[])) {
                prop_assert!(data.len() <= 20);
            }
            let _ = tx.poll_transmit(now);
            let _ = tx.handle_ack(&f, now);
            let _ = tx.poll_event(now);
        }
    }

    #[test]
    fn explicit_messages_round_trip(message in proptest::collection::vec(any::<u8>(), 9..=512)) {
        let mut message = message;
        message[0] &= 0x7F;
        let (frames, event, rx) = transfer::<512>(&message);
        prop_assert_eq!(event, TransmitEvent::Completed);
        prop_assert_eq!(frames.len(), (message.len() - 1).div_ceil(EXPLICIT_FRAGMENT_BODY));
        prop_assert_eq!(rx.message(), &message[..]);
    }

    #[test]
    fn explicit_round_trip_survives_single_losses(
        message in proptest::collection::vec(any::<u8>(), 9..=64),
        losses in proptest::collection::vec((any::<bool>(), any::<bool>()), 1..32),
    ) {
        // An exchange (one fragment frame and its ack) loses the fragment or the ack when its
        // loss flag is set, but never two exchanges in a row, so the one re-send gets through.
        let mut message = message;
        message[0] &= 0x7F;
        let mut tx = ExplicitTransmitter::<64>::new();
        let mut rx = ExplicitReassembler::<64>::new();
        let mut now = ms(0);
        let mut flags = losses.iter().cycle();
        let mut lost_previous = false;
        tx.start(&message, now).unwrap();
        let event = loop {
            while let Some(f) = tx.poll_transmit(now) {
                let (lossy, fragment_lost) = flags.next().copied().unwrap_or_default();
                let lost = lossy && !lost_previous;
                lost_previous = lost;
                if lost && fragment_lost {
                    continue;
                }
                let ack = match rx.receive(&f) {
                    ExplicitReceive::Ack(a) | ExplicitReceive::Complete(a) | ExplicitReceive::Duplicate(a) => a,
                    other => return Err(TestCaseError::fail(std::format!("unexpected {other:?}"))),
                };
                if !lost {
                    tx.handle_ack(&ack, now);
                }
            }
            if let Some(event) = tx.poll_event(now) {
                break event;
            }
            now = tx.poll_at().unwrap();
        };
        prop_assert_eq!(event, TransmitEvent::Completed);
        prop_assert_eq!(rx.message(), &message[..]);
    }

    #[test]
    fn io_messages_round_trip(data in proptest::collection::vec(any::<u8>(), 0..=600)) {
        let mut rx = IoReassembler::<600>::new();
        let frames: Vec<Payload> = io_fragments(&data).collect();
        prop_assert_eq!(frames.len(), io_fragment_count(data.len()));
        let (last, init) = frames.split_last().unwrap();
        for f in init {
            prop_assert_eq!(rx.receive(f), Ok(None));
        }
        prop_assert_eq!(rx.receive(last), Ok(Some(&data[..])));
    }
}
