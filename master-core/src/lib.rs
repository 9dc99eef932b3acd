//! # master-core
//!
//! The protocol layer of the bench DeviceNet master: what a program needs to talk to a device the
//! way a scanner does, and to check every frame it answers. The `dnet-master` tool
//! (`master-harness`) and the EDS tool's live device check (`eds-tool`, `dnet-eds check-device`) are both built
//! on it. Protocol facts are those of the guide's protocol reference (`docs/src/protocol/`, cited
//! as protocol §N); every wire format comes from the [`devicenet`] core, every bus from `can_io`.
//!
//! ## What it owns
//!
//! | module | what it holds |
//! |---|---|
//! | [`session`] | a bus with its transcript: every frame with time, direction, meaning and [`Verdict`](session::Verdict), and the log file |
//! | [`bring_up`] | the per-node bring-up engine ([`BringUp`](bring_up::BringUp)), sans-IO: Allocate with the requested connections, the reads, the expected packet rate that starts I/O, Release; what `connect`, `get`/`set`, `scan`, the scanner, the soak and `check-device` drive |
//! | [`client`] | one explicit transaction as a sans-IO state machine ([`Transaction`](client::Transaction)): fragmentation both ways, every response frame checked; [`drive`](client::drive) and [`run`](client::run), the one way to drive it |
//! | [`master`] | network access, waiting for the device, UCMM probe, allocation and release, get/set, polling, the bring-up of protocol §2 |
//! | [`io`] | the I/O connections next to poll: bit-strobe, change of state and cyclic with their acknowledgements, every frame and interval checked |
//! | [`recovery`] | a Communication Faulted node found and given a new MAC ID through the Offline Connection Set (Who, Identify, ownership, Change MAC ID) |
//! | [`decode`] | DeviceNet meaning of frames, with reassembly |
//! | [`error`] | [`MasterError`](error::MasterError): why an operation stopped |
//! | [`stop`] | [`Stop`](stop::Stop): a stop asked for by a signal, seen by the session while it waits |
//! | [`update`] | the firmware update through the update object (class 0x6A): the signed file checked against the device, Update, Transfer, Verify, Apply, the device's return and its verdict |
//!
//! ## What it must not depend on
//!
//! Not `master-harness` (the conformance suite, soak, replay, scan, monitor and command line are
//! built on this crate, not the other way round), not `eds` or `eds-tool`, and not the simulated device
//! (`converter-sim`, only in its tests): a product crate that checks a device over the bus pulls in
//! this crate and nothing of the bench.
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
//! Bus frames are untrusted: every frame is decoded and judged, never a panic.

pub mod bring_up;
pub mod client;
pub mod decode;
pub mod error;
pub mod master;
pub mod session;
pub mod stop;
pub mod update;

pub use master::{io, recovery};
