//! The Modbus RTU codec: requests and responses parsed from arbitrary bytes; what parses is
//! emitted again to the same bytes. The frame-length helpers see every prefix.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slave_fw::serial::modbus::pdu::{request_len, response_len};
use slave_fw::serial::modbus::{Request, Response, ADU_CAPACITY};

fuzz_target!(|data: &[u8]| {
    if let Ok((unit, r)) = Response::parse(data) {
        let mut out = [0u8; ADU_CAPACITY];
        if let Ok(n) = r.emit(unit, &mut out) {
            let (u2, r2) = Response::parse(&out[..n]).expect("an emitted response parses");
            assert_eq!((u2, r2), (unit, r));
        }
    }
    if let Ok((unit, r)) = Request::parse(data) {
        let mut out = [0u8; ADU_CAPACITY];
        if let Ok(n) = r.emit(unit, &mut out) {
            let (u2, r2) = Request::parse(&out[..n]).expect("an emitted request parses");
            assert_eq!((u2, r2), (unit, r));
        }
    }
    for k in 0..=data.len().min(16) {
        let _ = response_len(&data[..k]);
        let _ = request_len(&data[..k]);
    }
});
