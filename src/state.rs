//! The state vector of the flexible floating-base arm (model §4): its layout, the one place where
//! its offsets live (and those of its tangent), split into named parts. The quaternion arithmetic
//! it uses lives in [`crate::spatial`].

use crate::spatial::{
    quaternion_exp, quaternion_log, quaternion_product, Vec3, POSE_POSITION, POSE_QUATERNION,
};
use std::ops::Range;

/// Offsets of the blocks of the state `x ∈ R^{13+4n+k}` (model §4):
///
/// ```text
/// x = [ r_B (3) | quat_B (4) | q (n) | θ (n) | ω_B (3) | v_B (3) | q̇ (n) | θ̇ (n) | Ω (k) ]
/// ```
/// configuration first, then velocities. `r_B` is the base origin in the inertial frame (m),
/// `quat_B = (x, y, z, w)` maps base-frame components to inertial ones, `q` and `θ` are the link
/// and (link-side) motor angles (rad), `[ω_B; v_B]` is the base twist in base-frame components,
/// and `Ω` the speeds of the `k` reaction wheels relative to the bus (rad/s; none without
/// wheels, [`crate::flex::ReactionWheels`]).
///
/// ```
/// use orbitflex::StateLayout;
/// let layout = StateLayout { n: 7, wheels: 0 };
/// assert_eq!(layout.len(), 41);
/// assert_eq!(layout.theta(), 14..21);
/// assert_eq!(StateLayout::with_wheels(7, 4).wheel_speed(), 41..45);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StateLayout {
    /// Number of joints.
    pub n: usize,
    /// Number of reaction wheels `k` (0 without).
    pub wheels: usize,
}

impl StateLayout {
    /// The layout of an arm of `n` joints without wheels.
    pub fn new(n: usize) -> Self {
        Self { n, wheels: 0 }
    }

    /// The layout of an arm of `n` joints and `k` reaction wheels.
    pub fn with_wheels(n: usize, k: usize) -> Self {
        Self { n, wheels: k }
    }

    /// Length `13 + 4n + k`.
    pub fn len(&self) -> usize {
        13 + 4 * self.n + self.wheels
    }

    /// Length `n + k` of a row of held inputs in a record: the motor torques `u` (n), then the
    /// wheel torques applied (k).
    pub fn inputs_len(&self) -> usize {
        self.n + self.wheels
    }
    /// Never empty (the base alone has 13 states).
    pub fn is_empty(&self) -> bool {
        false
    }
    /// `r_B`: base origin in the inertial frame (m).
    pub fn position(&self) -> Range<usize> {
        POSE_POSITION
    }
    /// `quat_B = (x, y, z, w)`: base-frame to inertial-frame components.
    pub fn quaternion(&self) -> Range<usize> {
        POSE_QUATERNION
    }
    /// `[r_B; quat_B]`.
    pub fn base_pose(&self) -> Range<usize> {
        0..7
    }
    /// Link angles `q` (rad).
    pub fn q(&self) -> Range<usize> {
        7..7 + self.n
    }
    /// Motor angles `θ` (rad, link side).
    pub fn theta(&self) -> Range<usize> {
        7 + self.n..7 + 2 * self.n
    }
    /// Base twist `[ω_B; v_B]` in base-frame components.
    pub fn base_twist(&self) -> Range<usize> {
        7 + 2 * self.n..13 + 2 * self.n
    }
    /// Link rates `q̇` (rad/s).
    pub fn qd(&self) -> Range<usize> {
        13 + 2 * self.n..13 + 3 * self.n
    }
    /// Motor rates `θ̇` (rad/s, link side).
    pub fn theta_dot(&self) -> Range<usize> {
        13 + 3 * self.n..13 + 4 * self.n
    }
    /// Reaction-wheel speeds `Ω` relative to the bus (rad/s), at the end (empty without wheels).
    pub fn wheel_speed(&self) -> Range<usize> {
        13 + 4 * self.n..self.len()
    }
    /// Everything but the base pose: `[q | θ | V_B | q̇ | θ̇ | Ω]`, the part the dynamics act on.
    pub fn dynamic(&self) -> Range<usize> {
        7..self.len()
    }

    /// Length `12 + 4n + k` of the tangent `dx` (model §4): the quaternion's four numbers become
    /// a rotation vector of three.
    pub fn tangent_len(&self) -> usize {
        self.len() - 1
    }

    /// `x ⊕ dx` into `out`: the tangent `dx = [δr_B | δφ_B | δq | δθ | δω_B | δv_B | δq̇ | δθ̇]`
    /// applied to `x`: `r_B + δr_B` (inertial frame), `quat_B ⊗ Exp(δφ_B)` (`δφ_B` a rotation
    /// vector in the base frame), and every other block added. Lengths: `x` and `out`
    /// `13 + 4n + k`, `dx` `12 + 4n + k`.
    pub fn integrate(&self, x: &[f64], dx: &[f64], out: &mut [f64]) {
        out[..3]
            .iter_mut()
            .zip(x[..3].iter().zip(&dx[..3]))
            .for_each(|(o, (a, b))| *o = a + b);
        let turn = quaternion_exp(&Vec3::new(dx[3], dx[4], dx[5]));
        out[POSE_QUATERNION].copy_from_slice(&quaternion_product(&x[POSE_QUATERNION], &turn));
        out[7..]
            .iter_mut()
            .zip(x[7..].iter().zip(&dx[6..]))
            .for_each(|(o, (a, b))| *o = a + b);
    }

