//! Many runs at once: [`simulate_batch`] integrates `B` independent runs of the flexible arm over
//! a pool of threads, each run exactly as [`simulate`](super::simulate()) would, into one
//! contiguous record with a status per run.
//!
//! **Inputs broadcast over the run axis** as numpy broadcasts. Each per-step input is a
//! [`BatchInput`] of some width `w` (`n` for torques, 6 for wrenches, `13 + 4n` for initial
//! states) given with its shape:
//!
//! | shape | meaning |
//! |---|---|
//! | `(w,)` | one constant row for every run and step |
//! | `(B, w)` or `(1, w)` | a constant row per run (or one for all) |
//! | `(B, steps, w)` or `(1, steps, w)` | a table per run (or one for all), one row per step |
//!
//! Arms and controllers ([`BatchControl`]: a [`MotorPD`] on the motors, an [`AttitudePD`] on the
//! reaction wheels, either at its own rate) are [`PerRun`]: one shared by every run, or one per
//! run (dispersed stiffness, payloads, wheels, gains).
//!
//! **Record.** With `record_every = k` every run keeps rows `0, k, 2k, …` and the final row (the
//! rule of [`record`](super::record)); the rows of all runs live in one buffer `(B, rows, 13+4n)`.
//! A run that fails at step `s` keeps its rows up to `s` and NaN after them; its last good state
//! is in [`BatchRecord::final_state`], as for a complete run. Every run also keeps a summary
//! computed from *every* state and input, kept or not: the peak deflection `max |θ − q|` and the
//! peak torque `max |u|` per joint. With [`BatchSettings::keep_rows`] false only the summaries
//! and final states are kept: 55 numbers per run of a 7-joint arm, 44 MB for 10⁵ runs.
//!
//! **Determinism.** Each run is computed on one thread from its own inputs, with the same
//! arithmetic as [`simulate`](super::simulate()), so a batch equals its runs made one by one,
//! bit for bit, whatever the number of threads.
//!
//! ```
//! use orbitflex::integrate::batch::{
//!     simulate_batch, Batch, BatchControl, BatchInput, BatchSettings, BatchWatch, PerRun,
//! };
//! use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
//! let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
//! let x0 = arm.rest_state();
//! // three runs from rest, each with its own constant torque on every motor (N·m)
//! let u = [0.5; 7].iter().chain(&[1.0; 7]).chain(&[2.0; 7]).copied().collect::<Vec<_>>();
//! let batch = Batch {
//!     runs: 3,
//!     arms: PerRun::All(&arm),
//!     x0: BatchInput::new("x0s", &x0, &[x0.len()], 3, None, x0.len())?,
//!     u: BatchControl::Open(BatchInput::new("u", &u, &[3, 7], 3, Some(100), 7)?),
//!     base_wrench: BatchInput::zero(6),
//!     ee_wrench: BatchInput::zero(6),
//!     wheel_torque: BatchControl::zero(0),
//! };
//! let settings = BatchSettings { dt: 1e-3, steps: 100, record_every: 10, keep_rows: true, threads: Some(2) };
//! let record = simulate_batch(&batch, &settings, &BatchWatch::default())?;
//! assert_eq!((record.runs, record.rows), (3, 11));
//! assert!(record.status.iter().all(|s| s.failed_step().is_none()));
//! // twice the torque, (nearly) twice the deflection
//! let d = |run: usize| record.peak_deflection[run * 7];
//! assert!(d(2) > 1.9 * d(1) && d(1) > 1.9 * d(0));
//! # Ok::<(), orbitflex::Error>(())
//! ```

mod input;
mod pool;
mod record;

pub use input::BatchInput;
pub use pool::{in_pool, Cancel, MAX_THREADS};
pub use record::{BatchRecord, RunRecord, RunStatus};

use super::record::{is_recorded, recorded_rows, Recorder};
use super::run::Run;
use super::simulate::simulate_into;
use crate::control::{AttitudePD, MotorPD};
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;
pub use crate::lanes::Lanes;
use crate::lanes::{lane_groups, simulate_lanes, LaneRun};
use rayon::prelude::*;
use record::{buffer, per_run, Slot, SlotRecorder};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// One value shared by every run, or one per run.
#[derive(Debug)]
pub enum PerRun<'a, T> {
    /// The same for every run.
    All(&'a T),
    /// Run `b` uses element `b` (exactly `B` elements, borrowed: a thousand runs of one model
    /// need not copy it).
    Each(&'a [&'a T]),
}

