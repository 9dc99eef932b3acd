//! The commands of `dnet-master`, one module each: its arguments (`…Args`, parsed by clap) and
//! the function that runs it. [`crate::cli`] only dispatches; the work is in the libraries
//! (`master_core`, `dnet_scanner`, `dnet_conformance`, [`crate::replay`], [`crate::configure`]).

pub mod completions;
pub mod configure;
pub mod conformance;
pub mod connect;
pub mod decode;
pub mod explicit;
pub mod firmware_update;
pub mod man;
pub mod monitor;
pub mod params;
pub mod project;
pub mod recover;
pub mod replay;
pub mod scan;
pub mod scanner;
pub mod serial_trace;
pub mod sign_firmware;
pub mod ui;
pub mod ui_access;
pub mod ui_modbus;
pub mod ui_opcua;
pub mod ui_plant;
pub mod ui_sparkplug;
pub mod units;
pub mod user;
