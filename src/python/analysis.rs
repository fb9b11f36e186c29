//! The linear analysis (`crate::analysis`) for Python: private functions of `orbitflex._core`
//! that `orbitflex.analysis` wraps into `FlexibleArm.modes`, `.frequency_response`,
//! `.state_space` and `orbitflex.analysis.sweep`.
//!
//! They are module functions taking the arm, not methods of `FlexibleArm`: a second
//! `#[pymethods]` block would need pyo3's `multiple-pymethods` feature (and the `inventory`
//! crate), and the result types (`Modes`, `StateSpace` with `.to_control()` and `.savemat()`,
//! which need python-control and scipy) belong to the Python layer anyway.

use super::arm::PyFlexibleArm;
use super::control::{PyAttitudePD, PyMotorPD};
use super::convert::{array1, array2, matrix, vector};
use super::errors::ModelError;
use crate::analysis::{self, InputGroup, LinearSpec, Modes, Motors, OutputGroup, StateSpace};
use crate::control::AttitudePD;
use crate::integrate::Feedback;
use crate::planning::BaseMode;
use nalgebra::{Complex, DMatrix};
use numpy::{PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The feedback `u` gives: None or a torque array (open loop; the torques enter linearly and do
/// not change the model), a `MotorPD` (its gains close the loop), anything callable (unknown:
/// refused by the model's checks).
enum Loop {
    Open,
    Pd { kp: Vec<f64>, kd: Vec<f64> },
    Unknown,
}

impl Loop {
    fn parse(u: Option<&Bound<'_, PyAny>>, n: usize) -> PyResult<Self> {
        // (`u` is None, a MotorPD, a callable or torques)
        match u.filter(|o| !o.is_none()) {
            None => Ok(Loop::Open),
            Some(obj) if obj.is_instance_of::<PyMotorPD>() => {
                let pd = &obj.downcast::<PyMotorPD>()?.get().pd;
                Ok(Loop::Pd {
                    kp: pd.kp.clone(),
                    kd: pd.kd.clone(),
                })
            }
            Some(obj) if obj.is_callable() => Ok(Loop::Unknown),
            Some(obj) => {
                vector(obj, "u", Some(n))?;
                Ok(Loop::Open)
            }
        }
    }
    fn feedback(&self) -> Feedback<'_> {
        match self {
            Loop::Open => Feedback::None,
            Loop::Pd { kp, kd } => Feedback::MotorPd { kp, kd },
            Loop::Unknown => Feedback::Unknown,
        }
    }
}

/// The controllers `u` (and `wheel_torque`) name: a `MotorPD` on the motors, an `AttitudePD` on
/// the wheels, or a tuple or list of one of each; anything else goes to [`Loop::parse`].
fn controllers<'py>(
    arm: &crate::FlexibleArm,
    u: &Bound<'py, PyAny>,
    wheel_torque: Option<Bound<'py, PyAny>>,
) -> PyResult<(Option<Bound<'py, PyAny>>, Option<AttitudePD>)> {
    let mut motor = None;
    let mut attitude = None;
    let mut take = |obj: Bound<'py, PyAny>, what: &str| -> PyResult<()> {
        if obj.is_instance_of::<PyAttitudePD>() {
            if attitude.is_some() {
                return Err(ModelError::new_err(format!(
                    "{what}: two AttitudePDs; give one"
                )));
            }
            attitude = Some(obj.downcast::<PyAttitudePD>()?.get().bind(arm)?);
        } else if what == "wheel_torque" {
            return Err(ModelError::new_err(format!(
                "wheel_torque: the linear model takes an AttitudePD or None, given {}",
                obj.get_type().name()?
            )));
        } else if motor.is_some() {
            return Err(ModelError::new_err(
                "u: two motor controllers; give at most one MotorPD and one AttitudePD",
            ));
        } else {
            motor = Some(obj);
        }
        Ok(())
    };
    let is_pair =
        u.is_instance_of::<pyo3::types::PyTuple>() || u.is_instance_of::<pyo3::types::PyList>();
    if is_pair {
        for item in u.try_iter()? {
            take(item?, "u")?;
        }
    } else if !u.is_none() {
        take(u.clone(), "u")?;
    }
    if let Some(w) = wheel_torque.filter(|o| !o.is_none()) {
        take(w, "wheel_torque")?;
    }
    Ok((motor, attitude))
}

/// The parsed arguments of one call.
struct Model {
    x: Vec<f64>,
    feedback: Loop,
    /// An attitude PD on the wheels.
    attitude: Option<AttitudePD>,
    base: BaseMode,
    motors: Motors,
    inputs: Vec<InputGroup>,
    outputs: Vec<OutputGroup>,
    /// The damped modes (of the state matrix) or the undamped ones.
    damping: bool,
}

