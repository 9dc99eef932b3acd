//! Benchmarks of the I/O connection types (issue 14; docs/src/reference/io-connections.md),
//! reported and never
//! asserted (`cargo bench -p converter-sim --bench io_modes`):
//!
//! * **bus load** of the breaker converter at 250 kbit/s on the simulated bus, a master polling it
//!   every 10 ms against the same converter under change of state (acknowledged, and with
//!   acknowledge suppression; 10 s heartbeat) while the breaker reports once a second: frames per
//!   second and the share of bus time, every frame of both directions counted with its stuffed
//!   length (`can_io::sim::frame_duration`);
//! * **latency** in the soft slave's converter, wall clock: from the call that hands it the last
//!   byte of an instrument frame with new data to the first fragment of the COS production coming
//!   out of it (what the soft slave then writes to its CAN interface), median and 99th percentile.

use can_io::bus::{Bitrate, Bus};
use can_io::sim::{frame_duration, PowerOn, SimBus};
use converter_sim::breaker::SimulatedBreaker;
use converter_sim::device::SoftSlave;
use devicenet::{CanFrame, Duration, Instant, MacId};
use slave_fw::converter::{Converter, ConverterConfig};

/// The measured window, simulated.
const WINDOW: Duration = Duration::from_secs(60);

/// A master (MAC 0) on a fresh 250 kbit/s bus with the reference breaker converter at MAC 5,
/// on-line.
fn bus() -> SimBus {
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(SoftSlave::reference(MacId::from_low_bits(5))), PowerOn::AtStart);
    drain(&mut bus, Instant::from_millis(2500));
    bus
}

/// Every frame that completes on the bus until `until`.
fn drain(bus: &mut SimBus, until: Instant) -> Vec<CanFrame> {
    let mut frames = Vec::new();
    while let Some(event) = bus.recv(until).expect("the simulated bus does not fail") {
        frames.push(event.frame);
    }
    frames
}

/// Sends `data` on `id` and returns what the bus carried in the next 5 ms.
fn request(bus: &mut SimBus, id: u16, data: &[u8]) -> Vec<CanFrame> {
    bus.send(&CanFrame::from_raw(id, data).expect("a valid frame")).expect("sent");
    // The answers come within a few milliseconds; the poll connection's watchdog is 4 x 10 ms.
    let until = bus.now() + Duration::from_millis(5);
    drain(bus, until)
}

/// Allocates `choice` (explicit included) and sets the EPR of `instance`.
fn allocate(bus: &mut SimBus, choice: u8, instance: u8, epr_ms: u16) {
    let reply = request(bus, 0x42E, &[0x00, 0x4B, 0x03, 0x01, choice, 0x00]);
    assert!(reply.iter().any(|f| f.id().as_raw() == 0x42B && f.data() == [0x00, 0xCB, 0x00]), "{reply:?}");
    let [lo, hi] = epr_ms.to_le_bytes();
    let reply = request(bus, 0x42C, &[0x00, 0x10, 0x05, instance, 0x09, lo, hi]);
    assert!(reply.iter().any(|f| f.id().as_raw() == 0x42B && f.data()[1] == 0x90), "{reply:?}");
}

/// Frames per second and percent of bus time of `frames` over the window.
fn load(frames: &[CanFrame]) -> (f64, f64) {
    let busy: u64 = frames.iter().map(|f| frame_duration(f, Bitrate::K250).total_micros()).sum();
    let window = WINDOW.total_micros() as f64;
    (frames.len() as f64 / (window / 1e6), 100.0 * busy as f64 / window)
}

/// The master polls every 10 ms (EPR 10 ms): every frame of the window.
fn polled() -> Vec<CanFrame> {
    let mut bus = bus();
    allocate(&mut bus, 0x03, 2, 10);
    let start = bus.now();
    let mut frames = Vec::new();
    let mut next = start;
    while next < start + WINDOW {
        bus.send(&CanFrame::from_raw(0x42D, &[0; 8]).expect("a valid frame")).expect("sent");
        next += Duration::from_millis(10);
        frames.extend(drain(&mut bus, next));
    }
    frames
}

