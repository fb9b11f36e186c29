//! `orbitflex.FlexibleJoints`, `orbitflex.FlexibleArm` (core) and `orbitflex.MotorPD`.

use super::convert::{array1, matrix, row_major, vector, vector_or};
use super::robot::PyRobot;
use super::ModelError;
use crate::error::Error;
use crate::flex::{ArmWorkspace, FlexibleArm, FlexibleJoints};
use crate::integrate::{Controller, MotorPD, Schedule};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

/// A parameter given as a scalar (broadcast to every joint) or one value per joint.
#[derive(Clone, Debug)]
enum Param {
    Scalar(f64),
    PerJoint(Vec<f64>),
}

impl Param {
    fn parse(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        if let Ok(v) = obj.extract::<f64>() {
            crate::error::check_finite(what, &[v])?;
            return Ok(Param::Scalar(v));
        }
        Ok(Param::PerJoint(vector(obj, what, None)?))
    }
    /// An optional parameter: absent or None means 0 for every joint (SPEC §8 defaults).
    fn optional(obj: Option<&Bound<'_, PyAny>>, what: &str) -> PyResult<Self> {
        match obj {
            Some(o) if !o.is_none() => Self::parse(o, what),
            _ => Ok(Param::Scalar(0.0)),
        }
    }
    fn resolve(&self, n: usize) -> Vec<f64> {
        match self {
            Param::Scalar(v) => vec![*v; n],
            Param::PerJoint(v) => v.clone(),
        }
    }
    fn len(&self) -> Option<usize> {
        match self {
            Param::Scalar(_) => None,
            Param::PerJoint(v) => Some(v.len()),
        }
    }
}

/// Spong flexible-joint parameters (SPEC §3), link side: ``stiffness`` k > 0 (N·m/rad),
/// ``motor_inertia`` j > 0 (kg·m², ``N² J_rotor``), ``damping`` d ≥ 0 and ``motor_damping``
/// β ≥ 0 (N·m·s/rad). Each is a scalar (same for every joint) or an array of length n.
#[pyclass(name = "FlexibleJoints", module = "orbitflex", frozen)]
#[derive(Clone)]
pub struct PyFlexibleJoints {
    params: [Param; 4],
}

impl PyFlexibleJoints {
    const NAMES: [&'static str; 4] = ["stiffness", "motor_inertia", "damping", "motor_damping"];

    /// Checks the per-joint parameters against `n` joints (`expected` says where `n` comes from)
    /// and builds the validated Rust parameters.
    fn build(params: &[Param; 4], n: usize, expected: &str) -> Result<FlexibleJoints, Error> {
        for (p, name) in params.iter().zip(Self::NAMES) {
            match p.len() {
                Some(len) if len != n => {
                    return Err(Error::Dimension {
                        what: format!("FlexibleJoints.{name}"),
                        expected: format!("length {n} ({expected})"),
                        given: format!("length {len}"),
                    })
                }
                _ => {}
            }
        }
        let [k, j, d, beta] = params.clone().map(|p| p.resolve(n));
        FlexibleJoints::new(k, j, d, beta)
    }

    fn validate(params: [Param; 4]) -> PyResult<Self> {
        let n = params.iter().find_map(Param::len).unwrap_or(1);
        Self::build(&params, n, "as the other per-joint parameters")?;
        Ok(Self { params })
    }

    pub(crate) fn resolve(&self, n: usize) -> Result<FlexibleJoints, Error> {
        Self::build(&self.params, n, "the robot's dof")
    }

    fn from_rust(j: FlexibleJoints) -> Self {
        Self {
            params: [
                Param::PerJoint(j.stiffness),
                Param::PerJoint(j.motor_inertia),
                Param::PerJoint(j.damping),
                Param::PerJoint(j.motor_damping),
            ],
        }
    }

    fn get<'py>(&self, py: Python<'py>, k: usize) -> PyObject {
        match &self.params[k] {
            Param::Scalar(v) => v.into_pyobject(py).unwrap().into_any().unbind(),
            Param::PerJoint(v) => array1(py, v).into_any().unbind(),
        }
    }
}

