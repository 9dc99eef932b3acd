//! # devicenet
//!
//! A sans-IO DeviceNet protocol core: `no_std`, no allocation, no `unsafe`. It is shared by the
//! adapter board's firmware, the soft slave on Linux, the master harness and the tests.
//!
//! Frames and `now` go in; frames, events and the next deadline come out. The core never reads a
//! clock and never touches a peripheral. The protocol facts every module cites are those of the
//! guide's protocol reference (`docs/src/protocol/`), cited as protocol §N.
//!
//! ## Layers
//!
//! | module | what it holds |
//! |---|---|
//! | [`time`] | the core's own microsecond [`Instant`] and [`Duration`] |
//! | [`frame`] | [`CanFrame`]: 11-bit identifier + 0..=8 bytes, to and from `embedded_can::Frame` |
//! | [`id`] | the identifier codec: [`MacId`], message groups 1–4 and their message IDs |
//! | [`explicit`] | explicit message header, service codes, body formats, requests, (error) responses |
//! | [`fragment`] | explicit (acknowledged) and I/O (unacknowledged) fragmentation: senders and reassemblers |
//! | [`objects`] | the object class IDs ([`objects::class`], their one definition) and the names of classes, attributes, connection states and watchdog actions |
//! | [`messages`] | fixed-layout bodies, one file per family (below) |
//! | [`slave`] | the group-2-only [`SlaveNode`], one file per concern (below) |
//! | [`led`] | Module/Network Status LED indications, flashing and the power-up test |
//! | [`reference`](mod@reference) | the reference 28-frame bring-up of protocol §2, the golden transcript every test compares with |
//! | [`crc32`](mod@crc32) | CRC-32 (IEEE 802.3), not DeviceNet's: the one the board's settings records and the converter's configuration image share |
//!
//! [`messages`] holds one file per message family, every type re-exported as
//! `devicenet::messages::Name`:
//!
//! | file | messages |
//! |---|---|
//! | `messages/duplicate_mac.rs` | the duplicate MAC ID check (protocol §3.5) |
//! | `messages/allocation.rs` | allocation choice, Allocate/Release service data, allocation information (protocol §3.4) |
//! | `messages/ucmm.rs` | UCMM open/close requests and responses (protocol §3.6) |
//! | `messages/heartbeat.rs` | device heartbeat and shutdown (protocol §3.7) |
//! | `messages/offline.rs` | the Group 4 Offline Connection Set (protocol §3.8) |
//!
//! [`slave`] keeps [`SlaveNode`], its inputs and outputs in `slave/mod.rs`, and the rest as
//! `impl SlaveNode` blocks, one file per concern:
//!
//! | file | what it holds |
//! |---|---|
//! | `slave/network.rs` | network access: duplicate MAC ID check, Communication Faulted (protocol §7.1, §7.2) |
//! | `slave/allocation.rs` | Allocate/Release of the Predefined Master/Slave Connection Set, the Group 2 Only port (protocol §3.4) |
//! | `slave/explicit_messaging.rs` | the explicit connection: owner check, fragmentation, serving a request (protocol §3.1, §4.1) |
//! | `slave/polled_io.rs` | poll commands and responses (protocol §4.2) |
//! | `slave/objects/{router,identity,devicenet,assembly,connection}.rs` | the Message Router and the Identity, DeviceNet, Assembly and Connection objects, one class each (protocol §5, §6) |
//! | `slave/indications.rs` | the Module and Network Status LEDs (protocol §7.3) |
//! | [`slave::config`], [`slave::connection`], [`slave::reply`] | the device configuration, one Connection instance's state machine, response data and [`ServiceError`](slave::ServiceError) |
//!
//! ## Driving the slave
//!
//! ```
//! use devicenet::{CanFrame, DeviceConfig, Duration, Instant, SlaveNode};
//!
//! let mut node = SlaveNode::new(DeviceConfig::reference()).unwrap();
//! let mut now = Instant::ZERO;
//! node.power_on(now);
//! // The first duplicate MAC ID check request is queued at once.
//! let frame = node.poll_transmit().unwrap();
//! assert_eq!(frame.to_string(), "42F#00341278563412");
//! // Two seconds without an answer: on-line.
//! while let Some(at) = node.poll_at() {
//!     now = at;
//!     node.handle_timeout(now);
//!     while node.poll_transmit().is_some() {}
//!     if node.network_state() == devicenet::slave::NetworkState::Online { break; }
//! }
//! assert_eq!(now, Instant::ZERO + Duration::from_secs(2));
//! ```
//!
//! ## No-panic contract
//!
//! Every parser in this crate accepts any input and returns a value or an error; no bus input can
//! make the core panic, allocate, or grow without bound. Indexing and slicing that could panic are
//! denied by lint outside tests (`clippy::indexing_slicing`): access is checked (`get`,
//! `split_first`, slice patterns) or the bound is in the type (fixed-size arrays).
#![no_std]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

#[cfg(test)]
extern crate std;

pub mod crc32;
pub mod explicit;
pub mod fragment;
pub mod frame;
pub mod id;
pub mod led;
pub mod messages;
pub mod objects;
pub mod reference;
pub mod slave;
pub mod text;
pub mod time;

pub use frame::{CanFrame, CanId, FrameError};
pub use id::{Group2Message, Identifier, MacId};
pub use slave::{DeviceConfig, Event, SlaveNode};
pub use time::{Duration, Instant};
