//! [`MotorPD`]: the built-in motor-side PD with feedforward.

use super::controller::{Controller, Feedback};
use super::schedule::Schedule;
use crate::args::{check_parameter, Domain};
use crate::error::{Error, Result};
use crate::state::StateLayout;

/// Motor-side PD with feedforward:
/// `u = K_p (θ_ref − θ) + K_d (θ̇_ref − θ̇) + u_ff`, gains per joint, references constant or
/// tabulated per step.
///
/// ```
/// use orbitflex::control::{Controller, MotorPD, Schedule};
/// let mut pd = MotorPD::new(vec![100.0], vec![10.0], Schedule::Constant(vec![0.5]),
///                           Schedule::Zero, Schedule::Constant(vec![1.0]))?;
/// // one joint: x = [r (3) | quat (4) | q | θ | ω, v (6) | q̇ | θ̇], θ = 0.2, θ̇ = 0.1
/// let x = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1];
/// let mut u = [0.0];
/// pd.output(0, 0.0, &x, &mut u)?;
/// assert!((u[0] - (100.0 * 0.3 - 10.0 * 0.1 + 1.0)).abs() < 1e-12);
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MotorPD {
    /// Proportional gains `K_p` (N·m/rad), one per joint.
    pub kp: Vec<f64>,
    /// Derivative gains `K_d` (N·m·s/rad), one per joint.
    pub kd: Vec<f64>,
    /// `θ_ref` (rad, link side).
    pub theta_ref: Schedule,
    /// `θ̇_ref` (rad/s).
    pub theta_dot_ref: Schedule,
    /// Feedforward torque `u_ff` (N·m).
    pub feedforward: Schedule,
    n: usize,
    scratch: Vec<f64>,
}

impl MotorPD {
    /// Validated controller for `n` joints (gains finite and ≥ 0, length n; references of width n).
    pub fn new(
        kp: Vec<f64>,
        kd: Vec<f64>,
        theta_ref: Schedule,
        theta_dot_ref: Schedule,
        feedforward: Schedule,
    ) -> Result<Self> {
        let n = kp.len();
        for (what, gains) in [("kp", &kp), ("kd", &kd)] {
            check_parameter(what, gains, n, Domain::NonNegative)?;
        }
        theta_ref.check("theta_ref", n, None)?;
        theta_dot_ref.check("theta_dot_ref", n, None)?;
        feedforward.check("feedforward", n, None)?;
        Ok(Self {
            kp,
            kd,
            theta_ref,
            theta_dot_ref,
            feedforward,
            n,
            scratch: vec![0.0; 3 * n],
        })
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.n
    }

    /// Checks that tabulated references cover `steps` steps.
    pub fn check_steps(&self, steps: usize) -> Result<()> {
        self.theta_ref.check_covers("theta_ref", steps)?;
        self.theta_dot_ref.check_covers("theta_dot_ref", steps)?;
        self.feedforward.check_covers("feedforward", steps)
    }
}

impl Controller for MotorPD {
    fn output(&mut self, step: usize, _t: f64, x: &[f64], u: &mut [f64]) -> Result<()> {
        self.check_run("u", u.len(), step + 1)?;
        let n = self.n;
        // the arm's state, 13 + 4n, then any reaction-wheel speeds (which a motor PD ignores)
        let arm = StateLayout::new(n).len();
        if x.len() < arm {
            return Err(Error::Dimension {
                what: "x (state)".into(),
                expected: format!("length 13 + 4n = {arm} (then any wheel speeds)"),
                given: format!("length {}", x.len()),
            });
        }
        let s = StateLayout::new(n).split(&x[..arm]);
        let (reference, rest) = self.scratch.split_at_mut(n);
        let (rate, ff) = rest.split_at_mut(n);
        self.theta_ref.write(step, reference);
        self.theta_dot_ref.write(step, rate);
        self.feedforward.write(step, ff);
        for i in 0..n {
            u[i] = self.kp[i] * (reference[i] - s.theta[i])
                + self.kd[i] * (rate[i] - s.theta_dot[i])
                + ff[i];
        }
        Ok(())
    }

    fn feedback(&self) -> Feedback<'_> {
        Feedback::MotorPd {
            kp: &self.kp,
            kd: &self.kd,
        }
    }

    fn check_run(&self, _what: &str, n: usize, steps: usize) -> Result<()> {
        if n != self.n {
            return Err(Error::Dimension {
                what: "MotorPD".into(),
                expected: format!("a controller for {n} joints (the arm's)"),
                given: format!("one for {} joints", self.n),
            });
        }
        self.check_steps(steps)
    }
}
