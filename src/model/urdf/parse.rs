//! Step 1: URDF text to elements, in one streaming pass, and the conversions of poses and
//! inertias.
//!
//! The reader keeps what the dynamics need: the robot's name, each `<link>` with its
//! `<inertial>` (origin, mass, inertia), and each `<joint>` with its type, parent, child, origin,
//! axis and `<limit>` (lower, upper, effort, velocity, as written). It also keeps each link's
//! `<visual>`s (origin, shape, material colour) and the top-level `<material>` colours, for
//! viewers; a visual it cannot read is kept as [`Geometry::Malformed`] with the reason, never an
//! error, since the dynamics do not need it. Everything else (collisions, safety controllers,
//! transmissions, simulator extensions) is skipped. It reads the text once, in time linear in its size, and refuses what no URDF
//! needs: nesting deeper than [`MAX_DEPTH`], more than [`MAX_ELEMENTS`] elements, more than
//! [`crate::io::MAX_FILE_BYTES`] of text. Errors say what is wrong and on which line. Entities
//! other than XML's five are not expanded (no "billion laughs").

use crate::error::{Error, Result};
use crate::model::visual::Geometry;
use crate::spatial::{Inertia, Mat3, Transform};
use quick_xml::events::{BytesStart, Event};
use std::collections::HashMap;

/// The deepest element nesting accepted. A URDF needs about 6 (`robot/link/visual/geometry/mesh`),
/// a few more with simulator extensions.
pub const MAX_DEPTH: usize = 64;

/// The most elements accepted: enough for about 2·10⁵ links with their joints.
pub const MAX_ELEMENTS: usize = 4_000_000;

/// A URDF's `<robot>`: what the model is built from.
#[derive(Debug, Default)]
pub(super) struct Urdf {
    pub name: String,
    pub links: Vec<Link>,
    pub joints: Vec<Joint>,
    /// Top-level `<material name><color rgba/></material>` colours.
    pub materials: HashMap<String, [f64; 4]>,
}

/// A `<link>`.
#[derive(Debug, Default)]
pub(super) struct Link {
    pub name: String,
    /// Zero mass and inertia when the link has no `<inertial>`.
    pub inertial: Inertial,
    /// The link's `<visual>`s, in file order.
    pub visuals: Vec<RawVisual>,
}

/// A `<visual>` as written: its origin, shape (or why it is malformed), and material.
#[derive(Debug, Clone)]
pub(super) struct RawVisual {
    pub origin: Pose,
    pub geometry: Geometry,
    /// `<material name>`, looked up among the top-level materials when there is no colour.
    pub material: Option<String>,
    pub color: Option<[f64; 4]>,
}

/// A visual being read: the first problem met wins.
#[derive(Debug, Default)]
struct PartialVisual {
    origin: Pose,
    geometry: Option<Geometry>,
    material: Option<String>,
    color: Option<[f64; 4]>,
    problem: Option<String>,
}

/// An `<inertial>`: the COM frame, the mass (kg) and the inertia about the COM in that frame's
/// axes (kg·m²): `[ixx, ixy, ixz, iyy, iyz, izz]`.
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct Inertial {
    pub origin: Pose,
    pub mass: f64,
    pub inertia: [f64; 6],
}

/// An `<origin xyz rpy>` (m, rad).
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct Pose {
    pub xyz: [f64; 3],
    pub rpy: [f64; 3],
}

/// A joint type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum JointKind {
    Revolute,
    Continuous,
    Prismatic,
    Fixed,
    Floating,
    Planar,
    Spherical,
}

impl JointKind {
    const ALL: [(&'static str, JointKind); 7] = [
        ("revolute", JointKind::Revolute),
        ("continuous", JointKind::Continuous),
        ("prismatic", JointKind::Prismatic),
        ("fixed", JointKind::Fixed),
        ("floating", JointKind::Floating),
        ("planar", JointKind::Planar),
        ("spherical", JointKind::Spherical),
    ];

    /// The type's name as URDF spells it.
    pub fn name(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(_, k)| *k == self)
            .map_or("?", |(name, _)| name)
    }
}

