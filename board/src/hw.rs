//! Peripheral set-up of the selected board (target builds only).
//!
//! [`Board::take`] configures clocks, pins and peripherals and hands the application typed
//! handles: the LEDs, the switch reading (boards with switches), the service port (USART1, the
//! emulated board's SLCAN link), the instrument port (its USART and, on RS-485, the driver
//! enable, opened later with the serial profile's [`LineFormat`] by [`InstrumentUart::open`]),
//! the bxCAN (real boards only) and the settings flash. Which USART and which pins is the board's
//! ([`crate::boards`]); the typed pins here are checked against its description at compile time.
//!
//! With the `emulated` feature RCC is left at reset (HSI, 16 MHz on every bus; QEMU models no
//! PLL and would spin forever waiting for it) and CAN1 is not touched (QEMU has no bxCAN).

pub mod nor_flash;
mod old_settings;

pub use old_settings::OldSettingsFlash;
#[cfg(not(feature = "emulated"))]
mod watchdog;

#[cfg(not(feature = "emulated"))]
pub use watchdog::feed_watchdog;

use crate::boards::{Usart as UsartName, SELECTED};
use crate::clocks;
use crate::leds;
use crate::memory;
use crate::settings::{FlashError, Sector, SettingsFlash};
use crate::switches::SwitchReading;
use crate::uart::{bits, LineFormat, UsartRegisters};
use devicenet::led::Leds;
use stm32f4xx_hal::flash::{FlashExt, LockedFlash};
use stm32f4xx_hal::gpio::{Output, Pin, PushPull};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Enable, Rcc, Reset};

/// The HAL's CAN1 wrapper (pins PB9 TX / PB8 RX configured), for `bxcan::Can::builder`.
#[cfg(not(feature = "emulated"))]
pub type Can1 = stm32f4xx_hal::can::Can<pac::CAN1>;

/// The peripherals of the board, configured.
pub struct Board {
    /// The MS and NS LEDs.
    pub leds: LedPins,
    /// The DIP switches as read at reset; `None` on a board without switches.
    pub switches: Option<SwitchReading>,
    /// USART1, the service port, 115200 8N1: the SLCAN link of the emulated build. The real
    /// reference board's firmware does not use it and leaves it off (below).
    #[cfg(feature = "emulated")]
    pub service: Usart<pac::USART1>,
    /// The instrument's USART, not yet opened: its line format comes from the serial profile,
    /// which the application chooses after reading the switches and the stored settings.
    pub instrument: InstrumentUart,
    /// CAN1, pins configured, not yet started (real board only).
    #[cfg(not(feature = "emulated"))]
    pub can: Can1,
    /// The two settings sectors.
    pub flash: InternalFlash,
    /// The frequency SysTick counts at ([`clocks::SYSTICK_HZ`]).
    pub systick_hz: u32,
    /// The clock controller, frozen; [`InstrumentUart::open`] enables USART2 through it.
    pub rcc: Rcc,
}

/// Why the board could not be set up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum InitError {
    /// A USART baud rate the clock cannot produce.
    SerialConfig,
    /// A character format the USART cannot make ([`uart::UnsupportedFormat`]).
    SerialFormat,
}

impl Board {
    /// Sets the board up.
    pub fn take(dp: pac::Peripherals) -> Result<Board, InitError> {
        let mut rcc = clocks(dp.RCC);
        let gpioa = dp.GPIOA.split(&mut rcc);
        let gpiob = dp.GPIOB.split(&mut rcc);
        let leds = LedPins::take(&mut rcc);
        let switches = read_switches();
        #[cfg(feature = "emulated")]
        let service = {
            // Computed at compile time: 115200 8N1 from HSI.
            const SERVICE: UsartRegisters =
                match LineFormat::new_8n1(clocks::SERVICE_BAUD).registers(clocks::HSI_HZ) {
                    Ok(registers) => registers,
                    Err(_) => panic!("the service port's USART cannot make 115200 bit/s"),
                };
            let _ = (gpioa.pa9.into_alternate::<7>(), gpioa.pa10.into_alternate::<7>());
            Usart::open(dp.USART1, SERVICE, &mut rcc)
        };
        // The real reference board's firmware does not use the service port: USART1 stays
        // unclocked and both pins are inputs with their pull-ups, so that TX rests at the idle
        // (mark) level a connected adapter expects, as an idle USART would hold it, and RX does
        // not float.
        #[cfg(all(feature = "reference", not(feature = "emulated")))]
        let _ = (gpioa.pa9.into_pull_up_input(), gpioa.pa10.into_pull_up_input(), dp.USART1);
        #[cfg(any(feature = "reference", feature = "olimex-p405"))]
        let instrument = InstrumentUart {
            usart: dp.USART2,
            tx: gpioa.pa2,
            rx: gpioa.pa3,
            #[cfg(feature = "reference")]
            de: gpioa.pa1.into_push_pull_output(),
            #[cfg(feature = "olimex-p405")]
            de: NoDriverEnable,
        };
        #[cfg(any(feature = "nucleo-f446re", feature = "olimex-p405-rs485"))]
        let instrument = InstrumentUart {
            usart: dp.USART1,
            tx: gpioa.pa9,
            rx: gpioa.pa10,
            #[cfg(feature = "nucleo-f446re")]
            de: gpioa.pa8.into_push_pull_output(),
            #[cfg(feature = "olimex-p405-rs485")]
            de: gpioa.pa4.into_push_pull_output(),
        };

        #[cfg(not(feature = "emulated"))]
        let can = dp.CAN1.can((gpiob.pb9, gpiob.pb8), &mut rcc);
        // The self-test's fault: the HAL's `can()` enables CAN1's clock (RCC_APB1ENR.CAN1EN); undone.
        #[cfg(all(feature = "fault-can-clock", not(feature = "emulated")))]
        <pac::CAN1 as Enable>::disable(&mut rcc);
        #[cfg(feature = "emulated")]
        let _ = (gpiob.pb8, gpiob.pb9, dp.CAN1);

        Ok(Board {
            leds,
            switches,
            #[cfg(feature = "emulated")]
            service,
            instrument,
            #[cfg(not(feature = "emulated"))]
            can,
            flash: InternalFlash { flash: LockedFlash::new(dp.FLASH) },
            systick_hz: clocks::SYSTICK_HZ,
            rcc,
        })
    }
}

