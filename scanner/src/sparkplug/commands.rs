//! DCMD (`--sparkplug-commands`): a host application's writes to a device's output image and its
//! breaker commands, carried out by the scanner's loop like the console's and recorded through the
//! [`CommandLog`] given to the publisher. With `--plant` each network's devices go to that
//! network's scanner loop ([`Queues`]).
//!
//! A device's commands are handed to the scanner one at a time, in the order they came: the next
//! only two cycles after the scanner took the last, so that the cycle that sends it has run. The
//! scanner sends one output image per node per cycle; two handed over between the same two cycles
//! would leave only the second on the bus (a Close then an Open: the Close never reached the
//! breaker, yet both were recorded `ok`). Commands for other devices do not wait for it.

use super::edge::{Device, DeviceKey, Edge, BREAKER_CLOSE, BREAKER_OPEN, OUTPUT_IMAGE};
use super::proto::{self, Payload};
use crate::breaker::{breaker_output, BreakerCommand};
use crate::history::hex;
use crate::model::ConsoleCommand;
use crate::monitor::ImageProfile;
use std::collections::{BTreeMap, VecDeque};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// How long a command waits for the scanner's loop to carry it out.
const ANSWER_WITHIN: Duration = Duration::from_secs(10);

/// One DCMD metric carried out or refused, for the audit log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CommandRecord {
    /// Who sent it: `sparkplug` (MQTT carries no user of its own; the broker's ACL decides who may
    /// publish DCMD).
    pub user: String,
    /// The device's plant network (`None` without `--plant`).
    pub network: Option<String>,
    /// The device's MAC ID.
    pub mac: u8,
    /// What: `Outputs/Image = 0102...`, `Commands/Close`.
    pub what: String,
    /// `ok`, or the reason it was refused or failed.
    pub result: String,
}

/// Where commands are recorded (the audit log); called once per DCMD metric.
pub type CommandLog = Box<dyn Fn(&CommandRecord) + Send>;

/// Each network's scanner command queue: the key `None` is the one network without `--plant`.
pub type Queues = BTreeMap<Option<String>, Sender<ConsoleCommand>>;

impl CommandRecord {
    fn new(key: &DeviceKey, what: String) -> CommandRecord {
        CommandRecord {
            user: "sparkplug".into(),
            network: key.network.clone(),
            mac: key.mac,
            what,
            result: String::new(),
        }
    }
}

/// A DCMD as received: the device and the payload.
pub(super) struct Dcmd {
    pub key: DeviceKey,
    pub payload: Vec<u8>,
}

/// Starts the thread that carries out DCMD: `scanner` holds each network's scanner loop's
/// command queue.
pub(super) fn spawn(
    edge: Arc<Mutex<Edge>>,
    scanner: Queues,
    log: Option<CommandLog>,
) -> std::io::Result<mpsc::SyncSender<Dcmd>> {
    let (tx, rx) = mpsc::sync_channel::<Dcmd>(PENDING);
    std::thread::Builder::new()
        .name("sparkplug-dcmd".into())
        .spawn(move || run(&rx, &edge, &scanner, log.as_ref()))?;
    Ok(tx)
}

/// DCMD metrics waiting to be handed to the scanner at most.
const PENDING: usize = 256;

/// Cycles after the scanner's answer before a device's next command: the scanner takes commands
/// between two cycles and sends one output image per node per cycle, so a second image handed over
/// before the next cycle would overwrite the first unsent (and two breaker commands would share a
/// sequence number). Two, because the answer may be read before or after the edge has seen the
/// state of the cycle that took the command.
const CYCLES_BETWEEN: u64 = 2;

/// A command handed to the scanner, its answer not read yet.
struct Pending {
    record: CommandRecord,
    answer: Receiver<crate::model::Reply>,
    until: std::time::Instant,
}

/// Why a device's next command waits.
enum Busy {
    /// The scanner's answer to its last command is not read yet.
    Answer(Pending),
    /// Answered when the edge had seen `at` cycles: free once it has seen [`CYCLES_BETWEEN`] more,
    /// or at `until` if the scanner's loop stopped cycling.
    Sent { at: u64, until: std::time::Instant },
}

