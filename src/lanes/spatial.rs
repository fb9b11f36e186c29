//! The spatial quantities of the ABA in lanes: each type mirrors its `f64` counterpart in
//! [`crate::spatial`] and each operation groups its arithmetic as the scalar one does (nalgebra's
//! `Mat3 * Vec3` is `(m₀ x + m₁ y) + m₂ z` row by row, its `dot` `(a₀b₀ + a₁b₁) + a₂b₂`), so that
//! every lane gives the scalar bits. The tests in `super::tests` compare them.

use super::lane::L;
use crate::spatial::{
    ArticulatedInertia, Force, Inertia, Mat3, Motion, Symmetric3, Transform, Vec3,
};

/// A 3-vector in lanes.
#[derive(Debug, Clone, Copy, Default)]
pub struct V3<const W: usize> {
    /// `x` in every lane.
    pub x: L<W>,
    /// `y` in every lane.
    pub y: L<W>,
    /// `z` in every lane.
    pub z: L<W>,
}

impl<const W: usize> V3<W> {
    /// From its components.
    #[inline(always)]
    pub fn new(x: L<W>, y: L<W>, z: L<W>) -> Self {
        Self { x, y, z }
    }
    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: &Vec3) -> Self {
        Self::new(L::splat(v.x), L::splat(v.y), L::splat(v.z))
    }
    /// Lane `k` set to lane `k` of `v`.
    pub fn set_lane(&mut self, k: usize, v: &Self) {
        (self.x.0[k], self.y.0[k], self.z.0[k]) = (v.x.0[k], v.y.0[k], v.z.0[k]);
    }
    /// `a + b`.
    #[inline(always)]
    pub fn add(&self, o: &Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
    /// `a − b`.
    #[inline(always)]
    pub fn sub(&self, o: &Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
    /// `a s` (nalgebra's `Vec3 * f64`).
    #[inline(always)]
    pub fn scale(&self, s: L<W>) -> Self {
        Self::new(self.x * s, self.y * s, self.z * s)
    }
    /// `a × b`.
    #[inline(always)]
    pub fn cross(&self, b: &Self) -> Self {
        Self::new(
            self.y * b.z - self.z * b.y,
            self.z * b.x - self.x * b.z,
            self.x * b.y - self.y * b.x,
        )
    }
    /// `a · b = (a₀b₀ + a₁b₁) + a₂b₂`.
    #[inline(always)]
    pub fn dot(&self, b: &Self) -> L<W> {
        self.x * b.x + self.y * b.y + self.z * b.z
    }
}

/// A 3×3 matrix in lanes, `m[row][column]`.
#[derive(Debug, Clone, Copy, Default)]
pub struct M3<const W: usize> {
    pub m: [[L<W>; 3]; 3],
}

impl<const W: usize> M3<W> {
    #[inline(always)]
    pub fn splat(a: &Mat3) -> Self {
        let mut m = [[L::zero(); 3]; 3];
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = L::splat(a[(i, j)]);
            }
        }
        Self { m }
    }
    /// `M v`.
    #[inline(always)]
    pub fn mul_vec(&self, v: &V3<W>) -> V3<W> {
        let m = &self.m;
        V3::new(
            m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
            m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
        )
    }
    /// `Mᵀ v`.
    #[inline(always)]
    pub fn tr_mul_vec(&self, v: &V3<W>) -> V3<W> {
        let m = &self.m;
        V3::new(
            m[0][0] * v.x + m[1][0] * v.y + m[2][0] * v.z,
            m[0][1] * v.x + m[1][1] * v.y + m[2][1] * v.z,
            m[0][2] * v.x + m[1][2] * v.y + m[2][2] * v.z,
        )
    }
    #[inline(always)]
    pub fn column(&self, j: usize) -> V3<W> {
        V3::new(self.m[0][j], self.m[1][j], self.m[2][j])
    }
    #[inline(always)]
    pub fn row(&self, i: usize) -> V3<W> {
        V3::new(self.m[i][0], self.m[i][1], self.m[i][2])
    }
    #[inline(always)]
    pub fn from_columns(c: [V3<W>; 3]) -> Self {
        let mut m = [[L::zero(); 3]; 3];
        for (j, col) in c.iter().enumerate() {
            m[0][j] = col.x;
            m[1][j] = col.y;
            m[2][j] = col.z;
        }
        Self { m }
    }
    #[inline(always)]
    fn zip(&self, o: &Self, f: impl Fn(L<W>, L<W>) -> L<W>) -> Self {
        let mut m = self.m;
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = f(self.m[i][j], o.m[i][j]);
            }
        }
        Self { m }
    }
    #[inline(always)]
    pub fn add(&self, o: &Self) -> Self {
        self.zip(o, |a, b| a + b)
    }
    #[inline(always)]
    pub fn scale(&self, s: f64) -> Self {
        self.zip(self, |a, _| a * s)
    }
}

