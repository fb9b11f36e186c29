//! Jacobians of the flexible arm's state derivative and of one RK4 step, in tangent coordinates
//! (model §4 and §5), from the analytical derivatives of the rigid dynamics.
//!
//! **Continuous time.** Write the state as `x = x̄ ⊕ dx` with the tangent
//! `dx = [δr_B | δφ_B | δq | δθ | δω_B | δv_B | δq̇ | δθ̇]` ([`crate::StateLayout::integrate`]).
//! Along a run, `d(dx)/dt = F dx + G du + G_B df_B + G_E df` to first order, where
//!
//! - `δṙ_B = R_B δv_B − R_B [v_B]× δφ_B` (the base velocity seen in turned axes);
//! - `d(δφ_B)/dt = δω_B − ω_B × δφ_B` (the perturbation is carried in the turning base frame);
//! - `δq̇`, `δθ̇` are the rates' own perturbations;
//! - `[δα_B; δq̈]` comes from [`crate::algorithms::aba_derivatives`] with the spring torque
//!   `τ = k (θ − q) + d (θ̇ − q̇)` chained in, and `δv̇_B` adds `v_B × δω_B − ω_B × δv_B`;
//! - `δθ̈ = (δu − k (δθ − δq) − d (δθ̇ − δq̇) − β δθ̇)/j`.
//!
//! **One step.** RK4 runs on the raw state (the quaternion's four numbers, renormalised at the
//! end), so its Jacobian is the chain rule through the four stages in raw coordinates,
//! `J = I + dt/6 (dk₁ + 2dk₂ + 2dk₃ + dk₄)` with `dk_s = ∂k_s/∂x`, each from its stage's raw
//! Jacobian `K_s` (the stage products are organised as `step_jacobians` describes), then mapped to tangent coordinates at both ends: `A = P(x⁺) J E(x)`, where `E` turns a tangent
//! at `x` into a raw perturbation (`δquat = ½ quat ⊗ (δφ, 0)`) and `P` turns one at `x⁺` back
//! (`δφ = 2 vec(quat⁺* ⊗ δquat)`, which also discards the radial part the renormalisation
//! removes). The inputs are held over the step, so their Jacobians chain the same way.

use super::arm::{FlexibleArm, Inputs, ModelWorkspace};
use crate::algorithms;
use crate::args::RigidState;
use crate::error::{Error, Result};
use crate::spatial::{
    normalise_quaternion, quaternion_product, quaternion_to_rotation, skew, Mat3, Vec3,
};
use nalgebra::{DMatrix, DMatrixViewMut};

/// Jacobians with respect to the state's tangent and to the inputs. Rows: the tangent of the
/// result (`12 + 4n + k_w`, `k_w` reaction wheels); columns: the tangent of the state (`x`), the
/// motor torques (`u`, n), the base wrench (`base_wrench`, 6), the EE wrenches (`ee_wrench`, 6
/// per end-effector) and the wheel torque commands (`wheel_torque`, `k_w`).
#[derive(Debug, Clone, PartialEq)]
pub struct Jacobians {
    /// With respect to the state's tangent, (12+4n)×(12+4n).
    pub x: DMatrix<f64>,
    /// With respect to `u`, (12+4n)×n.
    pub u: DMatrix<f64>,
    /// With respect to `f_B`, (12+4n)×6.
    pub base_wrench: DMatrix<f64>,
    /// With respect to `[f_1; …; f_k]`, (12+4n)×6k.
    pub ee_wrench: DMatrix<f64>,
    /// With respect to the wheel torque commands, (12+4n+k_w)×k_w (no columns without wheels):
    /// the slope of the saturation ([`super::saturated_torque`]) times the applied torque's
    /// effect.
    pub wheel_torque: DMatrix<f64>,
}

impl Jacobians {
    /// The four blocks' numbers.
    pub(crate) fn blocks(&self) -> [&[f64]; 5] {
        [
            self.x.as_slice(),
            self.u.as_slice(),
            self.base_wrench.as_slice(),
            self.ee_wrench.as_slice(),
            self.wheel_torque.as_slice(),
        ]
    }

    fn zeros(rows: usize, state_columns: usize, n: usize, k: usize) -> Self {
        Self {
            x: DMatrix::zeros(rows, state_columns),
            u: DMatrix::zeros(rows, n),
            base_wrench: DMatrix::zeros(rows, 6),
            ee_wrench: DMatrix::zeros(rows, 6 * k),
            wheel_torque: DMatrix::zeros(rows, 0),
        }
    }

