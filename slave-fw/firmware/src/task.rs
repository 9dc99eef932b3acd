//! The converter task's work, apart from RTIC and the peripherals, so that the host tests run it.
//!
//! `app::converter_task` (main.rs) runs when an input was queued or the next deadline is due, then
//! hands what it got to a [`ConverterTask`]: [`ConverterTask::take_inputs`] for the queued inputs,
//! [`ConverterTask::handle_timeout`] for the timers. The board's side of every output (the CAN
//! transmit queue, the instrument USART, the settings flash, the reset) is behind the [`Hardware`] trait.
//!
//! Every input is followed by a full drain, in the converter's order (frames, instrument bytes,
//! events and a downloaded configuration image, stored in the settings journal; a due reset; `slave_fw::converter` module docs), before the next input is handed over:
//! the node queues at most 16 frames and the converter 8 events, and a burst of inputs taken
//! without draining would push responses and a `ResetRequested` or `SettingChanged` out of them.
//! Consecutive instrument bytes are one input (up to [`SERIAL_BATCH`] bytes in one
//! `handle_serial` call).
//!
//! Beside the converter the task may own an [`Application`] object: the firmware update object
//! (class 0x6A, `slave_fw::update`) on the real boards (`crate::update`), none ([`NoApplication`])
//! on the emulated board, where requests to its class get 0x16. Frames reach it through
//! `Converter::handle_can_frame_with`, as on the soft slave; it sees the events, and its reset
//! (Apply's) is carried out in the drain after the converter's.

use crate::log::{log_info as info, log_warn as warn};
use board::settings::Settings;
use devicenet::led::Leds;
use devicenet::slave::{Event, SettingChanged};
use devicenet::{CanFrame, Instant, MacId};
use embedded_storage::nor_flash::NorFlash;
use slave_fw::converter::{ApplicationObject, Converter, ResetKind};
use slave_fw::serial::trace::TraceKind;
use slave_fw::update::{MarkUpdated, UpdateObject};

/// Capacity of the converter task's input queue, and the most inputs taken per wake-up.
pub const INPUTS: usize = 64;
/// Instrument bytes handed to the converter in one call.
pub const SERIAL_BATCH: usize = 32;

/// What interrupts hand to the converter task.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    /// A frame for this node.
    Frame(CanFrame),
    /// The CAN controller went bus-off.
    BusOff,
    /// A byte from the instrument.
    InstrumentByte(u8),
    /// A line event of the instrument's USART (an error, an RS-485 driver edge), for the
    /// serial-line analyzer.
    LineEvent(TraceKind),
}

/// The board's side of the converter task's outputs.
pub trait Hardware {
    /// Queues `frame` for the CAN controller.
    fn send_frame(&mut self, frame: CanFrame);
    /// Queues `bytes` (one frame) for the instrument's UART.
    fn send_serial(&mut self, bytes: &[u8]);
    /// Resets the CAN controller after bus-off (bus-off interrupt setting 1, protocol §7.2).
    fn restart_can(&mut self);
    /// Receives for MAC ID `mac` from now on (taken through the Offline Connection Set, §II.6).
    fn set_can_mac(&mut self, mac: MacId);
    /// Stores `settings` in non-volatile memory; `false` when that failed.
    fn save_settings(&mut self, settings: &Settings) -> bool;
    /// Resets the device (Identity Reset, protocol §3.2); on the board this does not return.
    fn reset(&mut self, kind: ResetKind);
    /// Sees every event the converter passes on, before the task acts on it (the log; on a real
    /// board, `Event::Online` confirms an image on trial).
    fn event(&mut self, _event: &Event) {}
    /// The running image is on trial and has not confirmed (after [`Hardware::event`] saw
    /// `Event::Online`, a confirmation that failed or was withheld).
    fn image_on_trial(&self) -> bool {
        false
    }
}

/// An object the application serves beside the converter's own (module docs).
pub trait Application {
    /// The object for `Converter::handle_can_frame_with`; `None`: requests to a class neither
    /// the node nor the converter serves get 0x16 (object does not exist).
    fn object(&mut self) -> Option<&mut dyn ApplicationObject>;
    /// Sees every event the converter passes on (the update session ends with the explicit
    /// connection).
    fn on_event(&mut self, event: &Event);
    /// The running image confirmed itself: on-line and not on trial any more.
    fn confirmed(&mut self);
    /// `true` once, when the object's reset is due (the update object's, after Apply).
    fn poll_reset(&mut self, now: Instant) -> bool;
    /// When [`Application::poll_reset`] must run next.
    fn poll_at(&self) -> Option<Instant>;
}

