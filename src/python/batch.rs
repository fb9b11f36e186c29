//! `orbitflex.simulate_batch` and `orbitflex.BatchTrajectory`: many runs over a pool of threads,
//! without the GIL, honouring Ctrl-C.

use super::arm::PyFlexibleArm;
use super::batched::shape_and_values;
use super::control::{sampled, PyAttitudePD, PyMotorPD, PySampled};
use super::convert::{count, positive_count, real, record_every_arg};
use super::errors::ModelError;
use super::run::{runtime_warning, watched, Progress};
use super::state_columns::{state_getters, StateRecord};
use super::trajectory::{freeze, frozen_rows, PyTrajectory};
use crate::control::AttitudePD;
use crate::flex::{FlexibleArm, StateLayout};
use crate::integrate::batch::{
    simulate_batch_with_lanes, Batch, BatchControl, BatchInput, BatchRecord, BatchSettings,
    BatchWatch, Lanes, PerRun, RunRecord, RunStatus, SampleClock,
};
use crate::MotorPD;
use numpy::ndarray::Array3;
use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods};
use pyo3::exceptions::PyIndexError;
use pyo3::prelude::*;
use pyo3::types::{PyList, PySequence};
use std::sync::atomic::Ordering;

/// An input array of a batch: its shape and its values in C order.
struct Array {
    shape: Vec<usize>,
    values: Vec<f64>,
}

impl Array {
    fn parse(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Self> {
        let (shape, values) = shape_and_values(obj, what)?;
        Ok(Self { shape, values })
    }

    /// The length of the leading run axis, for arrays with one (ndim ≥ `with_run_axis`).
    fn runs(&self, with_run_axis: usize) -> Option<usize> {
        (self.shape.len() >= with_run_axis).then(|| self.shape[0])
    }

    fn input(
        &self,
        what: &str,
        runs: usize,
        steps: Option<usize>,
        width: usize,
    ) -> PyResult<BatchInput<'_>> {
        Ok(BatchInput::new(
            what,
            &self.values,
            &self.shape,
            runs,
            steps,
            width,
        )?)
    }
}

/// An optional per-step input: None (zeros), a scalar (the same for every element) or an array.
fn optional(obj: Option<&Bound<'_, PyAny>>, what: &str, width: usize) -> PyResult<Option<Array>> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(None);
    };
    let mut a = Array::parse(obj, what)?;
    if a.shape.is_empty() {
        a = Array {
            shape: vec![width],
            values: vec![a.values[0]; width],
        };
    }
    Ok(Some(a))
}

fn input_or_zero<'a>(
    a: &'a Option<Array>,
    what: &str,
    runs: usize,
    steps: usize,
    width: usize,
) -> PyResult<BatchInput<'a>> {
    match a {
        None => Ok(BatchInput::zero(width)),
        Some(a) => a.input(what, runs, Some(steps), width),
    }
}

/// A `FlexibleArm`, or a sequence of them.
fn arms<'py>(obj: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyFlexibleArm>>> {
    if let Ok(arm) = obj.downcast::<PyFlexibleArm>() {
        return Ok(vec![arm.clone()]);
    }
    let wrong = || {
        ModelError::new_err(format!(
            "arm_or_arms: expected a FlexibleArm or a sequence of them (one per run), given {}",
            obj.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    };
    let seq = obj.downcast::<PySequence>().map_err(|_| wrong())?;
    let mut out = Vec::new();
    for (k, item) in seq.try_iter()?.enumerate() {
        let item = item?;
        out.push(item.downcast::<PyFlexibleArm>().cloned().map_err(|_| {
            ModelError::new_err(format!(
                "arm_or_arms[{k}]: expected a FlexibleArm, given {}",
                item.get_type()
                    .name()
                    .map(|n| n.to_string())
                    .unwrap_or_default()
            ))
        })?);
    }
    if out.is_empty() {
        return Err(ModelError::new_err(
            "arm_or_arms: expected a FlexibleArm or a non-empty sequence of them, given an empty \
             sequence",
        ));
    }
    Ok(out)
}

/// The Python type name of `obj`, for messages.
fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_default()
}

/// One channel of a batch from Python (``u`` or ``wheel_torque``), before it borrows: an array,
/// a ``MotorPD`` or an ``AttitudePD`` (one shared, or one per run: the flag says shared), at its
/// own rate when given inside a ``Sampled``.
struct Channel<'py> {
    control: Control<'py>,
    clock: Option<SampleClock>,
}

