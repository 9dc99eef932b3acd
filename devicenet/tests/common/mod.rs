//! A scripted master for the integration tests: plays the master's frames of the reference
//! sequence at chosen instants on a virtual clock, and records every frame on the bus.

use devicenet::reference::{Direction, BRING_UP, INPUT_IMAGE};
use devicenet::{CanFrame, DeviceConfig, Duration, Instant, SlaveNode};

/// One frame seen on the bus.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Seen {
    pub at: Instant,
    pub direction: Direction,
    pub id: u16,
    pub data: Vec<u8>,
}

/// The reference node with the reference input image.
pub fn reference_node() -> SlaveNode {
    let mut node = SlaveNode::new(DeviceConfig::reference()).unwrap();
    node.set_input(&INPUT_IMAGE).unwrap();
    node
}

/// Runs the slave's timers up to `until`, recording what it sends.
pub fn run_until(node: &mut SlaveNode, until: Instant, seen: &mut Vec<Seen>) {
    while let Some(at) = node.poll_at() {
        if at > until {
            break;
        }
        node.handle_timeout(at);
        drain(node, at, seen);
    }
    node.handle_timeout(until);
    drain(node, until, seen);
}

pub fn drain(node: &mut SlaveNode, at: Instant, seen: &mut Vec<Seen>) {
    while let Some(f) = node.poll_transmit() {
        seen.push(Seen {
            at,
            direction: Direction::SlaveToMaster,
            id: f.id().as_raw(),
            data: f.data().to_vec(),
        });
    }
}

/// Plays the master's side of protocol §2: its duplicate MAC check at 0 s and 1 s, slave power-on
/// when the master is on-line (2 s), the UCMM open at 4 s and its retry 0.5 s later, then every
/// request 10 ms after the previous answer.
pub fn play_bring_up(node: &mut SlaveNode) -> Vec<Seen> {
    let mut seen = Vec::new();
    let mut now = Instant::ZERO;
    let master_frames = BRING_UP.iter().filter(|f| f.direction == Direction::MasterToSlave).enumerate();
    for (k, f) in master_frames {
        now = match k {
            0 => Instant::ZERO,
            1 => Instant::from_secs(1),
            2 => Instant::from_secs(4),
            3 => Instant::from_millis(4500),
            _ => now + Duration::from_millis(10),
        };
        if k == 2 {
            // The master went on-line at 2 s: the slave powers on then (as in the capture).
            run_until(node, Instant::from_secs(2), &mut seen);
            node.power_on(Instant::from_secs(2));
            drain(node, Instant::from_secs(2), &mut seen);
        }
        run_until(node, now, &mut seen);
        let frame = CanFrame::from_raw(f.id, f.data).unwrap();
        seen.push(Seen { at: now, direction: Direction::MasterToSlave, id: f.id, data: f.data.to_vec() });
        node.handle_frame(&frame, now);
        drain(node, now, &mut seen);
    }
    run_until(node, now + Duration::from_millis(10), &mut seen);
    seen
}