/// No object beside the converter's (the emulated board).
pub struct NoApplication;

impl Application for NoApplication {
    fn object(&mut self) -> Option<&mut dyn ApplicationObject> {
        None
    }
    fn on_event(&mut self, _: &Event) {}
    fn confirmed(&mut self) {}
    fn poll_reset(&mut self, _: Instant) -> bool {
        false
    }
    fn poll_at(&self) -> Option<Instant> {
        None
    }
}

/// An object, or none (the firmware's when the bootloader's key block is missing).
impl<T: Application> Application for Option<T> {
    fn object(&mut self) -> Option<&mut dyn ApplicationObject> {
        self.as_mut().and_then(T::object)
    }
    fn on_event(&mut self, event: &Event) {
        if let Some(app) = self {
            app.on_event(event);
        }
    }
    fn confirmed(&mut self) {
        if let Some(app) = self {
            app.confirmed();
        }
    }
    fn poll_reset(&mut self, now: Instant) -> bool {
        self.as_mut().is_some_and(|app| app.poll_reset(now))
    }
    fn poll_at(&self) -> Option<Instant> {
        self.as_ref().and_then(T::poll_at)
    }
}

/// The firmware update object: its session ends with the explicit connection, a trial ends
/// with the confirmation, and Apply's reset is [`UpdateObject::poll_reset`]'s.
impl<F: NorFlash, M: MarkUpdated> Application for UpdateObject<F, M> {
    fn object(&mut self) -> Option<&mut dyn ApplicationObject> {
        Some(self)
    }
    fn on_event(&mut self, event: &Event) {
        UpdateObject::on_event(self, event);
    }
    fn confirmed(&mut self) {
        self.confirm();
    }
    fn poll_reset(&mut self, now: Instant) -> bool {
        UpdateObject::poll_reset(self, now)
    }
    fn poll_at(&self) -> Option<Instant> {
        UpdateObject::poll_at(self)
    }
}

/// The converter, the settings in force and the application's object: everything the converter
/// task owns besides the LEDs.
pub struct ConverterTask<A = NoApplication> {
    converter: Converter,
    settings: Settings,
    application: A,
}

#[cfg(test)]
impl ConverterTask {
    /// The task for `converter`, running with the stored `settings`, without an object beside
    /// the converter's (the tests').
    pub fn new(converter: Converter, settings: Settings) -> ConverterTask {
        ConverterTask::with_application(converter, settings, NoApplication)
    }
}

impl<A: Application> ConverterTask<A> {
    /// The task for `converter`, running with the stored `settings`, serving `application`'s
    /// object too.
    pub fn with_application(converter: Converter, settings: Settings, application: A) -> ConverterTask<A> {
        ConverterTask { converter, settings, application }
    }

    /// Powers the converter on at `now` and drains.
    pub fn power_on(&mut self, now: Instant, hw: &mut impl Hardware) {
        self.converter.power_on(now);
        self.drain(now, hw);
    }

    /// Hands `first` and then the inputs `next` yields (at most [`INPUTS`] in all, so timers are
    /// never starved) to the converter, draining after each; consecutive instrument bytes go as
    /// one input.
    pub fn take_inputs(
        &mut self,
        first: Input,
        mut next: impl FnMut() -> Option<Input>,
        now: Instant,
        hw: &mut impl Hardware,
    ) {
        let mut serial = heapless::Vec::<u8, SERIAL_BATCH>::new();
        let mut current = first;
        for taken in 1..=INPUTS {
            match current {
                Input::InstrumentByte(b) => {
                    if serial.is_full() {
                        self.serial(&mut serial, now, hw);
                    }
                    // Room was made above.
                    let _ = serial.push(b);
                }
                Input::Frame(frame) => {
                    self.serial(&mut serial, now, hw);
                    match self.application.object() {
                        Some(object) => self.converter.handle_can_frame_with(&frame, now, object),
                        None => self.converter.handle_can_frame(&frame, now),
                    }
                    self.drain(now, hw);
                }
                Input::LineEvent(kind) => {
                    // After the bytes before it, so the analyzer keeps the line's order.
                    self.serial(&mut serial, now, hw);
                    self.converter.record_line_event(kind, now);
                }
                Input::BusOff => {
                    self.serial(&mut serial, now, hw);
                    warn!("CAN bus-off");
                    self.converter.handle_bus_off(now);
                    self.drain(now, hw);
                }
            }
            // Never take an input beyond the bound: it would be lost.
            match (taken < INPUTS).then(&mut next).flatten() {
                Some(input) => current = input,
                None => break,
            }
        }
        self.serial(&mut serial, now, hw);
    }

