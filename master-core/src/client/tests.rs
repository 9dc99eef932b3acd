//! The late acknowledge of a request's last fragment ([`Transaction::with_late_last_ack`]), on a
//! transaction driven by hand: a 20-byte request (Update's length) goes out in 4 fragments.

use super::*;

const DEVICE: u8 = 5;

fn mac(n: u8) -> MacId {
    MacId::new(n).unwrap()
}

fn update_like(late: bool) -> Transaction {
    let data = [0u8; 16];
    let req = Request { service: ServiceCode::from(0x4B), class: 0x6A, instance: 1, data: &data };
    let tx = Transaction::new(
        mac(DEVICE),
        mac(0),
        Port::Explicit,
        false,
        &req,
        BodyFormat::Class8Instance8,
        Duration::from_secs(10),
    )
    .unwrap();
    if late {
        tx.with_late_last_ack()
    } else {
        tx
    }
}

/// The frames the transaction has queued.
fn sent(tx: &mut Transaction) -> Vec<CanFrame> {
    std::iter::from_fn(|| tx.poll_transmit()).collect()
}

/// The device's acknowledge of request fragment `count` (header MAC 0, XID 0).
fn ack(count: u8) -> CanFrame {
    CanFrame::new(Identifier::group2(mac(DEVICE), Group2Message::ExplicitResponse), &[0x80, 0xC0 | count, 0])
        .unwrap()
}

/// Starts `tx` at 0 and acknowledges fragments 0–2 at once; returns the last fragment sent.
fn to_last_fragment(tx: &mut Transaction) -> CanFrame {
    tx.start(Instant::ZERO);
    for count in 0..3 {
        assert_eq!(sent(tx).len(), 1, "fragment {count}");
        assert!(matches!(tx.handle_frame(&ack(count), Instant::ZERO), Handled::Frame(Verdict::Ok(_))));
    }
    let last = sent(tx);
    assert_eq!(last.len(), 1);
    assert_eq!(last[0].data()[1], 0x80 | 3, "the last fragment, #3");
    last[0]
}

fn at_ms(ms: u64) -> Instant {
    Instant::from_millis(ms)
}

#[test]
fn late_last_ack_is_awaited_without_a_resend() {
    let mut tx = update_like(true);
    to_last_fragment(&mut tx);
    for ms in [1_000, 1_500, 2_000, 2_500] {
        tx.handle_timeout(at_ms(ms));
        assert!(sent(&mut tx).is_empty(), "nothing re-sent at {ms} ms");
        assert!(!tx.is_done(), "still waiting at {ms} ms");
    }
    let Handled::Frame(verdict) = tx.handle_frame(&ack(3), at_ms(2_100)) else {
        panic!("the ack is the transaction's")
    };
    assert!(matches!(&verdict, Verdict::Ok(note) if note.contains("2100 ms")), "{verdict:?}");
    let response = CanFrame::new(
        Identifier::group2(mac(DEVICE), Group2Message::ExplicitResponse),
        &[0x00, 0xCB, 128, 0, 0, 0, 0, 0],
    )
    .unwrap();
    assert!(matches!(tx.handle_frame(&response, at_ms(2_101)), Handled::Frame(Verdict::Ok(_))));
    let reply = tx.take_outcome().unwrap().unwrap();
    assert_eq!(reply.data(), Some(&[128, 0, 0, 0, 0, 0][..]));
}

#[test]
fn late_last_ack_times_out_after_the_response_timeout() {
    let mut tx = update_like(true);
    to_last_fragment(&mut tx);
    tx.handle_timeout(at_ms(1_000));
    tx.handle_timeout(at_ms(2_000));
    assert_eq!(tx.poll_at(), Some(at_ms(10_000)), "the response timeout from the fragment's send");
    tx.handle_timeout(at_ms(9_999));
    assert!(!tx.is_done());
    tx.handle_timeout(at_ms(10_000));
    let err = tx.take_outcome().unwrap().unwrap_err();
    assert_eq!(
        err,
        ClientError::RequestAborted("last request fragment not acknowledged within 10000 ms".into())
    );
}

#[test]
fn late_ack_of_another_fragment_fails() {
    let mut tx = update_like(true);
    to_last_fragment(&mut tx);
    tx.handle_timeout(at_ms(1_000));
    tx.handle_timeout(at_ms(2_000));
    assert!(matches!(tx.handle_frame(&ack(2), at_ms(2_100)), Handled::Frame(Verdict::Fail(_))));
    assert!(!tx.is_done(), "still waiting for #3");
}

#[test]
fn without_it_the_last_fragment_is_resent_once_then_aborted() {
    let mut tx = update_like(false);
    let last = to_last_fragment(&mut tx);
    tx.handle_timeout(at_ms(1_000));
    assert_eq!(sent(&mut tx), vec![last], "one re-send after the 1 s acknowledge timeout");
    tx.handle_timeout(at_ms(2_000));
    let err = tx.take_outcome().unwrap().unwrap_err();
    assert!(
        matches!(err, ClientError::RequestAborted(ref why) if why.contains("also after one re-send")),
        "{err:?}"
    );
    // A late acknowledge is then no longer the transaction's.
    assert_eq!(tx.handle_frame(&ack(3), at_ms(2_100)), Handled::NotMine);
}

#[test]
fn other_fragments_keep_their_resend() {
    let mut tx = update_like(true);
    tx.start(Instant::ZERO);
    let first = sent(&mut tx);
    tx.handle_timeout(at_ms(1_000));
    assert_eq!(sent(&mut tx), first, "fragment #0 re-sent after 1 s");
    tx.handle_timeout(at_ms(2_000));
    assert!(tx.take_outcome().unwrap().is_err(), "and the transfer aborted after the second timeout");
}
