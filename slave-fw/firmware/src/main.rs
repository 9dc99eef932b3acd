//! # slave-fw-firmware
//!
//! The RTIC 2 application of the STM32F405 serial-to-DeviceNet adapter board.
//!
//! - Interrupt tasks only move data: CAN RX0/RX1 (or, emulated, USART1 SLCAN lines) → frames into
//!   the converter task's channel; CAN TX refills the controller from the transmit queue; CAN SCE
//!   reports bus-off and error-passive; USART2 moves instrument bytes in and out.
//! - One software task, `app::converter_task`, owns the [`slave_fw::converter::Converter`] (the
//!   DeviceNet slave node and the serial profile of the instrument) and calls it with the time
//!   (SysTick monotonic, 1 kHz), drives the LEDs from `converter.leds(now)` (power-up test
//!   included), stores changed settings and performs resets.
//! - Switches and stored settings are read at reset ([`config`]); they choose the MAC ID, the data
//!   rate and the instrument preset ([`presets`]: the breaker, or the Modbus meter gateway), whose
//!   serial settings USART2 is opened with.
//!
//! The `emulated` feature swaps only the lowest layer (clock from HSI, CAN as SLCAN on USART1,
//! MAC from `DNET_MAC`); see `README.md` "Firmware".
//!
//! On the host this package builds a stub `main` so that `cargo test` and clippy over the
//! workspace stay clean; the firmware itself is built with `--target thumbv7em-none-eabihf`.
#![cfg_attr(target_os = "none", no_std, no_main)]
#![deny(unsafe_code)]

#[cfg(target_os = "none")]
mod can;
#[cfg(all(target_os = "none", not(feature = "emulated")))]
mod can_bxcan;
#[cfg(all(target_os = "none", feature = "emulated"))]
mod can_slcan;
#[cfg(any(target_os = "none", test))]
mod config;
#[cfg(target_os = "none")]
mod instrument;
#[cfg(target_os = "none")]
mod log;
#[cfg(any(target_os = "none", test))]
mod presets;

#[cfg(all(target_os = "none", not(feature = "defmt")))]
use panic_halt as _;
#[cfg(all(target_os = "none", feature = "defmt"))]
use {defmt_rtt as _, panic_probe as _};

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "slave-fw-firmware is the adapter board's firmware: build it with \
         `cargo build -p slave-fw-firmware --profile firmware --target thumbv7em-none-eabihf` \
         (add `--features emulated` for QEMU); see README.md \"Firmware\"."
    );
}

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, dispatchers = [EXTI1, EXTI2])]
mod app {
    use crate::can::CanPort;
    use crate::config;
    use crate::instrument::InstrumentPort;
    use crate::log::{log_info as info, log_warn as warn};
    use board::hw::{Board, BusState, LedPins};
    use board::settings::{Settings, SettingsStore};
    use devicenet::slave::{Event, SettingChanged};
    use devicenet::{CanFrame, Duration, Instant};
    use rtic_monotonics::systick::prelude::*;
    use rtic_sync::channel::{Receiver, Sender};
    use rtic_sync::make_channel;
    use slave_fw::converter::Converter;

    #[cfg(not(feature = "emulated"))]
    type Driver = crate::can_bxcan::Bxcan;
    #[cfg(feature = "emulated")]
    type Driver = crate::can_slcan::Slcan;

    #[cfg(not(feature = "emulated"))]
    type Flash = board::hw::InternalFlash;
    /// QEMU's flash controller is not emulated: settings live in RAM until the emulator stops.
    #[cfg(feature = "emulated")]
    type Flash = board::settings::RamFlash<{ 2 * board::settings::RECORD_LEN }>;

    systick_monotonic!(Mono, 1_000);

    /// What interrupts hand to the converter task.
    #[derive(Clone, Copy)]
    pub enum Input {
        /// A frame for this node.
        Frame(CanFrame),
        /// The CAN controller's error state changed.
        Bus(BusState),
        /// A byte from the instrument.
        InstrumentByte(u8),
    }

