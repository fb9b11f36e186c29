//! Joint frames: the frames the recursive algorithms compute in.
//!
//! A URDF puts each joint axis `h_i` anywhere in its link's frame. The recursions only need one
//! frame per body, so the model also keeps each body in its **joint frame**: the link frame turned
//! about its own origin by a constant rotation `Q_i` chosen so that `Q_i h_i = e_z`. In joint
//! frames `H_i = [e_z; 0]` selects a column, `U = I^A H` is a column read, `D = Hᵀ U` is one entry,
//! and the joint rotation `Φ(q)` mixes two rows of a constant matrix. The base keeps its frame
//! (`Q_0 = 𝟙`), so base-frame results (`f_B`, `α_B`, momentum) are unchanged, and joint-space
//! results do not depend on body frames at all. Only the per-body buffers of
//! [`crate::algorithms::Data`] are in joint frames; [`Robot::joint_frame_rotation`] maps them back.

use super::Robot;
use crate::spatial::{
    rotation_about_axis, ArticulatedInertia, Force, Inertia, Mat3, Transform, Vec3,
};

/// The model in joint frames (module docs), derived from the public link-frame model when a
/// [`Robot`] is built.
#[derive(Debug, Clone, PartialEq, Default)]
pub(crate) struct JointFrames {
    /// Per joint (index `i − 1` for body `i`): `Φ'_{i,λ(i)}` at `q = 0`, the joint frame of body
    /// `i` seen from the joint frame of its parent.
    pub(crate) origins: Vec<Transform>,
    /// Per joint: `Some((γ, cos α, sin α))` for a tilted joint, whose `R'_0 = R_z(−γ) R_x(−α)`
    /// ([`JointFrames::new`]).
    pub(crate) tilts: Vec<Option<Tilt>>,
    /// Body inertias in joint frames (index 0 is the base, unchanged).
    pub(crate) inertias: Vec<Inertia>,
    /// The same in the block form of the ABA, where each body's recursion starts.
    pub(crate) articulated: Vec<ArticulatedInertia>,
    /// Per end-effector, `Φ_{e,b}` from the joint frame of the body carrying it.
    pub(crate) ee_transforms: Vec<Transform>,
    /// `Q_i`: link-frame components to joint-frame components (index 0 is the base, `𝟙`).
    pub(crate) rotations: Vec<Mat3>,
    /// Per named frame ([`Robot::frames`]): its placement from the joint frame of its body.
    pub(crate) link_frames: Vec<Transform>,
}

/// `(γ, cos α, sin α)` of a tilted joint.
pub(crate) type Tilt = (f64, f64, f64);

impl JointFrames {
    /// The joint frames of `robot`'s link-frame model (its `joints`, `inertias`, `parents` and
    /// EE frame; the axes must already be unit vectors).
    ///
    /// `Q_i h_i = e_z` leaves one turn about `e_z` free per body. It is spent on the body's first
    /// child `k`, as Denavit–Hartenberg frames do: turned so that `R'_{k,i}` at `q = 0` has a zero
    /// entry `(2, 0)`, it factors as `R_z(−γ_k) R_x(−α_k)`, and joint `k` becomes a *tilted*
    /// joint, `R(q) = R_z(−(q + γ_k)) R_x(−α_k)`, whose congruence on an inertia is two plane
    /// turns and a shift. `R'_0` is then rebuilt from `γ_k` and `α_k` (a change at round-off
    /// level). Joints on the base, and later children of a body, keep a general `R'_0`.
    pub(crate) fn new(robot: &Robot) -> Self {
        let n = robot.joints.len();
        let mut rotations = vec![Mat3::identity()];
        rotations.extend(robot.joints.iter().map(|j| to_z(&j.axis)));
        for i in 1..=n {
            let Some(k) = (i + 1..=n).find(|&k| robot.parents[k] == i) else {
                continue;
            };
            let g = rotations[k] * robot.joints[k - 1].origin.rotation * rotations[i].transpose();
            // entry (2, 0) of g R_z(−φ) is g20 cos φ − g21 sin φ
            let phi = g[(2, 0)].atan2(g[(2, 1)]);
            rotations[i] = rotation_about_axis(&Vec3::z(), phi) * rotations[i];
        }
        let turn = |i: usize| Transform::new(rotations[i], Vec3::zeros());
        let back = |i: usize| Transform::new(rotations[i].transpose(), Vec3::zeros());
        let mut tilts = Vec::with_capacity(n);
        let origins = (1..=n)
            .map(|i| {
                let (joint, parent) = (&robot.joints[i - 1], robot.parents[i]);
                // Φ'_{i,λ} = Φ_{i',i} Φ_{i,λ} Φ_{λ,λ'}
                let mut origin = turn(i).compose(&joint.origin.compose(&back(parent)));
                let first_child = parent > 0 && (parent + 1..i).all(|k| robot.parents[k] != parent);
                let tilt = first_child.then(|| {
                    let r = &origin.rotation;
                    let gamma = (-r[(1, 0)]).atan2(r[(0, 0)]);
                    let alpha = (-r[(2, 1)]).atan2(r[(2, 2)]);
                    (gamma, alpha.cos(), alpha.sin())
                });
                if let Some((gamma, ca, sa)) = tilt {
                    origin.rotation = tilted_rotation(gamma, ca, sa);
                }
                tilts.push(tilt);
                origin
            })
            .collect();
        let inertias = robot
            .inertias
            .iter()
            .enumerate()
            .map(|(i, inertia)| inertia.transformed_to_parent(&back(i)))
            .collect::<Vec<_>>();
        let articulated = inertias.iter().map(ArticulatedInertia::from).collect();
        let ee_transforms = robot
            .ees
            .iter()
            .map(|e| e.transform.compose(&back(e.body)))
            .collect();
        let link_frames = robot
            .link_frames
            .iter()
            .map(|f| f.placement.compose(&back(f.body)))
            .collect();
        Self {
            link_frames,
            origins,
            tilts,
            inertias,
            articulated,
            ee_transforms,
            rotations,
        }
    }
}

