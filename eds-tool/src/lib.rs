//! # eds-tool
//!
//! The `dnet-eds` program (`src/main.rs`, a thin shell) and what it needs beyond the EDS file
//! format: [`device`], a device on the bus checked against its EDS (`dnet-eds check-device`).
//! The file format itself (lexer, parser, model, checker, writer, generator) is the `eds` crate,
//! which depends on no bus crate; the bus, the master and the simulated device come in here.
//!
//! | module | what it holds |
//! |---|---|
//! | [`device`] | [`Eds`](eds::Eds) + a device on a bus → [`DeviceReport`] of disagreements, through `master_core`'s per-node bring-up engine (never the harness) |
//!
//! ## No-panic contract
//!
//! The device check treats every answer from the bus as untrusted (wrong lengths, error
//! responses and malformed strings become findings, a silent device an error).

pub mod device;

pub use device::{check_device, check_on_bus, DeviceReport, Finding};
