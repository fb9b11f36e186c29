//! Structural modes of the arm about a state: the eigenvalues and eigenvectors of the linear
//! model's state matrix (damped, open or closed loop), or the undamped modes of the symmetric
//! pencil `(K, M)`, with the rigid-body modes (the null space of the stiffness) separated out.
//! See the [module documentation](super).

// Loops run over joint and eigenvalue indices shared by several arrays.
#![allow(clippy::needless_range_loop)]

use super::linear::{check_spec, state_space, LinearSpec, Motors, Tangent};
use crate::algorithms;
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, ModelWorkspace};
use crate::integrate::Feedback;
use crate::planning::BaseMode;
use crate::spatial::quaternion_to_rotation;
use nalgebra::{Complex, DMatrix, DVector};

/// The modes of the arm about a state.
#[derive(Debug, Clone, PartialEq)]
pub struct Modes {
    /// Every eigenvalue of the model's state matrix (1/s), rigid-body ones included, sorted by
    /// modulus then imaginary part. For the undamped modes, those of the undamped state matrix:
    /// `±iω` per structural mode and two zeros per rigid-body mode.
    pub eigenvalues: Vec<Complex<f64>>,
    /// Damped natural frequencies `Im λ / 2π` of the oscillatory structural modes (Hz),
    /// ascending.
    pub frequency_hz: Vec<f64>,
    /// Natural frequencies `|λ| / 2π` of the same modes (Hz).
    pub natural_frequency_hz: Vec<f64>,
    /// Damping ratios `−Re λ / |λ|` of the same modes (zero for undamped modes).
    pub damping_ratio: Vec<f64>,
    /// The mode shapes, one column per mode, in the full tangent layout (`12 + 4n + k` rows; rows of
    /// states the model holds fixed are zero), complex. The displacement part `z` (in the
    /// coordinates of the velocities) has unit modal mass `zᴴ M z = 1`, and its component of
    /// largest kinetic weight `M_ii |z_i|²` is real and positive.
    pub shapes: DMatrix<Complex<f64>>,
    /// The number of rigid-body modes separated out: the dimension of the stiffness's null
    /// space (6 + n for a free base with free motors, 6 with clamped motors, n for a held base
    /// with free motors, 0 held and clamped; a motor PD's `k_p` removes a joint's, an attitude
    /// PD's `k_p` the bus's rotation about each axis it holds).
    pub rigid_body: usize,
    /// The number of wheel-spin modes separated out: one per reaction wheel (`k`). A wheel's
    /// speed has no position in the state, so each adds one eigenvalue to `A` (zero, or the
    /// decay of its friction), not a pair; they are never reported as structural modes.
    pub wheel_spin: usize,
    /// Real eigenvalues (1/s) of structural modes damped past critical: they decay without
    /// oscillating and are not among the modes above.
    pub overdamped: Vec<f64>,
    /// True for the modes of the state matrix (damped), false for the undamped pencil.
    pub damped: bool,
}

/// One degree of freedom of the model: where its displacement and its rate sit in the tangent.
#[derive(Debug, Clone, Copy)]
struct Dof {
    config: usize,
    rate: usize,
}

/// The model's degrees of freedom, in the order of the velocities (`[ω_B; v_B]` for a free base,
/// then `q`, then `θ` for free motors), with the mass matrix `M`, the stiffness `K` and the
/// rigid-body basis (the null space of `K`) over them.
struct Mechanics {
    dofs: Vec<Dof>,
    mass: DMatrix<f64>,
    stiffness: DMatrix<f64>,
    rigid: DMatrix<f64>,
    /// `R_B`: the base's translation is displaced in the inertial frame, moved in the base
    /// frame.
    rotation: crate::spatial::Mat3,
    free_base: bool,
    /// Per reaction wheel: its spin inertia `J_s` and the inertia `I_w` its momentum is weighed
    /// against (the locked system's about the wheel's axis, or `J_s` on a held base).
    wheels: Vec<(f64, f64)>,
}

