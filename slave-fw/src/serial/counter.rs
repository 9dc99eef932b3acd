//! The wrapping counter increment of the [`sequencer`](super::sequencer)'s own counters (the
//! link statistics are a table in [`health`](super::health), counted by
//! [`LinkHealth::count`](super::LinkHealth::count)).

/// Adds one to a wrapping counter.
pub(crate) fn bump(counter: &mut u32) {
    *counter = counter.wrapping_add(1);
}
