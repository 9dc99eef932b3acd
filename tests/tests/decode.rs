//! `decode` on logs with fragmented explicit and I/O messages: fragments reassembled, services,
//! objects and error codes named.

use can_io::bus::Bitrate;
use can_io::log::parse_log;
use master_core::decode::Decoder;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use system_tests::{log_text, mac, sim_bus};

fn session_log(f: impl FnOnce(&mut Master<'_, '_>)) -> String {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    f(&mut Master::new(&mut session, MasterConfig::default()));
    log_text(session.records(), "can0")
}

fn decode_all(text: &str) -> Vec<String> {
    let mut d = Decoder::new();
    parse_log(text, "x").unwrap().iter().map(|e| d.decode(&e.frame).text()).collect()
}

#[test]
fn explicit_and_io_fragments_are_reassembled() {
    let text = session_log(|m| {
        m.connect(&ConnectOptions { polls: 1, ..ConnectOptions::default() }).unwrap();
        m.get(mac(5), 1, 1, 7).unwrap();
        let _ = m.get(mac(5), 1, 1, 42);
    });
    let lines = decode_all(&text);
    let all = lines.join("\n");
    assert!(all.contains("=> reassembled 26 bytes: Get_Attribute_Single response: Identity(1) inst 1 attr 7 (product name) = \"Serial-DeviceNet Bridge\""), "{all}");
    assert!(all.contains("fragment ack #4 status success (0x00)"), "{all}");
    assert!(all.contains("=> poll response from MAC 5, 18 bytes: 00 00 00 00 00 00 00 00 00 0F"), "{all}");
    assert!(
        all.contains(
            "Error_Response: attribute not supported (0x14), additional code 0xFF (no additional code)"
        ),
        "{all}"
    );
    assert!(all.contains("UCMM Open Explicit Messaging Connection request from MAC 0 to MAC 5"), "{all}");
}

#[test]
fn io_fragments_without_the_size_reads() {
    // A log cut after the bring-up: only poll traffic, sizes unknown.
    let text = session_log(|m| {
        m.connect(&ConnectOptions { polls: 2, ..ConnectOptions::default() }).unwrap();
    });
    let polls: String = text
        .lines()
        .filter(|l| l.contains(" 42D#") || l.contains(" 3C5#"))
        .map(|l| format!("{l}\n"))
        .collect();
    let lines = decode_all(&polls);
    assert_eq!(lines.len(), 8);
    assert!(lines[1].contains("size inferred from fragment bytes"), "{}", lines[1]);
    assert!(lines[3].contains("18 bytes"), "{}", lines[3]);
    assert!(lines[7].contains("18 bytes"), "{}", lines[7]);
}

#[test]
fn fragmented_requests_are_reassembled() {
    let text = session_log(|m| {
        m.open_explicit(mac(5)).unwrap();
        m.set(mac(5), 4, 150, 3, &[9, 8, 7, 6, 5, 4, 3, 2]).unwrap();
    });
    let all = decode_all(&text).join("\n");
    assert!(all.contains("reassembled 13 bytes: Set_Attribute_Single Assembly(4) inst 150 attr 3 (data) = 09 08 07 06 05 04 03 02"), "{all}");
}
