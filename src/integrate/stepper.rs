//! [`Stepper`]: the body of a run's step as a reusable value. Step `k` asks each channel of the
//! [`Drive`] for its row, checks the motor torques, saturates the wheel torques, takes one RK4 step of the arm with the inputs
//! held, and checks the new state. [`simulate_into`](super::simulate_into) loops over it; anything
//! that steps the arm one step at a time with controllers (a co-simulation slave, say) uses the
//! same value and is bit for bit the same run.

use super::arm::ArmWorkspace;
use super::record::Recorder;
use super::run::Drive;
use super::simulate::step_unchecked;
use crate::args::{check_finite, Loads};
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, Inputs};
use crate::spatial::Force;
use crate::state::state_defect;

/// The workspace of a run's steps: the arm's [`ArmWorkspace`] and one row per input channel.
/// Allocation-free once made.
#[derive(Debug, Clone)]
pub struct Stepper {
    ws: ArmWorkspace,
    /// The held inputs of the last step as a record keeps them: the motor torques (n), then the
    /// wheel torques applied (k, after saturation).
    inputs: Vec<f64>,
    base_wrench: [f64; 6],
    ee_wrench: Vec<f64>,
    /// The wheel torques commanded (k), before saturation.
    wheel_command: Vec<f64>,
}

impl Stepper {
    /// Buffers for `arm`.
    pub fn new(arm: &FlexibleArm) -> Self {
        Self {
            ws: arm.workspace(),
            inputs: vec![0.0; arm.layout().inputs_len()],
            base_wrench: [0.0; 6],
            ee_wrench: vec![0.0; 6 * arm.robot().end_effectors().len()],
            wheel_command: vec![0.0; arm.layout().wheels],
        }
    }

    /// The motor torques `u` (n, N·m) held during the last step (zeros before the first).
    pub fn u(&self) -> &[f64] {
        &self.inputs[..self.wheel_start()]
    }

    /// The wheel torques (k, N·m) applied during the last step, after saturation (zeros before
    /// the first; empty without wheels).
    pub fn wheel_torque(&self) -> &[f64] {
        &self.inputs[self.wheel_start()..]
    }

    /// The inputs held during the last step as a record row keeps them: `u` (n), then the
    /// applied wheel torques (k).
    pub fn inputs(&self) -> &[f64] {
        &self.inputs
    }

    #[inline]
    fn wheel_start(&self) -> usize {
        self.inputs.len() - self.wheel_command.len()
    }

    /// Step `k` (from `t = k dt` to `(k + 1) dt`) of `x` in place: the rows of the channels of
    /// `drive` at `(k, t, x)`, the motor torques checked finite, one RK4 step
    /// ([`step`](super::step())) with them held, and the new state checked. The arguments are
    /// not checked ([`Run::check`](super::Run::check) them first). Errors are an
    /// [`Error::Simulation`] at step `k`: a controller that fails or returns non-finite numbers,
    /// or a state that diverges.
    #[inline]
    pub fn step(
        &mut self,
        arm: &FlexibleArm,
        drive: &mut Drive<'_>,
        x: &mut [f64],
        k: usize,
        dt: f64,
    ) -> Result<()> {
        let t = k as f64 * dt;
        self.try_step(arm, drive, x, k, dt)
            .map_err(|message| Error::Simulation {
                step: k,
                time: t,
                message,
            })
    }

    #[inline]
    fn try_step(
        &mut self,
        arm: &FlexibleArm,
        drive: &mut Drive<'_>,
        x: &mut [f64],
        k: usize,
        dt: f64,
    ) -> std::result::Result<(), String> {
        let ee_given = self.prepare(arm, drive, x, k, dt)?;
        self.advance(arm, x, dt, ee_given)
    }

    /// The first half of step `k`: the rows of the channels of `drive` at `(k, k dt, x)`, checked
    /// finite, the wheel torques saturated, all held in `self` ([`Stepper::inputs`],
    /// [`Stepper::held_wrenches`]). Returns whether the EE wrenches are given (a zero channel is
    /// skipped). Errors are the message of step `k`'s [`Error::Simulation`].
    #[inline]
    pub(crate) fn prepare(
        &mut self,
        arm: &FlexibleArm,
        drive: &mut Drive<'_>,
        x: &[f64],
        k: usize,
        dt: f64,
    ) -> std::result::Result<bool, String> {
        let t = k as f64 * dt;
        let wheels = self.wheel_start();
        let (u, applied) = self.inputs.split_at_mut(wheels);
        drive
            .u
            .output(k, t, x, u)
            .map_err(|e| format!("the controller failed: {e}"))?;
        check_finite("u", u).map_err(|e| format!("the controller returned {e}"))?;
        if let Some(wheels) = arm.wheels() {
            // commanded at the start of the step, saturated there, held over it
            wrench_row(
                drive.wheel_torque.output(k, t, x, &mut self.wheel_command),
                "wheel_torque",
                &self.wheel_command,
            )?;
            wheels.saturate(&self.wheel_command, &x[arm.layout().wheel_speed()], applied);
        }
        let ee_given = !drive.ee_wrench.is_zero();
        if ee_given {
            wrench_row(
                drive.ee_wrench.output(k, t, x, &mut self.ee_wrench),
                "ee_wrench",
                &self.ee_wrench,
            )?;
        }
        wrench_row(
            drive.base_wrench.output(k, t, x, &mut self.base_wrench),
            "base_wrench",
            &self.base_wrench,
        )?;
        Ok(ee_given)
    }

