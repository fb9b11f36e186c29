//! `orbitflex.ReactionWheels`.

use super::convert::{array1, as_float_array, row_major};
use super::errors::ModelError;
use super::robot::PyRobot;
use crate::flex::{ReactionWheels, Wheel};
use numpy::{PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;

/// Reaction wheels fixed in the bus (base frame), for ``FlexibleArm(robot, joints,
/// wheels=wheels)``.
///
/// - ``axes`` (k, 3): unit spin axes, base frame. Axes whose norm is 1 within 1e-5 are
///   normalised; others are refused (a vector not meant to be unit is not silently rescaled).
/// - ``positions`` (k, 3): wheel centres, base frame (m).
/// - ``mass`` (kg, > 0), ``spin_inertia`` ``J_s`` (kg·m² about the spin axis, > 0),
///   ``transverse_inertia`` ``J_t`` (kg·m² about any axis through the centre normal to the spin
///   axis, ``≥ J_s/2``), ``max_torque`` (N·m, > 0), ``max_speed`` (rad/s relative to the bus,
///   > 0; ``inf`` for no limit), ``friction`` ``c`` (N·m·s/rad, viscous, ≥ 0): each (k,) or one
///   number for every wheel.
///
/// The robot's base inertia must exclude the wheels: the arm adds each wheel's mass and
/// transverse inertia to the bus. A wheel's speed ``Ω`` is relative to the bus, positive about
/// its axis; its motor torque ``u_w`` acts on the wheel about the axis (the bus feels
/// ``−u_w a``) and is saturated once per step: clipped to ``±max_torque``, and cut when
/// ``|Ω| ≥ max_speed`` and it would speed the wheel up (Basilisk's rule).
#[pyclass(name = "ReactionWheels", module = "orbitflex", frozen)]
pub struct PyReactionWheels {
    pub(crate) wheels: ReactionWheels,
}

/// One number per wheel: a scalar for every wheel, or a 1-D array of `k`.
fn per_wheel(obj: &Bound<'_, PyAny>, what: &str, k: usize) -> PyResult<Vec<f64>> {
    let a = as_float_array(obj, what)?;
    let ndim: usize = a.getattr("ndim")?.extract()?;
    match ndim {
        0 => Ok(vec![a.extract::<f64>()?; k]),
        1 => {
            let values: PyReadonlyArray1<f64> = a.extract()?;
            let values = values.as_array().to_vec();
            if values.len() != k {
                return Err(ModelError::new_err(format!(
                    "{what}: expected one number per wheel (k = {k}, from axes) or a single \
                     number, given length {}",
                    values.len()
                )));
            }
            Ok(values)
        }
        _ => Err(ModelError::new_err(format!(
            "{what}: expected a number or a 1-D array of {k}, given {ndim} dimensions"
        ))),
    }
}

/// Rows of three: an array of shape (k, 3).
fn triples(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Vec<[f64; 3]>> {
    let a = as_float_array(obj, what)?;
    let shape: Vec<usize> = a.getattr("shape")?.extract()?;
    if shape.len() != 2 || shape[1] != 3 {
        return Err(ModelError::new_err(format!(
            "{what}: expected shape (k, 3), one row per wheel, given shape {shape:?}"
        )));
    }
    let values: PyReadonlyArray2<f64> = a.extract()?;
    Ok(values
        .as_array()
        .rows()
        .into_iter()
        .map(|r| [r[0], r[1], r[2]])
        .collect())
}

#[pymethods]
impl PyReactionWheels {
    #[new]
    #[pyo3(signature = (axes, positions, mass, spin_inertia, transverse_inertia, max_torque, max_speed, friction=None))]
    fn new(
        axes: &Bound<'_, PyAny>,
        positions: &Bound<'_, PyAny>,
        mass: &Bound<'_, PyAny>,
        spin_inertia: &Bound<'_, PyAny>,
        transverse_inertia: &Bound<'_, PyAny>,
        max_torque: &Bound<'_, PyAny>,
        max_speed: &Bound<'_, PyAny>,
        friction: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let axes = triples(axes, "axes")?;
        let k = axes.len();
        let positions = triples(positions, "positions")?;
        if positions.len() != k {
            return Err(ModelError::new_err(format!(
                "positions: expected shape ({k}, 3), one row per wheel as in axes, given shape \
                 ({}, 3)",
                positions.len()
            )));
        }
        let column = |obj: &Bound<'_, PyAny>, what: &str| per_wheel(obj, what, k);
        let mass = column(mass, "mass")?;
        let spin = column(spin_inertia, "spin_inertia")?;
        let transverse = column(transverse_inertia, "transverse_inertia")?;
        let max_torque = column(max_torque, "max_torque")?;
        let max_speed = column(max_speed, "max_speed")?;
        let friction = match friction.filter(|o| !o.is_none()) {
            Some(f) => column(f, "friction")?,
            None => vec![0.0; k],
        };
        let wheels = (0..k)
            .map(|w| Wheel {
                axis: axes[w],
                position: positions[w],
                mass: mass[w],
                spin_inertia: spin[w],
                transverse_inertia: transverse[w],
                max_torque: max_torque[w],
                max_speed: max_speed[w],
                friction: friction[w],
            })
            .collect();
        Ok(Self {
            wheels: ReactionWheels::new(wheels)?,
        })
    }

    /// Number of wheels k.
    fn __len__(&self) -> usize {
        self.wheels.len()
    }

    /// Unit spin axes (k, 3), base frame (normalised).
    #[getter]
    fn axes<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.rows(py, |w| w.axis)
    }
    /// Wheel centres (k, 3), base frame (m).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        self.rows(py, |w| w.position)
    }
    /// Masses (k,), kg.
    #[getter]
    fn mass<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.column(py, |w| w.mass)
    }
    /// Spin inertias ``J_s`` (k,), kg·m².
    #[getter]
    fn spin_inertia<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.column(py, |w| w.spin_inertia)
    }
    /// Transverse inertias ``J_t`` (k,), kg·m².
    #[getter]
    fn transverse_inertia<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.column(py, |w| w.transverse_inertia)
    }
    /// Motor torque limits (k,), N·m.
    #[getter]
    fn max_torque<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.column(py, |w| w.max_torque)
    }
    /// Speed limits relative to the bus (k,), rad/s.
    #[getter]
    fn max_speed<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.column(py, |w| w.max_speed)
    }
    /// Viscous friction ``c`` (k,), N·m·s/rad.
    #[getter]
    fn friction<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        self.column(py, |w| w.friction)
    }

    /// The torques the motors apply (k,) for the commands ``command`` (k,) at speeds ``speed``
    /// (k,): the saturation rule of the class docs.
    fn saturate<'py>(
        &self,
        py: Python<'py>,
        command: &Bound<'py, PyAny>,
        speed: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let k = Some(self.wheels.len());
        let command = super::convert::vector(command, "command", k)?;
        let speed = super::convert::vector(speed, "speed", k)?;
        let mut out = vec![0.0; command.len()];
        self.wheels.saturate(&command, &speed, &mut out);
        Ok(array1(py, &out))
    }

    /// ``robot`` as URDF text with each wheel a link (``reaction_wheel_{w}``: its mass at its
    /// position, inertia ``diag(J_t, J_t, J_s)`` in a frame whose z is its axis) on a continuous
    /// joint of the root (``reaction_wheel_{w}_spin``, axis ``0 0 1``). Its rigid dynamics, with
    /// joint rate ``Ω`` and joint torque ``u_w − c Ω``, are those of an arm with these wheels:
    /// load it in Pinocchio to check them.
    fn to_urdf(&self, robot: &Bound<'_, PyRobot>) -> PyResult<String> {
        Ok(self.wheels.to_urdf(&robot.get().robot)?)
    }

    /// Pickle support.
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let me = slf.get();
        let args = (
            me.axes(py),
            me.positions(py),
            me.mass(py),
            me.spin_inertia(py),
            me.transverse_inertia(py),
            me.max_torque(py),
            me.max_speed(py),
            me.friction(py),
        );
        Ok((
            slf.get_type().into_any().unbind(),
            args.into_pyobject(py)?.into_any().unbind(),
        ))
    }

    fn __repr__(&self) -> String {
        format!("ReactionWheels(k={})", self.wheels.len())
    }
}

impl PyReactionWheels {
    fn rows<'py>(
        &self,
        py: Python<'py>,
        f: impl Fn(&Wheel) -> [f64; 3],
    ) -> Bound<'py, PyArray2<f64>> {
        let values: Vec<f64> = self.wheels.wheels().iter().flat_map(&f).collect();
        row_major(py, self.wheels.len(), 3, values)
    }
    fn column<'py>(&self, py: Python<'py>, f: impl Fn(&Wheel) -> f64) -> Bound<'py, PyArray1<f64>> {
        let values: Vec<f64> = self.wheels.wheels().iter().map(f).collect();
        array1(py, &values)
    }
}
