//! [`Target`]: a free, torque-free rigid body (a client satellite, a piece of debris) with a
//! handle to grasp, and its motion as a free function.
//!
//! The target's body frame `t` plays the part of the base frame of an arm (model §1): its pose is
//! `[r_t (3); quat_t (4)]` (origin in the inertial frame, quaternion `(x, y, z, w)` mapping
//! `t`-frame components to inertial ones) and its twist `W = [ω; v]` is in `t`-frame components,
//! `v` the velocity of the origin of `t`. Its mass `m`, centre of mass `c` (in `t`) and
//! rotational inertia `I_c` about the centre of mass (`t` axes) give the spatial inertia `Y`
//! about the origin of `t` (A.9). Its state is the 13 numbers `[r_t; quat_t; ω; v]`.

use crate::args::{check_finite, check_vector};
use crate::dynamics::momentum_in_inertial_frame;
use crate::error::{Error, Result};
use crate::model::{check_inertia, MAX_LENGTH};
use crate::spatial::{normalise_quaternion, quaternion_rate};
use crate::spatial::{quaternion_to_rotation, Inertia, Mat3, Motion, Transform, Vec3};

/// Length of a target's state `[r_t (3); quat_t (4); ω (3); v (3)]`.
pub const TARGET_STATE_LEN: usize = 13;

/// How far from 1 the norm of the grasp's quaternion may be: six printed digits.
pub const GRASP_QUATERNION_TOLERANCE: f64 = 1e-6;

/// A free rigid body to be captured (module docs for the frames), validated on construction.
///
/// ```
/// use orbitflex::capture::Target;
/// use orbitflex::spatial::{Mat3, Vec3};
/// // 200 kg, tumbling at 2 deg/s about its body z axis, its handle 0.8 m along body x
/// let inertia = Mat3::from_diagonal(&Vec3::new(40.0, 50.0, 60.0));
/// let rate = 2f64.to_radians();
/// let target = Target::new(
///     200.0,
///     inertia,
///     &[3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
///     &[0.0, 0.0, rate, 0.0, 0.0, 0.0],
///     &[0.8, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
/// )?;
/// // spin momentum 60 kg·m² × rate about z, at the origin: no orbital part
/// assert!((target.momentum()[2] - 60.0 * rate).abs() < 1e-12);
/// assert!((target.kinetic_energy() - 0.5 * 60.0 * rate * rate).abs() < 1e-15);
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    name: String,
    about_com: Mat3,
    inertia: Inertia,
    pose: [f64; 7],
    twist: Motion,
    grasp: [f64; 7],
}

impl Target {
    /// A target named `"target"` whose centre of mass is the origin of its frame: `mass` (kg),
    /// `inertia_about_com` (kg·m², `t` axes), `pose = [r_t; quat_t]` (its quaternion is
    /// normalised, as the base's), `twist = [ω; v]` (`t` frame) and `grasp`, the pose `[p; quat]`
    /// of the handle's frame in `t` (its quaternion must have norm 1 within
    /// [`GRASP_QUATERNION_TOLERANCE`]; it maps handle components to `t` components).
    ///
    /// Errors name what is wrong: a shape, a non-finite number, a mass ≤ 0, an inertia that is not
    /// symmetric, not positive definite or violates the triangle inequality, a zero pose
    /// quaternion, a grasp quaternion that is not a unit quaternion.
    pub fn new(
        mass: f64,
        inertia_about_com: Mat3,
        pose: &[f64],
        twist: &[f64],
        grasp: &[f64],
    ) -> Result<Self> {
        Self::build(
            "target",
            mass,
            Vec3::zeros(),
            inertia_about_com,
            pose,
            twist,
            grasp,
        )
    }

    /// This target with its centre of mass at `com` (m, `t` frame), validated again.
    pub fn with_com(&self, com: Vec3) -> Result<Self> {
        Self::build(
            &self.name,
            self.inertia.mass,
            com,
            self.about_com,
            &self.pose,
            &self.twist.to_array(),
            &self.grasp,
        )
    }

    /// This target under another name (used in its error messages and plots).
    pub fn named(mut self, name: &str) -> Self {
        self.name = name.to_string();
        self
    }

    /// This target at another state `[r_t; quat_t; ω; v]` (13 numbers; the quaternion is
    /// normalised), for example after propagating it with [`rigid_body_derivative`].
    pub fn at_state(&self, state: &[f64]) -> Result<Self> {
        check_vector(&self.what("state"), state, TARGET_STATE_LEN)?;
        Self::build(
            &self.name,
            self.inertia.mass,
            self.inertia.com,
            self.about_com,
            &state[..7],
            &state[7..],
            &self.grasp,
        )
    }

