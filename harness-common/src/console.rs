//! Where a run of `dnet-master` prints, and what stops it.
//!
//! - Results go to standard output; errors, notices and progress to standard error.
//! - Progress lines ([`Progress`]) are shown only on a terminal and never with `--json`: a line
//!   rewritten in place (`\r`, erase line) that is cleared before anything else is printed.
//! - SIGINT and SIGTERM set the [`Stop`]; the session sees it within
//!   [`STOP_CHECK`](master_core::session::STOP_CHECK), the command ends with what it recorded
//!   flushed and the device released, and the program exits 128 + the signal number (130, 143).

use master_core::stop::Stop;
use std::io::Write;

/// The program's surroundings.
#[derive(Clone, Debug, Default)]
pub struct Console {
    /// Standard output is a terminal: `monitor` refreshes its line in place.
    pub stdout_terminal: bool,
    /// Standard error is a terminal: progress lines are shown there.
    pub stderr_terminal: bool,
    /// Set by SIGINT / SIGTERM.
    pub stop: Stop,
}

impl Console {
    /// No terminal, and a stop only a caller of [`Stop::request`] sets (tests, embedding).
    #[must_use]
    pub fn plain() -> Console {
        Console::default()
    }
}

/// A progress line on a terminal: one line rewritten in place; [`Progress::off`] writes nothing.
pub struct Progress<'w> {
    out: Option<&'w mut dyn Write>,
    shown: bool,
}

impl<'w> Progress<'w> {
    /// Progress on `out` (standard error on a terminal).
    pub fn on(out: &'w mut dyn Write) -> Progress<'w> {
        Progress { out: Some(out), shown: false }
    }

    /// No progress (not a terminal, or `--json`).
    #[must_use]
    pub fn off() -> Progress<'w> {
        Progress { out: None, shown: false }
    }

    /// Whether anything is shown.
    #[must_use]
    pub fn enabled(&self) -> bool {
        self.out.is_some()
    }

    /// Shows `text` in place of the previous progress line.
    pub fn show(&mut self, text: &str) {
        if let Some(out) = &mut self.out {
            // Progress is a courtesy: a terminal that cannot be written loses nothing recorded.
            let _ = write!(out, "\r\x1b[2K{text}");
            let _ = out.flush();
            self.shown = true;
        }
    }

    /// Erases the progress line (before other output).
    pub fn clear(&mut self) {
        if let (Some(out), true) = (&mut self.out, self.shown) {
            let _ = write!(out, "\r\x1b[2K");
            let _ = out.flush();
            self.shown = false;
        }
    }
}

impl Drop for Progress<'_> {
    fn drop(&mut self) {
        self.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_rewrites_one_line_and_clears_it() {
        let mut out = Vec::new();
        {
            let mut p = Progress::on(&mut out);
            p.show("scan: MAC 3");
            p.show("scan: MAC 4");
        }
        assert_eq!(String::from_utf8(out).unwrap(), "\r\x1b[2Kscan: MAC 3\r\x1b[2Kscan: MAC 4\r\x1b[2K");
        let mut off = Progress::off();
        off.show("nothing");
        assert!(!off.enabled());
    }
}
