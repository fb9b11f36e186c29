//! The articulated-body inertia of the ABA: a symmetric 6×6 kept as 3×3 blocks, with the
//! operations the recursion needs in closed form.

use super::{skew, Force, Inertia, Mat3, Mat6, Motion, Transform, Vec3};
use std::ops::{Add, AddAssign};

/// A symmetric 3×3 matrix, stored as its upper triangle (six numbers).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Symmetric3 {
    /// Entry (0, 0).
    pub xx: f64,
    /// Entries (0, 1) and (1, 0).
    pub xy: f64,
    /// Entries (0, 2) and (2, 0).
    pub xz: f64,
    /// Entry (1, 1).
    pub yy: f64,
    /// Entries (1, 2) and (2, 1).
    pub yz: f64,
    /// Entry (2, 2).
    pub zz: f64,
}

impl Symmetric3 {
    /// The zero matrix.
    #[inline]
    pub fn zero() -> Self {
        Self::default()
    }

    /// `s 𝟙`.
    #[inline]
    pub fn scaled_identity(s: f64) -> Self {
        Self {
            xx: s,
            yy: s,
            zz: s,
            ..Self::default()
        }
    }

    /// The upper triangle of `m` (`m` is taken to be symmetric).
    #[inline]
    pub fn from_upper(m: &Mat3) -> Self {
        Self {
            xx: m[(0, 0)],
            xy: m[(0, 1)],
            xz: m[(0, 2)],
            yy: m[(1, 1)],
            yz: m[(1, 2)],
            zz: m[(2, 2)],
        }
    }

    /// Dense form.
    pub fn matrix(&self) -> Mat3 {
        Mat3::new(
            self.xx, self.xy, self.xz, self.xy, self.yy, self.yz, self.xz, self.yz, self.zz,
        )
    }

    /// `S v`.
    #[inline]
    pub fn mul_vec(&self, v: &Vec3) -> Vec3 {
        Vec3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }

    /// `S − s a aᵀ`.
    #[inline]
    pub fn minus_outer(&self, a: &Vec3, s: f64) -> Self {
        let sa = a * s;
        Self {
            xx: self.xx - sa.x * a.x,
            xy: self.xy - sa.x * a.y,
            xz: self.xz - sa.x * a.z,
            yy: self.yy - sa.y * a.y,
            yz: self.yz - sa.y * a.z,
            zz: self.zz - sa.z * a.z,
        }
    }

    /// `Rᵀ S R`: entry `(i, j)` is `r_i · (S r_j)` for the columns `r_i` of `R`.
    #[inline]
    pub fn rotated_by_transpose(&self, r: &Mat3) -> Self {
        let (r0, r1, r2) = columns(r);
        let (s0, s1, s2) = (self.mul_vec(&r0), self.mul_vec(&r1), self.mul_vec(&r2));
        Self {
            xx: r0.dot(&s0),
            xy: r0.dot(&s1),
            xz: r0.dot(&s2),
            yy: r1.dot(&s1),
            yz: r1.dot(&s2),
            zz: r2.dot(&s2),
        }
    }
}

impl Symmetric3 {
    /// `R S Rᵀ` for the turn `R = [[c, −s, 0], [s, c, 0], [0, 0, 1]]` about `e_z` (`c² + s² = 1`):
    /// the `xy` block by the double angle, `t = h cos 2θ − S_xy sin 2θ` with `m`, `h` the half
    /// sum and half difference of `S_xx`, `S_yy`.
    #[inline(always)]
    pub fn turned_about_z(&self, c: f64, s: f64) -> Self {
        let (c2, s2) = (c * c - s * s, 2.0 * c * s);
        let (m, h) = (0.5 * (self.xx + self.yy), 0.5 * (self.xx - self.yy));
        let t = h * c2 - self.xy * s2;
        Self {
            xx: m + t,
            xy: h * s2 + self.xy * c2,
            xz: c * self.xz - s * self.yz,
            yy: m - t,
            yz: s * self.xz + c * self.yz,
            zz: self.zz,
        }
    }

