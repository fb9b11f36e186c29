//! The named frames and visuals of a `Robot` for Python: its scene for viewers, and the parts
//! pickling carries.

use super::errors::ModelError;
use crate::model::{Geometry, LinkFrame, MeshSearch, Robot, RobotBuilder, Visual};
use crate::spatial::{Mat3, Transform, Vec3};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A frame as pickled: name, body, placement (rotation rows, translation), parent frame, joint
/// origin (rotation rows, translation).
type FramePart = (
    String,
    usize,
    [f64; 9],
    [f64; 3],
    Option<usize>,
    [f64; 9],
    [f64; 3],
);
/// A visual as pickled: frame, origin (rotation rows, translation), shape kind, its numbers,
/// its text (mesh file or malformed message), colour.
type VisualPart = (
    usize,
    [f64; 9],
    [f64; 3],
    String,
    Vec<f64>,
    String,
    Option<[f64; 4]>,
);
/// What `Robot.__reduce__` carries besides the dynamics: frames, visuals, URDF directory.
pub(crate) type Appearance = (Vec<FramePart>, Vec<VisualPart>, Option<PathBuf>);

fn rows(m: &Mat3) -> [f64; 9] {
    std::array::from_fn(|k| m[(k / 3, k % 3)])
}

fn transform(r: &[f64; 9], p: &[f64; 3]) -> Transform {
    Transform::new(Mat3::from_row_slice(r), Vec3::from(*p))
}

/// A shape's kind, numbers and text.
fn geometry_parts(g: &Geometry) -> (&'static str, Vec<f64>, String) {
    match g {
        Geometry::Box { size } => ("box", size.to_vec(), String::new()),
        Geometry::Cylinder { radius, length } => {
            ("cylinder", vec![*radius, *length], String::new())
        }
        Geometry::Sphere { radius } => ("sphere", vec![*radius], String::new()),
        Geometry::Capsule { radius, length } => ("capsule", vec![*radius, *length], String::new()),
        Geometry::Mesh { filename, scale } => ("mesh", scale.to_vec(), filename.clone()),
        Geometry::Malformed { message } => ("malformed", Vec::new(), message.clone()),
    }
}

fn geometry_from_parts(kind: &str, v: &[f64], text: String) -> PyResult<Geometry> {
    let bad = || {
        ModelError::new_err(format!(
            "Robot parts: a {kind} visual with {} numbers",
            v.len()
        ))
    };
    Ok(match (kind, v) {
        ("box", [x, y, z]) => Geometry::Box { size: [*x, *y, *z] },
        ("cylinder", [radius, length]) => Geometry::Cylinder {
            radius: *radius,
            length: *length,
        },
        ("sphere", [radius]) => Geometry::Sphere { radius: *radius },
        ("capsule", [radius, length]) => Geometry::Capsule {
            radius: *radius,
            length: *length,
        },
        ("mesh", [x, y, z]) => Geometry::Mesh {
            filename: text,
            scale: [*x, *y, *z],
        },
        ("malformed", []) => Geometry::Malformed { message: text },
        _ => return Err(bad()),
    })
}

/// The frames, visuals and URDF directory of `robot`, for pickling.
pub(crate) fn parts(robot: &Robot) -> Appearance {
    let frames = robot
        .frames()
        .iter()
        .map(|f| {
            let (p, o) = (&f.placement, &f.joint_origin);
            (
                f.name.clone(),
                f.body,
                rows(&p.rotation),
                p.translation.into(),
                f.parent,
                rows(&o.rotation),
                o.translation.into(),
            )
        })
        .collect();
    let visuals = robot
        .visuals()
        .iter()
        .map(|v| {
            let (kind, numbers, text) = geometry_parts(&v.geometry);
            let o = &v.origin;
            (
                v.frame,
                rows(&o.rotation),
                o.translation.into(),
                kind.to_string(),
                numbers,
                text,
                v.color,
            )
        })
        .collect();
    (frames, visuals, robot.urdf_dir().map(PathBuf::from))
}

/// `builder` with the frames, visuals and URDF directory of `parts` (checked by `build`).
pub(crate) fn rebuild(mut builder: RobotBuilder, parts: Appearance) -> PyResult<RobotBuilder> {
    let (frames, visuals, dir) = parts;
    let frames = frames
        .into_iter()
        .map(|(name, body, r, p, parent, jr, jp)| LinkFrame {
            name,
            body,
            placement: transform(&r, &p),
            parent,
            joint_origin: transform(&jr, &jp),
        })
        .collect();
    let visuals = visuals
        .into_iter()
        .map(|(frame, r, p, kind, numbers, text, color)| {
            Ok(Visual {
                frame,
                origin: transform(&r, &p),
                geometry: geometry_from_parts(&kind, &numbers, text)?,
                color,
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    builder = builder.frames(frames).visuals(visuals);
    if let Some(dir) = dir {
        builder = builder.urdf_dir(dir);
    }
    Ok(builder)
}

/// `Robot.scene`: the shapes as dicts, and the warnings.
pub(crate) fn scene<'py>(
    py: Python<'py>,
    robot: &Robot,
    packages: BTreeMap<String, PathBuf>,
    skeleton: bool,
) -> PyResult<(Vec<Bound<'py, PyDict>>, Vec<String>)> {
    let search = MeshSearch {
        packages,
        ros_package_path: None,
    };
    let scene = if skeleton {
        crate::model::Scene {
            shapes: robot.skeleton(),
            warnings: Vec::new(),
        }
    } else {
        py.allow_threads(|| robot.scene(&search))
    };
    let mut shapes = Vec::with_capacity(scene.shapes.len());
    for shape in &scene.shapes {
        let d = PyDict::new(py);
        d.set_item("frame", shape.frame)?;
        let o = &shape.origin;
        d.set_item(
            "origin",
            crate::algorithms::pose(&o.translation, &o.rotation.transpose()).to_vec(),
        )?;
        match &shape.geometry {
            Geometry::Box { size } => {
                d.set_item("kind", "box")?;
                d.set_item("size", size.to_vec())?;
            }
            Geometry::Cylinder { radius, length } | Geometry::Capsule { radius, length } => {
                let capsule = matches!(shape.geometry, Geometry::Capsule { .. });
                d.set_item("kind", if capsule { "capsule" } else { "cylinder" })?;
                d.set_item("radius", radius)?;
                d.set_item("length", length)?;
            }
            Geometry::Sphere { radius } => {
                d.set_item("kind", "sphere")?;
                d.set_item("radius", radius)?;
            }
            Geometry::Mesh { scale, .. } => {
                d.set_item("kind", "mesh")?;
                d.set_item("scale", scale.to_vec())?;
                if let Some((path, format)) = &shape.mesh {
                    d.set_item("path", path)?;
                    d.set_item("format", format.extension())?;
                }
            }
            Geometry::Malformed { .. } => unreachable!("scene shapes are never malformed"),
        }
        d.set_item("color", shape.color.map(|c| c.to_vec()))?;
        d.set_item("stand_in", shape.stand_in)?;
        shapes.push(d);
    }
    Ok((shapes, scene.warnings))
}