#[cfg(not(feature = "emulated"))]
fn clocks(rcc: pac::RCC) -> Rcc {
    use stm32f4xx_hal::rcc::Config;
    let hse = Config::hse(clocks::HSE_HZ.Hz());
    // The Nucleo's HSE is the ST-LINK's MCO, an external clock (bypass), not a crystal.
    let hse = if clocks::HSE_BYPASS { hse.bypass_hse_oscillator() } else { hse };
    rcc.freeze(hse.sysclk(clocks::SYSCLK_HZ.Hz()).pclk1(clocks::PCLK1_HZ.Hz()).pclk2(clocks::PCLK2_HZ.Hz()))
}

#[cfg(feature = "emulated")]
fn clocks(rcc: pac::RCC) -> Rcc {
    // Reset state: HSI on every bus. No register is written.
    rcc.constrain()
}

/// The GPIO port of the board's LEDs ([`leds::port`], checked below).
#[cfg(any(feature = "reference", feature = "olimex-p405", feature = "olimex-p405-rs485"))]
type LedPort = pac::GPIOC;
#[cfg(any(feature = "reference", feature = "olimex-p405", feature = "olimex-p405-rs485"))]
const _: () = assert!(matches!(leds::port(leds::WIRING), crate::pins::Port::C));
/// The GPIO port of the board's LEDs ([`leds::port`], checked below).
#[cfg(feature = "nucleo-f446re")]
type LedPort = pac::GPIOA;
#[cfg(feature = "nucleo-f446re")]
const _: () = assert!(matches!(leds::port(leds::WIRING), crate::pins::Port::A));

/// The board's status LEDs ([`crate::leds`]): the reference board's MS and NS pairs on PC0–PC3,
/// or the one LED of the Olimex (PC12) or the Nucleo (PA5). Set up in one register write and
/// shown in one ([`leds::bsrr`]): a board's LED pins change together, atomically, whatever its
/// wiring ([`leds::WIRING`]).
pub struct LedPins {
    _owned: (),
}

impl LedPins {
    /// Enables the LEDs' port and makes their pins push-pull outputs, low (all LEDs off; the
    /// output data register's reset value).
    fn take(rcc: &mut Rcc) -> LedPins {
        let port = leds::port(leds::WIRING).index();
        let (mask, outputs) = leds::moder_mask_and_outputs(leds::WIRING);
        // SAFETY: sets the port's clock enable bit only. The LED pins' MODER bits alone are
        // written, at set-up with interrupts disabled; no typed pin of the HAL is made for them,
        // so nothing else configures them. OTYPER and OSPEEDR stay at reset: push-pull, low speed.
        unsafe {
            rcc.ahb1enr().modify(|r, w| w.bits(r.bits() | 1 << port));
            let gpio = &*LedPort::ptr();
            gpio.moder().modify(|r, w| w.bits(r.bits() & !mask | outputs));
        }
        LedPins { _owned: () }
    }

    /// Shows `leds`.
    pub fn show(&mut self, leds: Leds) {
        // SAFETY: BSRR only sets or resets output levels, atomically; `leds::bsrr` names the LED
        // pins alone, which this handle (made once, in `Board::take`) owns.
        unsafe { (*LedPort::ptr()).bsrr().write(|w| w.bits(leds::bsrr(leds::WIRING, leds))) };
    }
}

