//! The immutable robot model.

use crate::spatial::{rotation_about_axis, Inertia, Transform, Vec3};

/// One revolute joint `i`: it connects body `parents()[i]` (`i − 1` on a chain) to body `i`.
#[derive(Debug, Clone, PartialEq)]
pub struct JointModel {
    /// Joint name (from the URDF, or given to the builder).
    pub name: String,
    /// Unit axis `h_i`, components in frame `i` (the child frame); `H_i = [h_i; 0]` (A.1).
    pub axis: Vec3,
    /// `Φ_{i,i-1}` at `q_i = 0`: the child frame's pose in the parent body's frame.
    pub origin: Transform,
    /// The joint's rated limits (a URDF's `<limit>`), where the model states them.
    pub limits: JointLimits,
}

/// A joint's limits as its model states them (a URDF's `<limit lower upper effort velocity>`),
/// link side; `None` where the model says nothing. They describe the hardware; the planner
/// takes its bounds from [`crate::Limits`], which can be made from them
/// ([`crate::Limits::from_robot`]).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointLimits {
    /// `(lower, upper)` of `q` (rad), `lower ≤ upper`. `None` for a continuous joint (or a
    /// revolute joint whose `<limit>` gives neither bound).
    pub position: Option<(f64, f64)>,
    /// `|q̇| ≤` this (rad/s), ≥ 0.
    pub velocity: Option<f64>,
    /// `|τ| ≤` this (N·m), ≥ 0: the torque the joint's actuator may apply to the link (for a
    /// flexible joint, the motor torque `u` after the gearbox).
    pub effort: Option<f64>,
}

impl JointLimits {
    /// No limits stated.
    pub const NONE: JointLimits = JointLimits {
        position: None,
        velocity: None,
        effort: None,
    };

    /// Checks the values: finite, `lower ≤ upper`, velocity and effort ≥ 0.
    pub fn check(&self) -> std::result::Result<(), String> {
        if let Some((lower, upper)) = self.position {
            if !(lower.is_finite() && upper.is_finite() && lower <= upper) {
                return Err(format!(
                    "position limits: expected finite lower <= upper (rad), given lower = {}, \
                     upper = {}",
                    crate::args::number(lower),
                    crate::args::number(upper)
                ));
            }
        }
        for (what, value) in [("velocity", self.velocity), ("effort", self.effort)] {
            if let Some(v) = value.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(format!(
                    "{what} limit: expected a finite number >= 0, given {}",
                    crate::args::number(v)
                ));
            }
        }
        Ok(())
    }
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

/// One end-effector: a named frame rigidly attached to a body, `Φ_{e,b}` from that body's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct EndEffector {
    /// The name of the EE frame (the URDF link whose frame it is).
    pub link: String,
    /// The body carrying it (`0` is the base).
    pub body: usize,
    /// `Φ_{e,b}`: the EE frame seen from the frame of its body (constant).
    pub transform: Transform,
}

