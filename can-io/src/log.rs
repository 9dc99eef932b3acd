//! can-utils `candump -L` log lines: `(seconds.micros) iface ID#DATA`, written by `--log` and read
//! by `replay` and `decode`.
//!
//! The entries, their errors and the line grammar live in [`crate::trace`] with the other trace
//! formats (re-exported here); this module adds [`LogWriter`], which writes a trace in any
//! writable format as frames are seen.

pub use crate::trace::entry::{format_line, parse_frame, parse_log, read_log, LogEntry, LogError};
use crate::trace::write::TraceWriter;
use crate::trace::{Direction, TraceFormat};
use devicenet::{CanFrame, Instant};
use std::fmt;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Writes a trace file as frames are seen: `candump -L` lines ([`LogWriter::create`]) or any
/// writable text format ([`LogWriter::create_as`]), through a buffer that [`LogWriter::flush`]
/// empties (see [`crate::trace::write`]).
pub struct LogWriter {
    out: TraceWriter,
    path: PathBuf,
}

impl fmt::Debug for LogWriter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LogWriter").field("path", &self.path).field("format", &self.out.format()).finish()
    }
}

impl LogWriter {
    /// Creates (truncates) `path`, a `candump -L` log.
    pub fn create(path: &Path) -> io::Result<LogWriter> {
        LogWriter::create_as(path, TraceFormat::Candump)
    }

    /// Creates (truncates) `path`, a trace in `format` (its header written); an error for a format
    /// that is not written.
    pub fn create_as(path: &Path, format: TraceFormat) -> io::Result<LogWriter> {
        if !format.writable() {
            // Checked before the file is created, so that no empty file is left behind.
            return Err(crate::trace::write::not_written(format));
        }
        let file = std::fs::File::create(path)?;
        Ok(LogWriter { out: TraceWriter::new(Box::new(file), format)?, path: path.to_path_buf() })
    }

    /// A `candump -L` writer into any sink (tests).
    pub fn from_writer(out: Box<dyn Write>) -> LogWriter {
        LogWriter { out: TraceWriter::candump(out), path: PathBuf::from("<memory>") }
    }

    /// Appends one frame, its direction unknown.
    pub fn write(&mut self, at: Instant, iface: &str, frame: &CanFrame) -> io::Result<()> {
        self.out.write(at, iface, None, frame)
    }

    /// Appends one frame with the direction it travelled (kept by trc and asc).
    pub fn write_dir(
        &mut self,
        at: Instant,
        iface: &str,
        direction: Direction,
        frame: &CanFrame,
    ) -> io::Result<()> {
        self.out.write(at, iface, Some(direction), frame)
    }

    /// Flushes to the file.
    pub fn flush(&mut self) -> io::Result<()> {
        self.out.flush()
    }

    /// Writes the format's footer and flushes (also done when the writer is dropped).
    pub fn finish(&mut self) -> io::Result<()> {
        self.out.finish()
    }
}
