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
//! Arms and motor-side PD controllers are [`PerRun`]: one shared by every run, or one per run
//! (dispersed stiffness, payloads, gains).
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
//!     wheel_torque: BatchInput::zero(0),
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

use super::control::{Controller, MotorPD, Schedule};
use super::record::{check_record_every, is_recorded, recorded_rows, Recorder};
use super::simulate::{check_run, simulate_into, Observer, Wrenches};
use super::trajectory::Trajectory;
use crate::args::check_dt;
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, StateLayout};
use rayon::prelude::*;
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

/// A per-step input of `width` numbers for every run of a batch, broadcast over the run and step
/// axes (module docs): a row-major buffer with a stride per run and per step, either of which may
/// be 0 (the same row repeated).
#[derive(Debug, Clone, Copy)]
pub struct BatchInput<'a> {
    values: &'a [f64],
    width: usize,
    run_stride: usize,
    step_stride: usize,
    /// The length of the run axis when it is not broadcast.
    runs: Option<usize>,
    /// The length of the step axis of a table.
    steps: Option<usize>,
}

impl<'a> BatchInput<'a> {
    /// Zeros of this width for every run and step (no buffer).
    pub const fn zero(width: usize) -> Self {
        Self {
            values: &[],
            width,
            run_stride: 0,
            step_stride: 0,
            runs: None,
            steps: None,
        }
    }

    /// The input `what` of a batch of `runs` runs, from a row-major buffer of shape `shape`:
    /// `(width,)`, `(R, width)` or, when `steps` is given, `(R, steps, width)`, with `R` either
    /// 1 or `runs`. An error names `what`, the shape expected and the shape given.
    pub fn new(
        what: &str,
        values: &'a [f64],
        shape: &[usize],
        runs: usize,
        steps: Option<usize>,
        width: usize,
    ) -> Result<Self> {
        let shown = crate::args::describe_shape;
        let expected = match steps {
            Some(s) => format!(
                "shape ({width},), ({runs}, {width}), (1, {width}), ({runs}, {s}, {width}) or \
                 (1, {s}, {width})"
            ),
            None => format!("shape ({width},), ({runs}, {width}) or (1, {width})"),
        };
        let wrong = || Error::Dimension {
            what: what.to_string(),
            expected: expected.clone(),
            given: format!("shape {}", shown(shape)),
        };
        let run_axis = |r: usize| match r {
            1 => Ok(0),
            r if r == runs => Ok(1),
            _ => Err(wrong()),
        };
        let (run_stride, step_stride) = match *shape {
            [w] if w == width => (0, 0),
            [r, w] if w == width => (run_axis(r)? * width, 0),
            [r, s, w] if w == width && Some(s) == steps => (run_axis(r)? * s * width, width),
            _ => return Err(wrong()),
        };
        if values.len() != shape.iter().product::<usize>() {
            return Err(Error::Dimension {
                what: what.to_string(),
                expected: format!(
                    "{} numbers for shape {}",
                    shape.iter().product::<usize>(),
                    shown(shape)
                ),
                given: format!("{} numbers", values.len()),
            });
        }
        Ok(Self {
            values,
            width,
            run_stride,
            step_stride,
            runs: (run_stride > 0).then_some(runs),
            steps: (step_stride > 0).then_some(steps).flatten(),
        })
    }

    /// Checks the width, that a run axis has `runs` rows and a step axis `steps`.
    fn check(&self, what: &str, width: usize, runs: usize, steps: usize) -> Result<()> {
        if let Some(s) = self.steps.filter(|&s| s != steps) {
            return Err(Error::Dimension {
                what: what.into(),
                expected: format!("a table of {steps} rows (one per step)"),
                given: format!("{s} rows"),
            });
        }
        // a zero input has no rows to check (its width is only a default)
        if self.width != width && !self.values.is_empty() {
            return Err(Error::Dimension {
                what: what.into(),
                expected: format!("rows of {width} numbers"),
                given: format!("rows of {}", self.width),
            });
        }
        match self.runs {
            Some(r) if r != runs => Err(Error::Dimension {
                what: what.into(),
                expected: format!("one row or table per run ({runs} runs)"),
                given: format!("{r}"),
            }),
            _ => Ok(()),
        }
    }

