//! Benchmark: the cost of one poll cycle on the host (poll command in, three fragments out), and
//! of one explicit Get_Attribute_Single. A plain bench binary: `cargo bench -p devicenet`.
//! The figures are reported, never asserted.

use devicenet::reference::{Direction, BRING_UP, INPUT_IMAGE};
use devicenet::{CanFrame, DeviceConfig, Duration, Instant, SlaveNode};
use std::hint::black_box;

fn established() -> (SlaveNode, Instant) {
    let mut node = SlaveNode::new(DeviceConfig::reference()).expect("reference config");
    node.set_input(&INPUT_IMAGE).expect("reference image");
    node.power_on(Instant::ZERO);
    let mut now = Instant::from_secs(2);
    node.handle_timeout(Instant::from_secs(1));
    node.handle_timeout(now);
    for f in BRING_UP.iter().filter(|f| f.direction == Direction::MasterToSlave).skip(4) {
        now += Duration::from_millis(1);
        node.handle_frame(&CanFrame::from_raw(f.id, f.data).expect("reference frame"), now);
        while node.poll_transmit().is_some() {}
    }
    while node.poll_event().is_some() {}
    (node, now)
}

fn measure(name: &str, iterations: u32, frame: CanFrame, expect_frames: usize) {
    let (mut node, mut now) = established();
    // Warm up.
    for _ in 0..10_000 {
        now += Duration::from_millis(1);
        node.handle_frame(&frame, now);
        while node.poll_transmit().is_some() {}
        while node.poll_event().is_some() {}
    }
    let mut runs = Vec::new();
    for _ in 0..5 {
        let start = std::time::Instant::now();
        let mut frames = 0usize;
        for _ in 0..iterations {
            now += Duration::from_millis(1);
            node.handle_frame(black_box(&frame), now);
            while let Some(f) = node.poll_transmit() {
                black_box(f);
                frames += 1;
            }
            while node.poll_event().is_some() {}
        }
        assert_eq!(frames, expect_frames * iterations as usize);
        runs.push(start.elapsed().as_nanos() as f64 / f64::from(iterations));
    }
    runs.sort_by(f64::total_cmp);
    println!(
        "{name}: median {:.0} ns per cycle (min {:.0}, max {:.0}; 5 runs of {iterations})",
        runs[2], runs[0], runs[4]
    );
}

fn main() {
    let poll = CanFrame::from_raw(0x42D, &[0; 8]).expect("poll frame");
    measure("poll cycle (8 bytes in, 3 fragments out)", 1_000_000, poll, 3);
    let get = CanFrame::from_raw(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]).expect("get frame");
    measure("explicit Get_Attribute_Single (Identity vendor ID)", 1_000_000, get, 1);
}