    /// [`Jacobians::zeros`], allocated fallibly: `Err(need())` when they do not fit.
    fn try_zeros(
        rows: usize,
        state_columns: usize,
        n: usize,
        k: usize,
        need: &dyn Fn() -> Error,
    ) -> Result<Self> {
        Ok(Self {
            x: try_matrix(rows, state_columns, need)?,
            u: try_matrix(rows, n, need)?,
            base_wrench: try_matrix(rows, 6, need)?,
            ee_wrench: try_matrix(rows, 6 * k, need)?,
            wheel_torque: DMatrix::zeros(rows, 0),
        })
    }
}

/// A zero matrix, allocated fallibly.
fn try_matrix(rows: usize, columns: usize, need: &dyn Fn() -> Error) -> Result<DMatrix<f64>> {
    let mut values = Vec::new();
    grow(
        &mut values,
        rows.checked_mul(columns).ok_or_else(need)?,
        need,
    )?;
    Ok(DMatrix::from_vec(rows, columns, values))
}

/// `buffer` resized to `len` (new numbers zero), allocated fallibly.
fn grow(buffer: &mut Vec<f64>, len: usize, need: &dyn Fn() -> Error) -> Result<()> {
    buffer
        .try_reserve_exact(len.saturating_sub(buffer.len()))
        .map_err(|_| need())?;
    buffer.resize(len, 0.0);
    Ok(())
}

/// [`too_large`] for [`step_jacobians`]: six blocks of `m × c` (the stage's Jacobians, `dk`,
/// the previous `dk`, their sum, the rows of `K` and the result).
fn step_too_large(arm: &FlexibleArm) -> Error {
    let layout = arm.layout();
    let (m, n) = (layout.len(), layout.n);
    let c = m + n + 6 + 6 * arm.robot().end_effectors().len();
    too_large("step_jacobians", n, m, c, 6)
}

/// The error for Jacobians too large for memory: `call`'s `blocks` buffers of `rows × columns`
/// numbers for an arm of `n` joints.
fn too_large(call: &str, n: usize, rows: usize, columns: usize, blocks: usize) -> Error {
    let advice = match blocks {
        1 => "linearise a smaller model".to_string(),
        _ => format!(
            "it keeps {blocks} blocks of that size; linearise a smaller model, or use \
             derivative_jacobians (one block)"
        ),
    };
    Error::OutOfMemory {
        what: call.into(),
        bytes: rows
            .checked_mul(columns)
            .and_then(|size| size.checked_mul(8 * blocks)),
        hint: format!("the Jacobians of a {n}-joint arm are {rows} × {columns} numbers; {advice}"),
    }
}

/// Which coordinates a Jacobian is written in: the tangent (`12 + 4n`, the pose as
/// `[δr; δφ]`) or the raw state (`13 + 4n`, the quaternion's four numbers).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Coordinates {
    Tangent,
    Raw,
}

impl Coordinates {
    /// The size of the pose block (6 or 7); the dynamic blocks follow it.
    fn pose(self) -> usize {
        match self {
            Coordinates::Tangent => 6,
            Coordinates::Raw => 7,
        }
    }

    /// Where the dynamic blocks start, for `n` joints.
    fn blocks(self, n: usize) -> Blocks {
        let pose = self.pose();
        Blocks {
            q: pose,
            theta: pose + n,
            twist: pose + 2 * n,
            qd: pose + 2 * n + 6,
            theta_dot: pose + 3 * n + 6,
        }
    }
}

/// The first index of each dynamic block of a state (or tangent): `q`, `θ`, the base twist,
/// `q̇`, `θ̇`.
struct Blocks {
    q: usize,
    theta: usize,
    twist: usize,
    qd: usize,
    theta_dot: usize,
}

