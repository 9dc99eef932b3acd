//! The engine driven by hand-built frames: the requests it sends byte for byte, and what it makes
//! of right answers, wrong answers, error responses, time-outs and fragmented answers.

use super::*;
use crate::session::Verdict;
use rstest::rstest;

const T: Duration = Duration::from_secs(1);

fn mac(n: u8) -> MacId {
    MacId::from_low_bits(n)
}

fn node() -> BringUp {
    BringUp::new(mac(5), mac(0), T)
}

fn at(ms: u64) -> Instant {
    Instant::ZERO + Duration::from_millis(ms)
}

/// A frame from the device at MAC 5 on its explicit response identifier (0x42B).
fn answer(data: &[u8]) -> CanFrame {
    CanFrame::new(devicenet::Identifier::group2(mac(5), devicenet::Group2Message::ExplicitResponse), data)
        .unwrap()
}

/// Every frame the engine has to send, as (identifier, data).
fn sent(node: &mut BringUp) -> Vec<(u16, Vec<u8>)> {
    std::iter::from_fn(|| node.poll_transmit()).map(|f| (f.id().as_raw(), f.data().to_vec())).collect()
}

fn events(node: &mut BringUp) -> Vec<Event> {
    std::iter::from_fn(|| node.poll_event()).collect()
}

fn answered(step: Step, data: &[u8]) -> Event {
    Event::Answered { step, body: ReplyBody::Success(data.to_vec()) }
}

const EXPLICIT_POLL: AllocationChoice = AllocationChoice::EXPLICIT.union(AllocationChoice::POLL);

#[test]
fn into_io_sends_the_frames_of_the_reference_bring_up() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, EXPLICIT_POLL);
    n.get(at(0), class::CONNECTION, 2, 7, Refusal::Stop);
    n.expected_packet_rate(at(0), 2, 100);
    // One request at a time: the Get waits for the Allocate's answer.
    assert_eq!(sent(&mut n), vec![(0x42E, vec![0x00, 0x4B, 0x03, 0x01, 0x03, 0x00])]);
    assert_eq!(n.handle_frame(&answer(&[0x00, 0xCB, 0x00]), at(2)), Handled::Frame(n_ok()));
    assert_eq!(n.held(), EXPLICIT_POLL);
    assert_eq!(sent(&mut n), vec![(0x42C, vec![0x00, 0x0E, 0x05, 0x02, 0x07])]);
    assert!(matches!(n.handle_frame(&answer(&[0x00, 0x8E, 0x12, 0x00]), at(4)), Handled::Frame(_)));
    assert_eq!(sent(&mut n), vec![(0x42C, vec![0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00])]);
    assert!(!n.is_idle());
    assert!(matches!(n.handle_frame(&answer(&[0x00, 0x90, 0x64, 0x00]), at(6)), Handled::Frame(_)));
    assert!(n.is_idle());
    assert_eq!(n.poll_at(), None);
    assert_eq!(
        events(&mut n),
        vec![
            answered(Step::Allocate { port: Port::Group2Only, choice: EXPLICIT_POLL }, &[0x00]),
            answered(Step::Get { class: class::CONNECTION, instance: 2, attribute: 7 }, &[0x12, 0x00]),
            answered(
                Step::Set { class: class::CONNECTION, instance: 2, attribute: 9, value: vec![0x64, 0x00] },
                &[0x64, 0x00]
            ),
        ]
    );
    assert!(n.answered());
}

/// The verdict the client gives a correct Allocate response (the engine passes it on).
fn n_ok() -> Verdict {
    let mut probe = node();
    probe.allocate(at(0), Port::Group2Only, EXPLICIT_POLL);
    let _ = sent(&mut probe);
    match probe.handle_frame(&answer(&[0x00, 0xCB, 0x00]), at(1)) {
        Handled::Frame(v) => v,
        Handled::NotMine => Verdict::fail("not taken"),
    }
}

#[test]
fn give_back_releases_what_is_held_through_the_group_2_only_port() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, EXPLICIT_POLL);
    n.get(at(0), class::IDENTITY, 1, 1, Refusal::Stop);
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x00, 0xCB, 0x00]), at(1));
    let _ = sent(&mut n);
    // Given back while the Get runs: the Get ends first, then the Release.
    n.give_back(at(2));
    assert_eq!(sent(&mut n), vec![]);
    n.handle_frame(&answer(&[0x00, 0x8E, 0x34, 0x12]), at(3));
    assert_eq!(sent(&mut n), vec![(0x42E, vec![0x00, 0x4C, 0x03, 0x01, 0x03])]);
    n.handle_frame(&answer(&[0x00, 0xCC]), at(4));
    assert!(n.is_idle());
    assert_eq!(n.held(), AllocationChoice::empty());
    assert_eq!(events(&mut n).len(), 3);
}

