//! Step 1: URDF text to elements (urdf-rs), after a streaming pre-scan; and the conversions of
//! its poses and inertias.
//!
//! urdf-rs converts the XML recursively, so a deeply nested file overflows the stack (a crash,
//! not an error) and takes time quadratic in the depth. The pre-scan reads the text once with a
//! streaming parser, in time linear in its size, and refuses what no URDF needs before urdf-rs
//! sees it: nesting deeper than [`MAX_DEPTH`], more than [`MAX_ELEMENTS`] elements, more than
//! [`crate::io::MAX_FILE_BYTES`] of text. It also reports malformed XML with its line.

use crate::error::{Error, Result};
use crate::spatial::{Inertia, Mat3, Transform};
use quick_xml::events::Event;

/// The deepest element nesting accepted. A URDF needs about 6 (`robot/link/visual/geometry/mesh`),
/// a few more with simulator extensions.
pub const MAX_DEPTH: usize = 64;

/// The most elements accepted: enough for about 2·10⁵ links with their joints.
pub const MAX_ELEMENTS: usize = 4_000_000;

/// Parses the XML text of a URDF; `source` names it in messages.
pub(super) fn parse(xml: &str, source: &str) -> Result<urdf_rs::Robot> {
    let malformed = |message: String| Error::Malformed {
        source_name: source.to_string(),
        format: "URDF",
        message,
    };
    if xml.trim().is_empty() {
        return Err(malformed(
            "the text is empty; expected a <robot> element with links and joints".into(),
        ));
    }
    scan(xml).map_err(malformed)?;
    urdf_rs::read_from_string(xml).map_err(|e| malformed(e.to_string()))
}

/// One streaming pass over the XML: well-formed, within [`MAX_DEPTH`], [`MAX_ELEMENTS`] and the
/// size limit.
fn scan(xml: &str) -> std::result::Result<(), String> {
    let limit = crate::io::MAX_FILE_BYTES;
    if xml.len() as u64 > limit {
        return Err(format!(
            "the text has {} bytes, more than the {limit} read",
            xml.len()
        ));
    }
    let mut reader = quick_xml::Reader::from_str(xml);
    let (mut depth, mut elements) = (0usize, 0usize);
    loop {
        let event = reader.read_event().map_err(|e| {
            format!(
                "line {}: {e}",
                line_of(xml, reader.error_position() as usize)
            )
        })?;
        match event {
            Event::Start(_) | Event::Empty(_) => {
                elements += 1;
                let opens = matches!(event, Event::Start(_));
                if depth + 1 > MAX_DEPTH {
                    return Err(format!(
                        "line {}: elements nested {} deep, deeper than the {MAX_DEPTH} accepted",
                        line_of(xml, reader.buffer_position() as usize),
                        depth + 1
                    ));
                }
                if elements > MAX_ELEMENTS {
                    return Err(format!(
                        "more than {MAX_ELEMENTS} elements (line {})",
                        line_of(xml, reader.buffer_position() as usize)
                    ));
                }
                depth += usize::from(opens);
            }
            Event::End(_) => depth = depth.saturating_sub(1),
            Event::Eof => break,
            _ => {}
        }
    }
    Ok(())
}

/// The 1-based line of byte `offset`.
fn line_of(text: &str, offset: usize) -> usize {
    let offset = offset.min(text.len());
    1 + text.as_bytes()[..offset]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
}

/// `Φ_{child,parent}` of a URDF `<origin xyz rpy>`.
pub(super) fn pose_transform(pose: &urdf_rs::Pose) -> Transform {
    Transform::from_xyz_rpy(pose.xyz.0, pose.rpy.0)
}

/// The joint type's name as URDF spells it.
pub(super) fn joint_kind(kind: &urdf_rs::JointType) -> &'static str {
    use urdf_rs::JointType;
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

/// A link's inertia in its own frame, from the URDF `<inertial>` (COM frame pose, mass, inertia
/// about the COM in the COM frame's axes), validated.
pub(super) fn link_inertia(link: &urdf_rs::Link, source: &str) -> Result<Inertia> {
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
    crate::model::builder::check_inertia(mass, &com_frame.translation, &about_com).map_err(
        |message| Error::InvalidInertia {
            source_name: source.to_string(),
            link: link.name.clone(),
            message,
        },
    )?;
    Ok(Inertia::from_com(mass, com_frame.translation, about_com))
}
