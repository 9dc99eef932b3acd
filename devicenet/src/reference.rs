//! The reference 28-frame connection sequence of protocol §2, with the
//! project's reference device ([`DeviceConfig::reference`](crate::slave::DeviceConfig::reference)):
//! master MAC 0 (vendor 0x0001, serial 0x01020304), slave MAC 5 (vendor 0x1234, device type 0x000C,
//! product code 1, serial 0x12345678), EPR 100 ms, a poll command of 8 zero bytes and an 18-byte
//! input image of zeros but byte 9 = 0x0F (the breaker's "open" state).
//!
//! The firmware, soft slave and master harness tests all compare their transcripts with this one
//! table, byte for byte.

/// Who sends a frame of the sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// The master (scanner).
    MasterToSlave,
    /// The device.
    SlaveToMaster,
}

/// One frame of the reference sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReferenceFrame {
    /// Sender.
    pub direction: Direction,
    /// 11-bit identifier.
    pub id: u16,
    /// Data bytes.
    pub data: &'static [u8],
    /// What the frame means (protocol §2 "Meaning").
    pub meaning: &'static str,
}

const fn m(id: u16, data: &'static [u8], meaning: &'static str) -> ReferenceFrame {
    ReferenceFrame { direction: Direction::MasterToSlave, id, data, meaning }
}

const fn s(id: u16, data: &'static [u8], meaning: &'static str) -> ReferenceFrame {
    ReferenceFrame { direction: Direction::SlaveToMaster, id, data, meaning }
}

/// The 18-byte input image of the reference device.
pub const INPUT_IMAGE: [u8; 18] = [0, 0, 0, 0, 0, 0, 0, 0, 0, 0x0F, 0, 0, 0, 0, 0, 0, 0, 0];

/// The reference poll command.
pub const POLL_COMMAND: [u8; 8] = [0; 8];

/// The 28 frames of protocol §2 for the reference device, in order.
pub const BRING_UP: [ReferenceFrame; 28] = [
    m(0x407, &[0x00, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01], "master duplicate MAC ID check request #1"),
    m(0x407, &[0x00, 0x01, 0x00, 0x04, 0x03, 0x02, 0x01], "master duplicate MAC ID check request #2"),
    s(0x42F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], "slave duplicate MAC ID check request #1"),
    s(0x42F, &[0x00, 0x34, 0x12, 0x78, 0x56, 0x34, 0x12], "slave duplicate MAC ID check request #2"),
    m(0x780, &[0x05, 0x4B, 0x00, 0x34], "UCMM open explicit connection (no answer: group-2-only)"),
    m(0x780, &[0x05, 0x4B, 0x00, 0x34], "UCMM open retry (no answer)"),
    m(0x42E, &[0x00, 0x4B, 0x03, 0x01, 0x01, 0x00], "Allocate explicit via the Group 2 Only port"),
    s(0x42B, &[0x00, 0xCB, 0x00], "Allocate success, body format 8/8"),
    m(0x42C, &[0x00, 0x10, 0x05, 0x01, 0x0C, 0x03], "Set explicit watchdog action = deferred delete"),
    s(0x42B, &[0x00, 0x90], "Set success"),
    m(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x01], "Get Identity vendor ID"),
    s(0x42B, &[0x00, 0x8E, 0x34, 0x12], "vendor ID 0x1234"),
    m(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x02], "Get Identity device type"),
    s(0x42B, &[0x00, 0x8E, 0x0C, 0x00], "device type 0x000C"),
    m(0x42C, &[0x00, 0x0E, 0x01, 0x01, 0x03], "Get Identity product code"),
    s(0x42B, &[0x00, 0x8E, 0x01, 0x00], "product code 1"),
    m(0x42C, &[0x00, 0x4B, 0x03, 0x01, 0x02, 0x00], "Allocate poll via the explicit connection"),
    s(0x42B, &[0x00, 0xCB, 0x00], "Allocate success, poll configuring"),
    m(0x42C, &[0x00, 0x0E, 0x05, 0x02, 0x07], "Get poll produced connection size"),
    s(0x42B, &[0x00, 0x8E, 0x12, 0x00], "18 bytes"),
    m(0x42C, &[0x00, 0x0E, 0x05, 0x02, 0x08], "Get poll consumed connection size"),
    s(0x42B, &[0x00, 0x8E, 0x08, 0x00], "8 bytes"),
    m(0x42C, &[0x00, 0x10, 0x05, 0x02, 0x09, 0x64, 0x00], "Set poll expected packet rate = 100 ms"),
    s(0x42B, &[0x00, 0x90, 0x64, 0x00], "EPR 100 ms applied, poll established"),
    m(0x42D, &POLL_COMMAND, "poll command, 8 output bytes"),
    s(0x3C5, &[0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00], "poll response, first fragment"),
    s(0x3C5, &[0x41, 0x00, 0x00, 0x0F, 0x00, 0x00, 0x00, 0x00], "poll response, middle fragment"),
    s(0x3C5, &[0x82, 0x00, 0x00, 0x00, 0x00], "poll response, last fragment"),
];
