//! # slave-fw-firmware
//!
//! The RTIC 2 application of the serial-to-DeviceNet converter boards (`board::boards`: the
//! reference adapter board, the Olimex STM32-P405, the NUCLEO-F446RE with the Waveshare RS485 CAN
//! Shield), chosen at build time by a Cargo feature; it takes every hardware fact from `board`.
//!
//! - Interrupt tasks only move data: CAN RX0/RX1 (or, emulated, USART1 SLCAN lines) → frames into
//!   the converter task's input queue; CAN TX refills the controller from the transmit queue; CAN
//!   SCE reports bus-off and error-passive; the instrument's USART (USART2 or USART1, the
//!   board's choice) moves instrument bytes in and out; SysTick
//!   counts the milliseconds. Each pends the converter task when it queued an input, SysTick when
//!   the task's deadline is due.
//! - One task at the lowest priority, `app::converter_task` (bound to the otherwise unused EXTI2
//!   interrupt, so no async executor), owns the [`slave_fw::converter::Converter`] (the DeviceNet
//!   slave node and the serial profile of the instrument) through a `task::ConverterTask`: each
//!   time it runs it hands the queued inputs over one at a time, draining the converter after
//!   each, runs the timers, sets its next deadline (1 ms resolution), drives the LEDs from
//!   `converter.leds(now)` (power-up test included), stores changed settings and resets the chip
//!   when the converter says the Identity Reset is due. Its work is in `task`, target
//!   independent and tested on the host; the peripherals are behind `task::Hardware`.
//! - Switches and stored settings are read at reset (`config`): the MAC ID and the data rate, and
//!   the configuration, the stored image a tool downloaded over the bus or else the factory
//!   default (the breaker converter; an unusable image runs it with a configuration fault). the instrument USART
//!   is opened with its serial settings. A downloaded image the converter hands over is stored in
//!   the settings journal and runs from the next reset.
//!
//! - Firmware update (issue 31, real boards): the image carries its image-info block
//!   (`image_info`, linked 0x200 into the image) and is linked at ACTIVE, started by the
//!   bootloader; at reset it moves the settings from their location before the update (board's
//!   `SettingsStore::migrate_from`), and `trial` confirms an image on trial once the node is
//!   on-line and feeds the independent watchdog from the converter task. The converter task
//!   serves the update object (class 0x6A, `update`) beside the converter's objects; its Apply
//!   ends in a reset into the bootloader. The emulated board has no update object.
//!
//! The `emulated` feature swaps only the lowest layer (clock from HSI, CAN as SLCAN on USART1,
//! MAC from `DNET_MAC`); see the guide, docs/src/development/firmware.md.
//!
//! On the host this package builds a stub `main` so that `cargo test` and clippy over the
//! workspace stay clean; the firmware itself is built with `--target thumbv7em-none-eabihf`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod can;
#[cfg(all(target_os = "none", not(feature = "emulated")))]
mod can_bxcan;
#[cfg(all(target_os = "none", feature = "emulated"))]
mod can_slcan;
#[cfg(any(target_os = "none", test))]
mod config;
#[cfg(any(target_os = "none", test))]
mod image_info;
#[cfg(target_os = "none")]
mod instrument;
#[cfg(any(target_os = "none", test))]
mod log;
#[cfg(any(target_os = "none", test))]
mod task;
#[cfg(all(target_os = "none", not(feature = "emulated")))]
mod trial;
#[cfg(all(target_os = "none", not(feature = "emulated")))]
mod update;

#[cfg(all(target_os = "none", not(feature = "defmt")))]
use panic_halt as _;
#[cfg(all(target_os = "none", feature = "defmt"))]
use {defmt_rtt as _, panic_probe as _};

