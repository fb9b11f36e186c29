//! `orbitflex.Limits`, `orbitflex.plan_slew` and `orbitflex.Plan`: minimum-time rest-to-rest
//! slews under motor-torque, joint-speed and base-actuation limits, and their tracking.

use super::arm::PyFlexibleArm;
use super::control::wheel_controller;
use super::convert::{array1, as_float_array, count, matrix, real, row_major, vector};
use super::errors::{simulation_error, LimitWarning, ModelError};
use super::joints::Param;
use super::robot::PyRobot;
use super::run::{run_releasing_gil, watched, Channels, Progress};
use super::trajectory::{freeze, PyTrajectory};
use crate::args::number;
use crate::control::Schedule;
use crate::error::Error;
use crate::integrate::Run;
use crate::planning::{
    plan_slew_watched, BaseLimits, BaseMode, BasePoint, Binding, Limits, Plan, Reference, Samples,
    Tracking, TrackingSetup,
};
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::sync::atomic::AtomicBool;

/// A per-joint limit: a number (every joint) or one value per joint. Unlike [`Param::parse`],
/// non-finite values pass here, so that [`Limits::new`] names them with the rule they break.
fn limit_values(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<(Vec<f64>, bool)> {
    let array = as_float_array(obj, what)?;
    let shape: Vec<usize> = array.getattr("shape")?.extract()?;
    match shape.len() {
        0 => Ok((vec![real(obj, what)?], true)),
        1 => {
            let values = array.extract::<numpy::PyReadonlyArray1<f64>>()?;
            Ok((values.as_array().to_vec(), false))
        }
        _ => Err(ModelError::new_err(format!(
            "{what}: expected a number or a 1-D array (one value per joint), given shape {shape:?}"
        ))),
    }
}

/// An optional bound per base axis: None, a number (every axis) or three (x, y, z; checked by
/// [`BaseLimits::check`]).
fn optional_axes(obj: Option<&Bound<'_, PyAny>>, what: &str) -> PyResult<Option<[f64; 3]>> {
    let Some(o) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let a = super::convert::as_float_array(o, what)?;
    let ndim: usize = a.getattr("ndim")?.extract()?;
    let v = if ndim == 0 {
        vec![real(&a, what)?; 3]
    } else {
        super::convert::vector(&a, what, Some(3))?
    };
    Ok(Some([v[0], v[1], v[2]]))
}

/// An optional scalar bound: None, or a real number (checked by [`Limits::new`]).
fn optional_bound(obj: Option<&Bound<'_, PyAny>>, what: &str) -> PyResult<Option<f64>> {
    match obj {
        Some(o) if !o.is_none() => Ok(Some(real(o, what)?)),
        _ => Ok(None),
    }
}

/// Bounds for :func:`plan_slew`, all link side and in SI units.
///
/// ``Limits(motor_torque, joint_speed, base_force=None, base_torque=None)``:
///
/// - ``motor_torque``: ``|u_i| ≤ motor_torque_i`` (N·m), the motor torque seen at the link
///   (after the gearbox); a number for every joint or one value per joint.
/// - ``joint_speed``: ``|q̇_i| ≤ joint_speed_i`` (rad/s), the link rate; a number or one value
///   per joint.
/// - ``base_force``: ``|F_B| ≤ base_force`` (N), the Euclidean norm of the force the base's
///   actuators apply (base frame); None: unbounded. Applies to a held base only.
/// - ``base_torque``: ``|n_B| ≤ base_torque`` (N·m), the norm of their moment about the base
///   origin; None: unbounded. Applies to a held base only.
/// - per base axis (base frame, x, y, z; a number for every axis or three): held base,
///   ``base_torque_axes`` ``|n_B,k|`` (N·m, about the base origin) and ``base_force_axes``
///   ``|F_B,k|`` (N); free base, ``base_rate_axes`` ``|ω_B,k|`` (rad/s) and
///   ``base_speed_axes`` ``|v_B,k|`` (m/s, the velocity of the base origin).
/// - free base by norm: ``base_rate`` ``|ω_B|`` (rad/s) and ``base_speed`` ``|v_B|`` (m/s).
/// - ``base_point``: ``"origin"`` (default) or ``"com"``, the point a held base's moment bounds
///   (``base_torque``, ``base_torque_axes``) are taken about. About the system centre of mass
///   the moment is ``n_C = n_B − r_c(q) × F_B``, ``r_c`` the COM relative to the base origin
///   (base frame). A free-floating plan refuses ``"com"``: its rates are the same about every
///   point and, from rest, the COM stays still, so it would bound what ``"origin"`` does.
///
/// Every value must be finite and > 0. Per-joint lengths are checked against the arm when a slew
/// is planned.
#[pyclass(name = "Limits", module = "orbitflex", frozen)]
#[derive(Clone)]
pub struct PyLimits {
    pub(crate) limits: Limits,
    /// Whether motor_torque / joint_speed were given as one number (returned as a float).
    scalar: [bool; 2],
}

impl PyLimits {
    pub(crate) fn from_rust(limits: Limits) -> Self {
        Self {
            limits,
            scalar: [false; 2],
        }
    }

    fn values(&self, py: Python<'_>, which: usize) -> PyObject {
        let v = if which == 0 {
            &self.limits.motor_torque
        } else {
            &self.limits.joint_speed
        };
        if self.scalar[which] {
            v[0].into_pyobject(py).expect("a float").into_any().unbind()
        } else {
            array1(py, v).into_any().unbind()
        }
    }
}

#[pymethods]
impl PyLimits {
    #[new]
    #[pyo3(signature = (motor_torque, joint_speed, base_force=None, base_torque=None, base_torque_axes=None, base_force_axes=None, base_rate=None, base_rate_axes=None, base_speed=None, base_speed_axes=None, base_point="origin"))]
    fn new(
        motor_torque: &Bound<'_, PyAny>,
        joint_speed: &Bound<'_, PyAny>,
        base_force: Option<&Bound<'_, PyAny>>,
        base_torque: Option<&Bound<'_, PyAny>>,
        base_torque_axes: Option<&Bound<'_, PyAny>>,
        base_force_axes: Option<&Bound<'_, PyAny>>,
        base_rate: Option<&Bound<'_, PyAny>>,
        base_rate_axes: Option<&Bound<'_, PyAny>>,
        base_speed: Option<&Bound<'_, PyAny>>,
        base_speed_axes: Option<&Bound<'_, PyAny>>,
        base_point: &str,
    ) -> PyResult<Self> {
        let (torque, torque_scalar) = limit_values(motor_torque, "motor_torque")?;
        let (speed, speed_scalar) = limit_values(joint_speed, "joint_speed")?;
        let axes = BaseLimits {
            torque: optional_axes(base_torque_axes, "base_torque_axes")?,
            force: optional_axes(base_force_axes, "base_force_axes")?,
            rate: optional_axes(base_rate_axes, "base_rate_axes")?,
            speed: optional_axes(base_speed_axes, "base_speed_axes")?,
            rate_norm: optional_bound(base_rate, "base_rate")?,
            speed_norm: optional_bound(base_speed, "base_speed")?,
            point: BasePoint::from_name(base_point)?,
        };
        let limits = Limits::new(
            torque,
            speed,
            optional_bound(base_force, "base_force")?,
            optional_bound(base_torque, "base_torque")?,
        )?
        .with_base_axes(axes)?;
        Ok(Self {
            limits,
            scalar: [torque_scalar, speed_scalar],
        })
    }

    /// The limits ``robot``'s model states (its URDF's ``<limit effort velocity>``, per joint):
    /// the effort becomes the motor torque at the link (``motor_torque``, N·m, after the
    /// gearbox), the velocity the joint speed (``joint_speed``, rad/s). ``base_force`` and
    /// ``base_torque`` as in the constructor. Raises ``ModelError`` naming every joint whose
    /// model states no such limit (or a zero one).
    #[staticmethod]
    #[pyo3(signature = (robot, base_force=None, base_torque=None))]
    fn from_urdf(
        robot: &Bound<'_, PyRobot>,
        base_force: Option<&Bound<'_, PyAny>>,
        base_torque: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let limits = Limits::from_robot(
            &robot.get().robot,
            optional_bound(base_force, "base_force")?,
            optional_bound(base_torque, "base_torque")?,
        )?;
        Ok(Self::from_rust(limits))
    }

    /// ``|u_i|`` bound (N·m, link side): a float (every joint) or an array (one per joint).
    #[getter]
    fn motor_torque(&self, py: Python<'_>) -> PyObject {
        self.values(py, 0)
    }
    /// ``|q̇_i|`` bound (rad/s): a float (every joint) or an array (one per joint).
    #[getter]
    fn joint_speed(&self, py: Python<'_>) -> PyObject {
        self.values(py, 1)
    }
    /// ``|F_B|`` bound (N), or None (unbounded); a held base only.
    #[getter]
    fn base_force(&self) -> Option<f64> {
        self.limits.base_force
    }
    /// ``|n_B|`` bound (N·m, about the base origin), or None (unbounded); a held base only.
    #[getter]
    fn base_torque(&self) -> Option<f64> {
        self.limits.base_torque
    }

    /// ``|n_B,k|`` bounds (N·m, about the base origin, base frame), (3,), or None; held base.
    #[getter]
    fn base_torque_axes(&self) -> Option<[f64; 3]> {
        self.limits.base_axes.torque
    }
    /// ``|F_B,k|`` bounds (N, base frame), (3,), or None; held base.
    #[getter]
    fn base_force_axes(&self) -> Option<[f64; 3]> {
        self.limits.base_axes.force
    }
    /// ``|ω_B|`` bound (rad/s), or None; free base.
    #[getter]
    fn base_rate(&self) -> Option<f64> {
        self.limits.base_axes.rate_norm
    }
    /// ``|ω_B,k|`` bounds (rad/s, base frame), (3,), or None; free base.
    #[getter]
    fn base_rate_axes(&self) -> Option<[f64; 3]> {
        self.limits.base_axes.rate
    }
    /// ``|v_B|`` bound (m/s, the base origin's velocity), or None; free base.
    #[getter]
    fn base_speed(&self) -> Option<f64> {
        self.limits.base_axes.speed_norm
    }
    /// ``|v_B,k|`` bounds (m/s, base frame), (3,), or None; free base.
    #[getter]
    fn base_speed_axes(&self) -> Option<[f64; 3]> {
        self.limits.base_axes.speed
    }
    /// ``"origin"`` or ``"com"``: the point the held moment bounds (``base_torque``,
    /// ``base_torque_axes``) are taken about.
    #[getter]
    fn base_point(&self) -> &'static str {
        self.limits.base_axes.point.name()
    }

    /// Pickle support.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let b = &me.limits.base_axes;
        let args = (
            me.values(py, 0),
            me.values(py, 1),
            me.limits.base_force,
            me.limits.base_torque,
            b.torque,
            b.force,
            b.rate_norm,
            b.rate,
            b.speed_norm,
            b.speed,
            b.point.name(),
        );
        Ok((
            slf.get_type().into_any().unbind(),
            args.into_pyobject(py)?.into_any().unbind(),
        ))
    }

    fn __repr__(&self) -> String {
        let show = |v: &Vec<f64>, scalar: bool| {
            if scalar {
                format!("{:?}", v[0])
            } else {
                format!("{v:?}")
            }
        };
        let bound = |b: Option<f64>| b.map_or("None".to_string(), |v| format!("{v:?}"));
        let b = &self.limits.base_axes;
        let extra: String = [
            ("base_torque_axes", b.torque.map(|v| format!("{v:?}"))),
            ("base_force_axes", b.force.map(|v| format!("{v:?}"))),
            ("base_rate", b.rate_norm.map(|v| format!("{v:?}"))),
            ("base_rate_axes", b.rate.map(|v| format!("{v:?}"))),
            ("base_speed", b.speed_norm.map(|v| format!("{v:?}"))),
            ("base_speed_axes", b.speed.map(|v| format!("{v:?}"))),
            (
                "base_point",
                (b.point != BasePoint::Origin).then(|| format!("{:?}", b.point.name())),
            ),
        ]
        .iter()
        .filter_map(|(name, v)| v.as_ref().map(|v| format!(", {name}={v}")))
        .collect();
        format!(
            "Limits(motor_torque={}, joint_speed={}, base_force={}, base_torque={}{extra})",
            show(&self.limits.motor_torque, self.scalar[0]),
            show(&self.limits.joint_speed, self.scalar[1]),
            bound(self.limits.base_force),
            bound(self.limits.base_torque)
        )
    }
}

