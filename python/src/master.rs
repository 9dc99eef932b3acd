//! `dnet.Master`: the Python class over the bus thread ([`crate::worker`]) and its calls
//! ([`crate::ops`]).

use crate::args::{bytes_arg, mac_arg, u16_arg, u8_arg};
use crate::error::{CallError, Error};
use crate::ops::{self, Monitor};
use crate::worker::{BusSetup, State, Worker};
use can_io::bus::{Bitrate, BusSpec};
use converter_sim::SimSetup;
use devicenet::{Duration, MacId};
use dnet_scanner::monitor::InputLayout;
use master_core::io::IoKind;
use master_core::master::{Master as CoreMaster, MasterConfig};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyBytes;
use slave_fw::description::DeviceDescription;
use std::path::PathBuf;
use std::sync::Mutex;

/// A DeviceNet master on a bus: ``sim`` (the simulated bus with the reference device, or the
/// devices of ``slave_config``), ``socketcan:IFACE`` or ``slcan:PATH[@SERIALBAUD]``.
///
/// A context manager: leaving the ``with`` block (or :meth:`close`) releases every connection the
/// master allocated and closes the bus. Every call waits on the bus with the GIL released.
#[pyclass(module = "dnet", name = "Master")]
pub struct PyMaster {
    worker: Mutex<Option<Worker>>,
    bus: String,
}

impl PyMaster {
    /// Runs `f` on the bus thread, the GIL released meanwhile.
    pub fn call<T: Send + 'static>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&mut CoreMaster<'_, '_>, &mut State) -> Result<T, CallError> + Send + 'static,
    ) -> Result<T, CallError> {
        py.detach(|| {
            let guard = self.worker.lock().map_err(|_| CallError::Closed)?;
            match guard.as_ref() {
                Some(w) => w.call(f),
                None => Err(CallError::Closed),
            }
        })
    }
}

/// The description file named by `slave_config`, read (a `ValueError` naming the file and line).
fn read_description(path: Option<&PathBuf>, arg: &str) -> PyResult<Option<DeviceDescription>> {
    path.map(|p| DeviceDescription::load(p).map_err(|e| PyValueError::new_err(format!("{arg}: {e}"))))
        .transpose()
}

