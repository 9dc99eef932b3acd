//! `dnet.decode`: a trace of any format `dnet-master decode` reads (candump -L, pcap, pcapng,
//! trc, asc, blf, csv), as an iterator of decoded messages.

use crate::args::bytes_arg;
use can_io::trace::{parse_trace, ReadOptions, TraceFormat};
use master_core::decode::filter::classify;
use master_core::decode::Decoder;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyString};
use std::sync::Mutex;

/// Where the decoder is in the trace.
struct Position {
    /// The trace's frames.
    trace: can_io::trace::Trace,
    /// The next frame's index.
    next: usize,
    /// Follows fragments and connections across frames.
    decoder: Decoder,
}

/// The iterator of decoded messages :func:`decode` returns; ``format`` is the trace's format,
/// ``skipped`` how many lines were not DeviceNet frames.
#[pyclass(module = "dnet")]
pub struct DecodeIter {
    position: Mutex<Position>,
    /// The trace's format (`candump`, `pcap`, ...).
    #[pyo3(get)]
    format: String,
    /// Lines or records that were not DeviceNet frames (skipped unless ``strict``).
    #[pyo3(get)]
    skipped: usize,
}

/// Reads `source` (text or bytes) as a trace; `format` names it when detection is not wanted.
#[pyfunction]
#[pyo3(signature = (source, *, format = None, strict = false))]
pub fn decode(source: &Bound<'_, PyAny>, format: Option<&str>, strict: bool) -> PyResult<DecodeIter> {
    let bytes = if let Ok(s) = source.cast::<PyString>() {
        s.to_cow()?.as_bytes().to_vec()
    } else {
        bytes_arg("source", source)
            .map_err(|_| PyTypeError::new_err("source: str, bytes or bytearray expected"))?
    };
    let format = format
        .map(|f| {
            TraceFormat::from_name(f).ok_or_else(|| {
                let names: Vec<&str> = TraceFormat::ALL.iter().map(|t| t.name()).collect();
                PyValueError::new_err(format!(
                    "format: unknown trace format '{f}' (one of: {})",
                    names.join(", ")
                ))
            })
        })
        .transpose()?;
    let trace = parse_trace(&bytes, "<input>", ReadOptions { strict, format })
        .map_err(|e| PyValueError::new_err(format!("source: {e}")))?;
    Ok(DecodeIter {
        format: trace.format.name().to_string(),
        skipped: trace.skipped_count,
        position: Mutex::new(Position { trace, next: 0, decoder: Decoder::new() }),
    })
}

#[pymethods]
impl DecodeIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next message: a dict with ``line``, ``time_us``, ``iface``, ``direction``, ``id``,
    /// ``data`` (bytes), ``frame``, ``kind``, ``group``, ``mac``, ``meaning``, ``message`` (the
    /// reassembled message a last fragment completes) and ``protocol_error``.
    fn __next__<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let mut p = self.position.lock().map_err(|_| PyValueError::new_err("decode: iterator poisoned"))?;
        let Some(e) = p.trace.entries.get(p.next).cloned() else {
            return Ok(None);
        };
        p.next += 1;
        let d = p.decoder.decode(&e.frame);
        let class = classify(&e.frame);
        let out = PyDict::new(py);
        out.set_item("line", e.line)?;
        out.set_item("time_us", e.at.total_micros())?;
        out.set_item("iface", &*e.iface)?;
        out.set_item("direction", e.direction.map(|d| d.name()))?;
        out.set_item("id", e.frame.id().as_raw())?;
        out.set_item("data", PyBytes::new(py, e.frame.data()))?;
        out.set_item("frame", e.frame.to_string())?;
        out.set_item("kind", class.kind.name())?;
        out.set_item("group", class.group)?;
        out.set_item("mac", class.mac)?;
        out.set_item("meaning", d.summary)?;
        out.set_item("message", d.message)?;
        out.set_item(
            "protocol_error",
            d.protocol_error.map(|v| {
                let mut text = String::new();
                v.push(&mut text);
                text.trim_start_matches(" (protocol error: ").trim_end_matches(')').to_string()
            }),
        )?;
        Ok(Some(out))
    }
}