fn mechanics(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    spec: &LinearSpec,
) -> Result<Mechanics> {
    let n = arm.dof();
    let t = Tangent::of(arm);
    let s = arm.layout().split(x);
    let p = arm.joints();
    let free_base = spec.base == BaseMode::Free;
    let free_motors = spec.motors == Motors::Free;
    let dofs = degrees_of_freedom(t, n, free_base, free_motors);
    let size = dofs.len();
    let full = algorithms::crba(arm.rigid_model(), &mut ws.data, s.q)?;
    let offset = if free_base { 0 } else { 6 };
    let rigid_size = if free_base { 6 + n } else { n };
    let mut mass = DMatrix::zeros(size, size);
    mass.view_mut((0, 0), (rigid_size, rigid_size))
        .copy_from(&full.view((offset, offset), (rigid_size, rigid_size)));
    let kp = match spec.feedback {
        Feedback::MotorPd { kp, .. } => kp.to_vec(),
        _ => vec![0.0; n],
    };
    let mut stiffness = DMatrix::zeros(size, size);
    let mut rigid_columns: Vec<DVector<f64>> = Vec::new();
    let attitude = attitude_stiffness(arm, x, spec, t)?;
    if free_base {
        for r in 0..3 {
            for c in 0..3 {
                stiffness[(r, c)] = attitude[(r, c)];
            }
        }
        for a in 0..6 {
            if a < 3 && attitude.column(a).amax() != 0.0 {
                // the attitude loop holds this rotation
                continue;
            }
            let mut v = DVector::zeros(size);
            v[a] = 1.0;
            rigid_columns.push(v);
        }
    }
    let wheels = wheel_inertias(arm, &mass, free_base);
    for i in 0..n {
        let (qi, k) = (rigid_size - n + i, p.stiffness[i]);
        stiffness[(qi, qi)] = k;
        if free_motors {
            let ti = rigid_size + i;
            mass[(ti, ti)] = p.motor_inertia[i];
            stiffness[(qi, ti)] = -k;
            stiffness[(ti, qi)] = -k;
            stiffness[(ti, ti)] = k + kp[i];
            if kp[i] == 0.0 {
                // link and motor turning together stretch no spring
                let mut v = DVector::zeros(size);
                v[qi] = 1.0;
                v[ti] = 1.0;
                rigid_columns.push(v);
            }
        }
    }
    let rigid = DMatrix::from_fn(size, rigid_columns.len(), |r, c| rigid_columns[c][r]);
    Ok(Mechanics {
        dofs,
        mass,
        stiffness,
        rigid,
        rotation: quaternion_to_rotation(s.quaternion),
        free_base,
        wheels,
    })
}

/// The degrees of freedom in the order of the velocities: `[ω_B; v_B]` for a free base (`δφ_B`
/// moves with `ω_B`, `δr_B` with `v_B`), then `q`, then `θ` for free motors.
fn degrees_of_freedom(t: Tangent, n: usize, free_base: bool, free_motors: bool) -> Vec<Dof> {
    let mut dofs = Vec::new();
    if free_base {
        dofs.extend((0..3).map(|a| Dof {
            config: 3 + a,
            rate: t.twist() + a,
        }));
        dofs.extend((0..3).map(|a| Dof {
            config: a,
            rate: t.twist() + 3 + a,
        }));
    }
    dofs.extend((0..n).map(|i| Dof {
        config: t.q() + i,
        rate: t.qd() + i,
    }));
    if free_motors {
        dofs.extend((0..n).map(|i| Dof {
            config: t.theta() + i,
            rate: t.theta_dot() + i,
        }));
    }
    dofs
}

/// The stiffness an attitude PD puts on the bus's rotation (zero without one): the bus feels
/// `T = A M T_cmd`, `T_cmd = −k_p ∘ (E δφ) − …`, a stiffness `A M diag(k_p) E`
/// (`A = [a_1 … a_k]`).
fn attitude_stiffness(
    arm: &FlexibleArm,
    x: &[f64],
    spec: &LinearSpec,
    t: Tangent,
) -> Result<crate::spatial::Mat3> {
    let mut block = crate::spatial::Mat3::zeros();
    if let (Some(pd), Some(wheels)) = (spec.attitude, arm.wheels()) {
        let (gain, _) = super::linear::attitude_gain(pd, x, t, arm.layout())?;
        for (w, wheel) in wheels.wheels().iter().enumerate() {
            for r in 0..3 {
                for c in 0..3 {
                    block[(r, c)] += wheel.axis[r] * gain[(w, 3 + c)];
                }
            }
        }
    }
    Ok(block)
}