    /// Runs the timers due at `now` and drains (a due reset included).
    pub fn handle_timeout(&mut self, now: Instant, hw: &mut impl Hardware) {
        self.converter.handle_timeout(now);
        self.drain(now, hw);
    }

    /// When [`ConverterTask::handle_timeout`] must run next (the application's reset included).
    pub fn poll_at(&self) -> Option<Instant> {
        match (self.converter.poll_at(), self.application.poll_at()) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// The LEDs at `now`.
    pub fn leds(&self, now: Instant) -> Leds {
        self.converter.leds(now)
    }

    /// The converter (the tests look into it).
    #[cfg(test)]
    pub fn converter(&self) -> &Converter {
        &self.converter
    }

    /// The application's object (the tests look into it).
    #[cfg(test)]
    pub fn application(&self) -> &A {
        &self.application
    }

    /// The settings in force, with the changes made over the network (the tests look at them).
    #[cfg(test)]
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Hands the batched instrument bytes over, if any, and drains.
    fn serial(&mut self, batch: &mut heapless::Vec<u8, SERIAL_BATCH>, now: Instant, hw: &mut impl Hardware) {
        if !batch.is_empty() {
            self.converter.handle_serial(batch, now);
            batch.clear();
            self.drain(now, hw);
        }
    }

    /// The converter's outputs, in its drain order: frames, instrument bytes, events, a downloaded
    /// image (stored), a due reset.
    fn drain(&mut self, now: Instant, hw: &mut impl Hardware) {
        while let Some(frame) = self.converter.poll_can_transmit() {
            hw.send_frame(frame);
        }
        while let Some(bytes) = self.converter.poll_serial_transmit(now) {
            hw.send_serial(bytes);
        }
        while let Some(event) = self.converter.poll_event() {
            hw.event(&event);
            self.on_event(event, hw);
        }
        if let Some(image) = self.converter.poll_new_image() {
            store_image(&mut self.settings, image, hw);
        }
        // An Identity Reset, or Apply's reset into the bootloader (a power cycle), each
        // RESET_DELAY after its request; the response drained first, above.
        let due = self.converter.poll_reset(now);
        if let Some(kind) = due.or_else(|| self.application.poll_reset(now).then_some(ResetKind::PowerCycle))
        {
            info!("reset, type {=u8}", kind.as_raw());
            hw.reset(kind);
        }
    }

    /// The application's part of an event: outputs, idle polls and connection faults are the
    /// converter's, and so is the reset's timing.
    fn on_event(&mut self, event: Event, hw: &mut impl Hardware) {
        self.application.on_event(&event);
        match event {
            // `hw.event` has seen it first: a trial image has confirmed, unless it is still on trial.
            Event::Online if !hw.image_on_trial() => self.application.confirmed(),
            Event::ResetCanController => hw.restart_can(),
            Event::SettingChanged(change) => {
                match change {
                    SettingChanged::MacId(mac) => self.settings.mac_id = mac,
                    SettingChanged::BaudRate(rate) => self.settings.baud_rate = rate,
                    SettingChanged::BusOffInterrupt(boi) => self.settings.bus_off_interrupt = boi,
                }
                self.save(hw);
            }
            // Taken at once through the Offline Connection Set, and stored like a network-set one.
            Event::MacIdChanged(mac) => {
                hw.set_can_mac(mac);
                self.settings.mac_id = mac;
                self.save(hw);
            }
            _ => {}
        }
    }
}

impl<A: Application> ConverterTask<A> {
    /// Stores the settings in force.
    fn save(&mut self, hw: &mut impl Hardware) {
        if !hw.save_settings(&self.settings) {
            warn!("settings: save failed");
        }
    }
}

/// Stores a downloaded, validated configuration image with the network `settings` in force (one
/// journal record, power-safe), to run from the next reset. An image larger than a record holds
/// cannot come (`MAX_IMAGE <= IMAGE_CAPACITY`, checked at compile time in `config`); it would be
/// refused, not cut.
fn store_image(settings: &mut Settings, image: &[u8], hw: &mut impl Hardware) {
    // The network settings and the new image, without copying the old image first.
    let mut new = Settings {
        mac_id: settings.mac_id,
        baud_rate: settings.baud_rate,
        bus_off_interrupt: settings.bus_off_interrupt,
        last_switches: settings.last_switches,
        image: heapless::Vec::new(),
    };
    if new.image.extend_from_slice(image).is_err() {
        warn!("configuration image: too large to store");
        return;
    }
    if hw.save_settings(&new) {
        info!("configuration image stored: {=usize} bytes, in force from the next reset", new.image.len());
        *settings = new;
    } else {
        warn!("configuration image: save failed");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use devicenet::reference::{Direction, BRING_UP};
    use devicenet::Duration;
    use slave_fw::converter::{ConverterConfig, RESET_DELAY};

    /// The board as a recorder.
    #[derive(Default)]
    struct Recorder {
        frames: Vec<CanFrame>,
        serial: Vec<Vec<u8>>,
        events: Vec<Event>,
        saved: Vec<Settings>,
        resets: Vec<(usize, ResetKind)>,
        restarts: usize,
        macs: Vec<MacId>,
        /// What [`Hardware::image_on_trial`] says.
        on_trial: bool,
    }

    impl Hardware for Recorder {
        fn send_frame(&mut self, frame: CanFrame) {
            self.frames.push(frame);
        }
        fn send_serial(&mut self, bytes: &[u8]) {
            self.serial.push(bytes.to_vec());
        }
        fn restart_can(&mut self) {
            self.restarts += 1;
        }
        fn set_can_mac(&mut self, mac: MacId) {
            self.macs.push(mac);
        }
        fn save_settings(&mut self, settings: &Settings) -> bool {
            self.saved.push(settings.clone());
            true
        }
        fn reset(&mut self, kind: ResetKind) {
            // Where in the frame stream the reset came.
            self.resets.push((self.frames.len(), kind));
        }
        fn event(&mut self, event: &Event) {
            self.events.push(*event);
        }
        fn image_on_trial(&self) -> bool {
            self.on_trial
        }
    }

    fn frame(id: u16, data: &[u8]) -> CanFrame {
        CanFrame::from_raw(id, data).unwrap()
    }

    /// The reference converter powered on at 2 s and brought up by the master's side of
    /// protocol §2, one input per wake-up; then a 5 s EPR on the poll connection.
    fn established(hw: &mut Recorder) -> (ConverterTask, Instant) {
        established_with(hw, NoApplication)
    }

    /// [`established`] with `application`'s object beside the converter's.
    fn established_with<A: Application>(hw: &mut Recorder, application: A) -> (ConverterTask<A>, Instant) {
        let converter = Converter::new(ConverterConfig::breaker_reference(), Instant::ZERO).unwrap();
        let mut task = ConverterTask::with_application(converter, Settings::default(), application);
        let mut now = Instant::from_millis(2000);
        task.power_on(now, hw);
        let online = now + Duration::from_secs(2);
        while let Some(at) = task.poll_at().filter(|&at| at <= online) {
            now = at.max(now);
            task.handle_timeout(now, hw);
        }
        let master = BRING_UP.iter().filter(|f| f.direction == Direction::MasterToSlave).skip(2);
        for f in master {
            now += Duration::from_millis(10);
            task.take_inputs(Input::Frame(frame(f.id, f.data)), || None, now, hw);
        }
        task.take_inputs(
            Input::Frame(frame(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x88, 0x13])),
            || None,
            now,
            hw,
        );
        assert_eq!(hw.frames.last(), Some(&frame(0x42B, &[0x00, 0x90, 0x88, 0x13])), "EPR set");
        hw.frames.clear();
        hw.events.clear();
        (task, now)
    }

    /// A MAC ID taken through the Offline Connection Set (protocol §II.6) reaches the CAN
    /// driver's filters and the stored settings, and the duplicate MAC ID check runs at it.
    #[test]
    fn a_mac_changed_offline_is_filtered_for_and_stored() {
        let mut hw = Recorder::default();
        let (mut task, now) = established(&mut hw);
        // Another node claims MAC 5: Communication Faulted.
        let claim = frame(0x42F, &[0x80, 0xFF, 0x0F, 0x02, 0x00, 0xA5, 0xA5]);
        task.take_inputs(Input::Frame(claim), || None, now, &mut hw);
        let change = frame(0x7ED, &[0x09, 0x4D, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]);
        task.take_inputs(Input::Frame(change), || None, now, &mut hw);
        let nine = MacId::new(9).unwrap();
        assert_eq!(hw.macs, [nine]);
        assert_eq!(hw.saved.last().map(|s| s.mac_id), Some(nine));
        assert_eq!(task.settings().mac_id, nine);
        assert_eq!(hw.frames.last(), Some(&frame(0x44F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12])));
    }

