//! Step 2: the URDF's links and joints as one checked kinematic tree.

use super::parse::{Joint, JointKind, Urdf};
use crate::error::{Error, Result};
use std::collections::{HashMap, HashSet};

/// The kinematic tree of a URDF: every link reached from the single root, at most one parent
/// joint per link, and the locked joints known.
pub(super) struct Tree<'a> {
    pub urdf: &'a Urdf,
    pub root: &'a str,
    /// The joint whose child is the link.
    pub parent_joint: HashMap<&'a str, &'a Joint>,
    /// The joints whose parent is the link, in file order.
    pub child_joints: HashMap<&'a str, Vec<&'a Joint>>,
    /// Joints held at zero and merged like fixed joints.
    pub locked: HashSet<&'a str>,
    /// Links below a locked joint.
    pub behind_lock: HashSet<&'a str>,
}

impl<'a> Tree<'a> {
    /// Builds and checks the tree: links and joints defined once, joints naming defined links,
    /// one parent per link, locked joints that exist, one root, every link reached from it.
    pub fn new(urdf: &'a Urdf, locked_joints: &'a [String], source: &str) -> Result<Self> {
        let invalid = |message: String| Error::InvalidModel {
            source_name: source.to_string(),
            message,
        };
        if urdf.links.is_empty() {
            return Err(invalid("the URDF has no <link>".into()));
        }
        let mut links = HashSet::new();
        for link in &urdf.links {
            if !links.insert(link.name.as_str()) {
                return Err(invalid(format!("link '{}' is defined twice", link.name)));
            }
        }
        let mut parent_joint = HashMap::new();
        let mut child_joints: HashMap<&str, Vec<&Joint>> = HashMap::new();
        let mut joint_names = HashSet::new();
        for joint in &urdf.joints {
            if !joint_names.insert(joint.name.as_str()) {
                return Err(invalid(format!("joint '{}' is defined twice", joint.name)));
            }
            for (role, name) in [("parent", &joint.parent), ("child", &joint.child)] {
                if !links.contains(name.as_str()) {
                    return Err(invalid(format!(
                        "joint '{}': {role} link '{name}' is not defined",
                        joint.name
                    )));
                }
            }
            if parent_joint.insert(joint.child.as_str(), joint).is_some() {
                return Err(invalid(format!(
                    "link '{}' is the child of more than one joint; a URDF must be a tree",
                    joint.child
                )));
            }
            child_joints
                .entry(joint.parent.as_str())
                .or_default()
                .push(joint);
        }
        if let Some(name) = locked_joints
            .iter()
            .find(|name| !joint_names.contains(name.as_str()))
        {
            return Err(Error::UnknownName {
                source_name: source.to_string(),
                what: "joint (in locked_joints)",
                name: name.clone(),
                available: names(urdf.joints.iter().map(|j| j.name.as_str())),
            });
        }
        let roots: Vec<&str> = urdf
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|l| !parent_joint.contains_key(l))
            .collect();
        let root = match roots.as_slice() {
            [root] => *root,
            [] => return Err(invalid("no root link: the joints form a cycle".into())),
            many => {
                return Err(invalid(format!(
                    "several root links ({}); a URDF must be a single tree",
                    many.join(", ")
                )))
            }
        };
        let mut tree = Tree {
            urdf,
            root,
            parent_joint,
            child_joints,
            locked: locked_joints.iter().map(String::as_str).collect(),
            behind_lock: HashSet::new(),
        };
        tree.check_reached(source)?;
        Ok(tree)
    }

    /// With one root and at most one parent per link, a link the root does not reach sits in a
    /// cycle (or a separate tree): reject it before any walk along parents. Also marks the links
    /// behind a locked joint.
    fn check_reached(&mut self, source: &str) -> Result<()> {
        let mut reached: HashSet<&str> = HashSet::from([self.root]);
        let mut stack = vec![self.root];
        while let Some(link) = stack.pop() {
            for joint in self.children(link).to_vec() {
                let child = joint.child.as_str();
                if reached.insert(child) {
                    if self.behind_lock.contains(link) || self.locked.contains(joint.name.as_str())
                    {
                        self.behind_lock.insert(child);
                    }
                    stack.push(child);
                }
            }
        }
        if reached.len() == self.urdf.links.len() {
            return Ok(());
        }
        let unreached = names(
            self.urdf
                .links
                .iter()
                .map(|l| l.name.as_str())
                .filter(|l| !reached.contains(l)),
        );
        Err(Error::InvalidModel {
            source_name: source.to_string(),
            message: format!(
                "links not connected to the root link '{}' (a cycle of joints, or a separate \
                 tree): {unreached}",
                self.root
            ),
        })
    }

    /// The joints whose parent is `link`.
    pub fn children(&self, link: &str) -> &[&'a Joint] {
        self.child_joints
            .get(link)
            .map(Vec::as_slice)
            .unwrap_or(&[])
    }

    /// True for a fixed joint or one named in `locked_joints`.
    pub fn is_fixed(&self, joint: &Joint) -> bool {
        joint.kind == JointKind::Fixed || self.locked.contains(joint.name.as_str())
    }

    /// Leaf links (links that are no joint's parent), depth-first from the root, children in
    /// file order: the order the bodies are numbered in.
    pub fn leaves(&self) -> Vec<&'a str> {
        self.depth_first()
            .into_iter()
            .filter(|l| !self.child_joints.contains_key(l))
            .collect()
    }

    /// Every link, depth-first from the root (pre-order), children in file order.
    pub fn depth_first(&self) -> Vec<&'a str> {
        let mut order = Vec::with_capacity(self.urdf.links.len());
        let mut stack = vec![self.root];
        while let Some(link) = stack.pop() {
            order.push(link);
            stack.extend(self.children(link).iter().rev().map(|j| j.child.as_str()));
        }
        order
    }

    /// Every link name, comma-separated, for messages.
    pub fn link_list(&self) -> String {
        names(self.urdf.links.iter().map(|l| l.name.as_str()))
    }
}

fn names<'s>(names: impl Iterator<Item = &'s str>) -> String {
    names.collect::<Vec<_>>().join(", ")
}
