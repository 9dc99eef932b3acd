//! Watchdogs (protocol §5.2–§5.4), bus-off (protocol §7.2) and the LEDs (protocol §7.3).

use super::*;

#[test]
fn explicit_inactivity_deletes_after_ten_seconds() {
    let mut rig = Rig::explicit();
    assert_eq!(rig.node.explicit_connection().deadline, rig.now + Duration::from_secs(10));
    rig.advance(Duration::from_millis(9_999));
    assert!(rig.node.explicit_connection().is_established());
    rig.advance(Duration::from_millis(1));
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::NonExistent);
    assert_eq!(rig.events(), std::vec![Event::ConnectionDeleted(ConnectionKind::Explicit)]);
    assert_eq!(rig.node.allocation(), (AllocationChoice::empty(), None));
}

#[test]
fn explicit_traffic_restarts_the_watchdog() {
    let mut rig = Rig::explicit();
    for _ in 0..5 {
        rig.advance(Duration::from_secs(9));
        rig.send(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01]);
    }
    assert!(rig.node.explicit_connection().is_established());
}

#[test]
fn poll_timeout_with_transition_to_timed_out() {
    let mut rig = Rig::established();
    rig.advance(Duration::from_millis(399));
    assert!(rig.node.poll_connection().is_established());
    rig.advance(Duration::from_millis(1));
    assert_eq!(rig.node.poll_connection().state, ConnectionState::TimedOut);
    assert_eq!(rig.events(), std::vec![Event::ConnectionTimedOut(ConnectionKind::Poll)]);
    assert_eq!(rig.node.network_indication(), Indication::FlashingRed);
    assert_eq!(rig.node.identity_status() >> 4 & 0xF, 0b0010);
    // Polls are ignored in the timed-out state; a Connection Reset brings it back.
    assert_eq!(rig.send(0x42D, &[0; 8]), Tx::new());
    assert_eq!(rig.send(0x42C, &[0x00, 0x05, 0x05, 0x02]), tx(0x42B, &[0x00, 0x85]));
    assert_eq!(rig.send(0x42D, &[0; 8]).len(), 3);
}

#[test]
fn connection_reset_reports_a_timed_out_poll_established_again() {
    let mut rig = Rig::established();
    // Reset of an established connection only restarts its timer: no event.
    assert_eq!(rig.send(0x42C, &[0x00, 0x05, 0x05, 0x02]), tx(0x42B, &[0x00, 0x85]));
    assert_eq!(rig.events(), Vec::<Event>::new());
    rig.advance(Duration::from_millis(400));
    assert_eq!(rig.events(), std::vec![Event::ConnectionTimedOut(ConnectionKind::Poll)]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x05, 0x05, 0x02]), tx(0x42B, &[0x00, 0x85]));
    assert_eq!(rig.events(), std::vec![Event::ConnectionEstablished(ConnectionKind::Poll)]);
}

#[test]
fn poll_auto_delete_and_auto_reset() {
    let mut rig = Rig::established();
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x0C, 0x02]);
    rig.advance(Duration::from_millis(1000));
    assert!(rig.node.poll_connection().is_established(), "auto reset keeps it established");
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x0C, 0x01]);
    rig.events();
    rig.advance(Duration::from_millis(400));
    assert_eq!(rig.node.poll_connection().state, ConnectionState::NonExistent);
    assert_eq!(rig.node.allocation().0, AllocationChoice::EXPLICIT);
}

#[test]
fn deferred_delete_waits_for_the_io_connection() {
    let mut rig = Rig::established();
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x01, 0x0C, 0x03]);
    // Keep polling for 12 s: the explicit watchdog (10 s) expires into deferred delete.
    for _ in 0..120 {
        rig.advance(Duration::from_millis(100));
        rig.send(0x42D, &[0; 8]);
    }
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::DeferredDelete);
    // Explicit traffic brings it back to established.
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x05, 0x01, 0x01]), tx(0x42B, &[0x00, 0x8E, 0x03]));
    for _ in 0..120 {
        rig.advance(Duration::from_millis(100));
        rig.send(0x42D, &[0; 8]);
    }
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::DeferredDelete);
    // Polling stops: the poll times out and the explicit connection is deleted with it (JB).
    rig.events();
    rig.advance(Duration::from_millis(400));
    assert_eq!(rig.node.poll_connection().state, ConnectionState::TimedOut);
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::NonExistent);
    assert_eq!(
        rig.events(),
        std::vec![
            Event::ConnectionTimedOut(ConnectionKind::Poll),
            Event::ConnectionDeleted(ConnectionKind::Explicit)
        ]
    );
}

