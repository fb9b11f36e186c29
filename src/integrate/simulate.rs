//! One RK4 step of the flexible arm, and [`simulate`]: a run of many steps with its checks, its
//! stability warning, a progress/interrupt hook and a record that survives a failure.

use super::control::{Controller, Schedule};
use super::rk4::OdeSystem;
use super::trajectory::Trajectory;
use crate::algorithms::Data;
use crate::args::{check_dt, check_finite, Loads};
use crate::error::{Error, Result};
use crate::flex::state::state_defect;
use crate::flex::{normalise_quaternion, ArmWorkspace, FlexibleArm, Inputs, StabilityLimit};
use crate::spatial::Force;

/// The external wrenches of a run, each a [`Schedule`] of width 6 `[moment; force]`:
/// `base` is `f_B` (base frame, applied to the base by its actuators) and `ee` is `f` (EE frame,
/// exerted by the EE on its environment).
#[derive(Debug, Clone, PartialEq)]
pub struct Wrenches {
    /// `f_B` per step.
    pub base: Schedule,
    /// `f` per step.
    pub ee: Schedule,
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
    };

    /// Checks both schedules: width 6, a table of exactly `steps` rows, finite values.
    pub fn check(&self, steps: usize) -> Result<()> {
        self.base.check("base_wrench", 6, Some(steps))?;
        self.ee.check("ee_wrench", 6, Some(steps))
    }

    /// The loads of step `k`.
    #[inline]
    pub fn loads(&self, k: usize) -> Loads {
        let mut row = [0.0; 6];
        self.base.write(k, &mut row);
        let base_wrench = Force::from_slice(&row);
        self.ee.write(k, &mut row);
        Loads {
            base_wrench,
            ee_wrench: Force::from_slice(&row),
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
    inputs.check(arm.dof())?;
    step_unchecked(arm, ws, x, dt, inputs)?;
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
    wrenches.check(steps)?;
    u.check_run(arm.dof(), steps)
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
/// the motor torques once per step and reading `wrenches` per step.
///
/// The arguments are checked first ([`check_run`]). A state that turns non-finite (or whose
/// quaternion collapses), or a controller that fails or returns non-finite torques, stops the
/// run: the [`Error::Simulation`] names the failing step `k` (from `t = k dt` to `(k+1) dt`), and
/// the failure keeps the `k + 1` valid states computed before it. The observer is asked before
/// every `observer.every()`-th step whether to go on.
///
/// Allocates the record once, then nothing per step.
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
    let mut traj = reserve(layout, steps).map_err(|e| fail(e, Trajectory::empty(layout)))?;
    let mut ws = arm.workspace();
    let mut x = x0.to_vec();
    normalise_quaternion(&mut x[layout.quaternion()]);
    traj.t.push(0.0);
    traj.x.extend_from_slice(&x);
    let mut torque = vec![0.0; layout.n];
    let every = observer.every();
    for k in 0..steps {
        let t = k as f64 * dt;
        let stop = |message: String| Error::Simulation {
            step: k,
            time: t,
            message,
        };
        if every > 0 && k > 0 && k % every == 0 && !observer.observe(k, steps) {
            return Err(fail(stop("interrupted by the caller".into()), traj));
        }
        let outcome = u
            .torque(k, t, &x, &mut torque)
            .map_err(|e| stop(format!("the controller failed: {e}")))
            .and_then(|_| {
                check_finite("u", &torque).map_err(|e| stop(format!("the controller returned {e}")))
            })
            .and_then(|_| {
                let inputs = Inputs {
                    u: &torque,
                    loads: wrenches.loads(k),
                };
                step_unchecked(arm, &mut ws, &mut x, dt, &inputs).map_err(|e| {
                    stop(format!(
                        "the state diverged during the step ({e}); dt = {dt} s may be past the \
                         RK4 stability limit"
                    ))
                })
            })
            .and_then(|_| match state_defect(&layout, &x) {
                Some(defect) => Err(stop(format!(
                    "the state diverged: {defect}; dt = {dt} s may be past the RK4 stability \
                     limit"
                ))),
                None => Ok(()),
            });
        if let Err(error) = outcome {
            return Err(fail(error, traj));
        }
        traj.t.push((k + 1) as f64 * dt);
        traj.x.extend_from_slice(&x);
        traj.u.extend_from_slice(&torque);
    }
    Ok(traj)
}

/// The bytes a record of `steps` steps takes: `t`, `x` and `u` (`None` if it overflows).
pub fn record_bytes(layout: crate::flex::StateLayout, steps: usize) -> Option<usize> {
    let rows = steps.checked_add(1)?;
    let values = rows
        .checked_mul(layout.len() + 1)?
        .checked_add(steps.checked_mul(layout.n)?)?;
    values.checked_mul(8)
}

/// An empty record with room for `steps` steps, or a clear error, before anything is allocated,
/// if it needs more memory than the system has available.
fn reserve(layout: crate::flex::StateLayout, steps: usize) -> Result<Trajectory> {
    let mut traj = Trajectory::empty(layout);
    let bytes = record_bytes(layout, steps);
    let available = crate::io::available_memory();
    let too_big = || Error::InvalidArgument {
        what: "steps".into(),
        message: format!(
            "the record of {steps} steps of a {}-element state needs {}, more than the {} of \
             memory available; simulate in shorter pieces",
            layout.len(),
            crate::args::describe_bytes(bytes),
            available.map_or("memory".into(), |a| crate::args::describe_bytes(Some(
                a as usize
            )))
        ),
    };
    match (bytes, available) {
        (None, _) => return Err(too_big()),
        (Some(b), Some(a)) if b as u64 > a => return Err(too_big()),
        _ => {}
    }
    let rows = steps + 1;
    let states = rows * layout.len();
    let inputs = steps * layout.n;
    traj.t.try_reserve_exact(rows).map_err(|_| too_big())?;
    traj.x.try_reserve_exact(states).map_err(|_| too_big())?;
    traj.u.try_reserve_exact(inputs).map_err(|_| too_big())?;
    Ok(traj)
}
