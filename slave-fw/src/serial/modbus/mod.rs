//! Modbus master profile: a DeviceNet-to-Modbus gateway, over RTU, ASCII or Modbus TCP.
//!
//! * [`pdu`]: the RTU ADU codec — [`Function`], [`ExceptionCode`], [`Request`], [`Response`],
//!   CRC-16/MODBUS framing, and [`response_len`](pdu::response_len) to delimit frames.
//! * [`master`]: the [`ModbusMaster`] that walks a [`ScanEntry`] list from a [`ModbusConfig`],
//!   filling the input image from reads and writing changed outputs.
//! * [`framing`]: the [`Framing`] of the line; [`ascii`] (LRC, `:` … CR LF) and [`mbap`] (the
//!   Modbus TCP header) wrap the address and PDU the master builds, RTU appends its CRC.
//!
//! The RTU codec and CRC are written here rather than taken from a crate (the issue allows
//! either). The no_std candidates are `modbus-core` (a codec) and `rmodbus` (mostly a server
//! framework); the codec here is small, borrows from the frame instead of copying, shares its CRC
//! with the framed profile, is tested against published vectors, and keeps the firmware's
//! dependencies to `heapless` and `devicenet`.

pub mod ascii;
mod config;
mod entry;
pub mod framing;
pub mod master;
pub mod mbap;
pub mod pdu;
pub mod schedule;
pub mod units;
mod valid_bits;

pub use framing::{FrameError, Framing, WIRE_CAPACITY};
pub use master::{ByteOrder, ModbusConfig, ModbusMaster, ScanEntry, WordOrder, SCAN_LIST_CAPACITY};
pub use pdu::{CodecError, ExceptionCode, Function, Request, Response, ADU_CAPACITY};
pub use schedule::WriteMode;
pub use units::{UnitHealth, UnitRow, UnitState, UNIT_CAPACITY};
