//! Time-Taylor ("jet") arithmetic: a quantity along a motion is carried as its value and its
//! first three time derivatives, `[x, ẋ, ẍ, x⃛]`, and products follow the Leibniz rule
//! `(a b)⁽ᵏ⁾ = Σᵢ C(k, i) a⁽ⁱ⁾ b⁽ᵏ⁻ⁱ⁾`. Running the Newton–Euler recursion on jets gives the exact
//! time derivatives of the joint torques, which the flexible-joint inverse dynamics needs
//! (`θ = q + τ/k` needs `τ̇` and `τ̈`), with no finite differences in time.
//!
//! A joint's rotation turns with its angle: `R_{i,λ}(t) = E(q_i(t)) R_{i,λ}(0)` with
//! `E(q) = Rot(h, q)ᵀ` and `dE/dq = −[h]× E`, so by Faà di Bruno
//! `Ė = −[h]× E q̇`, `Ë = [h]×² E q̇² − [h]× E q̈`, `E⃛ = −[h]×³ E q̇³ + 3 [h]×² E q̇ q̈ − [h]× E q⃛`.

use crate::spatial::{rotation_about_axis, skew, Mat3, Vec3};
use nalgebra::{Matrix6, Vector6};
use std::ops::{Add, Mul};

/// Number of Taylor terms carried: the value and three derivatives.
pub const TERMS: usize = 4;

/// Binomial coefficients `C(k, i)` for the Leibniz rule.
const BINOMIAL: [[f64; TERMS]; TERMS] = [
    [1.0, 0.0, 0.0, 0.0],
    [1.0, 1.0, 0.0, 0.0],
    [1.0, 2.0, 1.0, 0.0],
    [1.0, 3.0, 3.0, 1.0],
];

/// A function of time by its value and first three derivatives.
pub type Jet<T> = [T; TERMS];

/// The jet of `f(a(t), b(t))` for a bilinear `f`, by the Leibniz rule.
#[inline]
pub fn leibniz<A, B, C>(a: &Jet<A>, b: &Jet<B>, f: impl Fn(&A, &B) -> C) -> Jet<C>
where
    C: Add<Output = C> + Mul<f64, Output = C>,
{
    std::array::from_fn(|k| {
        (1..=k).fold(f(&a[0], &b[k]), |acc, i| {
            acc + f(&a[i], &b[k - i]) * BINOMIAL[k][i]
        })
    })
}

/// The jet of `ẋ`, one order shorter: `[ẋ, ẍ, x⃛, 0]` (the last term is not known).
#[inline]
pub fn derivative<T: Copy + Default>(x: &Jet<T>) -> Jet<T> {
    [x[1], x[2], x[3], T::default()]
}

/// `R(t) = Rot(h, q(t))ᵀ R₀` for a unit axis `h` and the angle's jet `q` (module docs).
pub fn joint_rotation(axis: &Vec3, q: &Jet<f64>, r0: &Mat3) -> Jet<Mat3> {
    let e = rotation_about_axis(axis, q[0]).tr_mul(r0);
    let k = skew(axis);
    let ke = k * e;
    let kke = k * ke;
    let kkke = k * kke;
    let (qd, qdd, qddd) = (q[1], q[2], q[3]);
    [
        e,
        -ke * qd,
        kke * (qd * qd) - ke * qdd,
        -kkke * (qd * qd * qd) + kke * (3.0 * qd * qdd) - ke * qddd,
    ]
}

