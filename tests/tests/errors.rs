//! Clear errors, never panics: a device that never answers (the timeout named), an error
//! response (by name), a duplicate of the master's MAC, unknown buses, bad files.

use can_io::bus::{Bitrate, BusSpec};
use master_core::error::MasterError;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use system_tests::{mac, sim_bus};

#[test]
fn a_device_that_never_answers_names_the_timeout() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let opts = ConnectOptions { target: mac(9), ..ConnectOptions::default() };
    let err = Master::new(&mut session, MasterConfig::default()).connect(&opts).unwrap_err();
    match &err {
        MasterError::Timeout { mac, timeout, .. } => {
            assert_eq!((*mac, *timeout), (9, "explicit response timeout"));
        }
        other => panic!("{other:?}"),
    }
    assert!(
        err.to_string().contains("no answer from MAC 9 within 1000ms (explicit response timeout)"),
        "{err}"
    );
    // Both UCMM opens went out before the Group 2 Only allocation was tried.
    let ucmm = session.records().iter().filter(|r| r.frame.id().as_raw() == 0x780).count();
    assert_eq!(ucmm, 2);
}

#[test]
fn an_error_response_stops_connect_by_name() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let opts = ConnectOptions { epr_ms: 65_001, ..ConnectOptions::default() };
    let err = Master::new(&mut session, MasterConfig::default()).connect(&opts).unwrap_err().to_string();
    assert!(
        err.contains(
            "expected packet rate) = 65001 ms: MAC 5 answered with an error: invalid attribute value (0x09)"
        ),
        "{err}"
    );
    assert_eq!(session.failures(), 1);
}

#[test]
fn another_node_with_the_masters_mac() {
    // A soft slave at MAC 0 is on-line before the master: it answers the master's check.
    let mut bus = can_io::sim::SimBus::new(Bitrate::K250);
    bus.attach(
        Box::new(converter_sim::device::SoftSlave::reference(mac(0))),
        can_io::sim::PowerOn::At(devicenet::Instant::ZERO),
    );
    let mut session = Session::new(&mut bus);
    // Let the slave go on-line first (its checks, seen before the master starts, are just recorded).
    while session.next(devicenet::Instant::from_secs(3)).unwrap().is_some() {}
    let mut m = Master::new(&mut session, MasterConfig::default());
    let err = m.network_access().unwrap_err();
    assert!(matches!(err, MasterError::DuplicateMac { mac: 0, .. }), "{err:?}");
}

#[test]
fn unknown_bus_is_named() {
    let err = "can0".parse::<BusSpec>().unwrap_err();
    assert_eq!(err, "unknown bus 'can0': expected sim, socketcan:IFACE or slcan:PATH[@SERIALBAUD]");
}

#[test]
fn a_missing_transcript_is_named() {
    let err = can_io::log::read_log(std::path::Path::new("/nonexistent/t.log")).unwrap_err();
    assert!(err.to_string().starts_with("/nonexistent/t.log:0:0: cannot read the file"), "{err}");
}