#[test]
fn give_back_with_nothing_held_sends_nothing() {
    let mut n = node();
    n.give_back(at(0));
    assert_eq!(sent(&mut n), vec![]);
    assert!(n.is_idle());
    assert_eq!(events(&mut n), vec![]);
}

#[rstest]
#[case::another_device(6, &[0x00, 0xCB, 0x00])]
#[case::a_poll_response(0xFF, &[0x00, 0xCB, 0x00])]
fn frames_of_others_are_not_mine(#[case] from: u8, #[case] data: &[u8]) {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, AllocationChoice::EXPLICIT);
    let _ = sent(&mut n);
    let frame = if from == 0xFF {
        CanFrame::new(
            devicenet::Identifier::group1(devicenet::id::Group1MessageId::POLL_RESPONSE, mac(5)),
            data,
        )
        .unwrap()
    } else {
        CanFrame::new(
            devicenet::Identifier::group2(mac(from), devicenet::Group2Message::ExplicitResponse),
            data,
        )
        .unwrap()
    };
    assert_eq!(n.handle_frame(&frame, at(1)), Handled::NotMine);
    assert_eq!(
        n.current(),
        Some(&Step::Allocate { port: Port::Group2Only, choice: AllocationChoice::EXPLICIT })
    );
    assert_eq!(events(&mut n), vec![]);
}

#[rstest]
#[case::wrong_service(&[0x00, 0x8E, 0x00], "service byte")]
#[case::wrong_header_mac(&[0x07, 0xCB, 0x00], "header MAC")]
fn a_wrong_answer_is_a_failed_frame(#[case] data: &[u8], #[case] failure: &str) {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, AllocationChoice::EXPLICIT);
    let _ = sent(&mut n);
    match n.handle_frame(&answer(data), at(1)) {
        Handled::Frame(Verdict::Fail(failures)) => {
            assert!(failures.iter().any(|f| f.contains(failure)), "{failures:?}")
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn an_error_response_stops_and_names_the_mac_the_step_and_the_status() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, AllocationChoice::EXPLICIT);
    n.get(at(0), class::IDENTITY, 1, 1, Refusal::Stop);
    n.set(at(0), (class::CONNECTION, 1, 12), &[3], Refusal::Stop);
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x00, 0xCB, 0x00]), at(1));
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x00, 0x94, 0x14, 0xFF]), at(2));
    // The queued Set is dropped.
    assert_eq!(sent(&mut n), vec![]);
    assert!(n.is_idle());
    let events = events(&mut n);
    let Some(Event::Failed(error)) = events.last() else { panic!("{events:?}") };
    assert_eq!(
        *error,
        NodeError::Refused {
            mac: mac(5),
            step: Step::Get { class: class::IDENTITY, instance: 1, attribute: 1 },
            general: GeneralStatus::AttributeNotSupported,
            additional: 0xFF,
        }
    );
    let text = error.to_string();
    assert!(text.starts_with("MAC 5: "), "{text}");
    assert!(text.contains("attribute not supported"), "{text}");
    // What the device still holds is known, to give it back.
    assert_eq!(n.held(), AllocationChoice::EXPLICIT);
}

#[test]
fn a_reported_error_response_is_an_answer_and_the_sequence_goes_on() {
    let mut n = node();
    n.allocate(at(0), Port::Explicit, AllocationChoice::BIT_STROBE);
    n.push(at(0), Step::Allocate { port: Port::Explicit, choice: AllocationChoice::CYCLIC }, Refusal::Report);
    let _ = sent(&mut n);
    let mut n2 = node();
    n2.push(
        at(0),
        Step::Allocate { port: Port::Explicit, choice: AllocationChoice::BIT_STROBE },
        Refusal::Report,
    );
    n2.get(at(0), class::IDENTITY, 1, 1, Refusal::Stop);
    assert_eq!(sent(&mut n2), vec![(0x42C, vec![0x00, 0x4B, 0x03, 0x01, 0x04, 0x00])]);
    n2.handle_frame(&answer(&[0x00, 0x94, 0x02, 0x02]), at(1));
    assert_eq!(sent(&mut n2), vec![(0x42C, vec![0x00, 0x0E, 0x01, 0x01, 0x01])]);
    assert_eq!(
        events(&mut n2),
        vec![Event::Answered {
            step: Step::Allocate { port: Port::Explicit, choice: AllocationChoice::BIT_STROBE },
            body: ReplyBody::Error { general: GeneralStatus::ResourceUnavailable, additional: 0x02 },
        }]
    );
    assert_eq!(n2.held(), AllocationChoice::empty());
    // Refusal::Stop on the same answer fails.
    n.handle_frame(&answer(&[0x00, 0x94, 0x02, 0x02]), at(1));
    assert!(matches!(events(&mut n).as_slice(), [Event::Failed(NodeError::Refused { .. })]));
}

