//! One RK4 step of the flexible arm, and [`simulate`]: a run of many steps with its checks, its
//! stability warning, a progress/interrupt hook and a record that survives a failure.

use super::arm::ArmWorkspace;
use super::record::{is_recorded, Recorder};
use super::rk4::OdeSystem;
use super::run::{Drive, Run};
use super::stepper::{ArmSteps, StepBody, Stepper};
use super::trajectory::Trajectory;
use crate::algorithms::Data;
use crate::args::check_dt;
use crate::control::Controller;
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, Inputs, ModelWorkspace, StabilityLimit, StateLayout};
use crate::spatial::normalise_quaternion;
use crate::state::state_defect;

/// Watches a run from outside: progress reports and interruption (Ctrl-C in the Python bindings).
pub trait Observer {
    /// Call [`observe`](Self::observe) before every `every()`-th step (never if 0).
    fn every(&self) -> usize;
    /// Called before step `step` of `steps`; returning `false` stops the run as interrupted,
    /// keeping the states computed so far.
    fn observe(&mut self, step: usize, steps: usize) -> bool;
}

/// No observer.
#[derive(Debug, Clone, Copy, Default)]
pub struct Unobserved;

impl Observer for Unobserved {
    fn every(&self) -> usize {
        0
    }
    fn observe(&mut self, _: usize, _: usize) -> bool {
        true
    }
}

/// A run that stopped early: the error (an [`Error::Simulation`] naming the step, or the argument
/// error that prevented the start) and every state computed before it.
#[derive(Debug, Clone)]
pub struct SimulationFailure {
    /// Why the run stopped.
    pub error: Error,
    /// The states (and inputs) computed before it stopped.
    pub trajectory: Trajectory,
}

impl From<Box<SimulationFailure>> for Error {
    fn from(f: Box<SimulationFailure>) -> Error {
        f.error
    }
}

/// The flexible arm with its inputs held over one step: the system RK4 integrates.
struct HeldInputs<'a> {
    arm: &'a FlexibleArm,
    data: &'a mut Data,
    tau: &'a mut [f64],
    inputs: &'a Inputs<'a>,
}

impl OdeSystem for HeldInputs<'_> {
    fn state_len(&self) -> usize {
        self.arm.layout().len()
    }
    fn derivative(&mut self, x: &[f64], xdot: &mut [f64]) -> Result<()> {
        self.arm
            .derivative_unchecked(self.data, self.tau, x, self.inputs, xdot)
    }
    fn project(&mut self, x: &mut [f64]) {
        normalise_quaternion(&mut x[self.arm.layout().quaternion()]);
    }
}

/// One classic RK4 step of length `dt` in place, inputs held over the step; the quaternion is
/// renormalised afterwards (model §5). Allocation-free. A state that turns non-finite is an
/// [`Error::Simulation`] at step 0.
pub fn step(
    arm: &FlexibleArm,
    ws: &mut ArmWorkspace,
    x: &mut [f64],
    dt: f64,
    inputs: &Inputs,
) -> Result<()> {
    check_dt(dt)?;
    crate::algorithms::check_data(arm.robot(), &ws.data)?;
    arm.check_state(x)?;
    arm.check_inputs(inputs)?;
    // the wheel torques are saturated once, at the start of the step, and held over it
    let mut applied = std::mem::take(&mut ws.wheel_torque);
    arm.saturate_wheels(x, inputs, &mut applied);
    let held = Inputs {
        wheel_torque: &applied,
        ..*inputs
    };
    let outcome = step_unchecked(arm, ws, x, dt, &held);
    ws.wheel_torque = applied;
    outcome?;
    match state_defect(&arm.layout(), x) {
        Some(defect) => Err(Error::Simulation {
            step: 0,
            time: 0.0,
            message: format!(
                "the state diverged: {defect}; dt = {dt} s may be past the RK4 stability limit"
            ),
        }),
        None => Ok(()),
    }
}

#[inline]
pub(crate) fn step_unchecked(
    arm: &FlexibleArm,
    ws: &mut ArmWorkspace,
    x: &mut [f64],
    dt: f64,
    inputs: &Inputs,
) -> Result<()> {
    let (model, rk4) = ws.parts();
    let ModelWorkspace { data, tau, .. } = model;
    let mut system = HeldInputs {
        arm,
        data,
        tau,
        inputs,
    };
    rk4.step(&mut system, x, dt)
}

/// The warning [`simulate`] gives before it starts when `dt` is past the closed-loop RK4
/// stability limit at `x0` ([`FlexibleArm::rk4_stability_limit`]), or `None`.
pub fn stability_warning(
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    u: &dyn Controller,
) -> Result<Option<String>> {
    let exceeded = arm.rk4_stability_exceeded(x0, u, dt)?;
    Ok(exceeded.map(|limit| describe_excess(dt, &limit)))
}

fn describe_excess(dt: f64, limit: &StabilityLimit) -> String {
    let what = match (limit.open_loop, limit.estimated) {
        (false, false) => {
            "of the closed loop (arm, joints and the controller, which holds its torque over \
             each step), linearised at x0"
        }
        (true, false) => {
            "of the arm and joints linearised at x0 (the controller's feedback is unknown and \
             not included)"
        }
        (false, true) => "estimated joint by joint (joints and controller at x0)",
        (true, true) => {
            "estimated joint by joint (joints at x0; the controller's feedback is unknown)"
        }
    };
    format!(
        "dt = {dt:e} s exceeds the RK4 stability limit {:.4e} s {what}; the run will likely \
         diverge",
        limit.dt
    )
}

