//! What a model looks like: the named frames of every URDF link (merged ones included) and the
//! `<visual>` shapes attached to them, with mesh files found on disk. The dynamics never read
//! any of this; viewers do ([`Robot::scene`]).
//!
//! Frames follow the joint-origin convention of the rest of the model: a frame's `placement` is
//! `Φ_{frame,body}`, the frame seen from the body that carries it (rotation `R_{frame,body}`,
//! translation `p_{body,frame}` in body components, m).

use super::Robot;
use crate::spatial::{Transform, Vec3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A named frame rigidly attached to a body: one per URDF link, in depth-first tree order.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkFrame {
    /// The URDF link's name.
    pub name: String,
    /// The body that carries the frame (0 is the base).
    pub body: usize,
    /// `Φ_{frame,body}`: the frame in the carrying body's frame (constant; links behind a
    /// locked joint are placed at the locked value, zero).
    pub placement: Transform,
    /// The frame of the parent link in the URDF tree (`None` for the root link).
    pub parent: Option<usize>,
    /// `Φ_{frame,parent}` at `q = 0`: the URDF joint origin from the parent link.
    pub joint_origin: Transform,
}

/// The shape of a `<visual>`, in its own frame (m). Cylinders and capsules run along their
/// `z` axis, centred on the origin (URDF's convention).
#[derive(Debug, Clone, PartialEq)]
pub enum Geometry {
    /// `<box size>`: full side lengths along x, y, z.
    Box {
        /// Side lengths (m).
        size: [f64; 3],
    },
    /// `<cylinder radius length>`.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length along `z` (m).
        length: f64,
    },
    /// `<sphere radius>`.
    Sphere {
        /// Radius (m).
        radius: f64,
    },
    /// A cylinder of `length` capped by two half-spheres (not a URDF shape: the stand-in
    /// drawn for links without visuals).
    Capsule {
        /// Radius of the cylinder and caps (m).
        radius: f64,
        /// Length of the cylinder along `z`, between the caps' centres (m).
        length: f64,
    },
    /// `<mesh filename scale>`: the file as the URDF names it, and its scale per axis.
    Mesh {
        /// As the URDF writes it (`package://…`, relative, absolute or `file://…`).
        filename: String,
        /// Scale per axis.
        scale: [f64; 3],
    },
    /// A `<visual>` that could not be read, and why; [`Robot::scene`] draws a stand-in.
    Malformed {
        /// What is wrong, with the URDF line.
        message: String,
    },
}

/// One `<visual>` of a link.
#[derive(Debug, Clone, PartialEq)]
pub struct Visual {
    /// Index into [`Robot::frames`] of the link it belongs to.
    pub frame: usize,
    /// `Φ_{visual,link}`: the `<origin>` of the visual in its link's frame.
    pub origin: Transform,
    /// The shape.
    pub geometry: Geometry,
    /// RGBA in 0..1, from the visual's `<material>` (inline or named at the top level).
    pub color: Option<[f64; 4]>,
}

/// A mesh file format a viewer can read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// STL, binary or ASCII.
    Stl,
    /// COLLADA (`.dae`).
    Dae,
    /// Wavefront OBJ.
    Obj,
}

impl MeshFormat {
    /// The lower-case file extension.
    pub fn extension(self) -> &'static str {
        match self {
            MeshFormat::Stl => "stl",
            MeshFormat::Dae => "dae",
            MeshFormat::Obj => "obj",
        }
    }
}

/// A shape ready to draw: what [`Robot::scene`] returns for every visual, with mesh files found
/// and checked, and stand-ins where a visual is missing or bad.
#[derive(Debug, Clone, PartialEq)]
pub struct Shape {
    /// Index into [`Robot::frames`].
    pub frame: usize,
    /// `Φ_{shape,frame}`: the shape in its frame.
    pub origin: Transform,
    /// Never [`Geometry::Malformed`]; a mesh here has a readable file at `mesh`.
    pub geometry: Geometry,
    /// For a mesh: the file found and its format.
    pub mesh: Option<(PathBuf, MeshFormat)>,
    /// RGBA in 0..1 (`None`: the mesh's own colours, or the viewer's default).
    pub color: Option<[f64; 4]>,
    /// Drawn in place of a missing or bad visual, or for a link without visuals.
    pub stand_in: bool,
}

/// Every shape of a model and the warnings met while finding them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Scene {
    /// The shapes, in frame order.
    pub shapes: Vec<Shape>,
    /// One line per missing or bad visual: the link, the file or element, and what is wrong.
    pub warnings: Vec<String>,
}

