//! `dnet-master firmware-update --mac N FILE`: a signed firmware file sent to the device's update
//! object (class 0x6A) and the device watched until it runs it; the work is
//! [`master_core::update::run`]'s, this module shows its progress and its report.
//!
//! Progress goes to standard error: on a terminal one line rewritten in place, otherwise a line
//! every [`LINE_EVERY`] (chunks, bytes, rate, time left); with `--json` none. A stop (Ctrl-C)
//! ends the run with the device released and says where the next run resumes.

use crate::options::{parse_mac, GlobalOptions};
use crate::run::{DeviceRun, Outcome, Ran};
use clap::Args;
use devicenet::MacId;
use harness_common::console::{Console, Progress};
use harness_common::error::HarnessError;
use master_core::update::{self, Event, Report, UpdateError, UpdateFile};
use serde_json::json;
use std::cell::RefCell;
use std::io::Write;
use std::path::PathBuf;
use std::rc::Rc;
use std::time::Instant;

/// How often a progress line is printed when standard error is not a terminal.
pub const LINE_EVERY: std::time::Duration = std::time::Duration::from_secs(2);

/// What `firmware-update` was asked.
#[derive(Args, Clone, Debug)]
pub struct FirmwareUpdateArgs {
    /// Device MAC ID.
    #[arg(long, value_parser = parse_mac)]
    pub mac: MacId,
    /// The signed firmware file (`scripts/sign-firmware` makes it: the flat binary and its
    /// 128-byte trailer).
    pub file: PathBuf,
    /// The release's Ed25519 public key (32 raw bytes): the file's signature is checked with it
    /// before anything is sent. Without it the device's own check at Verify is the only one.
    #[arg(long, value_name = "KEY")]
    pub public_key: Option<PathBuf>,
}

/// Runs `firmware-update`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &FirmwareUpdateArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let file = read_file(args)?;
    let public_key = args.public_key.as_deref().map(read_key).transpose()?;
    let slave = opts.slave_description()?;
    let run = DeviceRun::new(opts, Some(args.mac), slave.as_ref())?;
    // Standard error, shared by the run (its progress line, its report) and this command's
    // progress lines, which it prints while the run holds the writer.
    let shared = Shared(Rc::new(RefCell::new(err)));
    let mut lines = shared.clone();
    let mut run_err = shared;
    let json_mode = opts.json;
    run.run(out, &mut run_err, console, |master, progress, _| {
        let mut shown = Shown::new(args.mac, file.chunks(), file.image_len(), json_mode);
        let result = update::run(master, args.mac, &file, public_key.as_ref(), &mut |event| {
            shown.event(event, progress, &mut lines);
        });
        progress.clear();
        finish(args, &file, result, &shown)
    })
}

/// The file read and taken apart.
fn read_file(args: &FirmwareUpdateArgs) -> Result<UpdateFile, HarnessError> {
    let name = args.file.display().to_string();
    let bytes = std::fs::read(&args.file).map_err(|e| HarnessError::Read {
        path: name.clone(),
        what: "firmware file",
        error: e,
    })?;
    UpdateFile::parse(&name, bytes)
        .map_err(|source| HarnessError::Update(Box::new(UpdateError::File { file: name, source })))
}

/// `--public-key`: 32 raw bytes.
fn read_key(path: &std::path::Path) -> Result<[u8; 32], HarnessError> {
    let bytes = std::fs::read(path).map_err(|e| HarnessError::Read {
        path: path.display().to_string(),
        what: "public key",
        error: e,
    })?;
    <[u8; 32]>::try_from(bytes.as_slice()).map_err(|_| HarnessError::InvalidValue {
        option: "--public-key",
        value: path.display().to_string(),
        expected: "a file of the 32 raw bytes of an Ed25519 public key",
    })
}

/// The run's end: the report, or the error with where a next run resumes.
fn finish(
    args: &FirmwareUpdateArgs,
    file: &UpdateFile,
    result: Result<Report, UpdateError>,
    shown: &Shown,
) -> Ran {
    match result {
        Ok(report) => Ran::from(Ok(report_outcome(args, file, &report, shown))),
        Err(e) => {
            // Once applied, the device runs (or swaps in) the new image: nothing to resume.
            let at = shown.next_chunk.filter(|_| !shown.applied);
            let partial = at.filter(|&n| n > 0).map(|n| Outcome {
                text: format!(
                    "MAC {}: {n} of {} chunks are at the device; run the same command again to resume at chunk {n}",
                    args.mac,
                    file.chunks()
                ),
                json: json!({ "resume_at": n, "chunks": file.chunks() }),
                code: 1,
            });
            let error = match e {
                UpdateError::Master(m) => HarnessError::Master(m),
                other => HarnessError::Update(Box::new(other)),
            };
            Ran { result: Err(error), partial, cleanup: Vec::new() }
        }
    }
}