enum Control<'py> {
    Open(Option<Array>),
    Pd(Vec<Bound<'py, PyMotorPD>>, bool),
    Attitude(Vec<Bound<'py, PyAttitudePD>>, bool),
}

impl<'py> Channel<'py> {
    /// The channel `what` (`"u"`, width n, or `"wheel_torque"`, width k) from its argument.
    fn parse(obj: Option<&Bound<'py, PyAny>>, what: &str, width: usize) -> PyResult<Self> {
        let Some(obj) = obj.filter(|o| !o.is_none()) else {
            return Ok(Self {
                control: Control::Open(None),
                clock: None,
            });
        };
        if let Some((inner, rate_hz, delay)) = sampled(Some(obj))? {
            if inner.is_instance_of::<PySampled>() {
                return Err(ModelError::new_err(format!(
                    "{what}: a Sampled inside a Sampled; sample the controller once, at the rate \
                     it runs at"
                )));
            }
            return Ok(Self {
                control: Control::parse(&inner, what, width)?,
                clock: Some(SampleClock { rate_hz, delay }),
            });
        }
        Ok(Self {
            control: Control::parse(obj, what, width)?,
            clock: None,
        })
    }

    /// The length of the run axis this channel gives, if any.
    fn runs(&self) -> Option<usize> {
        match &self.control {
            Control::Open(a) => a.as_ref().and_then(|a| a.runs(2)),
            Control::Pd(pds, false) => Some(pds.len()),
            Control::Attitude(pds, false) => Some(pds.len()),
            Control::Pd(_, true) | Control::Attitude(_, true) => None,
        }
    }

    /// The `AttitudePD`s bound to the wheels of their runs' arms (`arms`, one per run): none
    /// for another control, one when both the controller and the arm are shared, else one per
    /// run. Errors name the run.
    fn bind(&self, arms: &[&FlexibleArm], shared_arm: bool) -> PyResult<Vec<AttitudePD>> {
        let Control::Attitude(pds, shared) = &self.control else {
            return Ok(Vec::new());
        };
        if *shared && shared_arm {
            return Ok(vec![pds[0].get().bind(arms[0])?]);
        }
        let mut bound = Vec::with_capacity(arms.len());
        for (run, arm) in arms.iter().enumerate() {
            let pd = &pds[if *shared { 0 } else { run }];
            bound.push(pd.get().bind(arm).map_err(|e| {
                ModelError::new_err(format!("wheel_torque (run {run}): {}", e.value(pd.py())))
            })?);
        }
        Ok(bound)
    }

    /// The [`BatchControl`] before sampling, borrowing the controllers in `pds` (the
    /// `MotorPD`s, as given) and `attitudes` (as bound by [`Channel::bind`]).
    fn plain<'s>(
        &'s self,
        pds: &'s [&'s MotorPD],
        attitudes: &'s [&'s AttitudePD],
        what: &str,
        runs: usize,
        steps: usize,
        width: usize,
    ) -> PyResult<BatchControl<'s>> {
        let per_run = |len: usize| len != 1 || !self.is_shared();
        Ok(match &self.control {
            Control::Open(a) => BatchControl::Open(input_or_zero(a, what, runs, steps, width)?),
            Control::Pd(..) if per_run(pds.len()) => BatchControl::Pd(PerRun::Each(pds)),
            Control::Pd(..) => BatchControl::Pd(PerRun::All(pds[0])),
            Control::Attitude(..) if per_run(attitudes.len()) => {
                BatchControl::Attitude(PerRun::Each(attitudes))
            }
            Control::Attitude(..) => BatchControl::Attitude(PerRun::All(attitudes[0])),
        })
    }

    fn is_shared(&self) -> bool {
        matches!(
            self.control,
            Control::Pd(_, true) | Control::Attitude(_, true) | Control::Open(_)
        )
    }

    /// `plain`, at its own rate if the channel was sampled.
    fn wrap<'s>(&self, plain: &'s BatchControl<'s>) -> BatchControl<'s> {
        match self.clock {
            Some(clock) => BatchControl::Sampled(plain, clock),
            None => *plain,
        }
    }
}