/// `R_z(−θ) R_x(−α)` from `θ`, `cos α` and `sin α`:
/// `[[c, s cα, s sα], [−s, c cα, c sα], [0, −sα, cα]]` with `c = cos θ`, `s = sin θ`.
#[inline(always)]
fn tilted_rotation(theta: f64, ca: f64, sa: f64) -> Mat3 {
    let (s, c) = theta.sin_cos();
    Mat3::new(c, s * ca, s * sa, -s, c * ca, c * sa, 0.0, -sa, ca)
}

/// `Φ'_{i,λ}(q)` (A.5) in joint frames: the rotation `q` about `e_z` after the constant `origin`,
/// `R = R_z(q)ᵀ R'_0`, which changes only the first two rows of `R'_0`; a tilted joint builds
/// `R_z(−(q + γ)) R_x(−α)` directly. `p_{λ,i}` does not depend on `q`.
#[inline(always)]
pub(crate) fn joint_transform(origin: &Transform, tilt: &Option<Tilt>, q: f64) -> Transform {
    if let Some((gamma, ca, sa)) = *tilt {
        return Transform::new(tilted_rotation(q + gamma, ca, sa), origin.translation);
    }
    let (s, c) = q.sin_cos();
    let r = &origin.rotation;
    let mut rotation = *r;
    for j in 0..3 {
        let (a, b) = (r[(0, j)], r[(1, j)]);
        rotation[(0, j)] = c * a + s * b;
        rotation[(1, j)] = c * b - s * a;
    }
    Transform::new(rotation, origin.translation)
}

/// A rotation `Q` with `Q h = e_z` for a unit `h`: the turn about `h × e_z` by the angle between
/// them, `Q = 𝟙 + [w]× + [w]×² / (1 + h_z)` with `w = h × e_z`. For `h_z < 0` the half turn
/// `diag(1, −1, −1)` is applied first, so `1 + h_z ≥ 1` and nothing cancels. Axes along a
/// coordinate axis give exact 0 and ±1 entries.
pub(crate) fn to_z(h: &Vec3) -> Mat3 {
    let (flip, h) = if h.z < 0.0 {
        let flip = Mat3::from_diagonal(&Vec3::new(1.0, -1.0, -1.0));
        (flip, flip * h)
    } else {
        (Mat3::identity(), *h)
    };
    let w = crate::spatial::skew(&Vec3::new(h.y, -h.x, 0.0));
    (Mat3::identity() + w + w * w / (1.0 + h.z)) * flip
}

impl Robot {
    /// `Q_i`: the constant rotation from body `i`'s link frame (the URDF frame, in which
    /// [`JointModel::axis`](super::JointModel::axis) and [`inertias`](Robot::inertias) are given)
    /// to its joint frame, in which its joint axis is `e_z`; `Q_0 = 𝟙`. The per-body buffers of
    /// [`crate::algorithms::Data`] (`v`, `acc`, `f`, …) are in joint frames: `Q_iᵀ v` gives
    /// link-frame components.
    pub fn joint_frame_rotation(&self, i: usize) -> &Mat3 {
        &self.frames.rotations[i]
    }

    /// `Φ'_{i,λ(i)}(q)` for body `i ≥ 1`, in joint frames.
    #[inline(always)]
    pub(crate) fn joint_transform(&self, i: usize, q: f64) -> Transform {
        joint_transform(&self.frames.origins[i - 1], &self.frames.tilts[i - 1], q)
    }

    /// The constant parts of joint `i ≥ 1`'s transform ([`joint_transform`]): the origin
    /// `Φ'_0` and the tilt `(γ, cos α, sin α)` of a tilted joint. For the lane kernels
    /// (`crate::lanes`), which build the transforms of many runs at once.
    #[inline(always)]
    pub(crate) fn joint_frame(&self, i: usize) -> (&Transform, Option<(f64, f64, f64)>) {
        (&self.frames.origins[i - 1], self.frames.tilts[i - 1])
    }

