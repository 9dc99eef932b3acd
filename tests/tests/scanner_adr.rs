//! The scanner's automatic device replacement on the simulated bus (issue 28 item 2): a node dies
//! and a factory-fresh device of its kind appears at MAC 63 (`--sim-replace`); the scanner moves
//! it to the lost MAC and brings it into I/O. The rules: a device whose MAC is set by switches is
//! not moved, two identical nodes lost at once turn address recovery off, a device of another
//! kind at 63 is left alone; each is reported as an event.

use can_io::bus::{Bitrate, BusSpec};
use converter_sim::{open_bus, SimSetup};
use devicenet::{Instant, MacId};
use dnet_scanner::events::{EventKind, ScanEvent};
use dnet_scanner::model::{AdrMode, ScanList};
use dnet_scanner::{build_scan_list, Scanner, ScannerOptions};
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;

fn mac(n: u8) -> MacId {
    MacId::new(n).unwrap()
}

/// `dnet-master ARGS` in-process: exit status, stdout, stderr.
fn dnet(args: &[&str]) -> (u8, String, String) {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let mut all = vec!["dnet-master"];
    all.extend_from_slice(args);
    let code = master_harness::cli::run(all, &mut out, &mut err, false);
    (code, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}

fn kinds(events: &[ScanEvent]) -> Vec<(u8, EventKind)> {
    events.iter().map(|e| (e.mac, e.kind)).collect()
}

/// The network scan that builds the list ends at about 6.5 s of simulated time (every empty MAC
/// costs its response timeout): the failures come later.
///
/// The scanner over `setup` with every node of the scanned list on ADR,
/// run until `until` of simulated time; its events and final node states.
fn run(setup: &SimSetup, until: Instant) -> (Vec<ScanEvent>, Scanner) {
    let mut bus = open_bus(&BusSpec::Sim, Bitrate::K250, setup).unwrap();
    let mut session = Session::new(bus.as_mut());
    let mut master = Master::new(&mut session, MasterConfig::default());
    let mut list: ScanList = build_scan_list(&mut master, 0, 63).unwrap();
    for n in &mut list.nodes {
        n.adr = AdrMode::ConfigAddress;
    }
    let mut scanner = Scanner::new(list, 0, ScannerOptions::default());
    scanner.start(&mut master).unwrap();
    while master.session.now() < until {
        scanner.cycle(&mut master).unwrap();
    }
    scanner.stop(&mut master).unwrap();
    (scanner.events().all(), scanner)
}

#[test]
fn a_replacement_at_63_is_moved_to_the_lost_mac_and_brought_into_io() {
    let mut setup = SimSetup::reference();
    setup.macs = vec![mac(5), mac(6)];
    let fails_at = Instant::from_millis(10_000);
    setup.replace = vec![(mac(5), fails_at)];
    let (events, scanner) = run(&setup, Instant::from_secs(22));
    let seen = kinds(&events);
    let steps: Vec<(u8, EventKind)> =
        seen.iter().copied().filter(|(_, k)| *k != EventKind::ConfigStored).collect();
    assert_eq!(
        steps,
        [
            (63, EventKind::AppearedAt63),
            (5, EventKind::NodeLost),
            (5, EventKind::Moved),
            (5, EventKind::DuplicateCheck),
            (5, EventKind::CcvDiffers),
            (5, EventKind::Replaced),
        ],
        "{events:#?}"
    );
    assert!(seen.contains(&(5, EventKind::ConfigStored)) && seen.contains(&(6, EventKind::ConfigStored)));
    let state = scanner.state();
    let n5 = state.nodes.iter().find(|n| n.mac == 5).unwrap();
    // Released at the stop; the replacement's serial number is the one read.
    assert_eq!(
        n5.identity.serial_number,
        Some(0x1234_5678 + converter_sim::replace::SERIAL_OFFSET),
        "{n5:?}"
    );
    assert!(n5.exchanges > 0, "{n5:?}");
    let appeared = events.iter().find(|e| e.kind == EventKind::AppearedAt63).unwrap().time_us;
    let in_io = events.iter().find(|e| e.kind == EventKind::Replaced).unwrap().time_us;
    assert!(appeared >= fails_at.total_micros(), "{events:#?}");
    for e in &events {
        println!("{:>9} us  MAC {:2}  {:?}  {}", e.time_us, e.mac, e.kind, e.detail);
    }
    println!("simulated time from the replacement at 63 to I/O: {} ms", (in_io - appeared) / 1000);
    // The other node never left I/O.
    assert!(!seen.contains(&(6, EventKind::NodeLost)), "{events:#?}");
}

#[test]
fn a_replacement_whose_mac_is_set_by_switches_is_reported_not_moved() {
    // A replacement whose MAC is set by switches (not programmable over the network).
    let mut setup = SimSetup::reference();
    setup.macs = vec![mac(5)];
    setup.replace = vec![(mac(5), Instant::from_millis(10_000))];
    let mut fixed = SimSetup::reference().config;
    fixed.device.switches.programmable = false;
    setup.replacement = Some(fixed);
    let (events, _) = run(&setup, Instant::from_secs(18));
    let seen = kinds(&events);
    assert!(seen.contains(&(63, EventKind::MoveRefused)), "{events:#?}");
    assert!(!seen.iter().any(|(_, k)| *k == EventKind::Moved), "{events:#?}");
    let refused = events.iter().find(|e| e.kind == EventKind::MoveRefused).unwrap();
    assert!(refused.detail.contains("switches"), "{}", refused.detail);
}

#[test]
fn two_identical_nodes_lost_at_once_turn_address_recovery_off() {
    let mut setup = SimSetup::reference();
    setup.macs = vec![mac(5), mac(6), mac(7)];
    setup.replace = vec![(mac(5), Instant::from_millis(10_000)), (mac(6), Instant::from_millis(10_000))];
    let (events, _) = run(&setup, Instant::from_secs(18));
    let seen = kinds(&events);
    assert!(seen.iter().any(|(_, k)| *k == EventKind::AdrDisabled), "{events:#?}");
    assert!(!seen.iter().any(|(_, k)| *k == EventKind::Moved), "{events:#?}");
}

#[test]
fn a_device_of_another_kind_at_63_is_a_keying_mismatch() {
    let mut setup = SimSetup::reference();
    setup.macs = vec![mac(5)];
    setup.replace = vec![(mac(5), Instant::from_millis(10_000))];
    let mut other = SimSetup::reference().config;
    other.device.identity.product_code = 77;
    other.device.switches.programmable = true;
    setup.replacement = Some(other);
    let (events, _) = run(&setup, Instant::from_secs(18));
    let seen = kinds(&events);
    assert!(seen.contains(&(63, EventKind::KeyingMismatch)), "{events:#?}");
    assert!(!seen.iter().any(|(_, k)| *k == EventKind::Moved), "{events:#?}");
}

#[test]
fn cli_scanner_adr_with_sim_replace_reports_the_events_in_json() {
    let (code, out, err) = dnet(&[
        "--slave-mac",
        "5,6",
        "--sim-replace",
        "5@10000",
        "--json",
        "scanner",
        "--adr",
        "--cycles",
        "6000",
    ]);
    let v: serde_json::Value =
        serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}\n{err}"));
    assert_eq!(code, 0, "{out}\n{err}");
    let events = v["events"].as_array().unwrap();
    let names: Vec<&str> = events.iter().map(|e| e["kind"].as_str().unwrap()).collect();
    // The factory-fresh replacement (MAC settable) has another CCV than the node it replaces: the
    // configuration stored when the node joined is downloaded (`configure`'s download).
    for want in
        ["appeared_at_63", "node_lost", "moved", "duplicate_check", "ccv_differs", "downloaded", "replaced"]
    {
        assert!(names.contains(&want), "{want} missing: {names:?}");
    }
    let n5 = v["nodes"].as_array().unwrap().iter().find(|n| n["mac"] == 5).unwrap();
    assert_eq!(n5["status"], "ok", "{n5}");
}
