use super::*;
use devicenet::reference::BRING_UP;
use rstest::rstest;

fn f(id: u16, data: &[u8]) -> CanFrame {
    CanFrame::from_raw(id, data).unwrap()
}

/// An object-specific service code names the DeviceNet object's service only on that object:
/// a vendor object's 0x4B (the configuration object's Read_Chunk) is not an Allocate.
#[rstest]
#[case::request_on_a_vendor_class(&[0x00, 0x4B, 0x66, 0x01, 0x00, 0x00, 0x00, 0x38], "service 0x4B class 0x66 inst 1")]
#[case::request_on_the_devicenet_object(&[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00], "Allocate_Master/Slave_Connection_Set DeviceNet(3) inst 1")]
fn object_specific_services_are_named_by_their_class(#[case] data: &[u8], #[case] expected: &str) {
    let mut d = Decoder::new();
    let text = d.decode(&f(0x42C, data)).text();
    assert!(text.contains(expected), "{text}");
    assert!(data[2] == 0x03 || !text.contains("Allocate_Master"), "{text}");
}

#[test]
fn the_reference_sequence_reads_like_the_notes() {
    let mut d = Decoder::new();
    let texts: Vec<String> = BRING_UP.iter().map(|r| d.decode(&f(r.id, r.data)).text()).collect();
    assert!(texts[0].contains("duplicate MAC ID check request for MAC 0"), "{}", texts[0]);
    assert!(
        texts[4].contains("UCMM Open Explicit Messaging Connection request from MAC 0 to MAC 5"),
        "{}",
        texts[4]
    );
    assert!(
        texts[6].contains(
            "Allocate_Master/Slave_Connection_Set DeviceNet(3) inst 1: choice explicit, allocator MAC 0"
        ),
        "{}",
        texts[6]
    );
    assert!(texts[7].contains("message body format 8/8"), "{}", texts[7]);
    assert!(texts[8].contains("attr 12 (watchdog timeout action) = 3 (deferred delete)"), "{}", texts[8]);
    assert!(texts[11].contains("vendor ID) = 0x1234"), "{}", texts[11]);
    assert!(texts[19].contains("produced connection size) = 18 bytes"), "{}", texts[19]);
    assert!(texts[23].contains("expected packet rate) applied = 100 ms"), "{}", texts[23]);
    assert!(texts[25].contains("I/O fragment first #0"), "{}", texts[25]);
    assert!(!texts[25].contains("inferred"), "size known from frame 19: {}", texts[25]);
    assert!(
        texts[27].contains("poll response from MAC 5, 18 bytes: 00 00 00 00 00 00 00 00 00 0F"),
        "{}",
        texts[27]
    );
    assert_eq!(d.connection_sizes(5), (Some(18), Some(8)));
}

#[test]
fn fragmented_explicit_response_is_reassembled() {
    let mut d = Decoder::new();
    d.decode(&f(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x07]));
    let first = d.decode(&f(0x42B, &[0x80, 0x00, 0x8E, 0x17, b'S', b'e', b'r', b'i']));
    assert!(first.summary.contains("fragment first #0"), "{first:?}");
    assert!(d.decode(&f(0x42C, &[0x80, 0xC0, 0x00])).summary.contains("fragment ack #0 status success"));
    d.decode(&f(0x42B, &[0x80, 0x41, b'a', b'l', b'-', b'D', b'e', b'v']));
    d.decode(&f(0x42B, &[0x80, 0x42, b'i', b'c', b'e', b'N', b'e', b't']));
    d.decode(&f(0x42B, &[0x80, 0x43, b' ', b'B', b'r', b'i', b'd', b'g']));
    let last = d.decode(&f(0x42B, &[0x80, 0x84, b'e']));
    let msg = last.message.expect("complete");
    assert!(msg.contains("attr 7 (product name) = \"Serial-DeviceNet Bridge\""), "{msg}");
}

#[test]
fn io_fragments_inferred_without_sizes() {
    let mut d = Decoder::new();
    let a = d.decode(&f(0x3C5, &[0x00, 1, 2, 3, 4, 5, 6, 7]));
    assert!(a.summary.contains("inferred"), "{a:?}");
    d.decode(&f(0x3C5, &[0x41, 8, 9, 10, 11, 12, 13, 14]));
    let c = d.decode(&f(0x3C5, &[0x82, 15, 16, 17, 18]));
    assert_eq!(
        c.message.as_deref(),
        Some("poll response from MAC 5, 18 bytes: 01 02 03 04 05 06 07 08 09 0A 0B 0C 0D 0E 0F 10 11 12")
    );
    // A short response is plain data.
    assert_eq!(d.decode(&f(0x3C5, &[0x0F, 0x00])).summary, "poll response from MAC 5: 2 bytes 0F 00");
}

