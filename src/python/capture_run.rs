//! Capture in a run from Python: `orbitflex.CaptureWhen`, the `CaptureEvent`s a run records, and
//! the run with a target (`FlexibleArm.simulate(..., target=, capture=)`) without the GIL.

use super::arm::PyFlexibleArm;
use super::capture::PyTarget;
use super::convert::{array1, real};
use super::run::{Channels, Progress, Watch};
use crate::capture::{
    simulate_capture_into, CaptureEvent, CaptureRecord, CaptureRun, CaptureWhen, Target,
};
use crate::flex::FlexibleArm;
use crate::integrate::{Recorder, Run};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyList;

/// When a run captures its target (model §9.6): the end-effector within ``distance`` (m) of the
/// handle's origin, the EE origin moving relative to the target at at most ``speed`` (m/s), and
/// the EE's axes within ``angle`` (rad) of the handle's. Each tolerance finite and > 0.
///
/// ``CaptureWhen(distance, speed, angle)``; pass it with a :class:`Target` to
/// :meth:`FlexibleArm.simulate` (``target=..., capture=...``).
#[pyclass(name = "CaptureWhen", module = "orbitflex", frozen)]
#[derive(Clone)]
pub struct PyCaptureWhen {
    pub(crate) when: CaptureWhen,
}

#[pymethods]
impl PyCaptureWhen {
    #[new]
    fn new(
        distance: &Bound<'_, PyAny>,
        speed: &Bound<'_, PyAny>,
        angle: &Bound<'_, PyAny>,
    ) -> PyResult<Self> {
        let when = CaptureWhen::new(
            real(distance, "CaptureWhen.distance")?,
            real(speed, "CaptureWhen.speed")?,
            real(angle, "CaptureWhen.angle")?,
        )?;
        Ok(Self { when })
    }
    /// Largest distance from the EE origin to the handle's (m).
    #[getter]
    fn distance(&self) -> f64 {
        self.when.distance
    }
    /// Largest speed of the EE origin relative to the target (m/s).
    #[getter]
    fn speed(&self) -> f64 {
        self.when.speed
    }
    /// Largest angle between the EE's axes and the handle's (rad).
    #[getter]
    fn angle(&self) -> f64 {
        self.when.angle
    }
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, (f64, f64, f64))> {
        let w = slf.get().when;
        Ok((
            slf.get_type().into_any().unbind(),
            (w.distance, w.speed, w.angle),
        ))
    }
    fn __repr__(&self) -> String {
        let w = self.when;
        format!(
            "CaptureWhen(distance={}, speed={}, angle={})",
            w.distance, w.speed, w.angle
        )
    }
}

/// A capture that happened in a run (``Trajectory.events``).
///
/// - ``step``, ``time`` (s): the step that started from the post-capture state (the row kept at
///   ``time`` holds the state before the impulse);
/// - ``ee``: the grasping end-effector (an index into ``robot.ee_links``);
/// - ``distance`` (m), ``speed`` (m/s), ``angle`` (rad): the approach that met the tolerances;
/// - ``impulse`` (6,): ``[moment (N·m·s); force (N·s)]`` the EE exerted on the target, EE frame;
/// - ``energy_loss`` (J, ≥ 0); ``relative_twist`` (6,): the EE's twist relative to the target
///   just before (EE frame);
/// - ``x_before``, ``x_after`` (13 + 4n): the arm's state either side of the jump;
///   ``target_before``, ``target_after`` (13): the target's ``[r; quat; ω; v]``;
/// - ``momentum_before``, ``momentum_after`` (6,): total ``[K; L]`` (inertial, about the inertial
///   origin) of arm and target just before, of the combined arm just after.
#[pyclass(name = "CaptureEvent", module = "orbitflex", frozen)]
pub struct PyCaptureEvent {
    event: CaptureEvent,
}