    /// `x1 ⊖ x0` into `out`: the tangent with `integrate(x0, difference(x0, x1)) = x1`, the
    /// rotation taken the short way (`δφ_B = Log(quat_0* ⊗ quat_1)`, `|δφ_B| ≤ π`).
    pub fn difference(&self, x0: &[f64], x1: &[f64], out: &mut [f64]) {
        out[..3]
            .iter_mut()
            .zip(x1[..3].iter().zip(&x0[..3]))
            .for_each(|(o, (a, b))| *o = a - b);
        let q0 = &x0[POSE_QUATERNION];
        let conjugate = [-q0[0], -q0[1], -q0[2], q0[3]];
        let relative = quaternion_product(&conjugate, &x1[POSE_QUATERNION]);
        out[3..6].copy_from_slice(quaternion_log(&relative).as_slice());
        out[6..]
            .iter_mut()
            .zip(x1[7..].iter().zip(&x0[7..]))
            .for_each(|(o, (a, b))| *o = a - b);
    }

    /// The named blocks, in order, with their ranges: `base_pose`, `q`, `theta`, `base_twist`,
    /// `qd`, `theta_dot`, `wheel_speed` (empty without wheels). Bindings build their views from
    /// this list.
    pub fn blocks(&self) -> [(&'static str, Range<usize>); 7] {
        [
            ("base_pose", self.base_pose()),
            ("q", self.q()),
            ("theta", self.theta()),
            ("base_twist", self.base_twist()),
            ("qd", self.qd()),
            ("theta_dot", self.theta_dot()),
            ("wheel_speed", self.wheel_speed()),
        ]
    }

    /// Names of the state's elements, in order: `r_x … quat_w`, `q[joint]`, `theta[joint]`,
    /// `omega_x … v_z`, `qd[joint]`, `theta_dot[joint]`, `wheel_speed[w]`.
    pub fn element_names(&self, joint_names: &[&str]) -> Vec<String> {
        let per_joint =
            |prefix: &'static str| joint_names.iter().map(move |j| format!("{prefix}[{j}]"));
        ["r_x", "r_y", "r_z", "quat_x", "quat_y", "quat_z", "quat_w"]
            .iter()
            .map(|s| s.to_string())
            .chain(per_joint("q"))
            .chain(per_joint("theta"))
            .chain(
                ["omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z"]
                    .iter()
                    .map(|s| s.to_string()),
            )
            .chain(per_joint("qd"))
            .chain(per_joint("theta_dot"))
            .chain((0..self.wheels).map(|w| format!("wheel_speed[{w}]")))
            .collect()
    }

    /// The blocks of `x` as named slices.
    #[inline]
    pub fn split<'a>(&self, x: &'a [f64]) -> StateParts<'a> {
        StateParts {
            position: &x[self.position()],
            quaternion: &x[self.quaternion()],
            q: &x[self.q()],
            theta: &x[self.theta()],
            base_twist: &x[self.base_twist()],
            qd: &x[self.qd()],
            theta_dot: &x[self.theta_dot()],
            wheel_speed: &x[self.wheel_speed()],
        }
    }
}

/// The blocks of one state `x`, borrowed ([`StateLayout::split`]).
#[derive(Debug, Clone, Copy)]
pub struct StateParts<'a> {
    /// `r_B` (m, inertial frame).
    pub position: &'a [f64],
    /// `quat_B = (x, y, z, w)`.
    pub quaternion: &'a [f64],
    /// Link angles `q` (rad).
    pub q: &'a [f64],
    /// Motor angles `θ` (rad, link side).
    pub theta: &'a [f64],
    /// Base twist `[ω_B; v_B]` (base frame).
    pub base_twist: &'a [f64],
    /// Link rates `q̇` (rad/s).
    pub qd: &'a [f64],
    /// Motor rates `θ̇` (rad/s).
    pub theta_dot: &'a [f64],
    /// Reaction-wheel speeds `Ω` relative to the bus (rad/s; empty without wheels).
    pub wheel_speed: &'a [f64],
}

impl StateParts<'_> {
    /// `ω_B` (rad/s, base frame).
    #[inline]
    pub fn omega(&self) -> Vec3 {
        Vec3::new(self.base_twist[0], self.base_twist[1], self.base_twist[2])
    }
    /// `v_B` (m/s, base frame).
    #[inline]
    pub fn velocity(&self) -> Vec3 {
        Vec3::new(self.base_twist[3], self.base_twist[4], self.base_twist[5])
    }
}

/// Why `x` is not a valid state, if it is not: a non-finite element or a zero quaternion.
pub(crate) fn state_defect(layout: &StateLayout, x: &[f64]) -> Option<String> {
    if let Some(i) = x.iter().position(|v| !v.is_finite()) {
        return Some(format!("element {i} turned non-finite"));
    }
    let scale = x[layout.quaternion()]
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    if scale == 0.0 {
        return Some("the base quaternion collapsed to zero".into());
    }
    None
}