#[test]
fn allocated_to_another_master_is_an_allocation_conflict() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, EXPLICIT_POLL);
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x00, 0x94, 0x0C, 0x01]), at(1));
    assert_eq!(
        events(&mut n),
        vec![Event::Failed(NodeError::AllocationConflict {
            mac: mac(5),
            step: Step::Allocate { port: Port::Group2Only, choice: EXPLICIT_POLL },
        })]
    );
}

#[test]
fn a_set_still_allocated_to_this_master_is_released_and_allocated_again_once() {
    let mut n = node();
    let choice = EXPLICIT_POLL | AllocationChoice::ACK_SUPPRESSION;
    n.allocate(at(0), Port::Group2Only, choice);
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x00, 0x94, 0x0B, 0x02]), at(1));
    // The I/O connection first, then explicit; acknowledge suppression is never released.
    assert_eq!(sent(&mut n), vec![(0x42E, vec![0x00, 0x4C, 0x03, 0x01, 0x02])]);
    // Already gone (its watchdog fired): fine.
    n.handle_frame(&answer(&[0x00, 0x94, 0x0B, 0x02]), at(2));
    assert_eq!(sent(&mut n), vec![(0x42E, vec![0x00, 0x4C, 0x03, 0x01, 0x01])]);
    n.handle_frame(&answer(&[0x00, 0xCC]), at(3));
    assert_eq!(sent(&mut n), vec![(0x42E, vec![0x00, 0x4B, 0x03, 0x01, 0x43, 0x00])]);
    // A second 0x0B is not retried again.
    n.handle_frame(&answer(&[0x00, 0x94, 0x0B, 0x02]), at(4));
    assert_eq!(sent(&mut n), vec![]);
    let events = events(&mut n);
    assert_eq!(events.first(), Some(&Event::Reallocated { choice }));
    assert!(
        matches!(
            events.as_slice(),
            [_, Event::Failed(NodeError::Refused { general: GeneralStatus::AlreadyInRequestedState, .. })]
        ),
        "{events:?}"
    );
}

#[test]
fn reallocated_then_allocated() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, AllocationChoice::EXPLICIT);
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x00, 0x94, 0x0B, 0x02]), at(1));
    assert_eq!(sent(&mut n), vec![(0x42E, vec![0x00, 0x4C, 0x03, 0x01, 0x01])]);
    n.handle_frame(&answer(&[0x00, 0xCC]), at(2));
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x00, 0xCB, 0x00]), at(3));
    assert_eq!(n.held(), AllocationChoice::EXPLICIT);
    assert_eq!(
        events(&mut n),
        vec![
            Event::Reallocated { choice: AllocationChoice::EXPLICIT },
            answered(Step::Allocate { port: Port::Group2Only, choice: AllocationChoice::EXPLICIT }, &[0x00]),
        ]
    );
}

#[test]
fn silence_times_out_at_the_response_timeout() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, AllocationChoice::EXPLICIT);
    n.get(at(0), class::IDENTITY, 1, 1, Refusal::Stop);
    let _ = sent(&mut n);
    assert_eq!(n.poll_at(), Some(at(1000)));
    n.handle_timeout(at(999));
    assert_eq!(events(&mut n), vec![]);
    n.handle_timeout(at(1000));
    assert!(n.is_idle());
    assert!(!n.answered());
    let events = events(&mut n);
    let [Event::Failed(e @ NodeError::Timeout { timeout: "explicit response timeout", .. })] =
        events.as_slice()
    else {
        panic!("{events:?}")
    };
    assert_eq!(e.step(), &Step::Allocate { port: Port::Group2Only, choice: AllocationChoice::EXPLICIT });
    assert!(e.to_string().starts_with("MAC 5: "), "{e}");
}

