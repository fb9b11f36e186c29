//! `orbitflex.MotorPD`, input schedules from numpy, and Python callables as controllers.

use super::convert::{array1, as_float_array, matrix, real, row_major, vector};
use super::errors::ModelError;
use super::joints::Param;
use crate::control::{Controller, MotorPD, Schedule};
use crate::error::Error;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyTuple;

/// The wheel-torque commands of a run on an arm with `k` reaction wheels: a [`schedule`] of
/// width `k`; anything but None is refused on an arm without wheels.
pub(crate) fn wheel_schedule(obj: Option<&Bound<'_, PyAny>>, k: usize) -> PyResult<Schedule> {
    match (obj.filter(|o| !o.is_none()), k) {
        (Some(_), 0) => Err(ModelError::new_err(
            "wheel_torque: the arm has no reaction wheels; give none (or build the arm with \
             wheels=)",
        )),
        (w, k) => schedule(w, "wheel_torque", k),
    }
}

/// A per-step input of width `n` from Python: None (zero), a scalar (the same for every element),
/// an (n,) constant, or a (rows, n) table.
pub(crate) fn schedule(obj: Option<&Bound<'_, PyAny>>, what: &str, n: usize) -> PyResult<Schedule> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Schedule::Zero);
    };
    let a = as_float_array(obj, what)?;
    let ndim: usize = a.getattr("ndim")?.extract()?;
    match ndim {
        0 => {
            let v = real(&a, what)?;
            crate::args::check_finite(what, &[v])?;
            Ok(Schedule::Constant(vec![v; n]))
        }
        1 => Ok(Schedule::Constant(vector(&a, what, Some(n))?)),
        2 => {
            let (_, values) = matrix(&a, what, n)?;
            Ok(Schedule::Table { values, width: n })
        }
        _ => Err(ModelError::new_err(format!(
            "{what}: expected shape ({n},) or (steps, {n}), given a {ndim}-D array"
        ))),
    }
}

/// A schedule back as Python: None, an (n,) array or a (rows, n) array.
fn schedule_object(py: Python<'_>, s: &Schedule) -> PyObject {
    match s {
        Schedule::Zero => py.None(),
        Schedule::Constant(v) => array1(py, v).into_any().unbind(),
        Schedule::Table { values, width } => {
            row_major(py, values.len() / width, *width, values.clone())
                .into_any()
                .unbind()
        }
    }
}

/// Motor-side PD with feedforward, run inside Rust without the GIL:
/// ``u = kp (theta_ref − θ) + kd (theta_dot_ref − θ̇) + feedforward`` (N·m, link side).
///
/// Gains: a scalar or (n,), ``kp`` in N·m/rad and ``kd`` in N·m·s/rad, both ≥ 0. References and
/// feedforward: (n,) constant, or (steps, n) with one row per step (row k is held during step k).
/// ``n`` is taken from ``theta_ref``.
#[pyclass(name = "MotorPD", module = "orbitflex", frozen)]
#[derive(Clone)]
pub struct PyMotorPD {
    pub(crate) pd: MotorPD,
}

#[pymethods]
impl PyMotorPD {
    #[new]
    #[pyo3(signature = (kp, kd, theta_ref, theta_dot_ref=None, feedforward=None))]
    fn new(
        kp: &Bound<'_, PyAny>,
        kd: &Bound<'_, PyAny>,
        theta_ref: &Bound<'_, PyAny>,
        theta_dot_ref: Option<&Bound<'_, PyAny>>,
        feedforward: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let reference = as_float_array(theta_ref, "theta_ref")?;
        let shape: Vec<usize> = reference.getattr("shape")?.extract()?;
        let n = match shape.as_slice() {
            [n] | [_, n] => *n,
            _ => {
                return Err(ModelError::new_err(format!(
                    "theta_ref: expected shape (n,) or (steps, n), given shape {shape:?}"
                )))
            }
        };
        let kp = Param::parse(kp, "kp")?;
        let kd = Param::parse(kd, "kd")?;
        for (what, p) in [("kp", &kp), ("kd", &kd)] {
            if let Some(len) = p.len().filter(|&len| len != n) {
                return Err(ModelError::new_err(format!(
                    "{what}: expected length {n} (as theta_ref), given length {len}"
                )));
            }
        }
        let pd = MotorPD::new(
            kp.resolve(n),
            kd.resolve(n),
            schedule(Some(&reference), "theta_ref", n)?,
            schedule(theta_dot_ref, "theta_dot_ref", n)?,
            schedule(feedforward, "feedforward", n)?,
        )?;
        Ok(Self { pd })
    }

    /// Number of joints.
    #[getter]
    fn dof(&self) -> usize {
        self.pd.dof()
    }

    /// Proportional gains (N·m/rad), shape (n,).
    #[getter]
    fn kp<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.pd.kp)
    }

    /// Derivative gains (N·m·s/rad), shape (n,).
    #[getter]
    fn kd<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.pd.kd)
    }

    /// Pickle support: the gains and schedules exactly as stored.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let pd = &slf.get().pd;
        let args = PyTuple::new(
            py,
            [
                array1(py, &pd.kp).into_any().unbind(),
                array1(py, &pd.kd).into_any().unbind(),
                schedule_object(py, &pd.theta_ref),
                schedule_object(py, &pd.theta_dot_ref),
                schedule_object(py, &pd.feedforward),
            ],
        )?;
        Ok((slf.get_type().into_any().unbind(), args.into_any().unbind()))
    }

    fn __repr__(&self) -> String {
        format!(
            "MotorPD(dof={}, kp={:?}, kd={:?})",
            self.pd.dof(),
            self.pd.kp,
            self.pd.kd
        )
    }
}

/// The controller of a run from ``u``: an ``orbitflex.MotorPD`` (a copy), a callable
/// ``u(t, x) -> (n,)`` ([`PyCallable`], whose first exception lands in `error`), or a schedule
/// (None, a scalar, (n,) or (steps, n)). `Send`: a run leaves the GIL whatever drives it.
pub(crate) fn controller<'a>(
    u: Option<&Bound<'_, PyAny>>,
    n: usize,
    error: &'a mut Option<PyErr>,
) -> PyResult<Box<dyn Controller + Send + 'a>> {
    Ok(match u.filter(|o| !o.is_none()) {
        Some(obj) if obj.is_instance_of::<PyMotorPD>() => {
            Box::new(obj.downcast::<PyMotorPD>()?.get().pd.clone())
        }
        Some(obj) if obj.is_callable() => Box::new(PyCallable {
            func: obj.clone().unbind(),
            n,
            error,
        }),
        other => Box::new(schedule(other, "u", n)?),
    })
}

/// A Python callable ``(t, x) -> u`` as a [`Controller`], taking the GIL for each call; the first
/// Python exception is kept in `error`.
pub(crate) struct PyCallable<'a> {
    func: Py<PyAny>,
    n: usize,
    error: &'a mut Option<PyErr>,
}

impl Controller for PyCallable<'_> {
    fn output(&mut self, _step: usize, t: f64, x: &[f64], u: &mut [f64]) -> crate::Result<()> {
        let result = Python::with_gil(|py| {
            self.func
                .call1(py, (t, array1(py, x)))
                .and_then(|out| vector(out.bind(py), "u returned by the controller", Some(self.n)))
        });
        match result {
            Ok(values) => {
                u.copy_from_slice(&values);
                Ok(())
            }
            Err(e) => {
                let message = e.to_string();
                *self.error = Some(e);
                Err(Error::InvalidArgument {
                    what: "controller".into(),
                    message,
                })
            }
        }
    }
}
