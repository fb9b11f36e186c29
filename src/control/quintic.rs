//! [`Quintic`]: the rest-to-rest quintic slew, tabulated as the [`Schedule`]s a motor PD follows.
//!
//! The profile is `p(s) = 10s³ − 15s⁴ + 6s⁵` on the normalised time `s = t/T ∈ [0, 1]` (held
//! at 0 before and at 1 after), with `p(0) = 0`, `p(1) = 1` and zero rate and acceleration at both
//! ends. It is evaluated in factored form, multiplications and additions only, so it gives the
//! same bits on every processor (no `pow`, whose vectorised versions differ in the last bits):
//!
//! - `p(s)  = s³ · (10 + s·(6s − 15))`
//! - `p'(s) = 30 · (s·(1 − s))²` (`dp/ds`; `1 − s` is exact for `s ∈ [½, 1]`, so the rate near
//!   the end has no cancellation)

use super::Schedule;
use crate::args::{check_finite, check_length};
use crate::error::{Error, Result};

/// The quintic profile `p(s)` and its derivative `dp/ds` at `s` (clamped to `[0, 1]`; NaN stays
/// NaN), as `s³·(10 + s·(6s − 15))` and `30·(s·(1 − s))²`: multiplications and additions only, the
/// same bits on every processor.
#[inline]
pub fn quintic_profile(s: f64) -> (f64, f64) {
    let s = s.clamp(0.0, 1.0);
    let s2 = s * s;
    let p = s2 * s * (10.0 + s * (6.0 * s - 15.0));
    let w = s * (1.0 - s);
    (p, 30.0 * (w * w))
}

/// A rest-to-rest slew of the joints from `start` to `goal` (rad) over `duration` (s), on the
/// quintic profile, then held at `goal`: `θ_ref(t) = start + p(t/T)·(goal − start)` and
/// `θ̇_ref(t) = (p'(t/T)/T)·(goal − start)` (rad/s).
#[derive(Debug, Clone, PartialEq)]
pub struct Quintic {
    start: Vec<f64>,
    delta: Vec<f64>,
    duration: f64,
}

impl Quintic {
    /// The slew from `start` to `goal` over `duration` seconds; both of the same length, finite,
    /// and `duration` finite and positive.
    pub fn new(start: &[f64], goal: &[f64], duration: f64) -> Result<Quintic> {
        check_finite("start", start)?;
        check_length("goal", goal.len(), start.len())?;
        check_finite("goal", goal)?;
        if !(duration.is_finite() && duration > 0.0) {
            return Err(Error::InvalidArgument {
                what: "duration".into(),
                message: format!("expected a finite duration > 0 s, given {duration}"),
            });
        }
        let delta = goal.iter().zip(start).map(|(g, s)| g - s).collect();
        Ok(Quintic {
            start: start.to_vec(),
            delta,
            duration,
        })
    }

    /// Number of joints.
    pub fn width(&self) -> usize {
        self.start.len()
    }

    /// The reference angles and rates at time `t` (s), written into `theta` and `theta_dot`
    /// (each of [`width`](Self::width)).
    pub fn write(&self, t: f64, theta: &mut [f64], theta_dot: &mut [f64]) {
        let (p, dp) = quintic_profile(t / self.duration);
        let rate = dp / self.duration;
        for (i, (s, d)) in self.start.iter().zip(&self.delta).enumerate() {
            theta[i] = s + p * d;
            theta_dot[i] = rate * d;
        }
    }

    /// The reference tabulated for `steps` steps of `dt` (row `k` at `t = k·dt`, held over step
    /// `k`): `(θ_ref, θ̇_ref)`, two tables of `steps × width`, ready for a
    /// [`MotorPD`](super::MotorPD).
    pub fn schedules(&self, dt: f64, steps: usize) -> Result<(Schedule, Schedule)> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::InvalidArgument {
                what: "dt".into(),
                message: format!("expected a finite step > 0 s, given {dt}"),
            });
        }
        let n = self.width();
        let len = steps.checked_mul(n);
        let table = || -> Result<Vec<f64>> {
            let too_big = || Error::OutOfMemory {
                what: "reference".into(),
                bytes: len.and_then(|len| len.checked_mul(8)),
                hint: "tabulate fewer steps".into(),
            };
            let len = len.ok_or_else(too_big)?;
            let mut v = Vec::new();
            v.try_reserve_exact(len).map_err(|_| too_big())?;
            v.resize(len, 0.0);
            Ok(v)
        };
        let (mut theta, mut theta_dot) = (table()?, table()?);
        if n > 0 {
            for (k, (a, b)) in theta
                .chunks_exact_mut(n)
                .zip(theta_dot.chunks_exact_mut(n))
                .enumerate()
            {
                self.write(k as f64 * dt, a, b);
            }
        }
        let table = |values| Schedule::Table { values, width: n };
        Ok((table(theta), table(theta_dot)))
    }
}