/// The sampled arrays of a plan, read-only.
struct SampleArrays {
    t: Py<PyArray1<f64>>,
    /// `(name, rows × width)` in the order of [`SAMPLE_NAMES`].
    tables: Vec<Py<PyArray2<f64>>>,
}

const SAMPLE_NAMES: [&str; 10] = [
    "q",
    "qd",
    "qdd",
    "theta",
    "theta_dot",
    "u",
    "tau",
    "base_wrench",
    "base_twist",
    "base_pose",
];

impl SampleArrays {
    fn new(py: Python<'_>, n: usize, s: Samples) -> PyResult<Self> {
        let rows = s.t.len();
        let t = PyArray1::from_vec(py, s.t);
        freeze(t.as_any())?;
        let columns = [
            (s.q, n),
            (s.qd, n),
            (s.qdd, n),
            (s.theta, n),
            (s.theta_dot, n),
            (s.u, n),
            (s.tau, n),
            (s.base_wrench, 6),
            (s.base_twist, 6),
            (s.base_pose, 7),
        ];
        let mut tables = Vec::with_capacity(columns.len());
        for (values, width) in columns {
            let a = row_major(py, rows, width, values);
            freeze(a.as_any())?;
            tables.push(a.unbind());
        }
        Ok(Self {
            t: t.unbind(),
            tables,
        })
    }
}

