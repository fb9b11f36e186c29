//! The largest step for which a run stays stable: RK4 on the arm and its flexible joints, closed
//! by a controller that holds its torque over each step (model §5).
//!
//! Linearised at a state `x`, the non-pose part of the state `y = [q | θ | V_B | q̇ | θ̇]`
//! obeys `ẏ = F y + G u` between steps, and a state-feedback controller sets `u = K y` at the
//! start of each step and holds it (zero-order hold). For a linear system with constant input,
//! one RK4 step is exactly
//!
//! ```text
//! y⁺ = R(hF) y + h S(hF) G u,   R(z) = 1 + z + z²/2 + z³/6 + z⁴/24,   S(z) = 1 + z/2 + z²/6 + z³/24
//! ```
//! so the run is stable while the step matrix `M(h) = R(hF) + h S(hF) G K` has spectral radius
//! at most 1, or, when the physics itself grows (a frozen-time linearisation of a moving state can
//! have modes with `Re λ > 0`), no more than that growth `e^{1.1 h max Re λ}` with a 10 % margin
//! for the O(h) shift the held input gives slow modes. The limit is the smallest step `h` where
//! that fails, found by a geometric scan and bisection.
//!
//! This is not the stability region of RK4 applied to the continuous closed loop `F + GK`: a
//! derivative gain `k_d` held over the step acts like forward Euler on the motor pole `−k_d/j`, and
//! fails near `h = 2j/k_d`, well before RK4 would (`2.785 j/k_d`). A motor PD that looks
//! harmless in continuous time can therefore diverge; this analysis catches it.
//!
//! `F` is the analytical Jacobian of [`FlexibleArm::derivative`] ([`super::jacobians`]) on the
//! non-pose part (the base pose does not enter the dynamics, and its own kinematic modes,
//! `±i|ω_B|/2`, are added exactly); `G` is `1/j` on the `θ̈` rows; `K` comes from the
//! controller's [`Feedback`]. Above [`DENSE_LIMIT`]
//! joints the dense (6+4n)² matrices would cost too much, and each joint is analysed on its own
//! (see [`StabilityLimit::estimated`]).
//!
//! ```
//! use orbitflex::{FlexibleArm, FlexibleJoints, MotorPD, Robot, Schedule};
//! let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
//! let pd = MotorPD::new(vec![2000.0; 7], vec![800.0; 7], Schedule::Zero, Schedule::Zero, Schedule::Zero)?;
//! let limit = arm.rk4_stability_limit(&arm.rest_state(), &pd)?;
//! // the held derivative gain of the light wrist motors sets it: about 2 j / k_d
//! assert!(limit.dt > 0.9e-3 && limit.dt < 1.0e-3);
//! # Ok::<(), orbitflex::Error>(())
//! ```

use super::arm::{FlexibleArm, Inputs, ModelWorkspace};
use crate::algorithms;
use crate::args::{Loads, RigidState};
use crate::control::Feedback;
use crate::error::{Error, Result};
use crate::linalg::eigenvalues;
use nalgebra::{Complex, DMatrix};

/// Above this many joints each joint is analysed on its own instead of the whole (6+4n)² system.
pub const DENSE_LIMIT: usize = 16;

/// How far above the continuous growth the step matrix's spectral radius may sit before a step
/// counts as unstable. The free-floating arm's step matrices have defective eigenvalues at 1
/// (rigid motions), which floating point computes only to about √ε ≈ 1.5e-8; a real instability
/// crosses this margin within a relative step change of about the same size.
const TOLERANCE: f64 = 1e-6;

/// The stability limit of a run at one state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StabilityLimit {
    /// The largest stable step (s); infinite when nothing limits it.
    pub dt: f64,
    /// The continuous closed loop's eigenvalue of largest magnitude (1/s), for orientation: the
    /// fastest mode of the linearised system.
    pub fastest_mode: Complex<f64>,
    /// True when the controller's feedback was unknown (a Python callable, say), so that only
    /// the open loop was analysed.
    pub open_loop: bool,
    /// True when the limit comes from analysing each joint on its own (more than
    /// [`DENSE_LIMIT`] joints) rather than the whole linearised system.
    pub estimated: bool,
}

