//! The scenarios: each runs one board ELF on a fresh [`EmulatedBoard`] on a simulated bus and
//! compares what happens with what must; [`Outcome::line`] is the runner's line for it.

use crate::board::{BoardKind, NodeSetting};
use crate::device::{EmulatedBoard, OnBus};
use can_io::bus::{Bitrate, Origin};
use can_io::sim::{PowerOn, SimBus};
use converter_sim::device::{COMMAND_CLOSE, COMMAND_OPEN, SWITCH_BYTE, SWITCH_CLOSED, SWITCH_OPEN};
use devicenet::reference::{Direction, BRING_UP};
use devicenet::slave::BaudRate;
use devicenet::{Duration, MacId};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use slave_fw::serial::breaker::SwitchState;
use std::cell::RefCell;
use std::rc::Rc;

/// The device's MAC ID in every scenario (the reference transcript's).
pub const MAC: MacId = MacId::from_low_bits(5);

/// A scenario: its name and what it runs.
#[derive(Clone, Copy)]
pub struct Scenario {
    /// The name printed.
    pub name: &'static str,
    /// Runs it on `elf` of `board`; `Err` says why it failed.
    pub run: fn(BoardKind, &[u8], &Options) -> Result<(), String>,
}

/// How a scenario runs (the defaults are the real scenarios; the others exist so that a test
/// can prove a scenario fails when the world is wrong).
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// The bus's bit rate.
    pub bus_rate: Bitrate,
    /// The node's MAC and rate before power-on.
    pub setting: NodeSetting,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            bus_rate: Bitrate::K125,
            setting: NodeSetting { mac: MAC, rate: BaudRate::Kbps125, bus_off_interrupt: false },
        }
    }
}

/// Every scenario, in the order the runner runs them.
pub const ALL: [Scenario; 8] = [
    Scenario { name: "bring-up", run: bring_up },
    Scenario { name: "breaker", run: breaker },
    Scenario { name: "power-cycle", run: power_cycle },
    Scenario { name: "configure", run: configure },
    Scenario { name: "download-cut", run: download_cut },
    Scenario { name: "wrong-bit-rate", run: wrong_bit_rate },
    Scenario { name: "bus-load", run: bus_load },
    Scenario { name: "bus-off", run: bus_off },
];

/// The result of one scenario on one board.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The board's build name.
    pub board: String,
    /// The scenario.
    pub scenario: &'static str,
    /// `Err(why)` when it failed.
    pub result: Result<(), String>,
}

impl Outcome {
    /// `ok   BOARD SCENARIO` or `FAIL BOARD SCENARIO: why`.
    pub fn line(&self) -> String {
        match &self.result {
            Ok(()) => format!("ok   {} {}", self.board, self.scenario),
            Err(why) => format!("FAIL {} {}: {}", self.board, self.scenario, why.replace('\n', " ")),
        }
    }
}

/// Runs `scenario` on `elf` of `board`.
pub fn run(scenario: &Scenario, board: BoardKind, elf: &[u8], options: &Options) -> Outcome {
    Outcome {
        board: board.name.to_string(),
        scenario: scenario.name,
        result: (scenario.run)(board, elf, options),
    }
}

/// The bus with the emulated board on it, and the test's handle on the board.
fn world(
    board: BoardKind,
    elf: &[u8],
    options: &Options,
    power: PowerOn,
) -> Result<(SimBus, Rc<RefCell<EmulatedBoard>>), String> {
    let device = EmulatedBoard::new(board, elf, options.setting, options.bus_rate)
        .map_err(|e| format!("the machine: {e}"))?;
    let handle = Rc::new(RefCell::new(device));
    Ok((bus_with(&handle, options, power), handle))
}

/// A new bus with the board on it: powering it on there is a power cycle if it ran before.
fn bus_with(handle: &Rc<RefCell<EmulatedBoard>>, options: &Options, power: PowerOn) -> SimBus {
    let mut bus = SimBus::new(options.bus_rate);
    bus.attach(Box::new(OnBus(Rc::clone(handle))), power);
    bus
}

