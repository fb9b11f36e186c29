//! One RK4 step of the flexible arm, and [`simulate`]: a run of many steps with its checks, its
//! stability warning, a progress/interrupt hook and a record that survives a failure.

use super::control::{Controller, Schedule};
use super::record::{check_record_every, is_recorded, Recorder};
use super::rk4::OdeSystem;
use super::trajectory::Trajectory;
use crate::algorithms::Data;
use crate::args::{check_dt, check_finite, Loads};
use crate::error::{Error, Result};
use crate::flex::state::state_defect;
use crate::flex::{normalise_quaternion, ArmWorkspace, FlexibleArm, Inputs, StabilityLimit};
use crate::spatial::Force;

/// The external wrenches of a run, each a [`Schedule`] of `[moment; force]` rows: `base` is
/// `f_B` (width 6, base frame, applied to the base by its actuators) and `ee` is
/// `[f_1; …; f_k]` (width 6k, one wrench per end-effector in
/// [`crate::Robot::ee_links`] order, each in its EE frame, exerted by the end-effector on its
/// environment; width 6 on a chain); and the torques commanded to the bus's reaction wheels
/// (width k, [`crate::flex::ReactionWheels`]; zero on an arm without wheels), saturated once
/// per step.
#[derive(Debug, Clone, PartialEq)]
pub struct Wrenches {
    /// `f_B` per step.
    pub base: Schedule,
    /// `[f_1; …; f_k]` per step.
    pub ee: Schedule,
    /// Reaction-wheel torque commands per step (N·m).
    pub wheel_torque: Schedule,
}

impl Default for Wrenches {
    fn default() -> Self {
        Self::ZERO
    }
}

impl Wrenches {
    /// No external wrench (free floating).
    pub const ZERO: Wrenches = Wrenches {
        base: Schedule::Zero,
        ee: Schedule::Zero,
        wheel_torque: Schedule::Zero,
    };

    /// Checks both schedules for `robot`: widths 6 and 6k, a table of exactly `steps` rows,
    /// finite values.
    pub fn check(&self, robot: &crate::Robot, steps: usize) -> Result<()> {
        self.base.check("base_wrench", 6, Some(steps))?;
        let width = 6 * robot.end_effectors().len();
        self.ee.check("ee_wrench", width, Some(steps))
    }

    /// The loads of step `k`, the EE row written into `ee_row` (unused when the EE schedule is
    /// zero).
    ///
    /// # Panics
    /// If `ee_row`'s length is not the EE schedule's width (6k; [`check`](Self::check) it first).
    #[inline]
    pub fn loads<'b>(&self, k: usize, ee_row: &'b mut [f64]) -> Loads<'b> {
        let mut row = [0.0; 6];
        self.base.write(k, &mut row);
        let base_wrench = Force::from_slice(&row);
        let ee_wrench: &[f64] = if matches!(self.ee, Schedule::Zero) {
            &[]
        } else {
            self.ee.write(k, ee_row);
            ee_row
        };
        Loads {
            base_wrench,
            ee_wrench,
        }
    }
}

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
    let ArmWorkspace { data, tau, rk4, .. } = ws;
    let mut system = HeldInputs {
        arm,
        data,
        tau,
        inputs,
    };
    rk4.step(&mut system, x, dt)
}

/// The checks [`simulate`] runs before its first step: `dt`, the initial state, the wrench
/// tables (exactly `steps` rows) and the controller (`steps` rows of references, `n` joints).
pub fn check_run(
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    steps: usize,
    u: &dyn Controller,
    wrenches: &Wrenches,
) -> Result<()> {
    check_dt(dt)?;
    arm.check_state(x0).map_err(|e| match e {
        Error::Dimension {
            expected, given, ..
        } => Error::Dimension {
            what: "x0".into(),
            expected,
            given,
        },
        other => other,
    })?;
    wrenches.check(arm.robot(), steps)?;
    check_wheel_torque(arm, &wrenches.wheel_torque, steps)?;
    u.check_run(arm.dof(), steps)
}