#[pymethods]
impl PyFlexibleJoints {
    #[new]
    #[pyo3(
        signature = (stiffness, motor_inertia, damping=None, motor_damping=None),
        text_signature = "(stiffness, motor_inertia, damping=0.0, motor_damping=0.0)"
    )]
    fn new(
        stiffness: &Bound<'_, PyAny>,
        motor_inertia: &Bound<'_, PyAny>,
        damping: Option<&Bound<'_, PyAny>>,
        motor_damping: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        Self::validate([
            Param::parse(stiffness, "stiffness")?,
            Param::parse(motor_inertia, "motor_inertia")?,
            Param::optional(damping, "damping")?,
            Param::optional(motor_damping, "motor_damping")?,
        ])
    }

    /// From gearbox data: ``motor_inertia = gear_ratio² · rotor_inertia``. With this, the
    /// control input ``u`` and motor angle ``θ`` are link-side: ``u = N · (motor torque)`` and
    /// ``θ = (motor angle) / N``.
    #[staticmethod]
    #[pyo3(signature = (stiffness, gear_ratio, rotor_inertia, damping=None, motor_damping=None))]
    fn from_gear(
        stiffness: &Bound<'_, PyAny>,
        gear_ratio: &Bound<'_, PyAny>,
        rotor_inertia: &Bound<'_, PyAny>,
        damping: Option<&Bound<'_, PyAny>>,
        motor_damping: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let g = Param::parse(gear_ratio, "gear_ratio")?;
        let r = Param::parse(rotor_inertia, "rotor_inertia")?;
        let n = g.len().or(r.len()).unwrap_or(1);
        if let (Some(a), Some(b)) = (g.len(), r.len()) {
            if a != b {
                return Err(ModelError::new_err(format!(
                    "rotor_inertia: expected length {a} (as gear_ratio), given length {b}"
                )));
            }
        }
        let (g, r) = (g.resolve(n), r.resolve(n));
        for (what, v) in [("gear_ratio", &g), ("rotor_inertia", &r)] {
            if let Some(i) = v.iter().position(|&x| x <= 0.0) {
                return Err(ModelError::new_err(format!(
                    "{what}[{i}]: expected > 0, given {}",
                    v[i]
                )));
            }
        }
        let j: Vec<f64> = g.iter().zip(&r).map(|(g, r)| g * g * r).collect();
        let inertia = if n == 1
            && j.len() == 1
            && gear_ratio.extract::<f64>().is_ok()
            && rotor_inertia.extract::<f64>().is_ok()
        {
            Param::Scalar(j[0])
        } else {
            Param::PerJoint(j)
        };
        Self::validate([
            Param::parse(stiffness, "stiffness")?,
            inertia,
            Param::optional(damping, "damping")?,
            Param::optional(motor_damping, "motor_damping")?,
        ])
    }

    /// Reads parameters keyed by joint name from a TOML file (``[defaults]`` and
    /// ``[joints.<name>]`` tables with ``stiffness``, ``motor_inertia`` or ``gear_ratio`` +
    /// ``rotor_inertia``, ``damping``, ``motor_damping``) for the joints of ``robot``.
    #[staticmethod]
    fn from_toml(path: std::path::PathBuf, robot: &PyRobot) -> PyResult<Self> {
        let names = robot.robot.joint_names();
        Ok(Self::from_rust(FlexibleJoints::from_toml_file(
            path, &names,
        )?))
    }

    /// Like :meth:`from_toml`, from TOML text.
    #[staticmethod]
    fn from_toml_string(text: &str, robot: &PyRobot) -> PyResult<Self> {
        let names = robot.robot.joint_names();
        Ok(Self::from_rust(FlexibleJoints::from_toml_str(
            text,
            &names,
            "<toml string>",
        )?))
    }

    /// k (N·m/rad): a float or an array.
    #[getter]
    fn stiffness(&self, py: Python<'_>) -> PyObject {
        self.get(py, 0)
    }
    /// j (kg·m², link side): a float or an array.
    #[getter]
    fn motor_inertia(&self, py: Python<'_>) -> PyObject {
        self.get(py, 1)
    }
    /// d (N·m·s/rad): a float or an array.
    #[getter]
    fn damping(&self, py: Python<'_>) -> PyObject {
        self.get(py, 2)
    }
    /// β (N·m·s/rad): a float or an array.
    #[getter]
    fn motor_damping(&self, py: Python<'_>) -> PyObject {
        self.get(py, 3)
    }

    /// Pickle support.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let args = PyTuple::new(py, (0..4).map(|k| me.get(py, k)))?;
        Ok((slf.get_type().into_any().unbind(), args.into_any().unbind()))
    }

    fn __repr__(&self) -> String {
        format!("FlexibleJoints{:?}", self.params)
    }
}

