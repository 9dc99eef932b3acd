//! `ccv`: Identity attribute 9, the configuration consistency value (protocol §II.5.3), on the
//! exact firmware: the factory value, a new value after a download, the same after a power cycle.

use super::configure::METER;
use super::world::{bus_with, machine_fault, master_checks, world, Options, MAC};
use crate::board::BoardKind;
use crate::device::Firmware;
use can_io::sim::PowerOn;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use slave_fw::converter::consistency::{consistency_value, FACTORY_CCV};

/// Reads Identity attribute 9 (a UINT) through the master's explicit connection.
fn read_ccv(master: &mut Master<'_, '_>, when: &str) -> Result<u16, String> {
    master.open_explicit(MAC).map_err(|e| format!("{when}: open: {e}"))?;
    let (value, _) = master.get(MAC, 1, 1, 9).map_err(|e| format!("{when}: get attribute 9: {e}"))?;
    match value.as_slice() {
        &[lo, hi] => Ok(u16::from_le_bytes([lo, hi])),
        other => Err(format!("{when}: attribute 9 is {other:02x?}, not a UINT")),
    }
}

/// Reads the CCV of the factory default (the value the host computes from the firmware's
/// factory image, [`FACTORY_CCV`]), downloads the Modbus meter with `dnet-master configure`'s
/// own download (which resets the device), reads the CCV of that image (the host's
/// [`consistency_value`] of the bytes downloaded, not the factory value), power-cycles the
/// board and reads the same value again: the CCV follows the stored configuration, is computed
/// by the firmware as by the host, and survives a reset.
pub fn ccv(board: BoardKind, elf: &Firmware, options: &Options) -> Result<(), String> {
    use master_harness::configure::download;
    let meter =
        slave_fw::description::DeviceDescription::parse(METER).map_err(|e| format!("the meter: {e}"))?;
    let image = slave_fw::image::encode_to_vec(&meter.converter).map_err(|e| format!("the meter: {e}"))?;
    let want = consistency_value(&image);
    if want == FACTORY_CCV {
        return Err(format!("the meter's CCV {want:#06x} is the factory one: nothing to tell apart"));
    }
    let (mut bus, handle) = world(board, elf, options, PowerOn::WhenMasterOnline)?;
    {
        let mut session = Session::new(&mut bus);
        let mut master = Master::new(&mut session, MasterConfig::default());
        let connected = master.connect(&ConnectOptions::default());
        machine_fault(&handle)?;
        connected.map_err(|e| format!("connect: {e}"))?;
        let factory = read_ccv(&mut master, "factory default");
        machine_fault(&handle)?;
        let factory = factory?;
        if factory != FACTORY_CCV {
            return Err(format!("the factory CCV is {factory:#06x}, the host computes {FACTORY_CCV:#06x}"));
        }
        let report = download(&mut master, MAC, &meter, &mut |_| {});
        machine_fault(&handle)?;
        let report = report.map_err(|e| format!("download: {e}"))?;
        if let Some(check) = report.failures().first() {
            return Err(format!("after the download: {check:?}"));
        }
        let configured = read_ccv(&mut master, "after the download");
        machine_fault(&handle)?;
        let configured = configured?;
        if configured != want {
            return Err(format!("after the download the CCV is {configured:#06x}, not {want:#06x}"));
        }
        master_checks(master.session)?;
    }
    let mut bus = bus_with(&handle, options, PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let online = master.network_access().and_then(|()| master.await_online(&[MAC]));
    machine_fault(&handle)?;
    online.map_err(|e| format!("after the power cycle: {e}"))?;
    let after = read_ccv(&mut master, "after the power cycle");
    machine_fault(&handle)?;
    let after = after?;
    if after != want {
        return Err(format!("after the power cycle the CCV is {after:#06x}, not {want:#06x}"));
    }
    master_checks(master.session)
}