#[test]
fn a_complete_response_between_fragments_resets_the_response_reassembly() {
    // Test vectors of an independent analyzer: a first fragment, a complete response, then a
    // last fragment. Nothing may be reassembled from the first and the last.
    let mut d = Decoder::new();
    let first = d.decode(&f(0x40B, &[0x80, 0x00, 0x8E, 0x01]));
    assert!(first.summary.contains("fragment first #0"), "{first:?}");
    let whole = d.decode(&f(0x40B, &[0x00, 0x8E, 0xAA]));
    assert!(whole.text().contains("Get_Attribute_Single response") && whole.message.is_none(), "{whole:?}");
    let last = d.decode(&f(0x40B, &[0x80, 0x81, 0xBB]));
    assert_eq!(last.message, None, "no invented message: {last:?}");
    assert!(last.summary.contains("fragment last #1") && last.summary.contains("dropped"), "{last:?}");
}

#[test]
fn a_connection_opened_through_ucmm_is_followed_in_the_body_format_it_was_given() {
    // MAC 0 opens a Group 3 connection to MAC 5 (source message ID 4), MAC 5 answers with
    // body format 8/16, consuming message 4 and producing message 2, Connection instance 6.
    let mut d = Decoder::new();
    d.decode(&f(0x780, &[0x05, 0x4B, 0x01, 0x34]));
    let open = d.decode(&f(0x745, &[0x00, 0xCB, 0x01, 0x42, 0x06, 0x00])).text();
    assert!(open.ends_with("requests on 0x700, responses on 0x685 (group 3)"), "{open}");
    // A Get_Attribute_Single in 8/16 on G3 message 4 from MAC 0, and its answer.
    let get = d.decode(&f(0x700, &[0x05, 0x0E, 0x01, 0x01, 0x00, 0x07])).text();
    assert_eq!(
        get,
        "explicit request on UCMM connection 6 (from MAC 0) to MAC 5 [master MAC 5] Get_Attribute_Single Identity(1) inst 1 attr 7 (product name)"
    );
    let rsp = d.decode(&f(0x685, &[0x00, 0x8E, 0x02, b'O', b'K'])).text();
    assert!(rsp.starts_with("explicit response on UCMM connection 6 (to MAC 0) from MAC 5"), "{rsp}");
    assert!(rsp.contains("attr 7 (product name) = \"OK\""), "{rsp}");
    // Fragments on the connection are reassembled on it.
    d.decode(&f(0x700, &[0x05, 0x0E, 0x01, 0x01, 0x00, 0x07]));
    d.decode(&f(0x685, &[0x80, 0x00, 0x8E, 0x04, b'a', b'b', b'c']));
    let last = d.decode(&f(0x685, &[0x80, 0x81, b'd']));
    assert!(last.message.as_deref().is_some_and(|m| m.contains("\"abcd\"")), "{last:?}");
    // Closed: the identifiers are raw dynamic traffic again.
    d.decode(&f(0x780, &[0x05, 0x4C, 0x06, 0x00]));
    let close = d.decode(&f(0x745, &[0x00, 0xCC])).text();
    assert!(close.ends_with("connection 6 closed"), "{close}");
    let after = d.decode(&f(0x700, &[0x05, 0x0E, 0x01, 0x01, 0x00, 0x07])).text();
    assert!(
        after.starts_with("G3 message 4 from MAC 0 (dynamic connection, not opened in this trace)"),
        "{after}"
    );
}

#[rstest]
#[case::group1(0x00, 0x040, 0x085)]
#[case::group2(0x10, 0x42D, 0x42B)]
fn ucmm_connections_in_groups_1_and_2(#[case] select: u8, #[case] request: u16, #[case] response: u16) {
    // The Open response's destination message ID (high nibble) is what the server consumes,
    // its source message ID (low nibble) what it produces.
    let mut d = Decoder::new();
    let msgs = if select == 0 { 0x12 } else { 0x53 };
    d.decode(&f(0x780, &[0x05, 0x4B, 0x00, select | msgs >> 4]));
    let open = d.decode(&f(0x745, &[0x00, 0xCB, 0x00, msgs, 0x07, 0x00])).text();
    assert!(open.contains(&format!("requests on 0x{request:03X}, responses on 0x{response:03X}")), "{open}");
    let get = d.decode(&f(request, &[0x05, 0x0E, 0x01, 0x01, 0x01])).text();
    assert!(get.starts_with("explicit request on UCMM connection 7"), "{get}");
}