/// Per reaction wheel: its spin inertia `J_s` and the inertia its momentum is weighed against,
/// the locked system's about its axis (`aᵀ M_ωω a`, from the free base's mass matrix `mass`)
/// or `J_s` on a held base, whichever is larger.
fn wheel_inertias(arm: &FlexibleArm, mass: &DMatrix<f64>, free_base: bool) -> Vec<(f64, f64)> {
    arm.wheels().map_or(Vec::new(), |w| {
        w.wheels()
            .iter()
            .map(|wheel| {
                let a = crate::spatial::Vec3::from(wheel.axis);
                let locked = if free_base {
                    (a.transpose() * mass.fixed_view::<3, 3>(0, 0) * a)[0]
                } else {
                    0.0
                };
                (wheel.spin_inertia, locked.max(wheel.spin_inertia))
            })
            .collect()
    })
}

impl Mechanics {
    /// The displacement part `z` (velocity coordinates) of a tangent vector.
    fn displacement(&self, v: &DVector<Complex<f64>>) -> DVector<Complex<f64>> {
        let mut z = DVector::from_fn(self.dofs.len(), |a, _| v[self.dofs[a].config]);
        if self.free_base {
            // δr_B is inertial; the base's linear velocity is in base axes: z = R_Bᵀ δr_B
            let r = self.rotation.map(|x| Complex::new(x, 0.0));
            let lin = r.transpose() * z.fixed_rows::<3>(3);
            z.fixed_rows_mut::<3>(3).copy_from(&lin);
        }
        z
    }

    /// A tangent vector (full layout, `size` rows) from a displacement `z` and the eigenvalue
    /// `λ` of its mode: displacements `z`, rates `λ z`.
    fn tangent(
        &self,
        z: &DVector<Complex<f64>>,
        lambda: Complex<f64>,
        size: usize,
    ) -> DVector<Complex<f64>> {
        let mut v = DVector::from_element(size, Complex::new(0.0, 0.0));
        for (a, dof) in self.dofs.iter().enumerate() {
            v[dof.config] = z[a];
            v[dof.rate] = lambda * z[a];
        }
        if self.free_base {
            let r = self.rotation.map(|x| Complex::new(x, 0.0));
            let inertial = r * z.fixed_rows::<3>(3);
            v.fixed_rows_mut::<3>(0).copy_from(&inertial);
        }
        v
    }

    /// The share of `z`'s modal mass in rigid-body motion: `‖P z‖²_M / ‖z‖²_M`, `P` the
    /// `M`-orthogonal projector onto the null space of the stiffness.
    fn rigid_share(
        &self,
        z: &DVector<Complex<f64>>,
        rigid_mass: &Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
    ) -> f64 {
        let Some(chol) = rigid_mass else {
            return 0.0;
        };
        let mass = self.mass.map(|x| Complex::new(x, 0.0));
        let mz = &mass * z;
        let total = z.dotc(&mz).re;
        if total <= 0.0 {
            return 0.0;
        }
        let g = self.rigid.map(|x| Complex::new(x, 0.0)).transpose() * &mz;
        let (re, im) = (g.map(|c| c.re), g.map(|c| c.im));
        let projected = re.dot(&chol.solve(&re)) + im.dot(&chol.solve(&im));
        projected / total
    }

