//! # dnet-py: the Python package `dnet`
//!
//! The bench DeviceNet master for test scripts: the bring-up, explicit get/set, polled I/O, the
//! network scan and the monitor of `master-core` and `dnet-scanner`, and the frame decoder of
//! `master-core::decode`, as a Python extension module built with maturin (`python/run-tests`,
//! the guide's "Scripting" page). The simulated bus with the reference device (or a
//! `--slave-config` description) is the same one `dnet-master --bus sim` opens
//! ([`converter_sim::open_bus`]), so a script runs without hardware.
//!
//! | module | what it holds |
//! |---|---|
//! | [`master`] | the `dnet.Master` class and its monitor iterator |
//! | [`ops`] | what each call does with the master on the bus thread |
//! | [`worker`] | the bus thread that owns the bus, the session and the master |
//! | [`decode`] | `dnet.decode` and its iterator |
//! | [`error`] | `dnet.Error`, `dnet.DeviceError`, `dnet.Timeout` and the mapping of the master's errors |
//! | [`args`] | Python arguments checked, each error naming the argument |
//!
//! Bus frames and traces are untrusted: every error is a Python exception, never a panic.

pub mod args;
pub mod decode;
pub mod error;
pub mod master;
pub mod ops;
pub mod worker;

use pyo3::prelude::*;

/// `value` (a serde value: a report, scan rows, a sample) as Python dicts, lists and numbers.
pub(crate) fn to_py<T: serde::Serialize>(py: Python<'_>, value: &T) -> PyResult<Py<PyAny>> {
    pythonize::pythonize(py, value).map(Bound::unbind).map_err(PyErr::from)
}

/// The bench DeviceNet master for test scripts: ``Master`` (bring-up, get/set, poll, scan,
/// monitor, on ``sim``, ``socketcan:IFACE`` or ``slcan:PATH``) and ``decode`` (traces of any
/// common format). See the guide's "Scripting" page.
#[pymodule]
fn dnet(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_class::<master::PyMaster>()?;
    m.add_class::<master::MonitorIter>()?;
    m.add_class::<decode::DecodeIter>()?;
    m.add_function(wrap_pyfunction!(decode::decode, m)?)?;
    m.add("Error", py.get_type::<error::Error>())?;
    m.add("DeviceError", py.get_type::<error::DeviceError>())?;
    m.add("Timeout", py.get_type::<error::Timeout>())?;
    Ok(())
}