/// Motor-side PD with feedforward, run inside Rust:
/// ``u = kp (theta_ref − θ) + kd (theta_dot_ref − θ̇) + feedforward``.
/// Gains: scalar or (n,). References: (n,) constant or (steps, n) one row per step.
#[pyclass(name = "MotorPD", module = "orbitflex", frozen)]
#[derive(Clone)]
pub struct PyMotorPD {
    pub(crate) pd: MotorPD,
}

fn schedule(obj: Option<&Bound<'_, PyAny>>, what: &str, n: usize) -> PyResult<Schedule> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Schedule::Zero);
    };
    let a = super::convert::as_float_array(obj, what)?;
    let ndim: usize = a.getattr("ndim")?.extract()?;
    match ndim {
        0 => Ok(Schedule::Constant(vec![a.extract::<f64>()?; n])).and_then(|s| {
            s.check(what, n, None)?;
            Ok(s)
        }),
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
        let reference = super::convert::as_float_array(theta_ref, "theta_ref")?;
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
            if let Some(len) = p.len() {
                if len != n {
                    return Err(ModelError::new_err(format!(
                        "{what}: expected length {n} (as theta_ref), given length {len}"
                    )));
                }
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

    fn __repr__(&self) -> String {
        format!(
            "MotorPD(dof={}, kp={:?}, kd={:?})",
            self.pd.dof(),
            self.pd.kp,
            self.pd.kd
        )
    }
}

/// A Python callable ``(t, x) -> u`` as a [`Controller`]; the first Python exception is kept.
struct PyCallable<'py> {
    func: Bound<'py, PyAny>,
    n: usize,
    error: Option<PyErr>,
}

impl Controller for PyCallable<'_> {
    fn torque(&mut self, _step: usize, t: f64, x: &[f64], u: &mut [f64]) -> crate::Result<()> {
        let py = self.func.py();
        let result = self
            .func
            .call1((t, array1(py, x)))
            .and_then(|out| vector(&out, "u returned by the controller", Some(self.n)));
        match result {
            Ok(values) => {
                u.copy_from_slice(&values);
                Ok(())
            }
            Err(e) => {
                let message = e.to_string();
                self.error = Some(e);
                Err(Error::InvalidArgument {
                    what: "controller".into(),
                    message,
                })
            }
        }
    }
}

/// Runs `simulate` without the GIL, taking it back every 4096 steps to check for signals
/// (Ctrl-C): a pending `KeyboardInterrupt` stops the run and is raised as it is.
#[allow(clippy::too_many_arguments)]
fn simulate_releasing_gil(
    py: Python<'_>,
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    steps: usize,
    u: &mut (dyn Controller + Send),
    fb: &Schedule,
    f: &Schedule,
) -> PyResult<Result<crate::Trajectory, Box<crate::SimulationFailure>>> {
    let mut signal: Option<PyErr> = None;
    let result = py.allow_threads(|| {
        let mut check = |_k: usize| {
            Python::with_gil(|py| match py.check_signals() {
                Ok(()) => true,
                Err(e) => {
                    signal = Some(e);
                    false
                }
            })
        };
        arm.simulate_with_hook(x0, dt, steps, u, fb, f, 4096, &mut check)
    });
    match signal {
        Some(e) => Err(e),
        None => Ok(result),
    }
}

