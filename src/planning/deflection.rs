//! The joint deflection along a planned motion when the joints are damped: `δ = θ − q` obeys
//! `d δ̇ + k δ = τ(t)`, a stable first-order linear ODE driven by the spring torque the links
//! need. Between two samples `τ` is the quintic Hermite interpolant of its value, rate and
//! acceleration at both ends (all exact, from the jet recursion), and the ODE is then solved in
//! closed form over the interval: no time-stepping error, only the interpolation's `O(h⁶)`.
//!
//! Two closed forms cover the two regimes of `λ h` (`λ = k/d`, `h` the interval):
//! - `λ h ≥ 1` (stiff: the spring settles within the interval). The particular solution of a
//!   polynomial forcing `p` is `P = (1/k) Σₘ (−1/λ)ᵐ p⁽ᵐ⁾`, and
//!   `δ(t) = P(t) + (δ_a − P(t_a)) e^{−λ (t − t_a)}`; its rates follow term by term. In the
//!   normalised coefficients the terms are `m! eₘ / (λh)ᵐ`: no subtraction of nearly equal
//!   numbers, and at `λh ≫ 1` they fall fast.
//! - `λ h < 1`. `δ_b = e^{−λh} δ_a + (1/d) ∫₀ʰ e^{−λu} p(t_b − u) du`, the moments
//!   `∫₀ʰ e^{−λu} uᵐ du` by their power series (which converges fast here); then
//!   `δ̇ = (τ − k δ)/d` and `δ̈ = (τ̇ − k δ̇)/d`, well conditioned because `d` is not small.

/// `m!` for `m ≤ 7`.
const FACTORIAL: [f64; 8] = [1.0, 1.0, 2.0, 6.0, 24.0, 120.0, 720.0, 5040.0];

/// The quintic Hermite interpolant on `[0, h]` of `p(0) = a[0]`, `p'(0) = a[1]`, `p''(0) = a[2]`
/// and the same at `h` from `b`, in the normalised form `p(h − y h) = Σₘ eₘ yᵐ`, `y ∈ [0, 1]`
/// (every `eₘ` in the units of `p`; no powers of `h` beyond the second are formed).
fn hermite_from_right(a: &[f64; 3], b: &[f64; 3], h: f64) -> [f64; 6] {
    // e_0..e_2 from the right end, e_3..e_5 from the value, slope and curvature at y = 1
    let (a0, a1, a2) = (a[0], a[1] * h, a[2] * h * h);
    let (e0, e1, e2) = (b[0], -b[1] * h, b[2] * h * h / 2.0);
    let r0 = a0 - e0 - e1 - e2;
    let r1 = -a1 - e1 - 2.0 * e2;
    let r2 = a2 - 2.0 * e2;
    let e5 = (r2 - 6.0 * r1 + 12.0 * r0) / 2.0;
    let e4 = r1 - 3.0 * r0 - 2.0 * e5;
    let e3 = r0 - e4 - e5;
    [e0, e1, e2, e3, e4, e5]
}

/// `Σ_{m ≥ 0} c_{m+shift} (m+shift)! / zᵐ` by Horner's rule in `1/z`.
fn inverse_series(e: &[f64; 6], shift: usize, z: f64) -> f64 {
    (shift..6)
        .rev()
        .fold(0.0, |acc, m| acc / z + FACTORIAL[m] * e[m])
}