impl Model {
    /// From `x` and the dict `spec` that `orbitflex.analysis` builds: `u`, `wheel_torque`
    /// (optional), `base`, `motors`, `inputs`, `outputs` (lists of group names) and `damping`.
    fn parse(
        arm: &crate::FlexibleArm,
        x: Option<&Bound<'_, PyAny>>,
        spec: &Bound<'_, PyDict>,
    ) -> PyResult<Self> {
        let item = |key: &str| -> PyResult<Bound<'_, PyAny>> {
            spec.get_item(key)?
                .ok_or_else(|| ModelError::new_err(format!("spec: missing {key:?}")))
        };
        let names = |key: &str| -> PyResult<Vec<String>> { item(key)?.extract() };
        let u = item("u")?;
        let (motor, attitude) = controllers(arm, &u, spec.get_item("wheel_torque")?)?;
        Ok(Self {
            x: match x {
                Some(x) => vector(x, "x", Some(arm.layout().len()))?,
                None => Vec::new(),
            },
            feedback: Loop::parse(motor.as_ref(), arm.dof())?,
            attitude,
            base: BaseMode::from_name(&item("base")?.extract::<String>()?)?,
            motors: Motors::from_name(&item("motors")?.extract::<String>()?)?,
            inputs: names("inputs")?
                .iter()
                .map(|name| InputGroup::from_name(name))
                .collect::<crate::Result<_>>()?,
            outputs: names("outputs")?
                .iter()
                .map(|name| OutputGroup::from_name(name))
                .collect::<crate::Result<_>>()?,
            damping: item("damping")?.extract()?,
        })
    }
    fn spec(&self) -> LinearSpec<'_> {
        LinearSpec {
            base: self.base,
            motors: self.motors,
            feedback: self.feedback.feedback(),
            attitude: self.attitude.as_ref(),
            inputs: &self.inputs,
            outputs: &self.outputs,
        }
    }
}

fn complex1<'py>(py: Python<'py>, values: &[Complex<f64>]) -> Bound<'py, PyArray1<Complex<f64>>> {
    PyArray1::from_slice(py, values)
}

fn complex2<'py>(py: Python<'py>, m: &DMatrix<Complex<f64>>) -> Bound<'py, PyArray2<Complex<f64>>> {
    let (rows, cols) = m.shape();
    let data: Vec<Complex<f64>> = (0..rows)
        .flat_map(|r| (0..cols).map(move |c| m[(r, c)]))
        .collect();
    let array = numpy::ndarray::Array2::from_shape_vec((rows, cols), data).expect("shape matches");
    PyArray2::from_owned_array(py, array)
}

/// `crate::analysis::state_space` as a dict: `A`, `B`, `C`, `D`, `states`, `inputs`, `outputs`,
/// `tangent_index`.
#[pyfunction]
#[pyo3(name = "_state_space")]
pub fn py_state_space<'py>(
    py: Python<'py>,
    arm: &Bound<'py, PyFlexibleArm>,
    x: &Bound<'py, PyAny>,
    spec: &Bound<'py, PyDict>,
) -> PyResult<Bound<'py, PyDict>> {
    let arm = &arm.get().arm;
    let model = Model::parse(arm, Some(x), spec)?;
    let ss = analysis::state_space(arm, &mut arm.workspace(), &model.x, &model.spec())?;
    state_space_dict(py, &ss)
}

fn state_space_dict<'py>(py: Python<'py>, ss: &StateSpace) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("A", array2(py, &ss.a))?;
    d.set_item("B", array2(py, &ss.b))?;
    d.set_item("C", array2(py, &ss.c))?;
    d.set_item("D", array2(py, &ss.d))?;
    d.set_item("states", &ss.states)?;
    d.set_item("inputs", &ss.inputs)?;
    d.set_item("outputs", &ss.outputs)?;
    d.set_item("tangent_index", &ss.tangent_index)?;
    Ok(d)
}

fn modes_dict<'py>(py: Python<'py>, m: &Modes) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("eigenvalues", complex1(py, &m.eigenvalues))?;
    d.set_item("frequency_hz", array1(py, &m.frequency_hz))?;
    d.set_item("natural_frequency_hz", array1(py, &m.natural_frequency_hz))?;
    d.set_item("damping_ratio", array1(py, &m.damping_ratio))?;
    d.set_item("shapes", complex2(py, &m.shapes))?;
    d.set_item("rigid_body", m.rigid_body)?;
    d.set_item("wheel_spin", m.wheel_spin)?;
    d.set_item("overdamped", array1(py, &m.overdamped))?;
    d.set_item("damped", m.damped)?;
    Ok(d)
}

