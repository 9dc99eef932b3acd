//! System tests across the crates: the master harness (`master_harness`) driving the soft slave
//! (the core's `SlaveNode` with the built-in instrument model) on the simulated bus, compared with
//! the reference transcript of protocol §2 (`devicenet::reference`).
//!
//! The tests live in `tests/`, one file per feature; this library holds their shared helpers.

use can_io::bus::Bitrate;
use can_io::log::format_line;
use can_io::sim::{PowerOn, SimBus};
use converter_sim::device::SoftSlave;
use devicenet::{Instant, MacId};
use master_core::session::Record;

/// A MAC ID from a literal (test helper: panics on an invalid literal).
pub fn mac(n: u8) -> MacId {
    MacId::new(n).expect("MAC literal 0..=63")
}

/// A simulated bus at `bitrate` with a reference soft slave at each MAC, powered on when the master
/// is on-line.
pub fn sim_bus(macs: &[u8], bitrate: Bitrate) -> SimBus {
    let mut bus = SimBus::new(bitrate);
    for &m in macs {
        bus.attach(Box::new(SoftSlave::reference(mac(m))), PowerOn::WhenMasterOnline);
    }
    bus
}

/// The records as a `candump -L` log.
pub fn log_text(records: &[Record], iface: &str) -> String {
    records.iter().map(|r| format_line(r.at, iface, &r.frame) + "\n").collect()
}

/// Time of record `r` in whole milliseconds.
pub fn millis(at: Instant) -> u64 {
    at.total_millis()
}