/// What a channel accepts, and what the other channel's controller drives: for `u`, torques or
/// a `MotorPD` (an `AttitudePD` drives the wheels); for `wheel_torque`, the reverse.
fn accepted(wheels: bool) -> (&'static str, &'static str) {
    if wheels {
        (
            "wheel torques (an array) or an AttitudePD",
            "the motors (u)",
        )
    } else {
        (
            "torques (an array) or a MotorPD",
            "the reaction wheels (wheel_torque)",
        )
    }
}

/// `given` (a controller of the other channel) refused on `what`.
fn refused(what: &str, wheels: bool, given: &str) -> PyErr {
    let (accepted, other) = accepted(wheels);
    ModelError::new_err(format!(
        "{what}: {given} drives {other}; give {accepted} (one, or one per run), \
         optionally inside a Sampled"
    ))
}

impl<'py> Control<'py> {
    fn parse(obj: &Bound<'py, PyAny>, what: &str, width: usize) -> PyResult<Self> {
        let wheels = what == "wheel_torque";
        if obj.is_instance_of::<PyMotorPD>() {
            return match wheels {
                false => Ok(Control::Pd(
                    vec![obj.downcast::<PyMotorPD>()?.clone()],
                    true,
                )),
                true => Err(refused(what, wheels, "a MotorPD")),
            };
        }
        if obj.is_instance_of::<PyAttitudePD>() {
            return match wheels {
                true => Ok(Control::Attitude(
                    vec![obj.downcast::<PyAttitudePD>()?.clone()],
                    true,
                )),
                false => Err(refused(what, wheels, "an AttitudePD")),
            };
        }
        if obj.is_callable() {
            return Err(ModelError::new_err(format!(
                "{what}: simulate_batch runs without the GIL, so it cannot call a Python \
                 controller; give {} (one, or one per run, optionally inside a \
                 Sampled), or call FlexibleArm.simulate for each run",
                accepted(wheels).0
            )));
        }
        // a sequence of controllers, one per run (a buffer such as a 2-D memoryview is a
        // sequence whose items cannot be taken: it is an array)
        if let Ok(seq) = obj.downcast::<PySequence>() {
            if let Some(control) = Self::per_run(seq, what, wheels)? {
                return Ok(control);
            }
        }
        Ok(Control::Open(optional(Some(obj), what, width)?))
    }

    /// A sequence of controllers, one per run, or `None` if its first item is no controller
    /// (then it is an array).
    fn per_run(seq: &Bound<'py, PySequence>, what: &str, wheels: bool) -> PyResult<Option<Self>> {
        let first = seq
            .len()
            .ok()
            .filter(|&len| len > 0)
            .and_then(|_| seq.get_item(0).ok());
        let Some(first) = first else {
            return Ok(None);
        };
        if first.is_instance_of::<PySampled>() {
            return Err(ModelError::new_err(format!(
                "{what}: a sequence of Sampled; give one Sampled around the sequence of \
                 controllers (Sampled([c_0, c_1, …], rate_hz, delay)): the runs share \
                 one clock"
            )));
        }
        if first.is_instance_of::<PyMotorPD>() {
            if wheels {
                return Err(refused(what, wheels, "a MotorPD"));
            }
            return Ok(Some(Control::Pd(items(seq, what, "a MotorPD")?, false)));
        }
        if first.is_instance_of::<PyAttitudePD>() {
            if !wheels {
                return Err(refused(what, wheels, "an AttitudePD"));
            }
            return Ok(Some(Control::Attitude(
                items(seq, what, "an AttitudePD")?,
                false,
            )));
        }
        Ok(None)
    }
}

/// Every item of `seq`, each a `T` (named `kind` in the message naming the first that is not).
fn items<'py, T: pyo3::PyClass>(
    seq: &Bound<'py, PySequence>,
    what: &str,
    kind: &str,
) -> PyResult<Vec<Bound<'py, T>>> {
    let mut out = Vec::new();
    for (k, item) in seq.try_iter()?.enumerate() {
        let item = item?;
        out.push(item.downcast::<T>().cloned().map_err(|_| {
            ModelError::new_err(format!(
                "{what}[{k}]: expected {kind} ({what}[0] is one), given {}",
                type_name(&item)
            ))
        })?);
    }
    Ok(out)
}

/// The number of runs: the length of every leading run axis that is not 1, which must agree.
fn count_runs(candidates: &[(&str, Option<usize>)]) -> PyResult<usize> {
    let mut runs: Option<(&str, usize)> = None;
    for &(what, r) in candidates {
        match (r, runs) {
            (Some(r), None) if r != 1 => runs = Some((what, r)),
            (Some(r), Some((first, b))) if r != 1 && r != b => {
                return Err(ModelError::new_err(format!(
                    "runs: {first} gives {b} runs but {what} gives {r}; every leading run axis \
                     must have length 1 or the number of runs"
                )))
            }
            _ => {}
        }
    }
    Ok(runs.map_or(1, |(_, b)| b))
}

