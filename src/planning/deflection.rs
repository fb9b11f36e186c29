//! The joint deflection along a planned motion when the joints are damped: `δ = θ − q` obeys
//! `d δ̇ + k δ = τ(t)`, a stable first-order linear ODE driven by the spring torque the links
//! need. Between two samples `τ` is the quintic Hermite interpolant of its value, rate and
//! acceleration at both ends (all exact, from the jet recursion), and the ODE is then solved in
//! closed form over the interval: no time-stepping error, only the interpolation's `O(h⁶)`.
//!
//! Two closed forms cover the two regimes of `λ h` (`λ = k/d`, `h` the interval):
//! - `λ h ≥ 1` (stiff: the spring settles within the interval). The particular solution of a
//!   polynomial forcing `p` is `P = (1/k) Σₘ (−1/λ)ᵐ p⁽ᵐ⁾`, and
//!   `δ(t) = P(t) + (δ_a − P(t_a)) e^{−λ (t − t_a)}`; its rates follow term by term. No
//!   cancellation: every term is smaller than the one before.
//! - `λ h < 1`. `δ_b = e^{−λh} δ_a + (1/d) ∫₀ʰ e^{−λu} p(t_b − u) du`, the moments
//!   `∫₀ʰ e^{−λu} uᵐ du` by their power series (which converges fast here); then
//!   `δ̇ = (τ − k δ)/d` and `δ̈ = (τ̇ − k δ̇)/d`, well conditioned because `d` is not small.

/// The quintic Hermite interpolant on `[0, h]` of `p(0) = a[0]`, `p'(0) = a[1]`, `p''(0) = a[2]`
/// and the same at `h` from `b`, as `p(h − u) = Σₘ cₘ uᵐ` (its Taylor coefficients at the right
/// end).
fn hermite_from_right(a: &[f64; 3], b: &[f64; 3], h: f64) -> [f64; 6] {
    // In x = r/h, P(1 − y) = Σ e_m y^m; e_0..e_2 from the right end, e_3..e_5 from the left.
    let (a0, a1, a2) = (a[0], a[1] * h, a[2] * h * h);
    let (e0, e1, e2) = (b[0], -b[1] * h, b[2] * h * h / 2.0);
    let r0 = a0 - e0 - e1 - e2;
    let r1 = -a1 - e1 - 2.0 * e2;
    let r2 = a2 - 2.0 * e2;
    let e5 = (r2 - 6.0 * r1 + 12.0 * r0) / 2.0;
    let e4 = r1 - 3.0 * r0 - 2.0 * e5;
    let e3 = r0 - e4 - e5;
    let e = [e0, e1, e2, e3, e4, e5];
    std::array::from_fn(|m| e[m] / h.powi(m as i32))
}

