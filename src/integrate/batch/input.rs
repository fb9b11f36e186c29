//! The inputs of a batch: [`BatchInput`], one per-step input broadcast over the run and step
//! axes; each run's own controller and wrenches; the checks a batch makes before its first step
//! and the runs past their stability limit.

use super::pool::{in_pool, interrupted};
use super::{Batch, BatchControl, BatchSettings, BatchWatch, PerRun};
use crate::args::check_dt;
use crate::control::{AttitudePD, Controller, MotorPD, Sampled, Schedule};
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;
use crate::integrate::record::check_record_every;
use crate::integrate::run::{Drive, Run};
use rayon::prelude::*;
use std::sync::atomic::AtomicBool;

/// A per-step input of `width` numbers for every run of a batch, broadcast over the run and step
/// axes (module docs): a row-major buffer with a stride per run and per step, either of which may
/// be 0 (the same row repeated).
#[derive(Debug, Clone, Copy)]
pub struct BatchInput<'a> {
    values: &'a [f64],
    width: usize,
    pub(super) run_stride: usize,
    pub(super) step_stride: usize,
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
        let (run_stride, step_stride) =
            Self::strides(shape, runs, steps, width).ok_or_else(wrong)?;
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

    /// The broadcasting rule: the strides (per run, per step) of an input of `shape` read by
    /// `runs` runs of `steps` steps (`None`: no step axis), rows of `width` numbers, or `None`
    /// when the shape does not broadcast. A leading axis of 1 (or none) is shared by every run.
    fn strides(
        shape: &[usize],
        runs: usize,
        steps: Option<usize>,
        width: usize,
    ) -> Option<(usize, usize)> {
        let run_axis = |r: usize| match r {
            1 => Some(0),
            r if r == runs => Some(1),
            _ => None,
        };
        match *shape {
            [w] if w == width => Some((0, 0)),
            [r, w] if w == width => Some((run_axis(r)? * width, 0)),
            [r, s, w] if w == width && Some(s) == steps => Some((run_axis(r)? * s * width, width)),
            _ => None,
        }
    }

    /// The argument `what` of a per-call function with a leading batch axis of `rows` rows
    /// (the rule of [`new`](Self::new) without a step axis), from `values` of shape `(width,)`
    /// (one vector for every row) or `(rows, width)`. An error names `what`, the shapes
    /// expected and the one given.
    pub fn for_rows(
        what: &str,
        values: &'a [f64],
        shape: &[usize],
        rows: usize,
        width: usize,
    ) -> Result<Self> {
        let wrong = || Error::Dimension {
            what: what.to_string(),
            expected: format!("shape ({width},) or ({rows}, {width})"),
            given: format!("shape {}", crate::args::describe_shape(shape)),
        };
        let (run_stride, _) = Self::strides(shape, rows, None, width).ok_or_else(wrong)?;
        if values.len() != shape.iter().product::<usize>() {
            return Err(wrong());
        }
        Ok(Self {
            values,
            width,
            run_stride,
            step_stride: 0,
            runs: (run_stride > 0).then_some(rows),
            steps: None,
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

    /// The first row of run `run`, as [`row`](Self::row), empty for [`zero`](Self::zero).
    #[inline]
    pub fn row_or_empty(&self, run: usize) -> &'a [f64] {
        let start = run * self.run_stride;
        // the rows of an input read by `for_rows` are in its buffer; `zero` has none
        self.values
            .get(start..start + self.width)
            .unwrap_or_default()
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

/// Names the run an argument error belongs to.
pub(super) fn in_run(run: usize, error: Error) -> Error {
    error.in_context(&format!("run {run}"))
}

/// The owned controller of one channel of one run, a copy of the batch's.
enum RunControl {
    Open(Schedule),
    Pd(Box<MotorPD>),
    Attitude(Box<AttitudePD>),
    Sampled(Box<Sampled<'static>>),
}

impl RunControl {
    fn controller(&mut self) -> &mut dyn Controller {
        match self {
            RunControl::Open(s) => s,
            RunControl::Pd(pd) => pd.as_mut(),
            RunControl::Attitude(pd) => pd.as_mut(),
            RunControl::Sampled(s) => s.as_mut(),
        }
    }

    fn into_boxed(self) -> Box<dyn Controller + Send> {
        match self {
            RunControl::Open(s) => Box::new(s),
            RunControl::Pd(pd) => pd,
            RunControl::Attitude(pd) => pd,
            RunControl::Sampled(s) => s,
        }
    }
}

impl BatchControl<'_> {
    /// Run `run`'s own copy of the controller, over `steps` steps.
    fn for_run(&self, run: usize, steps: usize) -> Result<RunControl> {
        Ok(match self {
            BatchControl::Open(input) => RunControl::Open(input.schedule(run, steps)),
            BatchControl::Pd(pd) => RunControl::Pd(Box::new(pd.get(run).clone())),
            BatchControl::Attitude(pd) => RunControl::Attitude(Box::new(pd.get(run).clone())),
            BatchControl::Sampled(inner, clock) => {
                let inner = inner.for_run(run, steps)?.into_boxed();
                RunControl::Sampled(Box::new(Sampled::new(inner, clock.rate_hz, clock.delay)?))
            }
        })
    }

    /// Checks, before the runs, that this control can drive the channel `what` (`"u"`: not an
    /// [`AttitudePD`]; `"wheel_torque"`: not a [`MotorPD`]), that a per-run sequence has one
    /// element per run, the shapes of a table, and the clock of a sampled control.
    fn check(&self, what: &str, width: usize, runs: usize, steps: usize) -> Result<()> {
        let per_run = |given: usize, kind: &str| {
            if given == runs {
                Ok(())
            } else {
                Err(Error::Dimension {
                    what: what.into(),
                    expected: format!("{runs} {kind} controllers (one per run)"),
                    given: format!("{given}"),
                })
            }
        };
        match (self, what) {
            (BatchControl::Open(input), _) => input.check(what, width, runs, steps),
            (BatchControl::Pd(_), "wheel_torque") => Err(Error::InvalidArgument {
                what: what.into(),
                message: "a MotorPD drives the motors (u), not the reaction wheels; give wheel \
                          torques or an AttitudePD"
                    .into(),
            }),
            (BatchControl::Attitude(_), "u") => Err(Error::InvalidArgument {
                what: what.into(),
                message: "an AttitudePD drives the reaction wheels (wheel_torque), not the \
                          motors; give motor torques or a MotorPD"
                    .into(),
            }),
            (BatchControl::Pd(PerRun::Each(pds)), _) => per_run(pds.len(), "MotorPD"),
            (BatchControl::Attitude(PerRun::Each(pds)), _) => per_run(pds.len(), "AttitudePD"),
            (BatchControl::Pd(PerRun::All(_)) | BatchControl::Attitude(PerRun::All(_)), _) => {
                Ok(())
            }
            (BatchControl::Sampled(BatchControl::Sampled(..), _), _) => {
                Err(Error::InvalidArgument {
                    what: what.into(),
                    message: "a sampled control inside a sampled control; sample it once, at \
                              the rate it runs at"
                        .into(),
                })
            }
            (BatchControl::Sampled(inner, clock), _) => {
                Sampled::new(Box::new(Schedule::Zero), clock.rate_hz, clock.delay)?;
                inner.check(what, width, runs, steps)
            }
        }
    }

    /// Whether every run's control has the same [`Feedback`](crate::control::Feedback) for the
    /// stability limit: open loop, one shared PD, PDs with the same gains, or a sampled control
    /// (whose feedback is not known, whatever it wraps).
    fn same_feedback(&self) -> bool {
        match self {
            BatchControl::Pd(PerRun::Each(pds)) => pds
                .iter()
                .all(|pd| pd.kp == pds[0].kp && pd.kd == pds[0].kd),
            _ => true,
        }
    }
}

pub(super) struct RunInputs<'a> {
    pub(super) arm: &'a FlexibleArm,
    pub(super) x0: &'a [f64],
    control: RunControl,
    wheels: RunControl,
    base: Schedule,
    ee: Schedule,
}

impl RunInputs<'_> {
    /// The run's channels, as a [`Drive`].
    pub(super) fn drive(&mut self) -> Drive<'_> {
        Drive {
            u: self.control.controller(),
            base_wrench: &mut self.base,
            ee_wrench: &mut self.ee,
            wheel_torque: self.wheels.controller(),
        }
    }
}