/// The warning for runs whose `dt` is past their stability limit: `unstable` holds (run, limit)
/// pairs, `runs` the batch's size. One run is named with its limit; several are listed (the
/// first ten) with the smallest limit.
fn stability_warning(dt: f64, runs: usize, unstable: &[(usize, f64)]) -> String {
    let which = match unstable {
        [(_, limit)] if runs == 1 => format!(
            "the RK4 stability limit {limit:.4e} s of the run (linearised at its x0); it will \
             likely diverge"
        ),
        [(run, limit)] => format!(
            "the RK4 stability limit {limit:.4e} s of run {run} of {runs} (linearised at its \
             x0); it will likely diverge"
        ),
        _ => {
            let shown: Vec<String> = unstable
                .iter()
                .take(10)
                .map(|(r, _)| r.to_string())
                .collect();
            let more = if unstable.len() > 10 { ", …" } else { "" };
            let smallest = unstable
                .iter()
                .map(|(_, l)| *l)
                .fold(f64::INFINITY, f64::min);
            let count = if unstable.len() == runs {
                format!("all {runs}")
            } else {
                format!("{} of {runs}", unstable.len())
            };
            format!(
                "the RK4 stability limit of {count} runs (runs {}{more}; smallest limit \
                 {smallest:.4e} s, linearised at each run's x0); they will likely diverge",
                shown.join(", ")
            )
        }
    };
    format!("dt = {dt:e} s exceeds {which}")
}

/// `lanes=` of `simulate_batch`: None, a bool, or a width 1, 4 or 8.
fn parse_lanes(obj: Option<&Bound<'_, PyAny>>) -> PyResult<Lanes> {
    let Some(obj) = obj.filter(|o| !o.is_none()) else {
        return Ok(Lanes::Auto);
    };
    if let Ok(b) = obj.downcast::<pyo3::types::PyBool>() {
        return Ok(match b.is_true() {
            true => Lanes::Width(crate::lanes::processor_width()),
            false => Lanes::Off,
        });
    }
    match obj.extract::<i64>() {
        Ok(1) => Ok(Lanes::Off),
        Ok(w @ (4 | 8)) => Ok(Lanes::Width(w as usize)),
        _ => Err(ModelError::new_err(format!(
            "lanes: expected None, True, False, 1, 4 or 8, given {}",
            obj.repr().map(|r| r.to_string()).unwrap_or_default()
        ))),
    }
}

