//! The emulated firmware answers over SLCAN: `scripts/qemu-firmware` runs the real firmware
//! (feature `emulated`) on QEMU's netduinoplus2, and this test plays the master on the USART1
//! pseudo-terminal, byte for byte against the reference sequence of protocol §2.
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

/// QEMU runs one at a time: the script's log and pty files are shared.
static QEMU: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Whether the QEMU tests are enabled (`DNET_QEMU=1`).
fn qemu_enabled() -> bool {
    if std::env::var("DNET_QEMU").as_deref() != Ok("1") {
        eprintln!("DNET_QEMU=1 not set: not running QEMU");
        return false;
    }
    // The reference device is MAC 5; the script's default build uses DNET_MAC=5.
    assert!(std::env::var("DNET_MAC").map_or(true, |m| m == "5"), "this test expects DNET_MAC=5");
    true
}

/// Boots the emulated firmware (its settings flash in `flash_dir`, kept, or a new one) and opens
/// the SLCAN link on USART1, once the firmware answers.
fn boot(flash_dir: Option<&std::path::Path>) -> (Emulator, Link) {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/../scripts/qemu-firmware");
    let mut args = vec!["--no-build".to_string(), "--timeout".into(), RUN_LIMIT.as_secs().to_string()];
    if let Some(dir) = flash_dir {
        args.extend(["--flash-dir".to_string(), dir.display().to_string()]);
    }
    let mut child =
        Process::new(script).args(&args).stdout(Stdio::piped()).spawn().expect("start scripts/qemu-firmware");
    let stdout = child.stdout.take().unwrap();
    let emulator = Emulator { child };

    // USART1=/dev/pts/N from the script.
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
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

    // QEMU notices a new pty client with some delay, so the first command is repeated until it
    // is answered.
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
    (emulator, link)
}

/// Opens the adapter, sees the duplicate MAC ID checks and allocates the explicit connection
/// (frames 3-8 of protocol §2).
fn bring_up_explicit(link: &mut Link, step: Duration) {
    link.send("O");
    assert_eq!(link.reply(step).as_deref(), Some(""), "{}", link.transcript);

    // Frames 3-4 of protocol §2: the two duplicate MAC ID check requests (held by the closed
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
}

#[test]
#[ignore = "runs QEMU: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p board --test qemu_slcan -- --ignored"]
fn emulated_firmware_answers_over_slcan() {
    if !qemu_enabled() {
        return;
    }
    let _one_at_a_time = QEMU.lock().unwrap_or_else(|e| e.into_inner());
    let started = Instant::now();
    let (_emulator, mut link) = boot(None);
    let step = Duration::from_secs(5);

    // Adapter commands: a bad command is refused.
    link.send("X");
    assert_eq!(link.reply(step).as_deref(), Some("\u{7}"), "{}", link.transcript);
    bring_up_explicit(&mut link, step);

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

/// The emulated board's settings flash is a host file: a setting made over the network is still
/// in force after QEMU stops and starts again on the same file, as after a power cycle.
#[test]
#[ignore = "runs QEMU: scripts/qemu-firmware --build-only && DNET_QEMU=1 cargo test -p board --test qemu_slcan -- --ignored"]
fn settings_survive_a_qemu_restart() {
    if !qemu_enabled() {
        return;
    }
    let _one_at_a_time = QEMU.lock().unwrap_or_else(|e| e.into_inner());
    let flash_dir = std::env::temp_dir().join(format!("dnet-qemu-flash-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&flash_dir);
    std::fs::create_dir_all(&flash_dir).unwrap();
    let step = Duration::from_secs(5);
    // Explicit requests from the master (MAC 0) to MAC 5 (Group 2 message 4) and the answers
    // (message 3); DeviceNet object, instance 1, attribute 3: bus-off interrupt (protocol §7.2).
    let request = |data: &[u8]| {
        let line = slcan::frame_line(&CanFrame::from_raw(0x42C, data).unwrap());
        String::from_utf8(line[..line.len() - 1].to_vec()).unwrap()
    };
    let answer = |data: &[u8]| CanFrame::from_raw(0x42B, data).unwrap();
    let get_boi = request(&[0x00, 0x0E, 0x03, 0x01, 0x03]);

    {
        let (_emulator, mut link) = boot(Some(&flash_dir));
        bring_up_explicit(&mut link, step);
        link.send(&get_boi);
        assert_eq!(link.frame(step), Some(answer(&[0x00, 0x8E, 0x00])), "new board\n{}", link.transcript);
        link.send(&request(&[0x00, 0x10, 0x03, 0x01, 0x03, 0x01]));
        assert_eq!(link.frame(step), Some(answer(&[0x00, 0x90])), "set\n{}", link.transcript);
        // The firmware stores the setting before it answers the next request.
        link.send(&get_boi);
        assert_eq!(link.frame(step), Some(answer(&[0x00, 0x8E, 0x01])), "after set\n{}", link.transcript);
    }

    let (_emulator, mut link) = boot(Some(&flash_dir));
    bring_up_explicit(&mut link, step);
    link.send(&get_boi);
    assert_eq!(link.frame(step), Some(answer(&[0x00, 0x8E, 0x01])), "after restart\n{}", link.transcript);
    drop(link);
    let _ = std::fs::remove_dir_all(&flash_dir);
}