    /// Whether every run reads the same rows.
    pub fn is_shared(&self) -> bool {
        self.run_stride == 0
    }

    /// The first row of run `run` (for inputs without a step axis: its only row). `None` for
    /// [`zero`](Self::zero).
    pub fn row(&self, run: usize) -> Option<&'a [f64]> {
        let start = run * self.run_stride;
        (!self.values.is_empty()).then(|| &self.values[start..start + self.width])
    }

    /// The schedule of run `run` over `steps` steps (a copy of its rows).
    pub fn schedule(&self, run: usize, steps: usize) -> Schedule {
        match self.row(run) {
            None => Schedule::Zero,
            Some(row) if self.step_stride == 0 => Schedule::Constant(row.to_vec()),
            Some(_) => {
                let start = run * self.run_stride;
                Schedule::Table {
                    values: self.values[start..start + steps * self.width].to_vec(),
                    width: self.width,
                }
            }
        }
    }
}

/// What drives the motors of each run.
#[derive(Debug, Clone, Copy)]
pub enum BatchControl<'a> {
    /// Open loop: motor torques `u` (N·m) per run and step.
    Open(BatchInput<'a>),
    /// A motor-side PD ([`MotorPD`]) shared by every run (each run starts from a copy), or one
    /// per run.
    Pd(PerRun<'a, MotorPD>),
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
    /// Reaction-wheel torque commands (N·m), width `k` (every arm must have `k` wheels); zero
    /// for arms without wheels.
    pub wheel_torque: BatchInput<'a>,
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

/// How one run of a batch ended.
#[derive(Debug, Clone, PartialEq)]
pub enum RunStatus {
    /// Every step was taken.
    Finished,
    /// The run stopped during step `step` (from `t = step dt`), as
    /// [`simulate`](super::simulate()) would have raised it: a diverged state, a failed
    /// controller, or an interruption.
    Failed {
        /// The failing step `k`; state `k` is the last good one.
        step: usize,
        /// `k dt` (s).
        time: f64,
        /// Why, as the [`Error::Simulation`] of a single run says it.
        message: String,
    },
}

impl RunStatus {
    /// The failing step, or `None` for a finished run.
    pub fn failed_step(&self) -> Option<usize> {
        match self {
            RunStatus::Finished => None,
            RunStatus::Failed { step, .. } => Some(*step),
        }
    }
}

/// The record of a batch: rows of every run in one buffer, plus per-run summaries.
#[derive(Debug, Clone, PartialEq)]
pub struct BatchRecord {
    /// Number of runs `B`.
    pub runs: usize,
    /// Rows per run ([`recorded_rows`]; 0 without rows).
    pub rows: usize,
    /// Steps per run.
    pub steps: usize,
    /// Rows `0, k, 2k, …` and the final row were kept.
    pub record_every: usize,
    /// The state layout.
    pub layout: StateLayout,
    /// Times of the rows (s), shared by every run: `(rows,)`.
    pub t: Vec<f64>,
    /// States, `(B, rows, 13 + 4n)` row-major; NaN after a run's failure.
    pub x: Vec<f64>,
    /// Motor torques (N·m) held during the step that starts at each kept row but the last,
    /// `(B, rows − 1, n)`; NaN after a run's failure.
    pub u: Vec<f64>,
    /// The last state of each run (the last good one for a failed run), `(B, 13 + 4n)`.
    pub final_state: Vec<f64>,
    /// `max |θ_i − q_i|` (rad) over every state of the run (kept or not), `(B, n)`.
    pub peak_deflection: Vec<f64>,
    /// `max |u_i|` (N·m) over every step of the run (kept or not), `(B, n)`; 0 without steps.
    pub peak_torque: Vec<f64>,
    /// How each run ended.
    pub status: Vec<RunStatus>,
}

impl BatchRecord {
    /// Run `run` as the [`Trajectory`] that [`simulate`](super::simulate()) with the same
    /// `record_every` returns for it ([`RunRecord::to_trajectory`]). `None` without rows
    /// ([`BatchSettings::keep_rows`] false) or for a run out of range.
    pub fn run(&self, run: usize) -> Option<Trajectory> {
        if self.rows == 0 || run >= self.runs {
            return None;
        }
        let (len, n) = (self.layout.len(), self.layout.inputs_len());
        let record = RunRecord {
            layout: self.layout,
            record_every: self.record_every,
            t: &self.t,
            x: &self.x[run * self.rows * len..(run + 1) * self.rows * len],
            u: &self.u[run * (self.rows - 1) * n..(run + 1) * (self.rows - 1) * n],
            final_state: &self.final_state[run * len..(run + 1) * len],
            status: &self.status[run],
        };
        Some(record.to_trajectory())
    }
}

/// The part of a [`BatchRecord`] that belongs to one run (with rows), borrowed.
#[derive(Debug, Clone, Copy)]
pub struct RunRecord<'a> {
    /// The state layout.
    pub layout: StateLayout,
    /// The batch's `record_every`.
    pub record_every: usize,
    /// The times of the rows, `(rows,)`.
    pub t: &'a [f64],
    /// The run's rows, `(rows, 13 + 4n)`.
    pub x: &'a [f64],
    /// The run's inputs, `(rows − 1, n + k)`: motor torques, then applied wheel torques.
    pub u: &'a [f64],
    /// Its final state.
    pub final_state: &'a [f64],
    /// How it ended.
    pub status: &'a RunStatus,
}

impl RunRecord<'_> {
    /// The [`Trajectory`] that [`simulate`](super::simulate()) with the same `record_every`
    /// returns for this run: its kept rows and, for a failed run, the trajectory of its
    /// [`SimulationFailure`](super::SimulationFailure): the rows kept up to the failing step,
    /// ending on the last good state.
    pub fn to_trajectory(&self) -> Trajectory {
        let (len, n, every) = (
            self.layout.len(),
            self.layout.inputs_len(),
            self.record_every,
        );
        let mut traj = Trajectory::empty(self.layout);
        match self.status {
            RunStatus::Finished => {
                traj.t = self.t.to_vec();
                traj.x = self.x.to_vec();
                traj.u = self.u.to_vec();
            }
            RunStatus::Failed { step, time, .. } => {
                let kept = step / every + 1;
                traj.t = self.t[..kept].to_vec();
                traj.x = self.x[..kept * len].to_vec();
                if step % every != 0 {
                    traj.t.push(*time);
                    traj.x.extend_from_slice(self.final_state);
                }
                traj.u = self.u[..(traj.t.len() - 1) * n].to_vec();
            }
        }
        traj
    }
}