    /// The wrenches held by the last [`Stepper::prepare`]: `f_B` and `[f_1; …; f_k]` (stale
    /// when that step's EE channel was zero).
    #[inline]
    pub(crate) fn held_wrenches(&self) -> (&[f64; 6], &[f64]) {
        (&self.base_wrench, &self.ee_wrench)
    }

    /// The second half of a step: one RK4 step of `x` in place with the inputs held by
    /// [`Stepper::prepare`] (`ee_given` as it returned), then the state check.
    #[inline]
    pub(crate) fn advance(
        &mut self,
        arm: &FlexibleArm,
        x: &mut [f64],
        dt: f64,
        ee_given: bool,
    ) -> std::result::Result<(), String> {
        let wheels = self.wheel_start();
        let ee_wrench: &[f64] = if ee_given { &self.ee_wrench } else { &[] };
        let (u, wheel_torque) = self.inputs.split_at(wheels);
        let inputs = Inputs {
            u,
            loads: Loads {
                base_wrench: Force::from_slice(&self.base_wrench),
                ee_wrench,
            },
            wheel_torque,
        };
        step_unchecked(arm, &mut self.ws, x, dt, &inputs).map_err(|e| {
            format!(
                "the state diverged during the step ({e}); dt = {dt} s may be past the RK4 \
                 stability limit"
            )
        })?;
        checked_state(arm, x, dt)
    }
}

/// The state check after a step: the message of a state that turned non-finite or whose
/// quaternion collapsed.
#[inline]
pub(crate) fn checked_state(
    arm: &FlexibleArm,
    x: &[f64],
    dt: f64,
) -> std::result::Result<(), String> {
    match state_defect(&arm.layout(), x) {
        Some(defect) => Err(format!(
            "the state diverged: {defect}; dt = {dt} s may be past the RK4 stability limit"
        )),
        None => Ok(()),
    }
}

/// What [`simulate_into`](super::simulate_into)'s loop calls for each step: step `k` of `x` in
/// place, the motor torques held over it, and how a kept row is handed to the recorder. The arm
/// alone ([`ArmSteps`]) is every ordinary run; a run that carries more beside the arm (a target
/// to capture, which may also change the arm mid-run) implements it around a [`Stepper`] and goes
/// through the same loop ([`run_steps`](super::simulate::run_steps)), so observers, failures and
/// the rows kept behave the same.
pub trait StepBody {
    /// Step `k` (from `t = k dt` to `(k + 1) dt`) of `x` in place; errors are an
    /// [`Error::Simulation`] at step `k`.
    fn step(&mut self, drive: &mut Drive<'_>, x: &mut [f64], k: usize, dt: f64) -> Result<()>;
    /// The motor torques held during the last step.
    fn u(&self) -> &[f64];
    /// The inputs held during the last step as a record row keeps them: `u` (n), then the
    /// applied reaction-wheel torques (k). The default: [`u`](Self::u) (an arm without wheels).
    fn inputs(&self) -> &[f64] {
        self.u()
    }
    /// Hands the kept row `(t, x)` to `recorder` (the default: [`Recorder::state`]).
    fn record(&mut self, recorder: &mut dyn Recorder, t: f64, x: &[f64]) -> Result<()> {
        recorder.state(t, x)
    }
}

/// The arm alone, as a [`StepBody`]: [`Stepper::step`] on `arm`.
#[derive(Debug)]
pub struct ArmSteps<'a> {
    /// The arm stepped.
    pub arm: &'a FlexibleArm,
    /// Its step's workspace.
    pub stepper: Stepper,
}

impl StepBody for ArmSteps<'_> {
    #[inline]
    fn step(&mut self, drive: &mut Drive<'_>, x: &mut [f64], k: usize, dt: f64) -> Result<()> {
        self.stepper.step(self.arm, drive, x, k, dt)
    }
    #[inline]
    fn u(&self) -> &[f64] {
        self.stepper.u()
    }
    #[inline]
    fn inputs(&self) -> &[f64] {
        self.stepper.inputs()
    }
}

/// The message of a wrench or wheel-torque channel whose controller failed or returned
/// non-finite numbers.
#[inline]
fn wrench_row(written: Result<()>, what: &str, row: &[f64]) -> std::result::Result<(), String> {
    written.map_err(|e| format!("the {what} controller failed: {e}"))?;
    check_finite(what, row).map_err(|e| format!("the {what} controller returned {e}"))
}
