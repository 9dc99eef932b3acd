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
//! | [`messages`] | fixed-layout bodies: duplicate MAC check, allocate/release, UCMM open/close, heartbeat/shutdown, Offline Connection Set |
//!
//! ## No-panic contract
//!
//! Every parser in this crate accepts any input and returns a value or an error; no bus input can
//! make the core panic, allocate, or grow without bound.
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod explicit;
pub mod fragment;
pub mod frame;
pub mod id;
pub mod messages;
pub mod time;

pub use frame::{CanFrame, CanId, FrameError};
pub use id::{Group2Message, Identifier, MacId};
pub use time::{Duration, Instant};
