//! `orbitflex.MotorPD`, input schedules from numpy, and Python callables as controllers.

use super::convert::{array1, as_float_array, matrix, real, row_major, vector};
use super::errors::ModelError;
use super::joints::Param;
use crate::control::{
    quintic_profile, AttitudePD, AttitudeTarget, Controller, MotorPD, Quintic, Sampled, Schedule,
};
use crate::error::Error;
use crate::flex::FlexibleArm;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

/// The wheel-torque channel of a run on `arm` from Python: None (zero), an
/// :class:`AttitudePD` (bound to the arm's wheels), a callable ``(t, x) -> (k,)``, or a schedule
/// of width `k`; anything but None is refused on an arm without wheels.
pub(crate) fn wheel_controller<'a>(
    obj: Option<&Bound<'_, PyAny>>,
    arm: &FlexibleArm,
    error: &'a mut Option<PyErr>,
) -> PyResult<Box<dyn Controller + Send + 'a>> {
    let k = arm.layout().wheels;
    if let Some((inner, rate_hz, delay)) = sampled(obj)? {
        return wrap(wheel_controller(Some(&inner), arm, error)?, rate_hz, delay);
    }
    Ok(match (obj.filter(|o| !o.is_none()), k) {
        (None, _) => Box::new(Schedule::Zero),
        (Some(_), 0) => {
            return Err(ModelError::new_err(
                "wheel_torque: the arm has no reaction wheels; give none (or build the arm with \
                 wheels=)",
            ))
        }
        (Some(obj), _) if obj.is_instance_of::<PyAttitudePD>() => {
            Box::new(obj.downcast::<PyAttitudePD>()?.get().bind(arm)?)
        }
        (Some(obj), k) if obj.is_callable() => Box::new(PyCallable {
            func: obj.clone().unbind(),
            n: k,
            what: "wheel_torque",
            error,
        }),
        (w, k) => Box::new(schedule(w, "wheel_torque", k)?),
    })
}