/// `δ`, `δ̇`, `δ̈` at the end of an interval of length `h`, from `δ` at its start and the spring
/// torque `τ` (with `τ̇`, `τ̈`) at both ends. `k > 0`, `d > 0`. `δ` and `δ̇` are accurate to
/// round-off; `δ̈` needs `τ⃛` through the interpolant, whose differencing over `h` costs a
/// relative `ε (T/h)²` when `τ` changes over a time `T`: about 1e-9 at `h = 1e-4 T`, the
/// shortest interval the planner uses.
pub(crate) fn advance(
    k: f64,
    d: f64,
    h: f64,
    delta: f64,
    tau_a: &[f64; 3],
    tau_b: &[f64; 3],
) -> [f64; 3] {
    if h <= 0.0 {
        let rate = (tau_b[0] - k * delta) / d;
        return [delta, rate, (tau_b[1] - k * rate) / d];
    }
    let lambda = k / d;
    let z = lambda * h;
    let e = hermite_from_right(tau_a, tau_b, h);
    let decay = (-z).exp();
    if z >= 1.0 {
        // With y = 1 − r/h, hᵐ p⁽ᵐ⁾(h) = (−1)ᵐ m! eₘ and hᵐ p⁽ᵐ⁾(0) = (−1)ᵐ Σ_{j≥m} eⱼ j!/(j−m)!,
        // so the particular solution P = (1/k) Σ (−1/λ)ᵐ p⁽ᵐ⁾ is, at both ends,
        // P(h) = (1/k) Σ m! eₘ / zᵐ, h P'(h) = −(1/k) Σ (m+1)! e_{m+1} / zᵐ, and so on.
        let left = (0..6).rev().fold(0.0, |acc, m| {
            acc / z + (m..6).fold(0.0, |sum, j| sum + e[j] * FACTORIAL[j] / FACTORIAL[j - m])
        }) / k;
        let transient = if decay > 0.0 {
            (delta - left) * decay
        } else {
            0.0
        };
        [
            inverse_series(&e, 0, z) / k + transient,
            -inverse_series(&e, 1, z) / (k * h) - lambda * transient,
            inverse_series(&e, 2, z) / (k * h) / h + lambda * lambda * transient,
        ]
    } else {
        // δ_b = e^{−z} δ_a + (h/d) Σ eₘ μₘ(z), μₘ(z) = ∫₀¹ e^{−z y} yᵐ dy = Σⱼ (−z)ʲ / (j! (m+j+1))
        let moment = |m: usize| {
            let (mut sum, mut term) = (0.0, 1.0);
            for j in 0..60 {
                let add = term / (m + j + 1) as f64;
                sum += add;
                if add.abs() <= 1e-17 * sum.abs() {
                    break;
                }
                term *= -z / (j + 1) as f64;
            }
            sum
        };
        let integral: f64 = (0..6).map(|m| e[m] * moment(m)).sum();
        let value = decay * delta + h / d * integral;
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

    /// All derivatives of a polynomial at `t`.
    fn derivatives(c: &[f64; 6], t: f64) -> [f64; 8] {
        let mut p = c.to_vec();
        std::array::from_fn(|_| {
            let value = p.iter().rev().fold(0.0, |acc, v| acc * t + v);
            p = p
                .iter()
                .enumerate()
                .skip(1)
                .map(|(i, v)| v * i as f64)
                .collect();
            value
        })
    }

    #[test]
    fn rates_are_exact_over_stiff_and_slow_springs_and_short_and_long_intervals() {
        // τ over a unit time scale; exact δ = P + (δ₀ − P(0)) e^{−λt}, P = (1/k) Σ (−1/λ)ᵐ τ⁽ᵐ⁾
        // (a reference that is itself ill-conditioned for d/k ≳ 1: the GL test covers those)
        let c = [0.0, 0.0, 0.0, 30.0, -40.0, 12.0];
        let k = 1e4;
        for ratio in [1e-9, 1e-7, 1e-5, 1e-3, 0.1] {
            let (d, lambda) = (ratio * k, 1.0 / ratio);
            let particular = |t: f64, shift: usize| {
                let p = derivatives(&c, t);
                (0..6)
                    .rev()
                    .fold(0.0, |acc, m| acc * (-1.0 / lambda) + p[m + shift])
                    / k
            };
            for h in [1e-4, 1e-3, 0.05, 0.7] {
                let t0 = 0.3;
                let start = particular(t0, 0);
                let got = advance(k, d, h, start, &jet(&c, t0), &jet(&c, t0 + h));
                let scale = derivatives(&c, t0 + h)[2].abs().max(1.0) / k;
                for (order, value) in got.iter().enumerate() {
                    let want = particular(t0 + h, order)
                        + (start - particular(t0, 0))
                            * (-lambda).powi(order as i32)
                            * (-lambda * h).exp();
                    // differencing τ over h for τ⃛ (which δ̈ needs through P'') costs ε (T/h)²
                    let tolerance = 1e-10 * (1e-3 / h).powi(2).max(1.0);
                    assert!(
                        (value - want).abs() < tolerance * scale,
                        "d/k={ratio} h={h} order {order}: {value} vs {want}"
                    );
                }
            }
        }
        // tiny intervals stay finite
        let tiny = advance(k, 1e-9 * k, 1e-100, 0.0, &[0.0; 3], &jet(&c, 1e-100));
        assert!(tiny.iter().all(|v| v.is_finite()), "{tiny:?}");
    }
}