/// Reads the DIP switches (the reference board's PB0–PB7, [`crate::switches`]): makes them inputs
/// with pull-ups, lets the pull-ups charge the switch lines and reads the eight in one read of the
/// input data register. `None` on a board without switches.
#[cfg(feature = "reference")]
fn read_switches() -> Option<SwitchReading> {
    const {
        assert!(
            matches!(crate::switches::BANK, Some(b) if b.first.number == 0 && matches!(b.first.port, crate::pins::Port::B))
        )
    };
    // SAFETY: only PB0–PB7's bits of MODER and PUPDR are written, at set-up with interrupts
    // disabled; their typed pins are never used, so nothing else configures them. GPIOB's clock
    // is on (`split`). Reading IDR has no side effect.
    let gpiob = unsafe { &*pac::GPIOB::ptr() };
    gpiob.moder().modify(|r, w| unsafe { w.bits(r.bits() & !0xFFFF) });
    gpiob.pupdr().modify(|r, w| unsafe { w.bits(r.bits() & !0xFFFF | 0x5555) });
    // Let the pull-ups charge the switch lines (tens of µs at most).
    cortex_m::asm::delay(clocks::HSI_HZ / 10_000);
    Some(SwitchReading::from_port(gpiob.idr().read().bits() as u8))
}

/// A board without DIP switches reads none.
#[cfg(not(feature = "reference"))]
fn read_switches() -> Option<SwitchReading> {
    const { assert!(crate::switches::BANK.is_none()) };
    None
}

/// The RS-485 driver enable (DE, /RE tied to it): high while transmitting. An RS-232 line has
/// none ([`NoDriverEnable`]).
pub trait DriverEnable {
    /// Enables the driver (transmit).
    fn enable(&mut self);
    /// Releases the driver (receive).
    fn release(&mut self);
    /// Whether there is a driver to enable (an RS-485 line), so that its edges mean something.
    const PRESENT: bool = true;
}

impl<const P: char, const N: u8> DriverEnable for Pin<P, N, Output<PushPull>> {
    fn enable(&mut self) {
        self.set_high();
    }

    fn release(&mut self) {
        self.set_low();
    }
}

/// The driver enable of an RS-232 line: none.
pub struct NoDriverEnable;

impl DriverEnable for NoDriverEnable {
    fn enable(&mut self) {}

    fn release(&mut self) {}

    const PRESENT: bool = false;
}

/// Why the USART dropped a received character (the `USART_SR` error flags, RM0090 §30.6.1), in
/// the order [`Usart::read_checked`] names them when several are set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum UartError {
    /// A character arrived while the last one was still unread (ORE): one was lost.
    Overrun,
    /// The stop bit read low (FE).
    Framing,
    /// The parity bit was wrong (PE).
    Parity,
    /// The receiver sampled noise (NF).
    Noise,
}

impl UartError {
    /// The error the flags of `sr` name, if any.
    const fn from_sr(sr: u16) -> Option<UartError> {
        if sr & bits::SR_ORE != 0 {
            Some(UartError::Overrun)
        } else if sr & bits::SR_FE != 0 {
            Some(UartError::Framing)
        } else if sr & bits::SR_PE != 0 {
            Some(UartError::Parity)
        } else if sr & bits::SR_NF != 0 {
            Some(UartError::Noise)
        } else {
            None
        }
    }
}

/// The instrument's USART, pins and driver enable on the reference board ([`crate::boards::reference`]).
#[cfg(feature = "reference")]
mod instrument_port {
    use super::*;
    pub type UsartPeriph = pac::USART2;
    pub type Tx = Pin<'A', 2>;
    pub type Rx = Pin<'A', 3>;
    pub type De = Pin<'A', 1, Output<PushPull>>;
    pub const TX_PIN: u8 = 2;
    pub const RX_PIN: u8 = 3;
    pub const DE_PIN: Option<u8> = Some(1);
    pub const USART: UsartName = UsartName::Usart2;
}
/// The instrument's USART and pins on the Olimex STM32-P405's RS-232 port ([`crate::boards::olimex_p405`]).
#[cfg(feature = "olimex-p405")]
mod instrument_port {
    use super::*;
    pub type UsartPeriph = pac::USART2;
    pub type Tx = Pin<'A', 2>;
    pub type Rx = Pin<'A', 3>;
    pub type De = NoDriverEnable;
    pub const TX_PIN: u8 = 2;
    pub const RX_PIN: u8 = 3;
    pub const DE_PIN: Option<u8> = None;
    pub const USART: UsartName = UsartName::Usart2;
}
/// The instrument's USART, pins and driver enable on the Olimex STM32-P405's UEXT
/// ([`crate::boards::olimex_p405::UEXT_RS485`]).
#[cfg(feature = "olimex-p405-rs485")]
mod instrument_port {
    use super::*;
    pub type UsartPeriph = pac::USART1;
    pub type Tx = Pin<'A', 9>;
    pub type Rx = Pin<'A', 10>;
    pub type De = Pin<'A', 4, Output<PushPull>>;
    pub const TX_PIN: u8 = 9;
    pub const RX_PIN: u8 = 10;
    pub const DE_PIN: Option<u8> = Some(4);
    pub const USART: UsartName = UsartName::Usart1;
}
/// The instrument's USART, pins and driver enable on the Nucleo's RS485 CAN Shield ([`crate::boards::nucleo_f446re`]).
#[cfg(feature = "nucleo-f446re")]
mod instrument_port {
    use super::*;
    pub type UsartPeriph = pac::USART1;
    pub type Tx = Pin<'A', 9>;
    pub type Rx = Pin<'A', 10>;
    pub type De = Pin<'A', 8, Output<PushPull>>;
    pub const TX_PIN: u8 = 9;
    pub const RX_PIN: u8 = 10;
    pub const DE_PIN: Option<u8> = Some(8);
    pub const USART: UsartName = UsartName::Usart1;
}
use instrument_port::{De, Rx, Tx, UsartPeriph};

