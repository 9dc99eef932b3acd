//! The converter (slave node + breaker profile) against the simulated breaker on a virtual clock:
//! the 28-frame bring-up with the breaker's real data, commands through the poll output executed
//! exactly once, stale detection reported to the scanner, the vendor objects, and the Identity
//! Reset the converter schedules.

use converter_sim::SoftSlave;
use devicenet::reference::{Direction, BRING_UP};
use devicenet::slave::ConnectionState;
use devicenet::{CanFrame, Duration, Instant};
use slave_fw::converter::{Converter, ConverterConfig, InputAssembly, ResetKind, RESET_DELAY};
use slave_fw::serial::breaker::{BreakerCommand, SwitchState};
use slave_fw::serial::{HealthConfig, ProfileConfig, StalePolicy};

struct Rig {
    slave: SoftSlave,
    now: Instant,
}

type Tx = Vec<(u16, Vec<u8>)>;

impl Rig {
    fn new(config: ConverterConfig) -> Rig {
        Rig { slave: SoftSlave::new(config).unwrap(), now: Instant::ZERO }
    }

    fn advance(&mut self, d: Duration) -> Tx {
        let end = self.now + d;
        let mut out = Tx::new();
        while let Some(at) = self.slave.poll_at().filter(|&at| at <= end) {
            self.now = at.max(self.now);
            self.slave.handle_timeout(self.now);
            out.extend(self.drain());
        }
        self.now = end;
        self.slave.handle_timeout(end);
        out.extend(self.drain());
        out
    }

    fn drain(&mut self) -> Tx {
        std::iter::from_fn(|| self.slave.poll_transmit())
            .map(|f| (f.id().as_raw(), f.data().to_vec()))
            .collect()
    }

    fn send(&mut self, id: u16, data: &[u8]) -> Tx {
        self.slave.handle_frame(&CanFrame::from_raw(id, data).unwrap(), self.now);
        self.drain()
    }

    /// Powers on at 2 s (the master is on-line) and plays the master's side of protocol §2.
    fn bring_up(&mut self) -> Tx {
        let mut seen = Tx::new();
        self.advance(Duration::from_secs(2));
        self.slave.power_on(self.now);
        seen.extend(self.drain());
        seen.extend(self.advance(Duration::from_secs(2)));
        for f in BRING_UP.iter().filter(|f| f.direction == Direction::MasterToSlave).skip(2) {
            seen.extend(self.advance(Duration::from_millis(10)));
            seen.push((f.id, f.data.to_vec()));
            seen.extend(self.send(f.id, f.data));
        }
        seen
    }

    /// The bring-up, then a 5 s EPR so the test can take its time between polls.
    fn established(&mut self) {
        self.bring_up();
        let epr = self.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x88, 0x13]);
        assert_eq!(epr, vec![(0x42B, vec![0x00, 0x90, 0x88, 0x13])]);
    }

    /// One poll cycle with `outputs`, returning the reassembled 18-byte response.
    fn poll(&mut self, outputs: &[u8]) -> Vec<u8> {
        self.advance(Duration::from_millis(50));
        let frames = self.send(0x42D, outputs);
        frames.iter().filter(|(id, _)| *id == 0x3C5).flat_map(|(_, d)| d[1..].to_vec()).collect()
    }
}

#[test]
fn bring_up_with_the_breakers_own_data() {
    let mut rig = Rig::new(ConverterConfig::breaker_reference());
    let seen = rig.bring_up();
    // Everything but the master's own duplicate MAC checks, which the rig does not send.
    let expected: Tx = BRING_UP.iter().skip(2).map(|f| (f.id, f.data.to_vec())).collect();
    assert_eq!(seen, expected, "the breaker starts open with zero currents: the reference image");
}

#[test]
fn open_and_close_reach_the_breaker_exactly_once() {
    let mut rig = Rig::new(ConverterConfig::breaker_reference());
    rig.established();
    rig.slave.breaker_mut().set_switch(SwitchState::Closed);
    rig.advance(Duration::from_millis(1100));
    assert_eq!(rig.poll(&[0; 8])[9], 0xF0, "closed shows in the next status frame");
    // Open, sequence 1, repeated a hundred times.
    for _ in 0..100 {
        rig.poll(&[1, 1, 0, 0, 0, 0, 0, 0]);
    }
    assert_eq!(rig.slave.breaker().commands(), &[BreakerCommand::Open]);
    rig.advance(Duration::from_millis(1100));
    assert_eq!(rig.poll(&[1, 1, 0, 0, 0, 0, 0, 0])[9], 0x0F);
    // Close with a new sequence number, also once.
    for _ in 0..20 {
        rig.poll(&[2, 2, 0, 0, 0, 0, 0, 0]);
    }
    assert_eq!(rig.slave.breaker().commands(), &[BreakerCommand::Open, BreakerCommand::Close]);
    assert_eq!(rig.slave.breaker().switch_state(), SwitchState::Closed);
}

