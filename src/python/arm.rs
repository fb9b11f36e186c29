//! `orbitflex.FlexibleArm`: state, derivative, step, diagnostics, ``simulate`` and the
//! flexible-joint inverse dynamics.

use super::capture_run::{capture_releasing_gil, CaptureInfo, Capturing};
use super::control::controller;
use super::convert::{
    array1, count, positive_count, real, record_every_arg, try_array2, vector, vector_or,
};
use super::errors::simulation_error;
use super::errors::ModelError;
use super::joints::PyFlexibleJoints;
use super::robot::PyRobot;
use super::run::{
    deliver, record_releasing_gil, runtime_warning, ChannelErrors, Channels, Progress, Stream,
};
use super::stability::PyStabilityLimit;
use super::trajectory::PyTrajectory;
use super::workspaces::{Lent, Pool};
use crate::args::Loads;
use crate::error::Error;
use crate::flex::{FlexibleArm, Inputs, StateSpec};
use crate::integrate::{self, Chunk, Chunks, Recorder, Trajectory};
use crate::integrate::{ArmWorkspace, Run};
use crate::planning::{BaseMode, LinkMotion};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

/// Two arrays returned together (``kp, kd``).
type ArrayPair<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// Rows per chunk given to ``on_rows`` by default.
const CHUNK_ROWS: usize = 1024;

/// Where `simulate` puts the kept rows: a `Trajectory`, or chunks for `on_rows`.
enum Sink<F> {
    Memory(Trajectory),
    Stream(Stream<F>),
}

impl<F: FnMut(Chunk<'_>) -> crate::Result<()> + Send> Sink<F> {
    fn recorder(&mut self) -> &mut (dyn Recorder + Send) {
        match self {
            Sink::Memory(traj) => traj,
            Sink::Stream(stream) => stream,
        }
    }

    /// The run's `Trajectory`: the record, or the final row alone when the rows were streamed.
    fn into_trajectory(self) -> Trajectory {
        match self {
            Sink::Memory(traj) => traj,
            Sink::Stream(stream) => stream.last_row(),
        }
    }
}

/// A floating-base arm with Spong flexible joints.
///
/// ``FlexibleArm(robot, joints, method="recursive")``; ``method="operator"`` uses the paper's
/// dense operator form for the rigid dynamics (slow; for validation).
///
/// State ``x`` (13+4n): ``[r_B | quat_B (x,y,z,w) | q | θ | ω_B | v_B | q̇ | θ̇]``. Inputs: motor
/// torques ``u`` (n, link side, N·m), base wrench ``f_B`` (6, ``[moment; force]``, base frame,
/// applied to the base) and EE wrench ``f`` (6, EE frame, the force the EE exerts on its
/// environment).
///
/// Thread-safe: call it from several threads at once (each call has a workspace of its own).
/// ``simulate`` without a Python controller runs without the GIL and stops on Ctrl-C.
#[pyclass(name = "FlexibleArm", module = "orbitflex", frozen)]
pub struct PyFlexibleArm {
    pub(crate) arm: FlexibleArm,
    robot: Py<PyRobot>,
    joints: Py<PyFlexibleJoints>,
    wheels: Option<Py<super::wheels::PyReactionWheels>>,
    /// Workspaces, one lent to each call in flight (see `workspaces`).
    workspaces: Pool<ArmWorkspace>,
}

impl PyFlexibleArm {
    /// A workspace of this call's own.
    fn ws(&self) -> Lent<'_, ArmWorkspace> {
        self.workspaces.take(|| self.arm.workspace())
    }
    fn n(&self) -> usize {
        self.arm.dof()
    }
    /// A checked state vector.
    fn state_arg(&self, x: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<f64>> {
        let x = vector(x, what, Some(self.arm.layout().len()))?;
        self.arm.check_state(&x)?;
        Ok(x)
    }
}

/// The owned inputs of one call, lent out as [`Inputs`].
struct InputArgs {
    u: Vec<f64>,
    base_wrench: Vec<f64>,
    /// `[f_1; …; f_k]`, or empty for none.
    ee_wrench: Vec<f64>,
    /// Wheel torque commands (k), or empty for none.
    wheel_torque: Vec<f64>,
}

