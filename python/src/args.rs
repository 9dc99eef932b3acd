//! Python arguments checked: a number out of range is a `ValueError` and a value of the wrong type
//! a `TypeError`, both naming the argument.

use devicenet::MacId;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyByteArray, PyBytes};

/// A MAC ID, 0..=63.
pub fn mac_arg(name: &str, v: i64) -> PyResult<MacId> {
    u8::try_from(v)
        .ok()
        .and_then(MacId::new)
        .ok_or_else(|| PyValueError::new_err(format!("{name}: {v} is not a MAC ID (0..=63)")))
}

/// A USINT, 0..=255.
pub fn u8_arg(name: &str, v: i64) -> PyResult<u8> {
    u8::try_from(v).map_err(|_| PyValueError::new_err(format!("{name}: {v} is not within 0..=255")))
}

/// A UINT, 0..=65535.
pub fn u16_arg(name: &str, v: i64) -> PyResult<u16> {
    u16::try_from(v).map_err(|_| PyValueError::new_err(format!("{name}: {v} is not within 0..=65535")))
}

/// Bytes: `bytes` or `bytearray` (a `str` or a list is refused, so that no text is sent by
/// mistake).
pub fn bytes_arg(name: &str, v: &Bound<'_, PyAny>) -> PyResult<Vec<u8>> {
    if let Ok(b) = v.cast::<PyBytes>() {
        Ok(b.as_bytes().to_vec())
    } else if let Ok(b) = v.cast::<PyByteArray>() {
        Ok(b.to_vec())
    } else {
        Err(PyTypeError::new_err(format!(
            "{name}: bytes or bytearray expected, not {}",
            v.get_type().name().map_or_else(|_| "?".to_string(), |n| n.to_string())
        )))
    }
}