/// A `<joint>`.
#[derive(Debug, Clone)]
pub(super) struct Joint {
    pub name: String,
    pub kind: JointKind,
    pub parent: String,
    pub child: String,
    pub origin: Pose,
    /// The `<axis xyz>`, default `1 0 0` (as URDF specifies).
    pub axis: [f64; 3],
    /// The `<limit>`, if the joint has one.
    pub limit: Option<RawLimit>,
}

/// A joint's `<limit lower upper effort velocity>` as written: each attribute if present.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct RawLimit {
    pub lower: Option<f64>,
    pub upper: Option<f64>,
    pub effort: Option<f64>,
    pub velocity: Option<f64>,
}

/// Parses the XML text of a URDF; `source` names it in messages.
pub(super) fn parse(xml: &str, source: &str) -> Result<Urdf> {
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
    let limit = crate::io::MAX_FILE_BYTES;
    if xml.len() as u64 > limit {
        return Err(malformed(format!(
            "the text has {} bytes, more than the {limit} read",
            xml.len()
        )));
    }
    Reader::new(xml).read().map_err(malformed)
}

/// What is being read: the open elements that matter, innermost last.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scope {
    Robot,
    Link,
    Inertial,
    Joint,
    Visual,
    Geometry,
    VisualMaterial,
    /// A top-level `<material>`, with its name.
    Material,
    /// Any element the reader skips, with everything inside it.
    Other,
}

struct Reader<'a> {
    xml: &'a str,
    reader: quick_xml::Reader<&'a [u8]>,
    /// `(offset, line)` of the last line number asked for: lines are counted onwards from it,
    /// so numbering every element costs O(size) in all.
    counted: std::cell::Cell<(usize, usize)>,
    scopes: Vec<Scope>,
    robot: Option<Urdf>,
    link: Option<Link>,
    joint: Option<PartialJoint>,
    visual: Option<PartialVisual>,
    material: Option<String>,
}

/// A joint being read: its parent and child may not have come yet.
struct PartialJoint {
    name: String,
    kind: JointKind,
    parent: Option<String>,
    child: Option<String>,
    origin: Pose,
    axis: [f64; 3],
    limit: Option<RawLimit>,
    line: usize,
}

type Message = String;

impl<'a> Reader<'a> {
    fn new(xml: &'a str) -> Self {
        Self {
            xml,
            reader: quick_xml::Reader::from_str(xml),
            counted: std::cell::Cell::new((0, 1)),
            scopes: Vec::new(),
            robot: None,
            link: None,
            joint: None,
            visual: None,
            material: None,
        }
    }

    /// The 1-based line of byte `offset`.
    fn line_at(&self, offset: u64) -> usize {
        let offset = (offset as usize).min(self.xml.len());
        let (from, line) = match self.counted.get() {
            (at, line) if at <= offset => (at, line),
            _ => (0, 1),
        };
        let line = line
            + self.xml.as_bytes()[from..offset]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
        self.counted.set((offset, line));
        line
    }

    fn line(&self) -> usize {
        self.line_at(self.reader.buffer_position())
    }

    fn read(mut self) -> std::result::Result<Urdf, Message> {
        let mut elements = 0usize;
        loop {
            let event = self
                .reader
                .read_event()
                .map_err(|e| format!("line {}: {e}", self.line_at(self.reader.error_position())))?;
            match event {
                Event::Start(ref e) | Event::Empty(ref e) => {
                    elements += 1;
                    if elements > MAX_ELEMENTS {
                        return Err(format!(
                            "more than {MAX_ELEMENTS} elements (line {})",
                            self.line()
                        ));
                    }
                    if self.scopes.len() + 1 > MAX_DEPTH {
                        return Err(format!(
                            "line {}: elements nested {} deep, deeper than the {MAX_DEPTH} \
                             accepted",
                            self.line(),
                            self.scopes.len() + 1
                        ));
                    }
                    let scope = self.open(e)?;
                    if matches!(event, Event::Start(_)) {
                        self.scopes.push(scope);
                    } else {
                        self.close(scope)?;
                    }
                }
                Event::End(_) => {
                    let scope = self.scopes.pop().unwrap_or(Scope::Other);
                    self.close(scope)?;
                }
                Event::Eof => break,
                _ => {}
            }
        }
        if !self.scopes.is_empty() {
            return Err(format!(
                "line {}: {} element(s) not closed at the end of the text",
                self.line(),
                self.scopes.len()
            ));
        }
        self.robot
            .ok_or_else(|| "no <robot> element; a URDF's root is <robot name=\"…\">".into())
    }

