//! What drives a run: input [`Schedule`]s, the [`Controller`] trait and the built-in [`MotorPD`].

use crate::args::{check_finite, check_vector};
use crate::error::{Error, Result};
use crate::flex::StateLayout;

/// A per-step input of fixed width: zero, a constant, or a table with one row per step
/// (row-major, `steps × width`). Held constant over each step (zero-order hold).
#[derive(Debug, Clone, PartialEq)]
pub enum Schedule {
    /// All zeros.
    Zero,
    /// The same row every step.
    Constant(Vec<f64>),
    /// Row `k` is used during step `k`; `rows × width`, row-major.
    Table {
        /// The rows, one after the other.
        values: Vec<f64>,
        /// The length of one row.
        width: usize,
    },
}

impl Schedule {
    /// Number of rows of a table (`None` for zero and constant schedules).
    pub fn rows(&self) -> Option<usize> {
        match self {
            Schedule::Table { values, width } => {
                Some(values.len().checked_div(*width).unwrap_or(0))
            }
            _ => None,
        }
    }

    /// Checks the width, the number of rows of a table against `steps` (if given: exactly
    /// `steps` rows), and that every value is finite.
    pub fn check(&self, what: &str, width: usize, steps: Option<usize>) -> Result<()> {
        match self {
            Schedule::Zero => Ok(()),
            Schedule::Constant(v) => check_vector(what, v, width),
            Schedule::Table { values, width: w } => {
                let rows = self.rows().unwrap_or(0);
                if *w != width || values.len() != rows * w || steps.is_some_and(|s| s != rows) {
                    return Err(Error::Dimension {
                        what: what.to_string(),
                        expected: format!(
                            "a table of shape ({}, {width})",
                            steps.map_or("steps".into(), |s| s.to_string())
                        ),
                        given: format!("shape ({rows}, {w})"),
                    });
                }
                check_finite(what, values)
            }
        }
    }

    /// Checks that a table has at least `steps` rows (zero and constant schedules always do).
    pub fn check_covers(&self, what: &str, steps: usize) -> Result<()> {
        match self.rows() {
            Some(rows) if rows < steps => Err(Error::Dimension {
                what: what.to_string(),
                expected: format!("at least {steps} rows (one per step)"),
                given: format!("{rows} rows"),
            }),
            _ => Ok(()),
        }
    }

    /// Writes the row for `step` into `out` (a table must cover `step`).
    #[inline]
    pub fn write(&self, step: usize, out: &mut [f64]) {
        match self {
            Schedule::Zero => out.fill(0.0),
            Schedule::Constant(v) => out.copy_from_slice(v),
            Schedule::Table { values, width } => {
                out.copy_from_slice(&values[step * width..(step + 1) * width])
            }
        }
    }
}

/// How a controller's torques depend on the state, for the closed-loop stability limit.
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

/// Computes the motor torques `u` (n) once per step, from the time and the state at the start of
/// the step. Built-in controllers implement it; users can too.
pub trait Controller {
    /// Writes `u` for step `step` (time `t`, state `x`) into `u`.
    fn torque(&mut self, step: usize, t: f64, x: &[f64], u: &mut [f64]) -> Result<()>;

    /// How `u` depends on the state; the default says it is not known.
    fn feedback(&self) -> Feedback<'_> {
        Feedback::Unknown
    }

    /// Checks, before a run of `steps` steps, that the controller serves `n` joints for that long.
    /// The default accepts anything.
    fn check_run(&self, _n: usize, _steps: usize) -> Result<()> {
        Ok(())
    }
}

impl Controller for Schedule {
    /// Row `step`; the width and the coverage are checked here (O(1)), the values once per run
    /// by [`Controller::check_run`].
    fn torque(&mut self, step: usize, _t: f64, _x: &[f64], u: &mut [f64]) -> Result<()> {
        let width = match self {
            Schedule::Zero => u.len(),
            Schedule::Constant(v) => v.len(),
            Schedule::Table { width, .. } => *width,
        };
        crate::args::check_length("u", width, u.len())?;
        self.check_covers("u", step + 1)?;
        self.write(step, u);
        Ok(())
    }

    fn feedback(&self) -> Feedback<'_> {
        Feedback::None
    }

    fn check_run(&self, n: usize, steps: usize) -> Result<()> {
        self.check("u", n, self.rows().map(|_| steps))
    }
}

/// Motor-side PD with feedforward:
/// `u = K_p (θ_ref − θ) + K_d (θ̇_ref − θ̇) + u_ff`, gains per joint, references constant or
/// tabulated per step.
///
/// ```
/// use orbitflex::{Controller, MotorPD, Schedule};
/// let mut pd = MotorPD::new(vec![100.0], vec![10.0], Schedule::Constant(vec![0.5]),
///                           Schedule::Zero, Schedule::Constant(vec![1.0]))?;
/// // one joint: x = [r (3) | quat (4) | q | θ | ω, v (6) | q̇ | θ̇], θ = 0.2, θ̇ = 0.1
/// let x = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.1];
/// let mut u = [0.0];
/// pd.torque(0, 0.0, &x, &mut u)?;
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
            crate::flex::joints::check_parameter(
                what,
                gains,
                n,
                crate::flex::joints::Domain::NonNegative,
            )?;
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
    fn torque(&mut self, step: usize, _t: f64, x: &[f64], u: &mut [f64]) -> Result<()> {
        self.check_run(u.len(), step + 1)?;
        let n = self.n;
        let layout = StateLayout::new(n);
        crate::args::check_length("x (state)", x.len(), layout.len())?;
        let s = layout.split(x);
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

    fn check_run(&self, n: usize, steps: usize) -> Result<()> {
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