/// Names the run an argument error belongs to.
fn in_run(run: usize, error: Error) -> Error {
    error.in_context(&format!("run {run}"))
}

/// The owned inputs of run `run`: its controller and wrenches.
enum RunControl {
    Open(Schedule),
    Pd(Box<MotorPD>),
}

impl RunControl {
    fn controller(&mut self) -> &mut dyn Controller {
        match self {
            RunControl::Open(s) => s,
            RunControl::Pd(pd) => pd.as_mut(),
        }
    }
}

struct RunInputs<'a> {
    arm: &'a FlexibleArm,
    x0: &'a [f64],
    control: RunControl,
    wrenches: Wrenches,
}

impl<'a> Batch<'a> {
    fn inputs(&self, run: usize, steps: usize) -> RunInputs<'a> {
        RunInputs {
            arm: self.arms.get(run),
            x0: self.x0.row(run).unwrap_or(&[]),
            control: match &self.u {
                BatchControl::Open(u) => RunControl::Open(u.schedule(run, steps)),
                BatchControl::Pd(pd) => RunControl::Pd(Box::new(pd.get(run).clone())),
            },
            wrenches: Wrenches {
                base: self.base_wrench.schedule(run, steps),
                ee: self.ee_wrench.schedule(run, steps),
                wheel_torque: self.wheel_torque.schedule(run, steps),
            },
        }
    }

    /// The runs whose stability limit can differ from run 0's: all of them, or only run 0 when
    /// every run has the same arm, start and feedback gains (open-loop torques, whatever their
    /// values, have no feedback).
    fn distinct_starts(&self) -> usize {
        let shared = self.arms.is_shared()
            && self.x0.is_shared()
            && match &self.u {
                BatchControl::Open(_) => true,
                BatchControl::Pd(PerRun::All(_)) => true,
                BatchControl::Pd(PerRun::Each(pds)) => pds
                    .iter()
                    .all(|pd| pd.kp == pds[0].kp && pd.kd == pds[0].kd),
            };
        if shared {
            self.runs.min(1)
        } else {
            self.runs
        }
    }

    /// Checks everything [`simulate_batch`] needs before its first step, run by run as
    /// [`check_run`] does for one run: `dt`, `record_every`, the number of runs, the same number
    /// of joints in every arm, the shapes, and each run's start, controller and wrench tables,
    /// on `settings.threads` threads. An error names the run.
    pub fn check(&self, settings: &BatchSettings) -> Result<()> {
        self.check_watched(settings, &BatchWatch::default())
    }

    /// [`Batch::check`], stopping with [`Error::Interrupted`] once `watch.cancel` is set (it
    /// looks before each run's checks).
    pub fn check_watched(&self, settings: &BatchSettings, watch: &BatchWatch) -> Result<()> {
        in_pool(settings.threads, || {
            self.check_runs(settings, &watch.cancel)
        })?
    }

    fn check_runs(&self, settings: &BatchSettings, cancel: &AtomicBool) -> Result<()> {
        check_dt(settings.dt)?;
        check_record_every(settings.record_every)?;
        if self.runs == 0 {
            return Err(Error::InvalidArgument {
                what: "runs".into(),
                message: "expected at least one run, given 0".into(),
            });
        }
        if let PerRun::Each(arms) = &self.arms {
            if arms.len() != self.runs {
                return Err(Error::Dimension {
                    what: "arms".into(),
                    expected: format!("{} arms (one per run)", self.runs),
                    given: format!("{}", arms.len()),
                });
            }
        }
        if let BatchControl::Pd(PerRun::Each(pds)) = &self.u {
            if pds.len() != self.runs {
                return Err(Error::Dimension {
                    what: "u".into(),
                    expected: format!("{} MotorPD controllers (one per run)", self.runs),
                    given: format!("{}", pds.len()),
                });
            }
        }
        let n = self.arms.get(0).dof();
        if let PerRun::Each(arms) = &self.arms {
            if let Some((run, arm)) = arms.iter().enumerate().find(|(_, a)| a.dof() != n) {
                return Err(Error::Dimension {
                    what: format!("arms[{run}]"),
                    expected: format!("an arm with {n} joints (as run 0's)"),
                    given: format!("one with {} joints", arm.dof()),
                });
            }
        }
        let width = self.arms.get(0).layout().len();
        let wheels = self.arms.get(0).layout().wheels;
        if let PerRun::Each(arms) = &self.arms {
            if let Some((run, arm)) = arms
                .iter()
                .enumerate()
                .find(|(_, a)| a.layout().wheels != wheels)
            {
                return Err(Error::Dimension {
                    what: format!("arms[{run}]"),
                    expected: format!("an arm with {wheels} reaction wheels (as run 0's)"),
                    given: format!("one with {}", arm.layout().wheels),
                });
            }
        }
        for (what, input, w) in [
            ("x0s", &self.x0, width),
            ("base_wrench", &self.base_wrench, 6),
            (
                "ee_wrench",
                &self.ee_wrench,
                6 * self.arms.get(0).robot().end_effectors().len(),
            ),
            ("wheel_torque", &self.wheel_torque, wheels),
        ] {
            input.check(what, w, self.runs, settings.steps)?;
        }
        if let BatchControl::Open(u) = &self.u {
            u.check("u", n, self.runs, settings.steps)?;
        }
        (0..self.runs).into_par_iter().try_for_each(|run| {
            interrupted(cancel, "the checks of the runs")?;
            let mut inputs = self.inputs(run, settings.steps);
            check_run(
                inputs.arm,
                inputs.x0,
                settings.dt,
                settings.steps,
                inputs.control.controller(),
                &inputs.wrenches,
            )
            .map_err(|e| in_run(run, e))
        })
    }

    /// The runs whose `dt` is past the closed-loop RK4 stability limit at their start
    /// ([`FlexibleArm::rk4_stability_limit`]), with that limit (s), in run order. Computed once
    /// when every run has the same arm, start and controller.
    pub fn unstable_runs(&self, dt: f64, threads: Option<usize>) -> Result<Vec<(usize, f64)>> {
        self.unstable_runs_watched(dt, threads, &BatchWatch::default())
    }

    /// [`Batch::unstable_runs`], stopping with [`Error::Interrupted`] once `watch.cancel` is
    /// set (it looks before each run's limit, which takes milliseconds on a large model).
    pub fn unstable_runs_watched(
        &self,
        dt: f64,
        threads: Option<usize>,
        watch: &BatchWatch,
    ) -> Result<Vec<(usize, f64)>> {
        let distinct = self.distinct_starts();
        let limits: Vec<f64> = in_pool(threads, || {
            (0..distinct)
                .into_par_iter()
                .map(|run| {
                    interrupted(&watch.cancel, "the stability limits of the runs")?;
                    let mut inputs = self.inputs(run, 0);
                    inputs
                        .arm
                        .rk4_stability_limit(inputs.x0, inputs.control.controller())
                        .map(|l| l.dt)
                        .map_err(|e| in_run(run, e))
                })
                .collect::<Result<_>>()
        })??;
        Ok((0..self.runs)
            .filter_map(|run| {
                let limit = limits[run.min(distinct - 1)];
                (dt > limit).then_some((run, limit))
            })
            .collect())
    }
}

