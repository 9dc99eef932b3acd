//! # dnet-scanner
//!
//! The plant side of the bench DeviceNet master: what `dnet-master scan`, `monitor`, `params`,
//! `scanner` and `ui` run. The command line that parses their options and opens the bus is
//! `master_harness`'s; the protocol (the session, the explicit client, the bring-up) is
//! `master_core`'s; errors, the console and the frame table are `harness_common`'s.
//!
//! | module | what it holds |
//! |---|---|
//! | [`scan`] | the network scan: every device's identity and I/O sizes, all MACs at once |
//! | [`monitor`] | one device polled at its expected packet rate, its data decoded by its profile ([`monitor::InputLayout`]) |
//! | [`params`] | the Parameter object (or an EDS's parameters) of one device, read and written |
//! | [`engine`] | the scanner: every node of a scan list kept in I/O ([`Scanner`]) |
//! | [`timing`] | the timing of a scan list: minimum cycle, inter-scan delay, EPR, response window |
//! | [`list`], [`model`] | the scan list file; what the scanner knows and shows (node status codes) |
//! | [`report`] | how a scanner run ends: nodes released, the node table, the `--json` summary |
//! | [`ui`] | the web console: the page and its JSON API over the scanner's shared state, with its own bounded HTTP server |
//! | [`accounts`], [`audit`] | who may command the plant (users file, roles), and the log of every command |
//! | [`adr`], [`events`] | automatic device replacement: what is kept of each node, how a replacement is recognised; the event log of its steps and of scan-list changes |
//! | [`plant`] | the plant file of `ui --plant`: several networks, each with its bus and scan list |
//! | [`history`] | the sample history in SQLite (schema, CSV export, retention) |
//! | [`mqtt`] | node status and decoded values published to an MQTT broker |
//! | [`sparkplug`] | the scanner as a Sparkplug B edge node: births, data by exception, store and forward, DCMD |
//!
//! ## No-panic contract
//!
//! Scan list files, HTTP requests, command values and bus frames are untrusted: every parser
//! returns a value or an error naming the file, line and key (or the request, or the frame), never
//! a panic; every queue and buffer is bounded.

pub mod accounts;
pub mod adr;
pub mod audit;
pub mod breaker;
pub mod engine;
pub mod events;
pub mod health;
pub mod history;
pub mod keying;
pub mod list;
pub mod model;
pub mod monitor;
pub mod mqtt;
pub mod params;
pub mod plant;
pub mod project;
pub mod report;
pub mod scan;
pub mod serial_trace;
pub mod sparkplug;
pub mod timing;
pub mod ui;

pub use engine::{build_scan_list, sample_values, Scanner, ScannerOptions};
pub use list::{parse_scan_list, parse_scan_list_for, read_scan_list, write_scan_list};
