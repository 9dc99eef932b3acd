//! Test equipment shared by the integration tests: an in-process CAN link on the real clock, and a
//! master that polls until a condition holds; the pty bench (socat pairs, child processes, the
//! Modbus server's Python) is the `pty-rig` crate's, re-exported here.
#![allow(dead_code, unused_imports)]

pub use pty_rig::{require_pymodbus, require_socat, scratch, Proc, PtyPair, PtyRig};

use can_io::bus::{Bus, BusError, BusEvent, Origin};
use devicenet::{CanFrame, Duration, Instant, MacId};
use master_core::master::{ConnectOptions, DeviceSummary, Master};
use soft_slave::clock::Clock;
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex};

/// The device MAC of every test description.
pub const MAC: u8 = 5;

pub fn mac() -> MacId {
    MacId::new(MAC).unwrap()
}

/// This package's folder.
pub fn package_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The workspace root.
pub fn workspace_dir() -> PathBuf {
    package_dir().join("../..").canonicalize().unwrap()
}

/// A description file of `tests/descriptions/`.
pub fn description(name: &str) -> PathBuf {
    package_dir().join("tests/descriptions").join(name)
}

// ---------------------------------------------------------------------------------------------
// An in-process CAN link on the real clock.

/// One end of a two-node CAN link made of channels; reports its own frames back as
/// [`Origin::Local`] like the real buses.
pub struct ChannelBus {
    name: &'static str,
    clock: Clock,
    tx: Sender<CanFrame>,
    rx: Receiver<CanFrame>,
    echo: VecDeque<BusEvent>,
}

impl ChannelBus {
    pub fn pair(clock: Clock) -> (ChannelBus, ChannelBus) {
        let (a_tx, b_rx) = mpsc::channel();
        let (b_tx, a_rx) = mpsc::channel();
        let end = |name, tx, rx| ChannelBus { name, clock, tx, rx, echo: VecDeque::new() };
        (end("link0", a_tx, a_rx), end("link0", b_tx, b_rx))
    }
}

impl Bus for ChannelBus {
    fn name(&self) -> &str {
        self.name
    }

    fn now(&mut self) -> Instant {
        self.clock.now()
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        let _ = self.tx.send(*frame);
        self.echo.push_back(BusEvent { at: self.clock.now(), frame: *frame, origin: Origin::Local });
        Ok(())
    }

    fn recv(&mut self, deadline: Instant) -> Result<Option<BusEvent>, BusError> {
        if let Some(ev) = self.echo.pop_front() {
            return Ok(Some(ev));
        }
        let now = self.clock.now();
        let wait = std::time::Duration::from_micros((deadline - now.min(deadline)).total_micros());
        match self.rx.recv_timeout(wait) {
            Ok(frame) => Ok(Some(BusEvent { at: self.clock.now(), frame, origin: Origin::Remote })),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                std::thread::sleep(wait);
                Ok(None)
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The master's side.

/// The bring-up with a slow EPR (1 s: the watchdog leaves room for explicit requests between
/// polls) and no polls; returns the summary.
pub fn bring_up(master: &mut Master<'_, '_>) -> DeviceSummary {
    let opts = ConnectOptions { target: mac(), epr_ms: 1000, polls: 0, ..ConnectOptions::default() };
    let summary = master.connect(&opts).unwrap_or_else(|e| panic!("bring-up failed: {e}"));
    assert_eq!(master.session.failures(), 0, "every frame of the bring-up checks");
    summary
}

/// Polls with `output` every 20 ms until `done` holds for the response or `timeout` passes;
/// returns the last response and how many polls it took.
pub fn poll_until(
    master: &mut Master<'_, '_>,
    summary: &DeviceSummary,
    output: &[u8],
    timeout: Duration,
    mut done: impl FnMut(&[u8]) -> bool,
) -> (Vec<u8>, usize) {
    let produced = summary.produced_size.unwrap();
    let consumed = summary.consumed_size.unwrap();
    let end = master.session.now() + timeout;
    let mut polls = 0;
    loop {
        let input = master
            .poll(mac(), output, produced, consumed, Duration::from_millis(500))
            .unwrap_or_else(|e| panic!("poll failed: {e}"));
        polls += 1;
        if done(&input) {
            return (input, polls);
        }
        let now = master.session.now();
        assert!(now < end, "condition not met within {timeout:?}; last input {input:02X?}");
        master.idle_until(now + Duration::from_millis(20)).unwrap();
    }
}

/// Get_Attribute_Single of a UDINT/USINT of the serial link object (class 0x64).
pub fn link_attribute(master: &mut Master<'_, '_>, attr: u8) -> u32 {
    let (data, _) = master.get(mac(), 0x64, 1, attr).unwrap_or_else(|e| panic!("get 0x64/1/{attr}: {e}"));
    let mut bytes = [0u8; 4];
    for (b, d) in bytes.iter_mut().zip(&data) {
        *b = *d;
    }
    u32::from_le_bytes(bytes)
}

/// The master's end of the rig's CAN link.
pub fn master_bus(rig: &PtyRig) -> can_io::bus::slcan::SlcanBus<Box<dyn serialport::SerialPort>> {
    can_io::bus::slcan::open(&rig.can.b, 115_200, can_io::bus::Bitrate::K250)
        .unwrap_or_else(|e| panic!("opening the master's end {}: {e}", rig.can.b))
}