/// Checks a run's wheel-torque schedule: width `k` and `steps` rows on an arm with `k` wheels,
/// zero on an arm without.
pub(crate) fn check_wheel_torque(
    arm: &FlexibleArm,
    schedule: &Schedule,
    steps: usize,
) -> Result<()> {
    match (arm.wheels(), schedule) {
        (Some(wheels), _) => schedule.check("wheel_torque", wheels.len(), Some(steps)),
        (None, Schedule::Zero) => Ok(()),
        (None, _) => Err(Error::InvalidArgument {
            what: "wheel_torque".into(),
            message: "the arm has no reaction wheels; give none (or build the arm with wheels)"
                .into(),
        }),
    }
}

/// The warning [`simulate`] gives before it starts when `dt` is past the closed-loop RK4
/// stability limit at `x0` ([`FlexibleArm::rk4_stability_limit`]), or `None`.
pub fn stability_warning(
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    u: &dyn Controller,
) -> Result<Option<String>> {
    let limit = arm.rk4_stability_limit(x0, u)?;
    Ok((dt > limit.dt).then(|| describe_excess(dt, &limit)))
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

/// Integrates `steps` RK4 steps of `dt` from `x0` ([`step`] each), asking the controller `u` for
/// the motor torques once per step and reading `wrenches` per step, and returns every state.
///
/// The arguments are checked first ([`check_run`]). A state that turns non-finite (or whose
/// quaternion collapses), or a controller that fails or returns non-finite torques, stops the
/// run: the [`Error::Simulation`] names the failing step `k` (from `t = k dt` to `(k+1) dt`), and
/// the failure keeps the `k + 1` valid states computed before it. The observer is asked before
/// every `observer.every()`-th step whether to go on.
///
/// [`simulate_into`] with `record_every = 1` into a [`Trajectory`]. Allocates the record once,
/// then nothing per step.
pub fn simulate(
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    steps: usize,
    u: &mut dyn Controller,
    wrenches: &Wrenches,
    observer: &mut dyn Observer,
) -> std::result::Result<Trajectory, Box<SimulationFailure>> {
    let layout = arm.layout();
    let fail = |error, trajectory| Box::new(SimulationFailure { error, trajectory });
    check_run(arm, x0, dt, steps, u, wrenches).map_err(|e| fail(e, Trajectory::empty(layout)))?;
    let mut traj =
        Trajectory::reserved(layout, steps, 1).map_err(|e| fail(e, Trajectory::empty(layout)))?;
    match run_checked(arm, x0, dt, steps, 1, u, wrenches, observer, &mut traj) {
        Ok(()) => Ok(traj),
        Err(error) => Err(fail(error, traj)),
    }
}

/// Integrates `steps` RK4 steps of `dt` (s) from `x0` as [`simulate`] does, and hands the rows
/// kept with `record_every` (≥ 1) to `recorder`: rows `0, k, 2k, …` and the final row, each with
/// the torques of the step that starts there (the rule of [`record`](super::record)).
///
/// With a [`Trajectory`] ([`Trajectory::reserved`]) the record takes O(rows) memory; with a
/// streaming recorder ([`Chunks`](super::record::Chunks)) it takes O(chunk), whatever `steps`.
/// Nothing is allocated per step (a buffer of one state when `record_every > 1`, for the last
/// good state of a failed run).
///
/// Errors: the argument checks ([`check_run`], `record_every` = 0) before row 0, with nothing
/// recorded; otherwise an [`Error::Simulation`] naming the step, after the recorder has received
/// the rows kept so far and the last good state as the final row, and
/// [`Recorder::finish`]. A recorder error stops the run as an
/// [`Error::Simulation`] with the recorder's message.
#[allow(clippy::too_many_arguments)]
pub fn simulate_into(
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    steps: usize,
    record_every: usize,
    u: &mut dyn Controller,
    wrenches: &Wrenches,
    observer: &mut dyn Observer,
    recorder: &mut dyn Recorder,
) -> Result<()> {
    check_record_every(record_every)?;
    check_run(arm, x0, dt, steps, u, wrenches)?;
    run_checked(
        arm,
        x0,
        dt,
        steps,
        record_every,
        u,
        wrenches,
        observer,
        recorder,
    )
}

/// [`simulate_into`] after its checks.
#[allow(clippy::too_many_arguments)]
fn run_checked(
    arm: &FlexibleArm,
    x0: &[f64],
    dt: f64,
    steps: usize,
    record_every: usize,
    u: &mut dyn Controller,
    wrenches: &Wrenches,
    observer: &mut dyn Observer,
    recorder: &mut dyn Recorder,
) -> Result<()> {
    let layout = arm.layout();
    let mut ws = arm.workspace();
    let mut x = x0.to_vec();
    normalise_quaternion(&mut x[layout.quaternion()]);
    let recording = |step: usize, e: Error| Error::Simulation {
        step,
        time: step as f64 * dt,
        message: format!("the recorder failed: {e}"),
    };
    recorder.state(0.0, &x).map_err(|e| recording(0, e))?;
    // the state before the step, kept when its row is not recorded: a failed run ends on it
    let mut last_good = if record_every > 1 {
        vec![0.0; x.len()]
    } else {
        Vec::new()
    };
    // the held inputs of a step: the motor torques (n), then the wheel torques applied (k)
    let mut torque = vec![0.0; layout.inputs_len()];
    let mut wheel_command = vec![0.0; layout.wheels];
    let mut ee_row = vec![0.0; 6 * arm.robot().end_effectors().len()];
    let every = observer.every();
    for k in 0..steps {
        let t = k as f64 * dt;
        let kept = k % record_every == 0;
        let stop = |message: String| Error::Simulation {
            step: k,
            time: t,
            message,
        };
        if !kept {
            last_good.copy_from_slice(&x);
        }
        let outcome = if every > 0 && k > 0 && k % every == 0 && !observer.observe(k, steps) {
            Err(stop("interrupted by the caller".into()))
        } else {
            run_step(
                arm,
                &mut ws,
                &mut x,
                dt,
                k,
                t,
                u,
                wrenches,
                &mut torque,
                &mut ee_row,
                &mut wheel_command,
            )
            .map_err(stop)
        };
        if let Err(error) = outcome {
            if !kept {
                recorder.state(t, &last_good).map_err(|e| recording(k, e))?;
            }
            recorder.finish().map_err(|e| recording(k, e))?;
            return Err(error);
        }
        if kept {
            recorder.input(&torque).map_err(|e| recording(k, e))?;
        }
        if is_recorded(k + 1, steps, record_every) {
            recorder
                .state((k + 1) as f64 * dt, &x)
                .map_err(|e| recording(k, e))?;
        }
    }
    recorder.finish().map_err(|e| recording(steps, e))
}

/// Step `k` of a run: the controller's torque into `torque[..n]`, checked, the wheel torques
/// applied into `torque[n..]` (saturated at `x`), then the RK4 step of `x`, checked; the message
/// of what went wrong otherwise.
#[allow(clippy::too_many_arguments)]
#[inline]
fn run_step(
    arm: &FlexibleArm,
    ws: &mut ArmWorkspace,
    x: &mut [f64],
    dt: f64,
    k: usize,
    t: f64,
    u: &mut dyn Controller,
    wrenches: &Wrenches,
    torque: &mut [f64],
    ee_row: &mut [f64],
    wheel_command: &mut [f64],
) -> std::result::Result<(), String> {
    let (torque, applied) = torque.split_at_mut(arm.dof());
    u.torque(k, t, x, torque)
        .map_err(|e| format!("the controller failed: {e}"))?;
    check_finite("u", torque).map_err(|e| format!("the controller returned {e}"))?;
    if !wheel_command.is_empty() {
        wrenches.wheel_torque.write(k, wheel_command);
        let commands = Inputs {
            wheel_torque: wheel_command,
            ..Inputs::torques(torque)
        };
        arm.saturate_wheels(x, &commands, applied);
    }
    let inputs = Inputs {
        u: torque,
        loads: wrenches.loads(k, ee_row),
        wheel_torque: applied,
    };
    step_unchecked(arm, ws, x, dt, &inputs).map_err(|e| {
        format!(
            "the state diverged during the step ({e}); dt = {dt} s may be past the RK4 \
             stability limit"
        )
    })?;
    match state_defect(&arm.layout(), x) {
        Some(defect) => Err(format!(
            "the state diverged: {defect}; dt = {dt} s may be past the RK4 stability limit"
        )),
        None => Ok(()),
    }
}

/// The bytes a record of `steps` steps takes with every row kept: `t`, `x` and `u` (`None` if it
/// overflows). See [`Trajectory::reserved`] for `record_every > 1`.
pub fn record_bytes(layout: crate::flex::StateLayout, steps: usize) -> Option<usize> {
    super::trajectory::rows_bytes(layout, steps.checked_add(1)?)
}
