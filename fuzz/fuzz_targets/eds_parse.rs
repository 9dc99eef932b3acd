//! The EDS parser and checker fed arbitrary bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(eds) = eds::parse(data) {
        let _ = eds::Summary::of(&eds);
    }
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = eds::check_str(text);
    }
});