#[test]
fn an_open_response_without_its_request_is_not_followed() {
    let mut d = Decoder::new();
    let open = d.decode(&f(0x745, &[0x00, 0xCB, 0x00, 0x42, 0x06, 0x00])).text();
    assert!(open.ends_with("the connection is not followed)"), "{open}");
    assert!(d.decode(&f(0x700, &[0x05, 0x0E, 0x01, 0x01, 0x07])).text().starts_with("G3 message 4"));
}

#[test]
fn change_of_state_data_is_reassembled_with_the_size_of_connection_4() {
    // Notes §II.2.1: 18-byte COS data from MAC 5 on 0x345, fragments back to back.
    let mut d = Decoder::new();
    d.decode(&f(0x42C, &[0x00, 0x0E, 0x05, 0x04, 0x07]));
    d.decode(&f(0x42B, &[0x00, 0x8E, 0x12, 0x00]));
    let first = d.decode(&f(0x345, &[0x00, 0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06]));
    assert_eq!(
        first.summary,
        "change-of-state/cyclic data from MAC 5: I/O fragment first #0: 00 01 02 03 04 05 06"
    );
    d.decode(&f(0x345, &[0x41, 0x07, 0x08, 0x09, 0x0A, 0x0B, 0x0C, 0x0D]));
    let last = d.decode(&f(0x345, &[0x82, 0x0E, 0x0F, 0x10, 0x11]));
    assert_eq!(
        last.message.as_deref(),
        Some("change-of-state/cyclic data from MAC 5, 18 bytes: 00 01 02 03 04 05 06 07 08 09 0A 0B 0C 0D 0E 0F 10 11")
    );
    // A one-frame series (first fragment, count 0x3F) is a whole message.
    let single = d.decode(&f(0x345, &[0x3F, 0xAA, 0xBB]));
    assert!(single.summary.contains("#63 (a one-frame series: the whole message)"), "{single:?}");
    assert_eq!(single.message.as_deref(), Some("change-of-state/cyclic data from MAC 5, 2 bytes: AA BB"));
    // Without the size, the fragment bytes tell (as for the poll response).
    let mut d = Decoder::new();
    let guessed = d.decode(&f(0x385, &[0x00, 1, 2, 3, 4, 5, 6, 7]));
    assert!(
        guessed.summary.starts_with("bit-strobe response from MAC 5: I/O fragment first #0, size inferred"),
        "{guessed:?}"
    );
}

#[test]
fn without_poll_connection_2_carries_cos_data_and_acknowledgements() {
    // Notes §II.2.5: COS allocated without poll; the master's data on 0x42D, the device's
    // zero-length acknowledgement on 0x3C5. Both directions, whichever way the frame is decoded.
    for fast in [true, false] {
        let mut d = Decoder::new();
        let mut text = |frame: CanFrame| {
            if fast {
                let mut out = Decoded::default();
                d.decode_into(&frame, &mut out);
                out.summary
            } else {
                d.decode(&frame).summary
            }
        };
        assert_eq!(text(f(0x3C5, &[])), "poll response from MAC 5: no data (idle)");
        text(f(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x11, 0x00]));
        text(f(0x42B, &[0x00, 0xCB, 0x00]));
        assert_eq!(text(f(0x42D, &[1, 2])), "change-of-state/cyclic data to MAC 5: 2 bytes 01 02");
        assert_eq!(text(f(0x3C5, &[])), "change-of-state/cyclic acknowledge from MAC 5: no data");
        // Released: Connection 2 is a poll connection again once poll is allocated.
        text(f(0x42C, &[0x00, 0x4C, 0x03, 0x01, 0x10]));
        text(f(0x42B, &[0x00, 0xCC]));
        text(f(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00]));
        text(f(0x42B, &[0x00, 0xCB, 0x00]));
        assert_eq!(text(f(0x42D, &[1, 2])), "poll command to MAC 5: 2 bytes 01 02");
    }
}

