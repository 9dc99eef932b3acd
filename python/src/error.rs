//! The Python exceptions and how the master's errors become them.
//!
//! | Rust error | Python exception |
//! |---|---|
//! | [`MasterError::ErrorResponse`] | `dnet.DeviceError` (`general`, `additional`, `general_name`, `additional_name`, `mac`, `request`) |
//! | [`MasterError::Timeout`] | `dnet.Timeout` (`mac`, `waiting_for`, `timeout`) |
//! | [`MasterError::Usage`], a MAC range refused | `ValueError` |
//! | every other (the bus, a protocol breach, an allocation conflict) | `dnet.Error` |
//!
//! `DeviceError` and `Timeout` are subclasses of `dnet.Error`.

use devicenet::explicit::additional;
use harness_common::error::HarnessError;
use master_core::error::MasterError;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    dnet,
    Error,
    PyException,
    "Every error of the dnet package that is not a usage error."
);
pyo3::create_exception!(
    dnet,
    DeviceError,
    Error,
    "The device answered with an error response: `general` and `additional` are the codes, \
     `general_name` and `additional_name` their names (None when unknown), `mac` the device, \
     `request` what was asked."
);
pyo3::create_exception!(
    dnet,
    Timeout,
    Error,
    "Nothing arrived in time: `mac` is the device, `waiting_for` what the master waited for, \
     `timeout` the name of the timeout that expired."
);

/// Why a call of the package failed, before it becomes a Python exception.
#[derive(Debug, thiserror::Error)]
pub enum CallError {
    /// What the master reported.
    #[error(transparent)]
    Master(#[from] MasterError),
    /// What a harness function (the scan) reported.
    #[error(transparent)]
    Harness(#[from] HarnessError),
    /// A call the master cannot make as asked (a `ValueError`): the message names the argument.
    #[error("{0}")]
    Usage(String),
    /// The bus thread is gone: the master was closed, or the thread stopped.
    #[error("the master is closed")]
    Closed,
}

impl From<CallError> for PyErr {
    fn from(e: CallError) -> PyErr {
        match e {
            CallError::Master(m) | CallError::Harness(HarnessError::Master(m)) => master_error(m),
            CallError::Harness(h @ HarnessError::MacRange { .. }) => PyValueError::new_err(h.to_string()),
            CallError::Harness(h) => Error::new_err(h.to_string()),
            CallError::Usage(text) => PyValueError::new_err(text),
            CallError::Closed => Error::new_err(e.to_string()),
        }
    }
}

/// The Python exception for `e`, its codes as attributes.
fn master_error(e: MasterError) -> PyErr {
    let text = e.to_string();
    match e {
        MasterError::ErrorResponse { what, mac, general, additional: code, .. } => Python::attach(|py| {
            let err = DeviceError::new_err(text);
            let value = err.value(py);
            let set = || -> PyResult<()> {
                value.setattr("general", general.as_raw())?;
                value.setattr("additional", code)?;
                value.setattr("general_name", general.name())?;
                value.setattr("additional_name", additional::name(code))?;
                value.setattr("mac", mac)?;
                value.setattr("request", what)?;
                Ok(())
            };
            match set() {
                Ok(()) => err,
                Err(failed) => failed,
            }
        }),
        MasterError::Timeout { what, mac, timeout, .. } => Python::attach(|py| {
            let err = Timeout::new_err(text);
            let value = err.value(py);
            let set = || -> PyResult<()> {
                value.setattr("mac", mac)?;
                value.setattr("waiting_for", what)?;
                value.setattr("timeout", timeout)?;
                Ok(())
            };
            match set() {
                Ok(()) => err,
                Err(failed) => failed,
            }
        }),
        MasterError::Usage(_) => PyValueError::new_err(text),
        _ => Error::new_err(text),
    }
}