/// The largest mesh file read (bytes): 64 MB.
pub const MAX_MESH_BYTES: u64 = 64_000_000;

/// The most mesh bytes (distinct files) one scene reads: 256 MB; meshes past it are drawn as
/// stand-ins, with a warning.
pub const MAX_SCENE_MESH_BYTES: u64 = 256_000_000;

/// Where `package://` mesh paths are looked up, in order: an explicit map from package name to
/// its directory, then each directory of `ROS_PACKAGE_PATH`, then the directories above the
/// URDF file (one named as the package, or holding it).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MeshSearch {
    /// Package name → the package's directory.
    pub packages: BTreeMap<String, PathBuf>,
    /// `ROS_PACKAGE_PATH`'s value (`None`: read from the environment).
    pub ros_package_path: Option<String>,
}

impl MeshSearch {
    /// Finds the file a URDF `filename` names: `package://pkg/rest`, `file://path`, an absolute
    /// path, or a path relative to `urdf_dir`. The error says where it looked.
    pub fn resolve(&self, filename: &str, urdf_dir: Option<&Path>) -> Result<PathBuf, String> {
        if let Some(rest) = filename.strip_prefix("package://") {
            return self.resolve_package(rest, urdf_dir);
        }
        // file:///abs and file://localhost/abs name the absolute path
        let path = match filename.strip_prefix("file://") {
            Some(rest) => rest.strip_prefix("localhost").unwrap_or(rest),
            None => filename,
        };
        let path = Path::new(path);
        let path = match urdf_dir {
            _ if path.is_absolute() => path.to_path_buf(),
            Some(dir) => dir.join(path),
            None => {
                return Err(format!(
                    "the relative path '{filename}' needs the URDF file's folder: load the URDF \
                     from its file, or name the mesh with package:// or an absolute path"
                ))
            }
        };
        match path.is_file() {
            true => Ok(path),
            false => Err(format!("no file at {}", path.display())),
        }
    }

    /// The file `package://{rest}` names: the first candidate directory of the package
    /// ([`Self::package_dirs`]) that holds it, if it stays inside the package.
    fn resolve_package(&self, rest: &str, urdf_dir: Option<&Path>) -> Result<PathBuf, String> {
        let (package, inner) = rest.split_once('/').unwrap_or((rest, ""));
        if package.is_empty() {
            return Err("no package name after package://".into());
        }
        // `package://../x` would look in the folder above each candidate directory
        if package == "." || package == ".." || package.contains('\\') {
            return Err(format!(
                "'{package}' is not a package name (package://NAME/path names a file inside \
                 the package NAME)"
            ));
        }
        let inside = Path::new(inner);
        if inside.is_absolute()
            || inside
                .components()
                .any(|c| matches!(c, std::path::Component::ParentDir))
        {
            return Err(format!(
                "the path '{inner}' leaves the package '{package}' (absolute, or with '..')"
            ));
        }
        let dirs = self.package_dirs(package, urdf_dir);
        if let Some((dir, file)) = dirs.iter().find_map(|d| {
            let file = d.join(inside);
            file.is_file().then_some((d, file))
        }) {
            return inside_package(dir, file, inner, package);
        }
        if let Some(dir) = dirs.iter().find(|d| d.is_dir()) {
            return Err(format!(
                "no file at {} (package '{package}' is {})",
                dir.join(inside).display(),
                dir.display()
            ));
        }
        Err(format!(
            "package '{package}' not found: give its directory in the package map, add its \
             parent to ROS_PACKAGE_PATH, or keep the URDF inside the package"
        ))
    }

    /// The candidate directories of `package`, in order: the package map's, then for each
    /// directory of `ROS_PACKAGE_PATH` the directory itself if it is named as the package and
    /// the package inside it, then the same for each directory above the URDF file.
    fn package_dirs(&self, package: &str, urdf_dir: Option<&Path>) -> Vec<PathBuf> {
        let mut dirs: Vec<PathBuf> = Vec::new();
        if let Some(dir) = self.packages.get(package) {
            dirs.push(dir.clone());
        }
        let env = self
            .ros_package_path
            .clone()
            .map(std::ffi::OsString::from)
            .or_else(|| std::env::var_os("ROS_PACKAGE_PATH"))
            .unwrap_or_default();
        for entry in std::env::split_paths(&env).filter(|e| !e.as_os_str().is_empty()) {
            if entry.file_name().is_some_and(|n| n == package) {
                dirs.push(entry.clone());
            }
            dirs.push(entry.join(package));
        }
        for dir in urdf_dir.into_iter().flat_map(Path::ancestors) {
            if dir.file_name().is_some_and(|n| n == package) {
                dirs.push(dir.to_path_buf());
            }
            dirs.push(dir.join(package));
        }
        dirs
    }
}