/// A planned slew ([`plan_slew`]): its samples, duration and binding limit.
///
/// Frames and units: joint quantities are link side, one column per joint in the arm's order
/// (``arm.robot.joint_names``): ``q``, ``theta`` (rad), ``qd``, ``theta_dot`` (rad/s), ``qdd``
/// (rad/s²), ``u`` (motor torque) and ``tau`` (spring torque ``k (θ − q) + d (θ̇ − q̇)``, N·m).
/// Base quantities are ``[angular; linear]`` in the base frame: ``base_wrench`` ``[n_B (N·m,
/// about the base origin); F_B (N)]`` applied to the base by its actuators (zero for a free
/// base), ``base_twist`` ``[ω_B (rad/s); v_B (m/s)]`` (zero for a held base); ``base_pose``
/// ``[r_B (m, inertial); quat_B (x, y, z, w)]``, starting at the origin with identity attitude.
///
/// The sample arrays (``t`` and the tables, one row per sample) are read-only; samples are
/// denser near the peaks that bind. :meth:`evaluate` computes any instant afresh.
#[pyclass(name = "Plan", module = "orbitflex", frozen)]
pub struct PyPlan {
    plan: Plan,
    arm: Py<PyFlexibleArm>,
    samples: SampleArrays,
}

/// Plans in Rust without the GIL and wraps the result; Ctrl-C sets the flag `solve` is given,
/// and is raised as `KeyboardInterrupt`.
fn wrap(
    py: Python<'_>,
    arm: Py<PyFlexibleArm>,
    solve: impl FnOnce(&AtomicBool) -> crate::Result<Plan> + Send,
) -> PyResult<PyPlan> {
    let cancel = AtomicBool::new(false);
    let (plan, samples) = watched(
        py,
        &cancel,
        |_| Ok(()),
        || {
            let plan = solve(&cancel)?;
            let samples = plan.samples();
            Ok::<_, Error>((plan, samples))
        },
    )??;
    let n = plan.arm().dof();
    Ok(PyPlan {
        plan,
        arm,
        samples: SampleArrays::new(py, n, samples)?,
    })
}

/// The waypoints argument: None, or (m, n) (a list of m waypoints, each n angles).
fn waypoint_rows(obj: Option<&Bound<'_, PyAny>>, n: usize) -> PyResult<Vec<Vec<f64>>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Vec::new());
    };
    let array = as_float_array(obj, "waypoints")?;
    let shape: Vec<usize> = array.getattr("shape")?.extract()?;
    match shape.as_slice() {
        [0] => Ok(Vec::new()),
        [len] => Err(ModelError::new_err(format!(
            "waypoints: expected a list of waypoints, shape (m, {n}), given a 1-D array of \
             length {len}; wrap a single waypoint in a list: waypoints=[q]"
        ))),
        _ => {
            let (_, values) = matrix(&array, "waypoints", n)?;
            Ok(values.chunks_exact(n).map(<[f64]>::to_vec).collect())
        }
    }
}

/// A binding limit as a dict.
fn binding_dict<'py>(py: Python<'py>, b: &Binding, names: &[&str]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("limit", b.constraint.name())?;
    d.set_item("joint", b.joint)?;
    d.set_item("joint_name", b.joint.map(|j| names[j]))?;
    d.set_item("axis", b.axis)?;
    d.set_item("point", b.point.map(BasePoint::name))?;
    d.set_item("segment", b.segment)?;
    d.set_item("time", b.time)?;
    d.set_item("value", b.value)?;
    d.set_item("bound", b.limit)?;
    Ok(d)
}

/// Bytes of `steps` rows of `width` f64 values, if they fit in the memory available.
fn check_steps(what: &str, steps: usize, width: usize) -> PyResult<()> {
    let bytes = steps.checked_mul(width).and_then(|v| v.checked_mul(8));
    let available = crate::io::available_memory();
    let fits = match (bytes, available) {
        (None, _) => false,
        (Some(b), Some(a)) => (b as u64) <= a,
        (Some(b), None) => b <= isize::MAX as usize,
    };
    if fits {
        return Ok(());
    }
    Err(ModelError::new_err(format!(
        "{what}: {steps} steps of {width} values each need {}, more than the {} available; \
         lengthen dt or ask for fewer steps",
        crate::args::describe_bytes(bytes),
        available.map_or("memory".into(), |a| crate::args::describe_bytes(Some(
            a as usize
        )))
    )))
}

