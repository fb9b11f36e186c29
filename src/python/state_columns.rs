//! The state-layout getters of a record, written once for `Trajectory` (rows of one run) and
//! `BatchTrajectory` (runs × rows): each is a view of the last axis of the states `x` or of
//! the held inputs `[u | applied wheel torques]`, the leading axes kept.

use crate::flex::StateLayout;
use pyo3::prelude::*;
use pyo3::types::{PyEllipsis, PySlice, PyTuple};
use std::ops::Range;

/// A record whose states and held inputs end in the state layout's axes: what
/// [`state_getters`] reads.
pub(crate) trait StateRecord {
    /// The layout of a state row (and of an input row, `n + w` numbers).
    fn layout(&self) -> StateLayout;
    /// The states, `(…, 13 + 4n + w)`.
    fn states<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny>;
    /// The held inputs, `(…, n + w)`.
    fn inputs<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny>;
}

/// Columns `range` of the last axis of `array` (`array[..., range]`), a view.
pub(crate) fn last_axis(array: &Bound<'_, PyAny>, range: Range<usize>) -> PyResult<PyObject> {
    let py = array.py();
    let columns = PySlice::new(py, range.start as isize, range.end as isize, 1);
    let key = PyTuple::new(
        py,
        [
            PyEllipsis::get(py).to_owned().into_any(),
            columns.into_any(),
        ],
    )?;
    Ok(array.get_item(key)?.unbind())
}

/// The motor torques of a record: its held inputs, whole without reaction wheels (no view),
/// otherwise their first `n` columns.
pub(crate) fn motor_torques(record: &impl StateRecord, py: Python<'_>) -> PyResult<PyObject> {
    let layout = record.layout();
    if layout.wheels == 0 {
        return Ok(record.inputs(py).unbind());
    }
    last_axis(&record.inputs(py), 0..layout.n)
}

/// Columns `columns(layout)` of a record's states, a view.
pub(crate) fn state_view(
    record: &impl StateRecord,
    py: Python<'_>,
    columns: impl Fn(&StateLayout) -> Range<usize>,
) -> PyResult<PyObject> {
    last_axis(&record.states(py), columns(&record.layout()))
}

/// The applied reaction-wheel torques of a record: the last `w` columns of its held inputs.
pub(crate) fn wheel_torques(record: &impl StateRecord, py: Python<'_>) -> PyResult<PyObject> {
    let layout = record.layout();
    last_axis(&record.inputs(py), layout.n..layout.inputs_len())
}

/// The getters of the state layout for a `#[pyclass]` implementing [`StateRecord`]: `u`,
/// `wheel_torque`, `wheel_speed`, `base_pose`, `q`, `theta`, `base_twist`, `qd`, `theta_dot`.
/// `$rows` names the leading axes in the docstrings (`"k"`, `"B, rows"`); `$u` and `$wheel`
/// are the docstrings of `u` and `wheel_torque`, whose rows are the steps.
macro_rules! state_getters {
    ($class:ty, rows: $rows:literal, u: $u:literal, wheel_torque: $wheel:literal) => {
        #[pymethods]
        impl $class {
            #[doc = $u]
            #[getter]
            fn u(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::motor_torques(self, py)
            }
            #[doc = $wheel]
            #[getter]
            fn wheel_torque(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::wheel_torques(self, py)
            }
            #[doc = concat!(
                "Reaction-wheel speeds relative to the bus (rad/s), (", $rows, ", w); a view of ``x``."
            )]
            #[getter]
            fn wheel_speed(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::state_view(self, py, $crate::flex::StateLayout::wheel_speed)
            }
            #[doc = concat!(
                "``[r_B (m); quat_B (x, y, z, w)]`` per state, (", $rows, ", 7); a view of ``x``."
            )]
            #[getter]
            fn base_pose(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::state_view(self, py, $crate::flex::StateLayout::base_pose)
            }
            #[doc = concat!("Link angles (rad), (", $rows, ", n); a view of ``x``.")]
            #[getter]
            fn q(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::state_view(self, py, $crate::flex::StateLayout::q)
            }
            #[doc = concat!("Motor angles, link side (rad), (", $rows, ", n); a view of ``x``.")]
            #[getter]
            fn theta(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::state_view(self, py, $crate::flex::StateLayout::theta)
            }
            #[doc = concat!(
                "``[ω_B (rad/s); v_B (m/s)]`` in base-frame components, (", $rows,
                ", 6); a view of ``x``."
            )]
            #[getter]
            fn base_twist(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::state_view(self, py, $crate::flex::StateLayout::base_twist)
            }
            #[doc = concat!("Link rates (rad/s), (", $rows, ", n); a view of ``x``.")]
            #[getter]
            fn qd(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::state_view(self, py, $crate::flex::StateLayout::qd)
            }
            #[doc = concat!("Motor rates, link side (rad/s), (", $rows, ", n); a view of ``x``.")]
            #[getter]
            fn theta_dot(&self, py: Python<'_>) -> PyResult<PyObject> {
                $crate::python::state_columns::state_view(self, py, $crate::flex::StateLayout::theta_dot)
            }
        }
    };
}
pub(crate) use state_getters;
