//! The wrapping statistics counters every profile keeps: a helper of its own, so that the modules
//! counting ([`health`](super::health), [`sequencer`](super::sequencer),
//! [`framed_profile`](super::framed_profile), [`modbus`](super::modbus)) import it from here and
//! not from one another.

/// Adds one to a wrapping counter.
pub(crate) fn bump(counter: &mut u32) {
    *counter = counter.wrapping_add(1);
}
