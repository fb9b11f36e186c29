//! Writing a [`Robot`] back to URDF: the bodies as links (each with its merged inertia), the
//! joints with their origins, axes and limits, and the end-effector frames as massless links on
//! fixed joints. Loading the text again gives the same dynamics; Pinocchio reads it too, which is
//! how the reaction wheels' equivalence is tested ([`crate::flex::ReactionWheels::to_urdf`]).
//!
//! Numbers are written with Rust's shortest round-trip form, so every value is read back
//! exactly; only the rotations pass through roll-pitch-yaw angles (round-off, ~1e-16).

use crate::model::Robot;
use crate::spatial::{Inertia, Mat3, Transform, Vec3};
use std::fmt::Write;

impl Robot {
    /// This model as URDF text: one link per body (named as [`body_names`](Self::body_names),
    /// the links merged into it by fixed joints written as one, with the merged inertia), one
    /// joint per degree of freedom (`revolute` with its `<limit>` where the model has position
    /// limits, `continuous` otherwise), and each end-effector frame that is not a body's own as
    /// a massless link on a fixed joint. Visuals and the other named frames are not written.
    ///
    /// ```
    /// use orbitflex::{Robot, UrdfOptions};
    /// let arm = Robot::space_arm();
    /// let again = Robot::from_urdf_string(&arm.to_urdf(), &UrdfOptions::default())?;
    /// assert_eq!(again.joint_names(), arm.joint_names());
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn to_urdf(&self) -> String {
        write_urdf(self, "")
    }
}

/// [`Robot::to_urdf`] with `extra` (links and joints, URDF text) added before `</robot>`.
pub(crate) fn write_urdf(robot: &Robot, extra: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "<?xml version=\"1.0\"?>");
    let _ = writeln!(s, "<robot name=\"{}\">", escape(robot.name()));
    for (name, inertia) in robot.body_names().iter().zip(robot.inertias()) {
        s.push_str(&link(name, inertia));
    }
    for (i, joint) in robot.joints().iter().enumerate() {
        let body = i + 1;
        let names = robot.body_names();
        let (lower_upper, kind) = match joint.limits.position {
            Some((lower, upper)) => (
                format!(" lower=\"{lower:?}\" upper=\"{upper:?}\""),
                "revolute",
            ),
            None => (String::new(), "continuous"),
        };
        let mut limit = lower_upper;
        if let Some(effort) = joint.limits.effort {
            let _ = write!(limit, " effort=\"{effort:?}\"");
        }
        if let Some(velocity) = joint.limits.velocity {
            let _ = write!(limit, " velocity=\"{velocity:?}\"");
        }
        let limit = if limit.is_empty() {
            String::new()
        } else {
            format!("    <limit{limit}/>\n")
        };
        let _ = write!(
            s,
            "  <joint name=\"{}\" type=\"{kind}\">\n    <parent link=\"{}\"/>\n    <child link=\"{}\"/>\n{}    <axis xyz=\"{}\"/>\n{limit}  </joint>\n",
            escape(&joint.name),
            escape(&names[robot.parents()[body]]),
            escape(&names[body]),
            origin(&joint.origin),
            triple(&joint.axis),
        );
    }
    for ee in robot.end_effectors() {
        if robot.body_names()[ee.body] == ee.link {
            continue;
        }
        let _ = write!(
            s,
            "  <link name=\"{0}\"/>\n  <joint name=\"{0}_fixed\" type=\"fixed\">\n    <parent link=\"{1}\"/>\n    <child link=\"{0}\"/>\n{2}  </joint>\n",
            escape(&ee.link),
            escape(&robot.body_names()[ee.body]),
            origin(&ee.transform),
        );
    }
    s.push_str(extra);
    s.push_str("</robot>\n");
    s
}

/// `<link>` with its `<inertial>` (none for a massless body): mass, COM and the inertia about
/// the COM, in the link's axes.
pub(crate) fn link(name: &str, inertia: &Inertia) -> String {
    if inertia.mass == 0.0 && inertia.rotational.amax() == 0.0 {
        return format!("  <link name=\"{}\"/>\n", escape(name));
    }
    let c = inertia.inertia_about_com();
    format!(
        "  <link name=\"{}\">\n    <inertial>\n      <origin xyz=\"{}\" rpy=\"0 0 0\"/>\n      <mass value=\"{:?}\"/>\n      <inertia ixx=\"{:?}\" ixy=\"{:?}\" ixz=\"{:?}\" iyy=\"{:?}\" iyz=\"{:?}\" izz=\"{:?}\"/>\n    </inertial>\n  </link>\n",
        escape(name),
        triple(&inertia.com),
        inertia.mass,
        c[(0, 0)],
        c[(0, 1)],
        c[(0, 2)],
        c[(1, 1)],
        c[(1, 2)],
        c[(2, 2)],
    )
}

/// `<origin>` of a child frame from `Φ_{child,parent}`: `xyz = p_{parent,child}` and the
/// roll-pitch-yaw of `R_{parent,child} = R_{child,parent}ᵀ`.
pub(crate) fn origin(phi: &Transform) -> String {
    format!(
        "    <origin xyz=\"{}\" rpy=\"{}\"/>\n",
        triple(&phi.translation),
        triple(&rpy(&phi.rotation.transpose()))
    )
}

/// URDF's fixed-axis roll, pitch, yaw of `r = R_z(yaw) R_y(pitch) R_x(roll)`.
pub(crate) fn rpy(r: &Mat3) -> Vec3 {
    let cos_pitch = r[(0, 0)].hypot(r[(1, 0)]);
    let pitch = (-r[(2, 0)]).atan2(cos_pitch);
    if cos_pitch > 1e-10 {
        Vec3::new(
            r[(2, 1)].atan2(r[(2, 2)]),
            pitch,
            r[(1, 0)].atan2(r[(0, 0)]),
        )
    } else {
        // gimbal lock: only roll ∓ yaw is defined; put it all in yaw
        Vec3::new(0.0, pitch, (-r[(0, 1)]).atan2(r[(1, 1)]))
    }
}

fn triple(v: &Vec3) -> String {
    format!("{:?} {:?} {:?}", v.x, v.y, v.z)
}

/// A name as an XML attribute value.
pub(crate) fn escape(name: &str) -> String {
    name.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::rotation_about_axis;

    /// Roll-pitch-yaw back to the matrix, URDF's convention.
    fn matrix(a: &Vec3) -> Mat3 {
        rotation_about_axis(&Vec3::z(), a.z)
            * rotation_about_axis(&Vec3::y(), a.y)
            * rotation_about_axis(&Vec3::x(), a.x)
    }

    #[test]
    fn rpy_inverts_the_urdf_rotation_also_at_gimbal_lock() {
        for a in [
            Vec3::new(0.3, -0.7, 2.1),
            Vec3::new(-2.9, 1.2, -0.4),
            Vec3::new(0.0, std::f64::consts::FRAC_PI_2, 0.8),
            Vec3::new(0.0, -std::f64::consts::FRAC_PI_2, -1.1),
        ] {
            let r = matrix(&a);
            assert!((matrix(&rpy(&r)) - r).amax() < 1e-15, "{a}");
        }
    }
}