/// The machine's fault, if it stopped.
fn machine_fault(handle: &Rc<RefCell<EmulatedBoard>>) -> Result<(), String> {
    match handle.borrow().fault() {
        Some(fault) => Err(format!("the machine stopped: {fault}")),
        None => Ok(()),
    }
}

fn direction(origin: Origin) -> Direction {
    match origin {
        Origin::Local => Direction::MasterToSlave,
        Origin::Remote => Direction::SlaveToMaster,
    }
}

/// The 28 frames of devicenet-notes §2, byte for byte and in order, every check holding. The
/// serial number in the device's frames is the reference's own: the emulated chip's unique ID
/// folds to it ([`crate::uid`]), nothing is substituted.
fn bring_up(board: BoardKind, elf: &[u8], options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let mut session = Session::new(&mut bus);
    let connected = Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let records = session.records();
    for (i, want) in BRING_UP.iter().enumerate() {
        let Some(got) = records.get(i) else {
            return Err(format!("{} frames, not {}", records.len(), BRING_UP.len()));
        };
        let got_key = (direction(got.origin), got.frame.id().as_raw(), got.frame.data());
        if got_key != (want.direction, want.id, want.data) {
            return Err(format!(
                "frame {i} ({}): id {:#05x} {:02x?}, want {:#05x} {:02x?}",
                want.meaning, got_key.1, got_key.2, want.id, want.data
            ));
        }
    }
    if records.len() != BRING_UP.len() {
        return Err(format!("{} frames, not {}", records.len(), BRING_UP.len()));
    }
    match session.failures() {
        0 => Ok(()),
        n => Err(format!("{n} checks of the master failed")),
    }
}

/// Close, then open, through the poll output: the breaker on the instrument USART obeys and its
/// switch state comes back in the input image.
fn breaker(board: BoardKind, elf: &[u8], options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    // 15 polls 100 ms apart: the close command goes out at once, the breaker's status frame
    // (once a second) shows it closed.
    let close = [COMMAND_CLOSE, 1, 0, 0, 0, 0, 0, 0];
    let opts = ConnectOptions { polls: 15, output: Some(close.to_vec()), ..ConnectOptions::default() };
    let summary = master.connect(&opts);
    machine_fault(&handle)?;
    let summary = summary.map_err(|e| format!("connect: {e}"))?;
    let input = summary.last_input.unwrap_or_default();
    if input.get(SWITCH_BYTE) != Some(&SWITCH_CLOSED) {
        return Err(format!("after Close the input image is {input:02x?}"));
    }
    if handle.borrow().breaker().switch_state() != SwitchState::Closed {
        return Err("the input image says closed but the breaker is not".into());
    }
    let open = [COMMAND_OPEN, 2, 0, 0, 0, 0, 0, 0];
    let mut input = Vec::new();
    for _ in 0..15 {
        let deadline = master.session.now() + Duration::from_millis(100);
        input =
            master.poll(MAC, &open, 18, 8, Duration::from_millis(500)).map_err(|e| format!("poll: {e}"))?;
        master.idle_until(deadline).map_err(|e| format!("idle: {e}"))?;
    }
    machine_fault(&handle)?;
    if input.get(SWITCH_BYTE) != Some(&SWITCH_OPEN) {
        return Err(format!("after Open the input image is {input:02x?}"));
    }
    if handle.borrow().breaker().switch_state() != SwitchState::Open {
        return Err("the input image says open but the breaker is not".into());
    }
    match master.session.failures() {
        0 => Ok(()),
        n => Err(format!("{n} checks of the master failed")),
    }
}