    /// `R S Rᵀ` for the turn `R = [[1, 0, 0], [0, c, −s], [0, s, c]]` about `e_x`, as
    /// [`turned_about_z`](Self::turned_about_z) in the `yz` plane.
    #[inline(always)]
    pub fn turned_about_x(&self, c: f64, s: f64) -> Self {
        let (c2, s2) = (c * c - s * s, 2.0 * c * s);
        let (m, h) = (0.5 * (self.yy + self.zz), 0.5 * (self.yy - self.zz));
        let t = h * c2 - self.yz * s2;
        Self {
            xx: self.xx,
            xy: c * self.xy - s * self.xz,
            xz: s * self.xy + c * self.xz,
            yy: m + t,
            yz: h * s2 + self.yz * c2,
            zz: m - t,
        }
    }
}

impl Symmetric3 {
    /// `L` of the Cholesky factorisation `S = L Lᵀ` (lower triangle, row by row:
    /// `[l00, l10, l11, l20, l21, l22]`), or `None` unless `S` is positive definite.
    #[inline]
    fn cholesky(&self) -> Option<[f64; 6]> {
        let l00 = self.xx.sqrt();
        let l10 = self.xy / l00;
        let l20 = self.xz / l00;
        let d1 = self.yy - l10 * l10;
        let l11 = d1.sqrt();
        let l21 = (self.yz - l20 * l10) / l11;
        let d2 = self.zz - l20 * l20 - l21 * l21;
        let l22 = d2.sqrt();
        // `x > 0` is false for NaN: a non-positive or non-finite pivot fails here.
        (self.xx > 0.0 && d1 > 0.0 && d2 > 0.0 && l22.is_finite())
            .then_some([l00, l10, l11, l20, l21, l22])
    }
}

/// Solves `L Lᵀ x = b` for the factor of [`Symmetric3::cholesky`].
#[inline]
fn cholesky_solve(l: &[f64; 6], b: &Vec3) -> Vec3 {
    let [l00, l10, l11, l20, l21, l22] = *l;
    let y0 = b.x / l00;
    let y1 = (b.y - l10 * y0) / l11;
    let y2 = (b.z - l20 * y0 - l21 * y1) / l22;
    let x2 = y2 / l22;
    let x1 = (y1 - l21 * x2) / l11;
    let x0 = (y0 - l10 * x1 - l20 * x2) / l00;
    Vec3::new(x0, x1, x2)
}

/// The factors of `I^A = [[A, B], [Bᵀ, C]]` for solves: the Cholesky factors of `C` and of the
/// Schur complement `A − B C⁻¹ Bᵀ`, `B`, and `W = C⁻¹ Bᵀ`.
#[derive(Debug, Clone, Copy)]
struct BlockFactor {
    linear: [f64; 6],
    schur: [f64; 6],
    coupling: Mat3,
    w: Mat3,
}

impl BlockFactor {
    /// `α_ω = S⁻¹ (f_n − B C⁻¹ f_F)`, `α_v = C⁻¹ f_F − W α_ω`.
    #[inline(always)]
    fn solve(&self, f: &Force) -> Motion {
        let y = cholesky_solve(&self.linear, &f.linear);
        let angular = cholesky_solve(&self.schur, &(f.angular - self.coupling * y));
        Motion::new(angular, y - self.w * angular)
    }
}

impl Add for Symmetric3 {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self {
            xx: self.xx + o.xx,
            xy: self.xy + o.xy,
            xz: self.xz + o.xz,
            yy: self.yy + o.yy,
            yz: self.yz + o.yz,
            zz: self.zz + o.zz,
        }
    }
}