impl<T> Clone for PerRun<'_, T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for PerRun<'_, T> {}

impl<'a, T> PerRun<'a, T> {
    /// The value of run `run`.
    #[inline]
    pub fn get(&self, run: usize) -> &'a T {
        match self {
            PerRun::All(v) => v,
            PerRun::Each(v) => v[run],
        }
    }

    fn is_shared(&self) -> bool {
        matches!(self, PerRun::All(_))
    }
}

/// What drives one channel (the motors `u`, or the reaction wheels `wheel_torque`) of each run.
///
/// Every controller is copied for each run, which starts from its copy (its state, such as an
/// [`AttitudePD`]'s latched attitude or a [`Sampled`](crate::control::Sampled) hold, is the
/// run's own): run `b` is exactly the single run driven by the same controller.
///
/// | variant | channel |
/// |---|---|
/// | [`Open`](Self::Open) | either: a table (or constant) per run |
/// | [`Pd`](Self::Pd) | `u`: a motor-side PD |
/// | [`Attitude`](Self::Attitude) | `wheel_torque`: the bus's attitude held by the wheels |
/// | [`Sampled`](Self::Sampled) | either: one of the above at its own rate |
#[derive(Debug, Clone, Copy)]
pub enum BatchControl<'a> {
    /// Open loop: the rows (N·m) per run and step.
    Open(BatchInput<'a>),
    /// A motor-side PD ([`MotorPD`]) shared by every run (each run starts from a copy), or one
    /// per run. Drives `u` only.
    Pd(PerRun<'a, MotorPD>),
    /// An [`AttitudePD`] on the bus, shared by every run (each run starts from a copy), or one
    /// per run (each bound to its run's wheels: `k` rows of allocation). Drives
    /// `wheel_torque` only.
    Attitude(PerRun<'a, AttitudePD>),
    /// The control inside run at its own rate, with zero-order hold and a delay of whole
    /// samples, as [`Sampled`](crate::control::Sampled) runs it in a single run. The control
    /// inside is not itself sampled.
    Sampled(&'a BatchControl<'a>, SampleClock),
}

impl<'a> BatchControl<'a> {
    /// Zeros of `width` numbers for every run and step: an idle channel (`BatchInput::zero`).
    pub const fn zero(width: usize) -> Self {
        BatchControl::Open(BatchInput::zero(width))
    }
}

impl<'a> From<BatchInput<'a>> for BatchControl<'a> {
    fn from(input: BatchInput<'a>) -> Self {
        BatchControl::Open(input)
    }
}

/// The clock of a sampled controller: `rate_hz` (finite, > 0) and a delay of `delay` whole
/// samples (see [`Sampled`](crate::control::Sampled)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleClock {
    /// Samples per second (Hz).
    pub rate_hz: f64,
    /// Whole samples between computing a row and applying it.
    pub delay: usize,
}

/// The inputs of a batch of `runs` runs (module docs for the broadcasting rule).
#[derive(Debug, Clone, Copy)]
pub struct Batch<'a> {
    /// Number of runs `B` (≥ 1).
    pub runs: usize,
    /// The arm of each run. Every arm must have the same number of joints.
    pub arms: PerRun<'a, FlexibleArm>,
    /// Initial states, width `13 + 4n`, without a step axis.
    pub x0: BatchInput<'a>,
    /// The motor torques or controller.
    pub u: BatchControl<'a>,
    /// `f_B` (base frame, `[moment; force]`, applied to the base), width 6.
    pub base_wrench: BatchInput<'a>,
    /// `f` (EE frame, exerted by the EE on its environment), width 6.
    pub ee_wrench: BatchInput<'a>,
    /// Reaction-wheel torque commands (N·m), width `k` (every arm must have `k` wheels), or
    /// their controller; [`BatchControl::zero`] for arms without wheels.
    pub wheel_torque: BatchControl<'a>,
}

