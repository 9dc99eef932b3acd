//! `--pcap`: the capture of a whole bring-up, written by can-io's `PcapBus` around the simulated
//! bus, holds every frame of protocol §2 with the times of the transcript.

use can_io::bus::Bitrate;
use can_io::pcap::{record, PcapBus, PcapWriter, CAN_FRAME_LEN, FILE_HEADER_LEN, RECORD_HEADER_LEN};
use can_io::sim::{PowerOn, SimBus};
use converter_sim::SoftSlave;
use devicenet::reference::BRING_UP;
use devicenet::MacId;
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;
use std::io::{self, Write};
use std::sync::{Arc, Mutex};

/// A sink the test can read back.
#[derive(Clone, Default)]
struct Shared(Arc<Mutex<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.lock().map_err(|_| io::Error::other("poisoned"))?.extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[test]
fn wrapped_bus_captures_the_whole_bring_up() {
    let sink = Shared::default();
    let mut sim = SimBus::new(Bitrate::K250);
    sim.attach(Box::new(SoftSlave::reference(MacId::new(5).unwrap())), PowerOn::WhenMasterOnline);
    let mut bus = PcapBus::new(Box::new(sim), PcapWriter::new(Box::new(sink.clone())).unwrap());
    let mut session = Session::new(&mut bus);
    Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default()).unwrap();
    let records: Vec<_> = session.records().to_vec();
    let bytes = sink.0.lock().unwrap().clone();
    assert_eq!(bytes.len(), FILE_HEADER_LEN + BRING_UP.len() * (RECORD_HEADER_LEN + CAN_FRAME_LEN));
    for (i, (chunk, want)) in
        bytes[FILE_HEADER_LEN..].chunks(RECORD_HEADER_LEN + CAN_FRAME_LEN).zip(&BRING_UP).enumerate()
    {
        let can = &chunk[RECORD_HEADER_LEN..];
        assert_eq!(u32::from_be_bytes([can[0], can[1], can[2], can[3]]), u32::from(want.id), "frame {i}");
        assert_eq!(&can[8..8 + usize::from(can[4])], want.data, "frame {i}");
        assert_eq!(chunk, record(records[i].at, &records[i].frame), "frame {i}: time as in the log");
    }
}