#[pymethods]
impl PyCaptureEvent {
    #[getter]
    fn step(&self) -> usize {
        self.event.step
    }
    #[getter]
    fn time(&self) -> f64 {
        self.event.time
    }
    #[getter]
    fn ee(&self) -> usize {
        self.event.ee
    }
    #[getter]
    fn distance(&self) -> f64 {
        self.event.approach.distance
    }
    #[getter]
    fn speed(&self) -> f64 {
        self.event.approach.speed
    }
    #[getter]
    fn angle(&self) -> f64 {
        self.event.approach.angle
    }
    #[getter]
    fn energy_loss(&self) -> f64 {
        self.event.energy_loss
    }
    #[getter]
    fn impulse<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.event.impulse.to_vector().as_slice())
    }
    #[getter]
    fn relative_twist<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, self.event.relative_twist.to_vector().as_slice())
    }
    #[getter]
    fn x_before<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.event.x_before)
    }
    #[getter]
    fn x_after<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.event.x_after)
    }
    #[getter]
    fn target_before<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.event.target_before)
    }
    #[getter]
    fn target_after<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.event.target_after)
    }
    #[getter]
    fn momentum_before<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.event.momentum_before)
    }
    #[getter]
    fn momentum_after<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        array1(py, &self.event.momentum_after)
    }
    /// Pickles as its values, bit for bit ([`Self::restore`] rebuilds it).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<(PyObject, PyObject)> {
        let py = slf.py();
        let e = &slf.get().event;
        let a = &e.approach;
        let args = (
            (
                e.step,
                e.time,
                e.ee,
                a.distance,
                a.speed,
                a.angle,
                e.energy_loss,
            ),
            (
                e.impulse.to_array().to_vec(),
                e.relative_twist.to_array().to_vec(),
                e.x_before.clone(),
                e.x_after.clone(),
                e.target_before.to_vec(),
                e.target_after.to_vec(),
                e.momentum_before.to_vec(),
                e.momentum_after.to_vec(),
            ),
        );
        Ok((
            slf.get_type().getattr("_restore")?.unbind(),
            args.into_pyobject(py)?.into_any().unbind(),
        ))
    }
    /// The event from the values [`Self::__reduce__`] gives (for pickle).
    #[staticmethod]
    #[pyo3(name = "_restore")]
    #[allow(clippy::type_complexity)]
    fn restore(
        scalars: (usize, f64, usize, f64, f64, f64, f64),
        arrays: (
            Vec<f64>,
            Vec<f64>,
            Vec<f64>,
            Vec<f64>,
            Vec<f64>,
            Vec<f64>,
            Vec<f64>,
            Vec<f64>,
        ),
    ) -> PyResult<Self> {
        let (step, time, ee, distance, speed, angle, energy_loss) = scalars;
        let (impulse, relative_twist, x_before, x_after, tb, ta, mb, ma) = arrays;
        fn fixed<const N: usize>(v: Vec<f64>, what: &str) -> PyResult<[f64; N]> {
            let given = v.len();
            v.try_into().map_err(|_| {
                super::errors::ModelError::new_err(format!(
                    "CaptureEvent.{what}: expected {N} numbers, given {given}"
                ))
            })
        }
        Ok(Self {
            event: CaptureEvent {
                step,
                time,
                ee,
                approach: crate::capture::Approach {
                    distance,
                    speed,
                    angle,
                },
                impulse: crate::spatial::Force::from_slice(&fixed::<6>(impulse, "impulse")?),
                energy_loss,
                relative_twist: crate::spatial::Motion::from_slice(&fixed::<6>(
                    relative_twist,
                    "relative_twist",
                )?),
                x_before,
                x_after,
                target_before: fixed(tb, "target_before")?,
                target_after: fixed(ta, "target_after")?,
                momentum_before: fixed(mb, "momentum_before")?,
                momentum_after: fixed(ma, "momentum_after")?,
            },
        })
    }
    fn __repr__(&self) -> String {
        let e = &self.event;
        format!(
            "CaptureEvent(step={}, time={} s, energy_loss={:.6e} J, |impulse force|={:.6e} N·s)",
            e.step,
            e.time,
            e.energy_loss,
            e.impulse.linear.norm()
        )
    }
}

/// What a run captures, read from `simulate`'s keywords: `None` without a target.
pub(crate) struct Capturing {
    pub target: Target,
    pub when: CaptureWhen,
    pub ee: Option<usize>,
}