/// The continuous-time Jacobians `F`, `G`, `G_B`, `G_E` of the state derivative at `x` with
/// `inputs`, in tangent coordinates (see the module documentation). `x` and `inputs` must be
/// checked.
pub(crate) fn derivative_jacobians(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    inputs: &Inputs,
) -> Result<Jacobians> {
    let layout = arm.layout();
    let k = arm.robot().end_effectors().len();
    let t = layout.tangent_len();
    let c = t + layout.n + 6 + 6 * k;
    let need = || too_large("derivative_jacobians", layout.n, t, c, 1);
    let mut out = Jacobians::try_zeros(t, t, layout.n, k, &need)?;
    let Some(wheels) = arm.wheels() else {
        jacobians_into(arm, ws, x, inputs, Coordinates::Tangent, &mut out)?;
        return Ok(out);
    };
    // the rigid dynamics on the augmented bus, loaded with the wheels' moment Σ n_w (W2)
    let s = layout.split(x);
    let mut loads = inputs.loads;
    loads.base_wrench.angular += wheels.base_moment(&s.omega(), s.wheel_speed, &ws.wheel_torque);
    let loaded = Inputs { loads, ..*inputs };
    jacobians_into(arm, ws, x, &loaded, Coordinates::Tangent, &mut out)?;
    super::wheels::add_wheel_jacobians(wheels, layout, x, inputs.wheel_torque, &mut out);
    Ok(out)
}

/// The Jacobians of one RK4 step of `dt` from `x` with `inputs` held, in tangent coordinates at
/// `x` (columns) and at the new state `x⁺` (rows), including the quaternion's renormalisation.
/// Returns them with `x⁺`.
///
/// The sensitivities are kept row by row over all `c = m + n + 6 + 6k` parameters (the raw
/// state, `u`, `f_B`, `[f_1; …; f_k]`), so one row of a product is a combination of contiguous rows. With the stage
/// points `x_s = x + h_s k_{s−1}`, `dk₁ = K₁ [𝟙 | 0] + D₁` and
/// `dk_s = K_s ([𝟙 | 0] + h_s dk_{s−1}) + D_s` (`D_s` the direct input terms), so only three
/// products are needed, and in each only the rigid-dynamics rows of `K_s` are dense. Up to
/// [`DENSE_STAGES_UP_TO`] joints those rows multiply as a dense matrix (O(n³), small constant);
/// above, they are applied to each column as the forward dynamics' directional derivative
/// (O(n) per column: [`algorithms::fd_directional`]), so the step's Jacobians cost O(n²).
pub(crate) fn step_jacobians(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    dt: f64,
    inputs: &Inputs,
) -> Result<(Jacobians, Vec<f64>)> {
    let dense = arm.dof() <= DENSE_STAGES_UP_TO;
    step_jacobians_with(arm, ws, x, dt, inputs, dense)
}

/// Up to this many joints the stage products of [`step_jacobians`] are dense; above, they are
/// directional derivatives. Measured crossover (BENCHMARKS.md, "Derivatives").
pub(crate) const DENSE_STAGES_UP_TO: usize = 40;

/// [`step_jacobians`] with the stage products chosen: dense (`true`) or directional.
pub(crate) fn step_jacobians_with(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    dt: f64,
    inputs: &Inputs,
    dense_products: bool,
) -> Result<(Jacobians, Vec<f64>)> {
    let layout = arm.layout();
    let (m, n) = (layout.len(), layout.n);
    // the buffers live in the workspace: fresh megabytes per call would cost page faults
    let mut scratch = std::mem::take(&mut ws.jacobians);
    let k = arm.robot().end_effectors().len();
    // the stage's Jacobians, dk, the previous dk, their sum, the rows of K and the result: six
    // m × c blocks at most, allocated fallibly (a 1500-joint arm needs 2.2 GB)
    let need = || step_too_large(arm);
    if scratch.stage.x.nrows() != m || scratch.stage.ee_wrench.ncols() != 6 * k {
        scratch.stage = Jacobians::zeros(0, 0, 0, 0);
        scratch.stage = Jacobians::try_zeros(m, m, n, k, &need)?;
    }
    let result = stage_chain(arm, ws, x, dt, inputs, dense_products, &mut scratch);
    ws.jacobians = scratch;
    result
}

/// The buffers of [`step_jacobians`], kept in the [`ModelWorkspace`] between calls.
#[derive(Debug, Clone)]
pub(crate) struct StepScratch {
    stage: Jacobians,
    dk: Vec<f64>,
    previous: Vec<f64>,
    total: Vec<f64>,
    k_rows: Vec<f64>,
    sparse: Vec<(usize, usize, f64)>,
    directional: Vec<f64>,
    spring: Vec<f64>,
}