/// The number of steps of `dt` that cover `seconds`, or an error naming `dt` when it is absurd.
fn covering_steps(seconds: f64, dt: f64) -> PyResult<usize> {
    crate::args::check_dt(dt)?;
    let steps = (seconds / dt).ceil();
    if steps.is_nan() || steps >= 1e15 {
        return Err(ModelError::new_err(format!(
            "dt: {} s makes {steps:.3e} steps of {} s; lengthen dt",
            number(dt),
            rounded(seconds, 6)
        )));
    }
    Ok(steps as usize)
}

/// For a long computation without the GIL: false (stop) once a signal handler raised, keeping
/// its exception (`KeyboardInterrupt` for Ctrl-C) in `pending`.
fn keep_going(pending: &mut Option<PyErr>) -> bool {
    Python::with_gil(|py| match py.check_signals() {
        Ok(()) => true,
        Err(e) => {
            *pending = Some(e);
            false
        }
    })
}

/// A computed time for a message or repr: `decimals` decimals in the usual range, else three
/// significant digits in exponent form.
fn rounded(seconds: f64, decimals: usize) -> String {
    if (1e-3..1e6).contains(&seconds) {
        format!("{seconds:.decimals$}")
    } else {
        format!("{seconds:.3e}")
    }
}

/// The arguments of ``Plan.track``, read in this order (the first bad one is reported).
struct TrackingArgs {
    dt: f64,
    kp: Vec<f64>,
    kd: Vec<f64>,
    settle: f64,
}

impl TrackingArgs {
    /// Reads them and refuses, before the tables are built, a run too long for memory.
    fn parse(
        plan: &Plan,
        dt: &Bound<'_, PyAny>,
        kp: &Bound<'_, PyAny>,
        kd: &Bound<'_, PyAny>,
        settle: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let n = plan.arm().dof();
        let dt = real(dt, "dt")?;
        let settle = match settle.filter(|s| !s.is_none()) {
            Some(s) => real(s, "settle")?,
            None => 2.0,
        };
        if !(settle.is_finite() && settle >= 0.0) {
            return Err(ModelError::new_err(format!(
                "settle: expected a finite time >= 0 (s), given {settle}"
            )));
        }
        let (kp, kd) = (gains(kp, "kp", n)?, gains(kd, "kd", n)?);
        crate::args::check_dt(dt)?;
        // refuse a run too long for memory before its tables are built
        let seconds = plan.duration() + settle;
        let steps = (seconds / dt).ceil();
        let blame = if settle > plan.duration() {
            "settle"
        } else {
            "dt"
        };
        if steps >= 1e15 {
            return Err(ModelError::new_err(format!(
                "{blame}: dt = {} s over the plan's {} s plus settle = {} s makes {steps:.3e} \
                 steps; lengthen dt or shorten settle",
                number(dt),
                rounded(plan.duration(), 6),
                number(settle)
            )));
        }
        let layout = plan.arm().layout();
        check_steps(blame, steps as usize, 2 * layout.len() + 4 * n + 13)?;
        Ok(Self { dt, kp, kd, settle })
    }
}

/// Runs the tracking of `plan` set up by `setup` (its arm from its initial state, the setup's
/// steps of `dt`, its PD and wrenches), or with ``wheel_torque`` driving the wheels in place of
/// the base wrench: the trajectory and the setup's reference; a failure is the
/// `SimulationError` carrying what was computed.
fn run_tracking(
    py: Python<'_>,
    plan: &Plan,
    arm: &Py<PyFlexibleArm>,
    dt: f64,
    setup: TrackingSetup,
    wheel_torque: Option<&Bound<'_, PyAny>>,
) -> PyResult<(crate::integrate::Trajectory, crate::planning::Reference)> {
    let TrackingSetup {
        steps,
        reference,
        pd,
        wrenches,
    } = setup;
    let x0 = plan.initial_state();
    let mut error = None;
    let mut channels = match wheel_torque {
        None => Channels {
            u: Box::new(pd),
            base_wrench: Box::new(wrenches.base),
            ee_wrench: wrenches.ee,
            wheel_torque: Box::new(wrenches.wheel_torque),
        },
        // the wheels hold the bus instead of the plan's wrench
        Some(w) => Channels {
            u: Box::new(pd),
            base_wrench: Box::new(Schedule::Zero),
            ee_wrench: wrenches.ee,
            wheel_torque: wheel_controller(Some(w), plan.arm(), &mut error)?,
        },
    };
    let run = run_releasing_gil(
        py,
        plan.arm(),
        &Run::new(&x0, dt, steps),
        &mut channels,
        &mut Progress::new(None),
    )?;
    drop(channels);
    match run {
        Ok(trajectory) => Ok((trajectory, reference)),
        Err(failure) => {
            let (message, step, time) = match &failure.error {
                Error::Simulation { step, time, .. } => (failure.error.to_string(), *step, *time),
                other => return Err(other.clone().into()),
            };
            let traj = PyTrajectory::from_run(py, arm.clone_ref(py), failure.trajectory)?;
            let traj = Py::new(py, traj)?.into_any();
            Err(simulation_error(py, message, step, time, traj, error)?)
        }
    }
}

