//! The `candump -L` log parser and the DeviceNet decoder: what parses is formatted and parsed
//! again to the same frames; every frame is decoded.
#![no_main]

use libfuzzer_sys::fuzz_target;
use master_core::decode::Decoder;
use can_io::log::{format_line, parse_log};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(entries) = parse_log(text, "fuzz") else { return };
    let mut decoder = Decoder::new();
    let mut again = String::new();
    for e in &entries {
        let _ = decoder.decode(&e.frame).text();
        again.push_str(&format_line(e.at, &e.iface, &e.frame));
        again.push('\n');
    }
    let reparsed = parse_log(&again, "again").expect("formatted lines parse");
    assert_eq!(reparsed.len(), entries.len());
    for (a, b) in entries.iter().zip(&reparsed) {
        assert_eq!((a.at, &*a.iface, a.frame), (b.at, &*b.iface, b.frame));
    }
});