#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "slave-fw-firmware is the adapter board's firmware: build it with \
         `cargo build -p slave-fw-firmware --profile firmware --target thumbv7em-none-eabihf` \
         (add `--features emulated` for QEMU); see docs/src/development/firmware.md."
    );
}

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac)]
mod app {
    use crate::can::CanPort;
    use crate::config;
    use crate::instrument::{InstrumentPort, Received};
    use crate::log::{log_info as info, log_warn as warn};
    #[cfg(feature = "emulated")]
    use crate::task::NoApplication;
    use crate::task::{ConverterTask, Hardware, Input, INPUTS};
    #[cfg(not(feature = "emulated"))]
    use crate::trial::{Confirmation, Trial};
    #[cfg(not(feature = "emulated"))]
    use board::hw::BusState;
    use board::hw::{Board, LedPins};
    #[cfg(not(feature = "emulated"))]
    use board::settings::Migration;
    use board::settings::{Settings, SettingsStore};
    use cortex_m::peripheral::syst::SystClkSource;
    use devicenet::slave::Event;
    use devicenet::{CanFrame, Duration, Instant, MacId};
    use heapless::Deque;
    use portable_atomic::{AtomicU64, Ordering};
    use rtic::Mutex;
    use slave_fw::converter::ResetKind;
    use stm32f4xx_hal::pac::Interrupt;

    #[cfg(not(feature = "emulated"))]
    type Driver = crate::can_bxcan::Bxcan;
    #[cfg(feature = "emulated")]
    type Driver = crate::can_slcan::Slcan;

    /// The object beside the converter's: the update object (none without a key block).
    #[cfg(not(feature = "emulated"))]
    type App = Option<crate::update::FirmwareUpdate>;
    /// QEMU models no flash controller: no update object, class 0x6A answers 0x16.
    #[cfg(feature = "emulated")]
    type App = NoApplication;

    #[cfg(not(feature = "emulated"))]
    type Flash = board::hw::InternalFlash;
    /// QEMU's flash controller is not emulated: the settings sectors are a file on the host.
    #[cfg(feature = "emulated")]
    type Flash = board::hw::HostFileFlash;

    /// Milliseconds since reset, counted by the SysTick task. A plain counter and a deadline
    /// instead of rtic-monotonics' timer queue: the converter task is the only one that waits,
    /// for one deadline at a time.
    static MILLIS: AtomicU64 = AtomicU64::new(0);
    /// The millisecond at which the SysTick task pends the converter task (`u64::MAX`: none).
    static WAKE_AT: AtomicU64 = AtomicU64::new(u64::MAX);
    /// The interrupt the converter task is bound to; pending it runs the task.
    const CONVERTER_TASK: Interrupt = Interrupt::EXTI2;

    /// LED refresh period (flash half-period 500 ms, self-test steps 250 ms).
    const LED_PERIOD: Duration = Duration::from_millis(25);

    #[shared]
    struct Shared {
        /// CAN driver and its transmit queue: converter task sends, TX/RX interrupts pump and drain.
        can: CanPort<Driver>,
        /// the instrument USART and its transmit queue: converter task queues, its interrupt moves bytes.
        instrument_port: InstrumentPort,
        /// The converter task's inputs: the CAN, SLCAN and instrument USART interrupts queue, the task takes.
        /// A queue and a pended interrupt: one consumer, an interrupt task, no async executor.
        inputs: Deque<Input, INPUTS>,
    }

    #[local]
    struct Local {
        /// Everything only the converter task touches.
        state: TaskState,
    }

    /// The converter task's own resources.
    pub struct TaskState {
        /// The converter, the settings in force and the update object.
        task: ConverterTask<App>,
        /// The MS/NS LEDs.
        leds: LedPins,
        /// The settings flash.
        store: SettingsStore<Flash>,
        /// The image's trial boot and the watchdog (real boards).
        #[cfg(not(feature = "emulated"))]
        trial: Trial,
    }

    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let Ok(mut board) = Board::take(cx.device) else {
            panic!("board set-up failed");
        };
        // Before anything slow (the self-test, autobaud): the watchdog the bootloader started
        // is fed from here on, unless this image runs on trial.
        #[cfg(not(feature = "emulated"))]
        let trial = Trial::start();
        #[cfg(not(feature = "emulated"))]
        trial.feed();
        // SysTick: 1 kHz interrupt from the core clock.
        let mut syst = cx.core.SYST;
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(board.systick_hz / 1000 - 1);
        syst.clear_current();
        syst.enable_interrupt();
        syst.enable_counter();