#[pymethods]
impl PyMaster {
    /// Opens the bus. ``slave_config`` (a device description, TOML) and ``slave_macs`` choose
    /// the simulated devices (``sim`` only); ``timeout`` is the explicit response timeout in
    /// seconds; ``log`` writes every frame to a candump -L file.
    #[new]
    #[pyo3(signature = (bus = "sim", master_mac = 0, bitrate = "250k", *, slave_config = None, slave_macs = None, timeout = 1.0, log = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        bus: &str,
        master_mac: i64,
        bitrate: &str,
        slave_config: Option<PathBuf>,
        slave_macs: Option<Vec<i64>>,
        timeout: f64,
        log: Option<PathBuf>,
    ) -> PyResult<PyMaster> {
        let spec: BusSpec = bus.parse().map_err(|e| PyValueError::new_err(format!("bus: {e}")))?;
        let bitrate: Bitrate = bitrate.parse().map_err(|e| PyValueError::new_err(format!("bitrate: {e}")))?;
        let mac = mac_arg("master_mac", master_mac)?;
        if !(timeout.is_finite() && (0.001..=3600.0).contains(&timeout)) {
            return Err(PyValueError::new_err(format!("timeout: {timeout} s is not within 0.001..=3600")));
        }
        let described = read_description(slave_config.as_ref(), "slave_config")?;
        let is_sim = spec == BusSpec::Sim;
        if !is_sim && (described.is_some() || slave_macs.is_some()) {
            return Err(PyValueError::new_err(
                "slave_config, slave_macs: the simulated devices exist on bus=\"sim\" only",
            ));
        }
        let mut sim = match &described {
            Some(d) => SimSetup::described(d.converter.clone()),
            None => SimSetup::reference(),
        };
        sim.macs = slave_macs
            .unwrap_or_default()
            .into_iter()
            .map(|m| mac_arg("slave_macs", m))
            .collect::<PyResult<Vec<MacId>>>()?;
        // The simulated device's profile decodes the monitor's samples; a real device's data stays
        // raw unless monitor() is given a description.
        let layout = match (&described, is_sim) {
            (Some(d), true) => InputLayout::from_converter(&d.converter),
            (None, true) => InputLayout::from_converter(&DeviceDescription::reference().converter),
            _ => InputLayout::raw(),
        };
        let config = MasterConfig {
            mac,
            // Whole microseconds: the check above keeps the product within u64.
            response_timeout: Duration::from_micros((timeout * 1e6) as u64),
            ..MasterConfig::default()
        };
        let setup = BusSetup { spec, bitrate, sim, config, layout, log };
        let worker =
            py.detach(|| Worker::start(setup)).map_err(|e| Error::new_err(format!("bus {bus}: {e}")))?;
        Ok(PyMaster { worker: Mutex::new(Some(worker)), bus: bus.to_string() })
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    #[pyo3(signature = (*_exc))]
    fn __exit__(&self, py: Python<'_>, _exc: &Bound<'_, pyo3::types::PyTuple>) -> PyResult<bool> {
        self.close(py)?;
        Ok(false)
    }

    fn __repr__(&self) -> String {
        format!("dnet.Master(bus={:?})", self.bus)
    }

    /// Releases every connection the master holds and closes the bus; returns the MAC IDs of the
    /// devices released. A closed master refuses every call; a second close does nothing.
    fn close(&self, py: Python<'_>) -> PyResult<Vec<u32>> {
        let worker = self.worker.lock().map_err(|_| CallError::Closed)?.take();
        match worker {
            Some(mut w) => {
                let released = py.detach(move || w.close())?;
                // A list of ints (a Vec<u8> would become bytes).
                Ok(released.into_iter().map(|m| u32::from(m.as_raw())).collect())
            }
            None => Ok(Vec::new()),
        }
    }

    /// The bring-up of the device at ``mac`` (protocol §2): network access, UCMM probe,
    /// allocation, identity reads, the I/O connection ``io`` (``poll``, ``strobe``, ``cos`` or
    /// ``cyclic``) at ``epr`` ms, one I/O cycle. Returns the report: ``ok``, ``failures``,
    /// ``device`` (identity, sizes, EPR, last input) and ``frames`` (every frame with its
    /// verdict). The connection stays for :meth:`poll` and :meth:`monitor`. Scripts check
    /// ``report["ok"]``: a frame check that failed does not raise.
    #[pyo3(signature = (mac, io = "poll", *, epr = 100))]
    fn connect(&self, py: Python<'_>, mac: i64, io: &str, epr: i64) -> PyResult<Py<PyAny>> {
        let mac = mac_arg("mac", mac)?;
        let kind: IoKind = io.parse().map_err(|e| PyValueError::new_err(format!("io: {e}")))?;
        let epr = u16_arg("epr", epr)?;
        let report = self.call(py, move |m, s| ops::connect(m, s, mac, kind, epr))?;
        let obj = crate::to_py(py, &report)?;
        // The last input as bytes, like poll()'s.
        if let (Ok(d), Some(input)) = (obj.bind(py).get_item("device"), &report.device.last_input) {
            d.set_item("last_input", PyBytes::new(py, input))?;
        }
        Ok(obj)
    }

    /// Get_Attribute_Single of class ``cls``, instance ``inst``, attribute ``attr`` at ``mac``:
    /// the value's bytes. Allocates the explicit connection when the master has none.
    fn get<'py>(
        &self,
        py: Python<'py>,
        mac: i64,
        cls: i64,
        inst: i64,
        attr: i64,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let (mac, cls, inst, attr) =
            (mac_arg("mac", mac)?, u16_arg("cls", cls)?, u16_arg("inst", inst)?, u8_arg("attr", attr)?);
        let v = self.call(py, move |m, _| ops::get(m, mac, cls, inst, attr))?;
        Ok(PyBytes::new(py, &v))
    }

    /// Set_Attribute_Single of ``value`` (bytes) to class ``cls``, instance ``inst``, attribute
    /// ``attr`` at ``mac``: the response's data (usually empty).
    fn set<'py>(
        &self,
        py: Python<'py>,
        mac: i64,
        cls: i64,
        inst: i64,
        attr: i64,
        value: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let (mac, cls, inst, attr) =
            (mac_arg("mac", mac)?, u16_arg("cls", cls)?, u16_arg("inst", inst)?, u8_arg("attr", attr)?);
        let value = bytes_arg("value", value)?;
        let v = self.call(py, move |m, _| ops::set(m, mac, cls, inst, attr, &value))?;
        Ok(PyBytes::new(py, &v))
    }

    /// One I/O cycle on the connection :meth:`connect` left to ``mac``: sends ``output`` (bytes
    /// of the consumed size; ``None``: zeros) and returns the input image (bytes). A poll goes out
    /// no sooner than one EPR after the previous one (on ``sim`` the simulated time moves on).
    #[pyo3(signature = (mac, output = None))]
    fn poll<'py>(
        &self,
        py: Python<'py>,
        mac: i64,
        output: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyBytes>> {
        let mac = mac_arg("mac", mac)?;
        let output = output.map(|o| bytes_arg("output", o)).transpose()?;
        let (_, v) = self.call(py, move |m, s| ops::io_cycle(m, s, mac, output.as_deref()))?;
        Ok(PyBytes::new(py, &v))
    }

    /// The devices at MAC IDs ``first``..=``last`` (the master's own left out): a list of dicts
    /// with the MAC, identity (vendor, device type, product code, revision, serial number,
    /// product name), poll sizes and status.
    #[pyo3(signature = (first = 0, last = 63))]
    fn scan(&self, py: Python<'_>, first: i64, last: i64) -> PyResult<Py<PyAny>> {
        let (first, last) = (mac_arg("first", first)?.as_raw(), mac_arg("last", last)?.as_raw());
        if first > last {
            return Err(PyValueError::new_err(format!("first, last: {first} is above {last}")));
        }
        let report = self.call(py, move |m, s| ops::scan(m, s, first, last))?;
        crate::to_py(py, &report.devices)
    }

    /// An iterator of samples of the device at ``mac``, one every EPR: each a dict with
    /// ``time_us``, ``fields`` (decoded by the simulated device's profile, or by ``description``,
    /// a device description file), ``link``, ``stale``, ``raw`` (bytes). Brings the device
    /// up first unless :meth:`connect` did. Ends after ``count`` samples or ``duration`` seconds of
    /// bus time; with neither, it never ends (break out of the loop).
    #[pyo3(signature = (mac, *, io = "poll", epr = 100, count = None, duration = None, output = None, description = None))]
    #[allow(clippy::too_many_arguments)]
    fn monitor(
        slf: Bound<'_, Self>,
        mac: i64,
        io: &str,
        epr: i64,
        count: Option<i64>,
        duration: Option<f64>,
        output: Option<&Bound<'_, PyAny>>,
        description: Option<PathBuf>,
    ) -> PyResult<MonitorIter> {
        let mac = mac_arg("mac", mac)?;
        let kind: IoKind = io.parse().map_err(|e| PyValueError::new_err(format!("io: {e}")))?;
        let epr_ms = u16_arg("epr", epr)?;
        let remaining = count
            .map(|c| u64::try_from(c).map_err(|_| PyValueError::new_err(format!("count: {c} is negative"))))
            .transpose()?;
        let duration = match duration {
            Some(d) if d.is_finite() && (0.0..=1e6).contains(&d) => {
                Some(Duration::from_micros((d * 1e6) as u64))
            }
            Some(d) => {
                return Err(PyValueError::new_err(format!("duration: {d} s is not within 0..=1000000")))
            }
            None => None,
        };
        let output = output.map(|o| bytes_arg("output", o)).transpose()?;
        let layout = read_description(description.as_ref(), "description")?
            .map(|d| InputLayout::from_converter(&d.converter));
        let state = Monitor { mac, output, epr_ms, kind, remaining, duration, end: None, layout };
        Ok(MonitorIter { master: slf.unbind(), state: Mutex::new(state) })
    }
}

/// The iterator :meth:`Master.monitor` returns.
#[pyclass(module = "dnet")]
pub struct MonitorIter {
    master: Py<PyMaster>,
    state: Mutex<Monitor>,
}

#[pymethods]
impl MonitorIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&self, py: Python<'_>) -> PyResult<Option<Py<PyAny>>> {
        let mut m = self.state.lock().map_err(|_| CallError::Closed)?.clone();
        let master = self.master.bind(py).borrow();
        let (sample, m) = master.call(py, move |core, s| {
            let sample = ops::monitor_next(core, s, &mut m)?;
            Ok((sample, m))
        })?;
        *self.state.lock().map_err(|_| CallError::Closed)? = m;
        let Some(sample) = sample else { return Ok(None) };
        let obj = crate::to_py(py, &sample)?;
        // The raw image as bytes, like poll()'s.
        if let Ok(d) = obj.bind(py).cast::<pyo3::types::PyDict>() {
            d.set_item("raw", PyBytes::new(py, &sample.raw))?;
        }
        Ok(Some(obj))
    }
}