#[test]
fn a_cip_path_request_with_an_attribute_segment_is_decoded() {
    // Issue 16's frames: MAC 3's explicit connection in body format 4 (announced by the
    // Allocate response), a Get_Attribute_Single whose path ends in an attribute segment.
    let mut d = Decoder::new();
    d.decode(&f(0x41E, &[0x0A, 0x4B, 0x03, 0x01, 0x01, 0x0A]));
    d.decode(&f(0x41B, &[0x0A, 0xCB, 0x04]));
    d.decode(&f(0x41C, &[0x8A, 0x00, 0x0E, 0x03, 0x20, 0x01, 0x24, 0x01]));
    let last = d.decode(&f(0x41C, &[0x8A, 0x81, 0x30, 0x01]));
    assert_eq!(
        last.message.as_deref(),
        Some("reassembled 9 bytes: Get_Attribute_Single Identity(1) inst 1 attr 1 (vendor ID) (CIP path)")
    );
    // Its response is read with the attribute of the path.
    let rsp = d.decode(&f(0x41B, &[0x0A, 0x8E, 0x34, 0x12])).text();
    assert!(rsp.contains("Identity(1) inst 1 attr 1 (vendor ID) = 0x1234"), "{rsp}");
}

#[rstest]
#[case::sixteen_bit(&[0x01, 0x04, 0x21, 0x00, 0x0F, 0x00, 0x25, 0x00, 0x02, 0x01], "Get_Attributes_All Parameter(15) inst 258 (CIP path)")]
#[case::attribute16(&[0x0E, 0x04, 0x20, 0x01, 0x24, 0x01, 0x31, 0x00, 0x00, 0x01], "Get_Attribute_Single Identity(1) inst 1 attr 256 (CIP path)")]
#[case::set(&[0x10, 0x03, 0x20, 0x05, 0x24, 0x02, 0x30, 0x09, 0x64, 0x00], "Set_Attribute_Single Connection(5) inst 2 attr 9 (expected packet rate) = 100 ms (CIP path)")]
fn cip_path_requests(#[case] body: &[u8], #[case] text: &str) {
    let (req, attribute) = path_request(body).unwrap();
    assert_eq!(path_request_text(&req, attribute).0, text);
}

#[rstest]
#[case::no_instance(&[0x0E, 0x02, 0x20, 0x01, 0x30, 0x01], "path segments out of order (class, instance, attribute): 20 01 30 01")]
#[case::twice(&[0x0E, 0x03, 0x20, 0x01, 0x24, 0x01, 0x24, 0x02], "path segments out of order (class, instance, attribute): 20 01 24 01 24 02")]
#[case::port_segment(&[0x0E, 0x02, 0x01, 0x05, 0x20, 0x01], "unsupported path segment 0x01 in 01 05 20 01")]
#[case::short(&[0x0E, 0x03, 0x20, 0x01], "path of 3 words, only 2 bytes follow")]
#[case::response(&[0x8E, 0x01, 0x20, 0x01], "not a request (bit 7 of the service set)")]
#[case::empty(&[0x0E], "truncated: no path size")]
fn malformed_cip_paths(#[case] body: &[u8], #[case] why: &str) {
    assert_eq!(path_request(body).unwrap_err(), why);
}

#[test]
fn the_body_format_is_said_to_be_assumed_until_an_allocate_response_is_seen() {
    let mut d = Decoder::new();
    let get = f(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]);
    let before = d.decode(&get).text();
    assert!(before.ends_with("[body format 8/8 assumed: no Allocate response seen]"), "{before}");
    // The Group 2 Only port is 8/8 by definition: nothing assumed.
    let alloc = d.decode(&f(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00])).text();
    assert!(!alloc.contains("assumed"), "{alloc}");
    // Allocate response announcing 8/16: requests on the connection are read with it.
    d.decode(&f(0x42B, &[0x00, 0xCB, 0x01]));
    let after = d.decode(&f(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x00, 0x01])).text();
    assert!(!after.contains("assumed") && after.contains("Identity(1) inst 1 attr 1"), "{after}");
    // ... while the Group 2 Only port stays 8/8.
    let release = d.decode(&f(0x42E, &[0x00, 0x4C, 0x03, 0x01, 0x01])).text();
    assert!(release.contains("Release_Master/Slave_Connection_Set DeviceNet(3) inst 1"), "{release}");
}