impl Capturing {
    /// `target` and `capture` come together; `capture_ee` only with them.
    pub fn from_args<'py>(
        arm: &FlexibleArm,
        target: Option<&Bound<'py, PyAny>>,
        capture: Option<&Bound<'py, PyAny>>,
        capture_ee: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Option<Self>> {
        let given = |o: Option<&Bound<'py, PyAny>>| o.filter(|o| !o.is_none()).cloned();
        let (target, capture, ee) = (given(target), given(capture), given(capture_ee));
        let missing = |what: &str| {
            super::errors::ModelError::new_err(format!(
                "{what}: a run with a target needs target=Target(...) and \
                 capture=CaptureWhen(distance, speed, angle) together"
            ))
        };
        match (target, capture) {
            (None, None) => match ee {
                None => Ok(None),
                Some(_) => Err(missing("capture_ee")),
            },
            (Some(_), None) => Err(missing("capture")),
            (None, Some(_)) => Err(missing("target")),
            (Some(target), Some(capture)) => {
                let target = target.downcast::<PyTarget>().map_err(|_| {
                    super::errors::ModelError::new_err(format!(
                        "target: expected an orbitflex.Target, given {}",
                        target
                            .get_type()
                            .name()
                            .map(|n| n.to_string())
                            .unwrap_or_default()
                    ))
                })?;
                let when = capture.downcast::<PyCaptureWhen>().map_err(|_| {
                    super::errors::ModelError::new_err(format!(
                        "capture: expected an orbitflex.CaptureWhen, given {}",
                        capture
                            .get_type()
                            .name()
                            .map(|n| n.to_string())
                            .unwrap_or_default()
                    ))
                })?;
                let ee = super::convert::ee_arg(arm.robot(), ee.as_ref())?;
                Ok(Some(Self {
                    target: target.get().target.clone(),
                    when: when.get().when,
                    ee: Some(ee),
                }))
            }
        }
    }
}

/// [`simulate_capture_into`] without the GIL: the run's result and its record (complete, or what
/// a failed run kept). A pending `KeyboardInterrupt` (or an exception from the progress
/// callback) is raised as it is.
pub(crate) fn capture_releasing_gil(
    py: Python<'_>,
    arm: &FlexibleArm,
    run: &Run<'_>,
    channels: &mut Channels<'_>,
    progress: &mut Progress,
    recorder: &mut (dyn Recorder + Send),
    capturing: &Capturing,
) -> PyResult<(crate::Result<()>, CaptureRecord)> {
    let mut watch = Watch::new(progress);
    let spec = CaptureRun {
        target: &capturing.target,
        when: capturing.when,
        ee: capturing.ee,
    };
    let outcome = py.allow_threads(|| {
        simulate_capture_into(arm, run, &mut channels.drive(), &spec, &mut watch, recorder)
    });
    if let Some(e) = watch.error {
        return Err(e);
    }
    Ok(match outcome {
        Ok(record) => (Ok(()), record),
        Err(failure) => (Err(failure.error), failure.record),
    })
}

/// The [`CaptureRecord`] of a pickled `Trajectory` (its `_restore_capture`): the events (a
/// list of `CaptureEvent`), the target's rows (13 per row), the combined arm and the target.
pub(crate) fn restore_record(
    events: &Bound<'_, PyAny>,
    target: Vec<f64>,
    arm_after: Option<&Bound<'_, PyFlexibleArm>>,
    body: &Target,
) -> PyResult<CaptureRecord> {
    let events = events
        .try_iter()?
        .map(|e| Ok(e?.downcast::<PyCaptureEvent>()?.get().event.clone()))
        .collect::<PyResult<Vec<_>>>()?;
    if target.len() % crate::capture::TARGET_STATE_LEN != 0 {
        return Err(super::errors::ModelError::new_err(format!(
            "target: expected rows of {} numbers, given {} numbers",
            crate::capture::TARGET_STATE_LEN,
            target.len()
        )));
    }
    Ok(CaptureRecord {
        events,
        target,
        arm_after: arm_after.map(|a| a.get().arm.clone()),
        inertia: *body.spatial_inertia(),
    })
}