    /// 64 inputs at once, as a queue full of them after a busy spell: polls, instrument bytes,
    /// a Set of the bus-off interrupt (a stored setting) and an Identity Reset in the middle.
    #[test]
    fn burst_of_64_inputs_with_a_reset_in_the_middle_loses_no_frame_and_no_event() {
        let mut hw = Recorder::default();
        let (mut task, now) = established(&mut hw);
        let set_boi = frame(0x42C, &[0x00, 0x10, 0x03, 0x01, 0x03, 0x01]);
        let reset = frame(0x42C, &[0x00, 0x05, 0x01, 0x01]);
        let poll = frame(0x42D, &[0; 8]);
        let burst: Vec<Input> = (0..INPUTS)
            .map(|n| match n {
                20 => Input::Frame(set_boi),
                32 => Input::Frame(reset),
                n if n % 4 == 3 => Input::InstrumentByte(0xFF),
                _ => Input::Frame(poll),
            })
            .collect();
        let polls = burst.iter().filter(|i| **i == Input::Frame(poll)).count();
        let mut rest = burst[1..].iter().copied();
        task.take_inputs(burst[0], || rest.next(), now, &mut hw);
        assert_eq!(rest.next(), None, "all 64 taken in one wake-up");

        // Every poll answered: 18 bytes, three fragments each (protocol §4.2).
        let responses: Vec<&CanFrame> = hw.frames.iter().filter(|f| f.id().as_raw() == 0x3C5).collect();
        assert_eq!(responses.len(), 3 * polls, "{polls} polls");
        assert_eq!(responses.iter().filter(|f| f.data()[0] == 0x00).count(), polls, "first fragments");
        // Both explicit requests answered, in their place among the poll responses; the reset's
        // shutdown message follows its response (protocol §II.5.2).
        let explicit: Vec<&CanFrame> = hw.frames.iter().filter(|f| f.id().as_raw() == 0x42B).collect();
        let shutdown = frame(0x42B, &[0x05, 0xCE, 0x01, 0x00, 0x01, 0x00, 0x04, 0x00]);
        assert_eq!(explicit, [&frame(0x42B, &[0x00, 0x90]), &frame(0x42B, &[0x00, 0x85]), &shutdown]);
        let stats = task.converter().node().stats();
        assert_eq!((stats.tx_overflows, stats.event_overflows), (0, 0));

        // Both events reached the task, and it acted on them.
        assert!(hw.events.contains(&Event::ResetRequested(0)), "{:?}", hw.events);
        assert!(hw.events.contains(&Event::SettingChanged(SettingChanged::BusOffInterrupt(true))));
        assert_eq!(hw.saved.len(), 1);
        assert!(hw.saved[0].bus_off_interrupt && task.settings().bus_off_interrupt);

        // The reset comes RESET_DELAY after the request, after every response, and once.
        assert!(hw.resets.is_empty());
        let due = now + RESET_DELAY;
        assert!(task.poll_at().is_some_and(|at| at <= due));
        task.handle_timeout(now + Duration::from_millis(99), &mut hw);
        assert!(hw.resets.is_empty());
        task.handle_timeout(due, &mut hw);
        assert_eq!(hw.resets, [(hw.frames.len(), ResetKind::PowerCycle)]);
        task.handle_timeout(due + RESET_DELAY, &mut hw);
        assert_eq!(hw.resets.len(), 1);
    }