/// Simulates many runs of the flexible arm at once, over a pool of threads, without the GIL.
///
/// ``simulate_batch(arm_or_arms, x0s, dt, steps, u=None, base_wrench=None, ee_wrench=None,
/// threads=None, record_every=None, *, keep_rows=True, progress=None, wheel_torque=None)``
/// returns a :class:`BatchTrajectory`. Run ``b`` is exactly ``arm.simulate(x0s[b], dt, steps,
/// u[b], base_wrench[b], ee_wrench[b], wheel_torque=wheel_torque[b],
/// record_every=record_every)``, bit for bit, whatever the number of threads.
///
/// Inputs broadcast over a leading run axis as numpy does (B runs; each leading axis is 1 or B):
///
/// - ``arm_or_arms``: one ``FlexibleArm`` for every run, or a sequence of B (dispersed
///   stiffness, payloads; all with the same number of joints n);
/// - ``x0s``: (13+4n,) for every run, or (B, 13+4n);
/// - ``u`` (N·m, link side): None (zero), a scalar, (n,) constant for every run, (B, n) constant
///   per run, (B, steps, n) or (1, steps, n) tables (a 2-D ``u`` is always one row per run: one
///   table for every run is (1, steps, n)); or one ``MotorPD`` (each run starts from a copy) or
///   a sequence of B. A Python callable is refused: the runs go without the GIL;
/// - ``base_wrench`` (base frame, applied to the base) and ``ee_wrench`` (EE frame, exerted by
///   the EE): as ``u`` with 6 (``[moment (N·m); force (N)]``) in place of n; with k
///   end-effectors, ``ee_wrench`` rows are (k, 6) (so (runs, k, 6), (runs, steps, k, 6), …), or a
///   dict from EE link name to such arrays with 6 in place of (k, 6);
/// - ``wheel_torque`` (keyword; arms with w reaction wheels, all the same w): the wheel torque
///   commands, as ``u`` with w in place of n; or one ``AttitudePD`` (each run starts from a
///   copy, bound to its run's wheels as ``arm.simulate`` binds it) or a sequence of B;
///   saturated once per step, and the applied torques recorded
///   (``BatchTrajectory.wheel_torque``);
/// - ``Sampled(c, rate_hz, delay)`` around any of the above on ``u`` or ``wheel_torque`` (``c``
///   a ``MotorPD``, an ``AttitudePD``, a sequence of B of them, or an array) runs it at its own
///   rate in every run, exactly as in ``arm.simulate``. Only Python callables are refused.
///
/// ``threads=None`` uses every core (at most 1024 threads). ``record_every=k`` (None: 1) keeps rows 0, k, 2k, … and
/// the final row. ``keep_rows=False`` keeps only the per-run summaries and final states (no rows), for
/// campaigns of 10⁵ runs. ``progress(done, runs)`` is called about every 0.1 s.
///
/// One run that fails (a diverged state) never stops the others: its ``failed_step`` is the
/// ``SimulationError.step`` that ``arm.simulate`` would raise for it, and its rows after the
/// failure are NaN. Warns once (``RuntimeWarning``) when ``dt`` is past the RK4 stability limit
/// of some runs, naming how many and which. Ctrl-C stops every run and raises
/// ``KeyboardInterrupt``. Bad shapes raise ``ModelError`` naming the argument, the shapes
/// accepted and the shape given (and the run, for a bad row).
///
/// ``lanes`` (keyword): runs of one robot (with as many reaction wheels) go 4 or 8 at a time
/// through each RK4 step in SIMD lanes, each lane bit for bit its scalar run (the record is the
/// same whatever ``lanes`` says; the controllers, ``MotorPD``, ``AttitudePD``, ``Sampled`` or
/// tables, are called per run). ``None`` (default): lanes of the processor's width (8 with
/// AVX-512, else 4), unless the environment variable ``ORBITFLEX_LANES`` is ``0`` or ``1`` (the
/// scalar path) or ``4``/``8``; ``False`` or ``1``: the scalar path; ``True``: the processor's
/// width; ``4`` or ``8``: that width.
#[pyfunction]
#[pyo3(name = "simulate_batch", signature = (arm_or_arms, x0s, dt, steps, u=None, base_wrench=None, ee_wrench=None, threads=None, record_every=None, *, keep_rows=true, progress=None, wheel_torque=None, lanes=None))]
pub(crate) fn py_simulate_batch<'py>(
    py: Python<'py>,
    arm_or_arms: &Bound<'py, PyAny>,
    x0s: &Bound<'py, PyAny>,
    dt: &Bound<'py, PyAny>,
    steps: &Bound<'py, PyAny>,
    u: Option<&Bound<'py, PyAny>>,
    base_wrench: Option<&Bound<'py, PyAny>>,
    ee_wrench: Option<&Bound<'py, PyAny>>,
    threads: Option<&Bound<'py, PyAny>>,
    record_every: Option<&Bound<'py, PyAny>>,
    keep_rows: bool,
    progress: Option<&Bound<'py, PyAny>>,
    wheel_torque: Option<&Bound<'py, PyAny>>,
    lanes: Option<&Bound<'py, PyAny>>,
) -> PyResult<PyBatchTrajectory> {
    let lanes = parse_lanes(lanes)?;
    let settings = batch_settings(dt, steps, record_every, keep_rows, threads)?;
    let steps = settings.steps;
    let arm_objects = arms(arm_or_arms)?;
    let arm_refs: Vec<&FlexibleArm> = arm_objects.iter().map(|a| &a.get().arm).collect();
    let layout = arm_refs[0].layout();
    let n = layout.n;
    let x0 = Array::parse(x0s, "x0s")?;
    let control = Channel::parse(u, "u", n)?;
    let fb = optional(base_wrench, "base_wrench", 6)?;
    let ee_robot = arm_refs[0].robot();
    let k6 = 6 * ee_robot.end_effectors().len();
    let ee_wrench = super::convert::ee_wrench_arg(ee_robot, ee_wrench)?;
    let fee = optional(ee_wrench.as_ref(), "ee_wrench", k6)?;
    let wheels = layout.wheels;
    if wheels == 0 && wheel_torque.is_some_and(|w| !w.is_none()) {
        return Err(ModelError::new_err(
            "wheel_torque: the arms have no reaction wheels; give none",
        ));
    }
    let wheel_control = Channel::parse(wheel_torque, "wheel_torque", wheels)?;
    let shared_arm = arm_or_arms.is_instance_of::<PyFlexibleArm>();
    let runs = count_runs(&[
        ("arm_or_arms", (!shared_arm).then_some(arm_refs.len())),
        ("x0s", x0.runs(2)),
        ("u", control.runs()),
        ("base_wrench", fb.as_ref().and_then(|a| a.runs(2))),
        ("ee_wrench", fee.as_ref().and_then(|a| a.runs(2))),
        ("wheel_torque", wheel_control.runs()),
    ])?;
    let all_arms: Vec<&FlexibleArm> = if arm_refs.len() == runs {
        arm_refs.clone()
    } else {
        vec![arm_refs[0]; runs]
    };
    let pd_refs: Vec<&MotorPD> = match &control.control {
        Control::Pd(pds, _) => pds.iter().map(|p| &p.get().pd).collect(),
        _ => Vec::new(),
    };
    let attitudes = wheel_control.bind(&all_arms, arm_refs.len() == 1)?;
    let attitude_refs: Vec<&AttitudePD> = attitudes.iter().collect();
    let u_plain = control.plain(&pd_refs, &[], "u", runs, steps, n)?;
    let wheel_plain =
        wheel_control.plain(&[], &attitude_refs, "wheel_torque", runs, steps, wheels)?;
    let batch = Batch {
        runs,
        arms: if arm_refs.len() == 1 {
            PerRun::All(arm_refs[0])
        } else {
            PerRun::Each(&all_arms)
        },
        x0: x0.input("x0s", runs, None, layout.len())?,
        u: control.wrap(&u_plain),
        base_wrench: input_or_zero(&fb, "base_wrench", runs, steps, 6)?,
        ee_wrench: input_or_zero(&fee, "ee_wrench", runs, steps, k6)?,
        wheel_torque: wheel_control.wrap(&wheel_plain),
    };
    let record = run_batch(py, &batch, &settings, Progress::from_arg(progress), lanes)?;
    let arm_handles = arm_objects.into_iter().map(Bound::unbind).collect();
    PyBatchTrajectory::new(py, arm_handles, record)
}

