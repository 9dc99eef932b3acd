//! The start the scan-list edit tests share (`scanner_adr_edit.rs`, `scanner_health_edit.rs`):
//! MAC 5, 6 and 7 on the simulated bus at 250 kbit/s, the scan list uploaded from it, the scanner
//! started with MAC 5 and 6 only and run for 0.5 s.

use can_io::bus::{Bitrate, BusSpec};
use converter_sim::{open_bus, SimSetup};
use devicenet::{Duration, MacId};
use dnet_scanner::model::{ScanEntry, ScanList};
use dnet_scanner::{build_scan_list, Scanner, ScannerOptions};
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;

/// Runs the scanner's cycles for `d` of the session's time.
pub fn run_for(s: &mut Scanner, m: &mut Master<'_, '_>, d: Duration) {
    let end = m.session.now() + d;
    while m.session.now() < end {
        s.cycle(m).unwrap();
    }
}

/// Calls `test` with the scanner (MAC 5 and 6, run for 0.5 s), its master and MAC 7's entry as
/// uploaded (on the bus, not in the list).
pub fn with_5_and_6_scanned(test: impl FnOnce(&mut Scanner, &mut Master<'_, '_>, ScanEntry)) {
    let mut setup = SimSetup::reference();
    setup.macs = [5, 6, 7].map(|m| MacId::new(m).unwrap()).to_vec();
    let mut bus = open_bus(&BusSpec::Sim, Bitrate::K250, &setup).unwrap();
    let mut session = Session::new(bus.as_mut());
    let mut m = Master::new(&mut session, MasterConfig::default());
    let full: ScanList = build_scan_list(&mut m, 0, 63).unwrap();
    let seven = full.nodes.iter().find(|n| n.mac == 7).unwrap().clone();
    let mut list = full.clone();
    list.nodes.retain(|n| n.mac != 7);
    let mut s = Scanner::new(list, 0, ScannerOptions::default());
    s.start(&mut m).unwrap();
    run_for(&mut s, &mut m, Duration::from_millis(500));
    test(&mut s, &mut m, seven);
}
