//! The `candump -L` reader of [`super::read_trace`]: the line grammar is [`crate::log`]'s.
//!
//! Skipped (counted, named): error frames (identifier with `CAN_ERR_FLAG`, 8 hex digits `2xxxxxxx`),
//! extended, remote and FD frames, lines that are not log lines, and a half-written last line (a last line
//! with no newline that does not parse). Comments (`#`) and blank lines are not frames and not counted.

use super::Sink;
use crate::log::{parse_line, LogError};

/// Reads `candump -L` lines into `sink`.
pub fn read(bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    let complete = bytes.last().is_none_or(|&b| b == b'\n');
    let mut lines = bytes.split(|&b| b == b'\n').peekable();
    let mut number = 0;
    while let Some(raw) = lines.next() {
        number += 1;
        let last = lines.peek().is_none();
        if last && raw.is_empty() {
            break;
        }
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let line = match std::str::from_utf8(raw) {
            Ok(line) => line,
            Err(_) => {
                let text = String::from_utf8_lossy(raw);
                sink.skip(number, 1, "the line is not UTF-8 text", &text)?;
                continue;
            }
        };
        let trimmed = line.trim_start();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        match parse_line(line, number) {
            Ok(entry) => sink.frame(entry),
            // A last line cut off by an interrupted recording: it has no newline.
            Err((column, reason)) if last && !complete => {
                sink.skip(number, column, format!("half-written last line: {reason}"), line)?
            }
            Err((column, reason)) => sink.skip(number, column, reason, line)?,
        }
    }
    Ok(())
}
