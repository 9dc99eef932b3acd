//! A stand-in scanner for the console's tests: it feeds a [`Shared`] the way the scanner's loop
//! does (state after each cycle, frames, samples, answers to commands) with two simulated breakers
//! at MAC 5 (input assembly 100, 18 bytes) and MAC 6 (assembly 101, 20 bytes with the status
//! byte and the freshness counter), and an in-memory history.
#![allow(dead_code)]

use devicenet::{CanFrame, CanId};
use dnet_scanner::model::{
    unix_ms_now, ConsoleCommand, FrameRow, HistoryStore, Identity, NodeState, NodeStatus, Sample,
    ScannerState, ScannerStatus, Shared,
};
use master_core::decode::Decoder;
use std::collections::VecDeque;
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Samples in memory, as the SQLite history will keep them.
#[derive(Default)]
pub struct MemHistory(pub Mutex<Vec<Sample>>);

impl HistoryStore for MemHistory {
    fn samples(&self, mac: u8, from_ms: i64, to_ms: i64, limit: usize) -> Result<Vec<Sample>, String> {
        let all = self.0.lock().map_err(|_| "poisoned".to_string())?;
        let v: Vec<Sample> =
            all.iter().filter(|s| s.mac == mac && (from_ms..=to_ms).contains(&s.unix_ms)).cloned().collect();
        Ok(v[v.len().saturating_sub(limit)..].to_vec())
    }

    fn export_csv(
        &self,
        mac: Option<u8>,
        from_ms: i64,
        to_ms: i64,
        out: &mut dyn Write,
    ) -> Result<usize, String> {
        let all = self.0.lock().map_err(|_| "poisoned".to_string())?;
        let rows: Vec<&Sample> = all
            .iter()
            .filter(|s| mac.is_none_or(|m| s.mac == m) && (from_ms..=to_ms).contains(&s.unix_ms))
            .collect();
        let names: Vec<String> =
            rows.first().map(|s| s.values.iter().map(|(n, _)| n.clone()).collect()).unwrap_or_default();
        let e = |e: std::io::Error| e.to_string();
        writeln!(out, "unix_ms,time,mac,input_hex,{}", names.join(",")).map_err(e)?;
        for s in &rows {
            let values: Vec<String> =
                s.values.iter().map(|(n, v)| dnet_scanner::history::csv_value(n, *v)).collect();
            let input: String = s.input.iter().map(|b| format!("{b:02X}")).collect();
            writeln!(out, "{},{},{},{},{}", s.unix_ms, s.unix_ms / 1000, s.mac, input, values.join(","))
                .map_err(e)?;
        }
        Ok(rows.len())
    }
}

/// One simulated breaker.
struct Breaker {
    mac: u8,
    with_status: bool,
    closed: bool,
    params: [u16; 4],
    output: Vec<u8>,
    last_command: (u8, u8),
    outcome: u8,
    freshness: u8,
    exchanges: u64,
}

impl Breaker {
    fn new(mac: u8, with_status: bool) -> Breaker {
        Breaker {
            mac,
            with_status,
            closed: false,
            params: [100, 200, 300, 400],
            output: vec![0; 8],
            last_command: (0, 0),
            outcome: 0,
            freshness: 0,
            exchanges: 0,
        }
    }

    fn input_size(&self) -> u16 {
        if self.with_status {
            20
        } else {
            18
        }
    }

    /// The guide's command rule (docs/src/plant/console.md): executed when the code or the sequence changes.
    fn apply_output(&mut self) {
        let (code, seq) = (self.output[0], self.output[1]);
        if (code, seq) == self.last_command {
            return;
        }
        self.last_command = (code, seq);
        self.outcome = match code {
            0 => 0,
            1 => {
                self.closed = false;
                2
            }
            2 => {
                self.closed = true;
                2
            }
            3 => match self.params.get_mut(usize::from(self.output[2])) {
                Some(p) => {
                    *p = u16::from_le_bytes([self.output[3], self.output[4]]);
                    2
                }
                None => 3,
            },
            _ => 5,
        };
    }

    fn currents(&self, tick: u64) -> [u8; 4] {
        if !self.closed {
            return [0; 4];
        }
        let wobble = |k: u64| ((tick / 3 + k * 7) % 9) as u8;
        [118 + wobble(0), 121 + wobble(1), 116 + wobble(2), 4 + wobble(3) / 3]
    }

    fn input(&self, tick: u64) -> Vec<u8> {
        let mut v = vec![0u8; 18];
        v[..4].copy_from_slice(&self.currents(tick));
        v[9] = if self.closed { 0xF0 } else { 0x0F };
        for (i, p) in self.params.iter().enumerate() {
            v[10 + 2 * i..12 + 2 * i].copy_from_slice(&p.to_le_bytes());
        }
        if self.with_status {
            v.push(0x01 | (self.outcome << 4));
            v.push(self.freshness);
        }
        v
    }

