//! A run as values: [`Run`], what to integrate (start, step, length, which rows to keep), and
//! [`Drive`], what drives it (one [`Controller`] per input channel). Every way of running the arm
//! ([`FlexibleArm::simulate`], [`simulate`](super::simulate()),
//! [`simulate_into`](super::simulate_into), the batch, planning's tracking, the Python bindings)
//! builds these two and calls the same loop, so a new input channel is a new field here, not a
//! wider signature anywhere.

use super::record::check_record_every;
use crate::args::check_dt;
use crate::control::{Controller, Wrenches};
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;

/// What a run integrates: `steps` RK4 steps of `dt` (s) from `x0` (13 + 4n), keeping rows
/// `0, k, 2k, …` and the final row with `k = record_every` (≥ 1; see
/// [`record`](super::record)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Run<'a> {
    /// The initial state (its quaternion is normalised before the first step).
    pub x0: &'a [f64],
    /// The step (s), finite and > 0.
    pub dt: f64,
    /// The number of steps.
    pub steps: usize,
    /// Keep every `record_every`-th row (and the final one).
    pub record_every: usize,
}

impl<'a> Run<'a> {
    /// `steps` steps of `dt` from `x0`, every row kept.
    pub fn new(x0: &'a [f64], dt: f64, steps: usize) -> Self {
        Self {
            x0,
            dt,
            steps,
            record_every: 1,
        }
    }

    /// The same run keeping every `k`-th row (and the final one).
    pub fn recording_every(self, k: usize) -> Self {
        Self {
            record_every: k,
            ..self
        }
    }

    /// The checks a run makes before its first step: `record_every`, `dt`, the initial state,
    /// then each channel of `drive` for `steps` steps (the wrenches: widths 6 and 6k, tables of
    /// exactly `steps` rows, finite; the controller: `n` joints, references covering the run).
    pub fn check(&self, arm: &FlexibleArm, drive: &Drive<'_>) -> Result<()> {
        check_record_every(self.record_every)?;
        check_dt(self.dt)?;
        arm.check_state(self.x0).map_err(|e| match e {
            Error::Dimension {
                expected, given, ..
            } => Error::Dimension {
                what: "x0".into(),
                expected,
                given,
            },
            other => other,
        })?;
        let ee_width = 6 * arm.robot().end_effectors().len();
        drive.base_wrench.check_run("base_wrench", 6, self.steps)?;
        drive
            .ee_wrench
            .check_run("ee_wrench", ee_width, self.steps)?;
        if arm.wheels().is_none() && !drive.wheel_torque.is_zero() {
            return Err(Error::InvalidArgument {
                what: "wheel_torque".into(),
                message: "the arm has no reaction wheels; give none (or build the arm with wheels)"
                    .into(),
            });
        }
        drive
            .wheel_torque
            .check_run("wheel_torque", arm.layout().wheels, self.steps)?;
        drive.u.check_run("u", arm.dof(), self.steps)
    }
}

/// What drives a run: one [`Controller`] per input channel, each asked once per step for its row
/// (held over the step) from the step, the time and the state at its start.
///
/// - `u`: the motor torques (n, N·m, link side);
/// - `base_wrench`: `f_B = [moment; force]` (6, base frame) applied to the base by its actuators;
/// - `ee_wrench`: `[f_1; …; f_k]` (6k), one wrench per end-effector in
///   [`crate::Robot::ee_links`] order, each in its EE frame, exerted by the end-effector on its
///   environment;
/// - `wheel_torque`: the torques commanded to the bus's reaction wheels (k, N·m, applied to each
///   wheel about its axis; the bus feels the opposite), saturated by the run once per step
///   ([`crate::flex::ReactionWheels::saturate`]); zero on an arm without wheels.
///
/// A [`Schedule`](crate::control::Schedule) (owned, or a `&Schedule` lent by
/// [`Wrenches`]), a [`MotorPD`](crate::control::MotorPD) or any other
/// controller can drive any channel.
pub struct Drive<'a> {
    /// The motor torques `u`.
    pub u: &'a mut dyn Controller,
    /// The base wrench `f_B`.
    pub base_wrench: &'a mut dyn Controller,
    /// The end-effector wrenches.
    pub ee_wrench: &'a mut dyn Controller,
    /// The reaction-wheel torque commands.
    pub wheel_torque: &'a mut dyn Controller,
}

impl<'a> Drive<'a> {
    /// The motor torques from `u`, the wrenches and the wheel torques from `wrenches`'
    /// schedules.
    pub fn new(u: &'a mut dyn Controller, wrenches: &'a mut Wrenches) -> Self {
        Self {
            u,
            base_wrench: &mut wrenches.base,
            ee_wrench: &mut wrenches.ee,
            wheel_torque: &mut wrenches.wheel_torque,
        }
    }
}