/// The base-wrench channel from Python: a callable ``(t, x) -> (6,)`` (thrusters, a custom
/// ACS), or a schedule of width 6.
pub(crate) fn base_wrench_controller<'a>(
    obj: Option<&Bound<'_, PyAny>>,
    error: &'a mut Option<PyErr>,
) -> PyResult<Box<dyn Controller + Send + 'a>> {
    if let Some((inner, rate_hz, delay)) = sampled(obj)? {
        return wrap(base_wrench_controller(Some(&inner), error)?, rate_hz, delay);
    }
    Ok(match obj.filter(|o| !o.is_none()) {
        Some(obj) if obj.is_callable() => Box::new(PyCallable {
            func: obj.clone().unbind(),
            n: 6,
            what: "base_wrench",
            error,
        }),
        other => Box::new(schedule(other, "base_wrench", 6)?),
    })
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
    if let Some((inner, rate_hz, delay)) = sampled(u)? {
        return wrap(controller(Some(&inner), n, error)?, rate_hz, delay);
    }
    Ok(match u.filter(|o| !o.is_none()) {
        Some(obj) if obj.is_instance_of::<PyMotorPD>() => {
            Box::new(obj.downcast::<PyMotorPD>()?.get().pd.clone())
        }
        Some(obj) if obj.is_callable() => Box::new(PyCallable {
            func: obj.clone().unbind(),
            n,
            what: "u",
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
    /// The channel it drives (`"u"`, `"wheel_torque"`, `"base_wrench"`), for messages.
    what: &'static str,
    error: &'a mut Option<PyErr>,
}

impl Controller for PyCallable<'_> {
    fn output(&mut self, _step: usize, t: f64, x: &[f64], u: &mut [f64]) -> crate::Result<()> {
        let result = Python::with_gil(|py| {
            self.func.call1(py, (t, array1(py, x))).and_then(|out| {
                let what = format!("{} returned by the controller", self.what);
                vector(out.bind(py), &what, Some(self.n))
            })
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

/// Quaternion-error PD on the bus attitude through its reaction wheels, run inside Rust without
/// the GIL: pass it as ``wheel_torque=`` of ``simulate`` (or ``Plan.track``).
///
/// ``q_e = q_ref* ⊗ q_B`` (the shorter way round), ``e = 2 vec(q_e)`` (rad, base frame), the
/// torque on the bus ``T = −kp e − kd (ω_B − ω_ref)`` (N·m, base frame), and the wheel torques
/// ``u = −allocation · T`` (N·m), saturated by the run (torque, then speed limits).
///
/// - ``kp`` (N·m/rad), ``kd`` (N·m·s/rad): a number or one per base axis (3,), ≥ 0.
/// - ``attitude``: None (hold the bus where it is at the start of the run), a quaternion
///   ``(x, y, z, w)`` (4,), or one per step (steps, 4); ``rate`` (steps, 3, rad/s in the
///   target's frame) goes with a table of attitudes (default zero).
/// - ``allocation`` (k, 3): wheel torques per unit bus torque, any ``M`` with ``A M = 1`` for
///   the axes ``A`` (3, k); None: the minimum-norm pseudo-inverse of the arm's wheel axes, which
///   needs them to span three dimensions (an error naming them otherwise).
#[pyclass(name = "AttitudePD", module = "orbitflex", frozen)]
#[derive(Clone)]
pub struct PyAttitudePD {
    kp: [f64; 3],
    kd: [f64; 3],
    target: AttitudeTarget,
    allocation: Option<(usize, Vec<f64>)>,
}

impl PyAttitudePD {
    /// The controller for `arm`'s wheels.
    pub(crate) fn bind(&self, arm: &FlexibleArm) -> PyResult<AttitudePD> {
        let Some(wheels) = arm.wheels() else {
            return Err(ModelError::new_err(
                "AttitudePD: the arm has no reaction wheels to drive (build it with wheels=)",
            ));
        };
        let allocation = match &self.allocation {
            Some((rows, m)) if *rows != wheels.len() => {
                return Err(ModelError::new_err(format!(
                    "allocation: expected shape ({}, 3) (one row per wheel of the arm), given \
                     shape ({rows}, 3)",
                    wheels.len()
                )))
            }
            Some((_, m)) => m.clone(),
            None => wheels.allocation()?,
        };
        Ok(AttitudePD::new(
            self.kp,
            self.kd,
            self.target.clone(),
            allocation,
        )?)
    }
}

/// A number or a (3,) vector as three gains.
fn three(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<[f64; 3]> {
    let a = as_float_array(obj, what)?;
    let ndim: usize = a.getattr("ndim")?.extract()?;
    let v = if ndim == 0 {
        vec![real(&a, what)?; 3]
    } else {
        vector(&a, what, Some(3))?
    };
    Ok([v[0], v[1], v[2]])
}

#[pymethods]
impl PyAttitudePD {
    #[new]
    #[pyo3(signature = (kp, kd, attitude=None, allocation=None, *, rate=None))]
    fn new(
        kp: &Bound<'_, PyAny>,
        kd: &Bound<'_, PyAny>,
        attitude: Option<&Bound<'_, PyAny>>,
        allocation: Option<&Bound<'_, PyAny>>,
        rate: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let (kp, kd) = (three(kp, "kp")?, three(kd, "kd")?);
        let rate = rate.filter(|o| !o.is_none());
        let target = match attitude.filter(|o| !o.is_none()) {
            None => AttitudeTarget::Initial,
            Some(a) => {
                let a = as_float_array(a, "attitude")?;
                let ndim: usize = a.getattr("ndim")?.extract()?;
                match ndim {
                    1 => {
                        let q = vector(&a, "attitude", Some(4))?;
                        AttitudeTarget::Constant([q[0], q[1], q[2], q[3]])
                    }
                    2 => {
                        let (rows, attitude) = matrix(&a, "attitude", 4)?;
                        let rate = match rate {
                            None => Vec::new(),
                            Some(r) => {
                                let (rate_rows, r) = matrix(r, "rate", 3)?;
                                if rate_rows != rows {
                                    return Err(ModelError::new_err(format!(
                                        "rate: expected shape ({rows}, 3) (one row per \
                                         attitude), given shape ({rate_rows}, 3)"
                                    )));
                                }
                                r
                            }
                        };
                        AttitudeTarget::Table { attitude, rate }
                    }
                    _ => {
                        return Err(ModelError::new_err(format!(
                            "attitude: expected None, shape (4,) or (steps, 4), given a \
                             {ndim}-D array"
                        )))
                    }
                }
            }
        };
        if rate.is_some() && !matches!(target, AttitudeTarget::Table { .. }) {
            return Err(ModelError::new_err(
                "rate: goes with a table of attitudes (steps, 4); a fixed target is at rest",
            ));
        }
        let allocation = match allocation.filter(|o| !o.is_none()) {
            None => None,
            Some(m) => Some(matrix(m, "allocation", 3)?),
        };
        // the checks of the Rust controller, with a stand-in allocation when none is given
        let probe = allocation.as_ref().map_or(vec![0.0; 3], |(_, m)| m.clone());
        AttitudePD::new(kp, kd, target.clone(), probe)?;
        Ok(Self {
            kp,
            kd,
            target,
            allocation,
        })
    }

    /// Proportional gains per base axis (N·m/rad), shape (3,).
    #[getter]
    fn kp<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.kp)
    }

    /// Derivative gains per base axis (N·m·s/rad), shape (3,).
    #[getter]
    fn kd<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.kd)
    }

    /// The allocation given (k, 3), or None for the arm's minimum-norm one.
    #[getter]
    fn allocation(&self, py: Python<'_>) -> PyObject {
        match &self.allocation {
            None => py.None(),
            Some((rows, m)) => row_major(py, *rows, 3, m.clone()).into_any().unbind(),
        }
    }

    /// The wheel torques (k,) this controller commands at state ``x`` of ``arm`` at step
    /// ``step`` (0: the target latches the attitude of ``x`` when it is None), before
    /// saturation.
    #[pyo3(signature = (arm, x, step=0))]
    fn command<'py>(
        &self,
        py: Python<'py>,
        arm: &Bound<'py, super::arm::PyFlexibleArm>,
        x: &Bound<'py, PyAny>,
        step: usize,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let arm = &arm.get().arm;
        let x = vector(x, "x", Some(arm.layout().len()))?;
        let mut pd = self.bind(arm)?;
        if step > 0 {
            if let AttitudeTarget::Initial = pd.target() {
                return Err(ModelError::new_err(
                    "step: an AttitudePD without attitude latches the attitude at step 0; \
                     give step=0 or a target",
                ));
            }
        }
        let mut u = vec![0.0; arm.layout().wheels];
        pd.output(step, 0.0, &x, &mut u)?;
        Ok(array1(py, &u))
    }

    /// Pickle support.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let (attitude, rate) = match &me.target {
            AttitudeTarget::Initial => (py.None(), py.None()),
            AttitudeTarget::Constant(q) => (array1(py, q).into_any().unbind(), py.None()),
            AttitudeTarget::Table { attitude, rate } => (
                row_major(py, attitude.len() / 4, 4, attitude.clone())
                    .into_any()
                    .unbind(),
                if rate.is_empty() {
                    py.None()
                } else {
                    row_major(py, rate.len() / 3, 3, rate.clone())
                        .into_any()
                        .unbind()
                },
            ),
        };
        let kwargs = pyo3::types::PyDict::new(py);
        kwargs.set_item("rate", rate)?;
        let args = PyTuple::new(
            py,
            [
                array1(py, &me.kp).into_any().unbind(),
                array1(py, &me.kd).into_any().unbind(),
                attitude,
                me.allocation(py),
            ],
        )?;
        let functools = py.import("functools")?;
        let partial = functools
            .getattr("partial")?
            .call((slf.get_type(),), Some(&kwargs))?;
        Ok((partial.unbind(), args.into_any().unbind()))
    }

    fn __repr__(&self) -> String {
        let target = match &self.target {
            AttitudeTarget::Initial => "the initial attitude".to_string(),
            AttitudeTarget::Constant(q) => format!("{q:?}"),
            AttitudeTarget::Table { attitude, .. } => format!("{} attitudes", attitude.len() / 4),
        };
        format!(
            "AttitudePD(kp={:?}, kd={:?}, attitude: {target}, allocation: {})",
            self.kp,
            self.kd,
            if self.allocation.is_some() {
                "given"
            } else {
                "minimum-norm"
            }
        )
    }
}