/// A symmetric 3×3 in lanes ([`Symmetric3`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct S3<const W: usize> {
    pub xx: L<W>,
    pub xy: L<W>,
    pub xz: L<W>,
    pub yy: L<W>,
    pub yz: L<W>,
    pub zz: L<W>,
}

impl<const W: usize> S3<W> {
    #[inline(always)]
    pub fn splat(s: &Symmetric3) -> Self {
        Self {
            xx: L::splat(s.xx),
            xy: L::splat(s.xy),
            xz: L::splat(s.xz),
            yy: L::splat(s.yy),
            yz: L::splat(s.yz),
            zz: L::splat(s.zz),
        }
    }
    #[inline(always)]
    pub fn mul_vec(&self, v: &V3<W>) -> V3<W> {
        V3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }
    #[inline(always)]
    pub fn minus_outer(&self, a: &V3<W>, s: L<W>) -> Self {
        let sa = a.scale(s);
        Self {
            xx: self.xx - sa.x * a.x,
            xy: self.xy - sa.x * a.y,
            xz: self.xz - sa.x * a.z,
            yy: self.yy - sa.y * a.y,
            yz: self.yz - sa.y * a.z,
            zz: self.zz - sa.z * a.z,
        }
    }
    /// `Rᵀ S R` ([`Symmetric3::rotated_by_transpose`]).
    #[inline(always)]
    pub fn rotated_by_transpose(&self, r: &M3<W>) -> Self {
        let (r0, r1, r2) = (r.column(0), r.column(1), r.column(2));
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
    /// [`Symmetric3::turned_about_z`].
    #[inline(always)]
    pub fn turned_about_z(&self, c: L<W>, s: L<W>) -> Self {
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
    /// [`Symmetric3::turned_about_x`].
    #[inline(always)]
    pub fn turned_about_x(&self, c: L<W>, s: L<W>) -> Self {
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
    #[inline(always)]
    pub fn add(&self, o: &Self) -> Self {
        Self {
            xx: self.xx + o.xx,
            xy: self.xy + o.xy,
            xz: self.xz + o.xz,
            yy: self.yy + o.yy,
            yz: self.yz + o.yz,
            zz: self.zz + o.zz,
        }
    }
    /// The Cholesky factor `[l00, l10, l11, l20, l21, l22]` and, per lane, whether `S` was
    /// positive definite (`Symmetric3::cholesky`).
    #[inline(always)]
    pub fn cholesky(&self) -> ([L<W>; 6], [bool; W]) {
        let l00 = self.xx.sqrt();
        let l10 = self.xy / l00;
        let l20 = self.xz / l00;
        let d1 = self.yy - l10 * l10;
        let l11 = d1.sqrt();
        let l21 = (self.yz - l20 * l10) / l11;
        let d2 = self.zz - l20 * l20 - l21 * l21;
        let l22 = d2.sqrt();
        let ok = std::array::from_fn(|k| {
            self.xx.0[k] > 0.0 && d1.0[k] > 0.0 && d2.0[k] > 0.0 && l22.0[k].is_finite()
        });
        ([l00, l10, l11, l20, l21, l22], ok)
    }
}

/// Solves `L Lᵀ x = b` (`cholesky_solve` of the scalar code).
#[inline(always)]
pub fn cholesky_solve<const W: usize>(l: &[L<W>; 6], b: &V3<W>) -> V3<W> {
    let [l00, l10, l11, l20, l21, l22] = *l;
    let y0 = b.x / l00;
    let y1 = (b.y - l10 * y0) / l11;
    let y2 = (b.z - l20 * y0 - l21 * y1) / l22;
    let x2 = y2 / l22;
    let x1 = (y1 - l21 * x2) / l11;
    let x0 = (y0 - l10 * x1 - l20 * x2) / l00;
    V3::new(x0, x1, x2)
}

/// A spatial motion or force in lanes, `[angular; linear]`.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sv<const W: usize> {
    /// `ω` (motion) or the moment (force).
    pub angular: V3<W>,
    /// `v` (motion) or the force (force).
    pub linear: V3<W>,
}

impl<const W: usize> Sv<W> {
    /// From its parts.
    #[inline(always)]
    pub fn new(angular: V3<W>, linear: V3<W>) -> Self {
        Self { angular, linear }
    }
    /// `f` in every lane.
    #[inline(always)]
    pub fn splat_force(f: &Force) -> Self {
        Self::new(V3::splat(&f.angular), V3::splat(&f.linear))
    }
    /// `m` in every lane.
    #[inline(always)]
    pub fn splat_motion(m: &Motion) -> Self {
        Self::new(V3::splat(&m.angular), V3::splat(&m.linear))
    }
    /// `a + b`.
    #[inline(always)]
    pub fn add(&self, o: &Self) -> Self {
        Self::new(self.angular.add(&o.angular), self.linear.add(&o.linear))
    }
    /// `a − b`.
    #[inline(always)]
    pub fn sub(&self, o: &Self) -> Self {
        Self::new(self.angular.sub(&o.angular), self.linear.sub(&o.linear))
    }
    /// `a s`.
    #[inline(always)]
    pub fn scale(&self, s: L<W>) -> Self {
        Self::new(self.angular.scale(s), self.linear.scale(s))
    }
    /// `m · f` (`Motion::dot`).
    #[inline(always)]
    pub fn dot(&self, f: &Self) -> L<W> {
        self.angular.dot(&f.angular) + self.linear.dot(&f.linear)
    }
}

/// `Φ` (A.5) in lanes.
#[derive(Debug, Clone, Copy, Default)]
pub struct Xf<const W: usize> {
    pub rotation: M3<W>,
    pub translation: V3<W>,
}

impl<const W: usize> Xf<W> {
    #[inline(always)]
    pub fn splat(x: &Transform) -> Self {
        Self {
            rotation: M3::splat(&x.rotation),
            translation: V3::splat(&x.translation),
        }
    }
    /// `Φ V` ([`Transform::apply_motion`]).
    #[inline(always)]
    pub fn apply_motion(&self, m: &Sv<W>) -> Sv<W> {
        Sv::new(
            self.rotation.mul_vec(&m.angular),
            self.rotation
                .mul_vec(&m.linear.add(&m.angular.cross(&self.translation))),
        )
    }
    /// `Φᵀ f` ([`Transform::apply_force_transpose`]).
    #[inline(always)]
    pub fn apply_force_transpose(&self, f: &Sv<W>) -> Sv<W> {
        let linear = self.rotation.tr_mul_vec(&f.linear);
        Sv::new(
            self.rotation
                .tr_mul_vec(&f.angular)
                .add(&self.translation.cross(&linear)),
            linear,
        )
    }
}

/// A rigid-body inertia in lanes, each lane its run's ([`Inertia`]): mass, centre of mass and
/// rotational inertia about the frame origin.
#[derive(Debug, Clone, Copy, Default)]
pub struct In<const W: usize> {
    pub rotational: M3<W>,
    pub com: V3<W>,
    pub mass: L<W>,
}

impl<const W: usize> In<W> {
    /// `i` in every lane.
    pub fn splat(i: &Inertia) -> Self {
        Self {
            rotational: M3::splat(&i.rotational),
            com: V3::splat(&i.com),
            mass: L::splat(i.mass),
        }
    }

    /// Lane `k` set to `i`.
    pub fn set_lane(&mut self, k: usize, i: &Inertia) {
        let one = Self::splat(i);
        for r in 0..3 {
            for c in 0..3 {
                self.rotational.m[r][c].0[k] = one.rotational.m[r][c].0[0];
            }
        }
        self.com.set_lane(k, &one.com);
        self.mass.0[k] = i.mass;
    }
}

/// `b_i` (A.10) at the angular velocity `w` ([`crate::spatial::bias_force`]), the inertia in
/// lanes.
#[inline(always)]
pub fn bias_force<const W: usize>(inertia: &In<W>, w: &V3<W>) -> Sv<W> {
    Sv::new(
        w.cross(&inertia.rotational.mul_vec(w)),
        w.cross(&w.cross(&inertia.com)).scale(inertia.mass),
    )
}

/// An articulated-body inertia in lanes ([`ArticulatedInertia`]).
#[derive(Debug, Clone, Copy, Default)]
pub struct Art<const W: usize> {
    pub angular: S3<W>,
    pub coupling: M3<W>,
    pub linear: S3<W>,
}

impl<const W: usize> Art<W> {
    #[inline(always)]
    pub fn splat(a: &ArticulatedInertia) -> Self {
        Self {
            angular: S3::splat(&a.angular),
            coupling: M3::splat(&a.coupling),
            linear: S3::splat(&a.linear),
        }
    }
    /// Lane `k` set to `a`.
    pub fn set_lane(&mut self, k: usize, a: &ArticulatedInertia) {
        let one = Self::splat(a);
        for (to, from) in [
            (&mut self.angular, &one.angular),
            (&mut self.linear, &one.linear),
        ] {
            for (t, f) in [
                (&mut to.xx, from.xx),
                (&mut to.xy, from.xy),
                (&mut to.xz, from.xz),
                (&mut to.yy, from.yy),
                (&mut to.yz, from.yz),
                (&mut to.zz, from.zz),
            ] {
                t.0[k] = f.0[k];
            }
        }
        for r in 0..3 {
            for c in 0..3 {
                self.coupling.m[r][c].0[k] = one.coupling.m[r][c].0[k];
            }
        }
    }
    #[inline(always)]
    pub fn add_assign(&mut self, o: &Self) {
        self.angular = self.angular.add(&o.angular);
        self.coupling = self.coupling.add(&o.coupling);
        self.linear = self.linear.add(&o.linear);
    }
    /// `I^A V`.
    #[inline(always)]
    pub fn apply(&self, m: &Sv<W>) -> Sv<W> {
        Sv::new(
            self.angular
                .mul_vec(&m.angular)
                .add(&self.coupling.mul_vec(&m.linear)),
            self.coupling
                .tr_mul_vec(&m.angular)
                .add(&self.linear.mul_vec(&m.linear)),
        )
    }
    /// `I^A [e_z; 0]`.
    #[inline(always)]
    pub fn column_z(&self) -> Sv<W> {
        let (a, b) = (&self.angular, &self.coupling.m);
        Sv::new(
            V3::new(a.xz, a.yz, a.zz),
            V3::new(b[2][0], b[2][1], b[2][2]),
        )
    }
    /// `I^A − s U Uᵀ`.
    #[inline(always)]
    pub fn minus_outer(&self, u: &Sv<W>, s: L<W>) -> Self {
        let us = u.angular.scale(s);
        let (a, l) = ([us.x, us.y, us.z], [u.linear.x, u.linear.y, u.linear.z]);
        let mut coupling = self.coupling;
        for i in 0..3 {
            for j in 0..3 {
                coupling.m[i][j] = self.coupling.m[i][j] - a[i] * l[j];
            }
        }
        Self {
            angular: self.angular.minus_outer(&u.angular, s),
            coupling,
            linear: self.linear.minus_outer(&u.linear, s),
        }
    }
    /// `Φᵀ I^A Φ` ([`ArticulatedInertia::transformed_to_parent`]).
    #[inline(always)]
    pub fn transformed_to_parent(&self, phi: &Xf<W>) -> Self {
        let r = &phi.rotation;
        let (r0, r1, r2) = (r.column(0), r.column(1), r.column(2));
        let c = &self.coupling;
        let (b0, b1, b2) = (c.mul_vec(&r0), c.mul_vec(&r1), c.mul_vec(&r2));
        let b = M3 {
            m: [
                [r0.dot(&b0), r0.dot(&b1), r0.dot(&b2)],
                [r1.dot(&b0), r1.dot(&b1), r1.dot(&b2)],
                [r2.dot(&b0), r2.dot(&b1), r2.dot(&b2)],
            ],
        };
        Self {
            angular: self.angular.rotated_by_transpose(r),
            coupling: b,
            linear: self.linear.rotated_by_transpose(r),
        }
        .shifted(&phi.translation)
    }
    /// [`ArticulatedInertia::tilted_to_parent`].
    #[inline(always)]
    pub fn tilted_to_parent(&self, phi: &Xf<W>) -> Self {
        let r = &phi.rotation.m;
        let (c, s, ca, sa) = (r[0][0], -r[1][0], r[2][2], -r[2][1]);
        let z = Self {
            angular: self.angular.turned_about_z(c, s),
            coupling: turn(&self.coupling, c, s, 0, 1),
            linear: self.linear.turned_about_z(c, s),
        };
        Self {
            angular: z.angular.turned_about_x(ca, sa),
            coupling: turn(&z.coupling, ca, sa, 1, 2),
            linear: z.linear.turned_about_x(ca, sa),
        }
        .shifted(&phi.translation)
    }
    /// [`ArticulatedInertia::shifted`].
    #[inline(always)]
    pub fn shifted(&self, p: &V3<W>) -> Self {
        let (a, b, c) = (&self.angular, &self.coupling, &self.linear);
        let pc = M3::from_columns([
            p.cross(&V3::new(c.xx, c.xy, c.xz)),
            p.cross(&V3::new(c.xy, c.yy, c.yz)),
            p.cross(&V3::new(c.xz, c.yz, c.zz)),
        ]);
        let coupling = b.add(&pc);
        let half = b.add(&pc.scale(0.5));
        let np0 = half.row(0).cross(p);
        let np1 = half.row(1).cross(p);
        let np2 = half.row(2).cross(p);
        let angular = S3 {
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
    /// Solves `I^A α = f` by blocks ([`ArticulatedInertia::solve`]); per lane, whether `I^A`
    /// was positive definite.
    #[inline(always)]
    pub fn solve(&self, f: &Sv<W>) -> (Sv<W>, [bool; W]) {
        let (c, ok_c) = self.linear.cholesky();
        let b = &self.coupling;
        let (b0, b1, b2) = (b.row(0), b.row(1), b.row(2));
        let w0 = cholesky_solve(&c, &b0);
        let w1 = cholesky_solve(&c, &b1);
        let w2 = cholesky_solve(&c, &b2);
        let schur = S3 {
            xx: self.angular.xx - b0.dot(&w0),
            xy: self.angular.xy - b0.dot(&w1),
            xz: self.angular.xz - b0.dot(&w2),
            yy: self.angular.yy - b1.dot(&w1),
            yz: self.angular.yz - b1.dot(&w2),
            zz: self.angular.zz - b2.dot(&w2),
        };
        let (s, ok_s) = schur.cholesky();
        let w = M3::from_columns([w0, w1, w2]);
        let y = cholesky_solve(&c, &f.linear);
        let angular = cholesky_solve(&s, &f.angular.sub(&b.mul_vec(&y)));
        let ok = std::array::from_fn(|k| ok_c[k] && ok_s[k]);
        (Sv::new(angular, y.sub(&w.mul_vec(&angular))), ok)
    }
}

/// `R B Rᵀ` for a plane turn by `(c, s)` in the plane of axes `(i, j)`: rows `i`, `j` mixed,
/// then columns `i`, `j` (`turn_z` with `(0, 1)`, `turn_x` with `(1, 2)` of the scalar code).
#[inline(always)]
fn turn<const W: usize>(b: &M3<W>, c: L<W>, s: L<W>, i: usize, j: usize) -> M3<W> {
    let mut t = *b;
    for k in 0..3 {
        let (u, v) = (b.m[i][k], b.m[j][k]);
        t.m[i][k] = c * u - s * v;
        t.m[j][k] = s * u + c * v;
    }
    let mut y = t;
    for k in 0..3 {
        let (u, v) = (t.m[k][i], t.m[k][j]);
        y.m[k][i] = c * u - s * v;
        y.m[k][j] = s * u + c * v;
    }
    y
}
