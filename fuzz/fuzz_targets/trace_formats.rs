//! Every trace reader (candump, pcap, pcapng, trc, asc, blf, csv), with the format detected and
//! with each format forced: no panic, skipped lines counted, strict mode stops at one of them; what
//! `decode_into` makes of the frames; and what the text writers write is read back alike.
#![no_main]

use can_io::trace::{parse_trace, write::TraceWriter, ReadOptions, TraceFormat};
use libfuzzer_sys::fuzz_target;
use master_core::decode::{Decoded, Decoder};

fuzz_target!(|data: &[u8]| {
    let lenient = parse_trace(data, "fuzz", ReadOptions::default());
    for format in TraceFormat::ALL {
        let options = ReadOptions { strict: false, format: Some(format) };
        let Ok(trace) = parse_trace(data, "fuzz", options) else { continue };
        assert!(trace.skipped.len() <= trace.skipped_count);
        let strict = parse_trace(data, "fuzz", ReadOptions { strict: true, format: Some(format) });
        assert_eq!(strict.is_err(), trace.skipped_count > 0, "strict fails exactly when something was skipped");
        let mut decoder = Decoder::new();
        let mut out = Decoded::default();
        for e in &trace.entries {
            decoder.decode_into(&e.frame, &mut out);
        }
        if format.writable() && !trace.entries.is_empty() {
            let buffer = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
            let sink = Shared(std::sync::Arc::clone(&buffer));
            let mut writer = TraceWriter::new(Box::new(sink), format).expect("a text format");
            for e in &trace.entries {
                writer.write(e.at, &e.iface, e.direction, &e.frame).expect("into memory");
            }
            writer.finish().expect("into memory");
            drop(writer);
            let written = buffer.lock().expect("not poisoned").clone();
            let back = parse_trace(&written, "again", options).expect("what we write reads back");
            let frames = |t: &can_io::trace::Trace| t.entries.iter().map(|e| e.frame).collect::<Vec<_>>();
            assert_eq!(frames(&back), frames(&trace));
        }
    }
    let _ = lenient;
});

/// A `Write` into shared memory (the writer takes a boxed `Write`).
struct Shared(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl std::io::Write for Shared {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().map_err(|_| std::io::Error::other("poisoned"))?.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}