#[test]
fn idle_polls_and_poll_timeouts_never_send_a_command() {
    let mut rig = Rig::new(ConverterConfig::breaker_reference());
    rig.bring_up();
    for _ in 0..10 {
        rig.poll(&[]);
    }
    rig.advance(Duration::from_secs(2)); // 4 x EPR: the poll connection times out
    assert_eq!(rig.slave.converter().node().poll_connection().state, ConnectionState::TimedOut);
    assert!(rig.slave.breaker().commands().is_empty());
}

#[test]
fn silent_breaker_is_reported_stale() {
    let mut config = ConverterConfig::breaker_reference();
    config.input = InputAssembly::WithStatus;
    if let ProfileConfig::Framed(f) = &mut config.profile {
        f.health = HealthConfig { stale_timeout_ms: 2500, stale_policy: StalePolicy::Clear };
    }
    let mut rig = Rig::new(config);
    // The 28-frame sequence with a 20-byte produced size: read it and poll.
    rig.advance(Duration::from_secs(2));
    rig.slave.power_on(rig.now);
    rig.advance(Duration::from_secs(2));
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x03, 0x00]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x05, 0x02, 0x07]), vec![(0x42B, vec![0x00, 0x8E, 20, 0x00])]);
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0xE8, 0x03]); // EPR 1000 ms
    rig.slave.breaker_mut().set_load([10, 20, 30, 40]);
    rig.slave.breaker_mut().set_switch(SwitchState::Closed);
    rig.advance(Duration::from_millis(1100));
    let fresh = rig.poll(&[0; 8]);
    assert_eq!(&fresh[..4], &[10, 20, 30, 40]);
    assert_eq!(fresh[18] & 0x01, 0x01, "link ok");
    let counter = fresh[19];
    rig.advance(Duration::from_millis(1000));
    rig.advance(Duration::from_millis(100));
    assert_ne!(rig.poll(&[0; 8])[19], counter, "freshness counter moves with new frames");
    rig.slave.breaker_mut().set_silent(true);
    let mut stale = Vec::new();
    for _ in 0..8 {
        stale = rig.poll(&[0; 8]);
        rig.advance(Duration::from_millis(500));
    }
    assert_eq!(stale[18] & 0x03, 0x02, "status byte: timeout, not ok");
    assert_eq!(&stale[..4], &[0, 0, 0, 0], "clear policy");
    let status = rig.slave.converter().node().identity_status();
    assert_eq!(status & 0x100, 0x100, "minor recoverable fault");
    assert_eq!(rig.slave.converter().node().module_indication(), devicenet::led::Indication::FlashingRed);
}

#[test]
fn vendor_objects_over_explicit_messaging() {
    let mut rig = Rig::new(ConverterConfig::breaker_reference());
    rig.established();
    rig.advance(Duration::from_secs(3));
    // Frames received (class 0x64, instance 1, attribute 1): a UDINT.
    let resp = rig.send(0x42C, &[0x00, 0x0E, 0x64, 0x01, 0x01]);
    let (_, data) = &resp[0];
    assert_eq!(&data[..2], &[0x00, 0x8E]);
    let frames = u32::from_le_bytes(data[2..6].try_into().unwrap());
    assert!(frames >= 6, "about one status frame a second since t=0: {frames}");
    // Settings: baud 9600, stale timeout 3000 ms, assembly 100.
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x0E, 0x65, 0x01, 0x01]),
        vec![(0x42B, vec![0x00, 0x8E, 0x80, 0x25, 0, 0])]
    );
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x65, 0x01, 0x06]), vec![(0x42B, vec![0x00, 0x8E, 100])]);
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x10, 0x65, 0x01, 0x05, 1]),
        vec![(0x42B, vec![0x00, 0x94, 0x0E, 0xFF])]
    );
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x65, 0x01, 0x63]), vec![(0x42B, vec![0x00, 0x94, 0x14, 0xFF])]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x65, 0x02, 0x01]), vec![(0x42B, vec![0x00, 0x94, 0x16, 0xFF])]);
}