/// The final report.
fn report_outcome(args: &FirmwareUpdateArgs, file: &UpdateFile, r: &Report, shown: &Shown) -> Outcome {
    let seconds = shown.started.elapsed().as_secs_f64();
    let resumed = if r.resumed_at > 0 {
        format!("resumed at chunk {} of {}", r.resumed_at, r.chunks)
    } else {
        format!("{} chunks", r.chunks)
    };
    let text = format!(
        "MAC {mac}: firmware {old} -> {new}: {outcome}\n\
         {file}: {bytes} bytes, {resumed}, {sent} sent in this run, {resent} resent; {seconds:.1} s \
         (back on-line {back:.1} s after Apply)\n\
         Identity revision {ident}, update object state {state}",
        mac = args.mac,
        old = r.before.revision,
        new = r.revision,
        outcome = r.outcome,
        file = file.name,
        bytes = file.image_len(),
        sent = r.sent,
        resent = r.resent,
        back = r.back_after.total_millis() as f64 / 1000.0,
        ident = r.identity_revision,
        state = r.state,
    );
    let json = json!({
        "firmware_update": {
            "mac": args.mac.as_raw(),
            "file": file.name,
            "bytes": file.image_len(),
            "revision_before": r.before.revision.to_string(),
            "revision": r.revision.to_string(),
            "identity_revision": r.identity_revision.to_string(),
            "outcome": match r.outcome {
                update::Outcome::Confirmed => "confirmed",
                update::Outcome::Trial => "trial",
                update::Outcome::RolledBack => "rolled back",
            },
            "state": r.state.to_string(),
            "chunks": r.chunks,
            "resumed_at": r.resumed_at,
            "sent": r.sent,
            "resent": r.resent,
            "seconds": seconds,
            "back_after_ms": r.back_after.total_millis(),
        }
    });
    let code = match r.outcome {
        update::Outcome::Confirmed => 0,
        update::Outcome::Trial | update::Outcome::RolledBack => 1,
    };
    Outcome { text, json, code }
}

/// Standard error shared between the run and the progress lines.
#[derive(Clone)]
struct Shared<'w>(Rc<RefCell<&'w mut dyn Write>>);

impl Write for Shared<'_> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.0.borrow_mut().flush()
    }
}

/// What the progress display knows.
struct Shown {
    mac: MacId,
    chunks: u32,
    total: u32,
    json: bool,
    started: Instant,
    /// When the first chunk of this run went out, and the bytes at the device then.
    transfer_from: Option<(Instant, u64)>,
    last_line: Option<Instant>,
    /// The next chunk the device expects, as far as this run knows.
    next_chunk: Option<u32>,
    /// Apply was answered.
    applied: bool,
}

impl Shown {
    fn new(mac: MacId, chunks: u32, total: u32, json: bool) -> Shown {
        Shown {
            mac,
            chunks,
            total,
            json,
            started: Instant::now(),
            transfer_from: None,
            last_line: None,
            next_chunk: None,
            applied: false,
        }
    }

    /// Shows `event`: on the terminal's progress line, else as a line now and then.
    fn event(&mut self, event: Event, progress: &mut Progress<'_>, lines: &mut dyn Write) {
        let text = match event {
            Event::Checked => None,
            Event::Announced { next, chunks } => {
                self.next_chunk = Some(next);
                self.transfer_from = Some((Instant::now(), u64::from(next) * update::CHUNK_SIZE as u64));
                let line = if next > 0 {
                    format!("MAC {}: resuming at chunk {next} of {chunks} (the device holds the chunks before it)", self.mac)
                } else {
                    format!("MAC {}: sending {chunks} chunks ({} bytes)", self.mac, self.total)
                };
                self.say(&line, progress, lines);
                None
            }
            Event::Chunk { chunk, bytes, .. } => {
                self.next_chunk = Some(chunk + 1);
                Some(self.chunk_text(chunk + 1, bytes))
            }
            Event::Resent { chunk } => {
                self.say(&format!("MAC {}: chunk {chunk} unanswered, sent again", self.mac), progress, lines);
                None
            }
            Event::Verified => Some(format!("MAC {}: signature verified by the device; applying", self.mac)),
            Event::Applied => {
                self.applied = true;
                Some(format!("MAC {}: applied; waiting for the device to come back", self.mac))
            }
            Event::Back => Some(format!("MAC {}: back on-line; reading its revision", self.mac)),
        };
        let Some(text) = text else { return };
        if progress.enabled() {
            progress.show(&text);
            return;
        }
        let due = self.last_line.is_none_or(|t| t.elapsed() >= LINE_EVERY);
        let milestone = !matches!(event, Event::Chunk { .. });
        if !self.json && (due || milestone) {
            let _ = writeln!(lines, "{text}");
            self.last_line = Some(Instant::now());
        }
    }

    /// A line that stays: printed above the progress line.
    fn say(&self, line: &str, progress: &mut Progress<'_>, lines: &mut dyn Write) {
        if self.json {
            return;
        }
        progress.clear();
        let _ = writeln!(lines, "{line}");
    }

    /// `[#####.....] 40/368 chunks, 5120/47080 bytes, 3.1 KiB/s, 12 s left`.
    fn chunk_text(&self, done: u32, bytes: u64) -> String {
        let width = 20u64;
        let filled =
            (u64::from(done) * width).checked_div(u64::from(self.chunks)).unwrap_or(width).min(width);
        let bar: String = (0..width).map(|i| if i < filled { '#' } else { '.' }).collect();
        let (rate, left) = match self.transfer_from {
            Some((from, at_start)) if bytes > at_start => {
                let secs = from.elapsed().as_secs_f64().max(1e-3);
                let rate = (bytes - at_start) as f64 / secs;
                let left = (u64::from(self.total).saturating_sub(bytes)) as f64 / rate;
                (format!("{:.1} KiB/s", rate / 1024.0), format!("{left:.0} s left"))
            }
            _ => ("-".to_string(), "-".to_string()),
        };
        format!(
            "MAC {}: [{bar}] {done}/{} chunks, {bytes}/{} bytes, {rate}, {left}",
            self.mac, self.chunks, self.total
        )
    }
}