impl AddAssign for Symmetric3 {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

#[inline]
fn columns(m: &Mat3) -> (Vec3, Vec3, Vec3) {
    (
        m.column(0).into_owned(),
        m.column(1).into_owned(),
        m.column(2).into_owned(),
    )
}

/// An articulated-body inertia `I^A` (Featherstone's ABA, in the paper's `[ω; v]` ordering):
///
/// ```text
/// I^A = [ angular     coupling ]
///       [ couplingᵀ   linear   ]
/// ```
/// with symmetric `angular` and `linear` blocks. A rigid body's `M_i` (A.9) is the special case
/// `angular = (I_i)_i`, `coupling = m [p_c]×`, `linear = m 𝟙`; the ABA's rank-one reductions
/// make the blocks general.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArticulatedInertia {
    /// The symmetric angular block `A` (kg·m²).
    pub angular: Symmetric3,
    /// The coupling block `B` (kg·m).
    pub coupling: Mat3,
    /// The symmetric linear block `C` (kg).
    pub linear: Symmetric3,
}

impl From<&Inertia> for ArticulatedInertia {
    /// `M_i` (A.9) in block form.
    #[inline]
    fn from(inertia: &Inertia) -> Self {
        Self {
            angular: Symmetric3::from_upper(&inertia.rotational),
            coupling: skew(&(inertia.com * inertia.mass)),
            linear: Symmetric3::scaled_identity(inertia.mass),
        }
    }
}

impl ArticulatedInertia {
    /// The zero inertia.
    #[inline]
    pub fn zero() -> Self {
        Self::default()
    }

    /// From a dense symmetric 6×6 (its upper triangle is used).
    pub fn from_matrix(m: &Mat6) -> Self {
        Self {
            angular: Symmetric3::from_upper(&m.fixed_view::<3, 3>(0, 0).into_owned()),
            coupling: m.fixed_view::<3, 3>(0, 3).into_owned(),
            linear: Symmetric3::from_upper(&m.fixed_view::<3, 3>(3, 3).into_owned()),
        }
    }

    /// Dense 6×6 form.
    pub fn matrix(&self) -> Mat6 {
        super::blocks(
            &self.angular.matrix(),
            &self.coupling,
            &self.coupling.transpose(),
            &self.linear.matrix(),
        )
    }

    /// `I^A V = [A ω + B v; Bᵀ ω + C v]`.
    #[inline]
    pub fn apply(&self, m: &Motion) -> Force {
        Force::new(
            self.angular.mul_vec(&m.angular) + self.coupling * m.linear,
            self.coupling.tr_mul(&m.angular) + self.linear.mul_vec(&m.linear),
        )
    }

    /// Solves `I^A α = f` for a positive-definite `I^A` (the ABA's base step), or `None` when it
    /// is not positive definite.
    ///
    /// By blocks, with the Schur complement of the linear block `C`: `W = C⁻¹ Bᵀ`,
    /// `S = A − B W`, then `α_ω = S⁻¹ (f_n − B C⁻¹ f_F)` and `α_v = C⁻¹ f_F − W α_ω`; both 3×3
    /// systems are solved by Cholesky.
    #[inline(always)]
    pub fn solve(&self, f: &Force) -> Option<Motion> {
        Some(self.factor()?.solve(f))
    }

    /// `(I^A)⁻¹`, by the factorisation of [`solve`](Self::solve) (done once) on the six unit
    /// forces, or `None` when `I^A` is not positive definite (exactly when `solve` fails).
    pub fn inverse(&self) -> Option<Mat6> {
        let factor = self.factor()?;
        let mut inverse = Mat6::zeros();
        for j in 0..6 {
            let mut unit = [0.0; 6];
            unit[j] = 1.0;
            inverse.set_column(j, &factor.solve(&Force::from_slice(&unit)).to_vector());
        }
        Some(inverse)
    }