#[test]
fn garbage_on_the_serial_line_is_counted_and_survived() {
    let mut rig = Rig::new(ConverterConfig::breaker_reference());
    rig.established();
    let now = rig.now;
    rig.slave.breaker_mut().send_garbage(&[0x68, 0x99, 0x01, 0x16, 0xFF, 0x00], now);
    rig.slave.breaker_mut().corrupt_next_frames(2);
    rig.advance(Duration::from_secs(4));
    let stats = rig.slave.converter().profile().stats();
    assert!(stats.checksum_errors >= 2, "{stats:?}");
    rig.slave.breaker_mut().set_load([7, 0, 0, 0]);
    rig.slave.breaker_mut().set_switch(SwitchState::Closed);
    rig.advance(Duration::from_millis(1100));
    assert_eq!(rig.poll(&[0; 8])[0], 7, "still converting");
}

#[test]
fn identity_reset_power_cycles_the_converter() {
    let mut rig = Rig::new(ConverterConfig::breaker_reference());
    rig.established();
    // The response, then the shutdown message (§II.5.2).
    let shutdown = vec![0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00];
    assert_eq!(
        rig.send(0x42C, &[0x00, 0x05, 0x01, 0x01]),
        vec![(0x42B, vec![0x00, 0x85]), (0x42B, shutdown)]
    );
    // RESET_DELAY later the node restarts its duplicate MAC ID check, connections gone.
    let before = rig.advance(Duration::from_micros(slave_fw::converter::RESET_DELAY.total_micros() - 1000));
    assert_eq!(before, vec![], "nothing before the converter's reset delay");
    let after = rig.advance(Duration::from_millis(10));
    assert_eq!(after, vec![(0x42F, vec![0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12])]);
    assert_eq!(rig.slave.converter().node().poll_connection().state, ConnectionState::NonExistent);
    assert!(std::iter::from_fn(|| rig.slave.poll_event()).any(|e| e == devicenet::Event::ResetRequested(0)));
}

/// A bare converter (no instrument) brought up as in protocol §2, with its explicit and
/// poll connections established; returns it with the time and its drained frames.
/// The class instance (0) of the serial link, settings and configuration objects: revision 1 and
/// nothing else, served by the node for them (`ObjectHandler::class_revision`).
#[test]
fn vendor_class_instances_serve_their_revision() {
    let (mut c, now) = bare_established();
    for class in [0x64, 0x65, 0x66] {
        let get = |c: &mut Converter, data: &[u8]| {
            let mut req = vec![0x00, 0x0E, class, 0x00];
            req.extend_from_slice(data);
            explicit(c, now, &req)
        };
        assert_eq!(get(&mut c, &[1]), vec![vec![0x00, 0x8E, 1, 0]], "class {class:#x} revision");
        assert_eq!(get(&mut c, &[2]), vec![vec![0x00, 0x94, 0x14, 0xFF]], "class {class:#x} attribute 2");
        assert_eq!(get(&mut c, &[]), vec![vec![0x00, 0x94, 0x13, 0xFF]], "class {class:#x} no attribute");
        assert_eq!(get(&mut c, &[1, 2]), vec![vec![0x00, 0x94, 0x15, 0xFF]], "class {class:#x} too much");
        assert_eq!(
            explicit(&mut c, now, &[0x00, 0x10, class, 0x00, 0x01, 0x01]),
            vec![vec![0x00, 0x94, 0x08, 0xFF]],
            "class {class:#x} Set"
        );
    }
}

fn bare_established() -> (Converter, Instant) {
    let mut c = Converter::new(ConverterConfig::breaker_reference(), Instant::ZERO).unwrap();
    let mut now = Instant::from_millis(2000);
    c.power_on(now);
    let end = now + Duration::from_secs(2);
    while let Some(at) = c.poll_at().filter(|&at| at <= end) {
        now = at.max(now);
        c.handle_timeout(now);
        while c.poll_can_transmit().is_some() {}
    }
    for f in BRING_UP.iter().filter(|f| f.direction == Direction::MasterToSlave).skip(2) {
        now += Duration::from_millis(10);
        c.handle_can_frame(&CanFrame::from_raw(f.id, f.data).unwrap(), now);
        while c.poll_can_transmit().is_some() {}
    }
    while c.poll_event().is_some() {}
    (c, now)
}