    fn build(
        name: &str,
        mass: f64,
        com: Vec3,
        about_com: Mat3,
        pose: &[f64],
        twist: &[f64],
        grasp: &[f64],
    ) -> Result<Self> {
        let what = |part: &str| format!("target '{name}': {part}");
        let invalid = |part: &str, message: String| Error::InvalidArgument {
            what: what(part),
            message,
        };
        if mass.is_nan() || mass <= 0.0 {
            return Err(invalid(
                "mass",
                format!("expected a mass > 0 kg (a free body), given {mass}"),
            ));
        }
        check_finite(&what("com"), com.as_slice())?;
        check_finite(&what("inertia"), about_com.as_slice())?;
        check_inertia(mass, &com, &about_com).map_err(|m| invalid("inertia", m))?;
        check_positive_definite(&about_com).map_err(|m| invalid("inertia", m))?;
        check_vector(&what("pose"), pose, 7)?;
        check_vector(&what("twist"), twist, 6)?;
        check_vector(&what("grasp"), grasp, 7)?;
        let mut pose: [f64; 7] = pose.try_into().expect("checked length");
        let norm = quaternion_norm(&pose[3..]);
        if !(norm.is_finite() && norm >= 1e-9) {
            return Err(invalid(
                "pose",
                format!(
                    "the quaternion (elements 3..7, x y z w) has norm {norm:e}; expected a unit \
                     quaternion"
                ),
            ));
        }
        normalise_quaternion(&mut pose[3..]);
        let mut grasp: [f64; 7] = grasp.try_into().expect("checked length");
        let norm = quaternion_norm(&grasp[3..]);
        if norm.is_nan() || (norm - 1.0).abs() > GRASP_QUATERNION_TOLERANCE {
            return Err(invalid(
                "grasp",
                format!(
                    "the quaternion (elements 3..7, x y z w) has norm {norm}; expected a unit \
                     quaternion (norm 1 within {GRASP_QUATERNION_TOLERANCE:e})"
                ),
            ));
        }
        normalise_quaternion(&mut grasp[3..]);
        if grasp[..3].iter().any(|v| v.abs() > MAX_LENGTH) {
            return Err(invalid(
                "grasp",
                format!(
                    "the handle's position {:?} m is farther than the {MAX_LENGTH:e} m supported",
                    &grasp[..3]
                ),
            ));
        }
        Ok(Self {
            name: name.to_string(),
            about_com,
            inertia: Inertia::from_com(mass, com, about_com),
            pose,
            twist: Motion::from_slice(twist),
            grasp,
        })
    }

    fn what(&self, part: &str) -> String {
        format!("target '{}': {part}", self.name)
    }

    /// The name given (default `"target"`).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// `m` (kg).
    pub fn mass(&self) -> f64 {
        self.inertia.mass
    }
    /// The centre of mass `c` (m, `t` frame).
    pub fn com(&self) -> Vec3 {
        self.inertia.com
    }
    /// `I_c`, the rotational inertia about the centre of mass (kg·m², `t` axes), as given.
    pub fn inertia_about_com(&self) -> &Mat3 {
        &self.about_com
    }
    /// `Y`: the spatial inertia about the origin of `t`, in `t` (A.9).
    pub fn spatial_inertia(&self) -> &Inertia {
        &self.inertia
    }
    /// `[r_t; quat_t]`, the quaternion normalised.
    pub fn pose(&self) -> &[f64; 7] {
        &self.pose
    }
    /// `W = [ω; v]` (rad/s, m/s; `t` frame).
    pub fn twist(&self) -> &Motion {
        &self.twist
    }
    /// The handle's pose `[p; quat]` in `t`, the quaternion normalised.
    pub fn grasp(&self) -> &[f64; 7] {
        &self.grasp
    }
    /// The state `[r_t; quat_t; ω; v]` (13 numbers).
    pub fn state(&self) -> [f64; TARGET_STATE_LEN] {
        let mut s = [0.0; TARGET_STATE_LEN];
        s[..7].copy_from_slice(&self.pose);
        self.twist.write_to(&mut s[7..]);
        s
    }

    /// `t`'s axes (columns, `t` to inertial components) and origin (m, inertial).
    pub fn placement(&self) -> (Mat3, Vec3) {
        let p = &self.pose;
        (quaternion_to_rotation(&p[3..]), Vec3::new(p[0], p[1], p[2]))
    }

    /// The handle's inertial pose `[position (m); quaternion (x, y, z, w), w ≥ 0]`.
    pub fn grasp_pose(&self) -> [f64; 7] {
        let (axes, origin) = self.placement();
        let g = &self.grasp;
        let position = origin + axes * Vec3::new(g[0], g[1], g[2]);
        crate::algorithms::pose(&position, &(axes * quaternion_to_rotation(&g[3..])))
    }