/// The mesh files of one scene: each found and checked once, the distinct files' bytes within
/// [`MAX_SCENE_MESH_BYTES`].
#[derive(Default)]
struct SceneMeshes<'a> {
    found: BTreeMap<&'a str, Result<(PathBuf, MeshFormat), String>>,
    total: u64,
}

impl<'a> SceneMeshes<'a> {
    /// The file `filename` names and its format, or why it cannot be drawn.
    fn find(
        &mut self,
        filename: &'a str,
        search: &MeshSearch,
        urdf_dir: Option<&Path>,
    ) -> &Result<(PathBuf, MeshFormat), String> {
        let total = &mut self.total;
        self.found.entry(filename).or_insert_with(|| {
            let mesh = search
                .resolve(filename, urdf_dir)
                .and_then(|path| check_mesh_file(&path).map(|format| (path, format)))?;
            let size = std::fs::metadata(&mesh.0).map_or(0, |m| m.len());
            if *total + size > MAX_SCENE_MESH_BYTES {
                return Err(format!(
                    "the meshes would pass {MAX_SCENE_MESH_BYTES} bytes in all"
                ));
            }
            *total += size;
            Ok(mesh)
        })
    }
}

/// `file`, found in the package directory `dir`, if it is inside it once symbolic links are
/// resolved: a link in the package to a file elsewhere does not take a `package://` name out of
/// its package.
fn inside_package(
    dir: &Path,
    file: PathBuf,
    inner: &str,
    package: &str,
) -> Result<PathBuf, String> {
    let real = |p: &Path| {
        p.canonicalize()
            .map_err(|e| format!("cannot resolve {}: {e}", p.display()))
    };
    let (root, target) = (real(dir)?, real(&file)?);
    if target.starts_with(&root) {
        Ok(file)
    } else {
        Err(format!(
            "the path '{inner}' leaves the package '{package}' ({} is {} once links are \
             resolved, outside {})",
            file.display(),
            target.display(),
            root.display()
        ))
    }
}

/// The format of a mesh file from its extension, and a check of its first bytes.
pub fn check_mesh_file(path: &Path) -> Result<MeshFormat, String> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let format = match extension.as_str() {
        "stl" => MeshFormat::Stl,
        "dae" => MeshFormat::Dae,
        "obj" => MeshFormat::Obj,
        other => {
            return Err(format!(
                "unsupported mesh format '.{other}'; expected .stl, .dae or .obj"
            ))
        }
    };
    // at most one byte past the limit is read, whatever size the file system reports
    let file = std::fs::File::open(path).map_err(|e| format!("cannot read: {e}"))?;
    let mut bytes = Vec::new();
    std::io::Read::read_to_end(
        &mut std::io::Read::take(file, MAX_MESH_BYTES + 1),
        &mut bytes,
    )
    .map_err(|e| format!("cannot read: {e}"))?;
    if bytes.len() as u64 > MAX_MESH_BYTES {
        return Err(format!("more than the {MAX_MESH_BYTES} bytes read"));
    }
    check_mesh_bytes(format, &bytes)?;
    Ok(format)
}

/// Whether `bytes` look like a mesh of `format`: an STL whose size matches its triangle count
/// (binary) or that starts with `solid` and has a `facet` (ASCII); a COLLADA document; an OBJ
/// with at least one vertex (`v`) and one face (`f`).
pub fn check_mesh_bytes(format: MeshFormat, bytes: &[u8]) -> Result<(), String> {
    let text = || String::from_utf8_lossy(&bytes[..bytes.len().min(1 << 20)]).into_owned();
    match format {
        MeshFormat::Stl => {
            let start = bytes.iter().position(|b| !b.is_ascii_whitespace());
            let ascii =
                start.is_some_and(|k| bytes[k..].starts_with(b"solid")) && text().contains("facet");
            let binary = bytes.len() >= 84 && {
                let count = u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]);
                84 + 50 * count as u64 == bytes.len() as u64 && count > 0
            };
            if ascii || binary {
                Ok(())
            } else {
                Err(format!(
                    "not an STL file: {} bytes, neither ASCII ('solid … facet') nor binary (84 + \
                     50 bytes per triangle)",
                    bytes.len()
                ))
            }
        }
        MeshFormat::Dae => check_collada(bytes),
        MeshFormat::Obj => {
            let text = String::from_utf8_lossy(bytes);
            let has = |tag: &str| {
                text.lines()
                    .any(|l| l.split_whitespace().next() == Some(tag))
            };
            if has("v") && has("f") {
                Ok(())
            } else {
                Err("not an OBJ file: no vertex ('v') and face ('f') lines".into())
            }
        }
    }
}

