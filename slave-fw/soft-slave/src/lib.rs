//! # soft-slave
//!
//! The serial-to-DeviceNet converter as a Linux process: `dnet-soft-slave` runs the same
//! [`Converter`](slave_fw::converter::Converter) as the adapter board's firmware, between a real
//! CAN bus (SocketCAN or an SLCAN adapter, through `can_io`'s [`Bus`] implementations)
//! and a real serial port (the `serialport` crate) where the instrument is. `dnet-sim-breaker`
//! is its bench companion: the simulated intelligent circuit breaker
//! ([`SimulatedBreaker`](converter_sim::SimulatedBreaker)) on a serial port or pseudo-terminal.
//!
//! The converter is sans-IO (style.md practice 1); this crate is the one small adapter for time
//! and one for frames that a host needs around it:
//!
//! | module | what it holds |
//! |---|---|
//! | [`clock`] | [`Clock`](clock::Clock): the process's monotonic clock as a [`devicenet::Instant`] (microseconds since start) |
//! | [`serial`] | [`SerialLine`](serial::SerialLine): the instrument's port, opened with the profile's settings, read and written by two threads so the CAN side never waits on it |
//! | [`bridge`] | [`Bridge`](bridge::Bridge): the main loop — bus, serial line and converter, the drain order of the converter docs, Identity Reset, the `candump -L` log |
//! | [`breaker`] | [`BreakerRunner`](breaker::BreakerRunner): the simulated breaker on any byte stream, with fault knobs and an event log |
//! | [`firmware`] | `--firmware-dir DIR`: the firmware update object (class 0x6A) over files standing in for the DFU flash and the bootloader |
//! | [`state`] | `--state FILE`: the settings and configuration image kept across restarts, replaced atomically |
//! | [`tcp`] | [`TcpLine`](tcp::TcpLine): the instrument behind a serial device server (`--serial tcp:HOST:PORT`), reconnected with back-off |
//! | [`cli`] | the two command lines (clap) and their `run` functions |
//! | [`error`] | [`SoftSlaveError`](error::SoftSlaveError): every failure named, with its exit status |
//!
//! ## What it must not depend on
//!
//! The converter (`slave-fw`), `can-io` (its buses and logs) and `converter-sim` (the simulated
//! breaker of `dnet-sim-breaker`): never the master harness, which its tests use as a
//! dev-dependency only. The Identity Reset's delay is the converter's
//! ([`Converter::poll_reset`](slave_fw::converter::Converter::poll_reset)), the same as on the board.
//!
//! ## The main loop
//!
//! One thread owns the bus and the converter. Each turn it feeds the converter the serial bytes
//! the reader thread delivered (with the time they arrived), runs due timers, drains the
//! converter (CAN frames to the bus, serial bytes to the writer thread, events), then waits on
//! the bus for at most [`bridge::POLL_SLICE`] or until the converter's next deadline. A poll is
//! answered from the buffered input image as soon as its frame is read; the serial line is
//! never waited on inside a poll.
//!
//! ## Example: the converter between two in-memory ends
//!
//! ```
//! use soft_slave::bridge::Bridge;
//! use soft_slave::clock::Clock;
//! use soft_slave::serial::SerialLine;
//! use slave_fw::converter::ConverterConfig;
//! use std::os::unix::net::UnixStream;
//! use std::sync::atomic::AtomicBool;
//! # use can_io::bus::{Bus, BusError, BusEvent};
//! # use devicenet::{CanFrame, Instant};
//! # struct Quiet(Clock);
//! # impl Bus for Quiet {
//! #     fn name(&self) -> &str { "quiet" }
//! #     fn now(&mut self) -> Instant { self.0.now() }
//! #     fn send(&mut self, _: &CanFrame) -> Result<(), BusError> { Ok(()) }
//! #     fn recv(&mut self, deadline: Instant) -> Result<Option<BusEvent>, BusError> {
//! #         std::thread::sleep(std::time::Duration::from_micros((deadline - self.0.now().min(deadline)).total_micros()));
//! #         Ok(None)
//! #     }
//! # }
//!
//! let clock = Clock::start();
//! let (ours, _instrument) = UnixStream::pair().unwrap();
//! let serial = SerialLine::from_stream(ours, "pair", clock).unwrap();
//! let mut bridge =
//!     Bridge::new(ConverterConfig::breaker_reference(), Box::new(Quiet(clock)), serial, clock).unwrap();
//! let summary = bridge.run(&AtomicBool::new(false), Some(devicenet::Duration::from_millis(50))).unwrap();
//! assert_eq!(summary.can_received, 0);
//! ```
//!
//! ## No-panic contract
//!
//! Command-line values, description files, bus frames and serial bytes are untrusted: each is
//! answered with a value or an error that names it ([`error::SoftSlaveError`]), never a panic.
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

/// The package version and the git commit `dnet-soft-slave` and `dnet-sim-breaker` were built from.
pub const VERSION: &str = git_version::git_version!(
    prefix = "0.1.0 (",
    suffix = ")",
    args = ["--always", "--dirty=-modified", "--abbrev=12"],
    fallback = "0.1.0 (unknown commit)"
);

pub mod breaker;
pub mod bridge;
pub mod cli;
pub mod clock;
pub mod error;
pub mod firmware;
pub mod serial;
pub mod state;
pub mod tcp;

pub use can_io::bus::Bus;

#[cfg(test)]
mod version_tests {
    #[test]
    fn the_version_is_the_package_version_and_a_commit() {
        assert!(super::VERSION.starts_with(concat!(env!("CARGO_PKG_VERSION"), " (")), "{}", super::VERSION);
    }
}