impl Default for StepScratch {
    fn default() -> Self {
        Self {
            stage: Jacobians::zeros(0, 0, 0, 0),
            dk: Vec::new(),
            previous: Vec::new(),
            total: Vec::new(),
            k_rows: Vec::new(),
            sparse: Vec::new(),
            directional: Vec::new(),
            spring: Vec::new(),
        }
    }
}

/// The four stages and the map to tangent coordinates of [`step_jacobians_with`]: the chain
/// rule of the module docs, `dk_s = K_s (𝟙 + h_s dk_{s−1})` with `h_s` the stage's step
/// (`0, dt/2, dt/2, dt`) and `K_s` the raw Jacobian at the stage's state, summed into
/// `J = 𝟙 + dt/6 (dk₁ + 2dk₂ + 2dk₃ + dk₄)`, then `A = P(x⁺) J E(x)` ([`to_tangent`]).
fn stage_chain(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    dt: f64,
    inputs: &Inputs,
    dense_products: bool,
    scratch: &mut StepScratch,
) -> Result<(Jacobians, Vec<f64>)> {
    let need = &|| step_too_large(arm);
    let layout = arm.layout();
    let (m, n) = (layout.len(), layout.n);
    let c = m + n + 6 + 6 * arm.robot().end_effectors().len();
    let StepScratch {
        stage,
        dk,
        previous,
        total,
        k_rows,
        sparse,
        directional,
        spring,
    } = scratch;
    // row-major m × c: this stage's dk_s, the previous one, and J = 𝟙 + dt/6 Σ w_s dk_s
    for buffer in [&mut *dk, &mut *previous, &mut *k_rows] {
        grow(buffer, m * c, need)?;
    }
    total.clear();
    grow(total, m * c, need)?;
    for r in 0..m {
        total[r * c + r] = 1.0;
    }
    let mut xs = x.to_vec();
    let mut k = vec![0.0; m];
    let mut sum = vec![0.0; m];
    // the dense rows: the base twist and q̈, over the columns from q on
    let pose = Coordinates::Raw.pose();
    let blocks = Coordinates::Raw.blocks(n);
    let dense = blocks.twist..blocks.theta_dot;
    let mut h = 0.0;
    for (s, (weight, next)) in [(1.0, 0.5), (2.0, 0.5), (2.0, 1.0), (1.0, 0.0)]
        .into_iter()
        .enumerate()
    {
        // (the stage's forward dynamics is the one the derivatives have just run)
        jacobians_into(arm, ws, &xs, inputs, Coordinates::Raw, stage)?;
        arm.assemble_derivative(&xs, inputs, &ws.tau, ws.data.ddq.as_slice(), &mut k);
        // K_s and D_s, [K_x | K_u | K_B | K_E] (m × c): the dense rows copied into row order
        // (`k_rows`, 6 + n rows), the few non-zeros of the others listed
        sparse.clear();
        for (block, offset) in [
            (&stage.x, 0),
            (&stage.u, m),
            (&stage.base_wrench, m + n),
            (&stage.ee_wrench, m + n + 6),
        ] {
            for (col, column) in block.as_slice().chunks_exact(m).enumerate() {
                let (head, rest) = column.split_at(dense.start);
                let (middle, tail) = rest.split_at(dense.len());
                for (i, &value) in middle.iter().enumerate() {
                    k_rows[i * c + offset + col] = value;
                }
                let others = head.iter().enumerate().chain(
                    tail.iter()
                        .enumerate()
                        .map(|(i, value)| (dense.end + i, value)),
                );
                for (r, &value) in others {
                    if value != 0.0 {
                        sparse.push((r, offset + col, value));
                    }
                }
            }
        }
        std::mem::swap(dk, previous);
        if s > 0 && !dense_products {
            directional_rows(arm, ws, &xs, previous, c, directional, spring)?;
        }
        let dense_rows = dk[dense.start * c..dense.end * c].chunks_exact_mut(c);
        for (i, (row, k_row)) in dense_rows.zip(k_rows.chunks_exact(c)).enumerate() {
            if s > 0 && !dense_products {
                let y = &directional[i * c..(i + 1) * c];
                row.iter_mut().zip(y).for_each(|(o, y)| *o = h * y);
            } else if s > 0 {
                // (the rigid dynamics do not depend on the base pose: zero gravity)
                debug_assert!(k_row[..pose].iter().all(|&w| w == 0.0));
                // the rows of dk_{s−1} from q on, as the columns of a c × (m − pose) matrix
                crate::linalg::scaled_product(h, &previous[pose * c..], c, &k_row[pose..m], row);
            } else {
                row.fill(0.0);
            }
            row.iter_mut().zip(k_row).for_each(|(o, k)| *o += k);
        }
        dk[..dense.start * c].fill(0.0);
        dk[dense.end * c..].fill(0.0);
        for &(r, col, w) in sparse.iter() {
            let row = &mut dk[r * c..(r + 1) * c];
            if s > 0 && col < m {
                let from = &previous[col * c..(col + 1) * c];
                row.iter_mut().zip(from).for_each(|(o, a)| *o += h * w * a);
            }
            row[col] += w;
        }
        let w = dt / 6.0 * weight;
        total
            .iter_mut()
            .zip(dk.iter())
            .for_each(|(t, d)| *t += w * d);
        sum.iter_mut().zip(&k).for_each(|(a, b)| *a += weight * b);
        if s < 3 {
            h = next * dt;
            for (p, (x0, kk)) in xs.iter_mut().zip(x.iter().zip(&k)) {
                *p = x0 + h * kk;
            }
        }
    }
    let mut next: Vec<f64> = x
        .iter()
        .zip(&sum)
        .map(|(x0, s)| x0 + dt / 6.0 * s)
        .collect();
    normalise_quaternion(&mut next[layout.quaternion()]);
    Ok((to_tangent(arm, x, &next, total, k_rows, need)?, next))
}

