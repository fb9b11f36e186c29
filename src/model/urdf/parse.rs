//! Step 1: URDF text to elements (urdf-rs), and the conversions of its poses and inertias.

use crate::error::{Error, Result};
use crate::spatial::{Inertia, Mat3, Transform};

/// Parses the XML text of a URDF; `source` names it in messages.
pub(super) fn parse(xml: &str, source: &str) -> Result<urdf_rs::Robot> {
    urdf_rs::read_from_string(xml).map_err(|e| Error::Malformed {
        source_name: source.to_string(),
        format: "URDF",
        message: e.to_string(),
    })
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