/// How a batch runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BatchSettings {
    /// Time step (s).
    pub dt: f64,
    /// Steps per run.
    pub steps: usize,
    /// Keep rows `0, k, 2k, …` and the final row (k ≥ 1).
    pub record_every: usize,
    /// False keeps only the summaries and final states (no rows).
    pub keep_rows: bool,
    /// Worker threads, 1 to [`MAX_THREADS`]; `None` uses every core. The results do not depend
    /// on it.
    pub threads: Option<usize>,
}

/// Watches a batch from another thread: set `cancel` to stop every run at its next check (every
/// 16 steps), and the checks and stability limits before the runs at the next run; read `done`
/// for the number of runs over.
#[derive(Debug, Default)]
pub struct BatchWatch {
    /// Set to stop the runs still going; they end as failed, "interrupted by the caller".
    pub cancel: AtomicBool,
    /// Runs finished or failed so far.
    pub done: AtomicUsize,
}

/// Integrates every run of `batch` ([`Batch::check`] first) over a pool of
/// `settings.threads` threads, each run as [`simulate`](super::simulate()) would with its own
/// inputs, and returns the record with a status per run. One run that fails never stops the
/// others. `watch` can cancel the runs still going and counts the runs over.
///
/// Errors, before any step: an argument error (naming the run), or a record that does not fit
/// in the memory available (naming `runs` and how much it needs).
pub fn simulate_batch(
    batch: &Batch<'_>,
    settings: &BatchSettings,
    watch: &BatchWatch,
) -> Result<BatchRecord> {
    simulate_batch_with_lanes(batch, settings, watch, Lanes::Auto)
}

/// [`simulate_batch`] with the lanes chosen: runs of one robot (and as many reaction wheels) go
/// `W` at a time through one RK4 step in SIMD lanes ([`crate::lanes`]), each lane bit for bit
/// its scalar run, whatever drives them (every [`BatchControl`] is read per run by the scalar
/// code); `Lanes::Off` runs every run on the scalar path. The record is the same whatever the
/// choice.
pub fn simulate_batch_with_lanes(
    batch: &Batch<'_>,
    settings: &BatchSettings,
    watch: &BatchWatch,
    lanes: Lanes,
) -> Result<BatchRecord> {
    batch.check(settings)?;
    let layout = batch.arms.get(0).layout();
    let (runs, steps, every) = (batch.runs, settings.steps, settings.record_every);
    let rows = if settings.keep_rows {
        recorded_rows(steps, every)
    } else {
        0
    };
    let (len, n, inputs) = (layout.len(), layout.n, layout.inputs_len());
    let numbers = rows
        .checked_mul(len)
        .and_then(|x| x.checked_add(rows.saturating_sub(1).checked_mul(inputs)?))
        .and_then(|per_run| per_run.checked_add(len + 2 * n))
        .and_then(|per_run| per_run.checked_mul(runs));
    let bytes = numbers.and_then(|v| v.checked_mul(8));
    let too_big = || Error::InvalidArgument {
        what: "runs".into(),
        message: format!(
            "the record of {runs} runs of {rows} rows of {len} numbers needs {}, more than the \
             memory available; keep fewer rows (record_every), keep only the summaries \
             (keep_rows = false) or split the runs",
            crate::args::describe_bytes(bytes)
        ),
    };
    match (bytes, crate::io::available_memory()) {
        (None, _) => return Err(too_big()),
        (Some(b), Some(a)) if b as u64 > a => return Err(too_big()),
        _ => {}
    }
    let mut x = buffer(runs * rows * len, f64::NAN, &too_big)?;
    let mut u = buffer(runs * rows.saturating_sub(1) * inputs, f64::NAN, &too_big)?;
    let mut final_state = buffer(runs * len, f64::NAN, &too_big)?;
    let mut peak_deflection = buffer(runs * n, 0.0, &too_big)?;
    let mut peak_torque = buffer(runs * n, 0.0, &too_big)?;
    let slots: Vec<Slot<'_>> = per_run(&mut x, runs, rows * len)
        .into_iter()
        .zip(per_run(&mut u, runs, rows.saturating_sub(1) * inputs))
        .zip(per_run(&mut final_state, runs, len))
        .zip(per_run(&mut peak_deflection, runs, n))
        .zip(per_run(&mut peak_torque, runs, n))
        .map(|((((x, u), last), deflection), torque)| Slot {
            x,
            u,
            last,
            deflection,
            torque,
        })
        .collect();
    let status = run_all(batch, settings, slots, rows, watch, lanes.width())?;
    let t = (0..=steps)
        .filter(|&j| settings.keep_rows && is_recorded(j, steps, every))
        .map(|j| j as f64 * settings.dt)
        .collect();
    Ok(BatchRecord {
        runs,
        rows,
        steps,
        record_every: every,
        layout,
        t,
        x,
        u,
        final_state,
        peak_deflection,
        peak_torque,
        status,
    })
}