/// The dense rows of `K_s · dk_{s−1}` (the base twist's rate and `q̈`, `6 + n` rows of `c`) as
/// directional derivatives, one per column of `dk_{s−1}` (`previous`, row-major): the forward
/// dynamics along `(δq, δν)` with the spring torque's change `k (δθ − δq) + d (δθ̇ − δq̇)`, then
/// `v̇_B`'s own terms `v_B × δω_B − ω_B × δv_B`. Needs the stage's [`algorithms::aba_derivatives`]
/// in `ws.data` (as [`jacobians_into`] leaves it).
fn directional_rows(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    xs: &[f64],
    previous: &[f64],
    c: usize,
    out: &mut Vec<f64>,
    spring: &mut Vec<f64>,
) -> Result<()> {
    let need = &|| step_too_large(arm);
    let layout = arm.layout();
    let n = layout.n;
    let Blocks {
        q,
        theta,
        twist,
        qd,
        theta_dot,
    } = Coordinates::Raw.blocks(n);
    let row = |r: usize| &previous[r * c..(r + 1) * c];
    let p = arm.joints();
    spring.clear();
    grow(spring, n * c, need)?;
    for i in 0..n {
        let (k, d) = (p.stiffness[i], p.damping[i]);
        let rows = row(q + i)
            .iter()
            .zip(row(theta + i))
            .zip(row(qd + i).iter().zip(row(theta_dot + i)));
        for (o, ((dq, dtheta), (dqd, dtheta_dot))) in
            spring[i * c..(i + 1) * c].iter_mut().zip(rows)
        {
            *o = k * (dtheta - dq) + d * (dtheta_dot - dqd);
        }
    }
    out.clear();
    grow(out, (6 + n) * c, need)?;
    algorithms::fd_directional(
        arm.robot(),
        &mut ws.data,
        &previous[q * c..(q + n) * c],
        &previous[twist * c..(theta_dot) * c],
        spring,
        c,
        out,
    );
    let s = layout.split(xs);
    let (omega, v) = (s.omega(), s.velocity());
    for j in 0..c {
        let d_omega = Vec3::new(
            previous[twist * c + j],
            previous[(twist + 1) * c + j],
            previous[(twist + 2) * c + j],
        );
        let d_v = Vec3::new(
            previous[(twist + 3) * c + j],
            previous[(twist + 4) * c + j],
            previous[(twist + 5) * c + j],
        );
        let extra = v.cross(&d_omega) - omega.cross(&d_v);
        for r in 0..3 {
            out[(3 + r) * c + j] += extra[r];
        }
    }
    Ok(())
}

