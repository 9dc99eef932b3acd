//! `scan` with several simulated slaves at different MAC IDs: every device found with its
//! identity and I/O sizes, the requests overlapped.

use can_io::bus::Bitrate;
use devicenet::Duration;
use dnet_scanner::scan::scan;
use harness_common::console::Progress;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;
use system_tests::sim_bus;

#[test]
fn finds_every_device_with_identity_and_sizes() {
    let mut bus = sim_bus(&[3, 5, 12, 63], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let report =
        scan(&mut Master::new(&mut session, MasterConfig::default()), 0, 63, &mut Progress::off()).unwrap();
    let macs: Vec<u8> = report.devices.iter().map(|d| d.mac).collect();
    assert_eq!(macs, vec![3, 5, 12, 63]);
    assert_eq!(report.asked, 63);
    for d in &report.devices {
        assert_eq!(d.status, "ok");
        assert_eq!(d.identity.vendor_id, Some(0x1234));
        assert_eq!(d.identity.device_type, Some(0x000C));
        assert_eq!(d.identity.product_code, Some(1));
        assert_eq!(d.identity.revision.as_deref(), Some("1.1"));
        assert_eq!(d.identity.product_name.as_deref(), Some("Serial-DeviceNet Bridge"));
        assert_eq!((d.produced_size, d.consumed_size), (Some(18), Some(8)));
        assert_eq!(d.identity.serial_number, Some(0x1234_5678 + u32::from(d.mac) - 5));
    }
    assert_eq!(session.failures(), 0);
}

#[test]
fn absent_nodes_share_one_timeout() {
    let mut bus = sim_bus(&[5, 6], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let config = MasterConfig { response_timeout: Duration::from_millis(200), ..MasterConfig::default() };
    let report = scan(&mut Master::new(&mut session, config), 0, 63, &mut Progress::off()).unwrap();
    assert_eq!(report.devices.len(), 2);
    // 61 silent MAC IDs: one shared 200 ms window, not 61 of them.
    let scan_time = Duration::from_micros(report.scan_micros);
    assert!(scan_time < Duration::from_millis(400), "{scan_time}");
}

#[test]
fn requests_to_different_devices_overlap() {
    let mut bus = sim_bus(&[1, 2, 3, 4], Bitrate::K500);
    let mut session = Session::new(&mut bus);
    let report =
        scan(&mut Master::new(&mut session, MasterConfig::default()), 1, 4, &mut Progress::off()).unwrap();
    assert_eq!(report.devices.len(), 4);
    // All four allocations are on the bus before the master's first Get to any device: the
    // requests overlap instead of waiting node by node.
    let records = session.records();
    let last_allocate = records.iter().rposition(|r| r.frame.id().as_raw() & 7 == 6).unwrap();
    let first_get = records
        .iter()
        .position(|r| r.frame.id().as_raw() & 7 == 4 && r.frame.data().get(1) == Some(&0x0E))
        .unwrap();
    assert!(last_allocate < first_get, "{last_allocate} {first_get}");
}

#[test]
fn an_empty_network() {
    let mut bus = sim_bus(&[], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let report =
        scan(&mut Master::new(&mut session, MasterConfig::default()), 10, 20, &mut Progress::off()).unwrap();
    assert!(report.devices.is_empty());
    assert_eq!(report.asked, 11);
}
