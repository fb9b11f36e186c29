//! The [`Controller`] trait, channel-agnostic, and the [`Feedback`] a controller declares for the
//! stability limit.

use crate::error::Result;

/// How a controller's output depends on the state, for the closed-loop stability limit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Feedback<'a> {
    /// `u` does not depend on the state (open loop).
    None,
    /// `u = … − k_p θ − k_d θ̇`: a motor-side PD with these gains (one per joint).
    MotorPd {
        /// `∂u_i/∂θ_i = −kp_i` (N·m/rad).
        kp: &'a [f64],
        /// `∂u_i/∂θ̇_i = −kd_i` (N·m·s/rad).
        kd: &'a [f64],
    },
    /// Not known (for example, a Python callable): only the open loop can be analysed.
    Unknown,
}

/// Computes one channel's input once per step: a row of `width` numbers from the step, the time
/// and the state at the start of the step, held over the step (zero-order hold). The motor
/// torques `u` (width n) are one channel, the base wrench (6) and the EE wrenches (6k) two
/// others; [`Schedule`](super::Schedule) (zero, constant, table), [`MotorPD`](super::MotorPD) and the Python
/// callables implement it, and users can too.
pub trait Controller {
    /// Writes the row of step `step` (time `t`, state `x`) into `out`.
    fn output(&mut self, step: usize, t: f64, x: &[f64], out: &mut [f64]) -> Result<()>;

    /// How the output depends on the state; the default says it is not known.
    fn feedback(&self) -> Feedback<'_> {
        Feedback::Unknown
    }

    /// Checks, before a run of `steps` steps, that the controller serves a channel of `width`
    /// numbers (`what` names it in messages: `"u"`, `"base_wrench"`, …) for that long. The
    /// default accepts anything.
    fn check_run(&self, _what: &str, _width: usize, _steps: usize) -> Result<()> {
        Ok(())
    }

    /// Whether every row is zero whatever the state: a run then skips the channel (the EE
    /// wrenches of a free-floating arm cost nothing). The default says no.
    fn is_zero(&self) -> bool {
        false
    }
}
