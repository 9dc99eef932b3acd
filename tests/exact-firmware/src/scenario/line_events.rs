//! `line-events`: the serial-line analyzer (vendor class 0x68, protocol §6.3) of the exact
//! firmware records the instrument line's own events: a character injected on the USART's RX
//! with a framing error (sent 8E1 into the 8N1 breaker line: the receiver reads the parity bit,
//! 0 for 0x00, as a low stop bit) shows as a UART framing entry, and on a board with an RS-485
//! driver enable the driver's rising and falling edges around the Open command the firmware sends
//! show as driver entries (on an RS-232 board, none).
//!
//! Not injected: a parity error (the breaker line has no parity, so the USART checks none) and an
//! overrun (the model's receiver is read by the firmware's interrupt long before the next
//! character completes).

use super::world::{machine_fault, world, Options, MAC};
use crate::board::BoardKind;
use crate::device::Firmware;
use can_io::sim::PowerOn;
use converter_sim::device::{COMMAND_CLOSE, COMMAND_OPEN};
use devicenet::explicit::{Request, ServiceCode};
use devicenet::Duration;
use master_core::client::{Port, ReplyBody};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use master_harness::commands::serial_trace::parse_reply;
use slave_fw::converter::analyzer_object::{ANALYZER_CLASS, READ_TRACE};
use slave_fw::serial::trace::TraceKind;
use stm32_emu::usart::line::{Character, LineSettings, Parity};

/// Every entry the ring holds, oldest first, read with Read_Trace from sequence number 0 on.
fn read_kinds(master: &mut Master<'_, '_>) -> Result<Vec<TraceKind>, String> {
    let mut kinds = Vec::new();
    let mut from = 0u32;
    // The ring holds 32 entries, a reply at least one: a bound well above the reads needed.
    for _ in 0..64 {
        let data = from.to_le_bytes();
        let req = Request {
            service: ServiceCode::from(READ_TRACE),
            class: ANALYZER_CLASS,
            instance: 1,
            data: &data,
        };
        let answer = master.request(MAC, Port::Explicit, &req).map_err(|e| format!("Read_Trace: {e}"))?;
        let bytes = match answer.reply.body {
            ReplyBody::Success(bytes) => bytes,
            ReplyBody::Error { general, additional } => {
                return Err(format!("Read_Trace: error response {general:?}/{additional:?}"));
            }
        };
        let reply = parse_reply(&bytes).map_err(|e| format!("Read_Trace reply {bytes:02x?}: {e}"))?;
        kinds.extend(reply.entries.iter().map(|e| e.kind));
        from = reply.first.wrapping_add(reply.entries.len() as u32);
        if from == reply.next {
            return Ok(kinds);
        }
        if reply.entries.is_empty() {
            return Err(format!("Read_Trace from {from}: no entry, but the next is {}", reply.next));
        }
    }
    Err("Read_Trace: the ring never ran out".into())
}

/// Close, a framing error injected, Open; then the ring read back.
pub fn line_events(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let close = [COMMAND_CLOSE, 1, 0, 0, 0, 0, 0, 0];
    let opts = ConnectOptions { polls: 5, output: Some(close.to_vec()), ..ConnectOptions::default() };
    let connected = master.connect(&opts);
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;

    let line = handle.borrow().instrument_line();
    if line.parity != Parity::None || line.word_bits != 8 {
        return Err(format!("the instrument line is {line:?}, not the breaker's 8N1"));
    }
    let with_parity = LineSettings { word_bits: 9, parity: Parity::Even, ..line };
    {
        let mut device = handle.borrow_mut();
        let now = device.mcu().now();
        device.instrument_usart().borrow_mut().receive(Character::encode(0x00, with_parity), now);
    }
    let open = [COMMAND_OPEN, 2, 0, 0, 0, 0, 0, 0];
    for _ in 0..3 {
        let deadline = master.session.now() + Duration::from_millis(100);
        master.poll(MAC, &open, 18, 8, Duration::from_millis(500)).map_err(|e| format!("poll: {e}"))?;
        master.idle_until(deadline).map_err(|e| format!("idle: {e}"))?;
    }
    machine_fault(&handle)?;
    master.open_explicit(MAC).map_err(|e| format!("open explicit: {e}"))?;
    let kinds = read_kinds(&mut master);
    machine_fault(&handle)?;
    let kinds = kinds?;

    let count = |kind| kinds.iter().filter(|&&k| k == kind).count();
    if count(TraceKind::UartFraming) != 1 {
        return Err(format!(
            "{} UART framing entries for the one injected, in {kinds:?}",
            count(TraceKind::UartFraming)
        ));
    }
    let (on, off) = (count(TraceKind::DriverOn), count(TraceKind::DriverOff));
    if board.spec.instrument.driver_enable.is_some() {
        // Each frame sent is one rising and one falling edge, in that order.
        let edges: Vec<_> =
            kinds.iter().filter(|k| matches!(k, TraceKind::DriverOn | TraceKind::DriverOff)).collect();
        let alternate = edges.windows(2).all(|w| w[0] != w[1]);
        if on == 0 || off == 0 || !alternate || on.abs_diff(off) > 1 {
            return Err(format!(
                "RS-485 driver edges: {on} on, {off} off, alternating {alternate}, in {kinds:?}"
            ));
        }
        let transmits = count(TraceKind::Transmit);
        if transmits == 0 {
            return Err(format!("no transmitted bytes around the driver edges, in {kinds:?}"));
        }
    } else if on + off != 0 {
        return Err(format!(
            "an RS-232 board reports {on} driver-on and {off} driver-off edges, in {kinds:?}"
        ));
    }
    match master.session.failures() {
        0 => Ok(()),
        n => Err(format!("{n} checks of the master failed")),
    }
}
