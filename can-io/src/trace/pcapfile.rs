//! The pcapfile reader of [`super::read_trace`] (to be written).

use super::Sink;
use crate::log::LogError;

/// Reads a pcapfile trace into `sink`.
pub fn read(_bytes: &[u8], sink: &mut Sink<'_>) -> Result<(), LogError> {
    Err(sink.error(0, 0, "the pcapfile reader is not written yet", ""))
}