/// The linearised system `ẏ = F y + G u`, `u = K y` (held over each step).
struct Linear {
    f: DMatrix<f64>,
    /// `G K`
    gk: DMatrix<f64>,
}

impl Linear {
    /// The step matrix `M(h) = R(hF) + h S(hF) G K`.
    fn step_matrix(&self, h: f64) -> DMatrix<f64> {
        let m = self.f.nrows();
        let identity = DMatrix::<f64>::identity(m, m);
        let z = &self.f * h;
        // S = I + z (I/2 + z (I/6 + z/24)), and R = I + z S.
        let inner = &identity / 6.0 + &z / 24.0;
        let s = &identity + &z * (&identity / 2.0 + &z * inner);
        let r = &identity + &z * &s;
        r + (s * &self.gk) * h
    }

    /// Spectral radius of `M(h)` (infinite if the eigenvalues cannot be found).
    fn radius(&self, h: f64) -> f64 {
        eigenvalues(&self.step_matrix(h)).map_or(f64::INFINITY, |ev| {
            ev.iter().map(|l| l.norm()).fold(0.0, f64::max)
        })
    }

    /// When the eigenvalues cannot be computed because the feedback's entries are too large
    /// for floating point (beyond 1e100, whose products overflow in the QR iteration), the
    /// error naming the gain.
    fn blame_gains(&self, feedback: &Feedback) -> Option<Error> {
        let Feedback::MotorPd { kp, kd } = feedback else {
            return None;
        };
        let largest = |m: &DMatrix<f64>| m.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        if largest(&self.gk) <= 1e100 || largest(&self.gk) <= largest(&self.f) {
            return None;
        }
        let peak = |v: &[f64]| v.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
        let (what, gains) = if peak(kp) >= peak(kd) {
            ("kp", kp)
        } else {
            ("kd", kd)
        };
        Some(Error::InvalidArgument {
            what: what.into(),
            message: format!(
                "too large for floating point: the eigenvalues of the closed loop (for the RK4 \
                 stability limit) cannot be computed with gains up to {}",
                crate::args::number(peak(gains))
            ),
        })
    }

    /// The continuous closed loop's eigenvalues, `F + G K`.
    fn closed_eigenvalues(&self) -> Result<Vec<Complex<f64>>> {
        eigenvalues(&(&self.f + &self.gk)).ok_or_else(|| Error::InvalidArgument {
            what: "x".into(),
            message: "the linearised closed loop at this state has no computable eigenvalues \
                      (the QR iteration did not converge)"
                .into(),
        })
    }

    /// The largest stable step: the first `h` where `M(h)` grows a mode faster than the
    /// continuous closed loop `closed` (its eigenvalues) does.
    ///
    /// `enough` ends the search early: as soon as a step `h ≥ enough` is found stable, `h` is
    /// returned, a lower bound of the limit (which is at least every step the search has found
    /// stable). So a result below `enough` is the limit itself, found by the same sequence of
    /// steps as with `enough = ∞`, and a result at or above it says only that `enough` is within
    /// the limit: whether a given `dt` exceeds the limit is decided with the scan up to `dt`
    /// alone, without the bisection, for the same answer.
    fn limit(&self, closed: &[Complex<f64>], enough: f64) -> f64 {
        let growth = closed.iter().map(|l| l.re).fold(0.0, f64::max);
        // A mode the physics makes grow (a frozen-time linearisation of a moving state has some)
        // may grow; holding the controller's output shifts such slow modes by O(h), hence the
        // 10 % margin on the growth rate. A numerical instability overshoots it quickly.
        let stable = |h: f64| self.radius(h) <= (1.1 * growth * h).exp() * (1.0 + TOLERANCE);
        let spectral = closed.iter().map(|l| l.norm()).fold(0.0, f64::max);
        let fastest = spectral.max(self.f.iter().map(|v| v.abs()).fold(0.0, f64::max));
        if fastest == 0.0 {
            return f64::INFINITY;
        }
        // No limit within a million time constants of the fastest mode. The entries of F can be
        // far larger than its eigenvalues (k/j against √(k/j) for a stiff joint): they only
        // set where the scan starts.
        let cap = 1e6 / if spectral > 0.0 { spectral } else { fastest };
        // Scan up from inside the region (|λ h| = 0.5) until a step fails, then bisect.
        let mut lo = 0.5 / fastest;
        if !stable(lo) {
            return bisect(&stable, 0.0, lo, enough);
        }
        let mut hi = lo * 2.0;
        while lo < enough && stable(hi) {
            lo = hi;
            hi *= 2.0;
            if hi > cap {
                return f64::INFINITY;
            }
        }
        if lo >= enough {
            return lo;
        }
        bisect(&stable, lo, hi, enough)
    }
}