#[test]
fn identity_reset_is_due_reset_delay_after_the_request_and_once() {
    let (mut c, now) = bare_established();
    c.handle_can_frame(&CanFrame::from_raw(0x42C, &[0x00, 0x05, 0x01, 0x01]).unwrap(), now);
    let response: Vec<_> = std::iter::from_fn(|| c.poll_can_transmit()).collect();
    let shutdown = CanFrame::from_raw(0x42B, &[0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00]).unwrap();
    assert_eq!(
        response,
        vec![CanFrame::from_raw(0x42B, &[0x00, 0x85]).unwrap(), shutdown],
        "the response first, then the shutdown message"
    );
    assert_eq!(c.poll_event(), Some(devicenet::Event::ResetRequested(0)));
    let due = now + RESET_DELAY;
    assert!(c.poll_at().is_some_and(|at| at <= due), "poll_at includes the reset");
    assert_eq!(c.poll_reset(now), None);
    // A second request does not postpone the reset.
    let later = now + Duration::from_millis(50);
    c.handle_can_frame(&CanFrame::from_raw(0x42C, &[0x00, 0x05, 0x01, 0x01, 0x01]).unwrap(), later);
    assert_eq!(c.poll_reset(now + Duration::from_micros(RESET_DELAY.total_micros() - 1)), None);
    assert_eq!(c.poll_reset(due), Some(ResetKind::PowerCycle));
    assert_eq!(c.poll_reset(due + RESET_DELAY), None, "reported once");
}

#[test]
fn polls_are_consumed_not_passed_on_as_events() {
    let (mut c, mut now) = bare_established();
    // EPR 5 s, then a hundred polls: not one event, the queue stays free for the ones that matter.
    c.handle_can_frame(&CanFrame::from_raw(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x88, 0x13]).unwrap(), now);
    while c.poll_can_transmit().is_some() {}
    while c.poll_event().is_some() {}
    for n in 0..100u8 {
        now += Duration::from_millis(10);
        let data = if n % 10 == 0 { vec![] } else { vec![0; 8] };
        c.handle_can_frame(&CanFrame::from_raw(0x42D, &data).unwrap(), now);
        assert_eq!(
            std::iter::from_fn(|| c.poll_can_transmit()).count(),
            3,
            "an 18-byte response, fragmented"
        );
        assert_eq!(c.poll_event(), None);
    }
}

#[test]
fn reset_kinds_keep_their_type_byte() {
    for raw in 0..=255u8 {
        assert_eq!(ResetKind::from_raw(raw).as_raw(), raw);
    }
    assert_eq!(ResetKind::from_raw(1), ResetKind::OutOfBox);
}

/// One unfragmented explicit request on the explicit connection (MAC 5: 0x42C); the reply frames.
fn explicit(c: &mut Converter, now: Instant, data: &[u8]) -> Vec<Vec<u8>> {
    c.handle_can_frame(&CanFrame::from_raw(0x42C, data).unwrap(), now);
    std::iter::from_fn(|| c.poll_can_transmit())
        .filter(|f| f.id().as_raw() == 0x42B)
        .map(|f| f.data().to_vec())
        .collect()
}

fn modbus_image() -> Vec<u8> {
    use slave_fw::serial::modbus::{Function, ModbusConfig, ScanEntry};
    let scan = [ScanEntry {
        unit: 1,
        function: Function::ReadInputRegisters,
        address: 0,
        count: 4,
        offset: 0,
        word_order: Default::default(),
        period_ms: None,
        write: Default::default(),
        trigger_offset: None,
    }];
    let config = ConverterConfig {
        profile: ProfileConfig::Modbus(ModbusConfig::new(scan.into_iter().collect())),
        ..ConverterConfig::breaker_reference()
    };
    slave_fw::image::encode_to_vec(&config).unwrap()
}

