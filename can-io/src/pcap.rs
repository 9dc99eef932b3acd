//! `--pcap FILE`: every frame seen on the bus in a pcap capture file that Wireshark and tshark
//! open directly.
//!
//! The file is a classic pcap (magic `0xA1B2C3D4`, version 2.4, microsecond timestamps) with link
//! type [`LINKTYPE_CAN_SOCKETCAN`] (227). Each record is the 16-byte Linux `struct can_frame` as a
//! SocketCAN capture holds it:
//!
//! | bytes | content |
//! |---|---|
//! | 0–3 | CAN identifier and flags, **big-endian** (the link type's rule; DeviceNet uses 11-bit IDs, no flags) |
//! | 4 | data length (0–8) |
//! | 5–7 | padding and reserved, zero |
//! | 8–15 | data, zero-padded to 8 bytes |
//!
//! Timestamps are the bus clock (as in the `--log` file), so a capture and a log of one run agree.
//! Tshark shows the DeviceNet meaning with `tshark -r FILE -d can.subdissector=devicenet`.
//!
//! The writing wraps the bus ([`PcapBus`]) instead of changing the session, in the way smoltcp's
//! `PcapWriter` wraps a device: every frame the wrapped bus returns from [`Bus::recv`] — this
//! program's own and everyone else's — is appended and flushed at once, so the capture can be read
//! while the run goes on and survives an interrupted run.

use crate::bus::{Bus, BusError, BusEvent};
use devicenet::{CanFrame, Instant};
use std::io::{self, Write};
use std::path::Path;

/// The pcap link type of Linux SocketCAN captures (`LINKTYPE_CAN_SOCKETCAN`).
pub const LINKTYPE_CAN_SOCKETCAN: u32 = 227;
/// The size of one record's packet data: Linux `CAN_MTU`, a `struct can_frame`.
pub const CAN_FRAME_LEN: usize = 16;
/// The pcap file header's magic number (microsecond timestamps), written in native byte order.
pub const PCAP_MAGIC: u32 = 0xA1B2_C3D4;
/// The length of the pcap file header.
pub const FILE_HEADER_LEN: usize = 24;
/// The length of a record header.
pub const RECORD_HEADER_LEN: usize = 16;

/// The pcap file header for SocketCAN captures.
pub fn file_header() -> [u8; FILE_HEADER_LEN] {
    let mut h = [0u8; FILE_HEADER_LEN];
    h[0..4].copy_from_slice(&PCAP_MAGIC.to_le_bytes());
    h[4..6].copy_from_slice(&2u16.to_le_bytes()); // version 2.4
    h[6..8].copy_from_slice(&4u16.to_le_bytes());
    // bytes 8..16: time zone offset and timestamp accuracy, both 0
    h[16..20].copy_from_slice(&(CAN_FRAME_LEN as u32).to_le_bytes()); // snapshot length
    h[20..24].copy_from_slice(&LINKTYPE_CAN_SOCKETCAN.to_le_bytes());
    h
}

/// One record: its header (time, lengths) and the SocketCAN frame.
pub fn record(at: Instant, frame: &CanFrame) -> [u8; RECORD_HEADER_LEN + CAN_FRAME_LEN] {
    let us = at.total_micros();
    let secs = u32::try_from(us / 1_000_000).unwrap_or(u32::MAX);
    let micros = (us % 1_000_000) as u32;
    let mut r = [0u8; RECORD_HEADER_LEN + CAN_FRAME_LEN];
    r[0..4].copy_from_slice(&secs.to_le_bytes());
    r[4..8].copy_from_slice(&micros.to_le_bytes());
    r[8..12].copy_from_slice(&(CAN_FRAME_LEN as u32).to_le_bytes()); // captured
    r[12..16].copy_from_slice(&(CAN_FRAME_LEN as u32).to_le_bytes()); // on the wire
    let can = &mut r[RECORD_HEADER_LEN..];
    can[0..4].copy_from_slice(&u32::from(frame.id().as_raw()).to_be_bytes());
    let data = frame.data();
    can[4] = data.len() as u8; // a CanFrame holds at most 8 bytes
    can[8..8 + data.len()].copy_from_slice(data);
    r
}

