//! The immutable robot model.

use crate::spatial::{rotation_about_axis, Inertia, Transform, Vec3};

/// One revolute joint `i` of the chain: it connects body `i-1` (parent) to body `i` (child).
#[derive(Debug, Clone, PartialEq)]
pub struct JointModel {
    /// Joint name (from the URDF, or given to the builder).
    pub name: String,
    /// Unit axis `h_i`, components in frame `i` (the child frame); `H_i = [h_i; 0]` (A.1).
    pub axis: Vec3,
    /// `Φ_{i,i-1}` at `q_i = 0`: the child frame's pose in the parent body's frame.
    pub origin: Transform,
}

impl JointModel {
    /// `Φ_{i,i-1}(q)` (A.5): the origin transform followed by the rotation `q` about `h_i`,
    /// which turns about the child origin, so `p_{i-1,i}` does not depend on `q`.
    #[inline]
    pub fn transform(&self, q: f64) -> Transform {
        let rotation = rotation_about_axis(&self.axis, q).tr_mul(&self.origin.rotation);
        Transform::new(rotation, self.origin.translation)
    }
}

/// A floating-base chain of revolute joints: base `B` (body 0), links `1..=n`, and the EE frame
/// `n+1` rigidly attached to the EE body (link `n` of the chain).
///
/// Bodies are numbered so that each parent comes before its children: body `i` hangs from body
/// [`parents()[i]`](Robot::parents) through joint `i`. Every recursion reads the parent from there
/// rather than assuming `i − 1`, so the loops already work on a tree; the models built today are
/// chains (`parents()[i] = i − 1`).
///
/// Built by [`crate::RobotBuilder`] or loaded from a URDF; validated on construction (physical
/// inertias, unit axes, a positive-definite mass matrix at `q = 0`). Immutable afterwards.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    pub(crate) name: String,
    pub(crate) source: String,
    pub(crate) link_names: Vec<String>,
    pub(crate) joints: Vec<JointModel>,
    /// `parents[i]` for body `i ≥ 1`; `parents[0] = 0` is unused.
    pub(crate) parents: Vec<usize>,
    pub(crate) inertias: Vec<Inertia>,
    /// The body carrying the EE frame.
    pub(crate) ee_body: usize,
    pub(crate) ee_link: String,
    pub(crate) ee_transform: Transform,
    /// The same model in joint frames (`super::frames`), derived by [`crate::RobotBuilder::build`].
    pub(crate) frames: super::JointFrames,
    /// One named frame per URDF link, depth-first (`super::visual`).
    pub(crate) link_frames: Vec<super::LinkFrame>,
    /// The URDF's `<visual>`s.
    pub(crate) visuals: Vec<super::Visual>,
    /// The URDF file's directory, where relative mesh paths start.
    pub(crate) urdf_dir: Option<std::path::PathBuf>,
}

impl Robot {
    /// Number of joints `n` (the base adds 6 more velocity coordinates).
    #[inline]
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The model's name (the URDF `<robot name>`).
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Where the model came from (a file path, `<urdf string>` or `<builder>`), used in messages.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// Joint names in chain order, base to EE.
    pub fn joint_names(&self) -> Vec<&str> {
        self.joints.iter().map(|j| j.name.as_str()).collect()
    }

    /// The joints in chain order.
    pub fn joints(&self) -> &[JointModel] {
        &self.joints
    }

    /// Names of the bodies: index 0 is the base (root link), `i` the child link of joint `i`.
    /// Links joined by fixed (or locked) joints are merged into these bodies.
    pub fn body_names(&self) -> &[String] {
        &self.link_names
    }

    /// The parent body of each body: `parents()[i] < i` for body `i ≥ 1` (joint `i` connects
    /// `parents()[i]` to `i`); entry 0, the base's, is 0 and unused. Length `n + 1`.
    #[inline]
    pub fn parents(&self) -> &[usize] {
        &self.parents
    }

    /// The bodies moved by the joints on the way from `body` to the base, `body` first:
    /// `body, parents()[body], …`, stopping before the base (empty for the base itself). Joint `k`
    /// moves `body` exactly when `k` is on this path.
    pub fn path_to_base(&self, body: usize) -> impl Iterator<Item = usize> + '_ {
        std::iter::successors(Some(body).filter(|&b| b > 0), move |&b| {
            Some(self.parents[b]).filter(|&p| p > 0)
        })
    }

    /// The body that carries the EE frame `n+1`.
    #[inline]
    pub fn ee_body(&self) -> usize {
        self.ee_body
    }

    /// Spatial inertia of body `i` about its own origin in its own frame (A.9); `0` is the base.
    pub fn inertias(&self) -> &[Inertia] {
        &self.inertias
    }

    /// Name of the link whose frame is the EE frame `n+1`.
    pub fn ee_link(&self) -> &str {
        &self.ee_link
    }

    /// `Φ_{n+1,e}`: the EE frame in the frame of the EE body `e` (constant).
    pub fn ee_transform(&self) -> &Transform {
        &self.ee_transform
    }

    /// Total mass of base and links (kg).
    pub fn total_mass(&self) -> f64 {
        self.inertias.iter().map(|i| i.mass).sum()
    }
}