    /// Total momentum `[angular about the inertial origin; linear]`, inertial components
    /// (model §6.1): `L = R_t m (v + ω × c)`, `K = R_t (I ω + m c × v) + r_t × L` with `I` about
    /// the origin of `t`.
    pub fn momentum(&self) -> [f64; 6] {
        rigid_body_momentum(&self.inertia, &self.pose, &self.twist)
    }

    /// Kinetic energy `½ Wᵀ Y W` (J).
    pub fn kinetic_energy(&self) -> f64 {
        0.5 * self.twist.dot(&self.inertia.apply(&self.twist))
    }

    /// The derivative of [`state`](Self::state) ([`rigid_body_derivative`]).
    pub fn derivative(&self) -> [f64; TARGET_STATE_LEN] {
        let mut out = [0.0; TARGET_STATE_LEN];
        rigid_body_derivative(&self.inertia, &self.state(), &mut out);
        out
    }
}

fn quaternion_norm(quat: &[f64]) -> f64 {
    quat.iter().map(|v| v * v).sum::<f64>().sqrt()
}

/// A free body needs inertia about every axis: its angular velocity about an axis of zero
/// inertia is not determined by its momentum. Refused when the smallest principal moment is
/// below `1e-12` of the largest (round-off of the other two).
fn check_positive_definite(about_com: &Mat3) -> std::result::Result<(), String> {
    let moments = about_com.symmetric_eigenvalues();
    let mut m = [moments[0], moments[1], moments[2]];
    m.sort_by(|a, b| a.total_cmp(b));
    if m[0] > 1e-12 * m[2] {
        return Ok(());
    }
    Err(format!(
        "inertia is not positive definite: principal moments {:.6e}, {:.6e}, {:.6e} kg·m²; \
         expected every moment > 0 (a free body needs inertia about every axis)",
        m[0], m[1], m[2]
    ))
}

/// `[K; L]` of a rigid body with spatial inertia `inertia` (about its frame origin, A.9) at
/// `pose = [r; quat]` moving with `twist` (its own frame): its momentum `Y W` carried to the
/// inertial origin and axes.
pub fn rigid_body_momentum(inertia: &Inertia, pose: &[f64], twist: &Motion) -> [f64; 6] {
    momentum_in_inertial_frame(pose, &inertia.apply(twist))
}

/// The derivative of a free, torque-free rigid body's state `[r; quat; ω; v]` (13 numbers, twist
/// in its own frame, `v` the velocity of its frame origin) into `out` (13):
///
/// ```text
/// ṙ = R v,   quat' = ½ quat ⊗ (ω, 0)
/// I_c ω̇ = −ω × I_c ω                                    (Euler)
/// v_c = v + ω × c,   v̇_c = −ω × v_c                      (the centre of mass drifts)
/// v̇ = v̇_c − ω̇ × c = −ω × v_c − ω̇ × c
/// ```
///
/// `I_c` the rotational inertia about the centre of mass `c`; `v̇` the rate of the frame
/// components (as the base's `v̇_B`, model §4). No allocation.
///
/// # Panics
/// If `state` or `out` is shorter than 13, or if the inertia about the centre of mass is
/// singular (a [`Target`] never is).
pub fn rigid_body_derivative(inertia: &Inertia, state: &[f64], out: &mut [f64]) {
    let quat = &state[3..7];
    let omega = Vec3::new(state[7], state[8], state[9]);
    let v = Vec3::new(state[10], state[11], state[12]);
    let c = inertia.com;
    let about_com = inertia.inertia_about_com();
    let omega_dot = about_com
        .cholesky()
        .expect("a free body's inertia is positive definite")
        .solve(&-omega.cross(&(about_com * omega)));
    let v_com = v + omega.cross(&c);
    let v_dot = -omega.cross(&v_com) - omega_dot.cross(&c);
    let r_dot = quaternion_to_rotation(quat) * v;
    out[..3].copy_from_slice(r_dot.as_slice());
    out[3..7].copy_from_slice(&quaternion_rate(quat, &omega));
    out[7..10].copy_from_slice(omega_dot.as_slice());
    out[10..13].copy_from_slice(v_dot.as_slice());
}

/// `Φ_{g,t}`: the handle's frame `g` seen from `t` (motions from `t` to `g`), from `grasp`.
pub fn grasp_transform(grasp: &[f64; 7]) -> Transform {
    Transform::new(
        quaternion_to_rotation(&grasp[3..]).transpose(),
        Vec3::new(grasp[0], grasp[1], grasp[2]),
    )
}
