//! A structure-aware URDF generator: links and joints that form chains, trees, cycles and
//! forests; numbers from the ordinary to the absurd (1e308, denormals, NaN, negative masses);
//! every joint type; and nesting from none to far past the loader's depth limit, which plain
//! byte mutation never reaches. Whatever loads is exercised by the dynamics.
#![no_main]

use arbitrary::Arbitrary;
use libfuzzer_sys::fuzz_target;
use orbitflex::{algorithms, Loads, RigidState, Robot, UrdfOptions};
use std::fmt::Write;

/// A number as it might appear in a URDF attribute.
#[derive(Arbitrary, Debug, Clone, Copy)]
enum Number {
    Small(i8),
    Scaled(i16, i8),
    Huge(bool),
    Tiny,
    NotANumber,
    Infinite(bool),
    Text,
}

impl Number {
    fn render(self) -> String {
        match self {
            Number::Small(v) => format!("{}", v as f64 / 16.0),
            Number::Scaled(m, e) => format!("{}e{}", m, e),
            Number::Huge(neg) => (if neg { "-1e308" } else { "1e308" }).into(),
            Number::Tiny => "4e-320".into(),
            Number::NotANumber => "nan".into(),
            Number::Infinite(neg) => (if neg { "-inf" } else { "inf" }).into(),
            Number::Text => "heavy".into(),
        }
    }
}

#[derive(Arbitrary, Debug)]
struct Link {
    inertial: Option<([Number; 3], Number, [Number; 6])>,
}

#[derive(Arbitrary, Debug)]
struct Joint {
    kind: u8,
    parent: u8,
    child: u8,
    origin: Option<([Number; 3], [Number; 3])>,
    axis: Option<[Number; 3]>,
}

#[derive(Arbitrary, Debug)]
struct Urdf {
    links: Vec<Link>,
    joints: Vec<Joint>,
    /// Elements wrapped around one link: (depth, close them).
    nesting: Option<(u32, bool)>,
    ee_link: Option<u8>,
    ee_links: Vec<u8>,
    locked: Vec<u8>,
}

fn three(v: &[Number; 3]) -> String {
    v.iter().map(|n| n.render()).collect::<Vec<_>>().join(" ")
}

impl Urdf {
    fn render(&self) -> String {
        let mut xml = String::from("<?xml version=\"1.0\"?>\n<robot name=\"fuzz\">\n");
        for (i, link) in self.links.iter().enumerate() {
            let nest = (i == 0).then_some(self.nesting).flatten();
            if let Some((depth, _)) = nest {
                for _ in 0..depth % 1_000 {
                    xml.push_str("<a>");
                }
            }
            let _ = write!(xml, "<link name=\"l{i}\">");
            if let Some((com, mass, inertia)) = &link.inertial {
                let _ = write!(
                    xml,
                    "<inertial><origin xyz=\"{}\" rpy=\"0 0 0\"/><mass value=\"{}\"/><inertia ixx=\"{}\" \
                     iyy=\"{}\" izz=\"{}\" ixy=\"{}\" ixz=\"{}\" iyz=\"{}\"/></inertial>",
                    three(com),
                    mass.render(),
                    inertia[0].render(),
                    inertia[1].render(),
                    inertia[2].render(),
                    inertia[3].render(),
                    inertia[4].render(),
                    inertia[5].render()
                );
            }
            xml.push_str("</link>\n");
            if let Some((depth, close)) = nest {
                if close {
                    for _ in 0..depth % 1_000 {
                        xml.push_str("</a>");
                    }
                }
            }
        }
        let kinds = ["revolute", "continuous", "fixed", "prismatic", "floating", "planar", "spherical", "bogus"];
        let count = self.links.len().max(1);
        for (i, joint) in self.joints.iter().enumerate() {
            let _ = write!(
                xml,
                "<joint name=\"j{i}\" type=\"{}\"><parent link=\"l{}\"/><child link=\"l{}\"/>",
                kinds[joint.kind as usize % kinds.len()],
                joint.parent as usize % count,
                joint.child as usize % count
            );
            if let Some((xyz, rpy)) = &joint.origin {
                let _ = write!(xml, "<origin xyz=\"{}\" rpy=\"{}\"/>", three(xyz), three(rpy));
            }
            if let Some(axis) = &joint.axis {
                let _ = write!(xml, "<axis xyz=\"{}\"/>", three(axis));
            }
            xml.push_str("</joint>\n");
        }
        xml.push_str("</robot>\n");
        xml
    }
}

fuzz_target!(|urdf: Urdf| {
    let xml = urdf.render();
    let options = UrdfOptions {
        ee_link: urdf.ee_link.map(|i| format!("l{}", i as usize % urdf.links.len().max(1))),
        locked_joints: urdf
            .locked
            .iter()
            .map(|i| format!("j{}", *i as usize % urdf.joints.len().max(1)))
            .collect(),
        ee_links: urdf
            .ee_links
            .iter()
            .map(|i| format!("l{}", *i as usize % urdf.links.len().max(1)))
            .collect(),
    };
    let Ok(robot) = Robot::from_urdf_string(&xml, &options) else {
        return;
    };
    let n = robot.dof();
    let q: Vec<f64> = (0..n).map(|i| 0.7 * (i as f64 + 1.0).cos()).collect();
    let qd = vec![0.2; n];
    let state = RigidState::new(&q, &[0.1, 0.0, -0.2, 0.0, 0.3, 0.0], &qd);
    let mut data = algorithms::Data::new(&robot);
    if let Ok(acc) = algorithms::aba(&robot, &mut data, &state, &vec![1.0; n], &Loads::ZERO) {
        // a model that loads has finite dynamics wherever they are regular
        assert!(acc.iter().all(|v| v.is_finite()), "{xml}");
    }
    let _ = algorithms::crba(&robot, &mut data, &q);
    // every end-effector: its Jacobian, and one wrench each through the inverse dynamics
    let k = robot.end_effectors().len();
    for e in 0..k {
        algorithms::ee_jacobian(&robot, &mut data, &q, e).expect("a valid end-effector index");
    }
    let wrench: Vec<f64> = (0..6 * k).map(|i| (i as f64).sin()).collect();
    let _ = algorithms::rnea(&robot, &mut data, &state, &[0.0; 6], &qd, &wrench);
});