#[test]
fn deferred_delete_without_io_deletes() {
    let mut rig = Rig::explicit();
    rig.send(0x42C, &[0x00, 0x10, 0x05, 0x01, 0x0C, 0x03]);
    rig.advance(Duration::from_secs(10));
    assert_eq!(rig.node.explicit_connection().state, ConnectionState::NonExistent);
}

// ----- bus-off (protocol §7.2) ------------------------------------------------------------------------

#[test]
fn bus_off_without_boi_faults() {
    let mut rig = Rig::established();
    rig.node.handle_bus_off(rig.now);
    assert_eq!(rig.node.network_state(), NetworkState::CommunicationFaulted(FaultReason::BusOff));
    assert_eq!(rig.node.bus_off_counter(), 1);
    assert_eq!(rig.node.allocation(), (AllocationChoice::empty(), None));
    assert_eq!(rig.node.network_indication(), Indication::Red);
    assert_eq!(rig.send(0x42D, &[0; 8]), Tx::new());
}

#[test]
fn bus_off_with_boi_restarts_the_duplicate_mac_check() {
    let mut config = DeviceConfig::reference();
    config.bus_off_interrupt = true;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    rig.events();
    rig.node.handle_bus_off(rig.now);
    assert_eq!(rig.events(), std::vec![Event::ResetCanController]);
    assert_eq!(rig.drain(), tx(0x42F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12]));
    rig.advance(Duration::from_secs(2));
    assert_eq!(rig.node.network_state(), NetworkState::Online);
    assert_eq!(rig.node.bus_off_counter(), 1);
}

#[test]
fn bus_off_counter_counts_every_bus_off() {
    let mut config = DeviceConfig::reference();
    config.bus_off_interrupt = true;
    let mut rig = Rig::new(config);
    rig.node.power_on(Instant::ZERO);
    rig.advance(Duration::from_secs(2));
    assert_eq!(rig.node.bus_off_counter(), 0);
    for _ in 0..2 {
        rig.node.handle_bus_off(rig.now);
        rig.advance(Duration::from_secs(2));
    }
    assert_eq!(rig.node.bus_off_counter(), 2);
    // DeviceNet attribute 4 (protocol §6.1) reports the same count.
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
    assert_eq!(rig.send(0x42C, &[0x00, 0x0E, 0x03, 0x01, 0x04]), tx(0x42B, &[0x00, 0x8E, 0x02]));
}

// ----- LEDs (protocol §7.3) ---------------------------------------------------------------------------

#[test]
fn led_indications_follow_the_state() {
    let mut rig = Rig::new(DeviceConfig::reference());
    rig.node.power_on(Instant::ZERO);
    assert_eq!(rig.node.leds(Instant::ZERO).module, led::Lit::Green, "self-test: MS green first");
    rig.advance(Duration::from_secs(2));
    assert_eq!(rig.node.network_indication(), Indication::FlashingGreen);
    assert_eq!(rig.node.module_indication(), Indication::Green);
    rig.send(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00]);
    assert_eq!(rig.node.network_indication(), Indication::Green);
    let status = ApplicationStatus { minor_recoverable_fault: true, ..ApplicationStatus::default() };
    rig.node.set_application_status(status, rig.now);
    assert_eq!(rig.node.module_indication(), Indication::FlashingRed);
    assert_eq!(rig.node.identity_status() & 0x100, 0x100);
}

#[test]
fn leds_show_the_indications_once_the_power_up_test_is_over() {
    use led::{Leds, Lit};
    // Powered on at 0 s (test over at 1.5 s), on-line at 2 s: Module Status solid green,
    // Network Status flashing green in phase with going on-line, 0.5 s on / 0.5 s off (protocol §7.3).
    let rig = Rig::online();
    assert_eq!(rig.node.leds(Instant::from_millis(2000)), Leds { module: Lit::Green, network: Lit::Green });
    assert_eq!(rig.node.leds(Instant::from_millis(2500)), Leds { module: Lit::Green, network: Lit::Off });
    assert_eq!(rig.node.leds(Instant::from_millis(3000)), Leds { module: Lit::Green, network: Lit::Green });
}

#[test]
fn major_unrecoverable_fault_alone_shows_module_status_solid_red() {
    let mut rig = Rig::online();
    let status = ApplicationStatus { major_unrecoverable_fault: true, ..ApplicationStatus::default() };
    rig.node.set_application_status(status, rig.now);
    assert_eq!(rig.node.module_indication(), Indication::Red);
}
