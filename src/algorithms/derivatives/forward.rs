//! The forward dynamics' derivatives: `∂FD/∂x = −𝓜⁻¹ ∂ID/∂x` at `a = FD`, and `𝓜⁻¹` itself for
//! the inputs (module docs of [`super`]).

// Loops run over body indices `i`, the equations' indices; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use super::*;

/// `∂[α_B; q̈]` with respect to `q`, `ν = [V_B; q̇]`, `τ`, `f_B` and `f`, at the state, torques
/// and loads of [`crate::algorithms::aba`], into `data.derivatives` (`fd_q`, `fd_v`, `fd_tau`,
/// `fd_base_wrench`, `fd_ee_wrench`; the inverse-dynamics derivatives at `a = FD` are left in
/// `id_q`, `id_v`, `id_ee_wrench`). `data.ddq` holds the forward dynamics.
///
/// The first call allocates the O(n²) outputs; later calls reuse them. Derivatives that
/// overflow (inputs too large for floating point) are an error naming the input.
pub fn aba_derivatives<'a>(
    robot: &Robot,
    data: &'a mut Data,
    state: &RigidState,
    tau: &[f64],
    loads: &Loads,
) -> Result<&'a Derivatives> {
    aba_derivatives_into(robot, data, state, tau, loads)?;
    let d = &data.derivatives;
    let base_wrench = loads.base_wrench.to_array();
    // ∂FD/∂τ, ∂FD/∂f_B and ∂FD/∂f are columns of 𝓜⁻¹ and depend on q alone, finite for any
    // finite q: only the blocks that grow with the inputs are scanned
    check_result(
        "forward_dynamics_derivatives",
        &[data.ddq.as_slice(), d.fd_q.as_slice(), d.fd_v.as_slice()],
        &forward_inputs(state, tau, loads, &base_wrench),
    )?;
    Ok(&data.derivatives)
}

/// [`aba_derivatives`] into `data.derivatives`, without looking at whether they overflowed
/// (for callers that check their own, final results).
pub(crate) fn aba_derivatives_into(
    robot: &Robot,
    data: &mut Data,
    state: &RigidState,
    tau: &[f64],
    loads: &Loads,
) -> Result<()> {
    crate::algorithms::aba(robot, data, state, tau, loads)?;
    let n = robot.dof();
    let k = robot.end_effectors().len();
    size_derivatives(data, n, k)?;
    let mut d = std::mem::take(&mut data.derivatives);
    let acc = Motion::from_slice(&data.ddq.as_slice()[..6]);
    let mut qdd = std::mem::take(&mut d.scratch.qdd);
    qdd.copy_from_slice(&data.ddq.as_slice()[6..]);
    id_derivatives(robot, data, &mut d, state, &acc, &qdd, loads.ee_wrench);
    d.scratch.qdd = qdd;
    ee_force_map(robot, &mut d);
    factorisation(robot, data, &mut d.scratch)?;
    // 𝓜⁻¹ on the unit columns; ∂FD/∂f_B, ∂FD/∂τ are its columns
    let m = 6 + n;
    let mut rhs = std::mem::take(&mut d.scratch.rhs);
    rhs.clear();
    rhs.resize(m * m, 0.0);
    for r in 0..m {
        rhs[r * m + r] = 1.0;
    }
    apply_inverse(robot, &mut d.scratch, &mut rhs, m);
    for (r, row) in rhs.chunks_exact(m).enumerate() {
        for (c, value) in row.iter().enumerate() {
            d.scratch.inverse[(r, c)] = *value;
        }
    }
    d.fd_base_wrench.copy_from(&d.scratch.inverse.columns(0, 6));
    d.fd_tau.copy_from(&d.scratch.inverse.columns(6, n));
    // ∂FD/∂x = −𝓜⁻¹ ∂ID/∂x for x = q, ν, f: dense products while they are cheaper, then the
    // factorisation on the columns (O(n) each, so O(n²) in all)
    if n <= DENSE_PRODUCTS_UP_TO {
        let inverse = &d.scratch.inverse;
        minus_product(inverse, &d.id_q, &mut d.fd_q);
        minus_product(inverse, &d.id_v, &mut d.fd_v);
        minus_product(inverse, &d.id_ee_wrench, &mut d.fd_ee_wrench);
    } else {
        let columns = 2 * n + 6 + 6 * k;
        rhs.clear();
        rhs.resize(m * columns, 0.0);
        for (offset, block) in [(0, &d.id_q), (n, &d.id_v), (2 * n + 6, &d.id_ee_wrench)] {
            for (c, column) in block.as_slice().chunks_exact(m).enumerate() {
                for (r, value) in column.iter().enumerate() {
                    rhs[r * columns + offset + c] = -value;
                }
            }
        }
        apply_inverse(robot, &mut d.scratch, &mut rhs, columns);
        for (r, row) in rhs.chunks_exact(columns).enumerate() {
            for k in 0..n {
                d.fd_q[(r, k)] = row[k];
            }
            for j in 0..m {
                d.fd_v[(r, j)] = row[n + j];
            }
            for j in 0..6 * k {
                d.fd_ee_wrench[(r, j)] = row[2 * n + 6 + j];
            }
        }
    }
    d.scratch.rhs = rhs;
    data.derivatives = d;
    Ok(())
}

/// Up to this many joints, `∂FD/∂x = −𝓜⁻¹ ∂ID/∂x` is a dense product with the formed `𝓜⁻¹`
/// (O(n³), small constant); above, the factorisation runs on the columns (O(n²)). Measured
/// crossover (BENCHMARKS.md, "Derivatives").
pub(crate) const DENSE_PRODUCTS_UP_TO: usize = 28;

/// `out = −a b` for a square `a`, column by column.
fn minus_product(a: &DMatrix<f64>, b: &DMatrix<f64>, out: &mut DMatrix<f64>) {
    let m = a.nrows();
    for (b_column, column) in b
        .as_slice()
        .chunks_exact(m)
        .zip(out.as_mut_slice().chunks_exact_mut(m))
    {
        crate::linalg::scaled_product(-1.0, a.as_slice(), m, b_column, column);
    }
}
