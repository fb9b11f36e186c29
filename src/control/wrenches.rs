//! [`Wrenches`]: the open-loop inputs of a run beside the motor torques, as [`Schedule`]s: the
//! external wrenches (base and end-effectors) and the reaction-wheel torque commands.

use super::schedule::Schedule;
use crate::args::Loads;
use crate::error::Result;
use crate::spatial::Force;

/// The external wrenches of a run, each a [`Schedule`] of `[moment; force]` rows: `base` is
/// `f_B` (width 6, base frame, applied to the base by its actuators) and `ee` is
/// `[f_1; …; f_k]` (width 6k, one wrench per end-effector in
/// [`crate::Robot::ee_links`] order, each in its EE frame, exerted by the end-effector on its
/// environment; width 6 on a chain); and `wheel_torque`, the torques commanded to the bus's
/// reaction wheels (width k, `crate::flex::ReactionWheels`; zero on an arm without wheels),
/// saturated once per step by the run.
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
