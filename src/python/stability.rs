//! `orbitflex.StabilityLimit`: what `FlexibleArm.rk4_stability_limit` returns.

use crate::flex::StabilityLimit;
use pyo3::prelude::*;
use pyo3::types::PyComplex;

/// The RK4 stability limit of a closed loop (``FlexibleArm.rk4_stability_limit``).
///
/// ``dt``: the largest stable step (s; ``inf`` when nothing limits it). ``fastest_mode``: the
/// linearised closed loop's eigenvalue of largest magnitude (complex, 1/s), and
/// ``fastest_mode_hz``, its magnitude in Hz (``|λ|/2π``), for orientation. ``open_loop``: True
/// when the controller's feedback was unknown (a Python callable) and only the open loop was
/// analysed. ``estimated``: True when each joint was analysed on its own (more than 16 joints).
/// ``float(limit)`` is ``limit.dt``.
#[pyclass(name = "StabilityLimit", module = "orbitflex", frozen)]
pub struct PyStabilityLimit {
    pub(crate) limit: StabilityLimit,
}

#[pymethods]
impl PyStabilityLimit {
    /// The largest stable step (s).
    #[getter]
    fn dt(&self) -> f64 {
        self.limit.dt
    }

    /// The closed loop's eigenvalue of largest magnitude (1/s).
    #[getter]
    fn fastest_mode<'py>(&self, py: Python<'py>) -> Bound<'py, PyComplex> {
        let mode = self.limit.fastest_mode;
        PyComplex::from_doubles(py, mode.re, mode.im)
    }

    /// ``|fastest_mode| / 2π`` (Hz).
    #[getter]
    fn fastest_mode_hz(&self) -> f64 {
        self.limit.fastest_mode.norm() / (2.0 * std::f64::consts::PI)
    }

    /// True when only the open loop was analysed (the controller's feedback is unknown).
    #[getter]
    fn open_loop(&self) -> bool {
        self.limit.open_loop
    }

    /// True when each joint was analysed on its own (more than 16 joints).
    #[getter]
    fn estimated(&self) -> bool {
        self.limit.estimated
    }

    fn __float__(&self) -> f64 {
        self.limit.dt
    }

    fn __repr__(&self) -> String {
        let mode = self.limit.fastest_mode;
        format!(
            "StabilityLimit(dt={:e}, fastest_mode=({:e}{:+e}j), open_loop={}, estimated={})",
            self.limit.dt,
            mode.re,
            mode.im,
            if self.limit.open_loop {
                "True"
            } else {
                "False"
            },
            if self.limit.estimated {
                "True"
            } else {
                "False"
            },
        )
    }
}