/// `A = P(x⁺) J E(x)` for the state columns and `P(x⁺) J` for the inputs, from the raw step
/// Jacobian `J` (row-major, `m × c`); `rows` is scratch. `E(x)` turns a tangent at `x` into a raw perturbation
/// (identity except `δquat = ½ quat ⊗ (δφ, 0)`), `P(x⁺)` a raw perturbation at `x⁺` back into a
/// tangent (identity except `δφ = 2 vec(quat⁺* ⊗ δquat)`).
fn to_tangent(
    arm: &FlexibleArm,
    x: &[f64],
    next: &[f64],
    total: &[f64],
    rows: &mut Vec<f64>,
    need: &dyn Fn() -> Error,
) -> Result<Jacobians> {
    let layout = arm.layout();
    let (m, n, t) = (layout.len(), layout.n, layout.tangent_len());
    let k = arm.robot().end_effectors().len();
    let c = m + n + 6 + 6 * k;
    let quaternion = layout.quaternion();
    // E's rotation block (4 × 3) and P's (3 × 4)
    let from = &x[quaternion.clone()];
    let e: [[f64; 4]; 3] = std::array::from_fn(|axis| {
        let mut unit = [0.0; 4];
        unit[axis] = 1.0;
        quaternion_product(from, &unit).map(|v| 0.5 * v)
    });
    let to = &next[quaternion];
    let conjugate = [-to[0], -to[1], -to[2], to[3]];
    let p: [[f64; 3]; 4] = std::array::from_fn(|r| {
        let mut unit = [0.0; 4];
        unit[r] = 1.0;
        let product = quaternion_product(&conjugate, &unit);
        [2.0 * product[0], 2.0 * product[1], 2.0 * product[2]]
    });
    // the result row by row (row-major, t × (t + n + 6 + 6k)), then into the column-major outputs
    let width = t + n + 6 + 6 * k;
    rows.clear();
    grow(rows, t * width, need)?;
    let mut row = vec![0.0; c];
    for (tr, out_row) in rows.chunks_exact_mut(width).enumerate() {
        match tr {
            0..=2 => row.copy_from_slice(&total[tr * c..(tr + 1) * c]),
            3..=5 => {
                row.fill(0.0);
                for (r, p_r) in p.iter().enumerate() {
                    let raw = &total[(3 + r) * c..(4 + r) * c];
                    row.iter_mut()
                        .zip(raw)
                        .for_each(|(o, a)| *o += p_r[tr - 3] * a);
                }
            }
            _ => row.copy_from_slice(&total[(tr + 1) * c..(tr + 2) * c]),
        }
        for (tc, value) in out_row[..t].iter_mut().enumerate() {
            *value = match tc {
                0..=2 => row[tc],
                3..=5 => (0..4).map(|r| row[3 + r] * e[tc - 3][r]).sum(),
                _ => row[tc + 1],
            };
        }
        out_row[t..].copy_from_slice(&row[m..]);
    }
    let mut out = Jacobians::try_zeros(t, t, n, k, need)?;
    for (block, offset) in [
        (&mut out.x, 0),
        (&mut out.u, t),
        (&mut out.base_wrench, t + n),
        (&mut out.ee_wrench, t + n + 6),
    ] {
        transpose_rows(rows, width, offset, block);
    }
    Ok(out)
}

/// `out[(i, j)] = rows[i * width + offset + j]` for a column-major `out`, eight rows at a time
/// so that the writes of a column share a cache line.
fn transpose_rows(rows: &[f64], width: usize, offset: usize, out: &mut DMatrix<f64>) {
    let (height, columns) = out.shape();
    let out = out.as_mut_slice();
    for start in (0..height).step_by(8) {
        let end = (start + 8).min(height);
        for j in 0..columns {
            for i in start..end {
                out[j * height + i] = rows[i * width + offset + j];
            }
        }
    }
}