// The typed pins above are the board description's (all on GPIOA).
const _: () = {
    let port = SELECTED.instrument;
    assert!(matches!(
        (port.usart, instrument_port::USART),
        (UsartName::Usart1, UsartName::Usart1) | (UsartName::Usart2, UsartName::Usart2)
    ));
    assert!(port.tx.number == instrument_port::TX_PIN && port.rx.number == instrument_port::RX_PIN);
    assert!(matches!(port.tx.port, crate::pins::Port::A) && matches!(port.rx.port, crate::pins::Port::A));
    match (port.driver_enable, instrument_port::DE_PIN) {
        (Some(de), Some(n)) => assert!(de.number == n && matches!(de.port, crate::pins::Port::A)),
        (None, None) => {}
        _ => panic!("driver enable differs from the board description"),
    }
};

/// The instrument's USART and its pins, before the line format is known.
pub struct InstrumentUart {
    usart: UsartPeriph,
    tx: Tx,
    rx: Rx,
    de: De,
}

impl InstrumentUart {
    /// Opens the instrument port with `format` (the serial profile's line settings); the RS-485
    /// driver starts released (receiving).
    pub fn open(self, format: &LineFormat, rcc: &mut Rcc) -> Result<Rs485, InitError> {
        // The self-test's `fault-usart-brr`: the registers computed for half the USART's clock.
        let clock_hz = if cfg!(feature = "fault-usart-brr") {
            clocks::INSTRUMENT_UART_HZ / 2
        } else {
            clocks::INSTRUMENT_UART_HZ
        };
        let registers = match format.registers(clock_hz) {
            Ok(registers) => registers,
            Err(_) if format.word_length().is_err() => return Err(InitError::SerialFormat),
            Err(_) => return Err(InitError::SerialConfig),
        };
        let _ = (self.tx.into_alternate::<7>(), self.rx.into_alternate::<7>());
        let usart = Usart::open(self.usart, registers, rcc);
        let mut de = self.de;
        de.release();
        Ok(Rs485 { usart, de, data_mask: format.data_mask() })
    }
}

/// A USART interrupt ([`Usart::listen`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SerialEvent {
    /// A received character waits (RXNEIE).
    RxNotEmpty,
    /// The transmit data register is empty (TXEIE).
    TxEmpty,
    /// The last stop bit is out (TCIE).
    TransmissionComplete,
}

impl SerialEvent {
    const fn cr1_bit(self) -> u16 {
        match self {
            SerialEvent::RxNotEmpty => bits::CR1_RXNEIE,
            SerialEvent::TxEmpty => bits::CR1_TXEIE,
            SerialEvent::TransmissionComplete => bits::CR1_TCIE,
        }
    }
}

/// A USART driven through its registers with the values [`LineFormat::registers`] computes
/// (RM0090 §30.6), so that the values written are the ones the platform check accepted and the
/// host tests check. (The HAL's serial driver would fit too; it computes its own divider at run
/// time.)
pub struct Usart<U> {
    usart: U,
}