/// A COLLADA document: well-formed XML, UTF-8, whose root element is `<COLLADA>`.
fn check_collada(bytes: &[u8]) -> Result<(), String> {
    let text = std::str::from_utf8(bytes).map_err(|e| {
        format!(
            "not a COLLADA file: not UTF-8 text (byte {})",
            e.valid_up_to()
        )
    })?;
    let mut reader = quick_xml::Reader::from_str(text);
    let mut depth = 0usize;
    let mut root = None;
    loop {
        match reader.read_event() {
            Ok(quick_xml::events::Event::Start(e)) => {
                if depth == 0 && root.is_none() {
                    root = Some(e.local_name().as_ref().to_vec());
                }
                depth += 1;
            }
            Ok(quick_xml::events::Event::Empty(e)) if depth == 0 && root.is_none() => {
                root = Some(e.local_name().as_ref().to_vec());
            }
            Ok(quick_xml::events::Event::End(_)) => depth = depth.saturating_sub(1),
            Ok(quick_xml::events::Event::Eof) => break,
            Ok(_) => {}
            Err(e) => {
                return Err(format!(
                    "not a COLLADA file: XML error at byte {}: {e}",
                    reader.error_position()
                ))
            }
        }
    }
    if depth != 0 {
        return Err("not a COLLADA file: the XML ends inside an element".into());
    }
    match root.as_deref() {
        Some(b"COLLADA") => Ok(()),
        _ => Err("not a COLLADA file: no <COLLADA> element".into()),
    }
}

/// Grey for links drawn from their joints, orange for stand-ins of bad visuals.
const LINK_GREY: [f64; 4] = [0.62, 0.64, 0.68, 1.0];
const STAND_IN_ORANGE: [f64; 4] = [1.0, 0.55, 0.1, 0.8];

impl Robot {
    /// The named frames, one per URDF link (merged links included), in depth-first tree order
    /// from the root (children in file order). A model built in code has one per body, and
    /// one more for the EE frame when it names a link of its own.
    pub fn frames(&self) -> &[LinkFrame] {
        &self.link_frames
    }

    /// The names of [`Robot::frames`], in order.
    pub fn frame_names(&self) -> Vec<&str> {
        self.link_frames.iter().map(|f| f.name.as_str()).collect()
    }

    /// The index of the frame named `name`.
    pub fn frame_index(&self, name: &str) -> Option<usize> {
        self.link_frames.iter().position(|f| f.name == name)
    }

    /// The URDF's `<visual>` elements, as written (malformed ones included).
    pub fn visuals(&self) -> &[Visual] {
        &self.visuals
    }

    /// The directory of the URDF file the model was read from (relative mesh paths start
    /// there); `None` for a URDF string or a model built in code.
    pub fn urdf_dir(&self) -> Option<&Path> {
        self.urdf_dir.as_deref()
    }

    /// Every shape to draw, with its mesh file found (`search`) and checked:
    /// - each readable `<visual>`;
    /// - for a link without visuals, a capsule from its origin (its joint) to each child
    ///   link's origin, or a small sphere for a leaf;
    /// - for a missing or bad mesh, or a malformed visual, the link's capsules as a stand-in
    ///   (orange) and a warning naming the link and the file.
    ///
    /// Never fails: a viewer shows what it can.
    pub fn scene(&self, search: &MeshSearch) -> Scene {
        let mut scene = Scene::default();
        let frames = self.link_frames.len();
        let mut has_visual = vec![false; frames];
        let mut stand_in = vec![false; frames];
        let mut numbers = vec![0usize; frames];
        // each file found and checked once; the distinct files' bytes within the budget
        let mut meshes = SceneMeshes::default();
        for visual in &self.visuals {
            let link = &self.link_frames[visual.frame].name;
            has_visual[visual.frame] = true;
            numbers[visual.frame] += 1;
            let number = numbers[visual.frame];
            let mut shape = Shape {
                frame: visual.frame,
                origin: visual.origin,
                geometry: visual.geometry.clone(),
                mesh: None,
                color: visual.color,
                stand_in: false,
            };
            match &visual.geometry {
                Geometry::Malformed { message } => {
                    scene.warnings.push(format!(
                        "link '{link}', visual {number}: {message}; drawn as a stand-in"
                    ));
                    stand_in[visual.frame] = true;
                    continue;
                }
                Geometry::Mesh { filename, .. } => {
                    let found = meshes.find(filename, search, self.urdf_dir());
                    match found {
                        Ok(mesh) => shape.mesh = Some(mesh.clone()),
                        Err(message) => {
                            scene.warnings.push(format!(
                                "link '{link}', mesh '{filename}': {message}; drawn as a \
                                 stand-in"
                            ));
                            stand_in[visual.frame] = true;
                            continue;
                        }
                    }
                }
                _ => {}
            }
            scene.shapes.push(shape);
        }
        self.push_default_shapes(&mut scene, &has_visual, &stand_in);
        scene.shapes.sort_by_key(|s| s.frame);
        scene
    }