/// The most threads a batch starts: more only spends time and memory starting them (20,000
/// threads once took over a minute to start, three pools per batch).
pub const MAX_THREADS: usize = 1024;

/// Runs `work` on a pool of `threads` threads (`None`: every core; at most [`MAX_THREADS`]).
fn in_pool<R: Send>(threads: Option<usize>, work: impl FnOnce() -> R + Send) -> Result<R> {
    let threads = threads.unwrap_or_else(|| {
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    });
    if threads == 0 || threads > MAX_THREADS {
        return Err(Error::InvalidArgument {
            what: "threads".into(),
            message: format!(
                "expected an integer from 1 to {MAX_THREADS} (or None for every core), given \
                 {threads}"
            ),
        });
    }
    // a pool even for one thread: the parallel iterators inside would otherwise run on rayon's
    // global pool, on every core
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("orbitflex-batch-{i}"))
        .build()
        .map_err(|e| Error::InvalidArgument {
            what: "threads".into(),
            message: format!("could not start {threads} threads: {e}"),
        })?;
    Ok(pool.install(work))
}

/// `Err(Error::Interrupted)` once `cancel` is set.
fn interrupted(cancel: &AtomicBool, what: &str) -> Result<()> {
    match cancel.load(Ordering::Relaxed) {
        true => Err(Error::Interrupted { what: what.into() }),
        false => Ok(()),
    }
}