impl<U> Usart<U>
where
    U: Enable + Reset + core::ops::Deref<Target = pac::usart1::RegisterBlock>,
{
    /// Clocks and resets the USART, then sets it up (pins already in their alternate function).
    fn open(usart: U, registers: UsartRegisters, rcc: &mut Rcc) -> Usart<U> {
        U::enable(rcc);
        U::reset(rcc);
        // SAFETY: the values are the USART's own register layouts (uart::bits, host-tested);
        // the USART is owned here and was just reset, so no transfer is under way.
        unsafe {
            usart.brr().write(|w| w.bits(registers.brr));
            usart.cr2().write(|w| w.bits(registers.cr2));
            usart.cr1().write(|w| w.bits(registers.cr1));
        }
        Usart { usart }
    }

    /// A received character, if any. A character with an error (parity, framing, noise,
    /// overrun) is read and dropped, which clears the error (RM0090 §30.6.1), and the next one is
    /// tried.
    pub fn read(&mut self) -> Option<u8> {
        loop {
            if let Ok(byte) = self.read_checked()? {
                return Some(byte);
            }
        }
    }

    /// A received character or, for one with an error, the error (the character is read and
    /// dropped, which clears the error, RM0090 §30.6.1); `None` when nothing waits.
    pub fn read_checked(&mut self) -> Option<Result<u8, UartError>> {
        let sr = self.usart.sr().read().bits();
        if sr & (bits::SR_ERRORS | bits::SR_RXNE) == 0 {
            return None;
        }
        let byte = self.usart.dr().read().bits() as u8;
        Some(match UartError::from_sr(sr) {
            Some(error) => Err(error),
            None => Ok(byte),
        })
    }

    /// Writes a byte if the transmit data register is empty.
    pub fn try_write(&mut self, byte: u8) -> bool {
        let empty = self.usart.sr().read().bits() & bits::SR_TXE != 0;
        if empty {
            // SAFETY: DR takes any 9-bit value; a byte is written.
            self.usart.dr().write(|w| unsafe { w.bits(u16::from(byte)) });
        }
        empty
    }

    /// Whether the last byte has completely left the shift register.
    pub fn is_transmission_complete(&self) -> bool {
        self.usart.sr().read().bits() & bits::SR_TC != 0
    }

    /// Enables an interrupt.
    pub fn listen(&mut self, event: SerialEvent) {
        // SAFETY: sets one interrupt enable bit of CR1, the rest unchanged.
        self.usart.cr1().modify(|r, w| unsafe { w.bits(r.bits() | event.cr1_bit()) });
    }

    /// Disables an interrupt.
    pub fn unlisten(&mut self, event: SerialEvent) {
        // SAFETY: clears one interrupt enable bit of CR1, the rest unchanged.
        self.usart.cr1().modify(|r, w| unsafe { w.bits(r.bits() & !event.cr1_bit()) });
    }
}

/// The instrument's USART behind its transceiver. On RS-485 the driver is enabled while bytes go
/// out and released once the last stop bit has left (transmission complete), so the instrument
/// can answer; on RS-232 ([`NoDriverEnable`]) both are no-ops.
pub struct Rs485 {
    usart: Usart<UsartPeriph>,
    de: De,
    data_mask: u8,
}

impl Rs485 {
    /// A received character or the error of one the USART dropped ([`Usart::read_checked`]);
    /// `None` when nothing waits.
    pub fn read(&mut self) -> Option<Result<u8, UartError>> {
        self.usart.read_checked().map(|r| r.map(|b| b & self.data_mask))
    }

    /// Whether the line has an RS-485 driver enable (false on RS-232).
    pub const fn has_driver_enable(&self) -> bool {
        De::PRESENT
    }

    /// Writes a byte if the transmit register is empty; enables the driver first.
    pub fn try_write(&mut self, byte: u8) -> bool {
        self.de.enable();
        self.usart.try_write(byte)
    }

    /// Whether the last byte has completely left the shift register.
    pub fn is_transmission_complete(&self) -> bool {
        self.usart.is_transmission_complete()
    }

    /// Releases the RS-485 driver (back to receive).
    pub fn release_driver(&mut self) {
        self.de.release();
    }

    /// Enables an interrupt.
    pub fn listen(&mut self, event: SerialEvent) {
        self.usart.listen(event);
    }

    /// Disables an interrupt.
    pub fn unlisten(&mut self, event: SerialEvent) {
        self.usart.unlisten(event);
    }
}

/// The bxCAN error state, read from `CAN_ESR` (RM0090 §32.9.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BusState {
    /// Error active (both error counters below 128).
    ErrorActive,
    /// Error passive (a counter at 128 or above).
    ErrorPassive,
    /// Bus-off (transmit error counter above 255).
    BusOff,
}

/// Enables the bus-off and error-passive interrupts on the SCE vector (ERRIE + BOFIE + EPVIE);
/// bxcan's builder offers only the summary bit.
#[cfg(not(feature = "emulated"))]
pub fn enable_can_error_interrupts() {
    // SAFETY: a read-modify-write of CAN1_IER's error bits only; the bxcan driver touches the
    // FIFO/mailbox bits of this register from the same priority level or with interrupts masked.
    let can = unsafe { &*pac::CAN1::ptr() };
    can.ier().modify(|_, w| w.errie().set_bit().bofie().set_bit().epvie().set_bit());
}

