//! The rigid-body transform `Φ_{i+1,i}` of (A.5).

use super::{blocks, skew, Force, Mat3, Mat6, Motion, Vec3};

/// The paper's `Φ_{i+1,i}` (A.5): takes motions from frame `i` to frame `i+1`.
///
/// ```text
/// Φ_{i+1,i} = [  R_{i+1,i}                 0        ]
///             [ -R_{i+1,i} [p_{i,i+1}]×    R_{i+1,i} ]
/// ```
/// `rotation` is `R_{i+1,i}` (frame-`i` components to frame-`i+1` components) and `translation`
/// is `p_{i,i+1}`, the vector from origin `i` to origin `i+1` in frame `i` (m). The transpose
/// `Φᵀ` takes forces from frame `i+1` back to frame `i` (moments re-taken about origin `i`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// `R_{i+1,i}`: frame-`i` components to frame-`i+1` components.
    pub rotation: Mat3,
    /// `p_{i,i+1}`: from origin `i` to origin `i+1`, in frame `i` (m).
    pub translation: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self::identity()
    }
}

impl Transform {
    /// `Φ_{ii} = I`.
    #[inline]
    pub fn identity() -> Self {
        Self {
            rotation: Mat3::identity(),
            translation: Vec3::zeros(),
        }
    }

    /// `Φ` from `R_{i+1,i}` and `p_{i,i+1}` (model §1).
    #[inline]
    pub fn new(rotation: Mat3, translation: Vec3) -> Self {
        Self {
            rotation,
            translation,
        }
    }

    /// `Φ V` (A.4): `[R ω; R (v + ω × p)]`, the same rigid motion seen from frame `i+1`.
    #[inline]
    pub fn apply_motion(&self, m: &Motion) -> Motion {
        Motion::new(
            self.rotation * m.angular,
            self.rotation * (m.linear + m.angular.cross(&self.translation)),
        )
    }

    /// `Φᵀ f` (A.8): `[Rᵀ n + p × Rᵀ F; Rᵀ F]`, a force at frame `i+1` moved to frame `i`.
    #[inline]
    pub fn apply_force_transpose(&self, f: &Force) -> Force {
        let linear = self.rotation.tr_mul(&f.linear);
        Force::new(
            self.rotation.tr_mul(&f.angular) + self.translation.cross(&linear),
            linear,
        )
    }

    /// `Φ⁻¹ V`: a motion in frame `i+1` expressed in frame `i`.
    #[inline]
    pub fn apply_motion_inverse(&self, m: &Motion) -> Motion {
        let angular = self.rotation.tr_mul(&m.angular);
        Motion::new(
            angular,
            self.rotation.tr_mul(&m.linear) - angular.cross(&self.translation),
        )
    }

    /// `Φ⁻ᵀ f`: a force in frame `i` expressed in frame `i+1`.
    #[inline]
    pub fn apply_force(&self, f: &Force) -> Force {
        Force::new(
            self.rotation * (f.angular - self.translation.cross(&f.linear)),
            self.rotation * f.linear,
        )
    }

    /// Composition `Φ_{k,i} = self ∘ inner`, where `self = Φ_{k,j}` and `inner = Φ_{j,i}`.
    #[inline]
    pub fn compose(&self, inner: &Transform) -> Transform {
        Transform {
            rotation: self.rotation * inner.rotation,
            translation: inner.translation + inner.rotation.tr_mul(&self.translation),
        }
    }

    /// `Φ⁻¹ = Φ_{i,i+1}`.
    #[inline]
    pub fn inverse(&self) -> Transform {
        Transform {
            rotation: self.rotation.transpose(),
            translation: -(self.rotation * self.translation),
        }
    }

    /// Dense 6×6 form of (A.5).
    pub fn matrix(&self) -> Mat6 {
        let r = self.rotation;
        blocks(&r, &Mat3::zeros(), &(-r * skew(&self.translation)), &r)
    }
}

/// `Φᵀ X Φ` for a symmetric 6×6 `X = [[A, B], [Bᵀ, C]]` (an inertia in frame `i+1`), giving the
/// same inertia in frame `i`, in closed form on 3×3 blocks.
///
/// With `A' = Rᵀ A R`, `B' = Rᵀ B R`, `C' = Rᵀ C R` and `P = [p]×`:
/// `Φᵀ X Φ = [[A' - B' P - (B' P)ᵀ - P C' P, B' + P C'], [(B' + P C')ᵀ, C']]`.
#[inline]
pub fn congruence(phi: &Transform, x: &Mat6) -> Mat6 {
    let r = &phi.rotation;
    let a = x.fixed_view::<3, 3>(0, 0);
    let b = x.fixed_view::<3, 3>(0, 3);
    let c = x.fixed_view::<3, 3>(3, 3);
    let a1 = r.tr_mul(&(a * r));
    let b1 = r.tr_mul(&(b * r));
    let c1 = r.tr_mul(&(c * r));
    let p = skew(&phi.translation);
    let pc = p * c1;
    let b1p = b1 * p;
    let top_left = a1 - b1p - b1p.transpose() - pc * p;
    let top_right = b1 + pc;
    let mut out = Mat6::zeros();
    out.fixed_view_mut::<3, 3>(0, 0).copy_from(&top_left);
    out.fixed_view_mut::<3, 3>(0, 3).copy_from(&top_right);
    out.fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&top_right.transpose());
    out.fixed_view_mut::<3, 3>(3, 3).copy_from(&c1);
    out
}

/// Rotation matrix `exp([h]× θ)` for a unit axis `h` (Rodrigues' formula): the matrix whose
/// columns are the rotated frame's axes, i.e. it maps rotated-frame components to fixed-frame ones.
///
/// Written out as `cos θ 𝟙 + sin θ [h]× + (1 − cos θ) h hᵀ`, which equals
/// `𝟙 + sin θ [h]× + (1 − cos θ) [h]×²` because `[h]×² = h hᵀ − 𝟙` for `|h| = 1`.
#[inline]
pub fn rotation_about_axis(axis: &Vec3, angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    let (x, y, z) = (axis.x, axis.y, axis.z);
    let (tx, ty, tz) = (t * x, t * y, t * z);
    let (sx, sy, sz) = (s * x, s * y, s * z);
    Mat3::new(
        c + tx * x,
        tx * y - sz,
        tx * z + sy,
        tx * y + sz,
        c + ty * y,
        ty * z - sx,
        tx * z - sy,
        ty * z + sx,
        c + tz * z,
    )
}

impl Transform {
    /// `Φ_{child,parent}` from a URDF-style origin: the child frame's position `xyz` (m) and
    /// orientation `rpy` (rad, fixed-axis roll-pitch-yaw, `E = R_z(y) R_y(p) R_x(r)`) in the
    /// parent frame. Then `R_{child,parent} = Eᵀ` and `p_{parent,child} = xyz`.
    pub fn from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Transform {
        let e = nalgebra::Rotation3::from_euler_angles(rpy[0], rpy[1], rpy[2]);
        Transform::new(e.matrix().transpose(), Vec3::new(xyz[0], xyz[1], xyz[2]))
    }
}
