//! `orbitflex.FlexibleJoints`.

use super::convert::{array1, vector};
use super::errors::ModelError;
use super::robot::PyRobot;
use crate::error::Error;
use crate::flex::{reflected_inertia, FlexibleJoints};
use pyo3::prelude::*;
use pyo3::types::PyTuple;

/// A parameter given as a scalar (broadcast to every joint) or one value per joint.
#[derive(Clone, Debug)]
pub(crate) enum Param {
    Scalar(f64),
    PerJoint(Vec<f64>),
}

impl Param {
    pub(crate) fn parse(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        let array = super::convert::as_float_array(obj, what)?;
        let ndim: usize = array.getattr("ndim")?.extract()?;
        if ndim == 0 && !obj.is_instance_of::<pyo3::types::PyBool>() {
            let v = super::convert::real(obj, what)?;
            crate::args::check_finite(what, &[v])?;
            return Ok(Param::Scalar(v));
        }
        if ndim == 0 {
            return Err(ModelError::new_err(format!(
                "{what}: expected a number or an array of numbers, given a bool"
            )));
        }
        Ok(Param::PerJoint(vector(obj, what, None)?))
    }
    /// An optional parameter: absent or None means 0 for every joint.
    fn optional(obj: Option<&Bound<'_, PyAny>>, what: &str) -> PyResult<Self> {
        match obj {
            Some(o) if !o.is_none() => Self::parse(o, what),
            _ => Ok(Param::Scalar(0.0)),
        }
    }
    pub(crate) fn resolve(&self, n: usize) -> Vec<f64> {
        match self {
            Param::Scalar(v) => vec![*v; n],
            Param::PerJoint(v) => v.clone(),
        }
    }
    pub(crate) fn len(&self) -> Option<usize> {
        match self {
            Param::Scalar(_) => None,
            Param::PerJoint(v) => Some(v.len()),
        }
    }
    fn to_object(&self, py: Python<'_>) -> PyObject {
        match self {
            Param::Scalar(v) => v.into_pyobject(py).expect("a float").into_any().unbind(),
            Param::PerJoint(v) => array1(py, v).into_any().unbind(),
        }
    }
    fn describe(&self) -> String {
        match self {
            Param::Scalar(v) => format!("{v}"),
            Param::PerJoint(v) => format!("{v:?}"),
        }
    }
}

/// Spong flexible-joint parameters, link side: ``stiffness`` k > 0 (N·m/rad), ``motor_inertia``
/// j > 0 (kg·m², ``N² J_rotor``), ``damping`` d ≥ 0 and ``motor_damping`` β ≥ 0 (N·m·s/rad).
/// Each is a scalar (the same for every joint) or an array of length n.
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
            if let Some(len) = p.len().filter(|&len| len != n) {
                return Err(Error::Dimension {
                    what: format!("FlexibleJoints.{name}"),
                    expected: format!("length {n} ({expected})"),
                    given: format!("length {len}"),
                });
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

    /// The Rust parameters for a robot with `n` joints.
    pub(crate) fn resolve(&self, n: usize) -> Result<FlexibleJoints, Error> {
        Self::build(&self.params, n, "the robot's dof")
    }

    pub(crate) fn from_rust(j: FlexibleJoints) -> Self {
        Self {
            params: [
                Param::PerJoint(j.stiffness),
                Param::PerJoint(j.motor_inertia),
                Param::PerJoint(j.damping),
                Param::PerJoint(j.motor_damping),
            ],
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
        let inertia = match (&g, &r) {
            (Param::Scalar(g), Param::Scalar(r)) => Param::Scalar(reflected_inertia("", *g, *r)?),
            _ => {
                let n = g.len().or(r.len()).unwrap_or(1);
                if let (Some(a), Some(b)) = (g.len(), r.len()) {
                    if a != b {
                        return Err(ModelError::new_err(format!(
                            "rotor_inertia: expected length {a} (as gear_ratio), given length {b}"
                        )));
                    }
                }
                let j = g
                    .resolve(n)
                    .iter()
                    .zip(r.resolve(n))
                    .enumerate()
                    .map(|(i, (&g, r))| reflected_inertia(&format!("joint {i}: "), g, r))
                    .collect::<Result<Vec<f64>, Error>>()?;
                Param::PerJoint(j)
            }
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
    fn from_toml(py: Python<'_>, path: std::path::PathBuf, robot: &PyRobot) -> PyResult<Self> {
        let names = robot.robot.joint_names();
        let joints = py.allow_threads(|| FlexibleJoints::from_toml_file(path, &names))?;
        Ok(Self::from_rust(joints))
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

    /// Parameters scaled to ``robot``'s links, for a robot with no actuator data: with its motor
    /// held, each joint rings at 5 Hz against the link-side inertia ``m_i = 1/(M⁻¹)_ii`` it sees
    /// at ``q = 0``; motor inertia ``j_i = m_i``; joint damping 5 % of critical; no motor
    /// friction.
    #[staticmethod]
    fn defaults_for(robot: &PyRobot) -> PyResult<Self> {
        Ok(Self::from_rust(FlexibleJoints::defaults_for(&robot.robot)?))
    }

    /// The built-in dual-arm servicer's joint parameters (see
    /// ``orbitflex.models.dual_arm_joints``).
    #[staticmethod]
    fn dual_arm() -> Self {
        Self::from_rust(FlexibleJoints::dual_arm())
    }

    /// The built-in arm's joint parameters (see ``orbitflex.models.space_arm_joints``).
    #[staticmethod]
    fn space_arm() -> Self {
        Self::from_rust(FlexibleJoints::space_arm())
    }

    /// k (N·m/rad): a float or an array.
    #[getter]
    fn stiffness(&self, py: Python<'_>) -> PyObject {
        self.params[0].to_object(py)
    }
    /// j (kg·m², link side): a float or an array.
    #[getter]
    fn motor_inertia(&self, py: Python<'_>) -> PyObject {
        self.params[1].to_object(py)
    }
    /// d (N·m·s/rad): a float or an array.
    #[getter]
    fn damping(&self, py: Python<'_>) -> PyObject {
        self.params[2].to_object(py)
    }
    /// β (N·m·s/rad): a float or an array.
    #[getter]
    fn motor_damping(&self, py: Python<'_>) -> PyObject {
        self.params[3].to_object(py)
    }

    /// Pickle support.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let args = PyTuple::new(py, me.params.iter().map(|p| p.to_object(py)))?;
        Ok((slf.get_type().into_any().unbind(), args.into_any().unbind()))
    }

    fn __repr__(&self) -> String {
        let fields: Vec<String> = Self::NAMES
            .iter()
            .zip(&self.params)
            .map(|(name, p)| format!("{name}={}", p.describe()))
            .collect();
        format!("FlexibleJoints({})", fields.join(", "))
    }
}