    /// Reads an opening tag in the current scope; returns the scope it opens.
    fn open(&mut self, e: &BytesStart) -> std::result::Result<Scope, Message> {
        let name = e.local_name();
        let name = name.as_ref();
        let line = self.line();
        match self.scopes.last().copied() {
            None => self.open_root(e, name, line),
            Some(Scope::Robot) => self.open_in_robot(e, name, line),
            Some(Scope::Link | Scope::Visual | Scope::Geometry | Scope::VisualMaterial) => {
                Ok(self.open_in_link(e, name, line))
            }
            Some(Scope::Material) => {
                if name == b"color" {
                    // a bad colour of a named material leaves it without colour
                    if let (Some(name), Ok(rgba)) = (self.material.clone(), self.rgba(e)) {
                        let robot = self.robot.as_mut().expect("inside the robot");
                        robot.materials.insert(name, rgba);
                    }
                }
                Ok(Scope::Other)
            }
            Some(Scope::Inertial) => self.open_in_inertial(e, name),
            Some(Scope::Joint) => self.open_in_joint(e, name),
            Some(Scope::Other) => Ok(Scope::Other),
        }
    }

    /// The root element: `<robot>`, once.
    fn open_root(
        &mut self,
        e: &BytesStart,
        name: &[u8],
        line: usize,
    ) -> std::result::Result<Scope, Message> {
        if name != b"robot" {
            return Err(format!(
                "line {line}: the root element is <{}>; expected <robot>",
                String::from_utf8_lossy(name)
            ));
        }
        if self.robot.is_some() {
            return Err(format!("line {line}: a second <robot> element"));
        }
        self.robot = Some(Urdf {
            name: self.attribute(e, "name")?.unwrap_or_default(),
            ..Urdf::default()
        });
        Ok(Scope::Robot)
    }

    /// A child of `<robot>`: a link, a named material or a joint.
    fn open_in_robot(
        &mut self,
        e: &BytesStart,
        name: &[u8],
        line: usize,
    ) -> std::result::Result<Scope, Message> {
        Ok(match name {
            b"link" => {
                self.link = Some(Link {
                    name: self.required(e, "link", "name")?,
                    inertial: Inertial::default(),
                    visuals: Vec::new(),
                });
                Scope::Link
            }
            b"material" => {
                self.material = self.attribute(e, "name").ok().flatten();
                Scope::Material
            }
            b"joint" => {
                let name = self.required(e, "joint", "name")?;
                let kind = self.required(e, "joint", "type")?;
                let kind = JointKind::ALL
                    .iter()
                    .find(|(spelled, _)| *spelled == kind)
                    .map(|(_, k)| *k)
                    .ok_or_else(|| {
                        format!(
                            "line {line}: joint '{name}' has the unknown type '{kind}'; URDF's \
                             types are revolute, continuous, prismatic, fixed, floating, planar \
                             and spherical"
                        )
                    })?;
                self.joint = Some(PartialJoint {
                    name,
                    kind,
                    parent: None,
                    child: None,
                    origin: Pose::default(),
                    axis: [1.0, 0.0, 0.0],
                    limit: None,
                    line,
                });
                Scope::Joint
            }
            _ => Scope::Other,
        })
    }

