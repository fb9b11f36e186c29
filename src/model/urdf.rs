//! Loading a [`Robot`] from URDF (SPEC §7) with `urdf-rs`.
//!
//! The root link is the base `B`; the chain runs from the root to `ee_link`. Revolute and
//! continuous joints on the chain are the degrees of freedom. Fixed joints, and joints named in
//! `locked_joints` (held at zero), are merged: the child's inertia is moved into the body that
//! carries it and frames are composed. Any other moving joint, or one off the chain, is an error.

use super::{Robot, RobotBuilder};
use crate::error::{Error, Result};
use crate::spatial::{Inertia, Mat3, Transform, Vec3};
use std::collections::{HashMap, HashSet};
use std::path::Path;
use urdf_rs::JointType;

/// Options for URDF loading.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UrdfOptions {
    /// The link whose frame is the EE frame; `None` picks the unique leaf link of the tree, not
    /// counting leaves behind a locked joint.
    pub ee_link: Option<String>,
    /// Joints held at zero and treated as fixed (any type), e.g. gripper fingers.
    pub locked_joints: Vec<String>,
}

impl Robot {
    /// Loads a URDF file (SPEC §7). Errors name the file and the offending element.
    pub fn from_urdf(path: impl AsRef<Path>, options: &UrdfOptions) -> Result<Robot> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::FileNotFound {
            path: path.to_path_buf(),
            reason: e.to_string(),
        })?;
        load(&text, &path.display().to_string(), options)
    }

    /// Loads a URDF from its XML text (SPEC §7).
    pub fn from_urdf_string(xml: &str, options: &UrdfOptions) -> Result<Robot> {
        load(xml, "<urdf string>", options)
    }
}

fn joint_kind(kind: &JointType) -> &'static str {
    match kind {
        JointType::Revolute => "revolute",
        JointType::Continuous => "continuous",
        JointType::Prismatic => "prismatic",
        JointType::Fixed => "fixed",
        JointType::Floating => "floating",
        JointType::Planar => "planar",
        JointType::Spherical => "spherical",
    }
}

fn pose_transform(pose: &urdf_rs::Pose) -> Transform {
    Transform::from_xyz_rpy(pose.xyz.0, pose.rpy.0)
}

/// A link's inertia in its own frame, from the URDF `<inertial>` (COM frame pose, mass, inertia
/// about the COM in the COM frame's axes), validated.
fn link_inertia(link: &urdf_rs::Link, source: &str) -> Result<Inertia> {
    let inertial = &link.inertial;
    let i = &inertial.inertia;
    let in_com_axes = Mat3::new(
        i.ixx, i.ixy, i.ixz, //
        i.ixy, i.iyy, i.iyz, //
        i.ixz, i.iyz, i.izz,
    );
    // R_{com,link} = Eᵀ, so the inertia in link axes is E I Eᵀ.
    let com_frame = pose_transform(&inertial.origin);
    let e = com_frame.rotation.transpose();
    let about_com = e * in_com_axes * e.transpose();
    let mass = inertial.mass.value;
    super::builder::check_inertia(mass, &com_frame.translation, &about_com).map_err(|message| {
        Error::InvalidInertia {
            source_name: source.to_string(),
            link: link.name.clone(),
            message,
        }
    })?;
    Ok(Inertia::from_com(mass, com_frame.translation, about_com))
}