/// Any controller run at its own rate: ``Sampled(controller, rate_hz, delay=0)``, for ``u``,
/// ``wheel_torque`` or ``base_wrench`` (a ``MotorPD``, an ``AttitudePD``, a callable ``(t, x)``
/// or a table).
///
/// Sample ``j`` is due at ``t = j / rate_hz`` (s) and taken at the first RK4 step starting at or
/// after it: the controller is asked for its row there (a callable is called only then), and
/// the row is held until the next sample (zero-order hold). With ``delay = d`` (whole samples)
/// the row computed at sample ``j`` is applied from sample ``j + d`` on, zero before the first
/// arrives. The dynamics keep their RK4 ``dt``; when ``1 / rate_hz`` is a whole number ``m`` of
/// steps the samples fall on steps 0, m, 2m, … exactly. The RK4 stability warning cannot
/// vouch for a sampled loop: it then checks the arm's open loop and says so. ``simulate`` also
/// checks a sampled ``MotorPD`` or ``AttitudePD`` at its rate and delay (the linear model
/// discretised with zero-order hold, :func:`orbitflex.analysis.sampled_loop`) and warns when
/// that discrete loop is unstable.
#[pyclass(name = "Sampled", module = "orbitflex", frozen)]
pub struct PySampled {
    controller: Py<PyAny>,
    rate_hz: f64,
    delay: usize,
}