/// The node set to 125k on a 500k bus: the master's bring-up finds nobody, not one frame of
/// the node reaches the bus, and its controller counts the errors (`CAN_ESR`: TEC from its own
/// flagged frames, up to bus-off; REC from the master's frames it cannot decode while it still
/// listens; the peaks, as a bus-off recovery clears both). With the bus-off interrupt setting 0
/// (the default) a node that went bus-off stays off the bus and hears nothing more, so either
/// its REC rose or it went bus-off.
fn wrong_bit_rate(board: BoardKind, elf: &[u8], options: &Options) -> Result<(), String> {
    let options = Options { bus_rate: Bitrate::K500, ..*options };
    let (mut bus, handle) = world(board, elf, &options, PowerOn::AtStart)?;
    let mut session = Session::new(&mut bus);
    let connected = Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    if connected.is_ok() {
        return Err("the master brought the node up on a bus at another rate".into());
    }
    if let Some(r) = session.records().iter().find(|r| r.origin == Origin::Remote) {
        return Err(format!(
            "a frame of the node reached the bus: {:#05x} {:02x?}",
            r.frame.id().as_raw(),
            r.frame.data()
        ));
    }
    let counts = handle.borrow().counts();
    if counts.flagged == 0 {
        return Err("the node never tried to send".into());
    }
    if counts.peak_tec == 0 && counts.bus_offs == 0 {
        return Err(format!(
            "{} frames flagged, but the controller counted no transmit error",
            counts.flagged
        ));
    }
    if counts.peak_rec == 0 && counts.bus_offs == 0 {
        return Err("the master's frames counted no receive error, and the node never went bus-off".into());
    }
    Ok(())
}

/// The DeviceNet object (class 3), instance 1, attribute 3: the bus-off interrupt (BOI).
const BOI: (u16, u16, u8) = (3, 1, 3);

