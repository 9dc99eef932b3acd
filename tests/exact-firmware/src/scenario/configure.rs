//! `configure`: the bench's download of the Modbus meter, and the stored image after a power cycle.

use super::world::{bus_with, machine_fault, world, Options, MAC};
use crate::board::BoardKind;
use crate::device::Firmware;
use can_io::sim::PowerOn;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;

/// The description `configure` downloads (the one the QEMU test downloads).
pub const METER: &str = include_str!("../../../../slave-fw/descriptions/modbus-meter.toml");

/// `dnet-master configure` of the Modbus meter (slave-fw/descriptions/modbus-meter.toml, through
/// master-harness's own download: Begin_Download, Write_Chunk, Commit_Download, read-back,
/// Identity Reset, every check of the device against the description), then a power cycle: the
/// stored image is still in force (configuration state 1, the description's product name) and
/// the instrument USART runs the description's line, 19200 bit/s 8E1. No Modbus slave answers
/// on the line here (the QEMU test's pymodbus does): what the gateway reads is not checked.
pub fn configure(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
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
