//! `orbitflex.Target`, `orbitflex.capture` and the `Capture` it returns.

use super::arm::PyFlexibleArm;
use super::convert::{array1, array2, real, vector};
use super::robot::{inertia_matrix, PyRobot};
use crate::capture::{capture, Capture, Target};
use crate::spatial::Vec3;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

/// A free, torque-free rigid body to capture: a client satellite or a piece of debris, with a
/// handle to grasp (model §9).
///
/// ``Target(mass, inertia, pose, twist, grasp, com=None, name="target")``:
///
/// - ``mass`` (kg, > 0);
/// - ``inertia`` (3, 3): the rotational inertia about the centre of mass, in the target's body
///   axes (kg·m²; symmetric, positive definite, the triangle inequality; three principal moments
///   (3,) are also accepted);
/// - ``pose`` (7,): ``[r_t; quat_t (x, y, z, w)]``, the body frame's origin in the inertial frame
///   and the quaternion mapping body to inertial components, as the base's (normalised);
/// - ``twist`` (6,): ``[ω; v]`` in body components, ``v`` the velocity of the body frame's origin
///   (rad/s, m/s), as the base twist;
/// - ``grasp`` (7,): the handle's pose ``[p; quat]`` in the body frame (a unit quaternion, within
///   1e-6);
/// - ``com`` (3,): the centre of mass in the body frame (m, default its origin).
///
/// Immutable; :meth:`at_state` gives the target at another state ``[r_t; quat_t; ω; v]`` (13).
#[pyclass(name = "Target", module = "orbitflex", frozen)]
pub struct PyTarget {
    pub(crate) target: Target,
}

#[pymethods]
impl PyTarget {
    #[new]
    #[pyo3(signature = (mass, inertia, pose, twist, grasp, com=None, name="target"))]
    fn new(
        mass: &Bound<'_, PyAny>,
        inertia: &Bound<'_, PyAny>,
        pose: &Bound<'_, PyAny>,
        twist: &Bound<'_, PyAny>,
        grasp: &Bound<'_, PyAny>,
        com: Option<&Bound<'_, PyAny>>,
        name: &str,
    ) -> PyResult<Self> {
        let what = |part: &str| format!("target '{name}': {part}");
        let mass = real(mass, &what("mass"))?;
        let inertia = inertia_matrix(inertia, &what("inertia"))?;
        let pose = vector(pose, &what("pose"), Some(7))?;
        let twist = vector(twist, &what("twist"), Some(6))?;
        let grasp = vector(grasp, &what("grasp"), Some(7))?;
        let com = match com.filter(|o| !o.is_none()) {
            Some(c) => Vec3::from_column_slice(&vector(c, &what("com"), Some(3))?),
            None => Vec3::zeros(),
        };
        let target = Target::new(mass, inertia, &pose, &twist, &grasp)?
            .named(name)
            .with_com(com)?;
        Ok(Self { target })
    }

    /// The name given.
    #[getter]
    fn name(&self) -> &str {
        self.target.name()
    }
    /// Mass (kg).
    #[getter]
    fn mass(&self) -> f64 {
        self.target.mass()
    }
    /// Rotational inertia about the centre of mass, body axes (3, 3), kg·m².
    #[getter]
    fn inertia<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        array2(py, self.target.inertia_about_com())
    }
    /// Centre of mass in the body frame (3,), m.
    #[getter]
    fn com<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.target.com().as_slice())
    }
    /// ``[r_t; quat_t (x, y, z, w)]`` (7,), the quaternion normalised.
    #[getter]
    fn pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.target.pose())
    }
    /// ``[ω; v]`` (6,), body frame.
    #[getter]
    fn twist<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.target.twist().to_array())
    }
    /// The handle's pose ``[p; quat]`` in the body frame (7,), the quaternion normalised.
    #[getter]
    fn grasp<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.target.grasp())
    }
    /// The state ``[r_t; quat_t; ω; v]`` (13,).
    #[getter]
    fn state<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.target.state())
    }
    /// The handle's inertial pose ``[position; quat (x, y, z, w), w ≥ 0]`` (7,).
    fn grasp_pose<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.target.grasp_pose())
    }
    /// Total momentum ``[angular about the inertial origin; linear]`` (6,), inertial components
    /// (N·m·s, N·s), as ``Robot.momentum``.
    fn momentum<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.target.momentum())
    }
    /// Kinetic energy ``½ Wᵀ Y W`` (J).
    fn kinetic_energy(&self) -> f64 {
        self.target.kinetic_energy()
    }
    /// The rate of :attr:`state` (13,) of the torque-free body: ``ṙ = R v``,
    /// ``quat' = ½ quat ⊗ (ω, 0)``, Euler's equations about the centre of mass, and ``v̇`` the rate
    /// of the body-frame components of the origin's velocity.
    fn derivative<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.target.derivative())
    }
    /// This target at the state ``[r_t; quat_t; ω; v]`` (13,), validated.
    fn at_state(&self, state: &Bound<'_, PyAny>) -> PyResult<Self> {
        let what = format!("target '{}': state", self.target.name());
        let state = vector(state, &what, Some(crate::capture::TARGET_STATE_LEN))?;
        Ok(Self {
            target: self.target.at_state(&state)?,
        })
    }

    /// Pickles as the constructor's arguments (for process pools and Dask workers).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let py = slf.py();
        let t = &slf.get().target;
        let args = (
            t.mass(),
            array2(py, t.inertia_about_com()),
            array1(py, t.pose()),
            array1(py, &t.twist().to_array()),
            array1(py, t.grasp()),
            array1(py, t.com().as_slice()),
            t.name(),
        );
        Ok((
            slf.get_type().into_any(),
            args.into_pyobject(py)?.into_any(),
        ))
    }

    fn __repr__(&self) -> String {
        let t = &self.target;
        format!(
            "Target(name={:?}, mass={}, pose={:?}, twist={:?})",
            t.name(),
            t.mass(),
            t.pose(),
            t.twist().to_array()
        )
    }
}