        #[cfg(not(feature = "emulated"))]
        let mut store = {
            let mut store = SettingsStore::new(board.flash);
            // The journal's location before the firmware update, moved once (board::memory): before
            // anything may erase it (on the F446 it is DFU now).
            let mut old = SettingsStore::new(board::hw::OldSettingsFlash::new());
            match store.migrate_from(&mut old) {
                Ok(Migration::Moved { .. }) => info!("settings: moved from their old location"),
                Ok(_) => {}
                Err(_) => warn!("settings: could not move them from their old location"),
            }
            store
        };
        #[cfg(feature = "emulated")]
        let mut store = {
            let _ = board.flash;
            SettingsStore::new(board::hw::HostFileFlash::open())
        };
        // The newest record, `None` when the journal holds none (or cannot be read).
        let stored = store.load().ok().flatten().map(|loaded| loaded.settings);
        #[allow(unused_mut)]
        let mut resolved = config::resolve(board.switches, stored.as_ref());
        let mut settings = stored.unwrap_or_default();
        if let (true, Some(reading)) = (resolved.store_reading, board.switches) {
            settings.last_switches = Some(reading.bits());
            if store.save(&settings).is_err() {
                warn!("settings: could not store the switch reading");
            }
        }
        // The CAN path's self-test and, with no rate known, autobaud, before the converter is
        // built with the rate found (real boards; the emulated one has no bxCAN).
        #[cfg(not(feature = "emulated"))]
        let (driver, self_test) = {
            let (driver, started) = crate::can_bxcan::Bxcan::start(
                board.can,
                resolved.baud_rate,
                resolved.autobaud,
                resolved.mac_id,
                || trial.feed(),
            );
            if let Ok(rate) = started {
                config::joined_at(&mut resolved, &mut settings, rate);
            }
            (driver, started.map(|_| ()))
        };
        #[cfg(feature = "emulated")]
        let driver = crate::can_slcan::Slcan::new(board.service, resolved.mac_id);

        #[allow(unused_mut)]
        let config::Boot { mut converter, line, origin } =
            config::boot(&resolved, &settings, config::serial_number(), now());
        #[cfg(not(feature = "emulated"))]
        if let Err(failure) = self_test {
            warn!("CAN self-test failed: {}; staying off the bus", failure);
            converter.set_major_unrecoverable_fault(now());
        }
        #[cfg(not(feature = "emulated"))]
        if trial.is_pending() {
            info!("on trial: confirms once on-line");
        }
        #[cfg(not(feature = "emulated"))]
        let app: App = match crate::update::object(trial.boot_state()) {
            Ok(object) => Some(object),
            Err(why) => {
                warn!("no firmware update object: {}", why);
                None
            }
        };
        #[cfg(feature = "emulated")]
        let app = NoApplication;
        info!(
            "MAC {=u8}, baud attribute {=u8}, {=str}",
            resolved.mac_id.as_raw(),
            resolved.baud_rate.attribute_value(),
            config::origin_name(&origin)
        );
        // `boot` chose a line the USART makes.
        let Ok(rs485) = board.instrument.open(&line, &mut board.rcc) else {
            panic!("instrument port set-up failed");
        };