impl<'a> Batch<'a> {
    /// Run `run`'s own inputs over `steps` steps (the batch checked: a sampled control's clock
    /// is valid).
    pub(super) fn inputs(&self, run: usize, steps: usize) -> Result<RunInputs<'a>> {
        Ok(RunInputs {
            arm: self.arms.get(run),
            x0: self.x0.row(run).unwrap_or(&[]),
            control: self.u.for_run(run, steps)?,
            wheels: self.wheel_torque.for_run(run, steps)?,
            base: self.base_wrench.schedule(run, steps),
            ee: self.ee_wrench.schedule(run, steps),
        })
    }

    /// The runs whose stability limit can differ from run 0's: all of them, or only run 0 when
    /// every run has the same arm, start and feedback gains (open-loop torques, whatever their
    /// values, have no feedback).
    fn distinct_starts(&self) -> usize {
        let shared = self.arms.is_shared() && self.x0.is_shared() && self.u.same_feedback();
        if shared {
            self.runs.min(1)
        } else {
            self.runs
        }
    }

    /// Checks everything [`simulate_batch`](super::simulate_batch) needs before its first step,
    /// run by run as [`Run::check`] does for one run: `dt`, `record_every`, the number of runs, the same number
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
        ] {
            input.check(what, w, self.runs, settings.steps)?;
        }
        self.u.check("u", n, self.runs, settings.steps)?;
        self.wheel_torque
            .check("wheel_torque", wheels, self.runs, settings.steps)?;
        (0..self.runs).into_par_iter().try_for_each(|run| {
            interrupted(cancel, "the checks of the runs")?;
            let mut inputs = self.inputs(run, settings.steps)?;
            let x0 = inputs.x0;
            Run::new(x0, settings.dt, settings.steps)
                .check(inputs.arm, &inputs.drive())
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
                    let mut inputs = self.inputs(run, 0)?;
                    // the limit where dt exceeds it, else a bound at or above dt (faster)
                    inputs
                        .arm
                        .rk4_stability_exceeded(inputs.x0, inputs.control.controller(), dt)
                        .map(|l| l.map_or(f64::INFINITY, |l| l.dt))
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
