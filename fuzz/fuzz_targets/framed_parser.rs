//! The serial frame parser: the breaker's framing, and any framing configuration, fed arbitrary
//! bytes; every frame found re-encodes and parses to the same data.
#![no_main]

use dnet_fuzz::steps::chunks;
use libfuzzer_sys::fuzz_target;
use slave_fw::serial::breaker::FRAMING;
use slave_fw::serial::{Checksum, FrameParser, FramedConfig, LengthField};

const N: usize = 300;

fn config(b: &[u8; 6]) -> FramedConfig {
    let max_len = b[5].max(1);
    FramedConfig {
        start: b[0],
        length: match b[1] % 3 {
            0 => LengthField::Byte,
            1 => LengthField::Fixed(b[2] % max_len.saturating_add(1).max(1)),
            _ => LengthField::Delimited,
        },
        end: (b[1] & 0x80 != 0 || b[1] % 3 == 2).then_some(b[3]),
        checksum: match b[4] % 4 {
            0 => Checksum::None,
            1 => Checksum::Sum8,
            2 => Checksum::Xor8,
            _ => Checksum::Crc16Modbus,
        },
        max_len,
    }
}

fn roundtrip(cfg: FramedConfig, frames: &[Vec<u8>]) {
    for data in frames {
        let mut out = [0u8; N];
        let Ok(n) = cfg.encode(data, &mut out) else { continue };
        let Ok(mut p) = FrameParser::<N>::new(cfg) else { return };
        let mut again = Vec::new();
        p.push_slice(&out[..n], |e| {
            if let Ok(f) = e {
                again.push(f.data().to_vec());
            }
        });
        assert_eq!(again.last(), Some(data), "{cfg:?}: {:02X?}", &out[..n]);
    }
}

fn run(cfg: FramedConfig, input: &[u8]) {
    let Ok(mut parser) = FrameParser::<N>::new(cfg) else { return };
    let mut frames = Vec::new();
    for chunk in chunks(input, 32) {
        parser.push_slice(chunk, |e| {
            if let Ok(f) = e {
                assert!(f.data().len() <= usize::from(cfg.max_len));
                frames.push(f.data().to_vec());
            }
        });
        assert!(parser.buffered() <= N);
    }
    roundtrip(cfg, &frames);
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    if mode & 1 == 0 {
        run(FRAMING, rest);
    } else if let Some((head, rest)) = rest.split_first_chunk::<6>() {
        run(config(head), rest);
    }
});