fn load(xml: &str, source: &str, options: &UrdfOptions) -> Result<Robot> {
    let urdf = urdf_rs::read_from_string(xml).map_err(|e| Error::Malformed {
        source_name: source.to_string(),
        format: "URDF",
        message: e.to_string(),
    })?;
    let invalid = |message: String| Error::InvalidModel {
        source_name: source.to_string(),
        message,
    };
    let link_list = || {
        urdf.links
            .iter()
            .map(|l| l.name.as_str())
            .collect::<Vec<_>>()
            .join(", ")
    };
    if urdf.links.is_empty() {
        return Err(invalid("the URDF has no <link>".into()));
    }

    let mut links: HashMap<&str, &urdf_rs::Link> = HashMap::new();
    for link in &urdf.links {
        if links.insert(link.name.as_str(), link).is_some() {
            return Err(invalid(format!("link '{}' is defined twice", link.name)));
        }
    }
    let mut parent_joint: HashMap<&str, &urdf_rs::Joint> = HashMap::new();
    let mut child_joints: HashMap<&str, Vec<&urdf_rs::Joint>> = HashMap::new();
    let mut joint_names = HashSet::new();
    for joint in &urdf.joints {
        if !joint_names.insert(joint.name.as_str()) {
            return Err(invalid(format!("joint '{}' is defined twice", joint.name)));
        }
        for (role, name) in [("parent", &joint.parent.link), ("child", &joint.child.link)] {
            if !links.contains_key(name.as_str()) {
                return Err(invalid(format!(
                    "joint '{}': {role} link '{name}' is not defined",
                    joint.name
                )));
            }
        }
        if parent_joint
            .insert(joint.child.link.as_str(), joint)
            .is_some()
        {
            return Err(invalid(format!(
                "link '{}' is the child of more than one joint; a URDF must be a tree",
                joint.child.link
            )));
        }
        child_joints
            .entry(joint.parent.link.as_str())
            .or_default()
            .push(joint);
    }

    for name in &options.locked_joints {
        if !joint_names.contains(name.as_str()) {
            return Err(Error::UnknownName {
                source_name: source.to_string(),
                what: "joint (in locked_joints)",
                name: name.clone(),
                available: urdf
                    .joints
                    .iter()
                    .map(|j| j.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
    }
    let locked: HashSet<&str> = options.locked_joints.iter().map(String::as_str).collect();
    let is_fixed =
        |j: &urdf_rs::Joint| j.joint_type == JointType::Fixed || locked.contains(j.name.as_str());

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

    // With one root and at most one parent per link, a link the root does not reach sits in a
    // cycle (or a separate tree); reject it before any walk along parents.
    let mut reached: HashSet<&str> = HashSet::from([root]);
    let mut behind_lock: HashSet<&str> = HashSet::new();
    let mut stack = vec![root];
    while let Some(link) = stack.pop() {
        for joint in child_joints.get(link).map(Vec::as_slice).unwrap_or(&[]) {
            let child = joint.child.link.as_str();
            if reached.insert(child) {
                if behind_lock.contains(link) || locked.contains(joint.name.as_str()) {
                    behind_lock.insert(child);
                }
                stack.push(child);
            }
        }
    }
    if reached.len() != urdf.links.len() {
        let unreached: Vec<&str> = urdf
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|l| !reached.contains(l))
            .collect();
        return Err(invalid(format!(
            "links not connected to the root link '{root}' (a cycle of joints, or a separate \
             tree): {}",
            unreached.join(", ")
        )));
    }

    let ee_link: &str = match &options.ee_link {
        Some(name) => {
            if !links.contains_key(name.as_str()) {
                return Err(Error::UnknownName {
                    source_name: source.to_string(),
                    what: "link (ee_link)",
                    name: name.clone(),
                    available: link_list(),
                });
            }
            name.as_str()
        }
        None => {
            // Leaves behind a locked joint (a locked gripper jaw, say) are not EE candidates,
            // unless they are all there is.
            let all_leaves: Vec<&str> = urdf
                .links
                .iter()
                .map(|l| l.name.as_str())
                .filter(|l| !child_joints.contains_key(l))
                .collect();
            let free: Vec<&str> = all_leaves
                .iter()
                .copied()
                .filter(|l| !behind_lock.contains(l))
                .collect();
            let leaves = if free.is_empty() { all_leaves } else { free };
            match leaves.as_slice() {
                [leaf] => leaf,
                many => {
                    return Err(Error::Branching {
                        source_name: source.to_string(),
                        message: format!(
                            "the tree has {} candidate leaf links ({}), so the EE link is \
                             ambiguous; pass ee_link to choose one, or lock the joints of \
                             branches that are not the arm (locked_joints)",
                            many.len(),
                            many.join(", ")
                        ),
                    })
                }
            }
        }
    };

    // The chain: joints from the root to ee_link.
    let mut chain: Vec<&urdf_rs::Joint> = Vec::new();
    let mut link = ee_link;
    while let Some(joint) = parent_joint.get(link) {
        chain.push(joint);
        link = joint.parent.link.as_str();
    }
    chain.reverse();
    let on_chain: HashSet<&str> = chain.iter().map(|j| j.name.as_str()).collect();

    for joint in &urdf.joints {
        if is_fixed(joint) {
            continue;
        }
        match joint.joint_type {
            JointType::Revolute | JointType::Continuous => {}
            _ => {
                return Err(Error::UnsupportedJoint {
                    source_name: source.to_string(),
                    joint: joint.name.clone(),
                    kind: joint_kind(&joint.joint_type).to_string(),
                })
            }
        }
        if !on_chain.contains(joint.name.as_str()) {
            return Err(Error::Branching {
                source_name: source.to_string(),
                message: format!(
                    "joint '{}' ({}) branches off the chain from '{root}' to the EE link \
                     '{ee_link}' at link '{}'; orbitflex models a serial chain: lock it with \
                     locked_joints=[\"{}\"] or choose another ee_link",
                    joint.name,
                    joint_kind(&joint.joint_type),
                    joint.parent.link,
                    joint.name
                ),
            });
        }
    }

    // Walk the tree from the root. Each link belongs to a body: the base, or the child link of
    // a moving chain joint. `placement[link] = (body, Φ_{link,body})`. Every moving joint is on
    // the chain, so bodies are numbered in chain order.
    let mut placement: HashMap<&str, (usize, Transform)> = HashMap::new();
    let mut bodies: Vec<(&str, Option<(&urdf_rs::Joint, Transform)>)> = vec![(root, None)];
    placement.insert(root, (0, Transform::identity()));
    let mut stack = vec![root];
    while let Some(parent) = stack.pop() {
        let (parent_body, parent_in_body) = placement[parent];
        for joint in child_joints.get(parent).map(Vec::as_slice).unwrap_or(&[]) {
            let child = joint.child.link.as_str();
            // Φ_{child,body} at q = 0: the joint origin composed with the parent's placement.
            let origin = pose_transform(&joint.origin).compose(&parent_in_body);
            if is_fixed(joint) {
                placement.insert(child, (parent_body, origin));
            } else {
                bodies.push((child, Some((joint, origin))));
                placement.insert(child, (bodies.len() - 1, Transform::identity()));
            }
            stack.push(child);
        }
    }

    let mut inertias = vec![Inertia::zero(); bodies.len()];
    for link in &urdf.links {
        let (body, in_body) = placement[link.name.as_str()];
        let inertia = link_inertia(link, source)?.transformed_to_parent(&in_body);
        inertias[body] = inertias[body].add(&inertia);
    }

    let mut builder = RobotBuilder::new(&urdf.name, root, inertias[0]).source(source);
    for ((link, joint), inertia) in bodies.iter().zip(&inertias).skip(1) {
        let (joint, origin) = joint.expect("every body after the base has a joint");
        let axis = Vec3::from(joint.axis.xyz.0);
        builder = builder.joint(&joint.name, origin, axis, link, *inertia);
    }
    let (ee_body, ee_in_body) = placement[ee_link];
    debug_assert_eq!(ee_body, bodies.len() - 1);
    builder.ee(ee_link, ee_in_body).build()
}