/// The outcome of :func:`capture`.
///
/// - ``arm``: the combined :class:`FlexibleArm`, the target joined to the grasping end-effector's
///   body as a payload at the relative pose of the moment of capture (``Robot.with_payload`` of
///   ``target.mass``, :attr:`payload_inertia`, :attr:`payload_com`);
/// - ``x``: the state just after (for ``arm``): the same poses, ``q``, ``θ`` and ``θ̇``; the new
///   base twist and ``q̇``;
/// - ``impulse`` (6,): ``[moment (N·m·s); force (N·s)]`` that the end-effector exerts on the
///   target, in the EE frame about its origin (the sign of ``ee_wrench``);
/// - ``energy_loss`` (J, ≥ 0): the kinetic energy the grasp dissipates;
/// - ``relative_twist`` (6,): the EE's twist relative to the target just before, EE frame;
/// - ``target_twist`` (6,): the target's twist just after, its body frame;
/// - ``payload_com`` (3,), ``payload_inertia`` (3, 3): the target's centre of mass (m) and
///   rotational inertia about it (kg·m²), in the EE frame;
/// - ``ee``: the index of the grasping end-effector in ``robot.ee_links``.
#[pyclass(name = "Capture", module = "orbitflex", frozen)]
pub struct PyCapture {
    capture: Capture,
    arm: Py<PyFlexibleArm>,
}

