//! The configuration image decoder (`slave_fw::image::decode`): arbitrary bytes never panic; what
//! decodes passes the configuration check and encodes again to the same bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slave_fw::image::{decode, encode, MAX_IMAGE};

fuzz_target!(|data: &[u8]| {
    if let Ok(config) = decode(data) {
        assert_eq!(config.check(), Ok(()));
        let mut out = [0u8; MAX_IMAGE];
        let n = encode(&config, &mut out).expect("a decoded configuration encodes");
        assert_eq!(decode(&out[..n]), Ok(config));
    }
});