    /// The block factorisation of [`solve`](Self::solve).
    #[inline(always)]
    fn factor(&self) -> Option<BlockFactor> {
        let c = self.linear.cholesky()?;
        let b = &self.coupling;
        // W = C⁻¹ Bᵀ, column by column: column k solves C w = (row k of B)ᵀ.
        let w0 = cholesky_solve(&c, &b.row(0).transpose());
        let w1 = cholesky_solve(&c, &b.row(1).transpose());
        let w2 = cholesky_solve(&c, &b.row(2).transpose());
        let (b0, b1, b2) = (b.row(0), b.row(1), b.row(2));
        let schur = Symmetric3 {
            xx: self.angular.xx - (b0 * w0)[0],
            xy: self.angular.xy - (b0 * w1)[0],
            xz: self.angular.xz - (b0 * w2)[0],
            yy: self.angular.yy - (b1 * w1)[0],
            yz: self.angular.yz - (b1 * w2)[0],
            zz: self.angular.zz - (b2 * w2)[0],
        };
        Some(BlockFactor {
            linear: c,
            schur: schur.cholesky()?,
            coupling: *b,
            w: Mat3::from_columns(&[w0, w1, w2]),
        })
    }

    /// `I^A [h; 0] = [A h; Bᵀ h]`: the ABA's `U = I^A H` for a revolute axis `h`.
    #[inline]
    pub fn apply_angular(&self, h: &Vec3) -> Force {
        Force::new(self.angular.mul_vec(h), self.coupling.tr_mul(h))
    }

    /// `I^A [e_z; 0] = [A e_z; Bᵀ e_z]`: the ABA's `U = I^A H` for the axis `e_z` of a joint
    /// frame, a column of `I^A`.
    #[inline]
    pub fn column_z(&self) -> Force {
        let (a, b) = (&self.angular, &self.coupling);
        Force::new(
            Vec3::new(a.xz, a.yz, a.zz),
            Vec3::new(b[(2, 0)], b[(2, 1)], b[(2, 2)]),
        )
    }

    /// `I^A − s U Uᵀ` for a force-like 6-vector `U` (the ABA's `I^a = I^A − U Uᵀ / D`).
    #[inline]
    pub fn minus_outer(&self, u: &Force, s: f64) -> Self {
        Self {
            angular: self.angular.minus_outer(&u.angular, s),
            coupling: self.coupling - (u.angular * s) * u.linear.transpose(),
            linear: self.linear.minus_outer(&u.linear, s),
        }
    }

    /// `Φᵀ I^A Φ` with `phi = Φ_{i+1,i}`: this inertia, given in frame `i+1`, expressed in frame
    /// `i` (the dense form is [`super::congruence`]): `Rᵀ (·) R` on each block, then
    /// [`shifted`](Self::shifted) by `p`.
    #[inline(always)]
    pub fn transformed_to_parent(&self, phi: &Transform) -> Self {
        let r = &phi.rotation;
        // B' = Rᵀ B R: entry (i, j) is r_i · (B r_j).
        let (r0, r1, r2) = columns(r);
        let (b0, b1, b2) = (self.coupling * r0, self.coupling * r1, self.coupling * r2);
        let b = Mat3::new(
            r0.dot(&b0),
            r0.dot(&b1),
            r0.dot(&b2),
            r1.dot(&b0),
            r1.dot(&b1),
            r1.dot(&b2),
            r2.dot(&b0),
            r2.dot(&b1),
            r2.dot(&b2),
        );
        Self {
            angular: self.angular.rotated_by_transpose(r),
            coupling: b,
            linear: self.linear.rotated_by_transpose(r),
        }
        .shifted(&phi.translation)
    }

    /// [`transformed_to_parent`](Self::transformed_to_parent) for a tilted joint's transform,
    /// whose rotation is `R = R_z(−θ) R_x(−α) = [[c, s cα, s sα], [−s, c cα, c sα], [0, −sα, cα]]`:
    /// `Rᵀ X R = R_x(α) (R_z(θ) X R_z(θ)ᵀ) R_x(α)ᵀ`, two plane turns read off `R`, then the shift.
    #[inline(always)]
    pub fn tilted_to_parent(&self, phi: &Transform) -> Self {
        let r = &phi.rotation;
        let (c, s, ca, sa) = (r[(0, 0)], -r[(1, 0)], r[(2, 2)], -r[(2, 1)]);
        let b = turn_z(&self.coupling, c, s);
        let z = Self {
            angular: self.angular.turned_about_z(c, s),
            coupling: b,
            linear: self.linear.turned_about_z(c, s),
        };
        Self {
            angular: z.angular.turned_about_x(ca, sa),
            coupling: turn_x(&z.coupling, ca, sa),
            linear: z.linear.turned_about_x(ca, sa),
        }
        .shifted(&phi.translation)
    }