/// A setting made over the network survives a power cycle: the master sets BOI (a stored
/// setting, DeviceNet object attribute 3) on the running node; the settings journal in flash
/// then holds it (decoded by the board crate); after a power cycle (SRAM and every register
/// reset, the flash array kept) a new bring-up reads it back from the node.
fn power_cycle(board: BoardKind, elf: &[u8], options: &Options) -> Result<(), String> {
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let (class, instance, attribute) = BOI;
    {
        let mut session = Session::new(&mut bus);
        let mut master = Master::new(&mut session, MasterConfig::default());
        let connected = master.connect(&ConnectOptions::default());
        machine_fault(&handle)?;
        connected.map_err(|e| format!("connect: {e}"))?;
        let (before, _) = master.get(MAC, class, instance, attribute).map_err(|e| format!("get BOI: {e}"))?;
        if before != [0] {
            return Err(format!("BOI reads {before:02x?} before it is set"));
        }
        master.set(MAC, class, instance, attribute, &[1]).map_err(|e| format!("set BOI: {e}"))?;
        let deadline = master.session.now() + Duration::from_millis(500);
        master.idle_until(deadline).map_err(|e| format!("idle: {e}"))?;
    }
    machine_fault(&handle)?;
    match handle.borrow().stored_settings() {
        Some((settings, _)) if settings.bus_off_interrupt => {}
        Some((settings, n)) => {
            return Err(format!("the journal's newest record ({n}) has BOI clear: {settings:?}"))
        }
        None => return Err("no valid record in the settings journal".into()),
    }
    let mut bus = bus_with(&handle, options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect after the power cycle: {e}"))?;
    let (after, _) = master.get(MAC, class, instance, attribute).map_err(|e| format!("get BOI: {e}"))?;
    if after != [1] {
        return Err(format!("after the power cycle BOI reads {after:02x?}, not 01"));
    }
    match master.session.failures() {
        0 => Ok(()),
        n => Err(format!("{n} checks of the master failed")),
    }
}

/// Bus-off recovery follows the stored bus-off interrupt setting (devicenet-notes §7.2): the
/// node at 125k on a 500k bus, alone, drives its controller bus-off with its own flagged
/// frames. With BOI 0 it stays bus-off (one bus-off, still off a second later); with BOI 1 it
/// resets the controller and continues, so it goes bus-off again and again.
fn bus_off(board: BoardKind, elf: &[u8], options: &Options) -> Result<(), String> {
    for boi in [false, true] {
        let setting = NodeSetting { bus_off_interrupt: boi, ..options.setting };
        let options = Options { bus_rate: Bitrate::K500, setting };
        let (mut bus, handle) = world(board, elf, &options, PowerOn::AtStart)?;
        let end = devicenet::Instant::from_secs(1);
        if let Some(event) = can_io::bus::Bus::recv(&mut bus, end).map_err(|e| format!("bus: {e}"))? {
            let frame = event.frame;
            return Err(format!(
                "a frame reached the bus: {:#05x} {:02x?}",
                frame.id().as_raw(),
                frame.data()
            ));
        }
        machine_fault(&handle)?;
        let counts = handle.borrow().counts();
        let (_, _, off) = handle.borrow().can_errors();
        let mcr = handle.borrow_mut().mcu().read_peripheral(stm32_emu::bxcan::CAN1_BASE).unwrap_or(0);
        let abom = if mcr & stm32_emu::bxcan::mcr::ABOM != 0 { ", MCR.ABOM set" } else { "" };
        match (boi, counts.bus_offs) {
            (_, 0) => {
                return Err(format!(
                    "BOI {}: never bus-off ({} frames flagged)",
                    u8::from(boi),
                    counts.flagged
                ))
            }
            (false, 1) if off => {}
            (false, n) => {
                return Err(format!(
                    "BOI 0: {n} bus-offs in 1 s, the controller {} bus-off at the end{abom}",
                    if off { "still" } else { "no longer" }
                ))
            }
            (true, 1) => return Err(format!("BOI 1: one bus-off, never recovered{abom}")),
            (true, _) => {}
        }
    }
    Ok(())
}

/// Poll commands the master sends back to back in [`bus_load`].
const FLOOD: usize = 2000;

/// At 100 % bus load at 500k no receive FIFO overruns: after the bring-up at 500k the master
/// queues [`FLOOD`] poll commands at once, so the bus carries them back to back (with the
/// node's responses, which win the arbitration); every delivery to the node is followed by a
/// look at FOVR of both FIFOs. The load is checked too: the frames' time on the wire over the
/// flood's span.
fn bus_load(board: BoardKind, elf: &[u8], options: &Options) -> Result<(), String> {
    let setting = NodeSetting { rate: BaudRate::Kbps500, ..options.setting };
    let options = Options { bus_rate: Bitrate::K500, setting };
    let (mut bus, handle) = world(board, elf, &options, PowerOn::WhenMasterOnline)?;
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let connected = master.connect(&ConnectOptions::default());
    machine_fault(&handle)?;
    connected.map_err(|e| format!("connect: {e}"))?;
    let id = devicenet::Identifier::group2(MAC, devicenet::Group2Message::PollCommand);
    let poll = devicenet::CanFrame::new(id, &[0; 8]).map_err(|e| format!("poll frame: {e:?}"))?;
    let first = master.session.next_index();
    let received_before = handle.borrow().counts().received;
    for _ in 0..FLOOD {
        master.session.send(&poll).map_err(|e| format!("send: {e}"))?;
    }
    let deadline = master.session.now() + Duration::from_secs(2);
    while master.session.next(deadline).map_err(|e| format!("bus: {e}"))?.is_some() {}
    machine_fault(&handle)?;
    let records: Vec<_> = master.session.records().iter().filter(|r| r.index >= first).collect();
    let polls = records.iter().filter(|r| r.origin == Origin::Local).count();
    let counts = handle.borrow().counts();
    if polls != FLOOD || counts.received - received_before < FLOOD as u64 {
        return Err(format!(
            "{polls} of {FLOOD} polls on the bus, {} received",
            counts.received - received_before
        ));
    }
    let (Some(start), Some(end)) = (records.first(), records.iter().rfind(|r| r.origin == Origin::Local))
    else {
        return Err("no frames".into());
    };
    let busy: u64 = records
        .iter()
        .filter(|r| r.at <= end.at)
        .map(|r| can_io::sim::frame_duration(&r.frame, Bitrate::K500).total_micros())
        .sum();
    let span = (end.at - start.at).total_micros()
        + can_io::sim::frame_duration(&start.frame, Bitrate::K500).total_micros();
    if busy * 100 < span * 99 {
        return Err(format!("the bus was busy {busy} of {span} us, not 100 %"));
    }
    match counts.overruns {
        0 => Ok(()),
        n => Err(format!("{n} deliveries left a receive FIFO overrun (FOVR)")),
    }
}

/// The description `configure` downloads (the one the QEMU test downloads).
const METER: &str = include_str!("../../../slave-fw/descriptions/modbus-meter.toml");

/// `dnet-master configure` of the Modbus meter (slave-fw/descriptions/modbus-meter.toml, through
/// master-harness's own download: Begin_Download, Write_Chunk, Commit_Download, read-back,
/// Identity Reset, every check of the device against the description), then a power cycle: the
/// stored image is still in force (configuration state 1, the description's product name) and
/// the instrument USART runs the description's line, 19200 bit/s 8E1. No Modbus slave answers
/// on the line here (the QEMU test's pymodbus does): what the gateway reads is not checked.
fn configure(board: BoardKind, elf: &[u8], options: &Options) -> Result<(), String> {
    use master_harness::configure::{download, CONFIGURATION_CLASS};
    let meter =
        slave_fw::description::DeviceDescription::parse(METER).map_err(|e| format!("the meter: {e}"))?;
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    {
        let mut session = Session::new(&mut bus);
        let mut master = Master::new(&mut session, MasterConfig::default());
        let connected = master.connect(&ConnectOptions::default());
        machine_fault(&handle)?;
        connected.map_err(|e| format!("connect: {e}"))?;
        let report = download(&mut master, MAC, &meter, &mut |_| {});
        machine_fault(&handle)?;
        let report = report.map_err(|e| format!("download: {e}"))?;
        if let Some(check) = report.failures().first() {
            return Err(format!("after the download: {check:?}"));
        }
    }
    let mut bus = bus_with(&handle, options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let online = master.network_access().and_then(|()| master.await_online(&[MAC]));
    machine_fault(&handle)?;
    online.map_err(|e| format!("after the power cycle: {e}"))?;
    master.open_explicit(MAC).map_err(|e| format!("after the power cycle: {e}"))?;
    let (state, _) =
        master.get(MAC, CONFIGURATION_CLASS, 1, 3).map_err(|e| format!("configuration state: {e}"))?;
    if state != [1] {
        return Err(format!(
            "after the power cycle the configuration state is {state:02x?}, not 01 (stored image)"
        ));
    }
    let (name, _) = master.get(MAC, 1, 1, 7).map_err(|e| format!("product name: {e}"))?;
    let want = meter.converter.device.identity.product_name.as_bytes();
    if name.get(1..) != Some(want) {
        return Err(format!("after the power cycle the product name is {name:02x?}"));
    }
    let line = handle.borrow().instrument_line();
    let parity = line.parity == stm32_emu::usart::line::Parity::Even;
    if (line.baud - 19_200.0).abs() > 19_200.0 * 0.01 || !parity || line.data_bits() != 8 {
        return Err(format!("after the power cycle the instrument line is {line:?}, not 19200 8E1"));
    }
    Ok(())
}

/// Where [`download_cut`] cuts the power: operations from the download's first flash operation.
/// The board's HAL programs the 640-byte settings record a byte at a time (board/src/settings.rs
/// "Record layout"), so these are the record's first byte (magic), its sequence number, the MAC
/// ID, the first and a middle byte of the image, the last image byte, the first and the last
/// byte of the CRC; clipped to the download's last operation.
const CUT_AT: [u64; 8] = [0, 4, 8, 16, 320, 635, 636, 639];

/// The configuration object's state and the Identity product name of the node at [`MAC`],
/// powered on again on `handle`'s flash.
fn state_after_power_up(
    handle: &Rc<RefCell<EmulatedBoard>>,
    options: &Options,
) -> Result<(Vec<u8>, Vec<u8>), String> {
    let mut bus = bus_with(handle, options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let online = master.network_access().and_then(|()| master.await_online(&[MAC]));
    machine_fault(handle)?;
    online.map_err(|e| format!("back on-line: {e}"))?;
    master.open_explicit(MAC).map_err(|e| format!("explicit connection: {e}"))?;
    let class = master_harness::configure::CONFIGURATION_CLASS;
    let (state, _) = master.get(MAC, class, 1, 3).map_err(|e| format!("configuration state: {e}"))?;
    let (name, _) = master.get(MAC, 1, 1, 7).map_err(|e| format!("product name: {e}"))?;
    Ok((state, name))
}

/// A power cut in the middle of a download's flash writes leaves the old configuration or the
/// new one in force, never neither: the download of [`configure`] runs once to count its flash
/// operations, then again on a fresh board for each operation of [`CUT_AT`], the power cut
/// there with the operation torn half-way
/// (stm32-emu `flash::CutKind::Torn`); powered up again, the node must come on-line with either
/// the factory configuration (state 0, its product name) or the meter's (state 1, its name).
/// Not every operation: a download is 640 of them (one byte each), and at about 3 s a run, one
/// run per operation would take half an hour per board.
fn download_cut(board: BoardKind, elf: &[u8], options: &Options) -> Result<(), String> {
    use master_harness::configure::download;
    let meter =
        slave_fw::description::DeviceDescription::parse(METER).map_err(|e| format!("the meter: {e}"))?;
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    let (first, last, factory_name) = {
        let mut session = Session::new(&mut bus);
        let mut master = Master::new(&mut session, MasterConfig::default());
        let connected = master.connect(&ConnectOptions::default());
        machine_fault(&handle)?;
        connected.map_err(|e| format!("connect: {e}"))?;
        let (name, _) = master.get(MAC, 1, 1, 7).map_err(|e| format!("product name: {e}"))?;
        let first = handle.borrow().flash_operations();
        download(&mut master, MAC, &meter, &mut |_| {}).map_err(|e| format!("download: {e}"))?;
        (first, handle.borrow().flash_operations(), name)
    };
    if last <= first {
        return Err("the download took no flash operation".into());
    }
    let mut meter_name = vec![meter.converter.device.identity.product_name.len() as u8];
    meter_name.extend_from_slice(meter.converter.device.identity.product_name.as_bytes());
    for offset in CUT_AT {
        let k = first + offset.min(last - 1 - first);
        let cut = Some((k, stm32_emu::flash::CutKind::Torn));
        let device = EmulatedBoard::with_power_cut(board, elf, options.setting, options.bus_rate, cut)
            .map_err(|e| format!("the machine: {e}"))?;
        let handle = Rc::new(RefCell::new(device));
        {
            let mut bus = bus_with(&handle, options, PowerOn::WhenMasterOnline);
            let mut session = Session::new(&mut bus);
            let mut master = Master::new(&mut session, MasterConfig::default());
            if master.connect(&ConnectOptions::default()).is_ok() {
                let _ = download(&mut master, MAC, &meter, &mut |_| {});
            }
        }
        machine_fault(&handle)?;
        if handle.borrow().power_cut().is_none() {
            return Err(format!("the cut at flash operation {k} of {first}..{last} never came"));
        }
        let (state, name) =
            state_after_power_up(&handle, options).map_err(|e| format!("cut at operation {k}: {e}"))?;
        let in_force = (state.as_slice(), name.as_slice());
        if in_force != (&[0][..], factory_name.as_slice()) && in_force != (&[1][..], meter_name.as_slice()) {
            return Err(format!(
                "cut at operation {k}: configuration state {state:02x?}, product name {name:02x?}"
            ));
        }
    }
    Ok(())
}