    /// Inside a `<link>`: its `<inertial>`, and its `<visual>`s with everything in them. A
    /// visual's problems are kept on the visual (it is dropped with a warning), never errors.
    fn open_in_link(&mut self, e: &BytesStart, name: &[u8], line: usize) -> Scope {
        match (self.scopes.last().copied(), name) {
            (Some(Scope::Link), b"inertial") => Scope::Inertial,
            (Some(Scope::Link), b"visual") => {
                self.visual = Some(PartialVisual::default());
                Scope::Visual
            }
            (Some(Scope::Visual), b"origin") => {
                match self.pose(e).and_then(|p| finite_pose(p, line)) {
                    Ok(pose) => self.visual_mut().origin = pose,
                    Err(message) => self.visual_problem(message),
                }
                Scope::Other
            }
            (Some(Scope::Visual), b"geometry") => Scope::Geometry,
            (Some(Scope::Geometry), b"box" | b"cylinder" | b"sphere" | b"mesh") => {
                let shape = self.shape(e, name);
                if self.visual_mut().geometry.is_some() {
                    self.visual_problem(format!(
                        "line {line}: <geometry> holds more than one shape"
                    ));
                }
                match shape {
                    Ok(shape) => self.visual_mut().geometry = Some(shape),
                    Err(message) => self.visual_problem(message),
                }
                Scope::Other
            }
            (Some(Scope::Visual), b"material") => {
                let name = self.attribute(e, "name").ok().flatten();
                self.visual_mut().material = name;
                Scope::VisualMaterial
            }
            (Some(Scope::VisualMaterial), b"color") => {
                match self.rgba(e) {
                    Ok(rgba) => self.visual_mut().color = Some(rgba),
                    Err(message) => self.visual_problem(message),
                }
                Scope::Other
            }
            _ => Scope::Other,
        }
    }

    /// Inside `<inertial>`: its origin, mass and inertia.
    fn open_in_inertial(
        &mut self,
        e: &BytesStart,
        name: &[u8],
    ) -> std::result::Result<Scope, Message> {
        match name {
            b"origin" => {
                let pose = self.pose(e)?;
                self.inertial()?.origin = pose;
            }
            b"mass" => {
                let mass = self.number(e, "mass", "value")?;
                self.inertial()?.mass = mass;
            }
            b"inertia" => {
                let mut values = [0.0; 6];
                for (value, key) in values
                    .iter_mut()
                    .zip(["ixx", "ixy", "ixz", "iyy", "iyz", "izz"])
                {
                    *value = self.number(e, "inertia", key)?;
                }
                self.inertial()?.inertia = values;
            }
            _ => {}
        }
        Ok(Scope::Other)
    }

    /// Inside `<joint>`: its parent, child, origin, axis and limit.
    fn open_in_joint(
        &mut self,
        e: &BytesStart,
        name: &[u8],
    ) -> std::result::Result<Scope, Message> {
        match name {
            b"parent" | b"child" => {
                let tag = if name == b"parent" { "parent" } else { "child" };
                let link = self.required(e, tag, "link")?;
                let joint = self.joint.as_mut().expect("inside a joint");
                if tag == "parent" {
                    joint.parent = Some(link);
                } else {
                    joint.child = Some(link);
                }
            }
            b"origin" => {
                let pose = self.pose(e)?;
                self.joint.as_mut().expect("inside a joint").origin = pose;
            }
            b"axis" => {
                let axis = self.triple(e, "axis", "xyz")?.unwrap_or([1.0, 0.0, 0.0]);
                self.joint.as_mut().expect("inside a joint").axis = axis;
            }
            b"limit" => {
                let limit = RawLimit {
                    lower: self.optional_number(e, "limit", "lower")?,
                    upper: self.optional_number(e, "limit", "upper")?,
                    effort: self.optional_number(e, "limit", "effort")?,
                    velocity: self.optional_number(e, "limit", "velocity")?,
                };
                self.joint.as_mut().expect("inside a joint").limit = Some(limit);
            }
            _ => {}
        }
        Ok(Scope::Other)
    }