/// Writes a SocketCAN pcap capture, flushing each record.
pub struct PcapWriter {
    out: Box<dyn Write>,
}

impl std::fmt::Debug for PcapWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PcapWriter").finish_non_exhaustive()
    }
}

impl PcapWriter {
    /// Creates (truncates) `path` and writes the file header.
    pub fn create(path: &Path) -> io::Result<PcapWriter> {
        PcapWriter::new(Box::new(std::fs::File::create(path)?))
    }

    /// A capture into any sink; the file header is written at once.
    pub fn new(mut out: Box<dyn Write>) -> io::Result<PcapWriter> {
        out.write_all(&file_header())?;
        out.flush()?;
        Ok(PcapWriter { out })
    }

    /// Appends one frame seen at `at` (bus clock).
    pub fn write(&mut self, at: Instant, frame: &CanFrame) -> io::Result<()> {
        self.out.write_all(&record(at, frame))?;
        self.out.flush()
    }
}

/// A bus that writes every frame it delivers to a pcap capture. See the [module docs](self).
/// `B` may be `dyn Bus`: the command line wraps whichever bus it opened.
pub struct PcapBus<B: Bus + ?Sized> {
    inner: Box<B>,
    pcap: PcapWriter,
}

impl<B: Bus + ?Sized> PcapBus<B> {
    /// Wraps `inner`, capturing into `pcap`.
    pub fn new(inner: Box<B>, pcap: PcapWriter) -> PcapBus<B> {
        PcapBus { inner, pcap }
    }
}

impl<B: Bus + ?Sized> Bus for PcapBus<B> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn now(&mut self) -> Instant {
        self.inner.now()
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        self.inner.send(frame)
    }

    fn recv(&mut self, deadline: Instant) -> Result<Option<BusEvent>, BusError> {
        let event = self.inner.recv(deadline)?;
        if let Some(ev) = &event {
            self.pcap
                .write(ev.at, &ev.frame)
                .map_err(|source| BusError::Io { what: "writing the pcap file".into(), source })?;
        }
        Ok(event)
    }

    fn error_state(&mut self) -> Option<crate::bus::health::ErrorReport> {
        self.inner.error_state()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rstest::rstest;

    #[test]
    fn file_header_is_classic_pcap_socketcan() {
        assert_eq!(
            file_header(),
            [0xD4, 0xC3, 0xB2, 0xA1, 2, 0, 4, 0, 0, 0, 0, 0, 0, 0, 0, 0, 16, 0, 0, 0, 227, 0, 0, 0]
        );
    }

    #[rstest]
    #[case::dup_mac(
        1_000_423, 0x407, &[0x00, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01],
        [0x01, 0, 0, 0, 0xA7, 0x01, 0, 0, 16, 0, 0, 0, 16, 0, 0, 0,
         0, 0, 0x04, 0x07, 7, 0, 0, 0, 0x00, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01, 0]
    )]
    #[case::last_poll_fragment(
        0, 0x3C5, &[0x82, 0x0E, 0x0F, 0x10, 0x11],
        [0, 0, 0, 0, 0, 0, 0, 0, 16, 0, 0, 0, 16, 0, 0, 0,
         0, 0, 0x03, 0xC5, 5, 0, 0, 0, 0x82, 0x0E, 0x0F, 0x10, 0x11, 0, 0, 0]
    )]
    #[case::empty(
        2_500_000, 0x7FF, &[],
        [2, 0, 0, 0, 0x20, 0xA1, 0x07, 0, 16, 0, 0, 0, 16, 0, 0, 0,
         0, 0, 0x07, 0xFF, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]
    )]
    fn records(#[case] us: u64, #[case] id: u16, #[case] data: &[u8], #[case] bytes: [u8; 32]) {
        let frame = CanFrame::from_raw(id, data).unwrap();
        assert_eq!(record(Instant::from_micros(us), &frame), bytes);
    }
}
