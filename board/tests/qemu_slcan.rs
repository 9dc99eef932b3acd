//! The emulated firmware answers over SLCAN: `scripts/qemu-firmware` runs the real firmware
//! (feature `emulated`) on QEMU's netduinoplus2, and this test plays the master on the USART1
//! pseudo-terminal, byte for byte against the reference sequence of notes §2.
//!
//! Run it (the check script's "emulated firmware run" stage does):
//!
//! ```sh
//! scripts/qemu-firmware --build-only
//! DNET_QEMU=1 cargo test -p board --test qemu_slcan -- --ignored
//! ```
//!
//! The firmware is built by the script beforehand rather than from inside the test, because a
//! nested `cargo build` would wait for the build-directory lock the running `cargo test` holds.
//!
//! This is the smallest proof that the firmware, its SLCAN driver and QEMU's USART mapping work,
//! and the one that checks the SLCAN adapter's own answers (bit rate while closed, a refused
//! command, the acceptance filter). The end-to-end run, the bench master through all 28 frames
//! with the simulated breaker on USART2, is the system test `tests/tests/qemu_firmware.rs`.

use can_io::slcan::{self, Command};
use devicenet::reference::{Direction, BRING_UP};
use devicenet::CanFrame;
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, Command as Process, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

/// The whole run's bound, also passed to the script as QEMU's time limit.
const RUN_LIMIT: Duration = Duration::from_secs(60);

/// The script and QEMU; stopped (SIGTERM, so the script stops QEMU) on drop, also on panic.
struct Emulator {
    child: Child,
}

impl Drop for Emulator {
    fn drop(&mut self) {
        let _ = Process::new("kill").arg("-TERM").arg(self.child.id().to_string()).status();
        let _ = self.child.wait();
    }
}

/// The host end of the SLCAN link.
struct Link {
    writer: std::fs::File,
    bytes: Receiver<u8>,
    transcript: String,
}

impl Link {
    fn send(&mut self, line: &str) {
        self.transcript.push_str(&format!("> {}\n", line.escape_debug()));
        self.writer.write_all(line.as_bytes()).and_then(|_| self.writer.write_all(b"\r")).expect("write pty");
    }

    /// The next reply: a line up to `\r`, or a lone BEL. `None` after `timeout`.
    fn reply(&mut self, timeout: Duration) -> Option<String> {
        let deadline = Instant::now() + timeout;
        let mut line = String::new();
        loop {
            let left = deadline.checked_duration_since(Instant::now())?;
            let b = self.bytes.recv_timeout(left).ok()?;
            match b {
                b'\r' => break,
                0x07 if line.is_empty() => {
                    line.push('\u{7}');
                    break;
                }
                _ => line.push(char::from(b)),
            }
        }
        self.transcript.push_str(&format!("< {}\n", line.escape_debug()));
        Some(line)
    }

    /// Discards replies until the link has been quiet for `quiet`.
    fn drain(&mut self, quiet: Duration) {
        while self.reply(quiet).is_some() {}
    }

    /// The next frame line (skipping `z` acknowledgements and empty command replies).
    fn frame(&mut self, timeout: Duration) -> Option<CanFrame> {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.checked_duration_since(Instant::now())?;
            let line = self.reply(left)?;
            if line.starts_with('t') {
                match slcan::parse(line.as_bytes()) {
                    Ok(Command::Frame(f)) => return Some(f),
                    other => panic!("bad frame line {line:?}: {other:?}\n{}", self.transcript),
                }
            }
        }
    }
}

fn line_for(frame_index: usize) -> String {
    let f = &BRING_UP[frame_index];
    assert_eq!(f.direction, Direction::MasterToSlave);
    let frame = CanFrame::from_raw(f.id, f.data).unwrap();
    let line = slcan::frame_line(&frame);
    String::from_utf8(line[..line.len() - 1].to_vec()).unwrap()
}

fn expected(frame_index: usize) -> CanFrame {
    let f = &BRING_UP[frame_index];
    assert_eq!(f.direction, Direction::SlaveToMaster);
    CanFrame::from_raw(f.id, f.data).unwrap()
}