/// `crate::analysis::modes` as a dict of arrays.
#[pyfunction]
#[pyo3(name = "_modes")]
pub fn py_modes<'py>(
    py: Python<'py>,
    arm: &Bound<'py, PyFlexibleArm>,
    x: &Bound<'py, PyAny>,
    spec: &Bound<'py, PyDict>,
) -> PyResult<Bound<'py, PyDict>> {
    let arm = &arm.get().arm;
    let model = Model::parse(arm, Some(x), spec)?;
    let m = analysis::modes(
        arm,
        &mut arm.workspace(),
        &model.x,
        &model.spec(),
        model.damping,
    )?;
    modes_dict(py, &m)
}

/// `H(j 2π f)` for each `f` of `freqs_hz`: a complex array (frequencies, outputs, inputs), with
/// the GIL released while it is computed.
#[pyfunction]
#[pyo3(name = "_frequency_response")]
pub fn py_frequency_response<'py>(
    py: Python<'py>,
    arm: &Bound<'py, PyFlexibleArm>,
    x: &Bound<'py, PyAny>,
    freqs_hz: &Bound<'py, PyAny>,
    spec: &Bound<'py, PyDict>,
) -> PyResult<Bound<'py, PyArray3<Complex<f64>>>> {
    let arm = &arm.get().arm;
    let freqs = vector(freqs_hz, "freqs_hz", None)?;
    let model = Model::parse(arm, Some(x), spec)?;
    let ss = analysis::state_space(arm, &mut arm.workspace(), &model.x, &model.spec())?;
    let h = py.allow_threads(|| analysis::frequency_response(&ss, &freqs))?;
    let (o, i) = (ss.c.nrows(), ss.b.ncols());
    let mut data = Vec::with_capacity(h.len() * o * i);
    for m in &h {
        for r in 0..o {
            for c in 0..i {
                data.push(m[(r, c)]);
            }
        }
    }
    let array = numpy::ndarray::Array3::from_shape_vec((h.len(), o, i), data).expect("shape");
    Ok(PyArray3::from_owned_array(py, array))
}

/// The modes at each row of `states` ((N, 13+4n)), over `threads` threads without the GIL: a
/// list of dicts as `_modes` gives, or an error naming the first row that failed.
#[pyfunction]
#[pyo3(name = "_sweep", signature = (arm, states, spec, threads))]
pub fn py_sweep<'py>(
    py: Python<'py>,
    arm: &Bound<'py, PyFlexibleArm>,
    states: &Bound<'py, PyAny>,
    spec: &Bound<'py, PyDict>,
    threads: Option<usize>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let arm = &arm.get().arm;
    let width = arm.layout().len();
    let (rows, values) = matrix(states, "configurations", width)?;
    if threads == Some(0) {
        return Err(ModelError::new_err(
            "threads: expected at least 1 (or None for every core), given 0",
        ));
    }
    let model = Model::parse(arm, None, spec)?;
    let (spec, damping) = (model.spec(), model.damping);
    let results = py.allow_threads(|| analysis::sweep(arm, &values, &spec, damping, threads))?;
    debug_assert_eq!(results.len(), rows);
    results
        .into_iter()
        .enumerate()
        .map(|(i, r)| match r {
            Ok(m) => modes_dict(py, &m),
            Err(e) => Err(ModelError::new_err(format!("configurations[{i}]: {e}"))),
        })
        .collect()
}

/// The controller a `Sampled` wraps, as the linear feedback it applies: a `MotorPD` or an
/// `AttitudePD` (bound to `arm`'s wheels), or None for anything else (a callable, a table).
enum SampledInner {
    Motor { kp: Vec<f64>, kd: Vec<f64> },
    Attitude(AttitudePD),
}

impl SampledInner {
    fn parse(arm: &crate::FlexibleArm, inner: &Bound<'_, PyAny>) -> PyResult<Option<Self>> {
        if inner.is_instance_of::<PyMotorPD>() {
            let pd = &inner.downcast::<PyMotorPD>()?.get().pd;
            return Ok(Some(SampledInner::Motor {
                kp: pd.kp.clone(),
                kd: pd.kd.clone(),
            }));
        }
        if inner.is_instance_of::<PyAttitudePD>() {
            let pd = inner.downcast::<PyAttitudePD>()?.get().bind(arm)?;
            return Ok(Some(SampledInner::Attitude(pd)));
        }
        Ok(None)
    }
    fn feedback(&self) -> analysis::SampledFeedback<'_> {
        match self {
            SampledInner::Motor { kp, kd } => analysis::SampledFeedback::MotorPd { kp, kd },
            SampledInner::Attitude(pd) => analysis::SampledFeedback::Attitude(pd),
        }
    }
}