/// The settings of :func:`simulate_batch`, read in the order of its arguments.
fn batch_settings(
    dt: &Bound<'_, PyAny>,
    steps: &Bound<'_, PyAny>,
    record_every: Option<&Bound<'_, PyAny>>,
    keep_rows: bool,
    threads: Option<&Bound<'_, PyAny>>,
) -> PyResult<BatchSettings> {
    Ok(BatchSettings {
        dt: real(dt, "dt")?,
        steps: count(steps, "steps")?,
        record_every: record_every_arg(record_every)?,
        keep_rows,
        threads: match threads.filter(|o| !o.is_none()) {
            Some(t) => Some(positive_count(t, "threads")?),
            None => None,
        },
    })
}

/// Checks the batch, warns once about the runs past their RK4 stability limit, and runs it,
/// every step without the GIL (stopping within `SIGNAL_CHECK` of Ctrl-C).
fn run_batch(
    py: Python<'_>,
    batch: &Batch<'_>,
    settings: &BatchSettings,
    progress: Progress,
    lanes: Lanes,
) -> PyResult<BatchRecord> {
    let (dt, runs) = (settings.dt, batch.runs);
    let watch = BatchWatch::default();
    let unstable = watched(
        py,
        &watch.cancel,
        |_| Ok(()),
        || {
            batch.check_watched(settings, &watch)?;
            batch.unstable_runs_watched(dt, settings.threads, &watch)
        },
    )??;
    if !unstable.is_empty() {
        runtime_warning(py, stability_warning(dt, runs, &unstable))?;
    }
    let tick = |py: Python<'_>| progress.report(py, watch.done.load(Ordering::Relaxed), runs);
    let record = watched(py, &watch.cancel, tick, || {
        simulate_batch_with_lanes(batch, settings, &watch, lanes)
    })??;
    progress.finish(py, runs, runs)?;
    Ok(record)
}