/// One DCMD metric waiting for its device to be free.
struct Queued {
    key: DeviceKey,
    metric: proto::Metric,
}

fn run(rx: &Receiver<Dcmd>, edge: &Mutex<Edge>, scanner: &Queues, log: Option<&CommandLog>) {
    let mut queue: VecDeque<Queued> = VecDeque::new();
    let mut busy: BTreeMap<DeviceKey, Busy> = BTreeMap::new();
    let record = |r: &CommandRecord| {
        if let Some(log) = log {
            log(r);
        }
    };
    loop {
        // Commands are handed over in the order they came, one at a time per device (see
        // CYCLES_BETWEEN); other devices' commands do not wait for it.
        let wait = if queue.is_empty() && busy.is_empty() { 20 } else { 5 };
        match rx.recv_timeout(Duration::from_millis(wait)) {
            Ok(cmd) => {
                for metric in metrics(&cmd, &mut |r| record(r)) {
                    if queue.len() >= PENDING {
                        let mut r = CommandRecord::new(&cmd.key, metric.name.clone().unwrap_or_default());
                        r.result = format!("refused: {PENDING} commands already wait for the scanner");
                        record(&r);
                    } else {
                        queue.push_back(Queued { key: cmd.key.clone(), metric });
                    }
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) if queue.is_empty() && busy.is_empty() => return,
            Err(mpsc::RecvTimeoutError::Disconnected) => std::thread::sleep(Duration::from_millis(20)),
        }
        let cycles = edge.lock().unwrap_or_else(PoisonError::into_inner).cycles.clone();
        let now = std::time::Instant::now();
        busy.retain(|key, b| match b {
            Busy::Answer(p) => {
                let (result, sent) = match p.answer.try_recv() {
                    Ok(Ok(_)) => ("ok".to_owned(), true),
                    Ok(Err(e)) => (format!("failed: {e}"), false),
                    Err(mpsc::TryRecvError::Disconnected) => {
                        ("failed: the scanner has stopped".into(), false)
                    }
                    Err(mpsc::TryRecvError::Empty) if now >= p.until => {
                        ("failed: no answer from the scanner".into(), false)
                    }
                    Err(mpsc::TryRecvError::Empty) => return true,
                };
                p.record.result = result;
                record(&p.record);
                *b = Busy::Sent { at: cycles_of(&cycles, key), until: now + ANSWER_WITHIN };
                sent
            }
            Busy::Sent { at, until } => {
                cycles_of(&cycles, key) < at.saturating_add(CYCLES_BETWEEN) && now < *until
            }
        });
        let mut i = 0;
        while let Some(q) = queue.get(i) {
            if busy.contains_key(&q.key) {
                i += 1;
                continue;
            }
            let Some(q) = queue.remove(i) else { break };
            let device = edge.lock().unwrap_or_else(PoisonError::into_inner).devices.get(&q.key).cloned();
            match hand_over(&q.key, device.as_ref(), &q.metric, scanner) {
                Ok(p) => {
                    busy.insert(q.key, Busy::Answer(p));
                }
                Err(r) => record(&r),
            }
        }
    }
}

/// The metrics of a DCMD; an undecodable payload is recorded as refused.
fn metrics(cmd: &Dcmd, record: &mut dyn FnMut(&CommandRecord)) -> Vec<proto::Metric> {
    match <Payload as prost::Message>::decode(cmd.payload.as_slice()) {
        Ok(p) => p.metrics,
        Err(e) => {
            let mut r = CommandRecord::new(&cmd.key, "DCMD".into());
            r.result = format!("refused: not a Sparkplug B payload ({e})");
            record(&r);
            Vec::new()
        }
    }
}

/// The cycle count of `key`'s network.
fn cycles_of(cycles: &BTreeMap<Option<String>, u64>, key: &DeviceKey) -> u64 {
    cycles.get(&key.network).copied().unwrap_or(0)
}

/// What one DCMD metric asks, as the output image to write.
fn output_for(device: &Device, metric: &proto::Metric) -> Result<(String, Vec<u8>), String> {
    let name = metric.name.as_deref().unwrap_or("");
    match (name, &metric.value) {
        (OUTPUT_IMAGE, Some(proto::Value::BytesValue(b))) => {
            Ok((format!("{OUTPUT_IMAGE} = {}", hex(b)), b.clone()))
        }
        (OUTPUT_IMAGE, _) => Err(format!("{OUTPUT_IMAGE} takes Bytes")),
        (BREAKER_OPEN | BREAKER_CLOSE, _) if device.layout.profile != ImageProfile::Breaker => {
            Err("not a breaker".into())
        }
        (BREAKER_OPEN | BREAKER_CLOSE, Some(proto::Value::BooleanValue(true))) => {
            let command = if name == BREAKER_OPEN { BreakerCommand::Open } else { BreakerCommand::Close };
            let data = breaker_output(command, &device.output, device.output_size);
            Ok((name.to_owned(), data))
        }
        (BREAKER_OPEN | BREAKER_CLOSE, _) => Err(format!("{name} takes Boolean true")),
        (other, _) => Err(format!(
            "no writable metric {other:?} (writable: {OUTPUT_IMAGE}, {BREAKER_OPEN}, {BREAKER_CLOSE})"
        )),
    }
}

/// Hands one DCMD metric to the scanner; a refusal is the record to log.
fn hand_over(
    key: &DeviceKey,
    device: Option<&Device>,
    metric: &proto::Metric,
    scanner: &Queues,
) -> Result<Pending, CommandRecord> {
    let mut record = CommandRecord::new(key, metric.name.clone().unwrap_or_default());
    let refuse = |mut record: CommandRecord, why: String| {
        record.result = why;
        Err(record)
    };
    let Some(device) = device else { return refuse(record, "refused: no such device".into()) };
    let (what, data) = match output_for(device, metric) {
        Ok(x) => x,
        Err(why) => return refuse(record, format!("refused: {why}")),
    };
    record.what = what;
    let Some(scanner) = scanner.get(&key.network) else {
        return refuse(record, "refused: no such network".into());
    };
    let (reply, answer) = mpsc::channel();
    if scanner.send(ConsoleCommand::SetOutput { mac: key.mac, data, reply }).is_err() {
        return refuse(record, "failed: the scanner has stopped".into());
    }
    Ok(Pending { record, answer, until: std::time::Instant::now() + ANSWER_WITHIN })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::monitor::InputLayout;

    fn device(profile: ImageProfile) -> Device {
        Device {
            metrics: Default::default(),
            output: vec![0, 7, 0, 0, 0, 0, 0, 0],
            output_size: Some(8),
            layout: InputLayout { profile, image_len: 18, with_status: false },
        }
    }

    fn metric(name: &str, value: proto::Value) -> proto::Metric {
        proto::Metric { name: Some(name.into()), value: Some(value), ..Default::default() }
    }

    #[test]
    fn breaker_close_bumps_the_sequence() {
        let (what, data) = output_for(
            &device(ImageProfile::Breaker),
            &metric(BREAKER_CLOSE, proto::Value::BooleanValue(true)),
        )
        .unwrap();
        assert_eq!((what.as_str(), data), (BREAKER_CLOSE, vec![2, 8, 0, 0, 0, 0, 0, 0]));
    }

    /// Two breaker commands for one device in one DCMD: the scanner sends one output image per
    /// node per cycle, so the Open is handed over only once the cycle that sends the Close has run,
    /// with the next sequence number (else the Close would be overwritten before it was sent).
    #[test]
    fn a_second_command_for_a_device_waits_for_the_cycle_that_sends_the_first() {
        let mut edge = Edge::default();
        edge.devices.insert(DeviceKey::single(5), device(ImageProfile::Breaker));
        let edge = Arc::new(Mutex::new(edge));
        let (scanner, commands) = mpsc::channel();
        let dcmd = spawn(Arc::clone(&edge), Queues::from([(None, scanner)]), None).unwrap();
        let payload = Payload {
            metrics: vec![
                metric(BREAKER_CLOSE, proto::Value::BooleanValue(true)),
                metric(BREAKER_OPEN, proto::Value::BooleanValue(true)),
            ],
            ..Default::default()
        };
        dcmd.send(Dcmd { key: DeviceKey::single(5), payload: prost::Message::encode_to_vec(&payload) })
            .unwrap();
        let set_output = |c: ConsoleCommand| match c {
            ConsoleCommand::SetOutput { mac, data, reply } => (mac, data, reply),
            _ => panic!("not an output"),
        };
        let (mac, close, reply) = set_output(commands.recv_timeout(Duration::from_secs(5)).unwrap());
        assert_eq!((mac, close.as_slice()), (5, [2, 8, 0, 0, 0, 0, 0, 0].as_slice()));
        // The scanner's loop takes it between two cycles; the edge sees the new output.
        edge.lock().unwrap().devices.get_mut(&DeviceKey::single(5)).unwrap().output = close;
        reply.send(Ok(Vec::new())).unwrap();
        assert!(
            commands.recv_timeout(Duration::from_millis(300)).is_err(),
            "the Open was handed over before a cycle sent the Close"
        );
        *edge.lock().unwrap().cycles.entry(None).or_default() += 2;
        let (_, open, _) = set_output(commands.recv_timeout(Duration::from_secs(5)).unwrap());
        assert_eq!(open, [1, 9, 0, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn refusals_say_why() {
        let raw = device(ImageProfile::Raw);
        let e = output_for(&raw, &metric(BREAKER_OPEN, proto::Value::BooleanValue(true))).unwrap_err();
        assert_eq!(e, "not a breaker");
        let e = output_for(&raw, &metric(OUTPUT_IMAGE, proto::Value::IntValue(3))).unwrap_err();
        assert!(e.contains("Bytes"), "{e}");
        let e = output_for(&raw, &metric("Inputs/phase_a", proto::Value::DoubleValue(1.0))).unwrap_err();
        assert!(e.contains("no writable metric"), "{e}");
    }

    /// With `--plant` a DCMD goes to its device's network's scanner only; a network the plant
    /// does not have is refused and recorded.
    #[test]
    fn a_plant_dcmd_goes_to_its_network_only() {
        let mut edge = Edge::default();
        edge.devices.insert(DeviceKey::of(Some("a"), 5), device(ImageProfile::Breaker));
        edge.devices.insert(DeviceKey::of(Some("b"), 5), device(ImageProfile::Breaker));
        edge.devices.insert(DeviceKey::of(Some("c"), 5), device(ImageProfile::Breaker));
        let edge = Arc::new(Mutex::new(edge));
        let (a, a_rx) = mpsc::channel();
        let (b, b_rx) = mpsc::channel();
        let (records_tx, records) = mpsc::channel();
        let log: CommandLog = Box::new(move |r: &CommandRecord| {
            let _ = records_tx.send(r.clone());
        });
        let queues = Queues::from([(Some("a".to_owned()), a), (Some("b".to_owned()), b)]);
        let dcmd = spawn(Arc::clone(&edge), queues, Some(log)).unwrap();
        let close = Payload {
            metrics: vec![metric(BREAKER_CLOSE, proto::Value::BooleanValue(true))],
            ..Default::default()
        };
        let payload = prost::Message::encode_to_vec(&close);
        dcmd.send(Dcmd { key: DeviceKey::of(Some("b"), 5), payload: payload.clone() }).unwrap();
        let ConsoleCommand::SetOutput { mac, reply, .. } = b_rx.recv_timeout(Duration::from_secs(5)).unwrap()
        else {
            panic!("not an output")
        };
        assert_eq!(mac, 5);
        reply.send(Ok(Vec::new())).unwrap();
        let r = records.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!((r.network.as_deref(), r.mac, r.result.as_str()), (Some("b"), 5, "ok"));
        assert!(a_rx.try_recv().is_err(), "network a got b's command");
        dcmd.send(Dcmd { key: DeviceKey::of(Some("c"), 5), payload }).unwrap();
        let r = records.recv_timeout(Duration::from_secs(5)).unwrap();
        assert_eq!((r.network.as_deref(), r.result.as_str()), (Some("c"), "refused: no such network"));
        assert!(a_rx.try_recv().is_err() && b_rx.try_recv().is_err());
    }
}
