//! A controller sampled at its own rate, as flight software runs it: the discrete loop of the
//! linear model with the controller's zero-order hold and delay, and its spectral radius.
//!
//! About a state `x̄` the plant is `d(dx)/dt = A dx + B u` ([`state_space`], the loops that run
//! continuously already closed into `A`). The controller samples `c_j = K dx(jT)` every
//! `T = 1/rate_hz` seconds and applies `c_{j−d}` (a delay of `d` whole samples, zero before the
//! first arrives), held over each period. Over one period the plant is then exactly
//!
//! ```text
//! dx_{j+1} = Φ dx_j + Γ c_{j−d},   Φ = e^{AT},   Γ = ∫₀ᵀ e^{As} ds B
//! ```
//! (both read off `exp([[A, B], [0, 0]] T)`), and with the `d` commands in flight as extra
//! states, `z_j = [dx_j; c_{j−1}; …; c_{j−d}]`,
//!
//! ```text
//! z_{j+1} = [[Φ, 0, …, 0, Γ], [K, 0, …, 0], [0, 𝟙, …, 0], …] z_j     (d ≥ 1)
//! dx_{j+1} = (Φ + Γ K) dx_j                                           (d = 0)
//! ```
//! The sampled loop is stable when this matrix's spectral radius `ρ` is below 1. Rigid-body
//! motions and free wheel spins the controller does not act on stay at `ρ = 1` (marginal:
//! `e^{0·T}`), computed to about `√ε` where they are defective; so the loop counts as unstable
//! when `ρ > 1 + 10⁻⁶` beyond the growth the continuous loop itself has at a moving state,
//! `e^{1.1 T max(0, max Re λ(A + B K))}` (as the RK4 check, [`crate::flex::stability`]).
//!
//! The samples fall on RK4 steps: when `T` is a whole number of steps they are exactly `T`
//! apart; otherwise they jitter by up to one step, which this analysis leaves out.

use super::linear::{attitude_gain, jacobians, state_space, FullJacobians, LinearSpec, Tangent};
use crate::control::AttitudePD;
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, ModelWorkspace};
use crate::linalg::eigenvalues;
use nalgebra::{Complex, DMatrix};

/// How far above the continuous loop's growth the spectral radius may sit before the sampled
/// loop counts as unstable (marginal modes at 1 are computed to about `√ε`).
pub const MARGIN: f64 = 1e-6;

/// The feedback a sampled controller applies (its linear part about the state).
#[derive(Debug, Clone, Copy)]
pub enum SampledFeedback<'a> {
    /// A motor PD, `δu = −k_p δθ − k_d δθ̇` on the motor torques.
    MotorPd {
        /// `k_p` (N·m/rad), one per joint.
        kp: &'a [f64],
        /// `k_d` (N·m·s/rad), one per joint.
        kd: &'a [f64],
    },
    /// An attitude PD on the reaction-wheel torques.
    Attitude(&'a AttitudePD),
}

impl SampledFeedback<'_> {
    /// `"MotorPD"` or `"AttitudePD"`.
    pub fn name(&self) -> &'static str {
        match self {
            SampledFeedback::MotorPd { .. } => "MotorPD",
            SampledFeedback::Attitude(_) => "AttitudePD",
        }
    }
}

/// The discrete loop of a sampled controller about a state.
#[derive(Debug, Clone, PartialEq)]
pub struct SampledLoop {
    /// Spectral radius `ρ` of the loop's one-period matrix.
    pub spectral_radius: f64,
    /// The largest `ρ` that counts as stable: `e^{1.1 T max(0, max Re λ(A + B K))} (1 + MARGIN)`.
    pub threshold: f64,
    /// Every eigenvalue of the one-period matrix (`s + d·m` of them: `s` states, `m` inputs).
    pub eigenvalues: Vec<Complex<f64>>,
    /// The sample period `T = 1/rate_hz` (s).
    pub period: f64,
    /// The delay (whole samples).
    pub delay: usize,
}

impl SampledLoop {
    /// True when `ρ` exceeds the threshold: the sampled loop diverges.
    pub fn unstable(&self) -> bool {
        self.spectral_radius > self.threshold
    }
}

