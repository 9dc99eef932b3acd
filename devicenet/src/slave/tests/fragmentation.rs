//! Explicit fragmentation (protocol §4.1).

use super::*;

#[test]
fn output_assembly_reads_the_consumed_size_of_zeros_before_any_output() {
    // Connection 2 attribute 8 and the EDS say 8 bytes: the data reads as 8 bytes from the start
    // (9 body bytes with the service, so fragmented, protocol §4.1).
    let mut rig = Rig::explicit();
    let first = rig.send(0x42C, &[0x00, 0x0E, 0x04, 0x96, 0x03]);
    assert_eq!(first, tx(0x42B, &[0x80, 0x00, 0x8E, 0, 0, 0, 0, 0]));
    let last = rig.send(0x42C, &[0x80, 0xC0, 0x00]);
    assert_eq!(last, tx(0x42B, &[0x80, 0x81, 0, 0, 0]));
    assert_eq!(rig.node.output(), &[0; 8]);
}

#[test]
fn product_name_is_sent_fragmented_with_acks() {
    let mut rig = Rig::explicit();
    // "Serial-DeviceNet Bridge": 23 characters; body 8E 17 <23 bytes> = 25 bytes.
    let first = rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x07]);
    assert_eq!(first, tx(0x42B, &[0x80, 0x00, 0x8E, 0x17, b'S', b'e', b'r', b'i']));
    let mut body = first[0].1[2..].to_vec();
    let mut count = 0u8;
    loop {
        let next = rig.send(0x42C, &[0x80, 0xC0 | count, 0x00]);
        if next.is_empty() {
            break;
        }
        assert_eq!(next.len(), 1);
        let frame = &next[0].1;
        assert_eq!(frame[0], 0x80);
        count += 1;
        let kind = frame[1] >> 6;
        assert_eq!(frame[1] & 0x3F, count);
        body.extend_from_slice(&frame[2..]);
        assert!(kind == 1 || kind == 2, "middle or last fragment");
    }
    assert_eq!(count, 4, "25 body bytes = 5 fragments of up to 6");
    assert_eq!(&body[..2], &[0x8E, 23]);
    assert_eq!(&body[2..], b"Serial-DeviceNet Bridge");
}

#[test]
fn missing_ack_retries_once_then_aborts() {
    let mut rig = Rig::explicit();
    let first = rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x07]);
    assert_eq!(first.len(), 1);
    // One re-send after 1 s, then the transfer is abandoned after another second.
    assert_eq!(rig.advance(Duration::from_millis(1000)), first);
    assert_eq!(rig.advance(Duration::from_millis(1000)), Tx::new());
    assert!(rig.events().contains(&Event::ExplicitTransferAborted));
    assert_eq!(rig.advance(Duration::from_secs(3)), Tx::new());
    // The connection still serves requests.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x34, 0x12]));
}

#[test]
fn fragmented_request_is_acked_and_served() {
    let mut rig = Rig::explicit();
    // Set Assembly 150 attribute 3 = 8 bytes: body 10 04 96 03 + 8 bytes = 12 bytes, 2 fragments.
    let out = [1u8, 2, 3, 4, 5, 6, 7, 8];
    let r1 = rig.send(0x42C, &[0x80, 0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]);
    assert_eq!(r1, tx(0x42B, &[0x80, 0xC0, 0x00]));
    // A duplicate of the first fragment is re-acked, not appended.
    let dup = rig.send(0x42C, &[0x80, 0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]);
    assert_eq!(dup, tx(0x42B, &[0x80, 0xC0, 0x00]));
    let r2 = rig.send(0x42C, &[0x80, 0x81, 3, 4, 5, 6, 7, 8]);
    assert_eq!(r2, std::vec![(0x42B, std::vec![0x80, 0xC1, 0x00]), (0x42B, std::vec![0x00, 0x90])]);
    assert_eq!(rig.node.output(), &out);
    assert!(rig.events().contains(&Event::OutputReceived));
}

#[test]
fn repeated_last_fragment_is_acked_again_and_not_served_twice() {
    let mut rig = Rig::explicit();
    rig.send(0x42C, &[0x80, 0x00, 0x10, 0x04, 0x96, 0x03, 1, 2]);
    let last = [0x80, 0x81, 3, 4, 5, 6, 7, 8];
    let r = rig.send(0x42C, &last);
    assert_eq!(r, std::vec![(0x42B, std::vec![0x80, 0xC1, 0x00]), (0x42B, std::vec![0x00, 0x90])]);
    let served = rig.events().iter().filter(|e| **e == Event::OutputReceived).count();
    // The master missed the ack and sends the last fragment again: acked, not served again.
    assert_eq!(rig.send(0x42C, &last), tx(0x42B, &[0x80, 0xC1, 0x00]));
    assert!(!rig.events().contains(&Event::OutputReceived), "served once ({served})");
    // The next request starts afresh.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x34, 0x12]));
}

#[test]
fn oversized_fragmented_request_is_rejected_with_too_much_data() {
    let mut rig = Rig::explicit();
    let mut acks = Vec::new();
    acks.extend(rig.send(0x42C, &[0x80, 0x00, 0x10, 0x04, 0x96, 0x03, 0, 0]));
    // 6 body bytes a fragment: one more fragment than MAX_EXPLICIT_SIZE holds.
    let middles = (MAX_EXPLICIT_SIZE / 6) as u8;
    for count in 1..=middles {
        acks.extend(rig.send(0x42C, &[0x80, 0x40 | count, 0, 0, 0, 0, 0, 0]));
    }
    assert!(acks.iter().any(|(_, d)| d.len() == 3 && d[2] == 0x01), "an ack with status 1: {acks:02X?}");
}

#[test]
fn a_firmware_update_transfer_request_is_reassembled_and_served() {
    // Service 0x4D, class 0x6A, instance 1, chunk number (4), 128 bytes: 135 body bytes in 23
    // fragments of 6 (the last 3), each acknowledged with status 0 (firmware-update.md).
    let mut body = std::vec![0x4D, 0x6A, 0x01, 0, 0, 0, 0];
    body.extend((0..128).map(|i| i as u8));
    let fragments: Vec<&[u8]> = body.chunks(6).collect();
    assert_eq!(fragments.len(), 23);
    let mut rig = Rig::explicit();
    for (count, part) in fragments.iter().enumerate() {
        let kind = match count {
            0 => 0x00,
            22 => 0x80,
            _ => 0x40,
        };
        let mut frame = std::vec![0x80, kind | count as u8];
        frame.extend_from_slice(part);
        let out = rig.send(0x42C, &frame);
        assert_eq!(out[0], (0x42B, std::vec![0x80, 0xC0 | count as u8, 0x00]), "fragment {count} acked");
        if count == 22 {
            // Served: the rig has no class 0x6A, so the answer is an error response, not a
            // "too much data" acknowledgement.
            assert_eq!(out.get(1), Some(&(0x42B, std::vec![0x00, 0x94, 0x16, 0xFF])), "{out:02X?}");
        } else {
            assert_eq!(out.len(), 1, "fragment {count}");
        }
    }
}