/// Integrates the [`Run`] driven by `drive` ([`Stepper::step`] each step: the channels' rows,
/// then one RK4 [`step`]) and returns the rows it keeps (`run.record_every`).
///
/// The arguments are checked first ([`Run::check`]). A state that turns non-finite (or whose
/// quaternion collapses), or a controller that fails or returns non-finite torques, stops the
/// run: the [`Error::Simulation`] names the failing step `k` (from `t = k dt` to `(k+1) dt`), and
/// the failure keeps the valid states computed before it. The observer is asked before every
/// `observer.every()`-th step whether to go on.
///
/// [`simulate_into`] into a [`Trajectory`]. Allocates the record once, then nothing per step.
pub fn simulate(
    arm: &FlexibleArm,
    run: &Run<'_>,
    drive: &mut Drive<'_>,
    observer: &mut dyn Observer,
) -> std::result::Result<Trajectory, Box<SimulationFailure>> {
    let layout = arm.layout();
    let fail = |error, trajectory| Box::new(SimulationFailure { error, trajectory });
    run.check(arm, drive)
        .map_err(|e| fail(e, Trajectory::empty(layout)))?;
    let mut traj = Trajectory::reserved(layout, run.steps, run.record_every)
        .map_err(|e| fail(e, Trajectory::empty(layout)))?;
    match run_checked(arm, run, drive, observer, &mut traj) {
        Ok(()) => Ok(traj),
        Err(error) => Err(fail(error, traj)),
    }
}

/// Integrates the [`Run`] driven by `drive` as [`simulate`] does, and hands the rows kept with
/// `run.record_every` (≥ 1) to `recorder`: rows `0, k, 2k, …` and the final row, each with the
/// torques of the step that starts there (the rule of [`record`](super::record)). The one entry
/// point of every run.
///
/// With a [`Trajectory`] ([`Trajectory::reserved`]) the record takes O(rows) memory; with a
/// streaming recorder ([`Chunks`](super::record::Chunks)) it takes O(chunk), whatever `steps`.
/// Nothing is allocated per step (a buffer of one state when `record_every > 1`, for the last
/// good state of a failed run).
///
/// Errors: the argument checks ([`Run::check`]) before row 0, with nothing recorded; otherwise
/// an [`Error::Simulation`] naming the step, after the recorder has received the rows kept so far
/// and the last good state as the final row, and [`Recorder::finish`]. A recorder error stops
/// the run as an [`Error::Simulation`] with the recorder's message.
pub fn simulate_into(
    arm: &FlexibleArm,
    run: &Run<'_>,
    drive: &mut Drive<'_>,
    observer: &mut dyn Observer,
    recorder: &mut dyn Recorder,
) -> Result<()> {
    run.check(arm, drive)?;
    run_checked(arm, run, drive, observer, recorder)
}

/// [`simulate_into`] after its checks.
fn run_checked(
    arm: &FlexibleArm,
    run: &Run<'_>,
    drive: &mut Drive<'_>,
    observer: &mut dyn Observer,
    recorder: &mut dyn Recorder,
) -> Result<()> {
    let mut body = ArmSteps {
        arm,
        stepper: Stepper::new(arm),
    };
    run_steps(&mut body, arm.layout(), run, drive, observer, recorder)
}

/// The loop of every run, after its checks ([`Run::check`]): `run.steps` steps of `body` from
/// `run.x0` (its quaternion normalised first, at the offsets of `layout`), the rows kept by
/// `run.record_every` handed to `recorder` through [`StepBody::record`], the observer asked as in
/// [`simulate_into`], and on a failure the last good state as the final row.
pub fn run_steps(
    body: &mut impl StepBody,
    layout: StateLayout,
    run: &Run<'_>,
    drive: &mut Drive<'_>,
    observer: &mut dyn Observer,
    recorder: &mut dyn Recorder,
) -> Result<()> {
    let Run {
        x0,
        dt,
        steps,
        record_every,
    } = *run;
    let mut x = x0.to_vec();
    normalise_quaternion(&mut x[layout.quaternion()]);
    let recording = |step: usize, e: Error| Error::Simulation {
        step,
        time: step as f64 * dt,
        message: format!("the recorder failed: {e}"),
    };
    body.record(recorder, 0.0, &x)
        .map_err(|e| recording(0, e))?;
    // the state before the step, kept when its row is not recorded: a failed run ends on it
    let mut last_good = if record_every > 1 {
        vec![0.0; x.len()]
    } else {
        Vec::new()
    };
    let every = observer.every();
    for k in 0..steps {
        let kept = k % record_every == 0;
        if !kept {
            last_good.copy_from_slice(&x);
        }
        let outcome = if every > 0 && k > 0 && k % every == 0 && !observer.observe(k, steps) {
            Err(Error::Simulation {
                step: k,
                time: k as f64 * dt,
                message: "interrupted by the caller".into(),
            })
        } else {
            body.step(drive, &mut x, k, dt)
        };
        if let Err(error) = outcome {
            if !kept {
                body.record(recorder, k as f64 * dt, &last_good)
                    .map_err(|e| recording(k, e))?;
            }
            recorder.finish().map_err(|e| recording(k, e))?;
            return Err(error);
        }
        if kept {
            recorder.input(body.inputs()).map_err(|e| recording(k, e))?;
        }
        if is_recorded(k + 1, steps, record_every) {
            body.record(recorder, (k + 1) as f64 * dt, &x)
                .map_err(|e| recording(k, e))?;
        }
    }
    recorder.finish().map_err(|e| recording(steps, e))
}

/// The bytes a record of `steps` steps takes with every row kept: `t`, `x` and `u` (`None` if it
/// overflows). See [`Trajectory::reserved`] for `record_every > 1`.
pub fn record_bytes(layout: crate::flex::StateLayout, steps: usize) -> Option<usize> {
    super::trajectory::rows_bytes(layout, steps.checked_add(1)?)
}