/// The state derivative's Jacobians at `x` in `coordinates` into `out` (rows and state columns
/// both in those coordinates): the rows of the module docs' continuous time (model §4), the
/// pose rows, `[δα_B; δq̈]` from [`algorithms::aba_derivatives_into`] with the spring torque
/// chained in, `δv̇_B`'s `v_B × δω_B − ω_B × δv_B`, and
/// `δθ̈ = (δu − k (δθ − δq) − d (δθ̇ − δq̇) − β δθ̇)/j`.
fn jacobians_into(
    arm: &FlexibleArm,
    ws: &mut ModelWorkspace,
    x: &[f64],
    inputs: &Inputs,
    coordinates: Coordinates,
    out: &mut Jacobians,
) -> Result<()> {
    let layout = arm.layout();
    let n = layout.n;
    let s = layout.split(x);
    arm.spring_torque(x, &mut ws.tau);
    let rigid = RigidState::new(s.q, s.base_twist, s.qd);
    algorithms::aba_derivatives_into(
        arm.rigid_model(),
        &mut ws.data,
        &rigid,
        &ws.tau,
        &inputs.loads,
    )?;
    let d = &ws.data.derivatives;
    let p = arm.joints();
    out.x.as_mut_slice().fill(0.0);
    out.u.as_mut_slice().fill(0.0);
    // offsets of the dynamic blocks, the same in rows and columns
    let Blocks {
        q,
        theta,
        twist,
        qd,
        theta_dot,
    } = coordinates.blocks(n);
    let (omega, v) = (s.omega(), s.velocity());
    let rotation = quaternion_to_rotation(s.quaternion);
    let block = |m: &mut DMatrix<f64>, r: usize, c: usize, value: &Mat3| {
        m.fixed_view_mut::<3, 3>(r, c).copy_from(value);
    };
    // pose rows
    block(&mut out.x, 0, twist + 3, &rotation);
    match coordinates {
        Coordinates::Tangent => {
            block(&mut out.x, 0, 3, &(-rotation * skew(&v)));
            block(&mut out.x, 3, 3, &(-skew(&omega)));
            block(&mut out.x, 3, twist, &Mat3::identity());
        }
        Coordinates::Raw => {
            raw_pose_rows(s.quaternion, &omega, &v, &mut out.x, twist);
        }
    }
    for i in 0..n {
        out.x[(q + i, qd + i)] = 1.0;
        out.x[(theta + i, theta_dot + i)] = 1.0;
    }
    // twist and q̈ rows: the rigid dynamics with τ = k (θ − q) + d (θ̇ − q̇) chained in
    for r in 0..6 + n {
        let row = if r < 6 { twist + r } else { qd + r - 6 };
        for i in 0..n {
            let dtau = d.fd_tau[(r, i)];
            out.x[(row, q + i)] = d.fd_q[(r, i)] - dtau * p.stiffness[i];
            out.x[(row, theta + i)] = dtau * p.stiffness[i];
            out.x[(row, qd + i)] = d.fd_v[(r, 6 + i)] - dtau * p.damping[i];
            out.x[(row, theta_dot + i)] = dtau * p.damping[i];
        }
        for j in 0..6 {
            out.x[(row, twist + j)] = d.fd_v[(r, j)];
            out.base_wrench[(row, j)] = d.fd_base_wrench[(r, j)];
        }
        for j in 0..d.fd_ee_wrench.ncols() {
            out.ee_wrench[(row, j)] = d.fd_ee_wrench[(r, j)];
        }
    }
    // v̇_B = α_B[3:6] − ω_B × v_B
    add_block(&mut out.x.view_mut((twist + 3, twist), (3, 3)), &skew(&v));
    add_block(
        &mut out.x.view_mut((twist + 3, twist + 3), (3, 3)),
        &(-skew(&omega)),
    );
    // θ̈ = (u − τ − β θ̇)/j
    for i in 0..n {
        let (k, damping, j, beta) = (
            p.stiffness[i],
            p.damping[i],
            p.motor_inertia[i],
            p.motor_damping[i],
        );
        let row = theta_dot + i;
        out.x[(row, q + i)] = k / j;
        out.x[(row, theta + i)] = -k / j;
        out.x[(row, qd + i)] = damping / j;
        out.x[(row, theta_dot + i)] = -(damping + beta) / j;
        out.u[(row, i)] = 1.0 / j;
    }
    Ok(())
}

fn add_block(view: &mut DMatrixViewMut<'_, f64>, value: &Mat3) {
    for r in 0..3 {
        for c in 0..3 {
            view[(r, c)] += value[(r, c)];
        }
    }
}