/// Turns the controller's automatic bus-off management (CAN_MCR.ABOM, RM0090 §32.9.2) off:
/// bus-off then lasts until software re-enters and leaves initialisation mode (§32.7.6), which the
/// converter asks for only with the bus-off interrupt setting 1 (protocol §7.2). bxcan 0.8's
/// `enable_non_blocking` sets ABOM on every start; with it a node set to stay off the bus (BOI 0)
/// would rejoin by itself after 128 × 11 recessive bits.
#[cfg(not(feature = "emulated"))]
pub fn disable_automatic_bus_off_management() {
    // SAFETY: a read-modify-write of CAN1_MCR's ABOM bit only, from init with interrupts masked or
    // from the converter task that owns the driver; INRQ/SLEEP are written back as read.
    let can = unsafe { &*pac::CAN1::ptr() };
    can.mcr().modify(|_, w| w.abom().clear_bit());
}

/// Reads the bus state and acknowledges the error interrupt (MSR.ERRI).
#[cfg(not(feature = "emulated"))]
pub fn can_bus_state() -> BusState {
    // SAFETY: reading ESR has no side effect; MSR.ERRI is write-1-to-clear and the other MSR
    // bits written as 0 have no effect.
    let can = unsafe { &*pac::CAN1::ptr() };
    let esr = can.esr().read();
    can.msr().write(|w| w.erri().set_bit());
    if esr.boff().bit_is_set() {
        BusState::BusOff
    } else if esr.epvf().bit_is_set() {
        BusState::ErrorPassive
    } else {
        BusState::ErrorActive
    }
}

/// Whether the bxCAN recorded a bus error since the last call, and its receive error counter
/// (`CAN_ESR`, RM0090 §32.9.2), for autobaud ([`crate::autobaud`]). The last error code (LEC) is
/// set back to 7 ("set by software") so that the next error, or the next error-free frame (0),
/// shows; codes 1–6 (stuff, form, acknowledgement, bit recessive, bit dominant, CRC) are errors.
#[cfg(not(feature = "emulated"))]
pub fn can_take_error() -> (bool, u8) {
    // SAFETY: reading ESR has no side effect; of its bits only LEC is writable (REC, TEC and the
    // flags are read-only), and LEC is the driver's to re-arm; bxcan never touches ESR.
    let can = unsafe { &*pac::CAN1::ptr() };
    let esr = can.esr().read();
    let lec = esr.lec().bits();
    // SAFETY: 7 is a valid LEC value ("set by software", RM0090 §32.9.2).
    can.esr().modify(|_, w| unsafe { w.lec().bits(7) });
    (matches!(lec, 1..=6), esr.rec().bits())
}

/// The MCU's 96-bit unique device ID ([`crate::uid`], RM0090 §39.1), word 0 first. Real board
/// only: QEMU's `netduinoplus2` maps nothing there (a read would be a bus fault).
#[cfg(not(feature = "emulated"))]
pub fn unique_id() -> [u32; 3] {
    let base = crate::uid::UID_ADDRESS as *const u32;
    // SAFETY: the unique ID is three aligned, read-only words of the system memory area, present
    // on every STM32F4 and readable at any time; reading them has no side effect.
    unsafe { [base.read_volatile(), base.add(1).read_volatile(), base.add(2).read_volatile()] }
}

/// The settings sectors of the internal flash (sectors 1 and 2: [`memory`]), as a
/// [`SettingsFlash`].
///
/// Erasing a 16 KiB sector stalls the CPU (the code runs from the same bank; 250 ms by stm32-emu's
/// datasheet timing, not confirmed); it happens once every 25 saves.
pub struct InternalFlash {
    flash: LockedFlash,
}

impl InternalFlash {
    fn offset(sector: Sector, offset: usize, len: usize) -> Result<usize, FlashError> {
        let size = memory::SETTINGS_SECTOR_SIZE as usize;
        match offset.checked_add(len) {
            Some(end) if end <= size => {}
            _ => return Err(FlashError::OutOfBounds),
        }
        let base = match sector {
            Sector::A => memory::SETTINGS_A_BASE,
            Sector::B => memory::SETTINGS_B_BASE,
        };
        Ok((base - memory::FLASH_BASE) as usize + offset)
    }
}

impl SettingsFlash for InternalFlash {
    fn sector_len(&self) -> usize {
        memory::SETTINGS_SECTOR_SIZE as usize
    }

    fn read(&mut self, sector: Sector, offset: usize, buf: &mut [u8]) -> Result<(), FlashError> {
        let at = Self::offset(sector, offset, buf.len())?;
        buf.copy_from_slice(&self.flash.read()[at..at + buf.len()]);
        Ok(())
    }

