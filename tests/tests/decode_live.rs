//! Live decode: `decode -` decodes each line as it arrives (the output of a frame is there before
//! the next line is read, and before the end of the input), and `decode --bus slcan:PATH` decodes
//! a live bus, where another master talks to the soft slave, without ever transmitting: the
//! adapter it opened was set up listen-only (`L`, never `O`) and received no transmit command.
//!
//! The live bus is three SLCAN ports joined by [`Hub`], a test CAN bus on socat ptys: what one port
//! transmits reaches the others; set-up commands are answered as an adapter does and recorded
//! per port.

use harness_common::console::Console;
use master_harness::commands::decode::{stream_stdin, DecodeArgs, Printer};
use master_harness::options::TraceInput;
use pty_rig::{require_socat, Proc, PtyPair, PtyRig};
use std::cell::RefCell;
use std::io::{BufRead, Read, Write};
use std::rc::Rc;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// A candump -L exchange: a duplicate MAC ID check, an Allocate and its answer, an error response.
const LINES: [&str; 5] = [
    "(1.000000) can0 42F#00341278563412\n",
    "(1.100000) can0 42E#004B03010100\n",
    "(1.100300) can0 42B#00CB00\n",
    "(1.200000) can0 42C#000E010163\n",
    "(1.200300) can0 42B#00940914\n",
];