/// The Rust core of ``orbitflex.FlexibleArm`` (the Python subclass adds ``simulate``).
#[pyclass(name = "FlexibleArm", module = "orbitflex", subclass, frozen)]
pub struct PyFlexibleArm {
    arm: FlexibleArm,
    robot: Py<PyRobot>,
    joints: Py<PyFlexibleJoints>,
    ws: std::sync::Mutex<ArmWorkspace>,
}

impl PyFlexibleArm {
    fn ws(&self) -> std::sync::MutexGuard<'_, ArmWorkspace> {
        self.ws.lock().unwrap_or_else(|p| p.into_inner())
    }
    fn n(&self) -> usize {
        self.arm.robot().dof()
    }
    fn inputs(
        &self,
        u: Option<&Bound<'_, PyAny>>,
        fb: Option<&Bound<'_, PyAny>>,
        f: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<(Vec<f64>, Vec<f64>, Vec<f64>)> {
        Ok((
            vector_or(u, "u", self.n(), 0.0)?,
            vector_or(fb, "base_wrench", 6, 0.0)?,
            vector_or(f, "ee_wrench", 6, 0.0)?,
        ))
    }
    /// Rows of states, each validated (finite, non-zero quaternion).
    fn states(&self, x: &Bound<'_, PyAny>) -> PyResult<(usize, Vec<f64>)> {
        let len = self.arm.layout().len();
        let (rows, values) = matrix(x, "x", len)?;
        for (k, row) in values.chunks(len).enumerate() {
            self.arm
                .check_state(row)
                .map_err(|e| ModelError::new_err(format!("x[{k}]: {e}")))?;
        }
        Ok((rows, values))
    }
}

#[pymethods]
impl PyFlexibleArm {
    #[new]
    #[pyo3(signature = (robot, joints, method="recursive"))]
    fn new(
        robot: Bound<'_, PyRobot>,
        joints: Bound<'_, PyFlexibleJoints>,
        method: &str,
    ) -> PyResult<Self> {
        let params = joints.get().resolve(robot.get().robot.dof())?;
        let arm = FlexibleArm::new(robot.get().robot.clone(), params)?
            .with_method(super::convert::method(method)?);
        let ws = std::sync::Mutex::new(ArmWorkspace::new(&arm));
        Ok(Self {
            arm,
            robot: robot.unbind(),
            joints: joints.unbind(),
            ws,
        })
    }