    /// The share of the eigenvector `v` (eigenvalue `λ`, full tangent) that is not structural:
    /// rigid-body motion or wheel spin. With the displacement `z`, the rates `ż` of the
    /// degrees of freedom and the wheels' momenta `J_s δΩ`, weigh
    ///
    /// ```text
    /// E_m = żᴴ M ż + (|λ|² + ω_K²) zᴴ M z,   E_w = Σ_w |J_s δΩ_w|² / I_w
    /// ```
    /// (`ω_K² = tr K / tr M`, a frequency scale of the model; `I_w` the locked system's inertia
    /// about the wheel's axis, so that a wheel absorbing the bus's momentum weighs about as
    /// much as the bus's own motion), and return `(E_w + s E_m) / (E_w + E_m)`, `s` the rigid
    /// share of `z` ([`Self::rigid_share`]). A structural mode scores near 0, a rigid-body
    /// mode or a wheel's free spin (or a mixture, where a multiple zero eigenvalue leaves the
    /// eigenvectors free) near 1.
    fn non_structural_share(
        &self,
        v: &DVector<Complex<f64>>,
        lambda: Complex<f64>,
        wheel0: usize,
        rigid_mass: &Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
    ) -> f64 {
        let z = self.displacement(v);
        let rates = DVector::from_fn(self.dofs.len(), |a, _| v[self.dofs[a].rate]);
        let mass = self.mass.map(|x| Complex::new(x, 0.0));
        let trace_m = self.mass.trace();
        let omega_k2 = if trace_m > 0.0 {
            self.stiffness.trace() / trace_m
        } else {
            0.0
        };
        let mechanical = rates.dotc(&(&mass * &rates)).re
            + (lambda.norm_sqr() + omega_k2) * z.dotc(&(&mass * &z)).re;
        let spin: f64 = self
            .wheels
            .iter()
            .enumerate()
            .map(|(w, &(js, iw))| (v[wheel0 + w] * js).norm_sqr() / iw)
            .sum();
        let total = mechanical + spin;
        if total <= 0.0 {
            return 0.0;
        }
        (spin + self.rigid_share(&z, rigid_mass) * mechanical) / total
    }

    /// The factor that scales `z` to unit modal mass and turns its heaviest component real and
    /// positive.
    fn normalising_factor(&self, z: &DVector<Complex<f64>>) -> Complex<f64> {
        let mass = self.mass.map(|x| Complex::new(x, 0.0));
        let norm = z.dotc(&(&mass * z)).re.sqrt();
        let heaviest = (0..z.len())
            .max_by(|&a, &b| {
                let wa = self.mass[(a, a)] * z[a].norm_sqr();
                let wb = self.mass[(b, b)] * z[b].norm_sqr();
                wa.total_cmp(&wb)
            })
            .unwrap_or(0);
        let phase = if z.is_empty() || z[heaviest].norm() == 0.0 {
            Complex::new(1.0, 0.0)
        } else {
            z[heaviest].conj() / z[heaviest].norm()
        };
        phase / norm.max(f64::MIN_POSITIVE)
    }
}

/// The modes of `arm` about the state `x` for the model `spec` (its inputs and outputs are not
/// used): of the state matrix `A` when `damped`, else of the undamped pencil `(K, M)` at `x`'s
/// configuration (see the [module documentation](super)).
///
/// ```
/// use orbitflex::analysis::{modes, LinearSpec};
/// use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
/// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
/// let m = modes(&arm, &mut arm.workspace(), &arm.rest_state(), &LinearSpec::default(), true)?;
/// assert_eq!(m.rigid_body, 6 + 7);           // the base's 6 and each joint's free rotation
/// assert_eq!(m.frequency_hz.len(), 7);       // one structural mode per spring
/// # Ok::<(), orbitflex::Error>(())
/// ```
pub fn modes(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    spec: &LinearSpec,
    damped: bool,
) -> Result<Modes> {
    arm.check_state(x)?;
    let mut x = x.to_vec();
    crate::flex::normalise_quaternion(&mut x[arm.layout().quaternion()]);
    check_spec(arm, &x, spec)?;
    let mech = mechanics(arm, ws, &x, spec)?;
    if damped {
        state_matrix_modes(arm, ws, &x, spec, &mech)
    } else {
        undamped_modes(arm, &mech)
    }
}

fn no_convergence(what: &str) -> Error {
    Error::InvalidArgument {
        what: "x".into(),
        message: format!(
            "the {what} of the linear model at this state did not converge within the QR \
             iteration's bound (30 iterations per row)"
        ),
    }
}

/// `2π`
const TAU: f64 = std::f64::consts::TAU;

