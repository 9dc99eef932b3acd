//! `connect` on the simulated bus reproduces the 28 frames of protocol §2 byte for byte,
//! deciding each frame from the answers, with every check holding.

use can_io::bus::{Bitrate, Origin};
use devicenet::reference::{Direction, BRING_UP, INPUT_IMAGE};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::{Session, Verdict};
use system_tests::{mac, sim_bus};

fn direction(origin: Origin) -> Direction {
    match origin {
        Origin::Local => Direction::MasterToSlave,
        Origin::Remote => Direction::SlaveToMaster,
    }
}

#[test]
fn connect_reproduces_the_reference_sequence_byte_for_byte() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let summary =
        Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default()).unwrap();
    let records = session.records();
    assert_eq!(records.len(), BRING_UP.len(), "{records:#?}");
    for (i, (got, want)) in records.iter().zip(BRING_UP.iter()).enumerate() {
        assert_eq!(
            (direction(got.origin), got.frame.id().as_raw(), got.frame.data()),
            (want.direction, want.id, want.data),
            "frame {i} ({})",
            want.meaning
        );
    }
    assert_eq!(session.failures(), 0);
    assert!(records.iter().all(|r| matches!(r.verdict, Verdict::Sent | Verdict::Ok(_))), "{records:#?}");
    assert_eq!(summary.vendor_id, Some(0x1234));
    assert_eq!(summary.device_type, Some(0x000C));
    assert_eq!(summary.product_code, Some(1));
    assert_eq!((summary.produced_size, summary.consumed_size), (Some(18), Some(8)));
    assert_eq!(summary.expected_packet_rate_ms, Some(100));
    assert_eq!(summary.last_input.as_deref(), Some(&INPUT_IMAGE[..]));
    assert!(!summary.ucmm_capable);
}

#[test]
fn timing_follows_the_capture() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default()).unwrap();
    let r = session.records();
    let ms = |i: usize| r[i].at.total_millis();
    // Master's checks 1 s apart; the slave powers on when the master is on-line (2 s).
    assert_eq!((ms(0), ms(1), ms(2), ms(3)), (0, 1000, 2000, 3000));
    // The device is on-line 1 s after its second request: the UCMM open follows, and its retry
    // after the 500 ms UCMM timeout; the allocation after the second 500 ms.
    assert_eq!((ms(4), ms(5), ms(6)), (4000, 4500, 5000));
    // Every frame takes its time on the wire: nothing overlaps.
    for w in r.windows(2) {
        assert!(w[1].at > w[0].at, "{w:#?}");
    }
}

#[test]
fn several_polls_at_the_expected_packet_rate_and_other_bitrates() {
    for bitrate in [Bitrate::K125, Bitrate::K250, Bitrate::K500] {
        let mut bus = sim_bus(&[5], bitrate);
        let mut session = Session::new(&mut bus);
        let opts = ConnectOptions { polls: 3, epr_ms: 50, ..ConnectOptions::default() };
        Master::new(&mut session, MasterConfig::default()).connect(&opts).unwrap();
        let polls: Vec<_> =
            session.records().iter().filter(|r| r.frame.id().as_raw() == 0x42D).map(|r| r.at).collect();
        assert_eq!(polls.len(), 3);
        // 50 ms apart, give or take the intermission the first poll waited for.
        let gap = (polls[2] - polls[1]).total_micros();
        assert_eq!(gap, 50_000, "{bitrate}");
        let first = (polls[1] - polls[0]).total_micros();
        assert!((49_900..=50_000).contains(&first), "{bitrate}: {first}");
        assert_eq!(session.failures(), 0);
    }
}

#[test]
fn output_command_closes_the_simulated_breaker() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    // 15 polls 100 ms apart: the close command goes out at once, the breaker's next status frame
    // (once a second) shows it closed and carrying its load.
    let opts =
        ConnectOptions { polls: 15, output: Some(vec![2, 1, 0, 0, 0, 0, 0, 0]), ..ConnectOptions::default() };
    let summary = Master::new(&mut session, MasterConfig::default()).connect(&opts).unwrap();
    let input = summary.last_input.unwrap();
    assert_eq!(input[9], 0xF0, "closed");
    assert!(input[0] > 100, "phase A current flows");
    assert_eq!(session.failures(), 0);
}

#[test]
fn verify_state_reads_the_states_and_the_watchdog() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let opts = ConnectOptions { verify_state: true, ..ConnectOptions::default() };
    Master::new(&mut session, MasterConfig::default()).connect(&opts).unwrap();
    assert_eq!(session.failures(), 0);
    let last = session.records().last().unwrap();
    assert_eq!(last.frame.data(), &[0x00, 0x8E, 0x04], "poll connection timed out after 4 x EPR");
}

#[test]
fn other_master_mac() {
    let mut bus = sim_bus(&[5], Bitrate::K250);
    let mut session = Session::new(&mut bus);
    let config = MasterConfig { mac: mac(3), ..MasterConfig::default() };
    Master::new(&mut session, config).connect(&ConnectOptions::default()).unwrap();
    let first = &session.records()[0];
    assert_eq!(first.frame.id().as_raw(), 0x41F);
    let alloc = session.records().iter().find(|r| r.frame.id().as_raw() == 0x42E).unwrap();
    assert_eq!(alloc.frame.data(), &[0x03, 0x4B, 0x03, 0x01, 0x01, 0x03]);
    assert_eq!(session.failures(), 0);
}