    /// The rigid robot.
    #[getter]
    fn robot(&self, py: Python<'_>) -> Py<PyRobot> {
        self.robot.clone_ref(py)
    }
    /// The joint parameters.
    #[getter]
    fn joints(&self, py: Python<'_>) -> Py<PyFlexibleJoints> {
        self.joints.clone_ref(py)
    }
    /// Number of joints n.
    #[getter]
    fn dof(&self) -> usize {
        self.n()
    }
    /// Length of the state vector, 13 + 4n.
    #[getter]
    fn state_size(&self) -> usize {
        self.arm.layout().len()
    }
    /// ``"recursive"`` or ``"operator"``.
    #[getter]
    fn method(&self) -> &'static str {
        match self.arm.method() {
            crate::Method::Recursive => "recursive",
            crate::Method::Operator => "operator",
        }
    }
    /// Per-joint parameters resolved to arrays: (k, j, d, β).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> Bound<'py, PyTuple> {
        let p = self.arm.joints();
        PyTuple::new(
            py,
            [
                array1(py, &p.stiffness),
                array1(py, &p.motor_inertia),
                array1(py, &p.damping),
                array1(py, &p.motor_damping),
            ],
        )
        .expect("tuple")
    }

    /// The state ``x`` (13+4n,): ``[r_B | quat_B (x,y,z,w) | q | θ | ω_B | v_B | q̇ | θ̇]``
    /// (SPEC §4). Defaults: zero angles and rates, base at the origin with identity attitude and
    /// at rest, ``theta = q`` (relaxed springs). The quaternion is normalised.
    #[pyo3(signature = (q=None, theta=None, qd=None, theta_dot=None, base_pose=None, base_twist=None))]
    #[allow(clippy::too_many_arguments)]
    fn state<'py>(
        &self,
        py: Python<'py>,
        q: Option<&Bound<'py, PyAny>>,
        theta: Option<&Bound<'py, PyAny>>,
        qd: Option<&Bound<'py, PyAny>>,
        theta_dot: Option<&Bound<'py, PyAny>>,
        base_pose: Option<&Bound<'py, PyAny>>,
        base_twist: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let n = self.n();
        let get =
            |o: Option<&Bound<'py, PyAny>>, what: &str, len: usize| -> PyResult<Option<Vec<f64>>> {
                match o {
                    Some(o) if !o.is_none() => Ok(Some(vector(o, what, Some(len))?)),
                    _ => Ok(None),
                }
            };
        let (q, theta, qd, td, pose, twist) = (
            get(q, "q", n)?,
            get(theta, "theta", n)?,
            get(qd, "qd", n)?,
            get(theta_dot, "theta_dot", n)?,
            get(base_pose, "base_pose", 7)?,
            get(base_twist, "base_twist", 6)?,
        );
        let x = self.arm.state(
            q.as_deref(),
            theta.as_deref(),
            qd.as_deref(),
            td.as_deref(),
            pose.as_deref(),
            twist.as_deref(),
        )?;
        Ok(array1(py, &x))
    }

    /// ``ẋ`` (13+4n,) at state ``x`` with motor torques ``u`` (n,), base wrench and EE wrench
    /// (6,), all defaulting to zero (SPEC §4).
    #[pyo3(signature = (x, u=None, base_wrench=None, ee_wrench=None))]
    fn derivative<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        let (u, fb, f) = self.inputs(u, base_wrench, ee_wrench)?;
        let mut xdot = vec![0.0; x.len()];
        self.arm
            .derivative(&mut self.ws(), &x, &u, &fb, &f, &mut xdot)?;
        Ok(array1(py, &xdot))
    }

    /// One RK4 step of ``dt`` seconds from ``x``, inputs held; returns the new state.
    #[pyo3(signature = (x, dt, u=None, base_wrench=None, ee_wrench=None))]
    fn step<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        dt: f64,
        u: Option<&Bound<'py, PyAny>>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let mut x = vector(x, "x", Some(self.arm.layout().len()))?;
        let (u, fb, f) = self.inputs(u, base_wrench, ee_wrench)?;
        self.arm.step(&mut self.ws(), &mut x, dt, &u, &fb, &f)?;
        Ok(array1(py, &x))
    }

    /// Largest stable RK4 step (s) for the stiffest joint mode at angles ``q`` (SPEC §5).
    #[pyo3(signature = (q=None))]
    fn rk4_stability_limit(&self, q: Option<&Bound<'_, PyAny>>) -> PyResult<f64> {
        let q = vector_or(q, "q", self.n(), 0.0)?;
        Ok(self.arm.rk4_stability_limit(&q)?)
    }

    /// Total energy at state ``x`` (SPEC §6.2), J.
    fn energy(&self, x: &Bound<'_, PyAny>) -> PyResult<f64> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        self.arm.check_state(&x)?;
        Ok(self.arm.energy(&mut self.ws(), &x))
    }

    /// Momentum ``[angular; linear]`` at state ``x``, inertial frame (SPEC §6.1).
    fn momentum<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        self.arm.check_state(&x)?;
        Ok(array1(py, &self.arm.momentum(&mut self.ws(), &x)))
    }

    /// EE pose ``[position (3); quaternion (x, y, z, w)]`` in the inertial frame at state ``x``.
    fn ee_pose<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        self.arm.check_state(&x)?;
        Ok(array1(py, &self.arm.ee_pose(&x)))
    }

    /// Diagnostics along a trajectory (rows of ``x``): ``"momentum"`` (rows, 6),
    /// ``"energy"`` (rows,), ``"ee_pose"`` (rows, 7). Computed in Rust.
    fn _along<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        what: &str,
    ) -> PyResult<PyObject> {
        let (rows, values) = self.states(x)?;
        let traj = crate::Trajectory {
            t: vec![0.0; rows],
            x: values,
            state_len: self.arm.layout().len(),
        };
        let arm = &self.arm;
        Ok(match what {
            "momentum" => row_major(py, rows, 6, py.allow_threads(|| arm.momentum_along(&traj)))
                .into_any()
                .unbind(),
            "energy" => array1(py, &py.allow_threads(|| arm.energy_along(&traj)))
                .into_any()
                .unbind(),
            "ee_pose" => row_major(py, rows, 7, py.allow_threads(|| arm.ee_pose_along(&traj)))
                .into_any()
                .unbind(),
            other => return Err(ModelError::new_err(format!("unknown diagnostic {other:?}"))),
        })
    }

    /// Core of ``simulate``: returns ``(t, x, error)`` where ``error`` is None or
    /// ``(message, step, time, python_exception_or_None)``; ``t``/``x`` hold every finite state.
    #[pyo3(signature = (x0, dt, steps, u=None, base_wrench=None, ee_wrench=None))]
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    fn _simulate<'py>(
        &self,
        py: Python<'py>,
        x0: &Bound<'py, PyAny>,
        dt: f64,
        steps: usize,
        u: Option<&Bound<'py, PyAny>>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<(
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray2<f64>>,
        Option<(String, usize, f64, Option<PyErr>)>,
    )> {
        let n = self.n();
        let len = self.arm.layout().len();
        let x0 = vector(x0, "x0", Some(len))?;
        let wrench = |o: Option<&Bound<'py, PyAny>>, what: &str| -> PyResult<Schedule> {
            let s = schedule(o, what, 6)?;
            s.check(what, 6, Some(steps))?;
            Ok(s)
        };
        let fb = wrench(base_wrench, "base_wrench")?;
        let f = wrench(ee_wrench, "ee_wrench")?;
        let arm = &self.arm;
        let mut callable_error = None;
        let result = match u.filter(|o| !o.is_none()) {
            Some(obj) if obj.is_instance_of::<PyMotorPD>() => {
                let mut pd = obj.downcast::<PyMotorPD>()?.get().pd.clone();
                if pd.dof() != n {
                    return Err(ModelError::new_err(format!(
                        "u: MotorPD for {} joints, the arm has {n}",
                        pd.dof()
                    )));
                }
                pd.check_steps(steps)?;
                simulate_releasing_gil(py, arm, &x0, dt, steps, &mut pd, &fb, &f)?
            }
            Some(obj) if obj.is_callable() => {
                let mut c = PyCallable {
                    func: obj.clone(),
                    n,
                    error: None,
                };
                let r = arm.simulate(&x0, dt, steps, &mut c, &fb, &f);
                // KeyboardInterrupt, SystemExit and other non-Exception errors are not a
                // controller failure: re-raise them as they are.
                if let Some(e) = c.error {
                    if !e.is_instance_of::<pyo3::exceptions::PyException>(py) {
                        return Err(e);
                    }
                    callable_error = Some(e);
                }
                r
            }
            other => {
                let mut s = schedule(other, "u", n)?;
                s.check("u", n, Some(steps))?;
                simulate_releasing_gil(py, arm, &x0, dt, steps, &mut s, &fb, &f)?
            }
        };
        let (traj, error) = match result {
            Ok(t) => (t, None),
            Err(failure) => match failure.error {
                Error::Simulation { step, time, .. } => {
                    let message = failure.error.to_string();
                    (
                        failure.trajectory,
                        Some((message, step, time, callable_error)),
                    )
                }
                other => return Err(other.into()),
            },
        };
        let rows = traj.len();
        Ok((array1(py, &traj.t), row_major(py, rows, len, traj.x), error))
    }

    fn __repr__(&self) -> String {
        format!(
            "FlexibleArm(robot={:?}, dof={}, method={:?})",
            self.arm.robot().name(),
            self.n(),
            self.method()
        )
    }
}