/// What a `Trajectory` of a run with a target holds beside the arm's rows.
pub(crate) struct CaptureInfo {
    pub record: CaptureRecord,
    pub events: Py<PyList>,
    pub target: Py<numpy::PyArray2<f64>>,
    pub arm_after: Option<Py<PyFlexibleArm>>,
    /// The run's target at `t = 0`.
    pub body: Py<PyTarget>,
}

impl CaptureInfo {
    pub fn new(
        py: Python<'_>,
        arm: &Bound<'_, PyFlexibleArm>,
        record: CaptureRecord,
        body: &Target,
    ) -> PyResult<Self> {
        let events = PyList::empty(py);
        for event in &record.events {
            events.append(Py::new(
                py,
                PyCaptureEvent {
                    event: event.clone(),
                },
            )?)?;
        }
        let arm_after = match &record.arm_after {
            None => None,
            Some(after) => Some(super::capture::combined_arm(py, arm, after)?),
        };
        let target = super::trajectory::frozen_rows(
            py,
            record.rows(),
            crate::capture::TARGET_STATE_LEN,
            record.target.clone(),
        )?;
        Ok(Self {
            record,
            events: events.unbind(),
            target,
            arm_after,
            body: Py::new(
                py,
                PyTarget {
                    target: body.clone(),
                },
            )?,
        })
    }
}

/// The built-in capture scenario's numbers (wrapped by ``orbitflex.models.capture_scenario``):
/// a dict of ``x0``, the target's ``mass``, ``inertia``, ``pose``, ``twist``, ``grasp`` and
/// ``name``, the trigger's ``distance``, ``speed``, ``angle``, the PD's ``kp``, ``kd`` and
/// ``theta_ref``, ``dt``, ``duration`` and ``meet`` (s).
#[pyfunction]
#[pyo3(name = "_capture_scenario", signature = (tumble_deg_s=2.0, drift=0.02, meet=5.0))]
pub fn py_capture_scenario(
    py: Python<'_>,
    tumble_deg_s: f64,
    drift: f64,
    meet: f64,
) -> PyResult<Bound<'_, pyo3::types::PyDict>> {
    let s = crate::capture::scenario::capture_scenario_with(tumble_deg_s, drift, meet)?;
    let d = pyo3::types::PyDict::new(py);
    let t = &s.target;
    d.set_item("x0", array1(py, &s.x0))?;
    d.set_item("mass", t.mass())?;
    d.set_item("inertia", super::convert::array2(py, t.inertia_about_com()))?;
    d.set_item("pose", array1(py, t.pose()))?;
    d.set_item("twist", array1(py, t.twist().to_vector().as_slice()))?;
    d.set_item("grasp", array1(py, t.grasp()))?;
    d.set_item("name", t.name())?;
    d.set_item("distance", s.when.distance)?;
    d.set_item("speed", s.when.speed)?;
    d.set_item("angle", s.when.angle)?;
    d.set_item("kp", array1(py, &s.controller.kp))?;
    d.set_item("kd", array1(py, &s.controller.kd))?;
    d.set_item(
        "theta_ref",
        array1(py, &crate::capture::scenario::PRE_GRASP),
    )?;
    d.set_item("dt", s.dt)?;
    d.set_item("duration", s.duration)?;
    d.set_item("meet", s.meet)?;
    Ok(d)
}

/// Reads `obj` as one `T` for every run, or a sequence of `runs` of them.
fn per_run<'py, T: pyo3::PyClass>(
    obj: &Bound<'py, PyAny>,
    what: &str,
    runs: usize,
) -> PyResult<Vec<Bound<'py, T>>> {
    if let Ok(one) = obj.downcast::<T>() {
        return Ok(vec![one.clone(); runs]);
    }
    let items: Vec<Bound<'py, PyAny>> = obj.try_iter().and_then(|i| i.collect()).map_err(|_| {
        super::errors::ModelError::new_err(format!(
            "{what}: expected one {} or a sequence of {runs}",
            T::NAME
        ))
    })?;
    if items.len() != runs {
        return Err(super::errors::ModelError::new_err(format!(
            "{what}: expected {runs} (one per target), given {}",
            items.len()
        )));
    }
    items
        .into_iter()
        .enumerate()
        .map(|(k, item)| {
            item.downcast_into::<T>().map_err(|e| {
                super::errors::ModelError::new_err(format!(
                    "{what}[{k}]: expected a {}, given {}",
                    T::NAME,
                    e.into_inner()
                        .get_type()
                        .name()
                        .map(|n| n.to_string())
                        .unwrap_or_default()
                ))
            })
        })
        .collect()
}