/// Output shared between the writer given to `decode` and the reader that feeds it.
#[derive(Clone, Default)]
struct Shared(Rc<RefCell<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.borrow_mut().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Shared {
    fn frame_lines(&self) -> usize {
        String::from_utf8_lossy(&self.0.borrow()).lines().filter(|l| l.starts_with('(')).count()
    }
}

/// Gives one line at a time; before each line after the first it notes how many frames were
/// already printed.
struct Incremental {
    lines: Vec<&'static [u8]>,
    next: usize,
    at: usize,
    out: Shared,
    printed_before: Vec<usize>,
}

impl Incremental {
    /// `LINES`, none read yet, with decode's output going to `out`.
    fn new(out: &Shared) -> Incremental {
        Incremental {
            lines: LINES.iter().map(|l| l.as_bytes()).collect(),
            next: 0,
            at: 0,
            out: out.clone(),
            printed_before: vec![],
        }
    }
}

impl Read for Incremental {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = {
            let b = self.fill_buf()?;
            let n = b.len().min(buf.len());
            buf[..n].copy_from_slice(&b[..n]);
            n
        };
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for Incremental {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        if self.next > 0 && self.at >= self.lines[self.next - 1].len() && self.next < self.lines.len() {
            // The previous line is used up: what did decode print of it before asking for more?
            self.printed_before.push(self.out.frame_lines());
        }
        if self.next == 0 || (self.at >= self.lines[self.next - 1].len() && self.next < self.lines.len()) {
            self.next += 1;
            self.at = 0;
        }
        let line = self.lines[self.next - 1];
        Ok(&line[self.at.min(line.len())..])
    }
    fn consume(&mut self, n: usize) {
        self.at += n;
    }
}

fn args(triggers: &[&str]) -> DecodeArgs {
    DecodeArgs {
        logfile: Some("-".into()),
        input: TraceInput::default(),
        macs: vec![],
        groups: vec![],
        kinds: vec![],
        triggers: triggers.iter().map(|t| t.parse().unwrap()).collect(),
        duration: None,
    }
}

#[test]
fn standard_input_is_decoded_line_by_line() {
    let out = Shared::default();
    let mut input = Incremental::new(&out);
    let a = args(&[]);
    let mut printer = Printer::new(false, a.filter(), a.triggers.clone());
    let mut err = Vec::new();
    let code =
        stream_stdin(&mut input, &a, &mut printer, &mut out.clone(), &mut err, &Console::plain()).unwrap();
    assert_eq!(code, 0);
    // Before line k+1 was read, k frames were on the output.
    assert_eq!(input.printed_before, vec![1, 2, 3, 4]);
    let text = String::from_utf8_lossy(&out.0.borrow()).into_owned();
    assert!(text.contains("duplicate MAC ID check"), "{text}");
    assert!(text.contains("Allocate_Master/Slave_Connection_Set"), "{text}");
}

#[test]
fn a_trigger_stops_reading() {
    let out = Shared::default();
    let mut input = Incremental::new(&out);
    let a = args(&["mac=5,kind=explicit-response"]);
    let mut printer = Printer::new(false, a.filter(), a.triggers.clone());
    let code =
        stream_stdin(&mut input, &a, &mut printer, &mut out.clone(), &mut Vec::new(), &Console::plain())
            .unwrap();
    assert_eq!(code, 0);
    let text = String::from_utf8_lossy(&out.0.borrow()).into_owned();
    assert!(text.contains("trigger mac=5,kind=explicit-response matched at line 3: stopped"), "{text}");
    assert_eq!(input.next, 3, "nothing read after the trigger's line");
    // A trigger that never matches: exit 1, said on standard error.
    let a = args(&["mac=9"]);
    let mut printer = Printer::new(false, a.filter(), a.triggers.clone());
    let mut input = Incremental::new(&out);
    let mut err = Vec::new();
    let code =
        stream_stdin(&mut input, &a, &mut printer, &mut out.clone(), &mut err, &Console::plain()).unwrap();
    assert_eq!(code, 1);
    assert!(String::from_utf8_lossy(&err).contains("no frame matched the trigger (mac=9) in 5 frame(s)"));
}

#[test]
#[ignore = "needs the built dnet-master: run by scripts/check"]
fn the_program_prints_before_the_end_of_its_input() {
    let mut child = std::process::Command::new(pty_rig::bin("dnet-master"))
        .args(["decode", "-"])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let stdout = child.stdout.take().unwrap();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    stdin.write_all(LINES[0].as_bytes()).unwrap();
    stdin.flush().unwrap();
    let first =
        rx.recv_timeout(Duration::from_secs(10)).expect("the first frame decoded while the input is open");
    assert!(first.contains("duplicate MAC ID check request for MAC 5"), "{first}");
    for l in &LINES[1..] {
        stdin.write_all(l.as_bytes()).unwrap();
    }
    drop(stdin);
    assert!(child.wait().unwrap().success());
}

/// What one port of the hub received from its host.
#[derive(Clone, Default)]
struct Received(Arc<Mutex<Vec<String>>>);

/// A CAN bus of SLCAN ports on pty pairs: frames one port transmits (`t...`) reach every other
/// port; set-up commands are answered (`\r`, `F00\r`) and recorded. Port 0 is the soft slave's
/// end of the rig's link (it answers its far end's set-up itself: nothing is answered to it).
struct Hub {
    received: Vec<Received>,
}

impl Hub {
    fn start(ports: Vec<(String, bool)>) -> Hub {
        let files: Vec<std::fs::File> = ports
            .iter()
            .map(|(p, _)| std::fs::OpenOptions::new().read(true).write(true).open(p).unwrap())
            .collect();
        let writers: Arc<Mutex<Vec<std::fs::File>>> =
            Arc::new(Mutex::new(files.iter().map(|f| f.try_clone().unwrap()).collect()));
        let received: Vec<Received> = ports.iter().map(|_| Received::default()).collect();
        for (i, mut file) in files.into_iter().enumerate() {
            let writers = Arc::clone(&writers);
            let seen = received[i].clone();
            let answers = ports[i].1;
            std::thread::spawn(move || {
                let mut line = Vec::new();
                let mut buf = [0u8; 256];
                while let Ok(n) = file.read(&mut buf) {
                    if n == 0 {
                        break;
                    }
                    for &b in &buf[..n] {
                        if b != b'\r' {
                            line.push(b);
                            continue;
                        }
                        let text = String::from_utf8_lossy(&line).into_owned();
                        line.clear();
                        seen.0.lock().unwrap().push(text.clone());
                        let mut w = writers.lock().unwrap();
                        if text.starts_with('t') {
                            for (j, other) in w.iter_mut().enumerate() {
                                if j != i {
                                    let _ = other.write_all(format!("{text}\r").as_bytes());
                                }
                            }
                        } else if answers {
                            let answer: &[u8] = if text == "F" { b"F00\r" } else { b"\r" };
                            let _ = w[i].write_all(answer);
                        }
                    }
                }
            });
        }
        Hub { received }
    }
}

#[test]
#[ignore = "needs socat and the built programs: run by scripts/check"]
fn a_live_slcan_bus_is_decoded_without_transmitting() {
    if !require_socat() {
        return;
    }
    let rig = PtyRig::breaker("decode-live", &["--period", "0.3"], None);
    let master = PtyPair::new();
    let decoder = PtyPair::new();
    let hub =
        Hub::start(vec![(rig.can.b.clone(), false), (master.a.clone(), true), (decoder.a.clone(), true)]);
    let bus = format!("slcan:{}", decoder.b);
    let listening = Proc::spawn(
        pty_rig::bin("dnet-master"),
        &[
            "--bus",
            &bus,
            "decode",
            "--kind",
            "explicit",
            "--trigger",
            "mac=5,kind=explicit-response,data=008E/00FF",
        ],
    );
    // Listening before the master starts.
    let end = std::time::Instant::now() + Duration::from_secs(10);
    while !listening.stderr.text().contains("listen-only") && std::time::Instant::now() < end {
        std::thread::sleep(Duration::from_millis(20));
    }
    let talking = format!("slcan:{}", master.b);
    let mut other =
        Proc::spawn(pty_rig::bin("dnet-master"), &["--bus", &talking, "scan", "--from", "4", "--to", "6"]);
    let status = other.wait(Duration::from_secs(60)).expect("the scan ends");
    assert!(status.success(), "{}\n{}", other.dump(), rig.dump());
    let mut listening = listening;
    let decoded = listening.wait(Duration::from_secs(20)).unwrap_or_else(|| panic!("{}", listening.dump()));
    let text = listening.stdout.text();
    assert_eq!(decoded.code(), Some(0), "the trigger matched\n{text}\n{}", listening.dump());
    assert!(text.contains("Allocate_Master/Slave_Connection_Set"), "{text}");
    assert!(text.contains("Get_Attribute_Single response: Identity(1) inst 1 attr"), "{text}");
    assert!(text.contains("trigger mac=5,kind=explicit-response,data=008E/00FF matched"), "{text}");
    assert!(!text.contains("poll response"), "--kind explicit shows no I/O\n{text}");
    // The decoder's adapter: set up listen-only, never opened, never asked to transmit.
    let commands = hub.received[2].0.lock().unwrap().clone();
    assert!(commands.contains(&"L".to_string()), "{commands:?}");
    assert!(!commands.iter().any(|c| c == "O" || c.starts_with(['t', 'T', 'r', 'R'])), "{commands:?}");
    // The master did transmit through the hub: the check can fail.
    assert!(hub.received[1].0.lock().unwrap().iter().any(|c| c.starts_with('t')));
    let _ = std::fs::remove_dir_all(&rig.dir);
}