/// What ``Plan.track`` returns: the trajectory (on `arm`), the reference and the measures.
fn tracking_dict(
    py: Python<'_>,
    arm: Py<PyFlexibleArm>,
    tracking: Tracking,
    n: usize,
) -> PyResult<Bound<'_, PyDict>> {
    let Tracking {
        trajectory,
        reference,
        slew_end,
        peak_motor_torque,
        tracking_error,
        residual_deflection,
        residual_link_error,
        base_position_error,
        base_attitude_error,
    } = tracking;
    let d = PyDict::new(py);
    let traj = PyTrajectory::from_run(py, arm, trajectory)?;
    d.set_item("trajectory", Py::new(py, traj)?)?;
    d.set_item("reference", reference_dict(py, reference, n)?)?;
    d.set_item("slew_end", slew_end)?;
    d.set_item("peak_motor_torque", array1(py, &peak_motor_torque))?;
    d.set_item("tracking_error", tracking_error)?;
    d.set_item("residual_deflection", residual_deflection)?;
    d.set_item("residual_link_error", residual_link_error)?;
    d.set_item("base_position_error", base_position_error)?;
    d.set_item("base_attitude_error", base_attitude_error)?;
    Ok(d)
}

/// Gains for the tracking PD: a number or one per joint, checked against `n`.
fn gains(obj: &Bound<'_, PyAny>, what: &str, n: usize) -> PyResult<Vec<f64>> {
    let p = Param::parse(obj, what)?;
    if let Some(len) = p.len().filter(|&len| len != n) {
        return Err(ModelError::new_err(format!(
            "{what}: expected a number or length {n} (one per joint), given length {len}"
        )));
    }
    Ok(p.resolve(n))
}

/// The reference tables as a dict of (steps, width) per-step arrays, the (steps + 1, width)
/// planned states `q` and `base_pose`, and their times `t` (steps + 1,).
fn reference_dict<'py>(py: Python<'py>, r: Reference, n: usize) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let t: Vec<f64> = (0..=r.steps).map(|k| k as f64 * r.dt).collect();
    d.set_item("t", PyArray1::from_vec(py, t))?;
    d.set_item("u", row_major(py, r.steps, n, r.u))?;
    d.set_item("theta_ref", row_major(py, r.steps, n, r.theta_ref))?;
    d.set_item("theta_dot_ref", row_major(py, r.steps, n, r.theta_dot_ref))?;
    d.set_item("base_wrench", row_major(py, r.steps, 6, r.base_wrench))?;
    d.set_item("q", row_major(py, r.steps + 1, n, r.q))?;
    d.set_item("base_pose", row_major(py, r.steps + 1, 7, r.base_pose))?;
    Ok(d)
}

impl PyPlan {
    fn table(&self, py: Python<'_>, name: &str) -> Py<PyArray2<f64>> {
        let k = SAMPLE_NAMES
            .iter()
            .position(|s| *s == name)
            .expect("a sample table");
        self.samples.tables[k].clone_ref(py)
    }

    fn joint_names(&self) -> Vec<&str> {
        self.plan.arm().robot().joint_names()
    }
}