/// Many runs with targets at once, over a pool of ``threads`` threads (default every core): run
/// ``k`` is ``arms[k].simulate(x0s[k], dt, steps, controllers[k], target=targets[k],
/// capture=capture, capture_ee=capture_ee, record_every=record_every,
/// wheel_torque=wheel_torque[k])``, bit for bit. ``arms``, ``controllers`` (``MotorPD``) and
/// ``wheel_torque`` (``AttitudePD`` for arms with reaction wheels, or None) may be one for every
/// run; ``x0s`` is (runs, 13 + 4n + k) or one state. Returns the ``Trajectory`` of each run in order (with ``events``,
/// ``target``, ``arm_after``). A run that fails does not stop the others; once all are over, the
/// first failure is raised as ``SimulationError`` naming the run, with its ``trajectory``
/// (what it computed) and ``.trajectories`` (every run's). Ctrl-C stops the runs.
#[pyfunction]
#[pyo3(name = "simulate_capture_batch", signature = (arms, x0s, dt, steps, controllers, targets, capture, *, capture_ee=None, record_every=None, threads=None, wheel_torque=None))]
pub fn py_simulate_capture_batch<'py>(
    py: Python<'py>,
    arms: &Bound<'py, PyAny>,
    x0s: &Bound<'py, PyAny>,
    dt: &Bound<'py, PyAny>,
    steps: &Bound<'py, PyAny>,
    controllers: &Bound<'py, PyAny>,
    targets: &Bound<'py, PyAny>,
    capture: &Bound<'py, PyCaptureWhen>,
    capture_ee: Option<&Bound<'py, PyAny>>,
    record_every: Option<&Bound<'py, PyAny>>,
    threads: Option<usize>,
    wheel_torque: Option<&Bound<'py, PyAny>>,
) -> PyResult<Vec<Py<super::trajectory::PyTrajectory>>> {
    use crate::capture::{simulate_capture_batch, CaptureBatchSettings, CaptureCase};
    use std::sync::atomic::{AtomicBool, AtomicUsize};
    let targets = targets_arg(targets)?;
    let runs = targets.len();
    let arms = per_run::<PyFlexibleArm>(arms, "arms", runs)?;
    let controllers = per_run::<super::control::PyMotorPD>(controllers, "controllers", runs)?;
    let first = &arms[0].get().arm;
    let len = first.layout().len();
    let x0 = states_arg(x0s, runs, len)?;
    for (k, arm) in arms.iter().enumerate() {
        if arm.get().arm.layout().len() != len {
            return Err(super::errors::ModelError::new_err(format!(
                "arms[{k}]: expected {} joints as arms[0], given {}",
                first.dof(),
                arm.get().arm.dof()
            )));
        }
    }
    let settings = CaptureBatchSettings {
        dt: real(dt, "dt")?,
        steps: super::convert::count(steps, "steps")?,
        record_every: super::convert::record_every_arg(record_every)?,
        when: capture.get().when,
        ee: Some(super::convert::ee_arg(first.robot(), capture_ee)?),
        threads,
    };
    let wheel_pds = wheel_pds_arg(wheel_torque, &arms)?;
    let cases: Vec<CaptureCase<'_>> = (0..runs)
        .map(|k| CaptureCase {
            arm: &arms[k].get().arm,
            x0: &x0[k * len..(k + 1) * len],
            controller: &controllers[k].get().pd,
            target: &targets[k].get().target,
            wheel_torque: wheel_pds.get(k),
        })
        .collect();
    let (cancel, done) = (AtomicBool::new(false), AtomicUsize::new(0));
    let outcomes = super::run::watched(
        py,
        &cancel,
        |_| Ok(()),
        || simulate_capture_batch(&cases, &settings, &cancel, &done),
    )??;
    capture_batch_result(py, outcomes, &arms, &targets)
}

