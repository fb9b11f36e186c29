//! Spatial inertia `M_i` (A.9), the bias force `b_i` (A.10) and the Coriolis term `a_i` (A.7).

use super::{blocks, skew, Force, Mat3, Mat6, Motion, Symmetric3, Transform, Vec3};

/// The spatial inertia of one rigid body about its frame origin, in its own frame (A.9):
///
/// ```text
/// M_i = [ (I_i)_i          m_i [p_{i,c}]× ]
///       [ -m_i [p_{i,c}]×  m_i 𝟙          ]
/// ```
/// `mass` in kg, `com` = `p_{i,c}` (m, in frame `i`), `rotational` = `(I_i)_i`, the rotational
/// inertia about the frame ORIGIN (kg·m², not about the centre of mass).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertia {
    /// `m_i` (kg).
    pub mass: f64,
    /// `p_{i,c}`: the centre of mass in frame `i` (m).
    pub com: Vec3,
    /// `(I_i)_i`: the rotational inertia about the frame ORIGIN, frame-`i` axes (kg·m²).
    pub rotational: Mat3,
}

impl Default for Inertia {
    fn default() -> Self {
        Self::zero()
    }
}

impl Inertia {
    /// A massless body.
    pub fn zero() -> Self {
        Self {
            mass: 0.0,
            com: Vec3::zeros(),
            rotational: Mat3::zeros(),
        }
    }

    /// From mass, COM `p_{i,c}` and the rotational inertia about the COM (axes of frame `i`), by
    /// the parallel-axis shift `(I_i)_i = I_c - m [p_c]×²`.
    pub fn from_com(mass: f64, com: Vec3, inertia_about_com: Mat3) -> Self {
        let c = skew(&com);
        Self {
            mass,
            com,
            rotational: inertia_about_com - mass * c * c,
        }
    }

    /// A solid cube of uniform density, `mass` (kg) and edge `side` (m), centred at `com`: its
    /// inertia about the centre is `m s²/6` about every axis. The default spacecraft bus
    /// ([`crate::model::DEFAULT_BUS_SIDE`]) when only its mass is known.
    pub fn solid_cube(mass: f64, side: f64, com: Vec3) -> Self {
        Self::from_com(mass, com, Mat3::identity() * (mass * side * side / 6.0))
    }

    /// The rotational inertia about the centre of mass (axes of this frame).
    pub fn inertia_about_com(&self) -> Mat3 {
        let c = skew(&self.com);
        self.rotational + self.mass * c * c
    }

    /// `M V` (A.9): `[I ω + m p_c × v; m (v + ω × p_c)]`, the body's spatial momentum.
    #[inline]
    pub fn apply(&self, v: &Motion) -> Force {
        Force::new(
            self.rotational * v.angular + self.mass * self.com.cross(&v.linear),
            self.mass * (v.linear + v.angular.cross(&self.com)),
        )
    }

    /// `M [e_z; 0] = [I e_z; m e_z × p_c]`: the momentum of a unit turn about the frame's z axis.
    #[inline]
    pub fn apply_z(&self) -> Force {
        let (m, c) = (self.mass, &self.com);
        Force::new(
            self.rotational.column(2).into_owned(),
            Vec3::new(-m * c.y, m * c.x, 0.0),
        )
    }

    /// Dense 6×6 form of (A.9).
    pub fn matrix(&self) -> Mat6 {
        let mc = skew(&self.com) * self.mass;
        blocks(
            &self.rotational,
            &mc,
            &(-mc),
            &(Mat3::identity() * self.mass),
        )
    }

    /// The sum of two inertias expressed in the same frame (rigidly joined bodies).
    pub fn add(&self, other: &Inertia) -> Inertia {
        let mass = self.mass + other.mass;
        let com = if mass > 0.0 {
            (self.com * self.mass + other.com * other.mass) / mass
        } else {
            Vec3::zeros()
        };
        Inertia {
            mass,
            com,
            rotational: self.rotational + other.rotational,
        }
    }

    /// This inertia, given in frame `i+1`, expressed in frame `i`, where `phi = Φ_{i+1,i}`;
    /// equal to `Φᵀ M Φ` but kept in (mass, COM, inertia) form.
    ///
    /// With the COM in parent axes `c_r = Rᵀ p_c` and `c' = p + c_r`, the parallel-axis theorem
    /// moves `Rᵀ (I_i)_i R` from the child origin to the COM and on to the parent origin:
    /// `Rᵀ (I_i)_i R + m ([c_r]×² − [c']×²)`, with `[a]×² = a aᵀ − |a|² 𝟙`.
    #[inline(always)]
    pub fn transformed_to_parent(&self, phi: &Transform) -> Inertia {
        let r = &phi.rotation;
        let c_r = r.tr_mul(&self.com);
        let com = phi.translation + c_r;
        let m = self.mass;
        let shift = m * (com.norm_squared() - c_r.norm_squared());
        let (mc_r, mcom) = (c_r * m, com * m);
        let rotated = Symmetric3::from_upper(&self.rotational).rotated_by_transpose(r);
        let rotational = Symmetric3 {
            xx: rotated.xx + mc_r.x * c_r.x - mcom.x * com.x + shift,
            xy: rotated.xy + mc_r.x * c_r.y - mcom.x * com.y,
            xz: rotated.xz + mc_r.x * c_r.z - mcom.x * com.z,
            yy: rotated.yy + mc_r.y * c_r.y - mcom.y * com.y + shift,
            yz: rotated.yz + mc_r.y * c_r.z - mcom.y * com.z,
            zz: rotated.zz + mc_r.z * c_r.z - mcom.z * com.z + shift,
        }
        .matrix();
        Inertia {
            mass: m,
            com,
            rotational,
        }
    }
}

/// The bias force `b_i` of (A.10) for a body turning at `ω` (rad/s, body frame):
/// `[ω × (I_i)_i ω; m ω × (ω × p_c)]`.
#[inline(always)]
pub fn bias_force(inertia: &Inertia, omega: &Vec3) -> Force {
    Force::new(
        omega.cross(&(inertia.rotational * omega)),
        inertia.mass * omega.cross(&omega.cross(&inertia.com)),
    )
}

/// The Coriolis/centripetal acceleration `a_{i+1}` of (A.7) for a revolute joint:
/// `[(R ω_i) × ω_{i+1}; R (ω_i × (ω_i × p_{i,i+1}))]`, where `phi = Φ_{i+1,i}` supplies `R` and `p`,
/// `omega_parent = ω_i` (frame `i`) and `omega_child = ω_{i+1}` (frame `i+1`).
#[inline]
pub fn coriolis_acceleration(phi: &Transform, omega_parent: &Vec3, omega_child: &Vec3) -> Motion {
    let w = phi.rotation * omega_parent;
    Motion::new(
        w.cross(omega_child),
        phi.rotation * omega_parent.cross(&omega_parent.cross(&phi.translation)),
    )
}