    /// The same inertia about a point at `p` from the origin (same axes): with `P = [p]×` and
    /// `N = B + ½ P C`, `[[A − (N P + (N P)ᵀ), B + P C], [(B + P C)ᵀ, C]]`, since
    /// `N P + (N P)ᵀ = B P + (B P)ᵀ + P C P` (`P C P` is symmetric). Row `k` of `N P` is
    /// `n_k × p` for the rows `n_k` of `N`, and column `k` of `P C` is `p × c_k`.
    #[inline(always)]
    pub fn shifted(&self, p: &Vec3) -> Self {
        let (a, b, c) = (&self.angular, &self.coupling, &self.linear);
        let pc = Mat3::from_columns(&[
            p.cross(&Vec3::new(c.xx, c.xy, c.xz)),
            p.cross(&Vec3::new(c.xy, c.yy, c.yz)),
            p.cross(&Vec3::new(c.xz, c.yz, c.zz)),
        ]);
        let coupling = b + pc;
        let half = b + pc * 0.5;
        let np0 = half.row(0).transpose().cross(p);
        let np1 = half.row(1).transpose().cross(p);
        let np2 = half.row(2).transpose().cross(p);
        let angular = Symmetric3 {
            xx: a.xx - 2.0 * np0.x,
            xy: a.xy - (np0.y + np1.x),
            xz: a.xz - (np0.z + np2.x),
            yy: a.yy - 2.0 * np1.y,
            yz: a.yz - (np1.z + np2.y),
            zz: a.zz - 2.0 * np2.z,
        };
        Self {
            angular,
            coupling,
            linear: *c,
        }
    }
}

/// `R B Rᵀ` for the turn `R = [[c, −s, 0], [s, c, 0], [0, 0, 1]]`: rows 0 and 1 mixed, then
/// columns 0 and 1.
#[inline(always)]
fn turn_z(b: &Mat3, c: f64, s: f64) -> Mat3 {
    let mut t = *b;
    for j in 0..3 {
        let (u, v) = (b[(0, j)], b[(1, j)]);
        t[(0, j)] = c * u - s * v;
        t[(1, j)] = s * u + c * v;
    }
    let mut y = t;
    for i in 0..3 {
        let (u, v) = (t[(i, 0)], t[(i, 1)]);
        y[(i, 0)] = c * u - s * v;
        y[(i, 1)] = s * u + c * v;
    }
    y
}

/// `R B Rᵀ` for the turn `R = [[1, 0, 0], [0, c, −s], [0, s, c]]`: rows 1 and 2, then columns
/// 1 and 2.
#[inline(always)]
fn turn_x(b: &Mat3, c: f64, s: f64) -> Mat3 {
    let mut t = *b;
    for j in 0..3 {
        let (u, v) = (b[(1, j)], b[(2, j)]);
        t[(1, j)] = c * u - s * v;
        t[(2, j)] = s * u + c * v;
    }
    let mut y = t;
    for i in 0..3 {
        let (u, v) = (t[(i, 1)], t[(i, 2)]);
        y[(i, 1)] = c * u - s * v;
        y[(i, 2)] = s * u + c * v;
    }
    y
}

impl Add for ArticulatedInertia {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        Self {
            angular: self.angular + o.angular,
            coupling: self.coupling + o.coupling,
            linear: self.linear + o.linear,
        }
    }
}

impl AddAssign for ArticulatedInertia {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
