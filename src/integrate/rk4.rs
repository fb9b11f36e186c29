//! Classic fixed-step fourth-order Runge–Kutta (model §5), generic over the system it integrates.

use crate::args::check_length;
use crate::error::Result;

/// A continuous-time system `ẋ = f(x)` with its inputs held: what [`Rk4`] integrates.
pub trait OdeSystem {
    /// Length of the state `x`.
    fn state_len(&self) -> usize;

    /// `ẋ = f(x)` into `xdot` (both of length [`state_len`](Self::state_len)).
    fn derivative(&mut self, x: &[f64], xdot: &mut [f64]) -> Result<()>;

    /// Brings the state back onto its manifold after a full step (for example, rescales a unit
    /// quaternion). The default does nothing.
    fn project(&mut self, _x: &mut [f64]) {}
}

/// RK4's four stages and trial state, allocated once for a state length.
///
/// ```
/// use orbitflex::integrate::{OdeSystem, Rk4};
/// /// ẋ = −x
/// struct Decay;
/// impl OdeSystem for Decay {
///     fn state_len(&self) -> usize { 1 }
///     fn derivative(&mut self, x: &[f64], xdot: &mut [f64]) -> orbitflex::Result<()> {
///         xdot[0] = -x[0];
///         Ok(())
///     }
/// }
/// let mut rk4 = Rk4::new(1);
/// let mut x = [1.0];
/// rk4.step(&mut Decay, &mut x, 0.1)?;
/// // one step of RK4 is the Taylor series of e^{-0.1} to fourth order
/// assert!((x[0] - (1.0 - 0.1 + 0.005 - 0.1f64.powi(3) / 6.0 + 0.1f64.powi(4) / 24.0)).abs() < 1e-15);
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone)]
pub struct Rk4 {
    stages: [Vec<f64>; 4],
    trial: Vec<f64>,
}

impl Rk4 {
    /// Buffers for states of length `len`.
    pub fn new(len: usize) -> Self {
        Self {
            stages: std::array::from_fn(|_| vec![0.0; len]),
            trial: vec![0.0; len],
        }
    }

    /// The state length these buffers serve.
    pub fn len(&self) -> usize {
        self.trial.len()
    }

    /// True for a zero-length state.
    pub fn is_empty(&self) -> bool {
        self.trial.is_empty()
    }

    /// One step of length `dt` in place:
    /// `k₁ = f(x)`, `k₂ = f(x + dt/2 k₁)`, `k₃ = f(x + dt/2 k₂)`, `k₄ = f(x + dt k₃)`,
    /// `x ← x + dt/6 (k₁ + 2k₂ + 2k₃ + k₄)`, then [`OdeSystem::project`]. Allocation-free.
    /// `x` and the system must have the length these buffers were made for.
    pub fn step(&mut self, system: &mut impl OdeSystem, x: &mut [f64], dt: f64) -> Result<()> {
        check_length("x (state)", x.len(), self.len())?;
        check_length("system state", system.state_len(), self.len())?;
        let [k1, k2, k3, k4] = &mut self.stages;
        let trial = &mut self.trial;
        system.derivative(x, k1)?;
        advance(trial, x, 0.5 * dt, k1);
        system.derivative(trial, k2)?;
        advance(trial, x, 0.5 * dt, k2);
        system.derivative(trial, k3)?;
        advance(trial, x, dt, k3);
        system.derivative(trial, k4)?;
        for i in 0..x.len() {
            x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        system.project(x);
        Ok(())
    }
}

/// `trial = x + h k`.
#[inline]
fn advance(trial: &mut [f64], x: &[f64], h: f64, k: &[f64]) {
    for (t, (xi, ki)) in trial.iter_mut().zip(x.iter().zip(k)) {
        *t = xi + h * ki;
    }
}