    #[test]
    fn instrument_bytes_are_batched_across_frames() {
        use slave_fw::serial::breaker::{StatusData, SwitchState, FRAMING};
        let mut hw = Recorder::default();
        let (mut task, now) = established(&mut hw);
        let mut wire = Vec::new();
        for n in 0..3u8 {
            let mut out = [0u8; 32];
            let len = FRAMING
                .encode(StatusData::new([n, 0, 0, 0], SwitchState::Open).as_bytes(), &mut out)
                .unwrap();
            wire.extend_from_slice(&out[..len]);
        }
        assert!(wire.len() > 2 * SERIAL_BATCH, "frames cross batch boundaries");
        let before = task.converter().profile().stats().frames_received;
        let mut bytes = wire.iter().map(|&b| Input::InstrumentByte(b));
        let mut wake_ups = 0;
        while let Some(first) = bytes.next() {
            task.take_inputs(first, || bytes.next(), now, &mut hw);
            wake_ups += 1;
        }
        assert_eq!(wake_ups, wire.len().div_ceil(INPUTS), "at most {INPUTS} inputs per wake-up");
        assert_eq!(task.converter().profile().stats().frames_received - before, 3);
        assert_eq!(task.converter().profile().input_image()[0], 2, "the last frame's image");
    }

    #[test]
    fn line_events_reach_the_trace_in_line_order() {
        let mut hw = Recorder::default();
        let (mut task, now) = established(&mut hw);
        let from = task.converter().trace().next_seq();
        let mut inputs = [
            Input::LineEvent(TraceKind::DriverOn),
            Input::LineEvent(TraceKind::DriverOff),
            Input::InstrumentByte(0x68),
            Input::LineEvent(TraceKind::UartFraming),
            Input::InstrumentByte(0x01),
            Input::LineEvent(TraceKind::UartParity),
            Input::LineEvent(TraceKind::UartOverrun),
        ]
        .into_iter();
        let first = inputs.next().unwrap();
        task.take_inputs(first, || inputs.next(), now, &mut hw);
        let trace = task.converter().trace();
        let kinds: Vec<_> =
            (from..trace.next_seq()).filter_map(|seq| trace.get(seq)).map(|e| e.kind).collect();
        assert_eq!(
            kinds,
            [
                TraceKind::DriverOn,
                TraceKind::DriverOff,
                TraceKind::Receive,
                TraceKind::UartFraming,
                TraceKind::Receive,
                TraceKind::UartParity,
                TraceKind::UartOverrun,
            ]
        );
    }

