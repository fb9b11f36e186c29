//! Step 4: fixed and locked joints merged away. Each link belongs to a body (the base, or the
//! child link of a moving joint), and each body's inertia sums those of its links.

use super::parse::{link_inertia, pose_transform, Joint};
use super::tree::Tree;
use crate::error::{Error, Result};
use crate::model::builder::check_length;
use crate::spatial::{Inertia, Transform};
use std::collections::HashMap;

/// One body of the model: its link, the moving joint that carries it with `Φ_{body,parent body}`
/// at `q = 0` (none for the base), and its merged inertia.
pub(super) struct Body<'a> {
    pub link: &'a str,
    pub joint: Option<(&'a Joint, Transform)>,
    pub inertia: Inertia,
}

/// The bodies, numbered so that each parent comes before its children, and where each link sits:
/// `placement[link] = (body, Φ_{link,body})`.
pub(super) struct Bodies<'a> {
    pub bodies: Vec<Body<'a>>,
    pub placement: HashMap<&'a str, (usize, Transform)>,
}

/// Walks the tree depth-first from the root, children in file order. A fixed or locked joint
/// places its child link in its parent's body (frames composed); a moving joint starts a new
/// body. Bodies are numbered in the order the walk meets them (pre-order), so each parent comes
/// before its children and every subtree is a contiguous range.
pub(super) fn merge<'a>(tree: &Tree<'a>, source: &str) -> Result<Bodies<'a>> {
    let mut placement: HashMap<&str, (usize, Transform)> = HashMap::new();
    let mut bodies = vec![Body {
        link: tree.root,
        joint: None,
        inertia: Inertia::zero(),
    }];
    placement.insert(tree.root, (0, Transform::identity()));
    for link in tree.depth_first().into_iter().skip(1) {
        let joint = tree.parent_joint[link];
        let (parent_body, parent_in_body) = placement[joint.parent.as_str()];
        // Φ_{child,body} at q = 0: the joint origin composed with the parent's placement.
        let own = pose_transform(&joint.origin);
        check_length(&own.translation).map_err(|m| Error::InvalidModel {
            source_name: source.to_string(),
            message: format!("joint '{}': origin xyz {m}", joint.name),
        })?;
        let origin = own.compose(&parent_in_body);
        if tree.is_fixed(joint) {
            placement.insert(link, (parent_body, origin));
        } else {
            bodies.push(Body {
                link,
                joint: Some((joint, origin)),
                inertia: Inertia::zero(),
            });
            placement.insert(link, (bodies.len() - 1, Transform::identity()));
        }
    }
    for link in &tree.urdf.links {
        let (body, in_body) = placement[link.name.as_str()];
        let inertia = link_inertia(link, source)?.transformed_to_parent(&in_body);
        bodies[body].inertia = bodies[body].inertia.add(&inertia);
    }
    Ok(Bodies { bodies, placement })
}
