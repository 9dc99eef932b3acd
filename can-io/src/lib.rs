//! # can-io
//!
//! Every way this project's programs reach a CAN bus, in one crate, so that the products (the
//! firmware, the soft slave, the EDS tool) and the bench master share one implementation of each
//! and none of them depends on the test harness.
//!
//! | module | feature | what it holds |
//! |---|---|---|
//! | [`slcan`] | (always, `no_std`) | the SLCAN (Lawicel) line codec and adapter state machine: the emulated firmware's CAN "transceiver", and the host side's encoder and parser |
//! | `bus` | `std` | the [`Bus`](bus::Bus) trait every host program runs on, [`BusSpec`](bus::BusSpec) (`--bus sim`, `socketcan:IFACE`, `slcan:PATH[@BAUD]`) and [`BusSpec::open`](bus::BusSpec::open); the SocketCAN (Linux) and SLCAN-adapter buses |
//! | `log` | `std` | `candump -L` log lines: writer, and reader with precise errors |
//! | `pcap` | `std` | a SocketCAN pcap capture (link type 227) written by a wrapper around any bus |
//! | `trace` | `std` | trace files of every format (candump, pcap, pcapng, PCAN `.trc`, Vector `.asc` and `.blf`, CSV): format detection, readers that skip and count what is not DeviceNet traffic, writers of the text formats |
//! | `sim` | `sim` | the simulated CAN bus: virtual clock, arbitration, each frame's exact time on the wire, simulated devices ([`SimDevice`](sim::SimDevice)), fault injection ([`sim::fault`]) |
//!
//! ## What it must not depend on
//!
//! The protocol core (`devicenet`) only: no converter, no harness, no EDS. The simulated bus knows
//! devices only through the [`SimDevice`](sim::SimDevice) trait; what runs on it (the converter
//! with a simulated breaker) is `converter-sim`'s.
//!
//! ## Features
//!
//! | feature | default | what it adds |
//! |---|---|---|
//! | `std` | yes | the host side; the firmware builds with `default-features = false` and gets the codec only |
//! | `sim` | no | the simulated bus |
//! | `defmt` | no | `defmt::Format` on the codec's types |
//!
//! ## No-panic contract
//!
//! Adapter bytes, log lines and bus frames are untrusted: every parser returns a value or an error
//! naming the line and column (or the frame), never a panic, and nothing grows without bound.
#![cfg_attr(not(feature = "std"), no_std)]

pub mod slcan;

#[cfg(feature = "std")]
pub mod bus;
#[cfg(feature = "std")]
pub mod log;
#[cfg(feature = "std")]
pub mod pcap;
#[cfg(feature = "sim")]
pub mod sim;
#[cfg(feature = "std")]
pub mod trace;