#[pymethods]
impl PyCapture {
    /// The combined arm.
    #[getter]
    fn arm(&self, py: Python<'_>) -> Py<PyFlexibleArm> {
        self.arm.clone_ref(py)
    }
    /// The state just after the capture.
    #[getter]
    fn x<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.capture.x)
    }
    /// ``[moment; force]`` the EE exerts on the target (EE frame; N·m·s, N·s).
    #[getter]
    fn impulse<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.capture.impulse.to_array())
    }
    /// The kinetic energy dissipated (J).
    #[getter]
    fn energy_loss(&self) -> f64 {
        self.capture.energy_loss
    }
    /// The EE's twist relative to the target just before (EE frame).
    #[getter]
    fn relative_twist<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.capture.relative_twist.to_array())
    }
    /// The target's twist just after (its body frame).
    #[getter]
    fn target_twist<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.capture.target_twist.to_array())
    }
    /// The target's centre of mass in the EE frame (m).
    #[getter]
    fn payload_com<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.capture.payload_com.as_slice())
    }
    /// The target's rotational inertia about its centre of mass, EE axes (kg·m²).
    #[getter]
    fn payload_inertia<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        array2(py, &self.capture.payload_inertia)
    }
    /// The grasping end-effector's index.
    #[getter]
    fn ee(&self) -> usize {
        self.capture.ee
    }

    /// Pickles as its values and its combined arm, bit for bit ([`Self::restore`]).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let c = &me.capture;
        let p = &c.payload;
        let args = (
            me.arm.clone_ref(py),
            c.x.clone(),
            (
                c.impulse.to_array().to_vec(),
                c.energy_loss,
                c.relative_twist.to_array().to_vec(),
                c.target_twist.to_array().to_vec(),
            ),
            (
                p.mass,
                p.com.as_slice().to_vec(),
                p.rotational.as_slice().to_vec(),
                c.payload_com.as_slice().to_vec(),
                c.payload_inertia.as_slice().to_vec(),
            ),
            c.ee,
        );
        Ok((
            slf.get_type().getattr("_restore")?.unbind(),
            args.into_pyobject(py)?.into_any().unbind(),
        ))
    }

    /// The capture from the values [`Self::__reduce__`] gives (for pickle).
    #[staticmethod]
    #[pyo3(name = "_restore")]
    fn restore(
        arm: Bound<'_, PyFlexibleArm>,
        x: Vec<f64>,
        jump: (Vec<f64>, f64, Vec<f64>, Vec<f64>),
        payload: (f64, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>),
        ee: usize,
    ) -> PyResult<Self> {
        use crate::spatial::{Force, Inertia, Mat3, Motion};
        let (impulse, energy_loss, relative_twist, target_twist) = jump;
        let (mass, com, rotational, payload_com, payload_inertia) = payload;
        let length = |v: &[f64], n: usize, what: &str| {
            if v.len() == n {
                Ok(())
            } else {
                Err(super::errors::ModelError::new_err(format!(
                    "Capture.{what}: expected {n} numbers, given {}",
                    v.len()
                )))
            }
        };
        length(&impulse, 6, "impulse")?;
        length(&relative_twist, 6, "relative_twist")?;
        length(&target_twist, 6, "target_twist")?;
        length(&com, 3, "payload com")?;
        length(&payload_com, 3, "payload_com")?;
        length(&rotational, 9, "payload rotational inertia")?;
        length(&payload_inertia, 9, "payload_inertia")?;
        let flex = arm.get().arm.clone();
        length(&x, flex.layout().len(), "x")?;
        Ok(Self {
            capture: Capture {
                arm: flex,
                x,
                impulse: Force::from_slice(&impulse),
                energy_loss,
                relative_twist: Motion::from_slice(&relative_twist),
                target_twist: Motion::from_slice(&target_twist),
                payload: Inertia {
                    mass,
                    com: Vec3::from_column_slice(&com),
                    rotational: Mat3::from_column_slice(&rotational),
                },
                payload_com: Vec3::from_column_slice(&payload_com),
                payload_inertia: Mat3::from_column_slice(&payload_inertia),
                ee,
            },
            arm: arm.unbind(),
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "Capture(impulse={:?}, energy_loss={})",
            self.capture.impulse.to_array(),
            self.capture.energy_loss
        )
    }
}

/// Captures ``target`` with an end-effector of ``arm`` at state ``x``: an instantaneous,
/// perfectly inelastic grasp that makes the EE frame and the target move as one rigid body, in
/// all six degrees of freedom, at their current relative pose (model §9).
///
/// The impulse passes through the links only: the springs carry none, so the motor rates ``θ̇``
/// keep their values, while the base twist and ``q̇`` jump. Total linear and angular momentum of
/// arm and target are kept; kinetic energy is lost. ``ee``: the grasping end-effector (a link
/// name or an index into ``robot.ee_links``; ``None`` is the only one). Returns a
/// :class:`Capture`. O(n).
#[pyfunction]
#[pyo3(name = "capture", signature = (arm, x, target, ee=None))]
pub fn py_capture(
    py: Python<'_>,
    arm: &Bound<'_, PyFlexibleArm>,
    x: &Bound<'_, PyAny>,
    target: &Bound<'_, PyTarget>,
    ee: Option<&Bound<'_, PyAny>>,
) -> PyResult<PyCapture> {
    let flex = &arm.get().arm;
    let ee = super::convert::ee_arg(flex.robot(), ee)?;
    let x = vector(x, "x (state)", Some(flex.layout().len()))?;
    let result = capture(flex, &x, &target.get().target, Some(ee))?;
    let combined = combined_arm(py, arm, &result.arm)?;
    Ok(PyCapture {
        capture: result,
        arm: combined,
    })
}

/// The Python `FlexibleArm` of the combined arm `after` of a capture by `arm`: its robot, with
/// `arm`'s joints, method and reaction wheels (the grasp leaves the bus's wheels on the bus).
pub(crate) fn combined_arm(
    py: Python<'_>,
    arm: &Bound<'_, PyFlexibleArm>,
    after: &crate::flex::FlexibleArm,
) -> PyResult<Py<PyFlexibleArm>> {
    let robot = Bound::new(py, PyRobot::wrap(after.robot().clone()))?;
    let combined = py.get_type::<PyFlexibleArm>().call1((
        robot,
        arm.getattr("joints")?,
        after.method().name(),
        arm.getattr("wheels")?,
    ))?;
    Ok(combined.downcast_into::<PyFlexibleArm>()?.unbind())
}