/// The record of :func:`simulate_batch`: B runs with a leading run axis, read-only arrays.
///
/// - ``t`` (rows,) in s, shared by every run; ``x`` (B, rows, 13+4n); ``u`` (B, rows − 1, n),
///   the motor torques (N·m) held during the step starting at each row;
/// - views of ``x`` (no copy): ``base_pose`` (B, rows, 7), ``q``, ``theta`` (rad),
///   ``base_twist`` (B, rows, 6), ``qd``, ``theta_dot`` (rad/s), as in ``Trajectory``;
/// - ``ok`` (B,) bool; ``failed_step`` (B,) int64, the failing step of each run, −1 for a run
///   that finished; ``messages``, why each run failed (None if it finished);
/// - summaries over *every* step (kept or not): ``final_state`` (B, 13+4n), the last (good)
///   state; ``peak_deflection`` (B, n) ``max |θ − q|`` (rad); ``peak_torque`` (B, n)
///   ``max |u|`` (N·m);
/// - ``run(b)``: run b as the ``Trajectory`` that ``arm.simulate`` returns for it (for a failed
///   run, the trajectory its ``SimulationError`` carries).
///
/// Rows after a run's failure are NaN. With ``keep_rows=False`` there are no rows: ``x`` is
/// (B, 0, 13+4n) and only the summaries are kept.
#[pyclass(name = "BatchTrajectory", module = "orbitflex", frozen)]
pub struct PyBatchTrajectory {
    arms: Vec<Py<PyFlexibleArm>>,
    layout: StateLayout,
    runs: usize,
    rows: usize,
    steps: usize,
    record_every: usize,
    status: Vec<RunStatus>,
    t: Py<PyArray1<f64>>,
    x: Py<PyArray3<f64>>,
    u: Py<PyArray3<f64>>,
    final_state: Py<PyArray2<f64>>,
    peak_deflection: Py<PyArray2<f64>>,
    peak_torque: Py<PyArray2<f64>>,
}

fn frozen3(
    py: Python<'_>,
    shape: (usize, usize, usize),
    values: Vec<f64>,
) -> PyResult<Py<PyArray3<f64>>> {
    let a = PyArray3::from_owned_array(
        py,
        Array3::from_shape_vec(shape, values).expect("shape matches the record"),
    );
    freeze(a.as_any())?;
    Ok(a.unbind())
}

impl PyBatchTrajectory {
    fn new(py: Python<'_>, arms: Vec<Py<PyFlexibleArm>>, record: BatchRecord) -> PyResult<Self> {
        let (runs, rows, layout) = (record.runs, record.rows, record.layout);
        let (len, n) = (layout.len(), layout.n);
        let t = PyArray1::from_vec(py, record.t);
        freeze(t.as_any())?;
        Ok(Self {
            arms,
            layout,
            runs,
            rows,
            steps: record.steps,
            record_every: record.record_every,
            status: record.status,
            t: t.unbind(),
            x: frozen3(py, (runs, rows, len), record.x)?,
            u: frozen3(
                py,
                (runs, rows.saturating_sub(1), layout.inputs_len()),
                record.u,
            )?,
            final_state: frozen_rows(py, runs, len, record.final_state)?,
            peak_deflection: frozen_rows(py, runs, n, record.peak_deflection)?,
            peak_torque: frozen_rows(py, runs, n, record.peak_torque)?,
        })
    }

    fn arm(&self, py: Python<'_>, run: usize) -> Py<PyFlexibleArm> {
        self.arms[if self.arms.len() == 1 { 0 } else { run }].clone_ref(py)
    }
}

impl StateRecord for PyBatchTrajectory {
    fn layout(&self) -> StateLayout {
        self.layout
    }
    fn states<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        self.x.bind(py).clone().into_any()
    }
    fn inputs<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        self.u.bind(py).clone().into_any()
    }
}

state_getters!(
    PyBatchTrajectory,
    rows: "B, rows",
    u: "Motor torques (N·m, link side) held during the step starting at each row but the last, \
        (B, rows − 1, n); NaN after a run's failure.",
    wheel_torque: "Reaction-wheel torques applied (after saturation) during the step starting at \
                   each row but the last, (B, rows − 1, w) (N·m); w = 0 without wheels."
);