fn state_matrix_modes(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    spec: &LinearSpec,
    mech: &Mechanics,
) -> Result<Modes> {
    let t = Tangent::of(arm);
    // the model's A alone: no inputs or outputs
    let bare = LinearSpec {
        inputs: &[],
        outputs: &[],
        ..*spec
    };
    let ss = state_space(arm, ws, x, &bare)?;
    let keep = &ss.tangent_index;
    let eig = crate::linalg::eigen(&ss.a).ok_or_else(|| no_convergence("eigenvalues"))?;
    let r = mech.rigid.ncols();
    let rigid_mass = (r > 0)
        .then(|| (mech.rigid.transpose() * &mech.mass * &mech.rigid).cholesky())
        .flatten();
    // each eigenvector in the full tangent and its share of rigid-body motion and wheel spin
    let count = eig.values.len();
    let mut vectors = Vec::with_capacity(count);
    let mut share = Vec::with_capacity(count);
    for j in 0..count {
        let mut v = DVector::from_element(t.len(), Complex::new(0.0, 0.0));
        for (row, &index) in keep.iter().enumerate() {
            v[index] = eig.vectors[(row, j)];
        }
        share.push(mech.non_structural_share(&v, eig.values[j], t.wheel(), &rigid_mass));
        vectors.push(v);
    }
    // the 2r + k least structural eigenvalues are the rigid-body modes' and the wheels' spins
    let rigid = least_structural(&eig.values, &share, 2 * r + t.k);
    let mut oscillatory = Vec::new();
    let mut overdamped = Vec::new();
    for j in 0..count {
        let lambda = eig.values[j];
        if rigid[j] || lambda.im < 0.0 {
            continue;
        }
        if lambda.im > 0.0 {
            oscillatory.push(j);
        } else {
            overdamped.push(lambda.re);
        }
    }
    oscillatory.sort_by(|&a, &b| eig.values[a].im.total_cmp(&eig.values[b].im));
    overdamped.sort_by(|a, b| b.total_cmp(a));
    let mut shapes = DMatrix::from_element(t.len(), oscillatory.len(), Complex::new(0.0, 0.0));
    for (column, &j) in oscillatory.iter().enumerate() {
        // the displacement's factor on the whole eigenvector (its rates included)
        let factor = mech.normalising_factor(&mech.displacement(&vectors[j]));
        shapes.set_column(column, &(&vectors[j] * factor));
    }
    let lambdas: Vec<Complex<f64>> = oscillatory.iter().map(|&j| eig.values[j]).collect();
    let mut eigenvalues = eig.values.clone();
    sort_eigenvalues(&mut eigenvalues);
    Ok(Modes {
        eigenvalues,
        frequency_hz: lambdas.iter().map(|l| l.im / TAU).collect(),
        natural_frequency_hz: lambdas.iter().map(|l| l.norm() / TAU).collect(),
        damping_ratio: lambdas.iter().map(|l| -l.re / l.norm()).collect(),
        shapes,
        rigid_body: r,
        wheel_spin: t.k,
        overdamped,
        damped: true,
    })
}

/// Flags the `count` eigenvalues of `values` (by Im λ ≥ 0, a conjugate pair counting two and
/// staying together) with the largest non-structural `share`; ties go to the lower index. The
/// conjugates with Im λ < 0 are never flagged (nor reported on their own).
fn least_structural(values: &[Complex<f64>], share: &[f64], count: usize) -> Vec<bool> {
    let mut order: Vec<usize> = (0..values.len()).filter(|&j| values[j].im >= 0.0).collect();
    order.sort_by(|&a, &b| share[b].total_cmp(&share[a]).then(a.cmp(&b)));
    let mut flagged = vec![false; values.len()];
    let mut left = count;
    for &j in &order {
        let size = if values[j].im > 0.0 { 2 } else { 1 };
        if size <= left {
            left -= size;
            flagged[j] = true;
        }
    }
    flagged
}

fn sort_eigenvalues(values: &mut [Complex<f64>]) {
    values.sort_by(|a, b| a.norm().total_cmp(&b.norm()).then(a.im.total_cmp(&b.im)));
}

