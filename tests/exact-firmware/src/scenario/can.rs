//! `wrong-bit-rate`, `bus-off`, `bus-load`: the CAN controller's error handling and throughput.

use super::world::{machine_fault, world, Options, MAC};
use crate::board::{BoardKind, NodeSetting};
use crate::device::Firmware;
use can_io::bus::{Bitrate, Origin};
use can_io::sim::PowerOn;
use devicenet::slave::BaudRate;
use devicenet::Duration;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;

/// The node set to 125k on a 500k bus: the master's bring-up finds nobody, not one frame of
/// the node reaches the bus, and its controller counts the errors (`CAN_ESR`: TEC from its own
/// flagged frames, up to bus-off; REC from the master's frames it cannot decode while it still
/// listens; the peaks, as a bus-off recovery clears both). With the bus-off interrupt setting 0
/// (the default) a node that went bus-off stays off the bus and hears nothing more, so either
/// its REC rose or it went bus-off.
pub fn wrong_bit_rate(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
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

/// Bus-off recovery follows the stored bus-off interrupt setting (protocol §7.2): the
/// node at 125k on a 500k bus, alone, drives its controller bus-off with its own flagged
/// frames. With BOI 0 it stays bus-off (one bus-off, still off a second later); with BOI 1 it
/// resets the controller and continues, so it goes bus-off again and again.
pub fn bus_off(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
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
pub const FLOOD: usize = 2000;

/// At 100 % bus load at 500k no receive FIFO overruns: after the bring-up at 500k the master
/// queues [`FLOOD`] poll commands at once, so the bus carries them back to back (with the
/// node's responses, which win the arbitration); every delivery to the node is followed by a
/// look at FOVR of both FIFOs. The load is checked too: the frames' time on the wire over the
/// flood's span.
pub fn bus_load(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
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
