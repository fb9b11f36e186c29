//! Spatial motion and force vectors, `[angular; linear]`.

use super::{skew, Mat6, Vec3, Vec6};
use std::ops::{Add, AddAssign, Mul, Neg, Sub, SubAssign};

/// A spatial motion (velocity or acceleration) `[ω; v]` in some body frame.
///
/// For a velocity, `ω` is the angular velocity (rad/s) and `v` the velocity of the frame origin
/// (m/s). For the paper's "classical" acceleration `α`, the parts are the inertial-frame time
/// derivatives of `ω` and of the origin velocity, expressed in the body frame (model §1).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion {
    /// `ω` (rad/s), or `ω̇` for an acceleration.
    pub angular: Vec3,
    /// `v`, the velocity of the frame origin (m/s), or its classical derivative.
    pub linear: Vec3,
}

/// A spatial force `[n; F]`: moment `n` about the frame origin (N·m) and force `F` (N).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Force {
    /// The moment `n` about the frame origin (N·m).
    pub angular: Vec3,
    /// The force `F` (N).
    pub linear: Vec3,
}

macro_rules! spatial_vector_impl {
    ($t:ident) => {
        impl $t {
            /// The zero vector, as a constant.
            pub const ZERO: Self = Self {
                angular: Vec3::new(0.0, 0.0, 0.0),
                linear: Vec3::new(0.0, 0.0, 0.0),
            };

            /// The zero vector.
            #[inline]
            pub fn zero() -> Self {
                Self {
                    angular: Vec3::zeros(),
                    linear: Vec3::zeros(),
                }
            }
            /// Builds the vector from its angular and linear parts.
            #[inline]
            pub fn new(angular: Vec3, linear: Vec3) -> Self {
                Self { angular, linear }
            }
            /// Reads `[angular; linear]` from a dense 6-vector.
            #[inline]
            pub fn from_vector(v: &Vec6) -> Self {
                Self {
                    angular: v.fixed_rows::<3>(0).into_owned(),
                    linear: v.fixed_rows::<3>(3).into_owned(),
                }
            }
            /// Reads `[angular; linear]` from a slice of 6 numbers.
            #[inline]
            pub fn from_slice(v: &[f64]) -> Self {
                Self {
                    angular: Vec3::new(v[0], v[1], v[2]),
                    linear: Vec3::new(v[3], v[4], v[5]),
                }
            }
            /// The dense 6-vector `[angular; linear]`.
            #[inline]
            pub fn to_vector(&self) -> Vec6 {
                Vec6::new(
                    self.angular.x,
                    self.angular.y,
                    self.angular.z,
                    self.linear.x,
                    self.linear.y,
                    self.linear.z,
                )
            }
            /// `[angular; linear]` as an array.
            #[inline]
            pub fn to_array(&self) -> [f64; 6] {
                [
                    self.angular.x,
                    self.angular.y,
                    self.angular.z,
                    self.linear.x,
                    self.linear.y,
                    self.linear.z,
                ]
            }
            /// Writes `[angular; linear]` into the first six elements of `out`.
            #[inline]
            pub fn write_to(&self, out: &mut [f64]) {
                out[..3].copy_from_slice(self.angular.as_slice());
                out[3..6].copy_from_slice(self.linear.as_slice());
            }
        }
        impl Add for $t {
            type Output = Self;
            #[inline]
            fn add(self, o: Self) -> Self {
                Self::new(self.angular + o.angular, self.linear + o.linear)
            }
        }
        impl AddAssign for $t {
            #[inline]
            fn add_assign(&mut self, o: Self) {
                self.angular += o.angular;
                self.linear += o.linear;
            }
        }
        impl Sub for $t {
            type Output = Self;
            #[inline]
            fn sub(self, o: Self) -> Self {
                Self::new(self.angular - o.angular, self.linear - o.linear)
            }
        }
        impl SubAssign for $t {
            #[inline]
            fn sub_assign(&mut self, o: Self) {
                self.angular -= o.angular;
                self.linear -= o.linear;
            }
        }
        impl Neg for $t {
            type Output = Self;
            #[inline]
            fn neg(self) -> Self {
                Self::new(-self.angular, -self.linear)
            }
        }
        impl Mul<f64> for $t {
            type Output = Self;
            #[inline]
            fn mul(self, s: f64) -> Self {
                Self::new(self.angular * s, self.linear * s)
            }
        }
    };
}

spatial_vector_impl!(Motion);
spatial_vector_impl!(Force);

impl Motion {
    /// Motion cross product `V ×ₘ m` (Featherstone's `crm(V) m`).
    #[inline]
    pub fn cross_motion(&self, m: &Motion) -> Motion {
        Motion::new(
            self.angular.cross(&m.angular),
            self.angular.cross(&m.linear) + self.linear.cross(&m.angular),
        )
    }

    /// Force cross product `V ×* f` (Featherstone's `crf(V) f = -crm(V)ᵀ f`).
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force::new(
            self.angular.cross(&f.angular) + self.linear.cross(&f.linear),
            self.angular.cross(&f.linear),
        )
    }

    /// Power `Vᵀ f` of a force along this motion (W).
    #[inline]
    pub fn dot(&self, f: &Force) -> f64 {
        self.angular.dot(&f.angular) + self.linear.dot(&f.linear)
    }

    /// Dense 6×6 motion cross-product matrix `crm(V)`.
    pub fn cross_motion_matrix(&self) -> Mat6 {
        let w = skew(&self.angular);
        super::blocks(&w, &super::Mat3::zeros(), &skew(&self.linear), &w)
    }

    /// Dense 6×6 force cross-product matrix `crf(V) = -crm(V)ᵀ`.
    pub fn cross_force_matrix(&self) -> Mat6 {
        -self.cross_motion_matrix().transpose()
    }
}
