//! # master-harness
//!
//! The bench DeviceNet master `dnet-master`.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod bus;
pub mod cli;
pub mod client;
pub mod decode;
pub mod error;
pub mod log;
pub mod master;
pub mod monitor;
pub mod replay;
pub mod scan;
pub mod session;
pub mod soft_slave;
