//! Directional derivatives of the forward dynamics: `∂FD/∂(q, ν, τ)` applied to many directions
//! without the matrices (the step Jacobians of long arms use them).

// Loops run over body indices `i`, the equations' indices; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use super::*;

/// After [`aba_derivatives`] at a state (same `data`): the forward dynamics' directional
/// derivatives `∂FD/∂q δq + ∂FD/∂ν δν + ∂FD/∂τ δτ` for `columns` directions at once, without the
/// dense matrices: the inverse dynamics' directional derivative (O(n) per direction, from the
/// per-body terms; module docs) then `𝓜⁻¹` by the factorisation (O(n)). All arrays hold one
/// coordinate per row and one direction per column: `dq` n rows, `dnu` 6+n, `dtau` n, `out` 6+n.
pub(crate) fn fd_directional(
    robot: &Robot,
    data: &mut Data,
    dq: &[f64],
    dnu: &[f64],
    dtau: &[f64],
    columns: usize,
    out: &mut [f64],
) {
    let n = robot.dof();
    debug_assert_eq!(out.len(), (6 + n) * columns);
    let s = &mut data.derivatives.scratch;
    // a few dozen directions at a time, so the per-body buffers stay in cache
    let mut tile = std::mem::take(&mut s.tile);
    for start in (0..columns).step_by(DIRECTIONS_PER_TILE) {
        let width = DIRECTIONS_PER_TILE.min(columns - start);
        let gather = |from: &[f64], rows: usize, into: &mut Vec<f64>| {
            into.clear();
            for r in 0..rows {
                into.extend_from_slice(&from[r * columns + start..r * columns + start + width]);
            }
        };
        gather(dq, n, &mut tile.dq);
        gather(dnu, 6 + n, &mut tile.dnu);
        tile.out.clear();
        tile.out.resize((6 + n) * width, 0.0);
        id_directional(robot, s, &tile.dq, &tile.dnu, width, &mut tile.out);
        gather(dtau, n, &mut tile.dq);
        for (o, t) in tile.out[6 * width..].iter_mut().zip(&tile.dq) {
            *o = t - *o;
        }
        tile.out[..6 * width].iter_mut().for_each(|o| *o = -*o);
        apply_inverse(robot, s, &mut tile.out, width);
        for r in 0..6 + n {
            out[r * columns + start..r * columns + start + width]
                .copy_from_slice(&tile.out[r * width..(r + 1) * width]);
        }
    }
    s.tile = tile;
}

/// Directions handled together by [`fd_directional`].
const DIRECTIONS_PER_TILE: usize = 32;

/// [`fd_directional`]'s gathered directions and results for one tile.
#[derive(Debug, Clone, Default)]
pub(super) struct Tile {
    dq: Vec<f64>,
    dnu: Vec<f64>,
    out: Vec<f64>,
}

/// `∂ID/∂q δq + ∂ID/∂ν δν` for `columns` directions (layout of [`fd_directional`]). Row `i` is
/// `α_i · C_i + β_i · U_i + S_i · G_i` with the path sums `C_i = c(δV) + Σ_{k ⪯ i} (c_k δq_k +
/// 2 u_k δq̇_k)`, `U_i = δV + Σ_{k ⪯ i} (u_k δq_k + S_k δq̇_k)` and the strict-subtree sum
/// `G_i = Σ_{k ≻ i} (δF^angle_k δq_k + δF^rate_k δq̇_k)`; the base row is the whole sum `G_B`
/// plus the base twist's own term.
fn id_directional(
    robot: &Robot,
    s: &mut Scratch,
    dq: &[f64],
    dnu: &[f64],
    columns: usize,
    out: &mut [f64],
) {
    let n = robot.dof();
    debug_assert_eq!(out.len(), (6 + n) * columns);
    let parents = robot.parents();
    let size = (n + 1) * columns;
    for buffer in [&mut s.path_c, &mut s.path_u] {
        buffer.resize(size, Motion::zero());
    }
    s.subtree.clear();
    s.subtree.resize(size, Force::zero());
    let v0 = s.v[0];
    for j in 0..columns {
        let twist: [f64; 6] = std::array::from_fn(|k| dnu[k * columns + j]);
        let dv = Motion::from_slice(&twist);
        s.path_c[j] = base_acceleration_change(&v0, &dv);
        s.path_u[j] = dv;
    }
    for i in 1..=n {
        let (lambda, c, u, axis) = (parents[i], s.c[i], s.u[i], s.axis[i]);
        let (angles, rates) = (
            &dq[(i - 1) * columns..i * columns],
            &dnu[(5 + i) * columns..(6 + i) * columns],
        );
        for (j, (&angle, &rate)) in angles.iter().zip(rates).enumerate() {
            s.path_c[i * columns + j] =
                s.path_c[lambda * columns + j] + c * angle + u * (2.0 * rate);
            s.path_u[i * columns + j] = s.path_u[lambda * columns + j] + u * angle + axis * rate;
        }
    }
    for i in (1..=n).rev() {
        let (lambda, alpha, beta, axis) = (parents[i], s.alpha[i], s.beta[i], s.axis[i]);
        let (angle_force, rate_force) = (s.angle_force[i], s.rate_force[i]);
        let (angles, rates) = (
            &dq[(i - 1) * columns..i * columns],
            &dnu[(5 + i) * columns..(6 + i) * columns],
        );
        let row = &mut out[(5 + i) * columns..(6 + i) * columns];
        for (j, ((value, &angle), &rate)) in row.iter_mut().zip(angles).zip(rates).enumerate() {
            let at = i * columns + j;
            let below = s.subtree[at];
            *value = s.path_c[at].dot(&alpha) + beta.dot(&s.path_u[at].angular) + axis.dot(&below);
            s.subtree[lambda * columns + j] += below + angle_force * angle + rate_force * rate;
        }
    }
    let (inertia, t, momentum) = (s.inertia[0], s.t[0], s.momentum[0]);
    for j in 0..columns {
        let base =
            s.subtree[j] + inertia.apply(&s.path_c[j]) + coriolis(&t, &momentum, &s.path_u[j]);
        for (k, value) in base.to_array().into_iter().enumerate() {
            out[k * columns + j] = value;
        }
    }
}
