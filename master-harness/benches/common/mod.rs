//! What the benchmarks share: a realistic exchange recorded on the simulated bus.

use can_io::bus::Bitrate;
use can_io::log::format_line;
use can_io::sim::{PowerOn, SimBus};
use converter_sim::device::SoftSlave;
use devicenet::{CanFrame, Instant, MacId};
use master_core::master::{ConnectOptions, Master, MasterConfig};
use master_core::session::Session;

/// The frames of a realistic exchange (bring-up, product name, 20 polls), repeated with shifted
/// times to reach `frames` frames.
pub fn generated_frames(frames: usize) -> Vec<(Instant, CanFrame)> {
    let mut bus = SimBus::new(Bitrate::K250);
    bus.attach(Box::new(SoftSlave::reference(MacId::from_low_bits(5))), PowerOn::WhenMasterOnline);
    let mut session = Session::new(&mut bus);
    {
        let mut m = Master::new(&mut session, MasterConfig::default());
        let opts = ConnectOptions { polls: 20, ..ConnectOptions::default() };
        m.connect(&opts).expect("bring-up on the simulated bus");
        m.get(MacId::from_low_bits(5), 1, 1, 7).expect("product name");
    }
    let records = session.records().to_vec();
    let span = records.last().map_or(1, |r| r.at.total_micros() + 1000);
    let mut out = Vec::with_capacity(frames);
    let mut round = 0u64;
    while out.len() < frames {
        for r in records.iter().take(frames - out.len()) {
            out.push((Instant::from_micros(r.at.total_micros() + round * span), r.frame));
        }
        round += 1;
    }
    out
}

/// [`generated_frames`] as a `candump -L` log.
#[allow(dead_code)] // each bench uses a part
pub fn generated_log(frames: usize) -> String {
    let mut text = String::with_capacity(frames * 40);
    for (at, frame) in generated_frames(frames) {
        text.push_str(&format_line(at, "can0", &frame));
        text.push('\n');
    }
    text
}