/// A floating base carrying a tree of revolute joints: base `B` (body 0), links `1..=n`, and
/// `k ≥ 1` end-effector frames, each rigidly attached to one body. A serial chain is the tree
/// whose only end-effector is the EE frame `n+1` on link `n`.
///
/// Bodies are numbered depth-first from the base (pre-order), so each parent comes before its
/// children and every subtree is a contiguous range: body `i` hangs from body
/// [`parents()[i]`](Robot::parents) through joint `i`, and its subtree is
/// `i..i + subtree_sizes()[i]`. Every recursion reads the parent from there rather than
/// assuming `i − 1`. On a chain `parents()[i] = i − 1`.
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
    /// The end-effectors, at least one, in the order of `ee_links`.
    pub(crate) ees: Vec<EndEffector>,
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

    /// Joint names in body order (depth-first from the base; base to EE on a chain).
    pub fn joint_names(&self) -> Vec<&str> {
        self.joints.iter().map(|j| j.name.as_str()).collect()
    }

    /// The joints in body order.
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

    /// The body that carries the first end-effector's frame (the EE frame `n+1` of a chain).
    #[inline]
    pub fn ee_body(&self) -> usize {
        self.ees[0].body
    }

    /// Spatial inertia of body `i` about its own origin in its own frame (A.9); `0` is the base.
    pub fn inertias(&self) -> &[Inertia] {
        &self.inertias
    }

    /// Name of the first end-effector's link (the EE link of a chain).
    pub fn ee_link(&self) -> &str {
        &self.ees[0].link
    }

    /// `Φ_{e,b}` of the first end-effector: its frame in the frame of the body carrying it.
    pub fn ee_transform(&self) -> &Transform {
        &self.ees[0].transform
    }

    /// The end-effectors, in order: wrenches `[f_1; …; f_k]`, stacked Jacobians and the block
    /// columns of the operator `B` all follow it.
    pub fn end_effectors(&self) -> &[EndEffector] {
        &self.ees
    }

    /// The end-effector links' names, in [`end_effectors`](Self::end_effectors) order.
    pub fn ee_links(&self) -> Vec<&str> {
        self.ees.iter().map(|e| e.link.as_str()).collect()
    }

    /// The index of the end-effector named `name` in [`ee_links`](Self::ee_links).
    pub fn ee_index(&self, name: &str) -> crate::Result<usize> {
        self.ees
            .iter()
            .position(|e| e.link == name)
            .ok_or_else(|| crate::Error::InvalidArgument {
                what: "ee".into(),
                message: format!(
                    "no end-effector named {name:?}; the end-effectors are {}",
                    self.ee_list()
                ),
            })
    }

    /// Picks one end-effector: `Some(k)` checked against the count, or `None` when the robot has
    /// exactly one (an error that lists them otherwise).
    pub fn ee_choice(&self, ee: Option<usize>) -> crate::Result<usize> {
        let k = self.ees.len();
        match ee {
            Some(e) if e < k => Ok(e),
            Some(e) => Err(crate::Error::InvalidArgument {
                what: "ee".into(),
                message: format!(
                    "end-effector index {e} is out of range: the robot has {k} ({})",
                    self.ee_list()
                ),
            }),
            None if k == 1 => Ok(0),
            None => Err(crate::Error::InvalidArgument {
                what: "ee".into(),
                message: format!(
                    "the robot has {k} end-effectors ({}); say which one with ee= (a name or an \
                     index)",
                    self.ee_list()
                ),
            }),
        }
    }

    fn ee_list(&self) -> String {
        self.ees
            .iter()
            .map(|e| format!("'{}'", e.link))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Whether the joints form one serial chain (`parents()[i] = i − 1` for every body).
    #[inline]
    pub fn is_chain(&self) -> bool {
        self.parents
            .iter()
            .enumerate()
            .skip(1)
            .all(|(i, &p)| p == i - 1)
    }

    /// The number of bodies in each body's subtree (itself included); the subtree of body `i` is
    /// the contiguous range `i..i + subtree_sizes()[i]` (bodies are numbered depth-first).
    pub fn subtree_sizes(&self) -> Vec<usize> {
        let mut sizes = vec![1; self.parents.len()];
        for i in (1..sizes.len()).rev() {
            sizes[self.parents[i]] += sizes[i];
        }
        sizes
    }

    /// The children of each body, in order.
    pub fn children(&self) -> Vec<Vec<usize>> {
        let mut children = vec![Vec::new(); self.parents.len()];
        for i in 1..self.parents.len() {
            children[self.parents[i]].push(i);
        }
        children
    }

    /// Each joint's `(lower, upper)` position limits (rad), `(−∞, ∞)` where the model states
    /// none (continuous joints).
    pub fn position_limits(&self) -> Vec<(f64, f64)> {
        self.joints
            .iter()
            .map(|j| {
                j.limits
                    .position
                    .unwrap_or((f64::NEG_INFINITY, f64::INFINITY))
            })
            .collect()
    }

    /// Each joint's speed limit `|q̇_i|` (rad/s), `∞` where the model states none.
    pub fn velocity_limits(&self) -> Vec<f64> {
        self.joints
            .iter()
            .map(|j| j.limits.velocity.unwrap_or(f64::INFINITY))
            .collect()
    }

    /// Each joint's effort limit `|τ_i|` (N·m, link side), `∞` where the model states none.
    pub fn effort_limits(&self) -> Vec<f64> {
        self.joints
            .iter()
            .map(|j| j.limits.effort.unwrap_or(f64::INFINITY))
            .collect()
    }

    /// Total mass of base and links (kg).
    pub fn total_mass(&self) -> f64 {
        self.inertias.iter().map(|i| i.mass).sum()
    }
}