impl InputArgs {
    fn parse(
        robot: &crate::Robot,
        u: Option<&Bound<'_, PyAny>>,
        base_wrench: Option<&Bound<'_, PyAny>>,
        ee_wrench: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let k = robot.end_effectors().len();
        let ee = super::convert::ee_wrench_arg(robot, ee_wrench)?;
        let args = Self {
            u: vector_or(u, "u", robot.dof(), 0.0)?,
            base_wrench: vector_or(base_wrench, "base_wrench", 6, 0.0)?,
            ee_wrench: match ee {
                Some(f) => vector(&f, "ee_wrench", Some(6 * k))?,
                None => Vec::new(),
            },
            wheel_torque: Vec::new(),
        };
        args.inputs().loads.check_for(robot)?;
        Ok(args)
    }
    /// With the wheel torque commands `wheel_torque` ((k,) or None), checked against `arm`.
    fn wheels(
        mut self,
        arm: &FlexibleArm,
        wheel_torque: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        if let Some(w) = wheel_torque.filter(|o| !o.is_none()) {
            let k = arm.layout().wheels;
            self.wheel_torque = vector(w, "wheel_torque", (k > 0).then_some(k))?;
            arm.check_inputs(&self.inputs())?;
        }
        Ok(self)
    }
    fn inputs(&self) -> Inputs<'_> {
        Inputs {
            u: &self.u,
            loads: Loads {
                base_wrench: crate::spatial::Force::from_slice(&self.base_wrench),
                ee_wrench: &self.ee_wrench,
            },
            wheel_torque: &self.wheel_torque,
        }
    }
}

/// Two matrices, `(F, G)`.
type MatrixPair<'py> = (Bound<'py, PyArray2<f64>>, Bound<'py, PyArray2<f64>>);

/// The four Jacobians of `call` as a dict (copied fallibly: a `MemoryError`, not an abort).
fn jacobians_dict<'py>(
    py: Python<'py>,
    j: crate::flex::Jacobians,
    call: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("x", try_array2(py, &j.x, call)?)?;
    drop(j.x);
    out.set_item("u", try_array2(py, &j.u, call)?)?;
    out.set_item("base_wrench", try_array2(py, &j.base_wrench, call)?)?;
    out.set_item("ee_wrench", try_array2(py, &j.ee_wrench, call)?)?;
    out.set_item("wheel_torque", try_array2(py, &j.wheel_torque, call)?)?;
    Ok(out)
}

#[pymethods]
impl PyFlexibleArm {
    #[new]
    #[pyo3(signature = (robot, joints, method="recursive", wheels=None))]
    fn new(
        robot: Bound<'_, PyRobot>,
        joints: Bound<'_, PyFlexibleJoints>,
        method: &str,
        wheels: Option<Bound<'_, super::wheels::PyReactionWheels>>,
    ) -> PyResult<Self> {
        let params = joints.get().resolve(robot.get().robot.dof())?;
        let mut arm = FlexibleArm::new(robot.get().robot.clone(), params)?
            .with_method(super::convert::method(method)?);
        if let Some(w) = &wheels {
            arm = arm.with_wheels(w.get().wheels.clone())?;
        }
        Ok(Self {
            workspaces: Pool::with(arm.workspace()),
            arm,
            robot: robot.unbind(),
            joints: joints.unbind(),
            wheels: wheels.map(Bound::unbind),
        })
    }

