//! Linear analysis of the flexible arm about a state: the state-space model, its structural
//! modes, its frequency response and sweeps of the modes across configurations
//! (`docs/modes.md`).
//!
//! **The linear model.** About a state `x̄`, with `x = x̄ ⊕ dx` and the tangent
//! `dx = [δr_B | δφ_B | δq | δθ | δω_B | δv_B | δq̇ | δθ̇]` (model §4.1):
//!
//! - *free base, free motors*: `A = F`, `B = G` of [`FlexibleArm::derivative_jacobians`]
//!   (model §4.1), all `12 + 4n` states;
//! - *clamped motors* (brakes on): `θ` is held at `x̄`'s value with `θ̇ = 0`. `θ` enters the
//!   links' equations only through the spring torque, where it is now a constant, so the model is
//!   `F` and `G` without the rows and columns of `δθ` and `δθ̇` (exact);
//! - *held base*: the base's actuators keep `V_B = 0`, `α_B = 0`. The links then obey the joint
//!   rows of (A.19) with the base's acceleration fixed, `M_r q̈ + ID_r(q, q̇) = τ − Jᵀ f`, whose
//!   linearisation `δq̈ = M_r⁻¹ (δτ − ∂ID_r/∂q δq − ∂ID_r/∂q̇ δq̇ − J_eᵀ δf_e)` is derived in
//!   `linear.rs`. It is *not* a sub-block of the free model: there the base's reaction changes
//!   the link accelerations (`𝓜⁻¹` against `M_r⁻¹`);
//! - *a motor PD closes the loop*: `u = k_p (θ_ref − θ) + k_d (θ̇_ref − θ̇) + u_ff` gives
//!   `δu = −k_p δθ − k_d δθ̇`, added to the `θ̈` rows: `A = F + G_u K`.
//!
//! Outputs are functions of the state (`D = 0`): angles, deflections, spring torques, base pose
//! and the end-effector's position `δp_e = δr_B − R_B [p_{B,e}]× δφ_B + R_B R_{e,B}ᵀ J_{e,lin} δq`.
//!
//! **Modes.** Two eigenproblems, which agree where both apply:
//!
//! - *Damped (default)*: the eigenvalues `λ` and eigenvectors of `A`, from the real Schur form
//!   ([`crate::linalg::eigen`]). An oscillatory mode is a pair `λ = −ζω_n ± iω_n√(1 − ζ²)`:
//!   its damped natural frequency is `Im λ / 2π`, its natural frequency `|λ| / 2π` and its
//!   damping ratio `−Re λ / |λ|`. This holds at any state, damped or not, open or closed loop.
//! - *Undamped*: at `x̄`'s configuration, `K φ = ω² M φ` with `M` the mass matrix of the kept
//!   degrees of freedom (`𝓜` or `M_r`, and `diag(j)` for free motors) and `K` the springs'
//!   stiffness (plus a PD's `k_p` on the motors), symmetric and positive semi-definite. Solved by
//!   Cholesky `M = L Lᵀ` and the symmetric eigenproblem of `L⁻¹ K L⁻ᵀ`; real, mass-normalised
//!   shapes. It ignores damping, velocities and preload.
//!
//! At a state at rest with relaxed springs and no load, `A = [[0, I], [−M⁻¹K, −M⁻¹C]]` in
//! these coordinates, so without damping (`d = β = k_d = 0`) the eigenvalues of `A` are exactly
//! `±iω` of the pencil, with the same shapes; with light damping `ω_n` stays close to `ω`, equal
//! to it for damping proportional to `M` and `K`.
//!
//! **Rigid-body modes.** Their number is the dimension `r` of the null space of `K`: the base's
//! 6 motions when it floats, and each joint whose link and motor can turn together without
//! stretching its spring (free motors, `k_p = 0`). They are counted from the stiffness, so motor
//! friction that damps a joint's free rotation does not change the count. In the damped problem
//! they account for `2r` eigenvalues of `A` (zeros, and a decay rate where friction acts); these
//! are the `2r` whose eigenvectors carry the largest share of their modal mass in the null space
//! of `K` (the `M`-orthogonal projection), and are never reported as structural modes. In the
//! undamped problem they are the `r` zero eigenvalues of the pencil.

pub mod frequency;
pub mod linear;
pub mod modes;
pub mod sampled;
pub mod sweep;

pub use frequency::{frequency_response, HessenbergForm};
pub use linear::{state_space, InputGroup, LinearSpec, Motors, OutputGroup, StateSpace};
pub use modes::{modes, Modes};
pub use sampled::{sampled_loop, SampledFeedback, SampledLoop};
pub use sweep::sweep;

#[cfg(doc)]
use crate::FlexibleArm;
