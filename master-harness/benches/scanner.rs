//! The scanner's speed goal (issue 15): 63 polled breakers (the reference soft slave: 18-byte
//! input, 8-byte output) at 500 kbit/s on the simulated bus. Reported, not asserted: the median
//! full scan cycle (bus time, inter-scan delay included), the time the cycle's frames alone take
//! on the wire (`can_io::sim::frame_bits` of the actual poll commands and response fragments), the
//! ratio of the two, the bus load, and the wall time per cycle of the simulation. Goal: <= 70 ms.
//!
//! `cargo bench -p master-harness --bench scanner`

use can_io::bus::Bitrate;
use can_io::sim::{frame_bits, PowerOn, SimBus};
use converter_sim::SoftSlave;
use devicenet::fragment::io_fragments;
use devicenet::id::Group1MessageId;
use devicenet::{CanFrame, Group2Message, Identifier, MacId};
use dnet_scanner::model::{ScanEntry, ScanList};
use dnet_scanner::{Scanner, ScannerOptions};
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;

const CYCLES: u64 = 200;

fn main() {
    let mut bus = SimBus::new(Bitrate::K500);
    for mac in 1..=63 {
        bus.attach(Box::new(SoftSlave::reference(MacId::new(mac).unwrap())), PowerOn::WhenMasterOnline);
    }
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let list = ScanList {
        nodes: (1..=63)
            .map(|mac| ScanEntry {
                mac,
                connection: "poll".into(),
                ack_suppression: false,
                inhibit_ms: None,
                vendor_id: Some(0x1234),
                device_type: Some(0x000C),
                product_code: Some(1),
                major_revision: None,
                minor_revision: None,
                input_size: 18,
                output_size: 8,
                name: None,
                adr: Default::default(),
                keying: Default::default(),
                enabled: true,
            })
            .collect(),
        ..ScanList::default()
    };
    let mut scanner =
        Scanner::new(list, 0, ScannerOptions { bitrate: Bitrate::K500, ..ScannerOptions::default() });
    scanner.start(&mut master).expect("start");
    let wall = std::time::Instant::now();
    for _ in 0..CYCLES {
        scanner.cycle(&mut master).expect("cycle");
    }
    let wall = wall.elapsed();
    let st = scanner.state().clone();
    assert!(st.nodes.iter().all(|n| n.code == 0), "every node ok");
    // The frames of one cycle, as they were on the wire.
    let mut bits = 0u64;
    for n in &st.nodes {
        let mac = MacId::new(n.mac).unwrap();
        let cmd = CanFrame::new(Identifier::group2(mac, Group2Message::PollCommand), &n.output).unwrap();
        bits += u64::from(frame_bits(&cmd));
        let rsp = Identifier::group1(Group1MessageId::POLL_RESPONSE, mac);
        for f in io_fragments(&n.input) {
            bits += u64::from(frame_bits(&CanFrame::new(rsp, &f).unwrap()));
        }
    }
    let frames_ms = bits as f64 / 500_000.0 * 1e3;
    let t = scanner.timing();
    println!("scanner: 63 polled breakers (18 in / 8 out) at 500 kbit/s, simulated bus, {CYCLES} cycles");
    println!("  median full scan cycle   {:.2} ms (goal <= 70 ms)", st.cycle_ms);
    println!("  frames alone             {frames_ms:.2} ms ({bits} bits)");
    println!("  ratio cycle / frames     {:.3}", st.cycle_ms / frames_ms);
    println!("  bus load                 {:.1} %", st.bus_load * 100.0);
    println!(
        "  inter-scan delay {} ms, EPR {} ms, worst-case minimum cycle {:.2} ms",
        t.interscan.total_millis(),
        t.epr_ms,
        t.min_cycle.total_micros() as f64 / 1e3
    );
    println!("  simulation wall time     {:.2} ms per cycle", wall.as_secs_f64() * 1e3 / CYCLES as f64);
}