    /// Capacity of the converter task's input channel.
    const INPUTS: usize = 64;
    /// Instrument bytes handed to the converter in one call.
    const SERIAL_BATCH: usize = 32;
    /// LED refresh period (flash half-period 500 ms, self-test steps 250 ms).
    const LED_PERIOD: Duration = Duration::from_millis(25);
    /// Delay between an Identity Reset request and the reset, so the response leaves first.
    const RESET_DELAY: Duration = Duration::from_millis(100);

    #[shared]
    struct Shared {
        /// CAN driver and its transmit queue: converter task sends, TX/RX interrupts pump and drain.
        can: CanPort<Driver>,
        /// USART2 and its transmit queue: converter task queues, USART2 interrupt moves bytes.
        instrument_port: InstrumentPort,
    }

    #[local]
    struct Local {
        /// The converter and everything only the converter task touches.
        state: ConverterTask,
        /// Channel into the converter task, one sender per interrupt: CAN RX0.
        #[cfg(not(feature = "emulated"))]
        rx0_inputs: Sender<'static, Input, INPUTS>,
        /// SLCAN on USART1 (emulated CAN).
        #[cfg(feature = "emulated")]
        slcan_inputs: Sender<'static, Input, INPUTS>,
        /// CAN RX1.
        #[cfg(not(feature = "emulated"))]
        rx1_inputs: Sender<'static, Input, INPUTS>,
        /// CAN SCE.
        #[cfg(not(feature = "emulated"))]
        sce_inputs: Sender<'static, Input, INPUTS>,
        /// USART2 (instrument bytes).
        usart2_inputs: Sender<'static, Input, INPUTS>,
        /// The converter task's end of the channel.
        inputs: Receiver<'static, Input, INPUTS>,
    }

    /// Everything the converter task owns.
    pub struct ConverterTask {
        converter: Converter,
        leds: LedPins,
        store: SettingsStore<Flash>,
        settings: Settings,
        reset_at: Option<Instant>,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let Ok(mut board) = Board::take(cx.device) else {
            panic!("board set-up failed");
        };
        Mono::start(cx.core.SYST, board.systick_hz);

        #[cfg(not(feature = "emulated"))]
        let mut store = SettingsStore::new(board.flash);
        #[cfg(feature = "emulated")]
        let mut store = {
            let _ = board.flash;
            SettingsStore::new(board::settings::RamFlash::new())
        };
        let mut settings = store.load_or_default();
        let resolved = config::resolve(board.switches, &settings);
        if resolved.store_reading {
            settings.last_switches = Some(board.switches.bits());
            if store.save(&settings).is_err() {
                warn!("settings: could not store the switch reading");
            }
        }
        let preset = config::preset(&settings);
        info!(
            "MAC {=u8}, baud attribute {=u8}, {}",
            resolved.mac_id.as_raw(),
            resolved.baud_rate.attribute_value(),
            preset
        );

        let converter_config = config::converter_config(preset, &resolved, &settings);
        let line = config::line_format(converter_config.profile.serial());
        let Ok(rs485) = board.instrument.open(&line, &mut board.rcc) else {
            panic!("instrument port set-up failed");
        };
        let Ok(converter) = Converter::new(converter_config, now()) else {
            panic!("invalid converter configuration");
        };

        #[cfg(not(feature = "emulated"))]
        let driver = crate::can_bxcan::Bxcan::new(board.can, resolved.baud_rate, resolved.mac_id);
        #[cfg(feature = "emulated")]
        let driver = crate::can_slcan::Slcan::new(board.service, resolved.mac_id);
        #[cfg(not(feature = "emulated"))]
        let _ = board.service;