/// The discrete loop of `feedback` sampled at `rate_hz` with `delay` whole samples, closed
/// around the linear model `plant` of `arm` at `x` (its own feedbacks, which run at every RK4
/// step, already closed in; they must not include `feedback`'s channel). See the module
/// documentation.
///
/// ```
/// use orbitflex::analysis::{sampled_loop, LinearSpec, SampledFeedback};
/// use orbitflex::planning::BaseMode;
/// use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
/// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
/// let (kp, kd) = (vec![2000.0; 7], vec![400.0; 7]);
/// let pd = SampledFeedback::MotorPd { kp: &kp, kd: &kd };
/// let plant = LinearSpec { base: BaseMode::Held, ..LinearSpec::default() };
/// let x = arm.rest_state();
/// let fast = sampled_loop(&arm, &mut arm.workspace(), &x, &plant, pd, 1000.0, 0)?;
/// assert!(!fast.unstable());
/// let slow = sampled_loop(&arm, &mut arm.workspace(), &x, &plant, pd, 20.0, 0)?;
/// assert!(slow.unstable());
/// # Ok::<(), orbitflex::Error>(())
/// ```
pub fn sampled_loop(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    plant: &LinearSpec,
    feedback: SampledFeedback,
    rate_hz: f64,
    delay: usize,
) -> Result<SampledLoop> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(Error::InvalidArgument {
            what: "rate_hz".into(),
            message: format!("expected a finite rate > 0 (Hz), given {rate_hz}"),
        });
    }
    let bare = LinearSpec {
        inputs: &[],
        outputs: &[],
        ..*plant
    };
    let ss = state_space(arm, ws, x, &bare)?;
    let mut x = x.to_vec();
    crate::flex::normalise_quaternion(&mut x[arm.layout().quaternion()]);
    let full = jacobians(arm, ws, &x, &bare)?;
    let (b_full, k_full) = feedback_over_tangent(arm, &x, &bare, full, feedback)?;
    let keep = &ss.tangent_index;
    let (s, m) = (keep.len(), b_full.ncols());
    let b = DMatrix::from_fn(s, m, |r, c| b_full[(keep[r], c)]);
    let k = DMatrix::from_fn(m, s, |r, c| k_full[(r, keep[c])]);
    let period = 1.0 / rate_hz;
    let step = one_period(&ss.a, &b, &k, period, delay);
    let no_convergence = |what: &str| Error::InvalidArgument {
        what: "x".into(),
        message: format!(
            "the eigenvalues of the {what} at this state did not converge within the QR \
             iteration's bound"
        ),
    };
    let values = eigenvalues(&step).ok_or_else(|| no_convergence("sampled loop"))?;
    let continuous =
        eigenvalues(&(&ss.a + &b * &k)).ok_or_else(|| no_convergence("continuous closed loop"))?;
    let growth = continuous.iter().map(|l| l.re).fold(0.0, f64::max);
    Ok(SampledLoop {
        spectral_radius: values.iter().map(|l| l.norm()).fold(0.0, f64::max),
        threshold: (1.1 * period * growth).exp() * (1.0 + MARGIN),
        eigenvalues: values,
        period,
        delay,
    })
}

/// `B` (the input columns of the sampled channel) and `K` (its linear feedback) over the full
/// tangent at `x`.
fn feedback_over_tangent(
    arm: &FlexibleArm,
    x: &[f64],
    bare: &LinearSpec,
    full: FullJacobians,
    feedback: SampledFeedback,
) -> Result<(DMatrix<f64>, DMatrix<f64>)> {
    let t = Tangent::of(arm);
    let n = arm.dof();
    Ok(match feedback {
        SampledFeedback::MotorPd { kp, kd } => {
            crate::args::check_vector("kp", kp, n)?;
            crate::args::check_vector("kd", kd, n)?;
            let mut k = DMatrix::zeros(n, t.len());
            for i in 0..n {
                k[(i, t.theta() + i)] = -kp[i];
                k[(i, t.theta_dot() + i)] = -kd[i];
            }
            (full.u, k)
        }
        SampledFeedback::Attitude(pd) => {
            let with = LinearSpec {
                attitude: Some(pd),
                ..*bare
            };
            super::linear::check_spec(arm, x, &with)?;
            (full.wheel_torque, attitude_gain(pd, x, t, arm.layout())?.0)
        }
    })
}

/// The one-period matrix of the module documentation: `Φ + Γ K` without delay, the matrix on
/// `z_j = [dx_j; c_{j−1}; …; c_{j−d}]` with `d = delay` samples; `Φ` and `Γ` read off
/// `exp([[A, B], [0, 0]] T)`.
fn one_period(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    k: &DMatrix<f64>,
    period: f64,
    delay: usize,
) -> DMatrix<f64> {
    let (s, m) = (a.nrows(), b.ncols());
    // exp([[A, B], [0, 0]] T) = [[Φ, Γ], [0, 𝟙]]
    let mut augmented = DMatrix::zeros(s + m, s + m);
    augmented.view_mut((0, 0), (s, s)).copy_from(&(a * period));
    augmented.view_mut((0, s), (s, m)).copy_from(&(b * period));
    let exp = augmented.exp();
    let phi = exp.view((0, 0), (s, s)).into_owned();
    let gamma = exp.view((0, s), (s, m)).into_owned();
    let size = s + delay * m;
    let mut step = DMatrix::zeros(size, size);
    if delay == 0 {
        step.copy_from(&(&phi + &gamma * k));
    } else {
        step.view_mut((0, 0), (s, s)).copy_from(&phi);
        step.view_mut((0, s + (delay - 1) * m), (s, m))
            .copy_from(&gamma);
        step.view_mut((s, 0), (m, s)).copy_from(k);
        for i in 1..delay {
            for r in 0..m {
                step[(s + i * m + r, s + (i - 1) * m + r)] = 1.0;
            }
        }
    }
    step
}