#[rstest]
#[case::who(0x7ED, &[0x3F, 0x4B, 0x02], "Who request (match 0 (mask), value 63), time-delay byte offset 2")]
#[case::who_response(0x7EC, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], "Who response from a faulted node: port 0, vendor 0x1234, serial 0x12345678")]
#[case::identify_short(0x7ED, &[0x45, 0x4C], "Identify request, multicast (match 1 (exact MAC ID), value 5)")]
#[case::identify_long(0x7ED, &[0x3F, 0x4C, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], "Identify request, point-to-point (match 0 (mask), value 63): vendor 0x1234, serial 0x12345678")]
#[case::identify_response(0x7EC, &[0x45, 0xCC], "Identify response (match 1 (exact MAC ID), value 5)")]
#[case::change_mac(0x7ED, &[0x07, 0x4D, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], "Change MAC ID to 7 for vendor 0x1234, serial 0x12345678")]
#[case::ownership(0x7EF, &[0x0A, 0x4B, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01], "ownership request from tool MAC 10: vendor 0x0001, serial 0x01020304")]
#[case::ownership_response(0x7EE, &[0x0A, 0xCB, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], "ownership response to tool MAC 10: vendor 0x1234, serial 0x12345678")]
fn group4_messages_show_every_field(#[case] id: u16, #[case] data: &[u8], #[case] text: &str) {
    let out = Decoder::new().decode(&f(id, data)).text();
    assert_eq!(out, format!("Offline Connection Set: {text}"));
}

#[rstest]
#[case::heartbeat(&[0x05, 0xCD, 0x01, 0x00, 0x03, 0x00, 0x00, 0x00], "Device Heartbeat from MAC 5: Identity instance 1, state 3 (operational), flags 0x00 (none), configuration consistency value 0x0000")]
#[case::heartbeat_faults(&[0x05, 0xCD, 0x01, 0x00, 0x04, 0x05, 0x34, 0x12], "Device Heartbeat from MAC 5: Identity instance 1, state 4 (major recoverable fault), flags 0x05 (DF device fault, SF system fault), configuration consistency value 0x1234")]
#[case::shutdown(&[0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00], "Device Shutdown from MAC 5: class 0x0001 instance 1 code 0x0004")]
#[case::wrong_header(&[0x00, 0xCD, 0x01, 0x00, 0x03, 0x00, 0x00, 0x00], "Device Heartbeat from MAC 5: Identity instance 1, state 3 (operational), flags 0x00 (none), configuration consistency value 0x0000 (warning: header MAC 0 is not the identifier's MAC 5; a heartbeat or shutdown carries the sender's own MAC)")]
#[case::short(&[0x05, 0xCE, 0x01, 0x00], "Device Shutdown from MAC 5, malformed: 4 bytes, a heartbeat or shutdown has exactly 8: 05 CE 01 00")]
fn heartbeat_and_shutdown_fields(#[case] data: &[u8], #[case] text: &str) {
    // Notes §II.5: sent on the device's explicit response identifier (0x42B for MAC 5).
    assert_eq!(Decoder::new().decode(&f(0x42B, data)).text(), text);
}

#[rstest]
#[case::not_supported(&[0x00, 0x94, 0x14, 0xFF], "Error_Response: attribute not supported (0x14), additional code 0xFF (no additional code)")]
#[case::conflict(&[0x00, 0x94, 0x0C, 0x01], "object state conflict (0x0C), additional code 0x01 (allocation conflict)")]
#[case::malformed(&[0x00, 0x0E], "malformed response")]
fn error_responses(#[case] data: &[u8], #[case] text: &str) {
    let mut d = Decoder::new();
    let out = d.decode(&f(0x42B, data)).text();
    assert!(out.contains(text), "{out}");
}

proptest::proptest! {
    #[test]
    fn any_frame_sequence_decodes(frames in proptest::collection::vec((0u16..=0x7FF, proptest::collection::vec(proptest::prelude::any::<u8>(), 0..=8)), 0..64)) {
        let mut d = Decoder::new();
        for (id, data) in frames {
            let _ = d.decode(&f(id, &data));
        }
    }

    #[test]
    fn device_traffic_decodes(frames in proptest::collection::vec((0u16..8, proptest::collection::vec(proptest::prelude::any::<u8>(), 0..=8)), 0..64)) {
        let mut d = Decoder::new();
        for (msg, data) in frames {
            let id = if msg == 0 { 0x3C5 } else { 0x428 | msg };
            let _ = d.decode(&f(id, &data));
        }
    }
}