    /// The ``ReactionWheels`` on the bus, or None.
    #[getter]
    fn wheels(&self, py: Python<'_>) -> Option<Py<super::wheels::PyReactionWheels>> {
        self.wheels.as_ref().map(|w| w.clone_ref(py))
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
    /// Length of the state vector, 13 + 4n + k (k reaction wheels, 0 without).
    #[getter]
    fn state_size(&self) -> usize {
        self.arm.layout().len()
    }
    /// Length of the tangent ``dx`` of the state, 12 + 4n: ``[δr_B | δφ_B | δq | δθ | δω_B |
    /// δv_B | δq̇ | δθ̇]``, with ``δφ_B`` a rotation vector in the base frame.
    #[getter]
    fn tangent_size(&self) -> usize {
        self.arm.tangent_size()
    }
    /// Where each block of the state sits: a dict from ``"base_pose"``, ``"q"``, ``"theta"``,
    /// ``"base_twist"``, ``"qd"``, ``"theta_dot"``, ``"wheel_speed"`` (empty without wheels) to
    /// a ``slice`` of ``x``.
    #[getter]
    fn state_slices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyDict>> {
        let d = pyo3::types::PyDict::new(py);
        for (name, range) in self.arm.layout().blocks() {
            let slice = pyo3::types::PySlice::new(py, range.start as isize, range.end as isize, 1);
            d.set_item(name, slice)?;
        }
        Ok(d)
    }
    /// ``"recursive"`` or ``"operator"``.
    #[getter]
    fn method(&self) -> &'static str {
        self.arm.method().name()
    }
    /// Per-joint parameters resolved to arrays: (k, j, d, β).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
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
    }

    /// The state ``x`` (13+4n,): ``[r_B | quat_B (x,y,z,w) | q | θ | ω_B | v_B | q̇ | θ̇]``.
    /// Defaults: zero angles and rates, base at the origin with identity attitude and at rest,
    /// ``theta = q`` (relaxed springs). The quaternion is normalised. With reaction wheels the
    /// state ends with their speeds ``wheel_speed`` (k,), rad/s relative to the bus (default 0).
    #[pyo3(signature = (q=None, theta=None, qd=None, theta_dot=None, base_pose=None, base_twist=None, wheel_speed=None))]
    fn state<'py>(
        &self,
        py: Python<'py>,
        q: Option<&Bound<'py, PyAny>>,
        theta: Option<&Bound<'py, PyAny>>,
        qd: Option<&Bound<'py, PyAny>>,
        theta_dot: Option<&Bound<'py, PyAny>>,
        base_pose: Option<&Bound<'py, PyAny>>,
        base_twist: Option<&Bound<'py, PyAny>>,
        wheel_speed: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let layout = self.arm.layout();
        let n = self.n();
        let get = |o: Option<&Bound<'py, PyAny>>, what: &str, len: usize| {
            o.filter(|o| !o.is_none())
                .map(|o| vector(o, what, Some(len)))
                .transpose()
        };
        let (q, theta, qd, theta_dot, base_pose, base_twist) = (
            get(q, "q", n)?,
            get(theta, "theta", n)?,
            get(qd, "qd", n)?,
            get(theta_dot, "theta_dot", n)?,
            get(base_pose, "base_pose", 7)?,
            get(base_twist, "base_twist", 6)?,
        );
        let wheel_speed = match (wheel_speed.filter(|o| !o.is_none()), layout.wheels) {
            (Some(_), 0) => {
                return Err(ModelError::new_err(
                    "wheel_speed: the arm has no reaction wheels; give none",
                ))
            }
            (w, k) => get(w, "wheel_speed", k)?,
        };
        let mut x = self.arm.state(&StateSpec {
            q: q.as_deref(),
            theta: theta.as_deref(),
            qd: qd.as_deref(),
            theta_dot: theta_dot.as_deref(),
            base_pose: base_pose.as_deref(),
            base_twist: base_twist.as_deref(),
        })?;
        if let Some(w) = wheel_speed {
            x[layout.wheel_speed()].copy_from_slice(&w);
        }
        Ok(array1(py, &x))
    }

    /// ``ẋ`` (13+4n+k,) at state ``x`` with motor torques ``u`` (n,), base wrench and EE wrench
    /// (6,), and, with k reaction wheels, the wheel torque commands ``wheel_torque`` (k,), all
    /// defaulting to zero. The wheel torques are saturated at ``x`` as a step would apply them.
    #[pyo3(signature = (x, u=None, base_wrench=None, ee_wrench=None, wheel_torque=None))]
    fn derivative<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
        wheel_torque: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        let inputs = InputArgs::parse(self.arm.robot(), u, base_wrench, ee_wrench)?
            .wheels(&self.arm, wheel_torque)?;
        let mut xdot = vec![0.0; x.len()];
        self.arm
            .derivative(&mut self.ws(), &x, &inputs.inputs(), &mut xdot)?;
        Ok(array1(py, &xdot))
    }

    /// One RK4 step of ``dt`` seconds from ``x``, inputs held (the wheel torques saturated once,
    /// at ``x``); returns the new state.
    #[pyo3(signature = (x, dt, u=None, base_wrench=None, ee_wrench=None, wheel_torque=None))]
    fn step<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        dt: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
        wheel_torque: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let mut x = vector(x, "x", Some(self.arm.layout().len()))?;
        let dt = real(dt, "dt")?;
        let inputs = InputArgs::parse(self.arm.robot(), u, base_wrench, ee_wrench)?
            .wheels(&self.arm, wheel_torque)?;
        self.arm
            .step(&mut self.ws(), &mut x, dt, &inputs.inputs())?;
        Ok(array1(py, &x))
    }

    /// The RK4 stability limit at state ``x`` (default: at rest) of the closed loop of the arm,
    /// its joints and the controller ``u`` (a ``MotorPD``, whose gains close the loop, its
    /// torque held over each step; None or an array, open loop; a callable, whose feedback is
    /// unknown, open loop), from the eigenvalues of the linearised loop's RK4 step matrix.
    /// Returns a ``StabilityLimit``: ``.dt``, the largest stable step (s), and
    /// ``.fastest_mode``, the fastest eigenvalue of the continuous closed loop (1/s).
    #[pyo3(signature = (x=None, u=None))]
    fn rk4_stability_limit(
        &self,
        x: Option<&Bound<'_, PyAny>>,
        u: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyStabilityLimit> {
        let x = match x.filter(|o| !o.is_none()) {
            Some(x) => self.state_arg(x, "x")?,
            None => self.arm.rest_state(),
        };
        let mut error = None;
        let controller = controller(u, self.n(), &mut error)?;
        let limit = self.arm.rk4_stability_limit(&x, &*controller)?;
        Ok(PyStabilityLimit { limit })
    }

    /// Motor PD gains ``(kp, kd)``, (n,) each (N·m/rad, N·m·s/rad), that give every joint a
    /// closed loop of ``bandwidth`` (Hz) and ``damping_ratio`` (ζ > 0), chosen from its motor
    /// inertia ``j``, the link-side inertia ``m`` it drives at the configuration ``q`` (rad,
    /// default zeros; ``m`` is the diagonal of the free-floating joint-space inertia
    /// ``M_r − M_br M_b⁻¹ M_rb``: base free, the other joints held by their servos), its spring
    /// ``k``, ``d`` and motor friction ``β``. Two roots of each joint's closed loop are put at
    /// ``s² + 2ζω s + ω² = 0``, ``ω = 2π·bandwidth``, exactly; for a stiff joint this is
    /// ``kp = (j + m) ω²``, ``kd = 2ζω (j + m) − β`` (docs/model.md §5.3). No step size enters:
    /// choose ``dt`` within ``rk4_stability_limit`` of the resulting loop. ``kd`` is 0 where the
    /// motor friction alone damps more than asked. Raises ``ModelError`` naming the joint whose
    /// link resonates at or below the bandwidth.
    #[pyo3(signature = (bandwidth, damping_ratio=None, q=None))]
    fn motor_pd_gains<'py>(
        &self,
        py: Python<'py>,
        bandwidth: &Bound<'py, PyAny>,
        damping_ratio: Option<&Bound<'py, PyAny>>,
        q: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<ArrayPair<'py>> {
        let bandwidth = real(bandwidth, "bandwidth")?;
        let damping_ratio = match damping_ratio {
            Some(z) => real(z, "damping_ratio")?,
            None => 1.0,
        };
        let q = vector_or(q, "q", self.n(), 0.0)?;
        let gains = self.arm.motor_pd_gains(&q, bandwidth, damping_ratio)?;
        Ok((array1(py, &gains.kp), array1(py, &gains.kd)))
    }

    /// The motor servo of a tracking loop, ``(kp, kd)`` (n each): ``kp = j ω²`` (N·m/rad) and
    /// ``kd = 2 j ω`` (N·m·s/rad), ``ω = 2π bandwidth`` (Hz), ``j`` the motor inertia: each motor
    /// a critically damped servo on its own inertia (``orbitflex plan``'s tracking PD).
    /// :meth:`motor_pd_gains` places the loop on the link and the spring as well.
    fn motor_servo_gains<'py>(
        &self,
        py: Python<'py>,
        bandwidth: &Bound<'py, PyAny>,
    ) -> PyResult<ArrayPair<'py>> {
        let (kp, kd) = self.arm.motor_servo_gains(real(bandwidth, "bandwidth")?)?;
        Ok((array1(py, &kp), array1(py, &kd)))
    }

    /// ``x ⊕ dx``: the state ``x`` moved along the tangent ``dx`` (12+4n): ``r_B + δr_B``
    /// (inertial frame), ``quat_B ⊗ Exp(δφ_B)`` (``δφ_B`` a rotation vector in the base frame,
    /// rad), every other block added.
    fn integrate<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        dx: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        let dx = vector(dx, "dx", Some(self.arm.tangent_size()))?;
        Ok(array1(py, &self.arm.integrate(&x, &dx)?))
    }

    /// ``x1 ⊖ x0``: the tangent (12+4n) with ``integrate(x0, difference(x0, x1)) == x1``; the
    /// base rotation is taken the short way (at most π).
    fn difference<'py>(
        &self,
        py: Python<'py>,
        x0: &Bound<'py, PyAny>,
        x1: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let len = Some(self.arm.layout().len());
        let (x0, x1) = (vector(x0, "x0", len)?, vector(x1, "x1", len)?);
        Ok(array1(py, &self.arm.difference(&x0, &x1)?))
    }

    /// The Jacobians of :meth:`derivative` in tangent coordinates, as a dict: ``"x"``
    /// (t, t), ``"u"`` (t, n), ``"base_wrench"`` (t, 6), ``"ee_wrench"`` (t, 6k) and
    /// ``"wheel_torque"`` (t, k_w; no columns without wheels), ``t = 12 + 4n + k_w``:
    /// ``d(dx)/dt = F dx + G du + …`` for ``x = x̄ ⊕ dx`` (see :meth:`integrate`). With reaction
    /// wheels the tangent ends with the wheel speeds, and ``wheel_torque`` (k_w,) commands are
    /// saturated at ``x`` as :meth:`derivative` does (a clipped command has zero slope).
    #[pyo3(signature = (x, u=None, base_wrench=None, ee_wrench=None, wheel_torque=None))]
    fn derivative_jacobians<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
        wheel_torque: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        let inputs = InputArgs::parse(self.arm.robot(), u, base_wrench, ee_wrench)?
            .wheels(&self.arm, wheel_torque)?;
        let j = self
            .arm
            .derivative_jacobians(&mut self.ws(), &x, &inputs.inputs())?;
        jacobians_dict(py, j, "derivative_jacobians")
    }

    /// The Jacobians of one RK4 :meth:`step` of ``dt`` (inputs held), in tangent coordinates at
    /// ``x`` and at the new state, including the quaternion's renormalisation: a dict with the
    /// keys of :meth:`derivative_jacobians`.
    #[pyo3(signature = (x, dt, u=None, base_wrench=None, ee_wrench=None))]
    fn step_jacobians<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        dt: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        let dt = real(dt, "dt")?;
        let inputs = InputArgs::parse(self.arm.robot(), u, base_wrench, ee_wrench)?;
        let j = self
            .arm
            .step_jacobians(&mut self.ws(), &x, dt, &inputs.inputs())?;
        jacobians_dict(py, j, "step_jacobians")
    }

    /// ``(F, G)`` of :meth:`derivative_jacobians` at ``x`` with torques ``u`` (default zero):
    /// the continuous-time linearisation ``d(dx)/dt = F dx + G du`` for control design.
    #[pyo3(signature = (x, u=None))]
    fn linearize<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<MatrixPair<'py>> {
        let x = vector(x, "x", Some(self.arm.layout().len()))?;
        let inputs = InputArgs::parse(self.arm.robot(), u, None, None)?;
        let j = self
            .arm
            .derivative_jacobians(&mut self.ws(), &x, &inputs.inputs())?;
        Ok((
            try_array2(py, &j.x, "linearize")?,
            try_array2(py, &j.u, "linearize")?,
        ))
    }

    /// Flexible-joint inverse dynamics (differential flatness): what the motors and the base do
    /// so that the links move with ``q`` (rad), ``qd`` (rad/s), ``qdd`` (rad/s²), ``qddd``
    /// (rad/s³) and ``qdddd`` (rad/s⁴) at this instant (n each, no EE wrench).
    ///
    /// ``base="held"``: the base's actuators hold it inertially still (``V_B = 0``, ``α_B = 0``)
    /// and ``base_wrench`` says with what; ``base="free"``: free floating with zero total
    /// momentum (as from rest), ``base_wrench = 0`` and ``base_twist``, ``base_acc`` say how the
    /// base moves.
    ///
    /// ``deflection``: the current ``θ − q`` (rad, n), required exactly when some joint has
    /// damping ``d > 0`` (its deflection then obeys ``d δ̇ + k δ = τ`` and depends on the
    /// motion's history; ``plan_slew`` integrates it); it must be omitted when every ``d = 0``
    /// (then ``θ − q = τ/k``). With some joints damped and some not, only the damped joints'
    /// entries are used; an undamped joint's deflection is always ``τ/k``.
    ///
    /// Returns a dict of arrays: ``theta`` (rad), ``theta_dot`` (rad/s), ``theta_ddot``
    /// (rad/s²): motor angles and rates, link side; ``u = j θ̈ + β θ̇ + τ`` (N·m): motor
    /// torques; ``tau`` (N·m): spring torques on the links (the rigid inverse dynamics); and,
    /// in the base frame, ``base_twist`` ``[ω_B (rad/s); v_B (m/s)]``, ``base_acc``, the
    /// classical ``[ω̇_B (rad/s²); v̇_B + ω_B × v_B (m/s²)]`` as in :meth:`Robot.forward_dynamics`,
    /// and ``base_wrench`` ``[moment (N·m, about the base origin); force (N)]`` applied to the
    /// base. With these, :meth:`derivative` at the matching state returns ``qdd`` and
    /// ``theta_ddot``.
    #[pyo3(signature = (q, qd, qdd, qddd, qdddd, base="held", deflection=None))]
    fn inverse_dynamics<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        qd: &Bound<'py, PyAny>,
        qdd: &Bound<'py, PyAny>,
        qddd: &Bound<'py, PyAny>,
        qdddd: &Bound<'py, PyAny>,
        base: &str,
        deflection: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let n = Some(self.n());
        let (q, qd, qdd, qddd, qdddd) = (
            vector(q, "q", n)?,
            vector(qd, "qd", n)?,
            vector(qdd, "qdd", n)?,
            vector(qddd, "qddd", n)?,
            vector(qdddd, "qdddd", n)?,
        );
        let base = BaseMode::from_name(base)?;
        // the length is checked after the misuse (deflection given for undamped joints)
        let deflection = deflection
            .filter(|o| !o.is_none())
            .map(|o| vector(o, "deflection", None))
            .transpose()?;
        let motion = LinkMotion {
            q: &q,
            qd: &qd,
            qdd: &qdd,
            qddd: &qddd,
            qdddd: &qdddd,
        };
        let out = self
            .arm
            .inverse_dynamics(&motion, base, deflection.as_deref())?;
        let d = PyDict::new(py);
        for (name, v) in [
            ("theta", &out.theta[..]),
            ("theta_dot", &out.theta_dot[..]),
            ("theta_ddot", &out.theta_ddot[..]),
            ("u", &out.u[..]),
            ("tau", &out.tau[..]),
            ("base_twist", &out.base_twist[..]),
            ("base_acc", &out.base_acc[..]),
            ("base_wrench", &out.base_wrench[..]),
        ] {
            d.set_item(name, array1(py, v))?;
        }
        Ok(d)
    }

    /// Total energy at state ``x`` (J): rigid kinetic + motor kinetic + spring.
    fn energy(&self, x: &Bound<'_, PyAny>) -> PyResult<f64> {
        let x = self.state_arg(x, "x")?;
        let e = self.arm.energy(&mut self.ws(), &x);
        self.arm
            .check_overflow("energy", &[&[e]], &[("x", &x, 2)])?;
        Ok(e)
    }

    /// Total momentum ``[angular (N·m·s); linear (N·s)]`` at state ``x``, inertial frame, about
    /// the inertial origin.
    fn momentum<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let x = self.state_arg(x, "x")?;
        let h = self.arm.momentum(&mut self.ws(), &x);
        self.arm
            .check_overflow("momentum", &[&h], &[("x", &x, 1)])?;
        Ok(array1(py, &h))
    }

    /// EE pose ``[position (m); quaternion (x, y, z, w), w ≥ 0]`` in the inertial frame at
    /// state ``x``. ``ee``: an end-effector link name or an index into ``robot.ee_links``;
    /// ``None`` is the only one (an error listing them when the robot has several).
    #[pyo3(signature = (x, ee=None))]
    fn ee_pose<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        ee: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let e = super::convert::ee_arg(self.arm.robot(), ee)?;
        let x = self.state_arg(x, "x")?;
        let pose = self.arm.ee_pose(&x, e);
        self.arm
            .check_overflow("ee_pose", &[&pose], &[("x", &x, 1)])?;
        Ok(array1(py, &pose))
    }

    /// Integrates ``steps`` RK4 steps of ``dt`` seconds from ``x0`` and returns a ``Trajectory``.
    ///
    /// ``u``: None (zero), a constant (n,), a table (steps, n) with one row per step, a callable
    /// ``u(t, x) -> (n,)`` called once per step, or an ``orbitflex.MotorPD`` (runs in Rust
    /// without the GIL). ``base_wrench`` / ``ee_wrench``: None, (6,) or (steps, 6); with k
    /// end-effectors ``ee_wrench`` is (k, 6) or (steps, k, 6), or a dict from EE link name to
    /// (6,) or (steps, 6); ``base_wrench`` may also be a callable ``f(t, x) -> (6,)`` (thrusters,
    /// a custom ACS closing a loop). ``wheel_torque`` (an arm with k reaction wheels): the
    /// commands, None, (k,), (steps, k), a callable ``(t, x) -> (k,)`` or an
    /// ``orbitflex.AttitudePD`` (in Rust without the GIL); saturated once per step, the applied
    /// torques recorded in ``Trajectory.wheel_torque``. Every callable is called once per step
    /// with the state at its start, its row held over the step. ``progress``:
    /// an optional callable ``progress(done, steps)`` called about every thousand steps and at
    /// the end.
    ///
    /// ``record_every`` (int ≥ 1, default 1: every row): keep rows 0, k, 2k, … and always the
    /// final row, that is ``steps // k + 1`` rows, plus one when ``k`` does not divide ``steps``.
    /// Each kept row and its time ``t = j·dt`` are bit for bit those of the full run; ``u`` holds,
    /// for each kept row but the final one, the torque held during the step that starts there
    /// (rows − 1, n). Memory is O(rows), not O(steps).
    ///
    /// ``on_rows``: an optional callable ``on_rows(t, x, u)`` that receives the kept rows in
    /// order, each exactly once, in chunks of at most ``chunk_rows`` rows (default 1024): ``t``
    /// (r,) in s, ``x`` (r, 13+4n), ``u`` (r, n), or (r − 1, n) in the chunk that holds the final
    /// row (new arrays, yours to keep). The last partial chunk comes at the end of the run, or
    /// before ``SimulationError`` is raised. The run holds the GIL only to deliver a chunk. With
    /// ``on_rows`` the returned ``Trajectory`` holds only the final row (the state to continue
    /// from; ``u`` (0, n)), so memory stays O(chunk_rows) however long the run. An exception in
    /// ``on_rows`` stops the run and is raised as it is.
    ///
    /// Warns (``RuntimeWarning``) before it starts when ``dt`` is past the RK4 stability limit of
    /// the closed loop at ``x0`` (see :meth:`rk4_stability_limit`), and when a ``Sampled``
    /// ``MotorPD`` or ``AttitudePD`` makes a loop that is unstable at its rate and delay (the
    /// spectral radius of the zero-order-hold discretisation of the linear model at ``x0``,
    /// :func:`orbitflex.analysis.sampled_loop`). Raises ``SimulationError``
    /// (with ``.trajectory``, the finite part, ``.step`` and ``.time``) when the state turns
    /// non-finite or the controller raises or returns non-finite torques; its trajectory keeps
    /// the rows kept so far and ends on the last good state (with ``on_rows``: that state
    /// alone). Ctrl-C stops the run.
    #[pyo3(signature = (x0, dt, steps, u=None, base_wrench=None, ee_wrench=None, *, wheel_torque=None, progress=None, record_every=None, on_rows=None, chunk_rows=None, target=None, capture=None, capture_ee=None))]
    fn simulate<'py>(
        slf: &Bound<'py, Self>,
        x0: &Bound<'py, PyAny>,
        dt: &Bound<'py, PyAny>,
        steps: &Bound<'py, PyAny>,
        u: Option<&Bound<'py, PyAny>>,
        base_wrench: Option<&Bound<'py, PyAny>>,
        ee_wrench: Option<&Bound<'py, PyAny>>,
        wheel_torque: Option<&Bound<'py, PyAny>>,
        progress: Option<&Bound<'py, PyAny>>,
        record_every: Option<&Bound<'py, PyAny>>,
        on_rows: Option<&Bound<'py, PyAny>>,
        chunk_rows: Option<&Bound<'py, PyAny>>,
        target: Option<&Bound<'py, PyAny>>,
        capture: Option<&Bound<'py, PyAny>>,
        capture_ee: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<PyTrajectory> {
        let py = slf.py();
        let arm = &slf.get().arm;
        let layout = arm.layout();
        let dt = real(dt, "dt")?;
        let steps = count(steps, "steps")?;
        let x0 = vector(x0, "x0", Some(layout.len()))?;
        let record_every = record_every_arg(record_every)?;
        let capturing = Capturing::from_args(arm, target, capture, capture_ee)?;
        let on_rows = OnRows::from_args(on_rows, chunk_rows, capturing.is_some())?;
        let mut errors = ChannelErrors::default();
        let mut channels =
            Channels::from_args(arm, u, base_wrench, ee_wrench, wheel_torque, &mut errors)?;
        let run = Run::new(&x0, dt, steps).recording_every(record_every);
        run.check(arm, &channels.drive())?;
        // the buffers, before the warning: a run whose record cannot fit does not start
        let mut stream_error = None;
        let mut sink = sink(&run, layout, on_rows.as_ref(), &mut stream_error)?;
        warn_before_run(py, arm, &run, u, wheel_torque, &*channels.u)?;
        let mut progress = Progress::from_arg(progress);
        let recorder = sink.recorder();
        let (result, record) = match &capturing {
            None => {
                let result =
                    record_releasing_gil(py, arm, &run, &mut channels, &mut progress, recorder)?;
                (result, None)
            }
            Some(capturing) => {
                let (result, record) = capture_releasing_gil(
                    py,
                    arm,
                    &run,
                    &mut channels,
                    &mut progress,
                    recorder,
                    capturing,
                )?;
                (result, Some(record))
            }
        };
        drop(channels);
        let cause = controller_failure(py, errors.first())?;
        let traj = sink.into_trajectory();
        // an exception from on_rows stops the run and is raised as it is
        if let Some(e) = stream_error {
            return Err(e);
        }
        let record = || -> PyResult<PyTrajectory> {
            let traj = PyTrajectory::from_run(py, slf.clone().unbind(), traj)?;
            Ok(match (record, &capturing) {
                (Some(record), Some(c)) => {
                    traj.with_capture(CaptureInfo::new(py, slf, record, &c.target)?)
                }
                _ => traj,
            })
        };
        finish_run(py, result, record, cause, &progress, steps)
    }

    /// Pickle support (with its Robot and FlexibleJoints).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let args = (me.robot(py), me.joints(py), me.method(), me.wheels(py));
        Ok((
            slf.get_type().into_any().unbind(),
            args.into_pyobject(py)?.into_any().unbind(),
        ))
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

