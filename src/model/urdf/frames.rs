//! Step 5: one named frame per URDF link, in depth-first order from the root, each placed on
//! the body it was merged into; and the links' visuals, with their colours looked up.

use super::merge::Bodies;
use super::parse::{pose_transform, Link};
use super::tree::Tree;
use crate::model::builder::check_transform;
use crate::model::{Geometry, LinkFrame, Visual};
use crate::spatial::Transform;
use std::collections::HashMap;

/// The frames (depth-first, children in file order) and the visuals. A visual whose origin is
/// out of range becomes [`Geometry::Malformed`]; a colour comes from the visual's own
/// `<material><color>`, or else from the material it names: a top-level one, or one given its
/// colour in another visual.
pub(super) fn frames(tree: &Tree<'_>, bodies: &Bodies<'_>) -> (Vec<LinkFrame>, Vec<Visual>) {
    let mut frames: Vec<LinkFrame> = Vec::with_capacity(tree.urdf.links.len());
    let mut stack: Vec<(&str, Option<usize>, Transform)> =
        vec![(tree.root, None, Transform::identity())];
    while let Some((link, parent, joint_origin)) = stack.pop() {
        let (body, placement) = bodies.placement[link];
        let index = frames.len();
        frames.push(LinkFrame {
            name: link.to_string(),
            body,
            placement,
            parent,
            joint_origin,
        });
        for joint in tree.children(link).iter().rev() {
            stack.push((
                joint.child.as_str(),
                Some(index),
                pose_transform(&joint.origin),
            ));
        }
    }
    // named colours: the top-level materials, then (as urdfdom does) a material first given
    // its colour inside a visual
    let mut materials = tree.urdf.materials.clone();
    for raw in tree.urdf.links.iter().flat_map(|l| &l.visuals) {
        if let (Some(name), Some(color)) = (&raw.material, raw.color) {
            materials.entry(name.clone()).or_insert(color);
        }
    }
    let links: HashMap<&str, &Link> = tree
        .urdf
        .links
        .iter()
        .map(|l| (l.name.as_str(), l))
        .collect();
    let mut visuals = Vec::new();
    for (index, frame) in frames.iter().enumerate() {
        let link = links[frame.name.as_str()];
        for raw in &link.visuals {
            let origin = pose_transform(&raw.origin);
            let geometry = match check_transform(&origin) {
                Ok(()) => raw.geometry.clone(),
                Err(m) => Geometry::Malformed {
                    message: format!("<origin>: {m}"),
                },
            };
            let color = raw.color.or_else(|| {
                raw.material
                    .as_ref()
                    .and_then(|name| materials.get(name).copied())
            });
            visuals.push(Visual {
                frame: index,
                origin: if matches!(geometry, Geometry::Malformed { .. }) {
                    Transform::identity()
                } else {
                    origin
                },
                geometry,
                color,
            });
        }
    }
    (frames, visuals)
}