#[pymethods]
impl PySampled {
    #[new]
    #[pyo3(signature = (controller, rate_hz, delay=0))]
    fn new(
        controller: &Bound<'_, PyAny>,
        rate_hz: &Bound<'_, PyAny>,
        delay: usize,
    ) -> PyResult<Self> {
        let rate_hz = real(rate_hz, "rate_hz")?;
        Sampled::new(Box::new(Schedule::Zero), rate_hz, delay)?;
        if controller.is_none() {
            return Err(ModelError::new_err(
                "controller: expected a controller to sample, given None",
            ));
        }
        Ok(Self {
            controller: controller.clone().unbind(),
            rate_hz,
            delay,
        })
    }

    /// The wrapped controller.
    #[getter]
    fn controller(&self, py: Python<'_>) -> PyObject {
        self.controller.clone_ref(py)
    }

    /// The sample rate (Hz).
    #[getter]
    fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// The delay (whole samples).
    #[getter]
    fn delay(&self) -> usize {
        self.delay
    }

    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let args = PyTuple::new(
            py,
            [
                me.controller.clone_ref(py),
                me.rate_hz.into_pyobject(py)?.into_any().unbind(),
                me.delay.into_pyobject(py)?.into_any().unbind(),
            ],
        )?;
        Ok((slf.get_type().into_any().unbind(), args.into_any().unbind()))
    }

    fn __repr__(&self) -> String {
        format!("Sampled(rate_hz={}, delay={})", self.rate_hz, self.delay)
    }
}

/// The wrapped controller, rate and delay of a ``Sampled``, or None.
pub(crate) fn sampled<'py>(
    obj: Option<&Bound<'py, PyAny>>,
) -> PyResult<Option<(Bound<'py, PyAny>, f64, usize)>> {
    match obj {
        Some(o) if o.is_instance_of::<PySampled>() => {
            let s = o.downcast::<PySampled>()?.get();
            Ok(Some((
                s.controller.bind(o.py()).clone(),
                s.rate_hz,
                s.delay,
            )))
        }
        _ => Ok(None),
    }
}

fn wrap<'a>(
    inner: Box<dyn Controller + Send + 'a>,
    rate_hz: f64,
    delay: usize,
) -> PyResult<Box<dyn Controller + Send + 'a>> {
    Ok(Box::new(Sampled::new(inner, rate_hz, delay)?))
}

/// The quintic rest-to-rest reference of the joints from ``start`` to ``goal`` (rad, (n,)) over
/// ``duration`` seconds, then held at ``goal``, tabulated for ``steps`` steps of ``dt`` (row ``k``
/// at ``t = k·dt``): ``(theta_ref, theta_dot_ref)``, each (steps, n), in rad and rad/s, ready for
/// :class:`MotorPD`. Evaluated in factored form (the same bits on every processor).
#[pyfunction]
#[pyo3(name = "quintic_reference", signature = (start, goal, duration, dt, steps))]
pub(crate) fn py_quintic_reference<'py>(
    py: Python<'py>,
    start: &Bound<'py, PyAny>,
    goal: &Bound<'py, PyAny>,
    duration: &Bound<'py, PyAny>,
    dt: &Bound<'py, PyAny>,
    steps: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let start = vector(start, "start", None)?;
    let goal = vector(goal, "goal", Some(start.len()))?;
    let quintic = Quintic::new(&start, &goal, real(duration, "duration")?)?;
    let steps = super::convert::count(steps, "steps")?;
    let (theta, theta_dot) = quintic.schedules(real(dt, "dt")?, steps)?;
    let shape = [steps, start.len()];
    let array = |s: Schedule| -> PyResult<Bound<'py, PyAny>> {
        let values = match s {
            Schedule::Table { values, .. } => values,
            _ => unreachable!("Quintic::schedules gives tables"),
        };
        Ok(PyArray1::from_vec(py, values).reshape(shape)?.into_any())
    };
    Ok((array(theta)?, array(theta_dot)?))
}

/// The quintic profile ``p(s) = 10s³ − 15s⁴ + 6s⁵`` and ``dp/ds`` at each ``s`` (a 1-D array,
/// clamped to [0, 1]); private, wrapped by ``orbitflex._reference.quintic``.
#[pyfunction]
#[pyo3(name = "_quintic_profile")]
pub(crate) fn py_quintic_profile<'py>(
    py: Python<'py>,
    s: &Bound<'py, PyAny>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let s = vector(s, "s", None)?;
    let (p, dp): (Vec<f64>, Vec<f64>) = s.iter().map(|&s| quintic_profile(s)).unzip();
    let array = |v| PyArray1::from_vec(py, v).into_any();
    Ok((array(p), array(dp)))
}
