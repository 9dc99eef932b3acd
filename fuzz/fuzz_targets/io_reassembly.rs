//! I/O (unacknowledged) fragmentation: the reassembler fed arbitrary frames, and any data through
//! the fragmenter and the reassembler.
#![no_main]

use devicenet::fragment::{io_fragment_count, io_fragments, IoReassembler};
use dnet_fuzz::steps::chunks;
use libfuzzer_sys::fuzz_target;

const N: usize = 128;

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else { return };
    if mode & 1 == 0 {
        let mut rx = IoReassembler::<N>::new();
        for frame in chunks(rest, 8) {
            if let Ok(Some(whole)) = rx.receive(frame) {
                assert!(whole.len() <= N);
            }
        }
    } else {
        let message = &rest[..rest.len().min(N)];
        let mut rx = IoReassembler::<N>::new();
        let frames: Vec<_> = io_fragments(message).collect();
        assert_eq!(frames.len(), io_fragment_count(message.len()));
        let mut whole = None;
        for f in &frames {
            assert!(f.len() <= 8);
            if let Some(w) = rx.receive(f).expect("own fragments are valid") {
                whole = Some(w.to_vec());
            }
        }
        if !message.is_empty() {
            assert_eq!(whole.as_deref(), Some(message));
        }
    }
});