/// The jet of `x(t)` solving `A(t) x(t) = b(t)` for 6×6 `A`: `A x⁽ᵏ⁾ = b⁽ᵏ⁾ − Σ_{i≥1} C(k, i)
/// A⁽ⁱ⁾ x⁽ᵏ⁻ⁱ⁾`, one Cholesky factorisation for all orders. `None` unless `A` is symmetric
/// positive definite (as a composite inertia is).
pub fn solve6(a: &Jet<Matrix6<f64>>, b: &Jet<Vector6<f64>>) -> Option<Jet<Vector6<f64>>> {
    let factor = a[0].cholesky()?;
    let mut x = [Vector6::zeros(); TERMS];
    for k in 0..TERMS {
        let mut rhs = b[k];
        for i in 1..=k {
            rhs -= a[i] * x[k - i] * BINOMIAL[k][i];
        }
        x[k] = factor.solve(&rhs);
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A polynomial's value and first three derivatives at `t` (coefficients lowest first).
    fn poly(c: &[f64], t: f64) -> Jet<f64> {
        std::array::from_fn(|k| {
            c.iter()
                .enumerate()
                .skip(k)
                .map(|(i, v)| {
                    let falling: f64 = (0..k).map(|j| (i - j) as f64).product();
                    v * falling * t.powi((i - k) as i32)
                })
                .sum()
        })
    }

    #[test]
    fn the_leibniz_rule_differentiates_products_of_polynomials() {
        let (ca, cb) = ([1.0, -2.0, 0.5, 0.3], [0.2, 1.0, -1.0, 0.0, 0.4]);
        let mut c = [0.0; 8];
        for (i, x) in ca.iter().enumerate() {
            for (j, y) in cb.iter().enumerate() {
                c[i + j] += x * y;
            }
        }
        let t = 0.7;
        let got = leibniz(&poly(&ca, t), &poly(&cb, t), |a, b| a * b);
        let want = poly(&c, t);
        for k in 0..TERMS {
            assert!(
                (got[k] - want[k]).abs() < 1e-12 * (1.0 + want[k].abs()),
                "{k}"
            );
        }
        assert_eq!(derivative(&want), [want[1], want[2], want[3], 0.0]);
    }

    #[test]
    fn joint_rotation_jets_match_central_differences_in_time() {
        let axis = Vec3::new(1.0, 2.0, -1.0).normalize();
        let r0 = rotation_about_axis(&Vec3::z(), 0.4);
        let coeffs = [0.3, 1.1, -0.7, 0.5, 0.2];
        let x = Vec3::new(0.4, -0.2, 0.9);
        let at = |t: f64| rotation_about_axis(&axis, poly(&coeffs, t)[0]).tr_mul(&r0) * x;
        let t = 0.6;
        let jet = joint_rotation(&axis, &poly(&coeffs, t), &r0);
        assert!((jet[0] * x - at(t)).norm() < 1e-15);
        let h = 1e-3;
        let first = (at(t + h) - at(t - h)) / (2.0 * h);
        let second = (at(t + h) - 2.0 * at(t) + at(t - h)) / (h * h);
        let third = (at(t + 2.0 * h) - 2.0 * at(t + h) + 2.0 * at(t - h) - at(t - 2.0 * h))
            / (2.0 * h.powi(3));
        // central differences err by O(h²) times the next derivatives (about 10 here)
        assert!(
            (jet[1] * x - first).norm() < 2e-5,
            "{}",
            (jet[1] * x - first).norm()
        );
        assert!(
            (jet[2] * x - second).norm() < 2e-5,
            "{}",
            (jet[2] * x - second).norm()
        );
        assert!(
            (jet[3] * x - third).norm() < 1e-4,
            "{}",
            (jet[3] * x - third).norm()
        );
    }

    #[test]
    fn solve6_differentiates_the_solution_of_a_moving_system() {
        // A(t) = A0 + t A1 (symmetric positive definite near t = 0), b(t) = b0 + t b1 + t² b2
        let a0 = Matrix6::from_fn(|i, j| {
            if i == j {
                4.0 + i as f64
            } else {
                0.3 / (1.0 + (i + j) as f64)
            }
        });
        let a1 = Matrix6::from_fn(|i, j| 0.1 * ((i * j) as f64).sin());
        let a1 = a1 + a1.transpose();
        let (b0, b1, b2) = (
            Vector6::from_fn(|i, _| i as f64 - 2.0),
            Vector6::from_fn(|i, _| (i as f64).cos()),
            Vector6::from_fn(|i, _| 0.5 * i as f64),
        );
        let x = |t: f64| {
            (a0 + a1 * t)
                .lu()
                .solve(&(b0 + b1 * t + b2 * t * t))
                .unwrap()
        };
        let a = [a0, a1, Matrix6::zeros(), Matrix6::zeros()];
        let b = [b0, b1, b2 * 2.0, Vector6::zeros()];
        let jet = solve6(&a, &b).unwrap();
        let h = 1e-3;
        assert!((jet[0] - x(0.0)).norm() < 1e-14);
        assert!((jet[1] - (x(h) - x(-h)) / (2.0 * h)).norm() < 1e-6);
        assert!((jet[2] - (x(h) - 2.0 * x(0.0) + x(-h)) / (h * h)).norm() < 1e-5);
        let third = (x(2.0 * h) - 2.0 * x(h) + 2.0 * x(-h) - x(-2.0 * h)) / (2.0 * h.powi(3));
        assert!((jet[3] - third).norm() < 1e-4);
        assert!(solve6(&[Matrix6::zeros(); 4], &b).is_none());
    }
}