    fn values(&self, input: &[u8]) -> Vec<(String, f64)> {
        let mut v: Vec<(String, f64)> = ["phase_a", "phase_b", "phase_c", "neutral"]
            .iter()
            .zip(input)
            .map(|(n, b)| ((*n).to_string(), f64::from(*b)))
            .collect();
        v.push(("switch".into(), f64::from(input[9])));
        v
    }

    fn state(&self, input: Vec<u8>) -> NodeState {
        NodeState {
            mac: self.mac,
            // The scan list names MAC 5 only: MAC 6 shows its product name alone.
            name: (self.mac == 5).then(|| "feeder 1".to_string()),
            connection: "poll".into(),
            ack_suppression: false,
            status: NodeStatus::Ok,
            code: 0,
            detail: None,
            identity: Identity {
                vendor_id: Some(0x1234),
                device_type: Some(0x000C),
                product_code: Some(1),
                revision: Some("1.1".into()),
                serial_number: Some(0x1234_5678 + u32::from(self.mac)),
                product_name: Some("Serial-DeviceNet Bridge".into()),
            },
            input_size: Some(self.input_size()),
            output_size: Some(8),
            input,
            output: self.output.clone(),
            exchanges: self.exchanges,
            last_exchange_us: None,
        }
    }
}

/// The stand-in scanner: a thread that runs 20 ms cycles until dropped.
pub struct FakeScanner {
    pub shared: Arc<Shared>,
    pub history: Arc<MemHistory>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

/// A history that is shared with the test (the `Box<dyn HistoryStore>` of [`Shared`] wraps it).
struct SharedHistory(Arc<MemHistory>);

impl HistoryStore for SharedHistory {
    fn samples(&self, mac: u8, from_ms: i64, to_ms: i64, limit: usize) -> Result<Vec<Sample>, String> {
        self.0.samples(mac, from_ms, to_ms, limit)
    }
    fn export_csv(
        &self,
        mac: Option<u8>,
        from_ms: i64,
        to_ms: i64,
        out: &mut dyn Write,
    ) -> Result<usize, String> {
        self.0.export_csv(mac, from_ms, to_ms, out)
    }
}

fn initial_state() -> ScannerState {
    ScannerState {
        mac: 0,
        status: ScannerStatus::Starting,
        cycles: 0,
        cycle_ms: 0.0,
        bus_load: 0.0,
        interscan_delay_ms: 10,
        expected_packet_rate_ms: 75,
        nodes: Vec::new(),
    }
}

impl FakeScanner {
    /// Starts the loop; recordings go to `record_dir`. `running: false` makes a scanner that
    /// never answers commands (for the timeout test).
    pub fn start(record_dir: &Path, answer_commands: bool) -> FakeScanner {
        let (tx, rx) = mpsc::channel();
        let history = Arc::new(MemHistory::default());
        let shared = Arc::new(Shared {
            state: Mutex::new(initial_state()),
            frames: Mutex::new(VecDeque::new()),
            commands: Mutex::new(tx),
            history: Some(Box::new(SharedHistory(Arc::clone(&history)))),
            record_dir: record_dir.to_path_buf(),
            mqtt: Mutex::new(Some("broker unreachable: tcp://127.0.0.1:1883 (connection refused)".into())),
            audit: Arc::new(dnet_scanner::audit::MemoryAudit::default()),
        });
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (shared, history, stop) = (Arc::clone(&shared), Arc::clone(&history), Arc::clone(&stop));
            std::thread::spawn(move || run(&shared, &history, &rx, &stop, answer_commands))
        };
        FakeScanner { shared, history, stop, thread: Some(thread) }
    }
}

impl Drop for FakeScanner {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

struct Frames {
    seq: u64,
    decoder: Decoder,
}

impl Frames {
    fn row(&mut self, time_us: u64, id: u16, data: &[u8], own: bool, mac: u8) -> Option<FrameRow> {
        let frame = CanFrame::new(CanId::new(id)?, data).ok()?;
        let decoded = self.decoder.decode(&frame);
        self.seq += 1;
        Some(FrameRow {
            seq: self.seq,
            time_us,
            frame: frame.to_string(),
            id,
            data: data.to_vec(),
            own,
            mac: Some(mac),
            kind: "io".into(),
            meaning: decoded.summary.clone(),
            message: decoded.message.clone(),
        })
    }