/// The eigenvalue of largest magnitude (zero for none).
fn fastest(eigenvalues: &[Complex<f64>]) -> Complex<f64> {
    eigenvalues
        .iter()
        .copied()
        .fold(Complex::new(0.0, 0.0), |a, b| {
            if b.norm() > a.norm() {
                b
            } else {
                a
            }
        })
}

/// The boundary between a stable `lo` and an unstable `hi`, to 1e-4 relative, or the first
/// stable step found at or above `enough` ([`Linear::limit`]).
fn bisect(stable: &impl Fn(f64) -> bool, mut lo: f64, mut hi: f64, enough: f64) -> f64 {
    while hi - lo > 1e-4 * hi && lo < enough {
        let mid = 0.5 * (lo + hi);
        if stable(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The stability limit of `arm` at state `x` under a controller with this `feedback`, held over
/// each step (see the module documentation).
pub fn rk4_stability_limit(
    arm: &FlexibleArm,
    x: &[f64],
    feedback: &Feedback,
) -> Result<StabilityLimit> {
    limit_until(arm, x, feedback, f64::INFINITY)
}

/// [`rk4_stability_limit`], its search ended as soon as a step `h ≥ enough` is found stable
/// ([`Linear::limit`]): a `dt` below `enough` is the limit itself; one at or above it is a lower
/// bound of the limit. `dt > limit.dt` therefore has the answer of the full search when
/// `enough = dt`, which saves the bisection (most of the eigenvalue solves) for a step that is
/// within the limit.
pub(crate) fn limit_until(
    arm: &FlexibleArm,
    x: &[f64],
    feedback: &Feedback,
    enough: f64,
) -> Result<StabilityLimit> {
    arm.check_state(x)?;
    if let Feedback::MotorPd { kp, kd } = feedback {
        crate::args::check_vector("kp", kp, arm.dof())?;
        crate::args::check_vector("kd", kd, arm.dof())?;
    }
    let open_loop = matches!(feedback, Feedback::Unknown);
    let estimated = arm.dof() > DENSE_LIMIT;
    let (dt, fastest_mode) = if estimated {
        joints_until(arm, x, feedback, enough)?
    } else {
        let linear = linearise(arm, x, feedback)?;
        let closed = linear
            .closed_eigenvalues()
            .map_err(|e| linear.blame_gains(feedback).unwrap_or(e))?;
        (linear.limit(&closed, enough), fastest(&closed))
    };
    // The quaternion kinematics oscillate at ±|ω_B|/2, on RK4's imaginary axis (2√2 / |λ|).
    let omega = arm.layout().split(x).omega().norm();
    let pose_limit = if omega > 0.0 {
        2.0 * std::f64::consts::SQRT_2 / (0.5 * omega)
    } else {
        f64::INFINITY
    };
    Ok(StabilityLimit {
        dt: dt.min(pose_limit),
        fastest_mode,
        open_loop,
        estimated,
    })
}

/// `F`, the analytical Jacobian of the derivative ([`super::jacobians`]) restricted to
/// `[q | θ | V_B | q̇ | θ̇]` at zero inputs (the pose rows and columns drop out: the dynamics do
/// not depend on the pose), and `G K` from the controller's feedback.
fn linearise(arm: &FlexibleArm, x: &[f64], feedback: &Feedback) -> Result<Linear> {
    let layout = arm.layout();
    let size = layout.dynamic().len();
    let mut ws = ModelWorkspace::new(arm);
    let u = vec![0.0; arm.dof()];
    let full = super::jacobians::derivative_jacobians(arm, &mut ws, x, &Inputs::torques(&u))?;
    arm.check_overflow(
        "rk4_stability_limit (the linearisation at x)",
        &full.blocks(),
        &[("x", x, 2)],
    )?;
    // the tangent's dynamic block starts at 6: [δr | δφ] come first
    let f = full.x.view((6, 6), (size, size)).into_owned();
    let mut gk = DMatrix::zeros(size, size);
    if let Feedback::MotorPd { kp, kd } = feedback {
        let j = &arm.joints().motor_inertia;
        let dynamic = layout.dynamic().start;
        let at = |range: std::ops::Range<usize>, i: usize| range.start + i - dynamic;
        for i in 0..arm.dof() {
            // θ̈_i = (u_i − …)/j_i with u_i = … − kp_i θ_i − kd_i θ̇_i
            let row = at(layout.theta_dot(), i);
            gk[(row, at(layout.theta(), i))] = -kp[i] / j[i];
            gk[(row, at(layout.theta_dot(), i))] = -kd[i] / j[i];
        }
    }
    Ok(Linear { f, gk })
}

/// The estimate used for large models, `(dt, fastest mode)`: each joint on its own, a motor `j_i`
/// coupled by the spring and damper to the link-side effective inertia `m_i = 1/(𝓜⁻¹)_ii` (one
/// articulated-body solve per joint, no dense matrix), under the same held PD. Returns the
/// smallest of the joints' limits. `x` must be a checked state.
pub fn joint_by_joint_limit(
    arm: &FlexibleArm,
    x: &[f64],
    feedback: &Feedback,
) -> Result<(f64, Complex<f64>)> {
    joints_until(arm, x, feedback, f64::INFINITY)
}

/// [`joint_by_joint_limit`] with each joint's search ended at `enough` ([`Linear::limit`]): the
/// smallest of the joints' results is the estimate itself when below `enough` (every joint whose
/// search ended early has a limit at or above `enough`).
fn joints_until(
    arm: &FlexibleArm,
    x: &[f64],
    feedback: &Feedback,
    enough: f64,
) -> Result<(f64, Complex<f64>)> {
    let n = arm.dof();
    let p = arm.joints();
    let s = arm.layout().split(x);
    let mut data = algorithms::Data::new(arm.robot());
    let zeros = vec![0.0; n];
    let mut unit = vec![0.0; n];
    let (mut dt, mut fastest) = (f64::INFINITY, Complex::new(0.0, 0.0));
    for i in 0..n {
        unit[i] = 1.0;
        let rigid = RigidState::at_rest(s.q, &zeros);
        algorithms::aba_unchecked(arm.robot(), &mut data, &rigid, &unit, &Loads::ZERO)?;
        unit[i] = 0.0;
        let inverse_inertia = data.ddq[6 + i];
        let (kp, kd) = match feedback {
            Feedback::MotorPd { kp, kd } => (kp[i], kd[i]),
            _ => (0.0, 0.0),
        };
        let (k, d, j, beta) = (
            p.stiffness[i],
            p.damping[i],
            p.motor_inertia[i],
            p.motor_damping[i],
        );
        // y = [q, θ, q̇, θ̇]: m q̈ = k (θ − q) + d (θ̇ − q̇), j θ̈ = u − k (θ − q) − d (θ̇ − q̇) − β θ̇
        let a = inverse_inertia;
        #[rustfmt::skip]
        let f = DMatrix::from_row_slice(4, 4, &[
            0.0, 0.0, 1.0, 0.0,
            0.0, 0.0, 0.0, 1.0,
            -k * a, k * a, -d * a, d * a,
            k / j, -k / j, d / j, -(d + beta) / j,
        ]);
        let mut gk = DMatrix::zeros(4, 4);
        gk[(3, 1)] = -kp / j;
        gk[(3, 3)] = -kd / j;
        let linear = Linear { f, gk };
        let closed = linear.closed_eigenvalues()?;
        dt = dt.min(linear.limit(&closed, enough));
        let mode = self::fastest(&closed);
        if mode.norm() > fastest.norm() {
            fastest = mode;
        }
    }
    Ok((dt, fastest))
}