/// Stops a run when the batch is cancelled.
struct Cancel<'a>(&'a AtomicBool);

impl Observer for Cancel<'_> {
    /// An atomic load every few steps, so that a run of a large model (a millisecond a step)
    /// stops within milliseconds.
    fn every(&self) -> usize {
        16
    }
    fn observe(&mut self, _: usize, _: usize) -> bool {
        !self.0.load(Ordering::Relaxed)
    }
}

/// The part of the record that belongs to one run.
struct Slot<'a> {
    x: &'a mut [f64],
    u: &'a mut [f64],
    last: &'a mut [f64],
    deflection: &'a mut [f64],
    torque: &'a mut [f64],
}

/// Receives every row of a run (`record_every = 1`), keeps the rows of the batch's rule in its
/// slot and the summaries of all. The summaries and the last state are kept in buffers of its
/// own and written to the slot at [`Recorder::finish`]: written every step, they would share
/// cache lines with the neighbouring runs' (false sharing between threads).
struct SlotRecorder<'a> {
    slot: Slot<'a>,
    deflection: Vec<f64>,
    torque: Vec<f64>,
    last: Vec<f64>,
    layout: StateLayout,
    steps: usize,
    every: usize,
    rows: usize,
    keep: bool,
    next: usize,
}

impl Recorder for SlotRecorder<'_> {
    fn state(&mut self, _t: f64, x: &[f64]) -> Result<()> {
        let row = self.next;
        self.next += 1;
        let (q, theta) = (&x[self.layout.q()], &x[self.layout.theta()]);
        for ((peak, q), theta) in self.deflection.iter_mut().zip(q).zip(theta) {
            *peak = peak.max((theta - q).abs());
        }
        self.last.copy_from_slice(x);
        if self.keep && is_recorded(row, self.steps, self.every) {
            let index = if row % self.every == 0 {
                row / self.every
            } else {
                self.rows - 1
            };
            let len = x.len();
            self.slot.x[index * len..(index + 1) * len].copy_from_slice(x);
        }
        Ok(())
    }

    fn input(&mut self, u: &[f64]) -> Result<()> {
        let row = self.next - 1;
        for (peak, u) in self.torque.iter_mut().zip(u) {
            *peak = peak.max(u.abs());
        }
        if self.keep && row % self.every == 0 {
            let index = row / self.every;
            let n = u.len();
            self.slot.u[index * n..(index + 1) * n].copy_from_slice(u);
        }
        Ok(())
    }

    fn finish(&mut self) -> Result<()> {
        self.slot.deflection.copy_from_slice(&self.deflection);
        self.slot.torque.copy_from_slice(&self.torque);
        self.slot.last.copy_from_slice(&self.last);
        Ok(())
    }
}

