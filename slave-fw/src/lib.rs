//! # slave-fw
//!
//! The serial side of the serial-to-DeviceNet converter: the code that talks to the legacy
//! instrument. It is `no_std`, allocation-free and `unsafe`-free, so the RTIC firmware on the
//! adapter board and the soft slave on Linux run exactly the same bridge logic.
//!
//! Like the [`devicenet`] core it is sans-IO: bytes and `now` go in, bytes to write to the UART,
//! an input image, a status and the next deadline come out. Nothing here reads a clock or touches a
//! peripheral; time is [`devicenet::Instant`] / [`devicenet::Duration`] (microseconds).
//!
//! ## Layers
//!
//! | module | what it holds |
//! |---|---|
//! | [`serial::line`] | [`SerialSettings`](serial::SerialSettings): baud, parity, stop bits, character and 3.5-character times |
//! | [`serial::checksum`] | 8-bit sum, 8-bit XOR and CRC-16/MODBUS |
//! | [`serial::framed`] | the generic framed-serial wire format: [`FramedConfig`](serial::FramedConfig), the resynchronising [`FrameParser`](serial::FrameParser), the encoder |
//! | [`serial::breaker`] | the intelligent circuit breaker of the source paper: status frames, commands, acknowledgements, and its preset configuration |
//! | [`serial::sequencer`] | the [`CommandSequencer`](serial::CommandSequencer): poll output bytes → commands sent exactly once, retried, outcome reported; idle/fault actions |
//! | [`serial::health`] | [`LinkHealth`](serial::LinkHealth): stale timeout and policy, the status byte, the freshness counter, [`Stats`](serial::Stats) |
//! | [`serial::framed_profile`] | [`FramedProfile`](serial::FramedProfile): framing + sequencer + health for the breaker and similar instruments |
//! | [`serial::modbus`] | Modbus RTU: the ADU codec ([`Request`](serial::modbus::Request), [`Response`](serial::modbus::Response)) and the scan-list [`ModbusMaster`](serial::modbus::ModbusMaster) |
//! | [`serial::profile`] | [`Profile`](serial::Profile): one concrete type the converter drives for any instrument |
//! | [`converter`] | the [`Converter`](converter::Converter): slave node + profile, input assemblies 100/101, the Identity Reset's delay ([`RESET_DELAY`](converter::RESET_DELAY), [`poll_reset`](converter::Converter::poll_reset)) |
//! | [`converter::objects`] | the vendor objects 0x64 (serial link) and 0x65 (settings): one attribute table each, served by the converter and written into the EDS by `eds::generate` |
//! | [`update`] | the firmware update object, class 0x6A: an image received in chunks into the DFU flash, checked against its signature, handed to the bootloader |
//! | [`image`] | the binary configuration image: a whole `ConverterConfig` with header and CRC-32, as stored and downloaded |
//! | `description` (feature `description`) | the TOML device description file: parse, validate, build a `ConverterConfig` |
//! | `description_write` (feature `description`) | the TOML form of a description, read back to the same configuration |
//!
//! The [`Converter`](converter::Converter) owns a [`Profile`](serial::Profile) next to the DeviceNet
//! slave node: consumed poll data goes to [`Profile::set_outputs`](serial::Profile::set_outputs),
//! the produced data is [`Profile::input_image`](serial::Profile::input_image) plus, in the
//! extended assembly, [`LinkStatus::to_bytes`](serial::LinkStatus::to_bytes).
//!
//! ## What it must not depend on
//!
//! The core (`devicenet`), `heapless`, and for the update object `embedded-storage` (the flash
//! trait) and `fw-image` (the signed image) only (and `serde`/`toml` behind the host-only
//! `description` feature): no CAN I/O, no simulated equipment (that is `converter-sim`), no
//! harness. The firmware and the soft slave run it as it is.
//!
//! ## Features
//!
//! | feature | default | what it adds |
//! |---|---|---|
//! | `std` | yes | `std::error::Error` on the error types; build the firmware with `--no-default-features` |
//! | `serde` | no | `Serialize`/`Deserialize` on every configuration type, for the device description file |
//!
//! ## No-panic contract
//!
//! Every parser and state machine in [`serial`] accepts any byte sequence and any `now`; no serial
//! input can make it panic, allocate or grow without bound. Indexing that could panic is denied by
//! lint outside tests, and property tests feed the parsers arbitrary bytes.
#![cfg_attr(not(feature = "std"), no_std)]
#![cfg_attr(
    not(test),
    deny(clippy::indexing_slicing, clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

#[cfg(all(test, not(feature = "std")))]
extern crate std;

pub mod converter;
/// The configuration image (`converter::image`), at the crate root where the firmware, the soft
/// slave and the tools have always named it.
pub use converter::image;
pub mod serial;
pub mod update;

#[cfg(feature = "description")]
pub mod description;
#[cfg(feature = "description")]
pub mod description_write;
