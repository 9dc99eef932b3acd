//! Unit tests of the slave node: network access, the validation tables of protocol §3.4 and §5,
//! objects, connections and fragmentation, driven on a virtual clock.

use super::*;
use crate::explicit::ServiceCode;
use crate::led;
use crate::reference::INPUT_IMAGE;
use crate::time::Duration;
use rstest::rstest;
use std::vec::Vec;

type Tx = Vec<(u16, Vec<u8>)>;

struct Rig {
    node: SlaveNode,
    now: Instant,
}

impl Rig {
    fn new(config: DeviceConfig) -> Rig {
        let mut node = SlaveNode::new(config).unwrap();
        // The reference image wherever the produced size is the reference one.
        let _ = node.set_input(&INPUT_IMAGE);
        Rig { node, now: Instant::ZERO }
    }

    /// Powered on at t = 0 and on-line at t = 2 s.
    fn online() -> Rig {
        let mut rig = Rig::new(DeviceConfig::reference());
        rig.node.power_on(rig.now);
        rig.advance(Duration::from_secs(2));
        assert_eq!(rig.node.network_state(), NetworkState::Online);
        rig.events();
        rig
    }

    /// On-line with explicit allocated by master 0.
    fn explicit() -> Rig {
        let mut rig = Rig::online();
        assert_eq!(rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]), tx(0x42B, &[0x00, 0xCB, 0x00]));
        rig.events();
        rig
    }

    /// Explicit and poll established (EPR 100 ms).
    fn established() -> Rig {
        let mut rig = Rig::explicit();
        assert_eq!(rig.send(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00]), tx(0x42B, &[0x00, 0xCB, 0x00]));
        assert_eq!(
            rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00]),
            tx(0x42B, &[0x00, 0x90, 0x64, 0x00])
        );
        rig.events();
        rig
    }

    fn drain(&mut self) -> Tx {
        let mut out = Vec::new();
        while let Some(f) = self.node.poll_transmit() {
            out.push((f.id().as_raw(), f.data().to_vec()));
        }
        out
    }

    fn events(&mut self) -> Vec<Event> {
        let mut out = Vec::new();
        while let Some(e) = self.node.poll_event() {
            out.push(e);
        }
        out
    }

    /// Runs every timer up to `now + d`, returning what was sent.
    fn advance(&mut self, d: Duration) -> Tx {
        let end = self.now + d;
        let mut out = self.drain();
        while let Some(at) = self.node.poll_at() {
            if at > end {
                break;
            }
            self.now = at.max(self.now);
            self.node.handle_timeout(self.now);
            out.extend(self.drain());
        }
        self.now = end;
        self.node.handle_timeout(end);
        out.extend(self.drain());
        out
    }

    fn send(&mut self, id: u16, data: &[u8]) -> Tx {
        let frame = CanFrame::from_raw(id, data).unwrap();
        self.node.handle_frame(&frame, self.now);
        self.drain()
    }
}

fn tx(id: u16, data: &[u8]) -> Tx {
    std::vec![(id, data.to_vec())]
}

mod connection_types;
mod fragmentation;
mod network;
mod objects;
mod polled_io;
mod supervision;