/// ``targets``: a non-empty sequence of ``Target``, one per run.
fn targets_arg<'py>(targets: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyTarget>>> {
    let targets: Vec<Bound<'py, PyTarget>> = targets
        .try_iter()
        .and_then(|i| i.collect::<PyResult<Vec<_>>>())
        .map_err(|_| super::errors::ModelError::new_err("targets: expected a sequence of Target"))?
        .into_iter()
        .enumerate()
        .map(|(k, t)| {
            t.downcast_into::<PyTarget>().map_err(|_| {
                super::errors::ModelError::new_err(format!("targets[{k}]: expected a Target"))
            })
        })
        .collect::<PyResult<_>>()?;
    if targets.is_empty() {
        return Err(super::errors::ModelError::new_err(
            "targets: expected at least one Target, given none",
        ));
    }
    Ok(targets)
}

/// ``x0s``: one state of `len` numbers for every run, or `runs` rows of them.
fn states_arg(x0s: &Bound<'_, PyAny>, runs: usize, len: usize) -> PyResult<Vec<f64>> {
    match super::convert::vector(x0s, "x0s", Some(len)) {
        Ok(one) => Ok(one.repeat(runs)),
        Err(_) => {
            let (rows, values) = super::convert::matrix(x0s, "x0s", len)?;
            if rows != runs {
                return Err(super::errors::ModelError::new_err(format!(
                    "x0s: expected ({runs}, {len}) (one state per target), given {rows} rows"
                )));
            }
            Ok(values)
        }
    }
}

/// ``wheel_torque``: none (wheels without a controller get no torque, as in ``simulate``), or
/// an ``AttitudePD`` for every run or one per run, each bound to its arm (which must have
/// wheels).
fn wheel_pds_arg(
    wheel_torque: Option<&Bound<'_, PyAny>>,
    arms: &[Bound<'_, PyFlexibleArm>],
) -> PyResult<Vec<crate::control::AttitudePD>> {
    let Some(obj) = wheel_torque.filter(|o| !o.is_none()) else {
        return Ok(Vec::new());
    };
    per_run::<super::control::PyAttitudePD>(obj, "wheel_torque", arms.len())?
        .iter()
        .zip(arms)
        .enumerate()
        .map(|(k, (pd, arm))| {
            let arm = &arm.get().arm;
            if arm.wheels().is_none() {
                return Err(super::errors::ModelError::new_err(format!(
                    "wheel_torque: arms[{k}] has no reaction wheels; give none (or build \
                     the arm with wheels)"
                )));
            }
            pd.get().bind(arm)
        })
        .collect()
}

/// The ``Trajectory`` of every run, or, once all are over, the first failure as a
/// ``SimulationError`` naming its run, with its trajectory and ``.trajectories`` (every run's).
fn capture_batch_result(
    py: Python<'_>,
    outcomes: Vec<crate::capture::CaptureOutcome>,
    arms: &[Bound<'_, PyFlexibleArm>],
    targets: &[Bound<'_, PyTarget>],
) -> PyResult<Vec<Py<super::trajectory::PyTrajectory>>> {
    let mut trajectories = Vec::with_capacity(outcomes.len());
    let mut failure = None;
    for (k, outcome) in outcomes.into_iter().enumerate() {
        let traj = super::trajectory::PyTrajectory::from_run(
            py,
            arms[k].clone().unbind(),
            outcome.trajectory,
        )?
        .with_capture(CaptureInfo::new(
            py,
            &arms[k],
            outcome.record,
            &targets[k].get().target,
        )?);
        let traj = Py::new(py, traj)?;
        if let (None, Some(error)) = (&failure, outcome.error) {
            failure = Some((k, error, traj.clone_ref(py)));
        }
        trajectories.push(traj);
    }
    if let Some((k, error, traj)) = failure {
        let (step, time) = match &error {
            crate::Error::Simulation { step, time, .. } => (*step, *time),
            _ => (0, 0.0),
        };
        let err = super::errors::simulation_error(
            py,
            format!("run {k}: {error}"),
            step,
            time,
            traj.into_any(),
            None,
        )?;
        err.value(py).setattr("trajectories", trajectories)?;
        return Err(err);
    }
    Ok(trajectories)
}
