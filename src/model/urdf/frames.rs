//! Step 5: one named frame per URDF link, in depth-first order from the root, each placed on
//! the body it was merged into; and the links' visuals, with their colours looked up.

use super::merge::Bodies;
use super::parse::pose_transform;
use super::tree::Tree;
use crate::model::builder::check_transform;
use crate::model::{Geometry, LinkFrame, Visual};
use crate::spatial::Transform;

/// The frames (depth-first, children in file order) and the visuals. A visual whose origin is
/// out of range becomes [`Geometry::Malformed`]; a colour comes from the visual's own
/// `<material><color>`, or else from the top-level material it names.
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
    let mut visuals = Vec::new();
    for (index, frame) in frames.iter().enumerate() {
        let link = tree
            .urdf
            .links
            .iter()
            .find(|l| l.name == frame.name)
            .expect("every frame is a link");
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
                    .and_then(|name| tree.urdf.materials.get(name).copied())
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
