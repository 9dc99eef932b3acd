//! # converter-sim
//!
//! The converter as simulated test equipment, on the host: everything the bench master, the EDS
//! tool's device check and the system tests need to run the real converter without a board.
//!
//! | module | what it holds |
//! |---|---|
//! | [`breaker`] | [`SimulatedBreaker`]: the intelligent circuit breaker of the source paper, sans-IO (the serial instrument `dnet-sim-breaker` serves on a real port) |
//! | [`device`] | [`SoftSlave`]: the one converter-as-a-device type — the real [`Converter`](slave_fw::converter::Converter) and a simulated breaker on a virtual clock, a [`SimDevice`](can_io::sim::SimDevice) of the simulated bus |
//! | [`mutants`] | [`MUTANTS`](mutants::MUTANTS): the reference converter with one deliberate fault each, as a [`FaultHook`](mutants::FaultHook) around the real node (`conformance --self-test`, `dnet-soft-slave --mutant`) |
//! | [`replace`] | `--sim-replace`: a device that goes silent, and its factory-fresh replacement at MAC 63 |
//! | [`open`] | [`open_bus`]: `--bus sim` with its simulated devices ([`SimSetup`]), or a real bus |
//!
//! ## What it must not depend on
//!
//! The converter (`slave-fw`), the core and `can-io` (feature `sim`) only: never the master
//! harness. The converter library itself stays `no_std` and knows nothing of this crate.
//!
//! ## Example: the reference converter answers the master on the simulated bus
//!
//! ```
//! use can_io::bus::{Bitrate, Bus};
//! use can_io::sim::{PowerOn, SimBus};
//! use converter_sim::SoftSlave;
//! use devicenet::{Instant, MacId};
//!
//! let mut bus = SimBus::new(Bitrate::K250);
//! bus.attach(Box::new(SoftSlave::reference(MacId::new(5).unwrap())), PowerOn::AtStart);
//! // The device's first duplicate MAC ID check request comes at once.
//! let first = bus.recv(Instant::from_millis(10)).unwrap().unwrap();
//! assert_eq!(first.frame.id().as_raw(), 0x42F);
//! ```
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

pub mod breaker;
pub mod device;
pub mod mutants;
pub mod open;
pub mod replace;

pub use breaker::SimulatedBreaker;
pub use device::SoftSlave;
pub use open::{open_bus, OpenError, SimSetup};