    /// Whether joint `i ≥ 1` is tilted ([`JointFrames::new`]), so that
    /// [`ArticulatedInertia::tilted_to_parent`](crate::spatial::ArticulatedInertia::tilted_to_parent)
    /// applies to its transform.
    #[inline(always)]
    pub(crate) fn is_tilted(&self, i: usize) -> bool {
        self.frames.tilts[i - 1].is_some()
    }

    /// The body inertias in joint frames.
    #[inline(always)]
    pub(crate) fn frame_inertias(&self) -> &[Inertia] {
        &self.frames.inertias
    }

    /// The body inertias in joint frames, in the ABA's block form.
    #[inline(always)]
    pub(crate) fn frame_articulated(&self) -> &[ArticulatedInertia] {
        &self.frames.articulated
    }

    /// `Φ_{e,b}` of end-effector `e` from the joint frame of its body.
    #[inline(always)]
    pub(crate) fn frame_ee_transform(&self, e: usize) -> &Transform {
        &self.frames.ee_transforms[e]
    }

    /// Adds every end-effector wrench, `Φ_{e,b}ᵀ f_e`, to the force of the body carrying it
    /// (joint frames): `ee_wrench` is `[f_1; …; f_k]` or empty (A.8, A.12).
    #[inline(always)]
    pub(crate) fn add_ee_wrenches(&self, forces: &mut [Force], ee_wrench: &[f64]) {
        for (e, w) in ee_wrench.chunks_exact(6).enumerate() {
            forces[self.ees[e].body] +=
                self.frames.ee_transforms[e].apply_force_transpose(&Force::from_slice(w));
        }
    }

    /// Each named frame's placement from the joint frame of its body.
    #[inline(always)]
    pub(crate) fn frame_link_transforms(&self) -> &[Transform] {
        &self.frames.link_frames
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn to_z_turns_the_axis_onto_e_z() {
        let axes = [
            Vec3::x(),
            Vec3::y(),
            Vec3::z(),
            -Vec3::x(),
            -Vec3::y(),
            -Vec3::z(),
            Vec3::new(0.3, -0.5, 0.8).normalize(),
            Vec3::new(-0.6, 0.2, -0.7).normalize(),
            Vec3::new(1e-9, 0.0, -1.0).normalize(),
        ];
        for h in axes {
            let q = to_z(&h);
            assert!((q * h - Vec3::z()).amax() < 1e-15, "{h:?}");
            assert!(
                (q * q.transpose() - Mat3::identity()).amax() < 1e-15,
                "{h:?}"
            );
            assert!((q.determinant() - 1.0).abs() < 1e-15, "{h:?}");
        }
        // coordinate axes give exact rotations
        assert_eq!(to_z(&Vec3::y()) * Vec3::y(), Vec3::z());
        assert_eq!(
            to_z(&-Vec3::z()),
            Mat3::from_diagonal(&Vec3::new(1.0, -1.0, -1.0))
        );
        assert_eq!(to_z(&Vec3::z()), Mat3::identity());
    }

    #[test]
    fn joint_transform_equals_the_turn_about_e_z() {
        let origin = Transform::new(
            rotation_about_axis(&Vec3::new(0.2, 0.9, -0.4).normalize(), 0.7),
            Vec3::new(0.1, -0.2, 0.3),
        );
        for q in [0.0, 0.4, -2.9, 3.5] {
            let fast = joint_transform(&origin, &None, q);
            let slow = rotation_about_axis(&Vec3::z(), q).tr_mul(&origin.rotation);
            assert!((fast.rotation - slow).amax() < 1e-15, "{q}");
            assert_eq!(fast.translation, origin.translation);
        }
    }

    /// The joint-frame model is the link-frame model seen through `Q_i`: every joint transform
    /// equals `Q_i Φ_{i,λ}(q) Q_λᵀ`, tilted or not, and exactly the first children of non-base
    /// bodies are tilted.
    #[test]
    fn joint_frames_reproduce_the_link_frame_model() {
        use crate::testing::{random_chain, random_tree, TREE_THREE_ARMS};
        for robot in [
            random_chain(9, 3),
            random_tree(TREE_THREE_ARMS, 5),
            Robot::space_arm(),
        ] {
            let n = robot.dof();
            for i in 1..=n {
                let parent = robot.parents()[i];
                let first_child = (1..i).all(|k| robot.parents()[k] != parent);
                assert_eq!(robot.is_tilted(i), parent > 0 && first_child, "joint {i}");
                for q in [0.0, 0.8, -2.3] {
                    let link = robot.joints()[i - 1].transform(q);
                    let (qi, ql) = (
                        robot.joint_frame_rotation(i),
                        robot.joint_frame_rotation(parent),
                    );
                    let expected =
                        Transform::new(qi * link.rotation * ql.transpose(), ql * link.translation);
                    let got = robot.joint_transform(i, q);
                    assert!(
                        (got.rotation - expected.rotation).amax() < 1e-14,
                        "joint {i}, q {q}"
                    );
                    assert!((got.translation - expected.translation).amax() < 1e-15);
                }
                assert!(
                    (robot.joint_frame_rotation(i) * robot.joints()[i - 1].axis - Vec3::z()).amax()
                        < 1e-15
                );
            }
        }
    }
}