    fn erase(&mut self, sector: Sector) -> Result<(), FlashError> {
        let number = memory::SETTINGS_SECTORS[sector.index()];
        self.flash.unlocked().erase(number).map_err(|_| FlashError::Controller)
    }

    fn program(&mut self, sector: Sector, offset: usize, data: &[u8]) -> Result<(), FlashError> {
        let at = Self::offset(sector, offset, data.len())?;
        #[cfg(feature = "fault-flash-unlock")]
        return program_without_unlock(at, data);
        #[cfg(not(feature = "fault-flash-unlock"))]
        self.flash.unlocked().program(at, data.iter()).map_err(|_| FlashError::Controller)
    }
}

/// The self-test's `fault-flash-unlock`: the HAL's byte programming (PSIZE x8, PG, the bytes,
/// BSY, the error flags) without the FLASH_KEYR sequence, so FLASH_CR stays locked.
#[cfg(feature = "fault-flash-unlock")]
fn program_without_unlock(at: usize, data: &[u8]) -> Result<(), FlashError> {
    // SAFETY: the FLASH registers and the settings sectors' bytes (bounds checked by the caller);
    // only the self-test's broken builds have this code.
    let flash = unsafe { &*pac::FLASH::ptr() };
    flash.cr().modify(|_, w| {
        w.psize().psize8();
        w.ser().clear_bit();
        w.pg().set_bit()
    });
    let base = memory::FLASH_BASE as *mut u8;
    for (i, byte) in data.iter().enumerate() {
        // SAFETY: as above.
        unsafe { core::ptr::write_volatile(base.add(at + i), *byte) };
    }
    while flash.sr().read().bsy().bit() {}
    // WRPERR, PGAERR, PGPERR, PGSERR (RM0090 §3.9.4).
    let errors = flash.sr().read().bits() & 0xF0;
    // SAFETY: the error flags are cleared by writing 1.
    flash.sr().write(|w| unsafe { w.bits(errors) });
    flash.cr().modify(|_, w| w.pg().clear_bit());
    if errors != 0 {
        Err(FlashError::Controller)
    } else {
        Ok(())
    }
}

/// The emulated board's settings sectors: a file on the host, `dnet-settings.bin` in QEMU's
/// working directory, reached through ARM semihosting (QEMU: `-semihosting-config
/// enable=on,target=native`; scripts/qemu-firmware passes it and chooses the directory). QEMU
/// emulates no flash controller, and the file keeps the settings when the emulator stops, as the
/// board's flash keeps them over a power cycle.
///
/// The file holds sector A then sector B, [`HOST_SECTOR_LEN`] bytes each; a new file starts
/// erased (0xFF). Programming reads, clears bits and writes back, so the file behaves as NOR
/// flash. If the file cannot be opened every access fails and the firmware runs on its defaults.
#[cfg(feature = "emulated")]
pub struct HostFileFlash {
    handle: Option<u32>,
}

/// Bytes per sector of [`HostFileFlash`]: eight records.
#[cfg(feature = "emulated")]
pub const HOST_SECTOR_LEN: usize = 8 * crate::settings::RECORD_LEN;

#[cfg(feature = "emulated")]
mod semihosting {
    //! The few ARM semihosting calls the host file needs ("Semihosting for AArch32 and AArch64",
    //! ARM DUI 0058 / IHI 0058: operation in r0, parameter block address in r1, `BKPT 0xAB` on
    //! M-profile).

    pub const SYS_OPEN: u32 = 0x01;
    pub const SYS_WRITE: u32 = 0x05;
    pub const SYS_READ: u32 = 0x06;
    pub const SYS_SEEK: u32 = 0x0A;
    pub const SYS_FLEN: u32 = 0x0C;
    /// `fopen` modes as SYS_OPEN numbers them.
    pub const MODE_READ_WRITE: u32 = 3; // "r+b"
    pub const MODE_CREATE: u32 = 7; // "w+b"

    /// Makes the call; the result is the operation's r0.
    pub fn call(op: u32, args: &[u32]) -> i32 {
        let result: i32;
        // SAFETY: `args` is a live parameter block of the length `op` reads; every address in it
        // points at a buffer the caller keeps alive and, for SYS_READ, mutable. The debugger
        // (QEMU) reads and writes only those; no register but r0 changes.
        unsafe {
            core::arch::asm!("bkpt #0xab", inout("r0") op => result, in("r1") args.as_ptr(), options(nostack));
        }
        result
    }
}

#[cfg(feature = "emulated")]
impl HostFileFlash {
    /// The file's name, NUL-terminated as SYS_OPEN wants it.
    const NAME: &'static [u8] = b"dnet-settings.bin\0";