        // The converter task's first run powers the converter on.
        rtic::pend(CONVERTER_TASK);
        (
            Shared {
                can: CanPort::new(driver),
                instrument_port: InstrumentPort::new(rs485),
                inputs: Deque::new(),
            },
            Local {
                state: TaskState {
                    task: ConverterTask::with_application(converter, settings, app),
                    leds: board.leds,
                    store,
                    #[cfg(not(feature = "emulated"))]
                    trial,
                },
            },
        )
    }

    fn now() -> Instant {
        Instant::from_millis(millis())
    }

    fn millis() -> u64 {
        MILLIS.load(Ordering::Relaxed)
    }

    /// The millisecond count; pends the converter task once its deadline is due.
    #[task(binds = SysTick, priority = 3)]
    fn systick(_: systick::Context) {
        let millis = MILLIS.fetch_add(1, Ordering::Relaxed) + 1;
        if millis >= WAKE_AT.load(Ordering::Relaxed) {
            WAKE_AT.store(u64::MAX, Ordering::Relaxed);
            rtic::pend(CONVERTER_TASK);
        }
    }

    fn forward_frames(can: &mut CanPort<Driver>, inputs: &mut Deque<Input, INPUTS>) {
        while let Some(frame) = can.receive() {
            // A full queue drops the frame, as a full bxCAN FIFO would.
            queue(inputs, Input::Frame(frame));
        }
    }

    /// Queues `input` for the converter task and pends it; a full queue drops the input (`false`).
    fn queue(inputs: &mut Deque<Input, INPUTS>, input: Input) -> bool {
        let queued = inputs.push_back(input).is_ok();
        rtic::pend(CONVERTER_TASK);
        queued
    }

    /// CAN FIFO 0 (the acceptance list): frames to the converter task.
    #[cfg(not(feature = "emulated"))]
    #[task(binds = CAN1_RX0, shared = [can, inputs], priority = 3)]
    fn can_rx0(cx: can_rx0::Context) {
        (cx.shared.can, cx.shared.inputs).lock(forward_frames);
    }

    /// CAN FIFO 1 (no filter routes here; drained for completeness).
    #[cfg(not(feature = "emulated"))]
    #[task(binds = CAN1_RX1, shared = [can, inputs], priority = 3)]
    fn can_rx1(cx: can_rx1::Context) {
        (cx.shared.can, cx.shared.inputs).lock(forward_frames);
    }

    /// A mailbox emptied: the next queued frame.
    #[cfg(not(feature = "emulated"))]
    #[task(binds = CAN1_TX, shared = [can], priority = 3)]
    fn can_tx(mut cx: can_tx::Context) {
        cx.shared.can.lock(|can| can.on_transmit_interrupt());
    }

    /// Status change: bus-off or error-passive, to the converter task.
    #[cfg(not(feature = "emulated"))]
    #[task(binds = CAN1_SCE, shared = [can, inputs], priority = 3)]
    fn can_sce(mut cx: can_sce::Context) {
        match cx.shared.can.lock(|can| can.bus_state()) {
            BusState::BusOff => {
                cx.shared.inputs.lock(|inputs| queue(inputs, Input::BusOff));
            }
            state => info!("CAN {}", state),
        }
    }

    /// Instrument bytes in, queued bytes out: the interrupt of the board's instrument USART.
    fn instrument_interrupt(
        mut instrument_port: impl Mutex<T = InstrumentPort>,
        mut inputs: impl Mutex<T = Deque<Input, INPUTS>>,
    ) {
        instrument_port.lock(|port| {
            let mut lost = 0u32;
            port.on_interrupt(|r| match r {
                // A full queue drops the byte, as an overrun would; the profile resynchronises.
                Received::Byte(b) => {
                    inputs.lock(|inputs| queue(inputs, Input::InstrumentByte(b)));
                }
                Received::Event(kind) => {
                    if !inputs.lock(|inputs| queue(inputs, Input::LineEvent(kind))) {
                        lost += 1;
                    }
                }
            });
            // The driver's edges, from this interrupt or from `send` in the converter task.
            while let Some(kind) = port.take_event() {
                if !inputs.lock(|inputs| queue(inputs, Input::LineEvent(kind))) {
                    lost += 1;
                }
            }
            for _ in 0..lost {
                port.count_lost_event();
            }
        });
    }

    /// USART2: the instrument on the reference board and the Olimex STM32-P405. On a board whose
    /// instrument is on USART1, USART2 stays unclocked with its interrupts disabled and this task
    /// never runs; binding both keeps the application free of the board's choice.
    #[task(binds = USART2, shared = [instrument_port, inputs], priority = 2)]
    fn usart2(cx: usart2::Context) {
        instrument_interrupt(cx.shared.instrument_port, cx.shared.inputs);
    }

    /// USART1: the emulated CAN bus, SLCAN lines from the host (frames to the converter task, and
    /// frames held while the channel was closed go out once it opens); on a real board the
    /// instrument of a board that wires it to USART1 (the NUCLEO-F446RE's shield, the Olimex
    /// STM32-P405's UEXT), otherwise
    /// unclocked, as above. One task for both: RTIC refuses a second binding of USART1 even
    /// under another `cfg`. At the CAN tasks' priority, which the SLCAN link needs.
    #[task(binds = USART1, shared = [can, instrument_port, inputs], priority = 3)]
    fn usart1(cx: usart1::Context) {
        let usart1::SharedResources { can, instrument_port, inputs, .. } = cx.shared;
        #[cfg(feature = "emulated")]
        {
            let _ = instrument_port;
            (can, inputs).lock(|can, inputs| {
                forward_frames(can, inputs);
                can.pump();
            });
        }
        #[cfg(not(feature = "emulated"))]
        {
            let _ = can;
            instrument_interrupt(instrument_port, inputs);
        }
    }

    /// The board's side of the converter task: the shared CAN and instrument ports, the settings
    /// flash, the reset.
    struct Io<'a, C, P> {
        can: &'a mut C,
        instrument_port: &'a mut P,
        store: &'a mut SettingsStore<Flash>,
        #[cfg(not(feature = "emulated"))]
        trial: &'a mut Trial,
    }

    impl<C, P> Hardware for Io<'_, C, P>
    where
        C: Mutex<T = crate::can::CanPort<Driver>>,
        P: Mutex<T = InstrumentPort>,
    {
        fn send_frame(&mut self, frame: CanFrame) {
            self.can.lock(|can| can.send(frame));
        }

        fn send_serial(&mut self, bytes: &[u8]) {
            self.instrument_port.lock(|port| port.send(bytes));
        }

        fn restart_can(&mut self) {
            self.can.lock(|can| can.restart());
        }

        fn set_can_mac(&mut self, mac: MacId) {
            self.can.lock(|can| can.set_mac(mac));
        }

        fn save_settings(&mut self, settings: &Settings) -> bool {
            self.store.save(settings).is_ok()
        }

        fn reset(&mut self, _kind: ResetKind) {
            cortex_m::peripheral::SCB::sys_reset();
        }

        fn event(&mut self, event: &Event) {
            info!("event {}", event);
            #[cfg(not(feature = "emulated"))]
            if *event == Event::Online {
                match self.trial.online() {
                    Confirmation::NotOnTrial => {}
                    Confirmation::Confirmed => info!("on-line: image confirmed"),
                    Confirmation::Failed => warn!("on-line: the image could not be confirmed"),
                    Confirmation::Withheld => warn!("on-line: fault-never-confirm, not confirmed"),
                }
            }
        }

        #[cfg(not(feature = "emulated"))]
        fn image_on_trial(&self) -> bool {
            self.trial.is_pending()
        }
    }

    /// The one task that owns the converter: inputs and timers in; frames, instrument bytes,
    /// LEDs and settings out ([`crate::task`]). It runs when an input was queued or its deadline
    /// is due (both pend it), and once after `init`, which powers the converter on.
    #[task(
        binds = EXTI2,
        shared = [can, instrument_port, inputs],
        local = [state, powered_on: bool = false, next_led: Instant = Instant::ZERO],
        priority = 1
    )]
    fn converter_task(cx: converter_task::Context) {
        let converter_task::LocalResources { state, powered_on, next_led, .. } = cx.local;
        #[cfg(not(feature = "emulated"))]
        let TaskState { task, leds, store, trial } = state;
        #[cfg(feature = "emulated")]
        let TaskState { task, leds, store } = state;
        let converter_task::SharedResources { mut can, mut instrument_port, mut inputs, .. } = cx.shared;
        macro_rules! io {
            () => {
                &mut Io {
                    can: &mut can,
                    instrument_port: &mut instrument_port,
                    store: &mut *store,
                    #[cfg(not(feature = "emulated"))]
                    trial: &mut *trial,
                }
            };
        }
        if !*powered_on {
            *powered_on = true;
            task.power_on(now(), io!());
        }
        let mut next = || inputs.lock(|q| q.pop_front());
        if let Some(first) = next() {
            task.take_inputs(first, next, now(), io!());
            // Inputs beyond the INPUTS `take_inputs` takes may wait: run again (a run that finds
            // none only runs the timers).
            rtic::pend(CONVERTER_TASK);
        }
        task.handle_timeout(now(), io!());
        // This task runs at least every LED_PERIOD: the watchdog's regular feed.
        #[cfg(not(feature = "emulated"))]
        trial.feed();

        let now_ms = millis();
        let now_ = Instant::from_millis(now_ms);
        if now_ >= *next_led {
            leds.show(task.leds(now_));
            *next_led = now_ + LED_PERIOD;
        }
        // The earliest deadline (a due reset included), rounded up to the next millisecond tick.
        // `now_` is on a tick and the deadline at most LED_PERIOD away: 32-bit arithmetic (no
        // 64-bit divide in the firmware).
        let deadline = task.poll_at().map_or(*next_led, |at| at.min(*next_led));
        let wait_us = u32::try_from(deadline.saturating_duration_since(now_).total_micros());
        WAKE_AT.store(now_ms + u64::from(wait_us.unwrap_or(u32::MAX).div_ceil(1000)), Ordering::Relaxed);
    }
}