#[test]
fn a_fragmented_answer_is_reassembled_and_acknowledged() {
    let mut n = node();
    n.get(at(0), class::IDENTITY, 1, 7, Refusal::Stop);
    assert_eq!(sent(&mut n), vec![(0x42C, vec![0x00, 0x0E, 0x01, 0x01, 0x07])]);
    // "8E 0B Breaker 01" in three fragments of at most 6 body bytes.
    let body: Vec<u8> = [0x8E, 10].iter().copied().chain(*b"Breaker 01").collect();
    let fragments: Vec<Vec<u8>> = body
        .chunks(6)
        .enumerate()
        .map(|(i, chunk)| {
            let kind = match i {
                0 => 0x00,
                _ if (i + 1) * 6 >= body.len() => 0x80,
                _ => 0x40,
            };
            [0x80, kind | i as u8].iter().copied().chain(chunk.iter().copied()).collect()
        })
        .collect();
    assert_eq!(fragments.len(), 2);
    for (i, f) in fragments.iter().enumerate() {
        assert!(matches!(n.handle_frame(&answer(f), at(1 + i as u64)), Handled::Frame(Verdict::Ok(_))));
        let acks = sent(&mut n);
        assert_eq!(acks.len(), 1, "fragment {i}: one acknowledge");
        assert_eq!(acks[0].0, 0x42C);
    }
    assert_eq!(
        events(&mut n),
        vec![answered(Step::Get { class: class::IDENTITY, instance: 1, attribute: 7 }, &body[1..])]
    );
}

#[test]
fn a_silent_fragment_times_out_as_a_fragment() {
    let mut n = node();
    n.get(at(0), class::IDENTITY, 1, 7, Refusal::Report);
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x80, 0x00, 0x8E, 10, b'B', b'r', b'e', b'a']), at(10));
    let _ = sent(&mut n);
    n.handle_timeout(at(1010));
    assert!(matches!(
        events(&mut n).as_slice(),
        [Event::Failed(NodeError::Timeout { timeout: "response fragment timeout", .. })]
    ));
}

#[test]
fn a_request_too_long_to_send_fails_naming_it() {
    let mut n = node();
    n.set(at(0), (class::ASSEMBLY, 100, 3), &[0; 2000], Refusal::Stop);
    assert_eq!(sent(&mut n), vec![]);
    assert!(matches!(
        events(&mut n).as_slice(),
        [Event::Failed(NodeError::Request { source: RequestError::TooLong { .. }, .. })]
    ));
    assert!(n.is_idle());
}

#[test]
fn the_body_format_an_allocate_answers_is_used_on_the_explicit_connection() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, AllocationChoice::EXPLICIT);
    n.get(at(0), class::IDENTITY, 1, 1, Refusal::Stop);
    let _ = sent(&mut n);
    // 16/16 (code 2): class and instance two bytes each.
    n.handle_frame(&answer(&[0x00, 0xCB, 0x02]), at(1));
    assert_eq!(n.body_format(), BodyFormat::Class16Instance16);
    assert_eq!(sent(&mut n), vec![(0x42C, vec![0x00, 0x0E, 0x01, 0x00, 0x01, 0x00, 0x01])]);
}

#[test]
fn each_allocate_is_released_and_allocated_again_once() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, AllocationChoice::EXPLICIT);
    n.allocate(at(0), Port::Explicit, AllocationChoice::POLL);
    let _ = sent(&mut n);
    let kept = [0x00, 0x94, 0x0B, 0x02];
    for (ms, release) in [(1, 0x01), (4, 0x02)] {
        n.handle_frame(&answer(&kept), at(ms));
        assert_eq!(sent(&mut n), vec![(0x42E, vec![0x00, 0x4C, 0x03, 0x01, release])]);
        n.handle_frame(&answer(&[0x00, 0xCC]), at(ms + 1));
        let _ = sent(&mut n);
        n.handle_frame(&answer(&[0x00, 0xCB, 0x00]), at(ms + 2));
        let _ = sent(&mut n);
    }
    assert!(n.is_idle());
    assert_eq!(n.held(), EXPLICIT_POLL);
    let reallocated = events(&mut n).iter().filter(|e| matches!(e, Event::Reallocated { .. })).count();
    assert_eq!(reallocated, 2);
}

#[test]
fn a_refused_give_back_is_reported_not_a_failure() {
    let mut n = node();
    n.allocate(at(0), Port::Group2Only, AllocationChoice::EXPLICIT);
    let _ = sent(&mut n);
    n.handle_frame(&answer(&[0x00, 0xCB, 0x00]), at(1));
    n.give_back(at(2));
    assert_eq!(sent(&mut n), vec![(0x42E, vec![0x00, 0x4C, 0x03, 0x01, 0x01])]);
    n.handle_frame(&answer(&[0x00, 0x94, 0x0B, 0x02]), at(3));
    let events = events(&mut n);
    assert!(
        matches!(
            events.last(),
            Some(Event::Answered { step: Step::Release { .. }, body: ReplyBody::Error { .. } })
        ),
        "{events:?}"
    );
    // Not released as far as the engine knows.
    assert_eq!(n.held(), AllocationChoice::EXPLICIT);
}
