//! The group-2-only slave node fed arbitrary frame sequences with time steps and bus-off events.
#![no_main]

use devicenet::{DeviceConfig, Duration, Instant, SlaveNode};
use dnet_fuzz::steps::{steps, Step};
use dnet_fuzz::{frame, slave_may_send};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(mut node) = SlaveNode::new(DeviceConfig::reference()) else { return };
    let mut now = Instant::ZERO;
    node.power_on(now);
    let drain = |node: &mut SlaveNode| {
        let mut sent = 0;
        // The MAC in force: the Offline Connection Set may change it (protocol §II.6).
        let mac = node.mac_id();
        while let Some(f) = node.poll_transmit() {
            assert!(slave_may_send(mac, f.id()), "the node sent {f}");
            sent += 1;
            assert!(sent <= devicenet::slave::TX_QUEUE_LEN, "more frames than the queue holds");
        }
        while node.poll_event().is_some() {}
    };
    drain(&mut node);
    for (dt, step) in steps(data) {
        let target = now + Duration::from_millis(dt);
        // Timers due before the step, as the firmware's task runs them.
        while let Some(at) = node.poll_at().filter(|&at| at <= target) {
            now = at.max(now);
            node.handle_timeout(now);
            drain(&mut node);
            assert!(node.poll_at().is_none_or(|next| next > now), "deadline not moved past {now}");
        }
        now = target;
        match step {
            Step::Frame(id, bytes) => {
                if let Some(f) = frame(id, bytes) {
                    node.handle_frame(&f, now);
                }
            }
            Step::Serial(_) => node.handle_timeout(now),
            Step::BusOff => node.handle_bus_off(now),
        }
        drain(&mut node);
        let _ = node.leds(now);
        let _ = node.identity_status();
        assert!(node.input().len() <= devicenet::slave::MAX_IO_SIZE);
        assert!(node.output().len() <= devicenet::slave::MAX_IO_SIZE);
    }
});