/// Splits `buffer` into `runs` consecutive pieces of `size` numbers (empty pieces when `size`
/// is 0).
fn per_run(buffer: &mut [f64], runs: usize, size: usize) -> Vec<&mut [f64]> {
    if size == 0 {
        return (0..runs).map(|_| <&mut [f64]>::default()).collect();
    }
    buffer.chunks_mut(size).collect()
}

/// A zero-filled or NaN-filled buffer of `len` numbers, or a clear error naming `runs` when it
/// does not fit in memory.
fn buffer(len: usize, fill: f64, too_big: &dyn Fn() -> Error) -> Result<Vec<f64>> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| too_big())?;
    v.resize(len, fill);
    Ok(v)
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
    let status = in_pool(settings.threads, || {
        slots
            .into_par_iter()
            .enumerate()
            .with_max_len(1)
            .map(|(run, slot)| {
                let status = one_run(batch, settings, run, slot, rows, &watch.cancel);
                watch.done.fetch_add(1, Ordering::Relaxed);
                status
            })
            .collect::<Vec<_>>()
    })?;
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

/// Run `run` of a checked batch into its slot.
fn one_run(
    batch: &Batch<'_>,
    settings: &BatchSettings,
    run: usize,
    slot: Slot<'_>,
    rows: usize,
    cancel: &AtomicBool,
) -> RunStatus {
    let mut inputs = batch.inputs(run, settings.steps);
    let layout = inputs.arm.layout();
    let mut recorder = SlotRecorder {
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
    if cancel.load(Ordering::Relaxed) {
        // cancelled before it started: its start is its last good state
        let mut x0 = inputs.x0.to_vec();
        crate::flex::normalise_quaternion(&mut x0[layout.quaternion()]);
        let _ = recorder.state(0.0, &x0).and_then(|_| recorder.finish());
        return RunStatus::Failed {
            step: 0,
            time: 0.0,
            message: "interrupted by the caller".into(),
        };
    }
    let outcome = simulate_into(
        inputs.arm,
        inputs.x0,
        settings.dt,
        settings.steps,
        1,
        inputs.control.controller(),
        &inputs.wrenches,
        &mut Cancel(cancel),
        &mut recorder,
    );
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
            wheel_torque: BatchInput::zero(0),
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