/// ``on_rows`` and its ``chunk_rows`` (default [`CHUNK_ROWS`]), when the rows are streamed.
struct OnRows {
    callback: Py<PyAny>,
    chunk_rows: usize,
}

impl OnRows {
    /// `None` without ``on_rows``; refuses ``on_rows`` with a target, one that is not callable,
    /// and ``chunk_rows`` without ``on_rows``.
    fn from_args(
        on_rows: Option<&Bound<'_, PyAny>>,
        chunk_rows: Option<&Bound<'_, PyAny>>,
        capturing: bool,
    ) -> PyResult<Option<Self>> {
        let on_rows = on_rows.filter(|o| !o.is_none());
        if capturing && on_rows.is_some() {
            return Err(ModelError::new_err(
                "on_rows: not with a target: the target's rows, the events and the momentum \
                 that includes the target are kept with the arm's rows, which on_rows(t, x, u) \
                 would not carry; leave on_rows out and thin the rows with record_every, or run \
                 the approach with the target until after the capture, then continue from \
                 traj.x[-1] on traj.arm_after (the target is part of it) with on_rows",
            ));
        }
        if let Some(callback) = on_rows {
            if !callback.is_callable() {
                return Err(ModelError::new_err(format!(
                    "on_rows: expected a callable on_rows(t, x, u), given {}",
                    callback.get_type().name()?
                )));
            }
        }
        let chunk_rows =
            match (chunk_rows.filter(|o| !o.is_none()), on_rows) {
                (Some(c), Some(_)) => positive_count(c, "chunk_rows")?,
                (Some(_), None) => return Err(ModelError::new_err(
                    "chunk_rows: sizes the chunks given to on_rows; give on_rows too, or leave \
                     chunk_rows out",
                )),
                (None, _) => CHUNK_ROWS,
            };
        Ok(on_rows.map(|c| OnRows {
            callback: c.clone().unbind(),
            chunk_rows,
        }))
    }
}