/// The arm of run `run` when the lanes may integrate it ([`crate::lanes::lane_groups`] then
/// checks the arm), `None` for the scalar path. Every [`BatchControl`] (tables, [`MotorPD`],
/// [`AttitudePD`], [`Sampled`](crate::control::Sampled) of those) is Rust code that each lane
/// calls through its own `Stepper`, so the controller never keeps a run out of the lanes.
fn lane_arm<'a>(batch: &Batch<'a>, run: usize) -> Option<&'a FlexibleArm> {
    Some(batch.arms.get(run))
}

/// A piece of work for one thread: a lane group, or one run on the scalar path.
enum Task<'s> {
    Lanes(Vec<(usize, Slot<'s>)>),
    One(usize, Slot<'s>),
}

/// Every run of a checked batch into its slot, lane groups of `width` first (the heavier
/// tasks), then the runs left to the scalar path; the statuses in run order.
fn run_all(
    batch: &Batch<'_>,
    settings: &BatchSettings,
    slots: Vec<Slot<'_>>,
    rows: usize,
    watch: &BatchWatch,
    width: usize,
) -> Result<Vec<RunStatus>> {
    let (groups, scalar) = lane_groups(batch.runs, width, |run| lane_arm(batch, run));
    let mut slots: Vec<Option<Slot<'_>>> = slots.into_iter().map(Some).collect();
    let mut take = |run: usize| (run, slots[run].take().expect("each run in one task"));
    let mut tasks: Vec<Task<'_>> = Vec::with_capacity(groups.len() + scalar.len());
    for g in &groups {
        tasks.push(Task::Lanes(g.iter().map(|&run| take(run)).collect()));
    }
    for &run in &scalar {
        let (run, slot) = take(run);
        tasks.push(Task::One(run, slot));
    }
    let done = in_pool(settings.threads, || {
        tasks
            .into_par_iter()
            .with_max_len(1)
            .flat_map_iter(|task| {
                let statuses = match task {
                    Task::Lanes(runs) => lane_runs(batch, settings, runs, rows, width, watch),
                    Task::One(run, slot) => {
                        vec![(
                            run,
                            one_run(batch, settings, run, slot, rows, &watch.cancel),
                        )]
                    }
                };
                watch.done.fetch_add(statuses.len(), Ordering::Relaxed);
                statuses
            })
            .collect::<Vec<_>>()
    })?;
    let mut status = vec![RunStatus::Finished; batch.runs];
    for (run, s) in done {
        status[run] = s;
    }
    Ok(status)
}

/// Run `run`'s inputs (an error when its controllers cannot be bound to its arm) and the
/// recorder of its slot.
fn prepared<'a, 's>(
    batch: &Batch<'a>,
    settings: &BatchSettings,
    run: usize,
    slot: Slot<'s>,
    rows: usize,
) -> (Result<input::RunInputs<'a>>, SlotRecorder<'s>) {
    let layout = batch.arms.get(run).layout();
    let recorder = SlotRecorder {
        deflection: vec![0.0; layout.n],
        torque: vec![0.0; layout.n],
        last: vec![f64::NAN; layout.len()],
        slot,
        layout,
        steps: settings.steps,
        every: settings.record_every,
        rows,
        keep: settings.keep_rows,
        next: 0,
    };
    (batch.inputs(run, settings.steps), recorder)
}

/// Run `run` cancelled before it started: its start is its last good state.
fn cancelled(batch: &Batch<'_>, run: usize, recorder: &mut SlotRecorder<'_>) -> RunStatus {
    let layout = batch.arms.get(run).layout();
    let mut x0 = batch.x0.row(run).unwrap_or(&[]).to_vec();
    crate::flex::normalise_quaternion(&mut x0[layout.quaternion()]);
    let _ = recorder.state(0.0, &x0).and_then(|_| recorder.finish());
    RunStatus::Failed {
        step: 0,
        time: 0.0,
        message: "interrupted by the caller".into(),
    }
}

/// The status of a run from the outcome of its [`simulate_into`].
fn status_of(outcome: Result<()>) -> RunStatus {
    match outcome {
        Ok(()) => RunStatus::Finished,
        Err(Error::Simulation {
            step,
            time,
            message,
        }) => RunStatus::Failed {
            step,
            time,
            message,
        },
        // the arguments were checked for every run before the first step
        Err(other) => RunStatus::Failed {
            step: 0,
            time: 0.0,
            message: other.to_string(),
        },
    }
}

/// Run `run` of a checked batch into its slot.
fn one_run(
    batch: &Batch<'_>,
    settings: &BatchSettings,
    run: usize,
    slot: Slot<'_>,
    rows: usize,
    cancel: &AtomicBool,
) -> RunStatus {
    let (inputs, mut recorder) = prepared(batch, settings, run, slot, rows);
    if cancel.load(Ordering::Relaxed) {
        return cancelled(batch, run, &mut recorder);
    }
    status_of(inputs.and_then(|mut inputs| {
        let (arm, x0) = (inputs.arm, inputs.x0);
        simulate_into(
            arm,
            &Run::new(x0, settings.dt, settings.steps),
            &mut inputs.drive(),
            &mut Cancel(cancel),
            &mut recorder,
        )
    }))
}

/// The runs of one lane group ([`crate::lanes::simulate_lanes`]), each into its slot.
fn lane_runs(
    batch: &Batch<'_>,
    settings: &BatchSettings,
    runs: Vec<(usize, Slot<'_>)>,
    rows: usize,
    width: usize,
    watch: &BatchWatch,
) -> Vec<(usize, RunStatus)> {
    let mut statuses = Vec::with_capacity(runs.len());
    let (mut ids, mut inputs, mut recorders) = (Vec::new(), Vec::new(), Vec::new());
    for (run, slot) in runs {
        match prepared(batch, settings, run, slot, rows) {
            (Ok(i), recorder) => {
                ids.push(run);
                inputs.push(i);
                recorders.push(recorder);
            }
            // as on the scalar path: the run fails before its first step
            (Err(e), _) => statuses.push((run, status_of(Err(e)))),
        }
    }
    if watch.cancel.load(Ordering::Relaxed) {
        statuses.extend(
            ids.into_iter()
                .zip(&mut recorders)
                .map(|(run, r)| (run, cancelled(batch, run, r))),
        );
        return statuses;
    }
    let mut lanes: Vec<LaneRun<'_>> = inputs
        .iter_mut()
        .zip(&mut recorders)
        .map(|(i, recorder)| LaneRun {
            arm: i.arm,
            run: Run::new(i.x0, settings.dt, settings.steps),
            drive: i.drive(),
            recorder,
        })
        .collect();
    let outcomes = simulate_lanes(&mut lanes, width, &mut Cancel(&watch.cancel));
    statuses.extend(ids.into_iter().zip(outcomes.into_iter().map(status_of)));
    statuses
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FlexibleJoints, Robot};

    fn arm() -> FlexibleArm {
        FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap()
    }

    #[test]
    fn broadcast_shapes_set_the_strides() {
        let v = [0.0; 2 * 5 * 3];
        let s = |shape: &[usize]| {
            BatchInput::new(
                "u",
                &v[..shape.iter().product::<usize>()],
                shape,
                2,
                Some(5),
                3,
            )
            .map(|b| (b.run_stride, b.step_stride))
        };
        assert_eq!(s(&[3]).unwrap(), (0, 0));
        assert_eq!(s(&[2, 3]).unwrap(), (3, 0));
        assert_eq!(s(&[1, 3]).unwrap(), (0, 0));
        assert_eq!(s(&[2, 5, 3]).unwrap(), (15, 3));
        assert_eq!(s(&[1, 5, 3]).unwrap(), (0, 3));
        let message = s(&[3, 3]).unwrap_err().to_string();
        assert_eq!(
            message,
            "u: expected shape (3,), (2, 3), (1, 3), (2, 5, 3) or (1, 5, 3), given shape (3, 3)"
        );
        assert!(s(&[2, 4, 3]).is_err());
        assert!(s(&[4]).is_err());
        assert!(BatchInput::new("x0s", &v[..6], &[2, 3], 2, None, 3).is_ok());
        assert!(BatchInput::new("x0s", &v[..15], &[1, 5, 3], 2, None, 3).is_err());
    }

    #[test]
    fn per_call_arguments_broadcast_by_the_same_rule() {
        // the batched per-call functions' arguments: (width,) for every row, or (rows, width)
        let v: Vec<f64> = (0..6).map(f64::from).collect();
        let each = BatchInput::for_rows("q", &v, &[2, 3], 2, 3).unwrap();
        assert_eq!(each.row_or_empty(0), &[0.0, 1.0, 2.0]);
        assert_eq!(each.row_or_empty(1), &[3.0, 4.0, 5.0]);
        assert!(!each.is_shared());
        let shared = BatchInput::for_rows("q", &v[3..], &[3], 2, 3).unwrap();
        assert_eq!(shared.row_or_empty(1), &[3.0, 4.0, 5.0]);
        assert!(shared.is_shared());
        assert!(BatchInput::zero(3).row_or_empty(1).is_empty());
        let message = BatchInput::for_rows("qd", &v, &[2, 3], 2, 2)
            .unwrap_err()
            .to_string();
        assert_eq!(
            message,
            "qd: expected shape (2,) or (2, 2), given shape (2, 3)"
        );
        assert!(BatchInput::for_rows("q", &v, &[3, 2], 2, 2).is_err()); // 3 rows, not 2
        assert!(BatchInput::for_rows("q", &v[..5], &[2, 3], 2, 3).is_err()); // 5 numbers, not 6
        assert!(BatchInput::for_rows("q", &v, &[1, 2, 3], 2, 3).is_err()); // no step axis
    }

    #[test]
    fn the_pool_has_the_threads_asked_for() {
        // threads = 1 once ran the parallel loops on rayon's global pool (every core)
        assert_eq!(in_pool(Some(1), rayon::current_num_threads).unwrap(), 1);
        assert_eq!(in_pool(Some(3), rayon::current_num_threads).unwrap(), 3);
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        assert_eq!(in_pool(None, rayon::current_num_threads).unwrap(), cores);
    }

    #[test]
    fn zero_threads_is_refused() {
        for (threads, given) in [(0, "0"), (MAX_THREADS + 1, "1025")] {
            let e = in_pool(Some(threads), || ()).unwrap_err().to_string();
            assert_eq!(
                e,
                format!(
                    "threads: expected an integer from 1 to 1024 (or None for every core), \
                     given {given}"
                )
            );
        }
        assert_eq!(
            in_pool(Some(MAX_THREADS), rayon::current_num_threads).unwrap(),
            1024
        );
    }

    #[test]
    fn bad_run_is_named() {
        let arm = arm();
        let mut x0 = [arm.rest_state(), arm.rest_state()].concat();
        let len = arm.layout().len();
        x0[len + 3..len + 7].fill(0.0); // run 1: a zero quaternion
        let batch = Batch {
            runs: 2,
            arms: PerRun::All(&arm),
            x0: BatchInput::new("x0s", &x0, &[2, len], 2, None, len).unwrap(),
            u: BatchControl::Open(BatchInput::zero(7)),
            base_wrench: BatchInput::zero(6),
            ee_wrench: BatchInput::zero(6),
            wheel_torque: BatchControl::zero(0),
        };
        let settings = BatchSettings {
            dt: 1e-3,
            steps: 3,
            record_every: 1,
            keep_rows: true,
            threads: Some(1),
        };
        let e = simulate_batch(&batch, &settings, &BatchWatch::default()).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("base_pose (run 1): the quaternion"),
            "{e}"
        );
    }
}