/// `crate::analysis::sampled_loop` for a `Sampled(MotorPD | AttitudePD, rate_hz, delay)`
/// closed around the model `spec` (whose `u`/`wheel_torque` are the loops running every step):
/// a dict with `spectral_radius`, `threshold`, `unstable`, `eigenvalues`, `period`, `delay`,
/// `rate_hz` and `controller` (its name).
#[pyfunction]
#[pyo3(name = "_sampled_loop")]
pub fn py_sampled_loop<'py>(
    py: Python<'py>,
    arm: &Bound<'py, PyFlexibleArm>,
    x: &Bound<'py, PyAny>,
    spec: &Bound<'py, PyDict>,
    controller: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let arm = &arm.get().arm;
    let Some((inner, rate_hz, delay)) = super::control::sampled(Some(controller))? else {
        return Err(ModelError::new_err(format!(
            "controller: expected a Sampled(MotorPD or AttitudePD, rate_hz, delay), given {}",
            controller.get_type().name()?
        )));
    };
    let Some(feedback) = SampledInner::parse(arm, &inner)? else {
        return Err(ModelError::new_err(format!(
            "controller: the linear model knows the feedback of a sampled MotorPD or \
             AttitudePD, not of a {}",
            inner.get_type().name()?
        )));
    };
    let model = Model::parse(arm, Some(x), spec)?;
    let l = analysis::sampled_loop(
        arm,
        &mut arm.workspace(),
        &model.x,
        &model.spec(),
        feedback.feedback(),
        rate_hz,
        delay,
    )?;
    let d = PyDict::new(py);
    d.set_item("spectral_radius", l.spectral_radius)?;
    d.set_item("threshold", l.threshold)?;
    d.set_item("unstable", l.unstable())?;
    d.set_item("eigenvalues", complex1(py, &l.eigenvalues))?;
    d.set_item("period", l.period)?;
    d.set_item("delay", l.delay)?;
    d.set_item("rate_hz", rate_hz)?;
    d.set_item("controller", feedback.feedback().name())?;
    Ok(d)
}

/// The warnings `simulate` gives before a run from `x0` for the sampled controllers among `u`
/// and `wheel_torque` (a `Sampled` `MotorPD` or `AttitudePD`): one per sampled loop whose
/// discrete loop at `x0` is unstable, naming the controller, its rate and delay and the
/// spectral radius. The other channel's controller, if it is a plain `MotorPD` or `AttitudePD`
/// (run every step), is closed into the plant. A loop the linear model cannot describe (a
/// state at a wheel's speed limit, say) gives no warning.
pub(crate) fn sampled_warnings(
    arm: &crate::FlexibleArm,
    x0: &[f64],
    u: Option<&Bound<'_, PyAny>>,
    wheel_torque: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<String>> {
    let mut out = Vec::new();
    let plain = |obj: Option<&Bound<'_, PyAny>>| -> PyResult<Option<SampledInner>> {
        match obj.filter(|o| !o.is_none()) {
            Some(o) if super::control::sampled(Some(o))?.is_none() => SampledInner::parse(arm, o),
            _ => Ok(None),
        }
    };
    let (plain_u, plain_w) = (plain(u)?, plain(wheel_torque)?);
    for (channel, obj) in [("u", u), ("wheel_torque", wheel_torque)] {
        let Some((inner, rate_hz, delay)) = super::control::sampled(obj)? else {
            continue;
        };
        let Some(feedback) = SampledInner::parse(arm, &inner)? else {
            continue;
        };
        let (motor, attitude) = match channel {
            "u" => (None, plain_w.as_ref()),
            _ => (plain_u.as_ref(), None),
        };
        let spec = LinearSpec {
            feedback: match motor {
                Some(SampledInner::Motor { kp, kd }) => Feedback::MotorPd { kp, kd },
                _ => Feedback::None,
            },
            attitude: match attitude {
                Some(SampledInner::Attitude(pd)) => Some(pd),
                _ => None,
            },
            ..LinearSpec::default()
        };
        let Ok(l) = analysis::sampled_loop(
            arm,
            &mut arm.workspace(),
            x0,
            &spec,
            feedback.feedback(),
            rate_hz,
            delay,
        ) else {
            continue;
        };
        if l.unstable() {
            out.push(format!(
                "{channel}: the {} sampled at {rate_hz} Hz (period {:e} s, delay {delay} \
                 samples) makes an unstable loop: the spectral radius of its zero-order-hold \
                 discretisation at x0 is {:.6} > 1; the run will likely diverge (raise rate_hz, \
                 shorten the delay or lower the gains)",
                feedback.feedback().name(),
                l.period,
                l.spectral_radius
            ));
        }
    }
    Ok(out)
}
