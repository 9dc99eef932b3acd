//! The timing of a scan list (the scanner's docs, [`crate::engine`], give the rules): each node's
//! worst-case frame bits, the minimum cycle, the inter-scan delay, the expected packet rate and the
//! response window.

use crate::model::{ScanEntry, ScanList};
use can_io::bus::Bitrate;
use devicenet::Duration;
use master_core::master::io::IoKind;

/// The computed timing of a scan list. See the scanner's timing rules ([`crate::engine`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Timing {
    /// Sum of every node's frames in a cycle (poll command and response, strobe command and
    /// responses, COS/cyclic production, data and acknowledgements), worst-case stuffing.
    pub min_cycle: Duration,
    /// The inter-scan delay.
    pub interscan: Duration,
    /// The expected packet rate, ms.
    pub epr_ms: u16,
    /// How long responses are waited for after the strobe and poll commands went out.
    pub window: Duration,
}

/// Worst-case bits of the frames carrying `size` bytes of I/O data (fragmented above 8 bytes).
#[must_use]
pub fn io_frame_bits(size: u16) -> u64 {
    let bits = |n: u32| u64::from(47 + 8 * n + (34 + 8 * n - 1) / 4);
    let size = u32::from(size);
    if size <= 8 {
        return bits(size);
    }
    let full = size / 7;
    let rest = size % 7;
    full as u64 * bits(8) + if rest > 0 { bits(rest + 1) } else { 0 }
}

/// The timing of `list` at `bitrate`. See the scanner's timing rules ([`crate::engine`]).
#[must_use]
pub fn timing(list: &ScanList, bitrate: Bitrate) -> Timing {
    let node_bits = |n: &ScanEntry| match n.io_kind() {
        IoKind::Poll => io_frame_bits(n.output_size) + io_frame_bits(n.input_size),
        IoKind::Strobe => io_frame_bits(n.input_size.min(8)),
        IoKind::ChangeOfState | IoKind::Cyclic => {
            let acks = if n.ack_suppression { 0 } else { 2 * io_frame_bits(0) };
            io_frame_bits(n.input_size) + io_frame_bits(n.output_size) + acks
        }
    };
    let strobe_command =
        if list.nodes.iter().any(|n| n.io_kind() == IoKind::Strobe) { io_frame_bits(8) } else { 0 };
    let bits: u64 = list.nodes.iter().map(node_bits).sum::<u64>() + strobe_command;
    let bps = u64::from(bitrate.bits_per_second().max(1));
    let min_cycle = Duration::from_micros((bits * 1_000_000).div_ceil(bps));
    let isd_ms = match list.interscan_delay_ms {
        Some(ms) => u64::from(ms),
        None => (min_cycle.total_micros().div_ceil(10_000)).max(2),
    };
    let interscan = Duration::from_millis(isd_ms);
    let epr_ms = match list.expected_packet_rate_ms {
        Some(ms) => ms.max(1),
        None => {
            let four = 4 * (min_cycle.total_micros() + interscan.total_micros());
            let ms = four.div_ceil(10_000) * 10;
            u16::try_from(ms.max(100)).unwrap_or(u16::MAX)
        }
    };
    let window_us = (2 * min_cycle.total_micros()).max(20_000).min(u64::from(epr_ms) * 1000);
    Timing { min_cycle, interscan, epr_ms, window: Duration::from_micros(window_us) }
}