    /// The default shapes ([`Self::default_shapes`]) of every frame without visuals (grey) or
    /// with a stand-in (orange).
    fn push_default_shapes(&self, scene: &mut Scene, has_visual: &[bool], stand_in: &[bool]) {
        let children = self.frame_children();
        for frame in 0..self.link_frames.len() {
            if !has_visual[frame] || stand_in[frame] {
                let color = if stand_in[frame] {
                    STAND_IN_ORANGE
                } else {
                    LINK_GREY
                };
                for (origin, geometry) in self.default_shapes(&children[frame]) {
                    scene.shapes.push(Shape {
                        frame,
                        origin,
                        geometry,
                        mesh: None,
                        color: Some(color),
                        stand_in: stand_in[frame],
                    });
                }
            }
        }
    }

    /// The child frames of each frame.
    fn frame_children(&self) -> Vec<Vec<usize>> {
        let mut children = vec![Vec::new(); self.link_frames.len()];
        for (k, frame) in self.link_frames.iter().enumerate() {
            if let Some(parent) = frame.parent {
                children[parent].push(k);
            }
        }
        children
    }

    /// The model as a stick figure: for every frame, a capsule from its origin to each child
    /// link's origin (a sphere for a leaf), whatever its visuals. Viewers draw the motor-side
    /// "ghost" arm with it.
    pub fn skeleton(&self) -> Vec<Shape> {
        let children = self.frame_children();
        (0..self.link_frames.len())
            .flat_map(|frame| {
                self.default_shapes(&children[frame])
                    .into_iter()
                    .map(move |(origin, geometry)| Shape {
                        frame,
                        origin,
                        geometry,
                        mesh: None,
                        color: None,
                        stand_in: false,
                    })
            })
            .collect()
    }

    /// A capsule from a frame's origin to the origin of each of its `children`, or a sphere
    /// for a leaf (or children all at the origin). The radius is a tenth of the segment,
    /// between 1 and 6 cm.
    fn default_shapes(&self, children: &[usize]) -> Vec<(Transform, Geometry)> {
        let mut shapes = Vec::new();
        for &child in children {
            let end = self.link_frames[child].joint_origin.translation;
            let length = end.norm();
            if length < 1e-6 {
                continue;
            }
            let radius = (0.1 * length).clamp(0.01, 0.06);
            // the capsule's z axis along `end`, its centre half-way
            let rotation = z_onto(&(end / length));
            let origin = Transform::new(rotation.transpose(), end * 0.5);
            shapes.push((origin, Geometry::Capsule { radius, length }));
        }
        if shapes.is_empty() {
            shapes.push((Transform::identity(), Geometry::Sphere { radius: 0.04 }));
        }
        shapes
    }
}

/// The default frames of a model built in code: one per body at its origin, and the EE frame
/// when its name is not a body's.
pub(crate) fn body_frames(robot: &Robot) -> Vec<LinkFrame> {
    let mut frames: Vec<LinkFrame> = robot
        .link_names
        .iter()
        .enumerate()
        .map(|(i, name)| LinkFrame {
            name: name.clone(),
            body: i,
            placement: Transform::identity(),
            parent: (i > 0).then(|| robot.parents[i]),
            joint_origin: if i > 0 {
                robot.joints[i - 1].origin
            } else {
                Transform::identity()
            },
        })
        .collect();
    for ee in &robot.ees {
        if !robot.link_names.contains(&ee.link) {
            frames.push(LinkFrame {
                name: ee.link.clone(),
                body: ee.body,
                placement: ee.transform,
                parent: Some(ee.body),
                joint_origin: ee.transform,
            });
        }
    }
    frames
}

/// A rotation taking `e_z` onto the unit vector `d` (a half turn about `x` when `d = −e_z`).
fn z_onto(d: &Vec3) -> crate::spatial::Mat3 {
    nalgebra::Rotation3::rotation_between(&Vec3::z(), d)
        .map(|r| r.into_inner())
        .unwrap_or_else(|| crate::spatial::Mat3::from_diagonal(&Vec3::new(1.0, -1.0, -1.0)))
}