    /// A poll command and its fragmented response.
    fn poll(&mut self, time_us: u64, b: &Breaker, input: &[u8]) -> Vec<FrameRow> {
        let mut rows = Vec::new();
        rows.extend(self.row(time_us, 0x400 | (u16::from(b.mac) << 3) | 5, &b.output, true, b.mac));
        let id = (0xF << 6) | u16::from(b.mac);
        let chunks: Vec<&[u8]> = input.chunks(7).collect();
        for (i, chunk) in chunks.iter().enumerate() {
            let kind: u8 = if i == 0 {
                0
            } else if i + 1 == chunks.len() {
                0x80
            } else {
                0x40
            };
            let mut data = vec![kind | i as u8];
            data.extend_from_slice(chunk);
            rows.extend(self.row(time_us + 300 + 200 * i as u64, id, &data, false, b.mac));
        }
        rows
    }
}

fn answer_get(b: &Breaker, class: u16, instance: u16, attribute: u8) -> Result<Vec<u8>, String> {
    let name = |s: &str| {
        let mut v = vec![s.len() as u8];
        v.extend_from_slice(s.as_bytes());
        v
    };
    match (class, instance, attribute) {
        (1, 1, 1) => Ok(0x1234u16.to_le_bytes().to_vec()),
        (1, 1, 7) => Ok(name("Serial-DeviceNet Bridge")),
        (0x0F, 0, 2) => Ok(4u16.to_le_bytes().to_vec()),
        (0x0F, i @ 1..=4, a) => {
            let i = usize::from(i - 1);
            match a {
                1 => Ok(b.params[i].to_le_bytes().to_vec()),
                4 => Ok(vec![0, 0]),
                5 => Ok(vec![0xC7]),
                6 => Ok(vec![2]),
                7 => Ok(name(["Rated current", "Trip delay", "Overload limit", "Restart delay"][i])),
                8 => Ok(name(["A", "ms", "%", "s"][i])),
                10 => Ok(0u16.to_le_bytes().to_vec()),
                11 => Ok(1000u16.to_le_bytes().to_vec()),
                12 => Ok(100u16.to_le_bytes().to_vec()),
                _ => Err("error response: attribute not supported (0x14)".into()),
            }
        }
        _ => Err("error response: object does not exist (0x16)".into()),
    }
}

fn run(
    shared: &Shared,
    history: &MemHistory,
    rx: &Receiver<ConsoleCommand>,
    stop: &AtomicBool,
    answer: bool,
) {
    let mut breakers = [Breaker::new(5, false), Breaker::new(6, true)];
    let mut frames = Frames { seq: 0, decoder: Decoder::new() };
    for b in &breakers {
        frames.decoder.set_connection_sizes(b.mac, Some(b.input_size()), Some(8));
    }
    let mut tick: u64 = 0;
    let mut held = Vec::new();
    while !stop.load(Ordering::SeqCst) {
        tick += 1;
        let bus_us = tick * 20_000;
        while let Ok(cmd) = rx.try_recv() {
            if !answer {
                held.push(cmd);
                continue;
            }
            match cmd {
                ConsoleCommand::SetOutput { mac, data, reply } => {
                    let r = match breakers.iter_mut().find(|b| b.mac == mac) {
                        Some(b) if data.len() == 8 => {
                            b.output = data;
                            Ok(Vec::new())
                        }
                        Some(_) => Err(format!("MAC {mac}: the output image is 8 bytes, not {}", data.len())),
                        None => Err(format!("MAC {mac} is not in the scan list")),
                    };
                    let _ = reply.send(r);
                }
                ConsoleCommand::Get { mac, class, instance, attribute, reply } => {
                    let r = match breakers.iter().find(|b| b.mac == mac) {
                        Some(b) => answer_get(b, class, instance, attribute),
                        None => Err(format!("MAC {mac} is not in the scan list")),
                    };
                    let _ = reply.send(r);
                }
                ConsoleCommand::Set { reply, .. } => {
                    let _ = reply.send(Err("error response: attribute not settable (0x0E)".into()));
                }
                // Nor any other service (the serial-line analyzer's Read_Trace).
                ConsoleCommand::Request { reply, .. } => {
                    let _ = reply.send(Err("the fake scanner serves Get and Set only".into()));
                }
                // The fake scanner keeps no health: the request goes unanswered (503).
                ConsoleCommand::Health { .. } => {}
                // Nor events or scan-list changes.
                ConsoleCommand::Events { .. } | ConsoleCommand::EditList { .. } => {}
            }
        }
        let mut nodes = Vec::new();
        let mut rows = Vec::new();
        let now = unix_ms_now();
        for b in &mut breakers {
            b.apply_output();
            b.exchanges += 1;
            if tick % 3 == 0 {
                b.freshness = b.freshness.wrapping_add(1);
            }
            let input = b.input(tick);
            rows.extend(frames.poll(bus_us, b, &input));
            if tick % 5 == 0 {
                if let Ok(mut h) = history.0.lock() {
                    h.push(Sample {
                        mac: b.mac,
                        unix_ms: now,
                        bus_us,
                        input: input.clone(),
                        values: b.values(&input),
                    });
                }
            }
            nodes.push(b.state(input));
        }
        shared.push_frames(rows);
        if let Ok(mut s) = shared.state.lock() {
            s.status = ScannerStatus::Running;
            s.cycles = tick;
            s.cycle_ms = 4.2;
            s.bus_load = 0.17;
            s.nodes = nodes;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}
