//! [`BaseLimits`]: bounds on the bus per base axis (and on its rates by norm), beside the norm
//! bounds of [`Limits`](super::Limits) on the wrench that holds a held base.
//!
//! All components are in the **base frame** (the bus's axes `x_B, y_B, z_B`):
//!
//! | field | base | bounds | unit |
//! |---|---|---|---|
//! | `torque` | held | each `n_B,k`, the moment holding the base about its origin | N·m |
//! | `force` | held | each `F_B,k`, the force holding it | N |
//! | `rate` | free | the magnitude of each `ω_B,k`, the bus's angular rate | rad/s |
//! | `speed` | free | the magnitude of each `v_B,k`, the velocity of the base origin | m/s |
//! | `rate_norm` | free | the norm of `ω_B` | rad/s |
//! | `speed_norm` | free | the norm of `v_B` | m/s |
//!
//! The held bounds apply to a held base only and the free ones to a free-floating base only: a
//! plan refuses the others, naming them.

use crate::error::{Error, Result};

/// Per-axis (and free-base rate) bounds on the bus (module docs); `None` leaves a quantity
/// unbounded. Every value finite and `> 0`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BaseLimits {
    /// Held base: `|n_B,k| ≤ torque[k]` (N·m, about the base origin, base frame).
    pub torque: Option<[f64; 3]>,
    /// Held base: `|F_B,k| ≤ force[k]` (N, base frame).
    pub force: Option<[f64; 3]>,
    /// Free base: `|ω_B,k| ≤ rate[k]` (rad/s, base frame).
    pub rate: Option<[f64; 3]>,
    /// Free base: `|v_B,k| ≤ speed[k]` (m/s, velocity of the base origin, base frame).
    pub speed: Option<[f64; 3]>,
    /// Free base: `|ω_B| ≤ rate_norm` (rad/s).
    pub rate_norm: Option<f64>,
    /// Free base: `|v_B| ≤ speed_norm` (m/s).
    pub speed_norm: Option<f64>,
}

/// Which per-axis (or rate) bound; `axis` is 0, 1, 2 for x, y, z (None for a norm).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseBound {
    /// `|n_B,k|` (held).
    TorqueAxis,
    /// `|F_B,k|` (held).
    ForceAxis,
    /// `|ω_B,k|` (free).
    RateAxis,
    /// `|v_B,k|` (free).
    SpeedAxis,
    /// `|ω_B|` (free).
    Rate,
    /// `|v_B|` (free).
    Speed,
}

impl BaseLimits {
    /// Checks every value (finite, `> 0`), naming the field and axis.
    pub fn check(&self) -> Result<()> {
        for (what, v) in [
            ("base_torque_axes", self.torque),
            ("base_force_axes", self.force),
            ("base_rate_axes", self.rate),
            ("base_speed_axes", self.speed),
        ] {
            if let Some(v) = v {
                for (k, x) in v.iter().enumerate() {
                    if !(x.is_finite() && *x > 0.0) {
                        return Err(Error::InvalidArgument {
                            what: format!("{what}[{k}]"),
                            message: format!(
                                "expected a finite limit > 0 (base-frame {} axis), given {x}",
                                ["x", "y", "z"][k]
                            ),
                        });
                    }
                }
            }
        }
        for (what, v) in [
            ("base_rate", self.rate_norm),
            ("base_speed", self.speed_norm),
        ] {
            if let Some(x) = v {
                if !(x.is_finite() && x > 0.0) {
                    return Err(Error::InvalidArgument {
                        what: what.into(),
                        message: format!("expected a finite limit > 0, given {x}"),
                    });
                }
            }
        }
        Ok(())
    }

