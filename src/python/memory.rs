//! The memory a run needs (`recorded_rows`, `run_bytes`, `check_run_memory`) and the memory the system has
//! (`available_memory`), for callers that refuse a run before allocating it (the CLI).

use super::convert::{count, positive_count};
use super::errors::ModelError;
use crate::integrate::footprint::{self, Count, RunBytes};
use crate::StateLayout;
use pyo3::exceptions::PyMemoryError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// A step count of any size: exact below 2¹²⁸, a float past that (a count from
/// ``round(duration / dt)`` may have hundreds of digits).
fn steps_arg(steps: &Bound<'_, PyAny>) -> PyResult<Count> {
    // an int or numpy integer, not a bool or a float
    let index = if steps.is_instance_of::<pyo3::types::PyBool>() {
        None
    } else {
        steps.call_method0("__index__").ok()
    };
    let Some(index) = index.filter(|i| i.ge(0).unwrap_or(false)) else {
        return Err(ModelError::new_err(format!(
            "steps: expected an integer >= 0, given {} ({})",
            steps.get_type().name()?,
            steps.repr()?
        )));
    };
    if let Ok(exact) = index.extract::<u128>() {
        return Ok(Count::Exact(exact));
    }
    // past u128: in units of 2^128 (infinite past a float's range in those units)
    let scaled = index.rshift(128)?.extract::<f64>();
    Ok(Count::Beyond(scaled.unwrap_or(f64::INFINITY)))
}

fn run_bytes_of(
    steps: &Bound<'_, PyAny>,
    n: &Bound<'_, PyAny>,
    record_every: Option<&Bound<'_, PyAny>>,
    wheels: Option<&Bound<'_, PyAny>>,
) -> PyResult<RunBytes> {
    let layout = StateLayout {
        n: count(n, "n")?,
        wheels: wheels.map_or(Ok(0), |k| count(k, "wheels"))?,
    };
    let every = record_every.map_or(Ok(1), |k| positive_count(k, "record_every"))?;
    Ok(RunBytes::new(steps_arg(steps)?, layout, every)?)
}

fn count_to_py<'py>(py: Python<'py>, c: Count) -> PyResult<Bound<'py, PyAny>> {
    match c {
        Count::Exact(v) => Ok(v.into_pyobject(py)?.into_any()),
        Count::Beyond(v) => Ok(v.into_pyobject(py)?.into_any()),
    }
}

/// Rows a complete run of ``steps`` steps keeps with ``record_every`` (``simulate``'s rule):
/// rows 0, k, 2k, … and always the final row, ``steps // k + 1`` plus one when k does not
/// divide ``steps``. An exact int below 2¹²⁸, a float past that.
#[pyfunction]
#[pyo3(name = "recorded_rows", signature = (steps, record_every))]
pub(crate) fn py_recorded_rows<'py>(
    py: Python<'py>,
    steps: &Bound<'py, PyAny>,
    record_every: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyAny>> {
    let every = positive_count(record_every, "record_every")?;
    count_to_py(py, footprint::recorded_rows(steps_arg(steps)?, every))
}

/// The bytes a run of ``steps`` steps of an arm of ``n`` joints (and ``wheels`` reaction wheels)
/// allocates, keeping one row in ``record_every`` and the final row, by part (a dict, in this
/// order): ``"reference tables"`` (a tabulated motor reference, ``θ_ref`` and ``θ̇_ref``:
/// ``2·steps·n`` numbers), ``"record"`` (the ``Trajectory``: per row ``t`` and ``x``, per row but
/// the last the inputs) and ``"diagnostics"`` (momentum, energy, an EE pose, deflection, spring
/// torque and working arrays computed along the record: ``14 + 4n`` numbers a row), 8 bytes a
/// number. Each is an exact int below 2¹²⁸, a float past that.
#[pyfunction]
#[pyo3(name = "run_bytes", signature = (steps, n, record_every = None, wheels = None))]
pub(crate) fn py_run_bytes<'py>(
    py: Python<'py>,
    steps: &Bound<'py, PyAny>,
    n: &Bound<'py, PyAny>,
    record_every: Option<&Bound<'py, PyAny>>,
    wheels: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let run = run_bytes_of(steps, n, record_every, wheels)?;
    let parts = PyDict::new(py);
    for (name, bytes) in run.parts() {
        parts.set_item(name, count_to_py(py, bytes)?)?;
    }
    Ok(parts)
}

/// Raises ``MemoryError`` when the run of :func:`run_bytes` needs more than ``available`` bytes
/// (default: :func:`available_memory`; no check where the system does not say), naming what it
/// needs, by part, against what is free: ``"20,000,000,000 steps of 7 joints need about 16.8 TB
/// (reference tables 2.24 TB, record 7.84 TB, diagnostics 6.72 TB) but 13.2 GB of memory is
/// free"``. Nothing is allocated.
#[pyfunction]
#[pyo3(name = "check_run_memory", signature = (steps, n, record_every = None, wheels = None, *, available = None))]
pub(crate) fn py_check_run_memory<'py>(
    steps: &Bound<'py, PyAny>,
    n: &Bound<'py, PyAny>,
    record_every: Option<&Bound<'py, PyAny>>,
    wheels: Option<&Bound<'py, PyAny>>,
    available: Option<&Bound<'py, PyAny>>,
) -> PyResult<()> {
    let run = run_bytes_of(steps, n, record_every, wheels)?;
    let available = match available {
        Some(a) => Some(count(a, "available")? as u64),
        None => crate::io::available_memory(),
    };
    run.check(available).map_err(PyMemoryError::new_err)
}

/// The bytes of memory available to new allocations (Linux: ``MemAvailable``, which counts the
/// page cache the kernel gives back), or ``None`` where the system does not say.
#[pyfunction]
pub(crate) fn available_memory() -> Option<u64> {
    crate::io::available_memory()
}
