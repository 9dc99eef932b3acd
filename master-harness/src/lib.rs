//! # master-harness
//!
//! The bench DeviceNet master `dnet-master`: it brings a device up the way a scanner does and
//! checks every frame against the protocol, replays recorded transcripts as regression tests, scans
//! a network, reads and writes attributes, monitors polled data and decodes `candump -L` logs. It
//! is a real master, not a script of canned bytes: each next frame is decided from what the device
//! answered. Protocol facts are those of the guide's protocol reference (`docs/src/protocol/`,
//! cited as protocol §N); every wire format comes from the [`devicenet`] core.
//!
//! ## Layers
//!
//! The buses, logs and captures are `can_io`'s; the simulated device (the converter with a simulated
//! breaker) is `converter_sim`'s. The master's protocol layer (the session and its transcript, the
//! explicit client, network access, allocation, requests, polling, the bring-up, the meaning of
//! frames) is [`master_core`]'s, which the EDS tool's device check uses too. This crate is the bench
//! built on it: nothing of the product depends on it.
//!
//! The plant scanner with its web console, history and MQTT (and the scan, monitor and params
//! commands it is built from) is `dnet_scanner`'s; the conformance suite is `dnet_conformance`'s;
//! the error type, the console and the frame table are `harness_common`'s. This crate is the
//! `dnet-master` command line over them, and the bench's own commands:
//!
//! | module | what it holds |
//! |---|---|
//! | [`cli`] | the command line: the subcommands and the dispatch between them |
//! | [`options`] | the options every command shares, the value parsers, the bus opened |
//! | [`commands`] | one module per command: its arguments and its run |
//! | [`run`] | how a command that talks to one device runs: session, release, reports and JSON |
//! | [`soak`] | hours of virtual time of a scanner and the soft slave under injected faults, with invariants checked |
//! | [`replay`] | the `replay` command: a transcript replayed against a device, frame by frame |
//! | [`configure`] | `configure` (a description downloaded over DeviceNet, read back, applied, checked; `--read` uploads it) |
//!
//! ## Example: the bring-up on the simulated bus
//!
//! ```
//! use can_io::bus::Bitrate;
//! use can_io::sim::{PowerOn, SimBus};
//! use converter_sim::SoftSlave;
//! use master_core::master::{ConnectOptions, Master, MasterConfig};
//! use master_core::session::Session;
//! use devicenet::{reference::BRING_UP, MacId};
//!
//! let mut bus = SimBus::new(Bitrate::K250);
//! bus.attach(Box::new(SoftSlave::reference(MacId::new(5).unwrap())), PowerOn::WhenMasterOnline);
//! let mut session = Session::new(&mut bus);
//! Master::new(&mut session, MasterConfig::default()).connect(&ConnectOptions::default()).unwrap();
//! assert_eq!(session.records().len(), BRING_UP.len());
//! assert_eq!(session.failures(), 0);
//! ```
//!
//! ## No-panic contract
//!
//! Transcripts, logs, command-line values and bus frames are untrusted: every parser returns a
//! value or an error naming the file, line and column (or the frame), never a panic.

pub mod cli;
pub mod commands;
pub mod configure;
pub mod options;
pub mod replay;
pub mod run;
pub mod soak;