#[pymethods]
impl PyBatchTrajectory {
    /// Number of runs B.
    #[getter]
    fn runs(&self) -> usize {
        self.runs
    }
    /// Steps per run.
    #[getter]
    fn steps(&self) -> usize {
        self.steps
    }
    /// The ``record_every`` of the batch.
    #[getter]
    fn record_every(&self) -> usize {
        self.record_every
    }
    /// Times of the rows (s), (rows,).
    #[getter]
    fn t(&self, py: Python<'_>) -> Py<PyArray1<f64>> {
        self.t.clone_ref(py)
    }
    /// States, (B, rows, 13+4n); NaN after a run's failure.
    #[getter]
    fn x(&self, py: Python<'_>) -> Py<PyArray3<f64>> {
        self.x.clone_ref(py)
    }
    /// Whether each run finished, (B,) bool.
    #[getter]
    fn ok<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let values: Vec<bool> = self
            .status
            .iter()
            .map(|s| s.failed_step().is_none())
            .collect();
        let a = PyArray1::from_vec(py, values).into_any();
        freeze(&a)?;
        Ok(a)
    }
    /// The failing step of each run (its ``SimulationError.step``), −1 for a run that
    /// finished, (B,) int64.
    #[getter]
    fn failed_step<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let values: Vec<i64> = self
            .status
            .iter()
            .map(|s| s.failed_step().map_or(-1, |k| k as i64))
            .collect();
        let a = PyArray1::from_vec(py, values).into_any();
        freeze(&a)?;
        Ok(a)
    }
    /// Why each run failed (the message of its ``SimulationError``), or None.
    #[getter]
    fn messages<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let items: Vec<Option<String>> = self
            .status
            .iter()
            .map(|s| match s {
                RunStatus::Finished => None,
                RunStatus::Failed {
                    step,
                    time,
                    message,
                } => Some(
                    crate::Error::Simulation {
                        step: *step,
                        time: *time,
                        message: message.clone(),
                    }
                    .to_string(),
                ),
            })
            .collect();
        PyList::new(py, items)
    }
    /// The last state of each run (its last good state if it failed), (B, 13+4n).
    #[getter]
    fn final_state(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.final_state.clone_ref(py)
    }
    /// ``max |θ_i − q_i|`` (rad) over every state of each run, kept or not, (B, n).
    #[getter]
    fn peak_deflection(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.peak_deflection.clone_ref(py)
    }
    /// ``max |u_i|`` (N·m) over every step of each run, kept or not, (B, n).
    #[getter]
    fn peak_torque(&self, py: Python<'_>) -> Py<PyArray2<f64>> {
        self.peak_torque.clone_ref(py)
    }

    /// Run ``b`` as the ``Trajectory`` that ``arm.simulate`` (same ``record_every``) returns
    /// for it; for a failed run, the trajectory its ``SimulationError`` carries. Negative ``b``
    /// counts from the end.
    fn run(&self, py: Python<'_>, b: isize) -> PyResult<PyTrajectory> {
        let run = if b < 0 { b + self.runs as isize } else { b };
        if run < 0 || run >= self.runs as isize {
            return Err(PyIndexError::new_err(format!(
                "run: expected an index from {} to {}, given {b}",
                -(self.runs as isize),
                self.runs - 1
            )));
        }
        let run = run as usize;
        if self.rows == 0 {
            return Err(ModelError::new_err(
                "run: this batch kept no rows (keep_rows=False); only its summaries and final \
                 states",
            ));
        }
        let (len, n, rows) = (self.layout.len(), self.layout.inputs_len(), self.rows);
        let t = self.t.bind(py).readonly();
        let x = self.x.bind(py).readonly();
        let u = self.u.bind(py).readonly();
        let last = self.final_state.bind(py).readonly();
        let record = RunRecord {
            layout: self.layout,
            record_every: self.record_every,
            t: t.as_slice()?,
            x: &x.as_slice()?[run * rows * len..(run + 1) * rows * len],
            u: &u.as_slice()?[run * (rows - 1) * n..(run + 1) * (rows - 1) * n],
            final_state: &last.as_slice()?[run * len..(run + 1) * len],
            status: &self.status[run],
        };
        PyTrajectory::from_run(py, self.arm(py, run), record.to_trajectory())
    }

    fn __len__(&self) -> usize {
        self.runs
    }

    fn __repr__(&self) -> String {
        let failed = self
            .status
            .iter()
            .filter(|s| s.failed_step().is_some())
            .count();
        format!(
            "BatchTrajectory(runs={}, rows={}, steps={}, failed={failed}, dof={})",
            self.runs, self.rows, self.steps, self.layout.n
        )
    }
}