/// Change of state with a 10 s heartbeat; the master acknowledges each production (the last
/// fragment, type 2) unless `suppressed`: every frame of the window.
fn change_of_state(suppressed: bool) -> Vec<CanFrame> {
    let mut bus = bus();
    allocate(&mut bus, if suppressed { 0x51 } else { 0x11 }, 4, 10_000);
    let end = bus.now() + WINDOW;
    let mut frames = Vec::new();
    while let Some(event) = bus.recv(end).expect("the simulated bus does not fail") {
        let f = event.frame;
        frames.push(f);
        if !suppressed && f.id().as_raw() == 0x345 && f.data().first().is_some_and(|b| b & 0xC0 == 0x80) {
            bus.send(&CanFrame::from_raw(0x42A, &[]).expect("a valid frame")).expect("sent");
        }
    }
    frames
}

/// Wall-clock latency in the converter: `samples` instrument frames with new data, each handed
/// over in one call, to the first COS fragment out. Returns the sorted latencies.
fn latency(samples: usize) -> Vec<std::time::Duration> {
    let mut now = Instant::ZERO;
    let mut c = Converter::new(ConverterConfig::breaker_reference(), now).expect("the reference converter");
    c.power_on(now);
    let step = |c: &mut Converter, until: Instant, now: &mut Instant| {
        while let Some(at) = c.poll_at().filter(|&at| at <= until) {
            *now = at.max(*now);
            c.handle_timeout(*now);
            while c.poll_can_transmit().is_some() {}
        }
        *now = until;
    };
    step(&mut c, Instant::from_secs(3), &mut now);
    for (id, data) in [
        (0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x11, 0x00][..]),
        (0x42C, &[0x00, 0x10, 0x05, 0x04, 0x09, 0x10, 0x27]),
    ] {
        c.handle_can_frame(&CanFrame::from_raw(id, data).expect("a valid frame"), now);
        while c.poll_can_transmit().is_some() {}
    }
    let mut breaker = SimulatedBreaker::new(now).with_period(Duration::from_millis(100));
    breaker.set_switch(slave_fw::serial::breaker::SwitchState::Closed);
    let mut out = Vec::with_capacity(samples);
    for i in 0..samples {
        breaker.set_load([(i % 200) as u8, 1, 2, 3]);
        now += Duration::from_millis(100);
        step(&mut c, now, &mut now);
        // Acknowledge the last production, so no retry is pending.
        c.handle_can_frame(&CanFrame::from_raw(0x42A, &[]).expect("a valid frame"), now);
        while c.poll_can_transmit().is_some() {}
        let Some(bytes) = breaker.poll_transmit(now) else { continue };
        let start = std::time::Instant::now();
        c.handle_serial(&bytes, now);
        let first = std::iter::from_fn(|| c.poll_can_transmit()).find(|f| f.id().as_raw() == 0x345);
        let took = start.elapsed();
        // Only a production that carries this frame's load (input byte 0 of the breaker image)
        // counts: the first fragment is `00` then input bytes 0-6.
        if first.is_some_and(|f| f.data().get(1) == Some(&((i % 200) as u8))) {
            out.push(took);
        }
        while c.poll_can_transmit().is_some() {}
    }
    out.sort();
    out
}

fn main() {
    println!("bus load at 250 kbit/s over {} s of simulated bus time, breaker at MAC 5 (18 bytes in, 8 out), instrument period 1 s:", WINDOW.total_millis() / 1000);
    for (name, frames) in [
        ("poll every 10 ms (EPR 10 ms)", polled()),
        ("change of state, acknowledged (EPR 10 s)", change_of_state(false)),
        ("change of state, ack suppressed (EPR 10 s)", change_of_state(true)),
    ] {
        let (per_s, percent) = load(&frames);
        println!("  {name:<45} {per_s:>8.1} frames/s  {percent:>6.2} % of bus time");
    }
    let lat = latency(10_000);
    assert!(!lat.is_empty(), "no COS production carried the instrument's new data: nothing measured");
    let pick = |q: f64| lat[((lat.len() - 1) as f64 * q) as usize].as_nanos();
    let mean = lat.iter().map(|d| d.as_nanos()).sum::<u128>() / lat.len() as u128;
    println!(
        "latency, new instrument data to the first COS fragment, in the converter (wall clock, {} samples): median {} ns, mean {mean} ns, 99th percentile {} ns",
        lat.len(),
        pick(0.5),
        pick(0.99)
    );
}
