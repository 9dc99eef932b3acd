//! # master-harness
//!
//! The bench DeviceNet master `dnet-master`: it brings a device up the way a scanner does and
//! checks every frame against the protocol, replays recorded transcripts as regression tests, scans
//! a network, reads and writes attributes, monitors polled data and decodes `candump -L` logs. It
//! is a real master, not a script of canned bytes: each next frame is decided from what the device
//! answered. Protocol facts are those of `../shared/devicenet-notes.md`; every wire format comes
//! from the [`devicenet`] core.
//!
//! ## Layers
//!
//! The buses, logs and captures are `can_io`'s; the simulated device (the converter with a simulated
//! breaker) is `converter_sim`'s. The master's protocol layer (the session and its transcript, the
//! explicit client, network access, allocation, requests, polling, the bring-up, the meaning of
//! frames) is [`master_core`]'s, which the EDS tool's device check uses too. This crate is the bench
//! built on it: nothing of the product depends on it.
//!
//! | module | what it holds |
//! |---|---|
//! | [`conformance`] | the conformance suite (`conformance`): checks by category, each citing the notes, graded pass / fail / advisory; terminal, JSON and HTML (sequence diagrams) reports; the self-test against mutant devices (`conformance --self-test`) |
//! | [`soak`] | hours of virtual time of a scanner and the soft slave under injected faults, with invariants checked |
//! | [`replay`], [`scan`], [`monitor`] | the `replay`, `scan` and `monitor` commands |
//! | [`configure`], [`params`] | `configure` (a description downloaded over DeviceNet, read back, applied, checked; `--read` uploads it) and `params` (the Parameter object or an EDS's parameters, read and written) |
//! | [`cli`] | the command line, reports and JSON |
//! | [`console`] | progress lines on a terminal, the stop asked for by SIGINT / SIGTERM |
//! | [`table`] | the frame-by-frame table and the JSON form of a record |
//! | [`history`] | the sample history in SQLite (schema, CSV export, retention) |
//! | [`mqtt`] | `--mqtt URL`: node status and decoded values published to an MQTT broker |
//! | [`ui`] | the web console (`ui`): the page and its JSON API over the scanner's shared state |
//! | [`error`] | [`HarnessError`](error::HarnessError): every failure of a command named |
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
#![forbid(unsafe_code)]
#![warn(missing_docs)]

/// The git commit this program was built from (`-modified` when the tree had changes), or
/// `unknown commit` outside a git checkout.
pub const GIT_COMMIT: &str = git_version::git_version!(
    args = ["--always", "--dirty=-modified", "--abbrev=12"],
    fallback = "unknown commit"
);

/// The version of `dnet-master` and of its reports: the package version and the git commit,
/// `0.1.0 (1a2b3c4d5e6f)`.
pub fn version() -> &'static str {
    static VERSION: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    VERSION.get_or_init(|| format!("{} ({GIT_COMMIT})", env!("CARGO_PKG_VERSION")))
}

pub mod cli;
pub mod configure;
pub mod conformance;
pub mod console;
pub mod error;
pub mod history;
pub mod monitor;
pub mod mqtt;
pub mod params;
pub mod replay;
pub mod scan;
pub mod scanner;
pub mod soak;
pub mod table;
pub mod ui;