/// The raw pose rows: `ṙ_B = R(q̂) v_B` with `q̂ = quat/|quat|` (the rotation a raw, possibly
/// unnormalised, stage quaternion stands for) and `quat' = ½ quat ⊗ (ω_B, 0)`.
fn raw_pose_rows(quat: &[f64], omega: &Vec3, v: &Vec3, out: &mut DMatrix<f64>, twist: usize) {
    let norm = quat.iter().map(|a| a * a).sum::<f64>().sqrt();
    let unit = [
        quat[0] / norm,
        quat[1] / norm,
        quat[2] / norm,
        quat[3] / norm,
    ];
    let (u, w) = (Vec3::new(unit[0], unit[1], unit[2]), unit[3]);
    // R v = v + 2w (u × v) + 2 u × (u × v) on the unit sphere, differentiated in (u, w)
    let d_du = -2.0 * w * skew(v) + 2.0 * (u * v.transpose() + Mat3::identity() * u.dot(v))
        - 4.0 * v * u.transpose();
    let d_dw = 2.0 * u.cross(v);
    // q̂ = quat/|quat|: ∂q̂/∂quat = (𝟙 − q̂ q̂ᵀ)/|quat|
    for c in 0..4 {
        let mut dunit = [0.0; 4];
        for (r, value) in dunit.iter_mut().enumerate() {
            *value = (f64::from(u8::from(r == c)) - unit[r] * unit[c]) / norm;
        }
        let column = d_du * Vec3::new(dunit[0], dunit[1], dunit[2]) + d_dw * dunit[3];
        for r in 0..3 {
            out[(r, 3 + c)] = column[r];
        }
    }
    // quat' = ½ quat ⊗ (ω, 0): linear in quat and in ω
    let pure = [omega.x, omega.y, omega.z, 0.0];
    for c in 0..4 {
        let mut unit_c = [0.0; 4];
        unit_c[c] = 1.0;
        let column = quaternion_product(&unit_c, &pure);
        for r in 0..4 {
            out[(3 + r, 3 + c)] = 0.5 * column[r];
        }
    }
    for axis in 0..3 {
        let mut e = [0.0; 4];
        e[axis] = 1.0;
        let column = quaternion_product(quat, &e);
        for r in 0..4 {
            out[(3 + r, twist + axis)] = 0.5 * column[r];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{
        random_chain, random_joints, random_tree, Rng, TREE_ONE_TRUNK, TREE_THREE_ARMS,
    };
    use crate::{Loads, Robot, StateSpec};

    /// The directional stage products equal the dense ones to round-off, on a chain and on a
    /// branched tree, with every input and damping term non-zero.
    #[test]
    fn directional_stage_products_equal_dense_ones() {
        for (robot, seed) in [
            (random_chain(7, 3), 3),
            (random_tree(TREE_ONE_TRUNK, 4), 4),
            (random_tree(TREE_THREE_ARMS, 5), 5),
        ] {
            let robot: Robot = robot;
            let n = robot.dof();
            let mut rng = Rng::new(seed + 100);
            let arm = FlexibleArm::new(robot, random_joints(n, seed)).unwrap();
            let q = rng.vector(n, -1.0, 1.0);
            let (theta, qd, td) = (
                rng.vector(n, -1.0, 1.0),
                rng.vector(n, -0.5, 0.5),
                rng.vector(n, -0.5, 0.5),
            );
            let (twist, pose) = (
                rng.vector(6, -0.3, 0.3),
                [0.1, 0.2, 0.3, 0.2, -0.4, 0.3, 0.8],
            );
            let mut x = arm
                .state(&StateSpec {
                    q: Some(&q),
                    theta: Some(&theta),
                    qd: Some(&qd),
                    theta_dot: Some(&td),
                    base_pose: Some(&pose),
                    base_twist: Some(&twist),
                })
                .unwrap();
            normalise_quaternion(&mut x[arm.layout().quaternion()]);
            let (u, fb, f) = (
                rng.vector(n, -3.0, 3.0),
                rng.vector(6, -3.0, 3.0),
                rng.vector(6, -3.0, 3.0),
            );
            let inputs = Inputs {
                u: &u,
                loads: Loads::from_slices(Some(&fb), Some(&f)).unwrap(),
                wheel_torque: &[],
            };
            let mut ws = ModelWorkspace::new(&arm);
            let (dense, _) = step_jacobians_with(&arm, &mut ws, &x, 2e-3, &inputs, true).unwrap();
            let (directional, _) =
                step_jacobians_with(&arm, &mut ws, &x, 2e-3, &inputs, false).unwrap();
            for (a, b) in [
                (&dense.x, &directional.x),
                (&dense.u, &directional.u),
                (&dense.base_wrench, &directional.base_wrench),
                (&dense.ee_wrench, &directional.ee_wrench),
            ] {
                let scale = a.amax().max(1.0);
                assert!((a - b).amax() < 1e-13 * scale, "{}", (a - b).amax() / scale);
            }
        }
    }
}
