//! The objects the core implements (protocol §5, §6), one file per class, each an
//! `impl SlaveNode` block with the class's services and attributes:
//!
//! | file | class |
//! |---|---|
//! | `router.rs` | the Message Router (class 0x02): routes a request to its class, then its own attributes |
//! | `identity.rs` | Identity (class 0x01, protocol §6.2) |
//! | `devicenet.rs` | DeviceNet (class 0x03, protocol §6.1), Allocate/Release included |
//! | `assembly.rs` | Assembly (class 0x04): the poll connection's input and output images |
//! | `connection.rs` | Connection (class 0x05, protocol §5): attributes, Reset, watchdogs and deletion |
//! | `ack_handler.rs` | Acknowledge Handler (class 0x2B, protocol §II.2.4) |
//!
//! Requests for any other class go to the application's [`ObjectHandler`](super::ObjectHandler).
//! Class IDs come from [`crate::objects::class`].

mod ack_handler;
mod assembly;
mod connection;
mod devicenet;
mod identity;
mod router;

pub use devicenet::SettingChanged;

use super::{Reply, ServiceError};

/// Class attribute 1 (revision), the only class attribute served; with `max_instance` also
/// attribute 2 (max instance, 1: the Acknowledge Handler's single instance).
fn class_revision(
    data: &[u8],
    revision: u16,
    max_instance: bool,
    reply: &mut Reply<'_>,
) -> Result<(), ServiceError> {
    match *data {
        [1] => reply.u16(revision),
        [2] if max_instance => reply.u16(1),
        [_] => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        _ => Err(ServiceError::wrong_length(data, 1)),
    }
}
