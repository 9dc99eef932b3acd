//! The converter (node + breaker profile, with the link-status assembly) fed arbitrary CAN
//! frames, bytes from the instrument, time steps and bus-off events.
#![no_main]

use devicenet::{Duration, Instant};
use dnet_fuzz::steps::{steps, Step};
use dnet_fuzz::{frame, slave_may_send};
use libfuzzer_sys::fuzz_target;
use slave_fw::converter::{Converter, ConverterConfig, InputAssembly};

fuzz_target!(|data: &[u8]| {
    let mut config = ConverterConfig::breaker_reference();
    config.input = if data.first().is_some_and(|b| b & 1 == 1) {
        InputAssembly::WithStatus
    } else {
        InputAssembly::Plain
    };
    let mut now = Instant::ZERO;
    let Ok(mut conv) = Converter::new(config.clone(), now) else { return };
    conv.power_on(now);
    let drain = |conv: &mut Converter, now: Instant| {
        // The MAC in force: the Offline Connection Set may change it (protocol §II.6).
        let mac = conv.node().mac_id();
        while let Some(f) = conv.poll_can_transmit() {
            assert!(slave_may_send(mac, f.id()), "the converter sent {f}");
        }
        let mut n = 0;
        while let Some(bytes) = conv.poll_serial_transmit(now) {
            assert!(bytes.len() <= 64, "serial frame of {} bytes", bytes.len());
            n += 1;
            assert!(n <= 64, "unbounded serial output");
        }
        while conv.poll_event().is_some() {}
    };
    drain(&mut conv, now);
    for (dt, step) in steps(data.get(1..).unwrap_or(&[])) {
        let target = now + Duration::from_millis(dt);
        while let Some(at) = conv.poll_at().filter(|&at| at <= target) {
            now = at.max(now);
            conv.handle_timeout(now);
            drain(&mut conv, now);
            // A due Identity Reset is the application's to carry out, as the firmware does: a new
            // converter, powered on (poll_at includes the reset's deadline until it is taken).
            if conv.poll_reset(now).is_some() {
                let Ok(fresh) = Converter::new(config.clone(), now) else { return };
                conv = fresh;
                conv.power_on(now);
                drain(&mut conv, now);
            }
            assert!(conv.poll_at().is_none_or(|next| next > now), "deadline not moved past {now}");
        }
        now = target;
        match step {
            Step::Frame(id, bytes) => {
                if let Some(f) = frame(id, bytes) {
                    conv.handle_can_frame(&f, now);
                }
            }
            Step::Serial(bytes) => conv.handle_serial(bytes, now),
            Step::BusOff => conv.handle_bus_off(now),
        }
        drain(&mut conv, now);
        let _ = conv.leds(now);
    }
});
