//! The checks, one module per category, run in the order of [`super::Category::ALL`]. Each check
//! prepares the state it needs itself (releasing and allocating connections through the protocol),
//! so one failure does not cascade into the next check.

mod connection_set;
mod connections;
mod explicit;
mod io_connections;
mod network;
mod offline;
mod timing;

use super::runner::Runner;
use harness_common::error::HarnessError;

/// Runs every check. Ends early with [`HarnessError::NoDevice`] when nothing answers at the MAC
/// after the bring-up, and with the interruption when a stop is asked for; releasing the device
/// is the caller's ([`Runner::finish`]).
pub(crate) fn run_all(r: &mut Runner<'_, '_>) -> Result<(), HarnessError> {
    network::run(r)?;
    connection_set::run(r)?;
    explicit::run(r)?;
    connections::run(r)?;
    io_connections::run(r)?;
    timing::run(r)?;
    offline::run(r)
}
