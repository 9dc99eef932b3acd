//! The master harness on the simulated bus (virtual clock) against the soft slave with the
//! simulated breaker: the breaker's state follows a close, an open and a close again, each sent
//! once through the poll output with a new sequence number, as `dnet-master monitor --output`
//! sends them.

mod common;

use can_io::bus::Bitrate;
use can_io::sim::{PowerOn, SimBus};
use common::{bring_up, mac, poll_until};
use converter_sim::device::{SoftSlave, LOAD, SWITCH_BYTE, SWITCH_CLOSED, SWITCH_OPEN};
use devicenet::Duration;
use master_core::master::{Master, MasterConfig};
use master_core::session::Session;

#[test]
fn close_open_close_through_the_poll_output() {
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(SoftSlave::reference(mac())), PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    let mut master = Master::new(&mut session, MasterConfig::default());
    let summary = bring_up(&mut master);
    let (input, _) = poll_until(&mut master, &summary, &[0; 8], Duration::from_secs(2), |_| true);
    assert_eq!(input[SWITCH_BYTE], SWITCH_OPEN, "the breaker starts open");

    let steps: [(u8, u8, u8); 3] = [(2, 1, SWITCH_CLOSED), (1, 2, SWITCH_OPEN), (2, 3, SWITCH_CLOSED)];
    for (command, sequence, want) in steps {
        let output = [command, sequence, 0, 0, 0, 0, 0, 0];
        // The breaker sends its status once a second: the change shows within ~1 s.
        let (input, polls) = poll_until(&mut master, &summary, &output, Duration::from_millis(1500), |i| {
            i[SWITCH_BYTE] == want
        });
        assert!(polls > 1, "the state changed only after the command, not before");
        let currents: [u8; 4] = input[..4].try_into().unwrap();
        assert_eq!(currents, if want == SWITCH_CLOSED { LOAD } else { [0; 4] });
    }
    // Three commands, each executed once (class 0x64 attribute 5: commands sent).
    assert_eq!(common::link_attribute(&mut master, 5), 3);
    assert_eq!(master.session.failures(), 0);
}