    /// The names of the bounds given that apply to a held base (`held`) or to a free one.
    pub fn given_for(&self, held: bool) -> Vec<&'static str> {
        let all = [
            ("base_torque_axes", self.torque.is_some(), true),
            ("base_force_axes", self.force.is_some(), true),
            ("base_rate_axes", self.rate.is_some(), false),
            ("base_speed_axes", self.speed.is_some(), false),
            ("base_rate", self.rate_norm.is_some(), false),
            ("base_speed", self.speed_norm.is_some(), false),
        ];
        all.iter()
            .filter(|(_, given, h)| *given && *h == held)
            .map(|(name, ..)| *name)
            .collect()
    }

    /// Calls `visit(value, bound, which, axis)` for every bound given that applies: on a held
    /// base to its holding wrench `wrench = [n_B; F_B]`, on a free one to its twist
    /// `twist = [ω_B; v_B]` (base frame). Values are magnitudes.
    pub fn visit(
        &self,
        held: bool,
        wrench: &[f64; 6],
        twist: &[f64; 6],
        mut visit: impl FnMut(f64, f64, BaseBound, Option<usize>),
    ) {
        let mut axes = |bound: Option<[f64; 3]>, values: &[f64], which| {
            if let Some(b) = bound {
                for k in 0..3 {
                    visit(values[k].abs(), b[k], which, Some(k));
                }
            }
        };
        if held {
            axes(self.torque, &wrench[..3], BaseBound::TorqueAxis);
            axes(self.force, &wrench[3..], BaseBound::ForceAxis);
        } else {
            axes(self.rate, &twist[..3], BaseBound::RateAxis);
            axes(self.speed, &twist[3..], BaseBound::SpeedAxis);
            let norm = |v: &[f64]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if let Some(b) = self.rate_norm {
                visit(norm(&twist[..3]), b, BaseBound::Rate, None);
            }
            if let Some(b) = self.speed_norm {
                visit(norm(&twist[3..]), b, BaseBound::Speed, None);
            }
        }
    }

    /// The number of channels [`visit`](Self::visit) can report (for the planner's refinement).
    pub const CHANNELS: usize = 14;

    /// The channel (0 to [`CHANNELS`](Self::CHANNELS) − 1) of a bound and axis.
    pub fn channel(which: BaseBound, axis: Option<usize>) -> usize {
        let k = axis.unwrap_or(0);
        match which {
            BaseBound::TorqueAxis => k,
            BaseBound::ForceAxis => 3 + k,
            BaseBound::RateAxis => 6 + k,
            BaseBound::SpeedAxis => 9 + k,
            BaseBound::Rate => 12,
            BaseBound::Speed => 13,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_values_are_named_with_their_axis() {
        let e = BaseLimits {
            rate: Some([0.1, 0.0, 0.1]),
            ..Default::default()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "base_rate_axes[1]: expected a finite limit > 0 (base-frame y axis), given 0"
        );
        let e = BaseLimits {
            speed_norm: Some(f64::NAN),
            ..Default::default()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert_eq!(e, "base_speed: expected a finite limit > 0, given NaN");
    }

    #[test]
    fn visit_reads_the_wrench_held_and_the_twist_free() {
        let limits = BaseLimits {
            torque: Some([1.0, 2.0, 3.0]),
            rate: Some([4.0, 5.0, 6.0]),
            speed_norm: Some(7.0),
            ..Default::default()
        };
        let wrench = [-1.0, 2.0, -3.0, 4.0, 5.0, 6.0];
        let twist = [0.1, -0.2, 0.3, 3.0, 0.0, -4.0];
        let mut seen = Vec::new();
        limits.visit(true, &wrench, &twist, |v, b, w, k| seen.push((v, b, w, k)));
        assert_eq!(
            seen,
            [
                (1.0, 1.0, BaseBound::TorqueAxis, Some(0)),
                (2.0, 2.0, BaseBound::TorqueAxis, Some(1)),
                (3.0, 3.0, BaseBound::TorqueAxis, Some(2)),
            ]
        );
        seen.clear();
        limits.visit(false, &wrench, &twist, |v, b, w, k| seen.push((v, b, w, k)));
        assert_eq!(seen.len(), 4);
        assert_eq!(seen[1], (0.2, 5.0, BaseBound::RateAxis, Some(1)));
        assert_eq!(seen[3], (5.0, 7.0, BaseBound::Speed, None));
        assert_eq!(limits.given_for(true), ["base_torque_axes"]);
        assert_eq!(limits.given_for(false), ["base_rate_axes", "base_speed"]);
    }
}
