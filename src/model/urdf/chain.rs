//! Step 3: the EE link, and the chain of joints from the root to it.

use super::parse::{Joint, JointKind};
use super::tree::Tree;
use crate::error::{Error, Result};
use std::collections::HashSet;

/// The EE link: the one asked for, or else the unique leaf, not counting leaves behind a locked
/// joint (a locked gripper jaw, say) unless they are all there is.
pub(super) fn ee_link<'a>(
    tree: &Tree<'a>,
    asked: Option<&'a str>,
    source: &str,
) -> Result<&'a str> {
    if let Some(name) = asked {
        if !tree.urdf.links.iter().any(|l| l.name == name) {
            return Err(Error::UnknownName {
                source_name: source.to_string(),
                what: "link (ee_link)",
                name: name.to_string(),
                available: tree.link_list(),
            });
        }
        return Ok(name);
    }
    let all_leaves = tree.leaves();
    let free: Vec<&str> = all_leaves
        .iter()
        .copied()
        .filter(|l| !tree.behind_lock.contains(l))
        .collect();
    let leaves = if free.is_empty() { all_leaves } else { free };
    match leaves.as_slice() {
        [leaf] => Ok(leaf),
        many => Err(Error::Branching {
            source_name: source.to_string(),
            message: format!(
                "the tree has {} candidate leaf links ({}), so the EE link is ambiguous; pass \
                 ee_link to choose one, or lock the joints of branches that are not the arm \
                 (locked_joints)",
                many.len(),
                many.iter()
                    .map(|l| format!("'{l}'"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }),
    }
}

/// The joints from the root to `ee_link`, root first. Every moving joint of the URDF must be
/// revolute or continuous and lie on this chain.
pub(super) fn chain<'a>(tree: &Tree<'a>, ee_link: &str, source: &str) -> Result<Vec<&'a Joint>> {
    let mut chain = Vec::new();
    let mut link = ee_link;
    while let Some(joint) = tree.parent_joint.get(link) {
        chain.push(*joint);
        link = joint.parent.as_str();
    }
    chain.reverse();
    let on_chain: HashSet<&str> = chain.iter().map(|j| j.name.as_str()).collect();
    for joint in tree.urdf.joints.iter().filter(|j| !tree.is_fixed(j)) {
        if !matches!(joint.kind, JointKind::Revolute | JointKind::Continuous) {
            return Err(Error::UnsupportedJoint {
                source_name: source.to_string(),
                joint: joint.name.clone(),
                kind: joint.kind.name().to_string(),
            });
        }
        if !on_chain.contains(joint.name.as_str()) {
            return Err(Error::Branching {
                source_name: source.to_string(),
                message: format!(
                    "joint '{}' ({}) branches off the chain from '{}' to the EE link '{ee_link}' \
                     at link '{}'; orbitflex models a serial chain: lock it with \
                     locked_joints=[\"{}\"] or choose another ee_link",
                    joint.name,
                    joint.kind.name(),
                    tree.root,
                    joint.parent,
                    joint.name
                ),
            });
        }
    }
    Ok(chain)
}