#[pymethods]
impl PyPlan {
    /// Total duration (s).
    #[getter]
    fn duration(&self) -> f64 {
        self.plan.duration()
    }
    /// Each segment's duration (s): one segment per waypoint, plus one.
    #[getter]
    fn segment_durations<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.plan.segment_durations())
    }
    /// The limit that sets the duration of the longest segment (each segment's is in
    /// :attr:`bindings`): a dict ``{"limit": "motor_torque" | "joint_speed" |
    /// "base_force" | "base_torque" | "base_torque_axes" | "base_force_axes" | "base_rate" |
    /// "base_rate_axes" | "base_speed" | "base_speed_axes", "joint": index (0-based) or None,
    /// "joint_name": str or None, "axis": the base axis (0, 1, 2 for x, y, z) of a per-axis
    /// limit or None, "point": ``"origin"`` or ``"com"`` for a moment limit (else None), "segment": index, "time": when it peaks (s from the start), "value": the peak
    /// (magnitude; N·m, rad/s or N), "bound": the limit}``.
    #[getter]
    fn binding<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        binding_dict(py, self.plan.binding(), &self.joint_names())
    }
    /// The binding limit of each segment (dicts as :attr:`binding`).
    #[getter]
    fn bindings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let names = self.joint_names();
        let items = self
            .plan
            .bindings()
            .iter()
            .map(|b| binding_dict(py, b, &names))
            .collect::<PyResult<Vec<_>>>()?;
        PyList::new(py, items)
    }
    /// ``"held"`` (the base's actuators hold it inertially still) or ``"free"`` (free floating
    /// from rest, zero momentum).
    #[getter]
    fn base(&self) -> &'static str {
        self.plan.base().name()
    }
    /// Whether this is the rigid-joint plan (:meth:`rigid`).
    #[getter]
    fn is_rigid(&self) -> bool {
        self.plan.is_rigid()
    }
    /// The limits planned for, one value per joint.
    #[getter]
    fn limits(&self) -> PyLimits {
        PyLimits::from_rust(self.plan.limits().clone())
    }
    /// The arm planned for.
    #[getter]
    fn arm(&self, py: Python<'_>) -> Py<PyFlexibleArm> {
        self.arm.clone_ref(py)
    }
    /// The stops, (m + 2, n) (rad): start, waypoints, goal.
    #[getter]
    fn stops<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let stops = self.plan.stops();
        let n = self.plan.arm().dof();
        row_major(py, stops.len(), n, stops.concat())
    }
    /// Sample times (s), (k,).
    #[getter]
    fn t(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.samples.t.clone_ref(py)
    }
    /// Link angles ``q`` (rad), (k, n).
    #[getter]
    fn q(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "q")
    }
    /// Link rates ``q̇`` (rad/s), (k, n).
    #[getter]
    fn qd(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "qd")
    }
    /// Link accelerations ``q̈`` (rad/s²), (k, n).
    #[getter]
    fn qdd(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "qdd")
    }
    /// Motor angles ``θ = q + δ`` (rad, link side), (k, n); zero deflection for a rigid plan.
    #[getter]
    fn theta(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "theta")
    }
    /// Motor rates ``θ̇`` (rad/s, link side), (k, n).
    #[getter]
    fn theta_dot(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "theta_dot")
    }
    /// Motor torques ``u = j θ̈ + β θ̇ + τ`` (N·m, link side), (k, n): the feedforward.
    #[getter]
    fn u(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "u")
    }
    /// Spring torques ``τ`` acting on the links (N·m), (k, n): the rigid inverse dynamics.
    #[getter]
    fn tau(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "tau")
    }
    /// ``[n_B (N·m, about the base origin); F_B (N)]`` the base's actuators apply, base frame,
    /// (k, 6); zero for a free base.
    #[getter]
    fn base_wrench(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "base_wrench")
    }
    /// ``[ω_B (rad/s); v_B (m/s)]``, base frame, (k, 6); zero for a held base.
    #[getter]
    fn base_twist(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "base_twist")
    }
    /// ``[r_B (m); quat_B (x, y, z, w)]``, inertial frame, (k, 7); from the origin with
    /// identity attitude (constant for a held base).
    #[getter]
    fn base_pose(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.table(py, "base_pose")
    }

    /// Everything at time ``t`` (s) computed afresh from the inverse dynamics (not interpolated;
    /// the deflection of damped joints is integrated exactly from a sample at least 1/1024 of
    /// the segment earlier): a dict of
    /// ``t`` and arrays ``q``, ``qd``, ``qdd``, ``theta``, ``deflection`` (``θ − q`` at full
    /// precision, rad: what :meth:`FlexibleArm.inverse_dynamics` takes for damped joints),
    /// ``theta_dot``, ``theta_ddot``, ``u``, ``tau`` (n each, units as the class docstring),
    /// ``base_twist``, the classical
    /// ``base_acc`` ``[ω̇_B; v̇_B + ω_B × v_B]`` (rad/s², m/s²) and ``base_wrench`` (6 each,
    /// base frame). Before the start the arm rests at the first stop. After the end the links
    /// rest at the goal; a damped joint's deflection keeps decaying (``e^{−k t/d}``), so its
    /// ``theta``, ``theta_dot`` and ``u`` still change.
    fn evaluate<'py>(
        &self,
        py: Python<'py>,
        t: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let t = real(t, "t")?;
        let p = self.plan.evaluate(t)?;
        let d = PyDict::new(py);
        d.set_item("t", p.t)?;
        for (name, v) in [
            ("q", &p.q),
            ("qd", &p.qd),
            ("qdd", &p.qdd),
            ("theta", &p.flexible.theta),
            ("deflection", &p.deflection),
            ("theta_dot", &p.flexible.theta_dot),
            ("theta_ddot", &p.flexible.theta_ddot),
            ("u", &p.flexible.u),
            ("tau", &p.flexible.tau),
        ] {
            d.set_item(name, array1(py, v))?;
        }
        d.set_item("base_twist", array1(py, &p.flexible.base_twist))?;
        d.set_item("base_acc", array1(py, &p.flexible.base_acc))?;
        d.set_item("base_wrench", array1(py, &p.flexible.base_wrench))?;
        Ok(d)
    }

    /// The state (13+4n,) a run of this plan starts from: ``q = θ =`` the start, at rest, base
    /// at the origin with identity attitude.
    fn initial_state<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.plan.initial_state())
    }

    /// Per-step tables for ``arm.simulate`` with steps of ``dt`` (s): ``steps`` rows (default:
    /// enough to cover the plan; more steps hold the goal at rest), row ``k`` for the step from
    /// ``k dt`` to ``(k+1) dt``. A dict of ``"u"`` (steps, n): the feedforward motor torque
    /// (the plan's ``u`` averaged over the step, N·m); ``"theta_ref"``, ``"theta_dot_ref"``
    /// (steps, n): ``θ`` (rad) and ``θ̇`` (rad/s) at the step's start, for a ``MotorPD``;
    /// ``"base_wrench"`` (steps, 6): the wrench (averaged) that holds a held base, zero for a
    /// free one; ``"q"`` (steps + 1, n) and ``"base_pose"`` (steps + 1, 7): the planned link
    /// angles and base pose at every state time of the run, as in its :class:`Trajectory`, to
    /// measure tracking; ``"t"`` (steps + 1,): those times ``k dt`` (s), so row ``k`` of the
    /// per-step tables spans ``t[k]`` to ``t[k+1]``.
    ///
    /// ``MotorPD(kp, kd, r["theta_ref"], r["theta_dot_ref"], r["u"])`` with
    /// ``base_wrench=r["base_wrench"]`` runs it (:meth:`track` does that).
    #[pyo3(signature = (dt, steps=None))]
    fn reference<'py>(
        &self,
        py: Python<'py>,
        dt: &Bound<'py, PyAny>,
        steps: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let dt = real(dt, "dt")?;
        crate::args::check_dt(dt)?;
        let steps_given = steps.is_some_and(|s| !s.is_none());
        let steps = match steps.filter(|s| !s.is_none()) {
            Some(s) => count(s, "steps")?,
            None => covering_steps(self.plan.duration(), dt)?,
        };
        let n = self.plan.arm().dof();
        let blame = if steps_given { "steps" } else { "dt" };
        check_steps(blame, steps, 4 * n + 13)?;
        let plan = &self.plan;
        let mut interrupt = None;
        let r = py.allow_threads(|| {
            plan.reference_with(dt, Some(steps), &mut |_| keep_going(&mut interrupt))
        })?;
        let Some(r) = r else {
            return Err(interrupt.expect("stopped only on a pending exception"));
        };
        reference_dict(py, r, n)
    }

    /// The same slew planned as if the joints were rigid (``θ = q``, ``u = j q̈ + β q̇ + τ``),
    /// under the same limits and base mode: what a planner that ignores joint flexibility makes.
    fn rigid(&self, py: Python<'_>) -> PyResult<PyPlan> {
        let plan = &self.plan;
        wrap(py, self.arm.clone_ref(py), |cancel| {
            plan.rigid_watched(cancel)
        })
    }

    /// Simulates the plan on its arm (the flexible one, also for a rigid plan) from
    /// :meth:`initial_state` with RK4 steps of ``dt`` (s) for the slew plus ``settle`` s at
    /// rest: a motor PD with gains ``kp`` (N·m/rad) and ``kd`` (N·m·s/rad) (numbers or one per
    /// joint) around :meth:`reference`'s ``theta_ref``, ``theta_dot_ref``, with its feedforward
    /// ``u`` and, for a held base, its base wrench.
    ///
    /// Returns a dict: ``"trajectory"`` (the ``Trajectory``), ``"reference"`` (the tables, as
    /// :meth:`reference`), ``"slew_end"`` (s), ``"peak_motor_torque"`` (n,): ``max |u_i|``
    /// commanded (feedforward + PD, N·m), ``"tracking_error"``: ``max |q − q_plan|`` over the
    /// run (rad), ``"residual_deflection"``: after the slew, ``max |θ − q|`` (rad, the residual
    /// vibration), ``"residual_link_error"``: after the slew, ``max |q − q_goal|`` (rad),
    /// ``"base_position_error"`` (m) and ``"base_attitude_error"`` (rad): the largest departure
    /// of the base from the plan's pose.
    ///
    /// Raises ``ModelError`` for a ``dt`` longer than the plan or past the RK4 stability limit
    /// of the tracking loop (the arm, its joints and the PD with these gains, linearised at the
    /// start; see ``arm.rk4_stability_limit``), where the run would diverge or mean nothing;
    /// ``SimulationError`` (with the finite part in ``.trajectory``) if the run turns
    /// non-finite anyway. Ctrl-C stops the run with ``KeyboardInterrupt``. The held base is
    /// held open loop, by the plan's own wrench; or, on an arm with reaction wheels, by them:
    /// ``wheel_torque`` (an ``AttitudePD``, a callable ``(t, x)``, a table or a ``Sampled``)
    /// then drives the wheels and no wrench is applied, so the wheels hold the bus's attitude
    /// while its position drifts as the system's centre of mass requires
    /// (``"base_position_error"`` shows by how much).
    #[pyo3(signature = (dt, kp, kd, settle=None, *, wheel_torque=None), text_signature = "($self, dt, kp, kd, settle=2.0, *, wheel_torque=None)")]
    fn track<'py>(
        &self,
        py: Python<'py>,
        dt: &Bound<'py, PyAny>,
        kp: &Bound<'py, PyAny>,
        kd: &Bound<'py, PyAny>,
        settle: Option<&Bound<'py, PyAny>>,
        wheel_torque: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let wheel_torque = wheel_torque.filter(|w| !w.is_none());
        let n = self.plan.arm().dof();
        let TrackingArgs { dt, kp, kd, settle } =
            TrackingArgs::parse(&self.plan, dt, kp, kd, settle)?;
        let plan = &self.plan;
        let mut interrupt = None;
        let setup = py.allow_threads(|| {
            plan.tracking_setup_with(dt, &kp, &kd, settle, &mut |_| keep_going(&mut interrupt))
        })?;
        let Some(setup) = setup else {
            return Err(interrupt.expect("stopped only on a pending exception"));
        };
        let arm = &self.arm;
        let (trajectory, reference) = run_tracking(py, plan, arm, dt, setup, wheel_torque)?;
        let tracking = py.allow_threads(|| plan.measure(trajectory, reference));
        tracking_dict(py, arm.clone_ref(py), tracking, n)
    }

    /// What holding the bus through this held-base plan asks of reaction ``wheels``
    /// (``orbitflex.ReactionWheels``; minimum-norm allocation of the plan's holding moment, the
    /// wheels from rest; the force part is not theirs to give). Returns a dict: ``"t"`` (the
    /// plan's samples, s), ``"torque"`` (samples, k) motor torques (N·m), ``"speed"`` (samples,
    /// k) wheel speeds (rad/s), ``"momentum"`` (samples, 3) the stored spin momentum (N·m·s,
    /// base frame), ``"peak_torque"`` and ``"peak_speed"`` (k,), ``"peak_momentum"`` (N·m·s),
    /// and ``"binding"``: the limit closest to its bound (``limit`` ``"max_torque"`` or
    /// ``"max_speed"``, ``wheel``, ``time``, ``value``, ``bound``, ``ratio``; a ratio above 1:
    /// the wheels cannot hold the bus through this plan). ``ModelError`` for a free-floating
    /// plan or axes that do not span three dimensions.
    fn wheel_demand<'py>(
        &self,
        py: Python<'py>,
        wheels: &Bound<'py, super::wheels::PyReactionWheels>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let wheels = wheels.get().wheels.clone();
        let demand = self.plan.wheel_demand(&wheels)?;
        let k = wheels.len();
        let rows = demand.t.len();
        let d = PyDict::new(py);
        d.set_item("t", array1(py, &demand.t))?;
        d.set_item("torque", row_major(py, rows, k, demand.torque))?;
        d.set_item("speed", row_major(py, rows, k, demand.speed))?;
        d.set_item("momentum", row_major(py, rows, 3, demand.momentum))?;
        d.set_item("peak_torque", array1(py, &demand.peak_torque))?;
        d.set_item("peak_speed", array1(py, &demand.peak_speed))?;
        d.set_item("peak_momentum", demand.peak_momentum)?;
        let b = PyDict::new(py);
        b.set_item("limit", demand.binding.limit)?;
        b.set_item("wheel", demand.binding.wheel)?;
        b.set_item("time", demand.binding.time)?;
        b.set_item("value", demand.binding.value)?;
        b.set_item("bound", demand.binding.bound)?;
        b.set_item("ratio", demand.binding.ratio())?;
        d.set_item("binding", b)?;
        Ok(d)
    }

    /// Rebuilds a plan from :meth:`__reduce__`'s parts (for pickling) by planning it again:
    /// the planner is deterministic, so the copy equals the original.
    #[staticmethod]
    fn _from_stops(
        py: Python<'_>,
        arm: Py<PyFlexibleArm>,
        stops: &Bound<'_, PyAny>,
        limits: PyLimits,
        base: &str,
        rigid: bool,
    ) -> PyResult<PyPlan> {
        let n = arm.get().arm.dof();
        let (rows, values) = matrix(stops, "stops", n)?;
        if rows < 2 {
            return Err(ModelError::new_err(format!(
                "stops: expected at least 2 rows (start and goal), given {rows}"
            )));
        }
        let stops: Vec<Vec<f64>> = values.chunks_exact(n).map(<[f64]>::to_vec).collect();
        let base = BaseMode::from_name(base)?;
        let solve_arm = arm.get().arm.clone();
        wrap(py, arm, move |cancel| {
            let (start, goal) = (&stops[0], &stops[rows - 1]);
            let plan = plan_slew_watched(
                &solve_arm,
                goal,
                Some(start),
                &limits.limits,
                base,
                &stops[1..rows - 1],
                cancel,
            )?;
            if rigid {
                plan.rigid_watched(cancel)
            } else {
                Ok(plan)
            }
        })
    }

    /// Pickle support: the arm, the stops, the limits, the base mode and whether the plan is
    /// rigid; unpickling plans again (tens of ms).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let args = (
            me.arm(py),
            me.stops(py),
            me.limits(),
            me.base(),
            me.is_rigid(),
        );
        let constructor = slf.get_type().getattr("_from_stops")?;
        Ok((
            constructor.unbind(),
            args.into_pyobject(py)?.into_any().unbind(),
        ))
    }

    fn __repr__(&self) -> String {
        let b = self.plan.binding();
        let joint = b
            .joint
            .map_or(String::new(), |j| format!("[{}]", self.joint_names()[j]));
        format!(
            "Plan(duration={} s, base='{}', rigid={}, binding={}{} at t={} s, segments={})",
            rounded(self.plan.duration(), 6),
            self.base(),
            if self.plan.is_rigid() {
                "True"
            } else {
                "False"
            },
            b.constraint.name(),
            joint,
            rounded(b.time, 4),
            self.plan.segment_durations().len()
        )
    }
}

