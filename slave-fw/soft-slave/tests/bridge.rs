//! The bridge's main loop in real time without external tools: the master harness on one end of
//! an in-process CAN link, the bridge on the other, the simulated breaker behind a Unix socket
//! pair. The same checks run over real pseudo-terminals in `breaker_pty.rs`.

mod common;

use can_io::log::{read_log, LogWriter};
use common::{bring_up, link_attribute, poll_until, ChannelBus};
use devicenet::Duration;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use slave_fw::converter::ConverterConfig;
use slave_fw::serial::breaker::{BreakerCommand, SWITCH_CLOSED, SWITCH_OPEN};
use soft_slave::breaker::{BreakerOptions, BreakerRunner};
use soft_slave::bridge::{Bridge, RunSummary};
use soft_slave::clock::Clock;
use soft_slave::serial::SerialLine;
use std::os::unix::net::UnixStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

struct Rig {
    stop: Arc<AtomicBool>,
    bridge: JoinHandle<RunSummary>,
    breaker: JoinHandle<Vec<BreakerCommand>>,
}

impl Rig {
    fn start(options: BreakerOptions, log: Option<std::path::PathBuf>) -> (Rig, ChannelBus) {
        let clock = Clock::start();
        let (master_end, slave_end) = ChannelBus::pair(clock);
        let (ours, theirs) = UnixStream::pair().unwrap();
        theirs.set_read_timeout(Some(std::time::Duration::from_millis(2))).unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let breaker_stop = Arc::clone(&stop);
        let breaker = std::thread::spawn(move || {
            let mut runner = BreakerRunner::new(theirs, options, clock, Box::new(std::io::sink()));
            let _ = runner.run(&breaker_stop, None);
            runner.breaker().commands().to_vec()
        });
        let bridge_stop = Arc::clone(&stop);
        let bridge = std::thread::spawn(move || {
            let serial = SerialLine::from_stream(ours, "socketpair", clock).unwrap();
            let mut bridge =
                Bridge::new(ConverterConfig::breaker_reference(), Box::new(slave_end), serial, clock)
                    .unwrap();
            if let Some(path) = log {
                bridge.set_log(LogWriter::create(&path).unwrap(), &path.display().to_string());
            }
            bridge.run(&bridge_stop, None).unwrap()
        });
        (Rig { stop, bridge, breaker }, master_end)
    }

    fn stop(self) -> (RunSummary, Vec<BreakerCommand>) {
        self.stop.store(true, Ordering::Relaxed);
        (self.bridge.join().unwrap(), self.breaker.join().unwrap())
    }
}

#[test]
fn data_and_exactly_once_commands_through_the_bridge() {
    let dir = common::scratch("bridge");
    let log = dir.join("can.log");
    let options =
        BreakerOptions { closed: true, period: Duration::from_millis(200), ..BreakerOptions::default() };
    let (rig, mut bus) = Rig::start(options, Some(log.clone()));
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let summary = bring_up(&mut master);
    assert_eq!(summary.produced_size, Some(18));

    // The breaker's data reaches the poll response.
    let (input, _) =
        poll_until(&mut master, &summary, &[0; 8], Duration::from_secs(3), |i| i[9] == SWITCH_CLOSED);
    assert_eq!(&input[..4], &[120, 118, 121, 3]);

    // Open, sequence 1, a hundred times: one command on the serial line.
    for _ in 0..100 {
        master.poll(common::mac(), &[1, 1, 0, 0, 0, 0, 0, 0], 18, 8, Duration::from_millis(500)).unwrap();
    }
    let (input, _) =
        poll_until(&mut master, &summary, &[1, 1, 0, 0, 0, 0, 0, 0], Duration::from_secs(3), |i| {
            i[9] == SWITCH_OPEN
        });
    assert_eq!(&input[..4], &[0, 0, 0, 0]);
    assert_eq!(link_attribute(&mut master, 5), 1, "commands sent (class 0x64 attribute 5)");
    assert_eq!(master.session.failures(), 0);
    drop(master);
    drop(session);

    let (run, commands) = rig.stop();
    assert_eq!(commands, vec![BreakerCommand::Open]);
    assert!(run.can_received > 100 && run.can_sent > 300, "{run:?}");
    assert_eq!(run.stats.commands_sent, 1);
    let frames = read_log(&log).unwrap();
    assert!(frames.iter().filter(|e| e.frame.id().as_raw() == 0x42D).count() > 100);
    assert!(frames.iter().any(|e| e.frame.id().as_raw() == 0x3C5));
    assert!(frames.iter().all(|e| &*e.iface == "link0"));
}

#[test]
fn identity_reset_restarts_the_converter() {
    let (rig, mut bus) = Rig::start(BreakerOptions::default(), None);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    bring_up(&mut master);
    let (data, _) = master
        .request_ok(
            common::mac(),
            master_core::client::Port::Explicit,
            &devicenet::explicit::Request {
                service: devicenet::explicit::ServiceCode::Reset,
                class: 1,
                instance: 1,
                data: &[],
            },
        )
        .unwrap();
    assert!(data.is_empty());
    // The converter comes back with its duplicate MAC ID check.
    let start = master.session.now();
    master.idle_until(start + Duration::from_millis(300)).unwrap();
    let announced = master
        .session
        .records()
        .iter()
        .filter(|r| r.at > start && r.frame.id().as_raw() == 0x42F && r.origin == can_io::bus::Origin::Remote)
        .count();
    assert_eq!(announced, 1, "the restarted node's first duplicate MAC ID check");
    drop(master);
    drop(session);
    let (run, _) = rig.stop();
    assert_eq!(run.resets, 1);
}