        let (sender, inputs) = make_channel!(Input, INPUTS);
        let _ = converter_task::spawn();
        (
            Shared { can: CanPort::new(driver), instrument_port: InstrumentPort::new(rs485) },
            Local {
                state: ConverterTask { converter, leds: board.leds, store, settings, reset_at: None },
                #[cfg(not(feature = "emulated"))]
                rx0_inputs: sender.clone(),
                #[cfg(feature = "emulated")]
                slcan_inputs: sender.clone(),
                #[cfg(not(feature = "emulated"))]
                rx1_inputs: sender.clone(),
                #[cfg(not(feature = "emulated"))]
                sce_inputs: sender.clone(),
                usart2_inputs: sender,
                inputs,
            },
        )
    }

    fn now() -> Instant {
        Instant::from_millis(Mono::now().ticks())
    }

    fn forward_frames(can: &mut CanPort<Driver>, inputs: &mut Sender<'static, Input, INPUTS>) {
        while let Some(frame) = can.receive() {
            // A full channel drops the frame, as a full bxCAN FIFO would.
            let _ = inputs.try_send(Input::Frame(frame));
        }
    }

    /// CAN FIFO 0 (the acceptance list): frames to the converter task.
    #[cfg(not(feature = "emulated"))]
    #[task(binds = CAN1_RX0, shared = [can], local = [rx0_inputs], priority = 3)]
    fn can_rx0(mut cx: can_rx0::Context) {
        cx.shared.can.lock(|can| forward_frames(can, cx.local.rx0_inputs));
    }

    /// CAN FIFO 1 (no filter routes here; drained for completeness).
    #[cfg(not(feature = "emulated"))]
    #[task(binds = CAN1_RX1, shared = [can], local = [rx1_inputs], priority = 3)]
    fn can_rx1(mut cx: can_rx1::Context) {
        cx.shared.can.lock(|can| forward_frames(can, cx.local.rx1_inputs));
    }

    /// A mailbox emptied: the next queued frame.
    #[cfg(not(feature = "emulated"))]
    #[task(binds = CAN1_TX, shared = [can], priority = 3)]
    fn can_tx(mut cx: can_tx::Context) {
        cx.shared.can.lock(|can| can.on_transmit_interrupt());
    }

    /// Status change: bus-off or error-passive, to the converter task.
    #[cfg(not(feature = "emulated"))]
    #[task(binds = CAN1_SCE, shared = [can], local = [sce_inputs], priority = 3)]
    fn can_sce(mut cx: can_sce::Context) {
        let state = cx.shared.can.lock(|can| can.bus_state());
        let _ = cx.local.sce_inputs.try_send(Input::Bus(state));
    }

    /// The emulated CAN bus: SLCAN lines from the host; frames to the converter task, and frames
    /// held while the channel was closed go out once it opens.
    #[cfg(feature = "emulated")]
    #[task(binds = USART1, shared = [can], local = [slcan_inputs], priority = 3)]
    fn slcan_rx(mut cx: slcan_rx::Context) {
        cx.shared.can.lock(|can| {
            forward_frames(can, cx.local.slcan_inputs);
            can.pump();
        });
    }

    /// Instrument bytes in, queued bytes out.
    #[task(binds = USART2, shared = [instrument_port], local = [usart2_inputs], priority = 2)]
    fn usart2(mut cx: usart2::Context) {
        let inputs = cx.local.usart2_inputs;
        cx.shared.instrument_port.lock(|port| {
            port.on_interrupt(|b| {
                // A full channel drops the byte, as an overrun would; the profile resynchronises.
                let _ = inputs.try_send(Input::InstrumentByte(b));
            })
        });
    }

