//! Step 3: the end-effector links, and the check that every moving joint is one orbitflex models.

use super::parse::JointKind;
use super::tree::Tree;
use crate::error::{Error, Result};

/// The end-effector links: the ones asked for (in that order; `option` names where, as
/// `"link (ee_link)"`, for messages), or else, depth-first from the root: every leaf link not
/// behind a locked joint, and every link that carries a locked subtree (a locked gripper, say)
/// with no such leaf below it, so that an arm whose fingers are locked keeps one end-effector,
/// its hand. A URDF with a single leaf gives that leaf.
pub(super) fn ee_links<'a>(
    tree: &Tree<'a>,
    asked: &'a [String],
    option: &'static str,
    source: &str,
) -> Result<Vec<&'a str>> {
    if !asked.is_empty() {
        let mut seen = std::collections::HashSet::new();
        for name in asked {
            if !tree.urdf.links.iter().any(|l| &l.name == name) {
                return Err(Error::UnknownName {
                    source_name: source.to_string(),
                    what: option,
                    name: name.to_string(),
                    available: tree.link_list(),
                });
            }
            if !seen.insert(name.as_str()) {
                return Err(Error::InvalidModel {
                    source_name: source.to_string(),
                    message: format!("end-effector link '{name}' is listed twice in ee_links"),
                });
            }
        }
        return Ok(asked.iter().map(String::as_str).collect());
    }
    let all_leaves = tree.leaves();
    if let [only] = all_leaves.as_slice() {
        return Ok(vec![only]);
    }
    // a link is an end-effector if it is a leaf not behind a lock, or if it carries a locked
    // subtree (a locked gripper) and nothing below it is such a leaf: one end-effector per arm
    let order = tree.depth_first();
    let mut free_below: std::collections::HashMap<&str, bool> = Default::default();
    for &link in order.iter().rev() {
        let leaf = tree.children(link).is_empty() && !tree.behind_lock.contains(link);
        let below = tree
            .children(link)
            .iter()
            .any(|j| free_below[j.child.as_str()]);
        free_below.insert(link, leaf || below);
    }
    let ees: Vec<&str> = order
        .into_iter()
        .filter(|&link| {
            let leaf = tree.children(link).is_empty() && !tree.behind_lock.contains(link);
            let carrier = !tree.behind_lock.contains(link)
                && !free_below[link]
                && tree
                    .children(link)
                    .iter()
                    .any(|j| tree.locked.contains(j.name.as_str()));
            leaf || carrier
        })
        .collect();
    Ok(if ees.is_empty() { all_leaves } else { ees })
}

/// Every joint that is neither fixed nor locked must be revolute or continuous; the error names
/// every one that is not, and the one `locked_joints` list (`locked`, as given, then those) that
/// fixes them all.
pub(super) fn check_joint_kinds(tree: &Tree<'_>, locked: &[String], source: &str) -> Result<()> {
    let joints: Vec<(String, String)> = tree
        .urdf
        .joints
        .iter()
        .filter(|j| !tree.is_fixed(j))
        .filter(|j| !matches!(j.kind, JointKind::Revolute | JointKind::Continuous))
        .map(|j| (j.name.clone(), j.kind.name().to_string()))
        .collect();
    if joints.is_empty() {
        return Ok(());
    }
    Err(Error::UnsupportedJoint {
        source_name: source.to_string(),
        joints,
        locked: locked.to_vec(),
    })
}