/// Where the rows of `run` go: a `Trajectory` reserved for them, or chunks of
/// ``chunk_rows`` rows for ``on_rows`` (whose exception goes to `error`).
fn sink<'a>(
    run: &Run<'_>,
    layout: crate::StateLayout,
    on_rows: Option<&'a OnRows>,
    error: &'a mut Option<PyErr>,
) -> PyResult<Sink<impl FnMut(Chunk<'_>) -> crate::Result<()> + Send + 'a>> {
    let (steps, every) = (run.steps, run.record_every);
    Ok(match on_rows {
        None => Sink::Memory(Trajectory::reserved(layout, steps, every)?),
        Some(OnRows {
            callback,
            chunk_rows,
        }) => {
            let rows = (*chunk_rows).min(integrate::recorded_rows(steps, every));
            let chunks = Chunks::new(layout, rows, move |chunk| deliver(callback, chunk, error))?;
            Sink::Stream(Stream::new(layout, chunks))
        }
    })
}

/// The warnings of a run before it starts: a `Sampled` loop unstable at its rate and delay, a
/// step past the RK4 stability limit of the closed loop at `x0`.
fn warn_before_run(
    py: Python<'_>,
    arm: &FlexibleArm,
    run: &Run<'_>,
    u: Option<&Bound<'_, PyAny>>,
    wheel_torque: Option<&Bound<'_, PyAny>>,
    motors: &dyn crate::control::Controller,
) -> PyResult<()> {
    let sampled = super::analysis::sampled_warnings(arm, run.x0, u, wheel_torque)?;
    let rk4 = integrate::stability_warning(arm, run.x0, run.dt, motors)?;
    for warning in rk4.into_iter().chain(sampled) {
        runtime_warning(py, warning)?;
    }
    Ok(())
}

/// A callable controller's exception, the cause of the run's failure; KeyboardInterrupt,
/// SystemExit and other non-Exception errors are not a controller failure: they are raised as
/// they are.
fn controller_failure(py: Python<'_>, error: Option<PyErr>) -> PyResult<Option<PyErr>> {
    match error {
        Some(e) if !e.is_instance_of::<pyo3::exceptions::PyException>(py) => Err(e),
        cause => Ok(cause),
    }
}

/// The trajectory (`record`) of a run that completed, after the last progress report, or the
/// `SimulationError` that carries it (with the controller's exception as its cause).
fn finish_run(
    py: Python<'_>,
    result: crate::Result<()>,
    record: impl FnOnce() -> PyResult<PyTrajectory>,
    cause: Option<PyErr>,
    progress: &Progress,
    steps: usize,
) -> PyResult<PyTrajectory> {
    match result {
        Ok(()) => {
            progress.finish(py, steps, steps)?;
            record()
        }
        Err(error) => match error {
            Error::Simulation { step, time, .. } => {
                let message = error.to_string();
                let traj = Py::new(py, record()?)?.into_any();
                Err(simulation_error(py, message, step, time, traj, cause)?)
            }
            other => Err(other.into()),
        },
    }
}