    /// The one task that owns the converter: inputs and timers in; frames, instrument bytes,
    /// LEDs and settings out.
    #[task(shared = [can, instrument_port], local = [state, inputs], priority = 1)]
    async fn converter_task(mut cx: converter_task::Context) {
        let t = cx.local.state;
        let inputs = cx.local.inputs;
        let start = now();
        t.converter.power_on(start);
        let mut next_led = start;
        loop {
            let now_ = now();
            // Outputs of the last step, in the converter's drain order: frames, instrument bytes,
            // events; then the LEDs.
            while let Some(frame) = t.converter.poll_can_transmit() {
                cx.shared.can.lock(|can| can.send(frame));
            }
            while let Some(bytes) = t.converter.poll_serial_transmit(now_) {
                cx.shared.instrument_port.lock(|port| port.send(bytes));
            }
            while let Some(event) = t.converter.poll_event() {
                t.on_event(event, now_, &mut cx.shared.can);
            }
            if now_ >= next_led {
                t.leds.show(t.converter.leds(now_));
                next_led = now_ + LED_PERIOD;
            }
            if t.reset_at.is_some_and(|at| now_ >= at) {
                info!("reset");
                cortex_m::peripheral::SCB::sys_reset();
            }

            // Sleep until an input arrives or the earliest deadline.
            let deadline = [t.converter.poll_at(), t.reset_at, Some(next_led)]
                .into_iter()
                .flatten()
                .min()
                .unwrap_or(next_led);
            // Round up to the next millisecond tick.
            let ticks = deadline.total_micros().div_ceil(1000);
            let first =
                Mono::timeout_at(<Mono as Monotonic>::Instant::from_ticks(ticks), inputs.recv()).await;
            // Every sender lives in a task that never ends, so the channel never closes.
            if let Ok(Ok(input)) = first {
                t.take_inputs(input, inputs, now());
            }
            t.converter.handle_timeout(now());
        }
    }

    impl ConverterTask {
        /// Hands `first` and every input already waiting to the converter, consecutive
        /// instrument bytes in one call.
        fn take_inputs(&mut self, first: Input, inputs: &mut Receiver<'static, Input, INPUTS>, now: Instant) {
            let mut serial = heapless::Vec::<u8, SERIAL_BATCH>::new();
            let mut next = Some(first);
            // Bounded: at most one channel's worth per wake-up, so timers are never starved.
            for _ in 0..INPUTS {
                let Some(input) = next else { break };
                if let Input::InstrumentByte(b) = input {
                    if serial.push(b).is_err() {
                        self.converter.handle_serial(&serial, now);
                        serial.clear();
                        let _ = serial.push(b);
                    }
                } else {
                    if !serial.is_empty() {
                        self.converter.handle_serial(&serial, now);
                        serial.clear();
                    }
                    self.handle(input, now);
                }
                next = inputs.try_recv().ok();
            }
            if !serial.is_empty() {
                self.converter.handle_serial(&serial, now);
            }
        }

        fn handle(&mut self, input: Input, now: Instant) {
            match input {
                Input::Frame(frame) => self.converter.handle_can_frame(&frame, now),
                Input::Bus(BusState::BusOff) => {
                    warn!("CAN bus-off");
                    self.converter.handle_bus_off(now);
                }
                Input::Bus(state) => info!("CAN {}", state),
                Input::InstrumentByte(b) => self.converter.handle_serial(&[b], now),
            }
        }

        /// The application's part of the node's events; outputs, idle and connection faults
        /// were already given to the serial profile by the converter.
        fn on_event(&mut self, event: Event, now: Instant, can: &mut impl rtic::Mutex<T = CanPort<Driver>>) {
            info!("event {}", event);
            match event {
                Event::ResetCanController => can.lock(|c| c.restart()),
                Event::ResetRequested(_) => self.reset_at = Some(now + RESET_DELAY),
                Event::SettingChanged(change) => {
                    match change {
                        SettingChanged::MacId(mac) => self.settings.mac_id = mac,
                        SettingChanged::BaudRate(rate) => self.settings.baud_rate = rate,
                        SettingChanged::BusOffInterrupt(boi) => self.settings.bus_off_interrupt = boi,
                    }
                    if self.store.save(&self.settings).is_err() {
                        warn!("settings: save failed");
                    }
                }
                _ => {}
            }
        }
    }
}
