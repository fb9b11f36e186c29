//! [`EnergyBalance`]: the energy a run's motors put in and its damping took out, against the
//! change of the arm's energy (model §6.2): `E(T) − E(0) = W_motor − D`, where over each step
//!
//! - `W_motor = h/2 · (u·θ̇(t_k) + u·θ̇(t_{k+1}))`, the held motor torque `u` times the motor
//!   rates, by the trapezoid rule;
//! - `D = h/2 · (P_d(t_k) + P_d(t_{k+1}))`, with the dissipated power
//!   `P_d = Σ_j d_j (θ̇_j − q̇_j)² + β_j θ̇_j²` (joint damping `d`, motor damping `β`).
//!
//! The residual `E(T) − E(0) − (W − D)` is the quadrature's error (O(h²) of the energy that
//! flowed) on a stable run; an unstable step makes energy the physics does not, and the residual
//! grows with it. The per-step sums are summed in step order with Neumaier's compensation, so
//! the totals do not depend on the processor or on the number of steps beyond rounding.

use super::Trajectory;
use crate::error::{Error, Result};
use crate::flex::FlexibleArm;

/// The energy balance of a record, J (see the [module documentation](self)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EnergyBalance {
    /// `E(T) − E(0)`, J.
    pub change: f64,
    /// The work of the motor torques, J.
    pub motor_work: f64,
    /// The energy dissipated by the joint and motor damping, J (≥ 0).
    pub dissipated: f64,
}

impl EnergyBalance {
    /// `change − (motor_work − dissipated)`, J: zero but for the quadrature's error.
    pub fn residual(&self) -> f64 {
        self.change - (self.motor_work - self.dissipated)
    }
}

/// A running sum with Neumaier's compensation (the error of each addition is kept apart).
#[derive(Default)]
struct Sum {
    sum: f64,
    carry: f64,
}

impl Sum {
    fn add(&mut self, x: f64) {
        let t = self.sum + x;
        self.carry += if self.sum.abs() >= x.abs() {
            (self.sum - t) + x
        } else {
            (x - t) + self.sum
        };
        self.sum = t;
    }

    fn total(&self) -> f64 {
        self.sum + self.carry
    }
}

impl Trajectory {
    /// Each step's `(E(t_{k+1}) − E(t_k), motor work, dissipated)`, J, for the steps whose
    /// motor torque the record holds. The record must keep every step (`record_every = 1`):
    /// the rows are taken as consecutive steps.
    pub fn energy_steps(&self, arm: &FlexibleArm) -> Result<Vec<[f64; 3]>> {
        Ok(self.energy_steps_with(arm)?.0)
    }

    /// [`energy_steps`](Self::energy_steps) and the energy of every row.
    fn energy_steps_with(&self, arm: &FlexibleArm) -> Result<(Vec<[f64; 3]>, Vec<f64>)> {
        let layout = self.layout;
        if arm.layout() != layout {
            return Err(Error::Dimension {
                what: "arm".into(),
                expected: format!("an arm with the record's state of {}", layout.len()),
                given: format!("an arm with a state of {}", arm.layout().len()),
            });
        }
        let width = layout.inputs_len();
        let steps = self
            .u
            .len()
            .checked_div(width)
            .unwrap_or(0)
            .min(self.len().saturating_sub(1));
        let energy = self.rows().energy(arm);
        let joints = arm.joints();
        let power = |x: &[f64]| -> f64 {
            let (qd, td) = (&x[layout.qd()], &x[layout.theta_dot()]);
            (0..layout.n)
                .map(|j| {
                    let slip = td[j] - qd[j];
                    joints.damping[j] * slip * slip + joints.motor_damping[j] * td[j] * td[j]
                })
                .sum()
        };
        let rows: Vec<&[f64]> = self.rows().iter().collect();
        let steps = (0..steps)
            .map(|k| {
                let h = self.t[k + 1] - self.t[k];
                let u = &self.u[k * width..k * width + layout.n];
                let motor = |x: &[f64]| -> f64 {
                    u.iter()
                        .zip(&x[layout.theta_dot()])
                        .map(|(u, w)| u * w)
                        .sum()
                };
                let (a, b) = (rows[k], rows[k + 1]);
                [
                    energy[k + 1] - energy[k],
                    h * (0.5 * (motor(a) + motor(b))),
                    0.5 * h * (power(a) + power(b)),
                ]
            })
            .collect();
        Ok((steps, energy))
    }

    /// The energy balance over the steps whose torque the record holds
    /// ([`energy_steps`](Self::energy_steps); `record_every = 1`).
    pub fn energy_balance(&self, arm: &FlexibleArm) -> Result<EnergyBalance> {
        let (steps, energy) = self.energy_steps_with(arm)?;
        let (mut work, mut dissipated) = (Sum::default(), Sum::default());
        for [_, w, d] in &steps {
            work.add(*w);
            dissipated.add(*d);
        }
        let change = if steps.is_empty() {
            0.0
        } else {
            energy[steps.len()] - energy[0]
        };
        Ok(EnergyBalance {
            change,
            motor_work: work.total(),
            dissipated: dissipated.total(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::Sum;

    fn total(values: &[f64]) -> f64 {
        let mut sum = Sum::default();
        for v in values {
            sum.add(*v);
        }
        sum.total()
    }

    /// Neumaier's example: `1 + 10¹⁰⁰ + 1 − 10¹⁰⁰` is 2, where a plain sum gives 0. Both
    /// branches of the compensation run (a term larger than the sum, then one smaller); every
    /// error term is exact, so the total is exactly 2 whichever large term comes first. A
    /// mistake in either branch, in the carry or in the total loses the 2 (each checked against
    /// `cargo mutants`).
    #[test]
    fn compensation_keeps_what_a_plain_sum_loses() {
        assert_eq!([1.0, 1e100, 1.0, -1e100].iter().sum::<f64>(), 0.0);
        assert_eq!(total(&[1.0, 1e100, 1.0, -1e100]), 2.0);
        assert_eq!(total(&[1e100, 1.0, -1e100, 1.0]), 2.0);
        assert_eq!(total(&[-1e100, 1.0, 1e100, 1.0]), 2.0);
        // 0.1 ten times: the compensated total is the double nearest to 1, a plain sum is not
        assert_eq!([0.1; 10].iter().sum::<f64>(), 0.9999999999999999);
        assert_eq!(total(&[0.1; 10]), 1.0);
        assert_eq!(total(&[]), 0.0);
    }
}