/// `K φ = ω² M φ` by Cholesky `M = L Lᵀ` and the symmetric eigenproblem of `L⁻¹ K L⁻ᵀ`; the `r`
/// smallest eigenvalues are the null space of `K` (exactly `r` of them are zero).
fn undamped_modes(arm: &FlexibleArm, mech: &Mechanics) -> Result<Modes> {
    let t = Tangent::of(arm);
    let chol = mech
        .mass
        .clone()
        .cholesky()
        .ok_or_else(|| Error::InvalidArgument {
            what: "x".into(),
            message: "the mass matrix is not positive definite at this configuration".into(),
        })?;
    let l = chol.l();
    let l_inv = l
        .clone()
        .try_inverse()
        .ok_or_else(|| no_convergence("mass factorisation"))?;
    let mut s = &l_inv * &mech.stiffness * l_inv.transpose();
    s = (&s + s.transpose()) * 0.5;
    let eig = nalgebra::SymmetricEigen::try_new(s, f64::EPSILON, 30 * mech.dofs.len().max(10))
        .ok_or_else(|| no_convergence("symmetric eigenvalues"))?;
    let mut order: Vec<usize> = (0..eig.eigenvalues.len()).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let r = mech.rigid.ncols();
    let structural = &order[r..];
    let mut shapes = DMatrix::from_element(t.len(), structural.len(), Complex::new(0.0, 0.0));
    let mut omegas = Vec::with_capacity(structural.len());
    for (column, &j) in structural.iter().enumerate() {
        let omega = eig.eigenvalues[j].max(0.0).sqrt();
        let phi = l_inv.transpose() * eig.eigenvectors.column(j);
        let z = phi.map(|x| Complex::new(x, 0.0));
        let z = &z * mech.normalising_factor(&z);
        shapes.set_column(column, &mech.tangent(&z, Complex::new(0.0, omega), t.len()));
        omegas.push(omega);
    }
    let mut eigenvalues: Vec<Complex<f64>> = vec![Complex::new(0.0, 0.0); 2 * r + t.k];
    for &w in &omegas {
        eigenvalues.push(Complex::new(0.0, w));
        eigenvalues.push(Complex::new(0.0, -w));
    }
    sort_eigenvalues(&mut eigenvalues);
    Ok(Modes {
        eigenvalues,
        frequency_hz: omegas.iter().map(|w| w / TAU).collect(),
        natural_frequency_hz: omegas.iter().map(|w| w / TAU).collect(),
        damping_ratio: vec![0.0; omegas.len()],
        shapes,
        rigid_body: r,
        wheel_spin: t.k,
        overdamped: Vec::new(),
        damped: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::random_chain;
    use crate::FlexibleJoints;

    /// One joint on a held base, motors free: the rigid-body basis is link and motor turning
    /// together, `v = [1, 1]`, and the share of a displacement `z` in it is
    /// `(vᵀ M z)² / (vᵀ M v · zᵀ M z)`: 1 for `v`, 0 for the `M`-orthogonal `[j, −I]`, and
    /// `I / (I + j)` for the link alone.
    #[test]
    fn rigid_share_is_the_m_orthogonal_projection() {
        let arm = FlexibleArm::new(
            random_chain(1, 3),
            FlexibleJoints::uniform(1, 100.0, 0.7, 0.0, 0.0).unwrap(),
        )
        .unwrap();
        let spec = LinearSpec {
            base: BaseMode::Held,
            ..LinearSpec::default()
        };
        let mut ws = arm.workspace();
        let mech = mechanics(&arm, &mut ws, &arm.rest_state(), &spec).unwrap();
        let (i, j) = (mech.mass[(0, 0)], mech.mass[(1, 1)]);
        assert_eq!(j, 0.7);
        let rigid_mass = (mech.rigid.transpose() * &mech.mass * &mech.rigid).cholesky();
        let share = |a: f64, b: f64| {
            let z = DVector::from_vec(vec![Complex::new(a, 0.0), Complex::new(0.0, b)]);
            mech.rigid_share(&z, &rigid_mass)
        };
        assert!((share(1.0, 0.0) - i / (i + j)).abs() < 1e-14);
        let z = DVector::from_vec(vec![Complex::new(2.0, 0.0), Complex::new(2.0, 0.0)]);
        assert!((mech.rigid_share(&z, &rigid_mass) - 1.0).abs() < 1e-14);
        let z = DVector::from_vec(vec![Complex::new(j, 0.0), Complex::new(-i, 0.0)]);
        assert!(mech.rigid_share(&z, &rigid_mass).abs() < 1e-14);
        // no rigid-body modes: no share
        assert_eq!(mech.rigid_share(&z, &None), 0.0);
    }
}