#[test]
fn a_modbus_image_is_downloaded_in_chunks_and_handed_over() {
    let (mut c, mut now) = bare_established();
    // Release the poll connection (DeviceNet object Release, choice 0x02): explicit only.
    assert_eq!(explicit(&mut c, now, &[0x00, 0x4C, 0x03, 0x01, 0x02]), vec![vec![0x00, 0xCC]]);
    let image = modbus_image();
    // State 0: the factory default is in force.
    assert_eq!(explicit(&mut c, now, &[0x00, 0x0E, 0x66, 0x01, 0x03]), vec![vec![0x00, 0x8E, 0]]);
    let size = (image.len() as u16).to_le_bytes();
    assert_eq!(explicit(&mut c, now, &[0x00, 0x4C, 0x66, 0x01, size[0], size[1]]), vec![vec![0x00, 0xCC]]);
    // Two bytes per request: an unfragmented Write_Chunk has room for no more.
    for (k, chunk) in image.chunks(2).enumerate() {
        now += Duration::from_millis(1);
        let offset = ((k * 2) as u16).to_le_bytes();
        let mut req = vec![0x00, 0x4D, 0x66, 0x01, offset[0], offset[1]];
        req.extend_from_slice(chunk);
        assert_eq!(explicit(&mut c, now, &req), vec![vec![0x00, 0xCD]], "chunk {k}");
    }
    assert_eq!(c.poll_new_image(), None, "nothing before the commit");
    assert_eq!(explicit(&mut c, now, &[0x00, 0x4E, 0x66, 0x01]), vec![vec![0x00, 0xCE]]);
    assert_eq!(c.poll_new_image(), Some(image.as_slice()));
    assert_eq!(c.poll_new_image(), None, "handed over once");
    // State 2: stored, applies at the next reset; the breaker profile still runs.
    assert_eq!(explicit(&mut c, now, &[0x00, 0x0E, 0x66, 0x01, 0x03]), vec![vec![0x00, 0x8E, 2]]);
    assert!(matches!(slave_fw::image::decode(&image).unwrap().profile, ProfileConfig::Modbus(_)));
    // The next start runs it, and says it is the stored image.
    let stored = slave_fw::image::decode(&image).unwrap();
    let c2 = Converter::with_origin(stored, slave_fw::converter::ConfigOrigin::Stored, now).unwrap();
    assert_eq!(c2.config_state(), slave_fw::converter::ConfigState::Stored);
}

#[test]
fn a_download_is_refused_while_polled() {
    let (mut c, now) = bare_established();
    assert_eq!(explicit(&mut c, now, &[0x00, 0x4C, 0x66, 0x01, 98, 0]), vec![vec![0x00, 0x94, 0x10, 0xFF]]);
    assert_eq!(explicit(&mut c, now, &[0x00, 0x4D, 0x66, 0x01, 0, 0, 1]), vec![vec![0x00, 0x94, 0x10, 0xFF]]);
    assert_eq!(c.poll_new_image(), None);
}

#[test]
fn parameters_are_set_into_the_pending_image_and_refused_while_polled() {
    let (mut c, now) = bare_established();
    // Parameter class attribute 2: nine instances (protocol §II.4.3 byte examples).
    assert_eq!(explicit(&mut c, now, &[0x00, 0x0E, 0x0F, 0x00, 0x02]), vec![vec![0x00, 0x8E, 9, 0]]);
    // Instance 2 (serial parity) attribute 1: none.
    assert_eq!(explicit(&mut c, now, &[0x00, 0x0E, 0x0F, 0x02, 0x01]), vec![vec![0x00, 0x8E, 0]]);
    // While the poll connection is established: object state conflict.
    assert_eq!(explicit(&mut c, now, &[0x00, 0x10, 0x0F, 0x02, 0x01, 2]), vec![vec![0x00, 0x94, 0x0C, 0xFF]]);
    assert_eq!(c.poll_new_image(), None);
    assert_eq!(explicit(&mut c, now, &[0x00, 0x4C, 0x03, 0x01, 0x02]), vec![vec![0x00, 0xCC]]);
    // Out of range (retries 11): invalid attribute value, nothing handed over.
    assert_eq!(
        explicit(&mut c, now, &[0x00, 0x10, 0x0F, 0x08, 0x01, 11]),
        vec![vec![0x00, 0x94, 0x09, 0xFF]]
    );
    assert_eq!(c.poll_new_image(), None);
    assert_eq!(c.config_state(), slave_fw::converter::ConfigState::FactoryDefault);
    // Even parity: pending, handed over as a download is, the running profile unchanged.
    assert_eq!(explicit(&mut c, now, &[0x00, 0x10, 0x0F, 0x02, 0x01, 2]), vec![vec![0x00, 0x90]]);
    let image = c.poll_new_image().unwrap().to_vec();
    let pending = slave_fw::image::decode(&image).unwrap();
    assert_eq!(pending.profile.serial().parity, slave_fw::serial::Parity::Even);
    assert_eq!(c.config_state(), slave_fw::converter::ConfigState::Pending);
    assert_eq!(explicit(&mut c, now, &[0x00, 0x0E, 0x0F, 0x02, 0x01]), vec![vec![0x00, 0x8E, 2]]);
    assert_eq!(explicit(&mut c, now, &[0x00, 0x0E, 0x0F, 0x02, 0x0C]), vec![vec![0x00, 0x8E, 0]]);
    assert_eq!(c.profile().serial_settings().parity, slave_fw::serial::Parity::None);
}