    #[test]
    fn a_downloaded_image_is_stored_with_the_settings_in_force() {
        let mut hw = Recorder::default();
        let (mut task, _) = established(&mut hw);
        task.settings.bus_off_interrupt = true;
        let image = [0xA5; 300];
        store_image(&mut task.settings, &image, &mut hw);
        assert_eq!(hw.saved.len(), 1);
        assert_eq!(hw.saved[0].image, image[..]);
        assert!(hw.saved[0].bus_off_interrupt, "the network settings travel with it");
        assert_eq!(task.settings().image, image[..]);
        // Too large for a record: refused, nothing stored.
        store_image(&mut task.settings, &[0; board::settings::IMAGE_CAPACITY + 1], &mut hw);
        assert_eq!(hw.saved.len(), 1);
        assert_eq!(task.settings().image, image[..]);
    }

    #[test]
    fn bus_off_with_boi_restarts_the_controller() {
        let mut hw = Recorder::default();
        let converter = Converter::new(
            ConverterConfig {
                device: devicenet::slave::DeviceConfig {
                    bus_off_interrupt: true,
                    ..ConverterConfig::breaker_reference().device
                },
                ..ConverterConfig::breaker_reference()
            },
            Instant::ZERO,
        )
        .unwrap();
        let mut task = ConverterTask::new(converter, Settings::default());
        task.power_on(Instant::ZERO, &mut hw);
        task.take_inputs(Input::BusOff, || None, Instant::from_millis(5), &mut hw);
        assert_eq!(hw.restarts, 1);
        let self_test_over = Instant::from_secs(2);
        assert_eq!(task.leds(self_test_over).network, devicenet::led::Lit::Off, "duplicate MAC check again");
        assert!(hw.events.contains(&Event::ResetCanController));
    }

    /// The application's object in the converter task.
    mod application;
}