    /// Opens the file, creating it erased when missing or short.
    pub fn open() -> HostFileFlash {
        use semihosting::*;
        let open = |mode| {
            let name_len = (Self::NAME.len() - 1) as u32;
            call(SYS_OPEN, &[Self::NAME.as_ptr() as u32, mode, name_len])
        };
        let mut handle = open(MODE_READ_WRITE);
        if handle < 0 {
            handle = open(MODE_CREATE);
        }
        let mut flash = HostFileFlash { handle: u32::try_from(handle).ok() };
        if let Some(h) = flash.handle {
            let len = usize::try_from(call(SYS_FLEN, &[h])).unwrap_or(0);
            let erased = [0xFF; 64];
            let mut at = len;
            while at < 2 * HOST_SECTOR_LEN {
                let n = erased.len().min(2 * HOST_SECTOR_LEN - at);
                if flash.write_at(at, &erased[..n]).is_err() {
                    flash.handle = None;
                    break;
                }
                at += n;
            }
        }
        flash
    }

    /// Seeks to `at` and makes `op` (SYS_READ or SYS_WRITE) on the `len` bytes at `buf`.
    fn transfer(&self, op: u32, at: usize, buf: u32, len: usize) -> Result<(), FlashError> {
        use semihosting::*;
        let Some(h) = self.handle else {
            return Err(FlashError::Controller);
        };
        // SYS_SEEK answers 0 when done, SYS_READ and SYS_WRITE the number of bytes *not* moved.
        if call(SYS_SEEK, &[h, at as u32]) == 0 && call(op, &[h, buf, len as u32]) == 0 {
            Ok(())
        } else {
            Err(FlashError::Controller)
        }
    }

    fn read_at(&self, at: usize, buf: &mut [u8]) -> Result<(), FlashError> {
        self.transfer(semihosting::SYS_READ, at, buf.as_mut_ptr() as u32, buf.len())
    }

    fn write_at(&self, at: usize, data: &[u8]) -> Result<(), FlashError> {
        self.transfer(semihosting::SYS_WRITE, at, data.as_ptr() as u32, data.len())
    }

    fn offset(sector: Sector, offset: usize, len: usize) -> Result<usize, FlashError> {
        match offset.checked_add(len) {
            Some(end) if end <= HOST_SECTOR_LEN => Ok(sector.index() * HOST_SECTOR_LEN + offset),
            _ => Err(FlashError::OutOfBounds),
        }
    }
}

#[cfg(feature = "emulated")]
impl SettingsFlash for HostFileFlash {
    fn sector_len(&self) -> usize {
        HOST_SECTOR_LEN
    }

    fn read(&mut self, sector: Sector, offset: usize, buf: &mut [u8]) -> Result<(), FlashError> {
        self.read_at(Self::offset(sector, offset, buf.len())?, buf)
    }

    fn erase(&mut self, sector: Sector) -> Result<(), FlashError> {
        let erased = [0xFF; 64];
        let start = Self::offset(sector, 0, HOST_SECTOR_LEN)?;
        for at in (start..start + HOST_SECTOR_LEN).step_by(erased.len()) {
            self.write_at(at, &erased)?;
        }
        Ok(())
    }

    fn program(&mut self, sector: Sector, offset: usize, data: &[u8]) -> Result<(), FlashError> {
        let start = Self::offset(sector, offset, data.len())?;
        let mut cell = [0u8; 64];
        for (i, chunk) in data.chunks(cell.len()).enumerate() {
            let at = start + i * cell.len();
            let cell = &mut cell[..chunk.len()];
            self.read_at(at, cell)?;
            // NOR flash: programming only clears bits.
            cell.iter_mut().zip(chunk).for_each(|(c, d)| *c &= d);
            self.write_at(at, cell)?;
        }
        Ok(())
    }
}

/// One word that survives a system reset (not a power-on): [`crate::memory::RETAINED_CELL`] at
/// the end of SRAM, with a check word. The emulated board keeps its SLCAN adapter's channel state there,
/// since in reality the adapter is a device of its own that a reset of the board leaves open.
pub mod retained {
    use crate::memory::RETAINED_CELL;

    const CHECK: u32 = 0x5245_5441; // "RETA"

    /// Stores `value` until the next power-on.
    pub fn store(value: u32) {
        let cell = RETAINED_CELL as *mut u32;
        // SAFETY: the last two words of SRAM, word-aligned, outside every linker region the
        // program uses (memory.x `RETAINED`, `crate::memory`): nothing else reads or writes them.
        unsafe {
            cell.write_volatile(value);
            cell.add(1).write_volatile(value ^ CHECK);
        }
    }

    /// The value stored before the last system reset; `None` after a power-on (the check word
    /// does not match).
    pub fn load() -> Option<u32> {
        let cell = RETAINED_CELL as *const u32;
        // SAFETY: as in `store`; any bit pattern is a valid `u32`.
        let (value, check) = unsafe { (cell.read_volatile(), cell.add(1).read_volatile()) };
        (check == value ^ CHECK).then_some(value)
    }
}