/// Plans the shortest rest-to-rest slew of ``arm`` from ``q_start`` (default: zeros) to
/// ``q_goal`` (rad, n each) through ``waypoints`` (a list of m stops, (m, n); the arm stops at
/// each) under ``limits`` (an ``orbitflex.Limits``; default ``Limits.from_urdf(arm.robot)``, the
/// limits the robot's URDF states). Limits that allow more torque or speed than the URDF's give
/// a ``LimitWarning`` (the plan uses them as given); a start, waypoint or goal outside a joint's
/// position limits (``robot.position_limits``) is refused.
///
/// The path between stops is fixed: ``q(t) = q_a + (q_b − q_a) σ(t/T)`` with the degree-9
/// polynomial ``σ`` whose derivatives 1–4 vanish at both ends; the planner finds per segment the
/// shortest ``T`` for which every limit holds, with the flexible-joint inverse dynamics (so
/// ``u`` includes the motors' extra effort to stretch the springs). The arm starts at rest with
/// relaxed springs.
///
/// ``base``: ``"held"`` (the base's actuators hold it inertially still; ``limits.base_force``
/// and ``limits.base_torque`` bound their wrench) or ``"free"`` (free floating from rest: zero
/// momentum, the base moves in reaction; the base limits do not apply).
///
/// Releases the GIL while planning; Ctrl-C stops it (``KeyboardInterrupt``). Raises
/// ``ModelError`` for wrong lengths, non-finite values, equal consecutive stops, or limits no
/// duration can meet.
#[pyfunction]
#[pyo3(name = "plan_slew", signature = (arm, q_goal, q_start=None, limits=None, base="held", waypoints=None))]
pub fn py_plan_slew(
    py: Python<'_>,
    arm: Bound<'_, PyFlexibleArm>,
    q_goal: &Bound<'_, PyAny>,
    q_start: Option<&Bound<'_, PyAny>>,
    limits: Option<&Bound<'_, PyAny>>,
    base: &str,
    waypoints: Option<&Bound<'_, PyAny>>,
) -> PyResult<PyPlan> {
    let n = arm.get().arm.dof();
    if q_start.is_some_and(|s| s.is_instance_of::<PyLimits>()) {
        return Err(PyTypeError::new_err(
            "plan_slew: q_start: given an orbitflex.Limits (the third positional argument is \
             q_start); pass the limits by name: plan_slew(arm, q_goal, limits=...)",
        ));
    }
    let limits = match limits.filter(|l| !l.is_none()) {
        Some(l) => l
            .downcast::<PyLimits>()
            .map_err(|_| {
                PyTypeError::new_err(format!(
                    "plan_slew: limits: expected an orbitflex.Limits, given {}",
                    l.get_type()
                        .name()
                        .map(|s| s.to_string())
                        .unwrap_or_default()
                ))
            })?
            .get()
            .limits
            .clone(),
        None => Limits::from_robot(arm.get().arm.robot(), None, None).map_err(|e| {
            ModelError::new_err(format!(
                "{e}, or pass limits=orbitflex.Limits(motor_torque, joint_speed, base_force=None, \
                 base_torque=None)"
            ))
        })?,
    };
    let over = limits.exceeding(arm.get().arm.robot())?;
    if !over.is_empty() {
        let message = format!(
            "limits allow more than the robot's model states (its URDF's <limit effort \
             velocity>): {}; the plan uses them as given",
            over.join("; ")
        );
        PyErr::warn(
            py,
            &py.get_type::<LimitWarning>(),
            &std::ffi::CString::new(message).unwrap_or_default(),
            1,
        )?;
    }
    let q_goal = vector(q_goal, "q_goal", Some(n))?;
    let q_start = q_start
        .filter(|o| !o.is_none())
        .map(|o| vector(o, "q_start", Some(n)))
        .transpose()?;
    let base = BaseMode::from_name(base)?;
    let waypoints = waypoint_rows(waypoints, n)?;
    let rust_arm = &arm.get().arm;
    wrap(py, arm.clone().unbind(), |cancel| {
        plan_slew_watched(
            rust_arm,
            &q_goal,
            q_start.as_deref(),
            &limits,
            base,
            &waypoints,
            cancel,
        )
    })
}