/// `δ`, `δ̇`, `δ̈` at the end of an interval of length `h`, from `δ` at its start and the spring
/// torque `τ` (with `τ̇`, `τ̈`) at both ends. `k > 0`, `d > 0`.
pub(crate) fn advance(
    k: f64,
    d: f64,
    h: f64,
    delta: f64,
    tau_a: &[f64; 3],
    tau_b: &[f64; 3],
) -> [f64; 3] {
    let lambda = k / d;
    if h <= 0.0 {
        let rate = (tau_b[0] - k * delta) / d;
        return [delta, rate, (tau_b[1] - k * rate) / d];
    }
    let c = hermite_from_right(tau_a, tau_b, h);
    let decay = (-lambda * h).exp();
    if lambda * h >= 1.0 {
        // p^(m)(h) = (−1)^m m! c_m;  p^(m)(0) = Σ_{j≥m} c_j (j!/(j−m)!) h^(j−m)
        let factorial = [1.0, 1.0, 2.0, 6.0, 24.0, 120.0];
        let right: [f64; 8] = std::array::from_fn(|m| {
            if m < 6 {
                (if m % 2 == 0 { 1.0 } else { -1.0 }) * factorial[m] * c[m]
            } else {
                0.0
            }
        });
        let left0 = c
            .iter()
            .enumerate()
            .fold(0.0, |acc, (j, cj)| acc + cj * h.powi(j as i32));
        let left: [f64; 6] = std::array::from_fn(|m| {
            if m == 0 {
                return left0;
            }
            // the derivative in r = h − u flips the sign of odd orders
            let sign = if m % 2 == 0 { 1.0 } else { -1.0 };
            sign * (m..6).fold(0.0, |acc, j| {
                acc + c[j] * factorial[j] / factorial[j - m] * h.powi((j - m) as i32)
            })
        });
        let particular = |p: &[f64], shift: usize| {
            (0..6).rev().fold(0.0, |acc, m| {
                acc * (-1.0 / lambda) + p.get(m + shift).copied().unwrap_or(0.0)
            }) / k
        };
        let transient = (delta - particular(&left, 0)) * decay;
        [
            particular(&right, 0) + transient,
            particular(&right, 1) - lambda * transient,
            particular(&right, 2) + lambda * lambda * transient,
        ]
    } else {
        // G_m = ∫₀ʰ e^{−λu} u^m du = h^{m+1} Σ_j (−λh)^j / (j! (m + j + 1))
        let z = -lambda * h;
        let moment = |m: usize| {
            let (mut sum, mut term, mut j) = (0.0, 1.0, 0usize);
            while j < 60 {
                let add = term / (m + j + 1) as f64;
                sum += add;
                if add.abs() <= 1e-17 * sum.abs() {
                    break;
                }
                j += 1;
                term *= z / j as f64;
            }
            sum * h.powi(m as i32 + 1)
        };
        let integral: f64 = (0..6).map(|m| c[m] * moment(m)).sum();
        let value = decay * delta + integral / d;
        let rate = (tau_b[0] - k * value) / d;
        [value, rate, (tau_b[1] - k * rate) / d]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `τ(t)` a polynomial of degree 5 (so the Hermite interpolant is exact), `δ(0) = δ₀`: the
    /// exact solution of `d δ̇ + k δ = τ` by a fine reference integration of the closed form
    /// `δ(t) = e^{−λt} δ₀ + (1/d) ∫₀ᵗ e^{−λ(t−s)} τ(s) ds` with composite Gauss–Legendre.
    fn reference(k: f64, d: f64, c: &[f64; 6], delta0: f64, t: f64) -> f64 {
        let lambda = k / d;
        let tau = |s: f64| c.iter().rev().fold(0.0, |acc, v| acc * s + v);
        let (nodes, weights) = (
            [
                -0.906_179_845_938_664,
                -0.538_469_310_105_683,
                0.0,
                0.538_469_310_105_683,
                0.906_179_845_938_664,
            ],
            [
                0.236_926_885_056_189,
                0.478_628_670_499_366,
                0.568_888_888_888_889,
                0.478_628_670_499_366,
                0.236_926_885_056_189,
            ],
        );
        let pieces = 4000;
        let width = t / pieces as f64;
        let mut integral = 0.0;
        for p in 0..pieces {
            let mid = (p as f64 + 0.5) * width;
            for (x, w) in nodes.iter().zip(weights) {
                let s = mid + x * width / 2.0;
                integral += w * width / 2.0 * (-lambda * (t - s)).exp() * tau(s);
            }
        }
        (-lambda * t).exp() * delta0 + integral / d
    }

    fn jet(c: &[f64; 6], t: f64) -> [f64; 3] {
        let d1: Vec<f64> = (1..6).map(|i| c[i] * i as f64).collect();
        let d2: Vec<f64> = (1..5).map(|i| d1[i] * i as f64).collect();
        let eval = |p: &[f64]| p.iter().rev().fold(0.0, |acc, v| acc * t + v);
        [eval(c), eval(&d1), eval(&d2)]
    }

    #[test]
    fn both_regimes_solve_the_deflection_equation_exactly_for_quintic_torques() {
        let c = [0.3, -1.0, 2.0, 0.5, -0.7, 0.2];
        // (k, d, h): stiff, borderline and slow springs
        for (k, d, h) in [
            (2e4, 0.2, 0.01),
            (100.0, 10.0, 0.09),
            (100.0, 10.0, 0.11),
            (50.0, 40.0, 0.3),
        ] {
            let delta0 = 0.01;
            let got = advance(k, d, h, delta0, &jet(&c, 0.0), &jet(&c, h));
            let want = reference(k, d, &c, delta0, h);
            assert!(
                (got[0] - want).abs() < 1e-12 * (1.0 + want.abs()),
                "k={k} d={d} h={h}: {} vs {want}",
                got[0]
            );
            // the rates satisfy the ODE and its derivative
            let tau = jet(&c, h);
            assert!((d * got[1] + k * got[0] - tau[0]).abs() < 1e-9 * tau[0].abs().max(1.0));
            assert!((d * got[2] + k * got[1] - tau[1]).abs() < 1e-9 * tau[1].abs().max(1.0));
        }
    }
}
