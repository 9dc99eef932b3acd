//! # dnet-modbus-tcp
//!
//! The scanner's data over Modbus TCP, read-only, for a SCADA or an HMI: `dnet-master ui
//! --modbus-tcp ADDR`. The layout is that of the status data table of Pyramid Solutions'
//! BridgeWay DeviceNet scanner (a scan counter, active / faulted / idle / verify-error node
//! tables of 64 bits, a status code per MAC ID), followed by one block per MAC ID with the node's
//! status, sizes, input image and output image at fixed addresses. The guide's page
//! `docs/src/plant/modbus-tcp.md` is the map a plant engineer reads; [`map`] is its code.
//!
//! | module | what it holds |
//! |---|---|
//! | [`map`] | the register map: every address computed from a [`ScannerState`](dnet_scanner::model::ScannerState), pure |
//! | [`server`] | the listener, its runtime thread and its bounds (connections, idle timeout, unit IDs) |
//!
//! ## Read-only
//!
//! Modbus TCP has no user and no authentication: anything that reaches the port could send a
//! write. Outputs and breaker commands switch plant equipment and need an authenticated user (the
//! console's accounts), so the server implements no write function: FC 05, 06, 15, 16, 22 and
//! 23, like every function but 03 and 04, are answered with exception 01 (illegal function).
//!
//! ## No-panic contract
//!
//! Every request is answered with its values or an exception, or (a frame that cannot be decoded)
//! its connection is closed; none stops the server. Every resource is bounded: connections, their
//! idle time, the size of a read.

pub mod map;
pub mod server;

pub use server::{ModbusServer, ServerConfig, ServerError};
