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
//!
//! **The point the held moment is taken about** ([`BasePoint`], `point`): the base origin `B`
//! (default) or the system centre of mass `C`. With `r_c(q)` the position of `C` relative to
//! `B` (base frame, a function of the joint angles), the same wrench `[n_B; F_B]` about `C` has
//! the moment `n_C = n_B − r_c × F_B`: a force `F` at a point `P` gives the moment
//! `(P − B) × F` about `B` and `(P − C) × F = (P − B) × F − r_c × F` about `C`. The force does
//! not depend on the point. The point applies to the per-axis torque bounds (`torque`) and to
//! the norm bound [`Limits::base_torque`](super::Limits).
//!
//! A free-floating base takes no point: it receives no wrench, its rates are those of a rigid
//! body (the same about every point), and with the zero momentum a plan starts from, the system
//! COM does not move, so the velocity of the base origin relative to the COM is `v_B` itself. A
//! COM option there would bound exactly what the origin's does; a plan refuses it, saying so.

use crate::error::{Error, Result};

/// The point a held base's moment bounds are taken about (module docs).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum BasePoint {
    /// The base origin `B`: the moment `n_B` as the plan reports it (the default).
    #[default]
    Origin,
    /// The system centre of mass `C` (base, links, wheels' locked parts) at the current joint
    /// angles: `n_C = n_B − r_c(q) × F_B`.
    SystemCom,
}

impl BasePoint {
    /// `"origin"` or `"com"` (the Python keyword's values).
    pub fn name(self) -> &'static str {
        match self {
            BasePoint::Origin => "origin",
            BasePoint::SystemCom => "com",
        }
    }

    /// The point named `"origin"` or `"com"`; the error names the choices.
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "origin" => Ok(BasePoint::Origin),
            "com" => Ok(BasePoint::SystemCom),
            other => Err(Error::InvalidArgument {
                what: "base_point".into(),
                message: format!(
                    "expected \"origin\" (the base origin) or \"com\" (the system centre of \
                     mass), given {other:?}"
                ),
            }),
        }
    }

    /// The wrench `[n; F]` about this point, from `wrench = [n_B; F_B]` about the base origin and
    /// `com = r_c`, the system COM relative to the base origin (base frame): the origin's is
    /// returned as it is, the COM's moment is `n_B − r_c × F_B`.
    pub fn wrench(self, wrench: &[f64; 6], com: &[f64; 3]) -> [f64; 6] {
        match self {
            BasePoint::Origin => *wrench,
            BasePoint::SystemCom => {
                let [n0, n1, n2, f0, f1, f2] = *wrench;
                let [c0, c1, c2] = *com;
                [
                    n0 - (c1 * f2 - c2 * f1),
                    n1 - (c2 * f0 - c0 * f2),
                    n2 - (c0 * f1 - c1 * f0),
                    f0,
                    f1,
                    f2,
                ]
            }
        }
    }
}

/// Per-axis (and free-base rate) bounds on the bus (module docs); `None` leaves a quantity
/// unbounded. Every value finite and `> 0`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct BaseLimits {
    /// Held base: `|n_k| ≤ torque[k]` (N·m, base frame), the holding moment about `point`.
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
    /// Held base: the point the moment bounds (`torque` and
    /// [`Limits::base_torque`](super::Limits)) are taken about; the base origin by default.
    pub point: BasePoint,
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
            ("base_point", self.point != BasePoint::Origin, true),
        ];
        all.iter()
            .filter(|(_, given, h)| *given && *h == held)
            .map(|(name, ..)| *name)
            .collect()
    }

    /// Calls `visit(value, bound, which, axis)` for every bound given that applies: on a held
    /// base to its holding wrench `wrench = [n; F]` (about [`point`](Self::point): the caller
    /// transfers it, [`BasePoint::wrench`]), on a free one to its twist
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

    #[test]
    fn the_point_moves_the_moment_and_not_the_force() {
        let wrench = [1.0, -2.0, 3.0, 4.0, 5.0, -6.0];
        let com = [0.5, -0.25, 2.0];
        assert_eq!(BasePoint::Origin.wrench(&wrench, &com), wrench);
        // r_c × F = (−0.25·−6 − 2·5, 2·4 − 0.5·−6, 0.5·5 − −0.25·4) = (−8.5, 11, 3.5)
        assert_eq!(
            BasePoint::SystemCom.wrench(&wrench, &com),
            [9.5, -13.0, -0.5, 4.0, 5.0, -6.0]
        );
        for point in [BasePoint::Origin, BasePoint::SystemCom] {
            assert_eq!(BasePoint::from_name(point.name()).unwrap(), point);
        }
        assert_eq!(BasePoint::default(), BasePoint::Origin);
        let e = BasePoint::from_name("cog").unwrap_err().to_string();
        assert_eq!(
            e,
            "base_point: expected \"origin\" (the base origin) or \"com\" (the system centre of \
             mass), given \"cog\""
        );
        let com = BaseLimits {
            point: BasePoint::SystemCom,
            ..Default::default()
        };
        assert_eq!(com.given_for(true), ["base_point"]);
        assert!(
            com.given_for(false).is_empty() && BaseLimits::default().given_for(true).is_empty()
        );
    }
}
