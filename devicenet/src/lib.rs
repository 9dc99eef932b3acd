//! # devicenet
//!
//! A sans-IO DeviceNet protocol core: `no_std`, no allocation, no `unsafe`. It is shared by the
//! adapter board's firmware, the soft slave on Linux, the master harness and the tests.
//!
//! Frames and `now` go in; frames, events and the next deadline come out. The core never reads a
//! clock and never touches a peripheral (see `../shared/devicenet-notes.md` for the protocol facts
//! every module cites).
//!
//! ## Layers
//!
//! | module | what it holds |
//! |---|---|
//! | [`time`] | the core's own microsecond [`Instant`](time::Instant) and [`Duration`](time::Duration) |
//! | [`frame`] | [`CanFrame`](frame::CanFrame): 11-bit identifier + 0..=8 bytes, to and from `embedded_can::Frame` |
//! | [`id`] | the identifier codec: [`MacId`](id::MacId), message groups 1–4 and their message IDs |
//! | [`explicit`] | explicit message header, service codes, body formats, requests, (error) responses |
//! | [`fragment`] | explicit (acknowledged) and I/O (unacknowledged) fragmentation: senders and reassemblers |
//! | [`objects`] | object class IDs and the names of classes, attributes, connection states and watchdog actions |
//! | [`messages`] | fixed-layout bodies: duplicate MAC check, allocate/release, UCMM open/close, heartbeat/shutdown, Offline Connection Set |
//! | [`slave`] | the group-2-only [`SlaveNode`](slave::SlaveNode): network access, Predefined Master/Slave Connection Set, objects, connections |
//! | [`led`] | Module/Network Status LED indications, flashing and the power-up test |
//! | [`reference`] | the reference 28-frame bring-up of notes §2, the golden transcript every test compares with |
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
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![cfg_attr(not(test), deny(clippy::indexing_slicing))]

#[cfg(test)]
extern crate std;

pub mod explicit;
pub mod fragment;
pub mod frame;
pub mod id;
pub mod led;
pub mod messages;
pub mod objects;
pub mod reference;
pub mod slave;
pub mod time;

pub use frame::{CanFrame, CanId, FrameError};
pub use id::{Group2Message, Identifier, MacId};
pub use slave::{DeviceConfig, Event, SlaveNode};
pub use time::{Duration, Instant};