    /// Finishes the element that closes.
    fn close(&mut self, scope: Scope) -> std::result::Result<(), Message> {
        match scope {
            Scope::Visual => {
                let v = self.visual.take().expect("a visual is open");
                let geometry = match (v.problem, v.geometry) {
                    (Some(message), _) => Geometry::Malformed { message },
                    (None, Some(shape)) => shape,
                    (None, None) => Geometry::Malformed {
                        message: "no shape in <geometry> (box, cylinder, sphere or mesh)".into(),
                    },
                };
                let visual = RawVisual {
                    origin: v.origin,
                    geometry,
                    material: v.material,
                    color: v.color,
                };
                self.link
                    .as_mut()
                    .expect("inside a link")
                    .visuals
                    .push(visual);
            }
            Scope::Material => self.material = None,
            Scope::Link => {
                let link = self.link.take().expect("a link is open");
                self.robot
                    .as_mut()
                    .expect("inside the robot")
                    .links
                    .push(link);
            }
            Scope::Joint => {
                let j = self.joint.take().expect("a joint is open");
                let missing = |what: &str| {
                    format!(
                        "line {}: joint '{}' has no <{what} link=\"…\"/>",
                        j.line, j.name
                    )
                };
                let joint = Joint {
                    parent: j.parent.clone().ok_or_else(|| missing("parent"))?,
                    child: j.child.clone().ok_or_else(|| missing("child"))?,
                    name: j.name,
                    kind: j.kind,
                    origin: j.origin,
                    axis: j.axis,
                    limit: j.limit,
                };
                self.robot
                    .as_mut()
                    .expect("inside the robot")
                    .joints
                    .push(joint);
            }
            _ => {}
        }
        Ok(())
    }

    fn visual_mut(&mut self) -> &mut PartialVisual {
        self.visual.as_mut().expect("inside a visual")
    }

    /// Records the first problem of the visual being read.
    fn visual_problem(&mut self, message: Message) {
        self.visual_mut().problem.get_or_insert(message);
    }

    /// A `<box>`, `<cylinder>`, `<sphere>` or `<mesh>` of a visual, checked: positive finite
    /// sizes, a file name, a finite non-zero scale.
    fn shape(&self, e: &BytesStart, tag: &[u8]) -> std::result::Result<Geometry, Message> {
        let line = self.line();
        let positive = |element: &str, key: &str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(value)
            } else {
                Err(format!(
                    "line {line}: <{element} {key}=\"{value}\">: expected a positive length (m)"
                ))
            }
        };
        Ok(match tag {
            b"box" => {
                let size = self
                    .triple(e, "box", "size")?
                    .ok_or_else(|| format!("line {line}: <box> has no size=\"x y z\" attribute"))?;
                for value in size {
                    positive("box", "size", value)?;
                }
                Geometry::Box { size }
            }
            b"cylinder" => Geometry::Cylinder {
                radius: positive("cylinder", "radius", self.number(e, "cylinder", "radius")?)?,
                length: positive("cylinder", "length", self.number(e, "cylinder", "length")?)?,
            },
            b"sphere" => Geometry::Sphere {
                radius: positive("sphere", "radius", self.number(e, "sphere", "radius")?)?,
            },
            _ => {
                let filename = self.required(e, "mesh", "filename")?;
                if filename.trim().is_empty() {
                    return Err(format!(
                        "line {line}: <mesh filename=\"\">: the file name is empty"
                    ));
                }
                let scale = self.triple(e, "mesh", "scale")?.unwrap_or([1.0; 3]);
                if scale.iter().any(|s| !s.is_finite() || *s == 0.0) {
                    return Err(format!(
                        "line {line}: <mesh scale=\"{} {} {}\">: expected three finite non-zero \
                         numbers",
                        scale[0], scale[1], scale[2]
                    ));
                }
                Geometry::Mesh { filename, scale }
            }
        })
    }

    /// A `<color rgba>`: four numbers in [0, 1].
    fn rgba(&self, e: &BytesStart) -> std::result::Result<[f64; 4], Message> {
        let line = self.line();
        let text = self.required(e, "color", "rgba")?;
        let values: Vec<f64> = text
            .split_whitespace()
            .map(|v| v.parse().unwrap_or(f64::NAN))
            .collect();
        match <[f64; 4]>::try_from(values) {
            Ok(rgba) if rgba.iter().all(|v| (0.0..=1.0).contains(v)) => Ok(rgba),
            _ => Err(format!(
                "line {line}: <color rgba=\"{text}\">: expected four numbers between 0 and 1"
            )),
        }
    }

    fn inertial(&mut self) -> std::result::Result<&mut Inertial, Message> {
        Ok(&mut self.link.as_mut().expect("inside a link").inertial)
    }

    /// The value of attribute `key`, unescaped, if it is there.
    fn attribute(&self, e: &BytesStart, key: &str) -> std::result::Result<Option<String>, Message> {
        let line = self.line();
        for attribute in e.attributes() {
            let attribute = attribute.map_err(|err| format!("line {line}: {err}"))?;
            if attribute.key.local_name().as_ref() == key.as_bytes() {
                let value = attribute
                    .unescape_value()
                    .map_err(|err| format!("line {line}: attribute {key}: {err}"))?;
                return Ok(Some(value.into_owned()));
            }
        }
        Ok(None)
    }

    fn required(
        &self,
        e: &BytesStart,
        element: &str,
        key: &str,
    ) -> std::result::Result<String, Message> {
        self.attribute(e, key)?.ok_or_else(|| {
            format!(
                "line {}: <{element}> has no {key}=\"…\" attribute",
                self.line()
            )
        })
    }

    /// A number attribute (required).
    fn number(
        &self,
        e: &BytesStart,
        element: &str,
        key: &str,
    ) -> std::result::Result<f64, Message> {
        let text = self.required(e, element, key)?;
        text.trim().parse().map_err(|_| {
            format!(
                "line {}: <{element} {key}=\"{text}\">: expected a number",
                self.line()
            )
        })
    }

    /// A number attribute, if it is there.
    fn optional_number(
        &self,
        e: &BytesStart,
        element: &str,
        key: &str,
    ) -> std::result::Result<Option<f64>, Message> {
        match self.attribute(e, key)? {
            None => Ok(None),
            Some(_) => self.number(e, element, key).map(Some),
        }
    }

    /// An attribute of three numbers, if it is there.
    fn triple(
        &self,
        e: &BytesStart,
        element: &str,
        key: &str,
    ) -> std::result::Result<Option<[f64; 3]>, Message> {
        let Some(text) = self.attribute(e, key)? else {
            return Ok(None);
        };
        let wrong = || {
            format!(
                "line {}: <{element} {key}=\"{text}\">: expected three numbers",
                self.line()
            )
        };
        let values: Vec<f64> = text
            .split_whitespace()
            .map(|v| v.parse().map_err(|_| wrong()))
            .collect::<std::result::Result<_, _>>()?;
        let values: [f64; 3] = values.try_into().map_err(|_| wrong())?;
        Ok(Some(values))
    }

    fn pose(&self, e: &BytesStart) -> std::result::Result<Pose, Message> {
        Ok(Pose {
            xyz: self.triple(e, "origin", "xyz")?.unwrap_or_default(),
            rpy: self.triple(e, "origin", "rpy")?.unwrap_or_default(),
        })
    }
}