#[test]
#[ignore = "runs QEMU: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p board --test qemu_slcan -- --ignored"]
fn emulated_firmware_answers_over_slcan() {
    if std::env::var("DNET_QEMU").as_deref() != Ok("1") {
        eprintln!("DNET_QEMU=1 not set: not running QEMU");
        return;
    }
    // The reference device is MAC 5; the script's default build uses DNET_MAC=5.
    assert!(std::env::var("DNET_MAC").map_or(true, |m| m == "5"), "this test expects DNET_MAC=5");

    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/qemu-firmware");
    let mut child = Process::new(script)
        .args(["--no-build", "--timeout", &RUN_LIMIT.as_secs().to_string()])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start scripts/qemu-firmware");
    let stdout = child.stdout.take().unwrap();
    let _emulator = Emulator { child };

    // USART1=/dev/pts/N from the script.
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let started = Instant::now();
    let usart1 = loop {
        let line = rx.recv_timeout(Duration::from_secs(20)).expect("scripts/qemu-firmware printed no pty");
        if let Some(path) = line.strip_prefix("USART1=") {
            break path.to_string();
        }
    };
    let status = Process::new("stty").args(["-F", &usart1, "raw", "-echo"]).status().expect("stty");
    assert!(status.success(), "stty raw on {usart1}");
    let file = std::fs::OpenOptions::new().read(true).write(true).open(&usart1).expect("open USART1 pty");
    let mut reader = file.try_clone().unwrap();
    let (btx, bytes) = mpsc::channel();
    std::thread::spawn(move || {
        let mut buf = [0u8; 64];
        while let Ok(n) = reader.read(&mut buf) {
            if n == 0 || buf[..n].iter().any(|&b| btx.send(b).is_err()) {
                break;
            }
        }
    });
    let mut link = Link { writer: file, bytes, transcript: String::new() };
    let step = Duration::from_secs(5);

    // Adapter commands: bit rate while closed, a bad command, open. QEMU notices a new pty
    // client with some delay, so the first command is repeated until it is answered.
    let mut answered = false;
    for _ in 0..20 {
        link.send("S5");
        if link.reply(Duration::from_millis(500)).is_some() {
            answered = true;
            break;
        }
    }
    assert!(answered, "no answer on USART1\n{}", link.transcript);
    // Answers to the repeated commands that were already on their way.
    link.drain(Duration::from_millis(500));
    link.send("X");
    assert_eq!(link.reply(step).as_deref(), Some("\u{7}"), "{}", link.transcript);
    link.send("O");
    assert_eq!(link.reply(step).as_deref(), Some(""), "{}", link.transcript);

    // Frames 3-4 of notes §2: the two duplicate MAC ID check requests (held by the closed
    // adapter until it opened, as a mailbox is on a bus with no other node).
    for i in [2, 3] {
        assert_eq!(link.frame(step), Some(expected(i)), "frame {}\n{}", i + 1, link.transcript);
    }

    // Frames 7-8: Allocate explicit through the Group 2 Only port. The node ignores it until it
    // is on-line, 1 s after its second request; ask again until it answers.
    let mut answer = None;
    for _ in 0..20 {
        link.send(&line_for(6));
        answer = link.frame(Duration::from_millis(300));
        if answer.is_some() {
            break;
        }
    }
    assert_eq!(answer, Some(expected(7)), "allocate\n{}", link.transcript);

    // Frames 9-16 over the explicit connection: set the watchdog action, get vendor ID, device
    // type, product code.
    for (request, response) in [(8, 9), (10, 11), (12, 13), (14, 15)] {
        link.send(&line_for(request));
        assert_eq!(link.frame(step), Some(expected(response)), "frame {}\n{}", response + 1, link.transcript);
    }

    // A frame for another node is filtered out: no answer.
    link.send("t4355000E010101");
    assert_eq!(link.frame(Duration::from_millis(500)), None, "{}", link.transcript);

    assert!(started.elapsed() < RUN_LIMIT);
    eprintln!("{}", link.transcript);
}