/// The pose if its six numbers are finite.
fn finite_pose(pose: Pose, line: usize) -> std::result::Result<Pose, Message> {
    if pose.xyz.iter().chain(&pose.rpy).all(|v| v.is_finite()) {
        Ok(pose)
    } else {
        Err(format!("line {line}: <origin>: expected finite numbers"))
    }
}

/// `Φ_{child,parent}` of a URDF `<origin xyz rpy>`.
pub(super) fn pose_transform(pose: &Pose) -> Transform {
    Transform::from_xyz_rpy(pose.xyz, pose.rpy)
}

/// A link's inertia in its own frame, from the URDF `<inertial>` (COM frame pose, mass, inertia
/// about the COM in the COM frame's axes), validated.
pub(super) fn link_inertia(link: &Link, source: &str) -> Result<Inertia> {
    let inertial = &link.inertial;
    let [ixx, ixy, ixz, iyy, iyz, izz] = inertial.inertia;
    let in_com_axes = Mat3::new(
        ixx, ixy, ixz, //
        ixy, iyy, iyz, //
        ixz, iyz, izz,
    );
    // R_{com,link} = Eᵀ, so the inertia in link axes is E I Eᵀ.
    let com_frame = pose_transform(&inertial.origin);
    let e = com_frame.rotation.transpose();
    let about_com = e * in_com_axes * e.transpose();
    let mass = inertial.mass;
    crate::model::builder::check_inertia(mass, &com_frame.translation, &about_com).map_err(
        |message| Error::InvalidInertia {
            source_name: source.to_string(),
            link: link.name.clone(),
            message,
        },
    )?;
    Ok(Inertia::from_com(mass, com_frame.translation, about_com))
}
