//! Named frames, their poses, and the visuals viewers draw: URDF `<visual>`s kept, mesh files
//! found, stand-ins for what is missing or bad.

use orbitflex::algorithms::{self, Data};
use orbitflex::spatial::{rotation_about_axis, Mat3, Transform, Vec3};
use orbitflex::{
    check_mesh_bytes, FlexibleArm, FlexibleJoints, Geometry, MeshFormat, MeshSearch, Robot,
    RobotBuilder, Schedule, UrdfOptions, Wrenches,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A chain with every kind of frame: a merged fixed link (`l1_tip`), a link without visuals
/// (`l2`), an EE link behind a fixed joint with a mesh (`tool`), a locked branch (`finger_link`,
/// with a malformed visual), a visual without a shape on the base, and colours inline and by
/// name.
const URDF: &str = r#"<?xml version="1.0"?>
<robot name="frames_test">
  <material name="gold"><color rgba="0.9 0.7 0.2 1"/></material>
  <link name="base">
    <inertial><mass value="50"/><inertia ixx="5" ixy="0" ixz="0" iyy="5" iyz="0" izz="5"/></inertial>
    <visual><geometry><box size="1 0.8 0.6"/></geometry><material name="gold"/></visual>
    <visual><origin xyz="0 0 1"/><geometry></geometry></visual>
  </link>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0.5 0.1 0.2" rpy="0.3 -0.2 0.7"/><axis xyz="0 0.6 0.8"/>
  </joint>
  <link name="l1">
    <inertial><origin xyz="0.4 0 0"/><mass value="3"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.3" iyz="0" izz="0.3"/></inertial>
    <visual>
      <origin xyz="0.4 0 0" rpy="0 1.5707963267948966 0"/>
      <geometry><cylinder radius="0.05" length="0.8"/></geometry>
      <material name="inline"><color rgba="0.1 0.2 0.3 0.5"/></material>
    </visual>
  </link>
  <joint name="f1" type="fixed">
    <parent link="l1"/><child link="l1_tip"/><origin xyz="0.8 0 0.05" rpy="0.1 0.2 0.3"/>
  </joint>
  <link name="l1_tip">
    <inertial><mass value="0.5"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
    <visual><geometry><sphere radius="0.07"/></geometry></visual>
  </link>
  <joint name="j2" type="continuous">
    <parent link="l1_tip"/><child link="l2"/><origin xyz="0.1 0 0" rpy="-0.4 0 0.2"/><axis xyz="1 0 0"/>
  </joint>
  <link name="l2">
    <inertial><origin xyz="0.3 0 0"/><mass value="2"/><inertia ixx="0.05" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
  </link>
  <joint name="tool_mount" type="fixed">
    <parent link="l2"/><child link="tool"/><origin xyz="0.6 0 0" rpy="0 0 0.5"/>
  </joint>
  <link name="tool">
    <visual><geometry><mesh filename="package://gripper_pkg/meshes/tool.stl" scale="0.001 0.001 0.001"/></geometry></visual>
  </link>
  <joint name="finger" type="revolute">
    <parent link="l2"/><child link="finger_link"/><origin xyz="0.3 0 0.1" rpy="0.2 0 0"/><axis xyz="0 0 1"/>
  </joint>
  <link name="finger_link">
    <inertial><mass value="0.2"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
    <visual><geometry><box size="0.1 0.2"/></geometry></visual>
  </link>
</robot>
"#;

fn options() -> UrdfOptions {
    UrdfOptions {
        ee_link: Some("tool".into()),
        locked_joints: vec!["finger".into()],
        ..UrdfOptions::default()
    }
}

fn robot() -> Robot {
    Robot::from_urdf_string(URDF, &options()).unwrap()
}

/// One binary STL triangle.
fn stl_triangle() -> Vec<u8> {
    let mut bytes = vec![0u8; 80];
    bytes.extend(1u32.to_le_bytes());
    for v in [
        0.0f32, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0,
    ] {
        bytes.extend(v.to_le_bytes());
    }
    bytes.extend([0u8, 0]);
    bytes
}

/// A fresh directory holding `gripper_pkg/urdf/robot.urdf` and, if `with_mesh`,
/// `gripper_pkg/meshes/tool.stl`.
fn package_tree(tag: &str, with_mesh: bool) -> PathBuf {
    let root = std::env::temp_dir().join(format!("orbitflex_visual_{tag}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    let pkg = root.join("gripper_pkg");
    std::fs::create_dir_all(pkg.join("urdf")).unwrap();
    std::fs::create_dir_all(pkg.join("meshes")).unwrap();
    std::fs::write(pkg.join("urdf/robot.urdf"), URDF).unwrap();
    if with_mesh {
        std::fs::write(pkg.join("meshes/tool.stl"), stl_triangle()).unwrap();
    }
    root
}

/// The rotation of a unit quaternion `(x, y, z, w)`.
fn rotation(quat: &[f64]) -> Mat3 {
    orbitflex::spatial::quaternion_to_rotation(quat)
}

/// Link poses by plain composition of the URDF origins and joint rotations (no merging, no
/// joint frames): `(axes → inertial, origin)` per link name.
fn reference_poses(base: &[f64; 7], q: &[(&str, f64)]) -> BTreeMap<String, (Mat3, Vec3)> {
    // (joint, parent, child, xyz, rpy, axis) as in URDF
    type J = (
        &'static str,
        &'static str,
        &'static str,
        [f64; 3],
        [f64; 3],
        [f64; 3],
    );
    let joints: [J; 5] = [
        (
            "j1",
            "base",
            "l1",
            [0.5, 0.1, 0.2],
            [0.3, -0.2, 0.7],
            [0.0, 0.6, 0.8],
        ),
        (
            "f1",
            "l1",
            "l1_tip",
            [0.8, 0.0, 0.05],
            [0.1, 0.2, 0.3],
            [0.0; 3],
        ),
        (
            "j2",
            "l1_tip",
            "l2",
            [0.1, 0.0, 0.0],
            [-0.4, 0.0, 0.2],
            [1.0, 0.0, 0.0],
        ),
        (
            "tool_mount",
            "l2",
            "tool",
            [0.6, 0.0, 0.0],
            [0.0, 0.0, 0.5],
            [0.0; 3],
        ),
        (
            "finger",
            "l2",
            "finger_link",
            [0.3, 0.0, 0.1],
            [0.2, 0.0, 0.0],
            [0.0, 0.0, 1.0],
        ),
    ];
    let mut poses = BTreeMap::new();
    poses.insert(
        "base".to_string(),
        (rotation(&base[3..]), Vec3::new(base[0], base[1], base[2])),
    );
    for (name, parent, child, xyz, rpy, axis) in joints {
        let (e, o) = poses[parent];
        let origin = Transform::from_xyz_rpy(xyz, rpy);
        let angle = q.iter().find(|(j, _)| *j == name).map_or(0.0, |(_, a)| *a);
        let turn = if angle == 0.0 {
            Mat3::identity()
        } else {
            // the child's axes turned by q about h, seen from the joint frame at q = 0
            rotation_about_axis(&Vec3::from(axis).normalize(), angle)
        };
        let axes = e * origin.rotation.transpose() * turn;
        poses.insert(child.to_string(), (axes, o + e * origin.translation));
    }
    poses
}

#[test]
fn every_urdf_link_is_a_frame_in_depth_first_order() {
    let robot = robot();
    assert_eq!(
        robot.frame_names(),
        ["base", "l1", "l1_tip", "l2", "tool", "finger_link"]
    );
    // merged links sit on the body they were merged into
    let bodies: Vec<usize> = robot.frames().iter().map(|f| f.body).collect();
    assert_eq!(bodies, [0, 1, 1, 2, 2, 2]);
    let parents: Vec<Option<usize>> = robot.frames().iter().map(|f| f.parent).collect();
    assert_eq!(parents, [None, Some(0), Some(1), Some(2), Some(3), Some(3)]);
    assert_eq!(robot.frame_index("tool"), Some(4));
    assert_eq!(robot.frame_index("nope"), None);
}

#[test]
fn frame_poses_equal_plain_composition_of_the_urdf() {
    let robot = robot();
    let base = [0.3, -1.2, 0.7, 0.1, -0.5, 0.3, 0.8];
    let norm = base[3..].iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut unit = base;
    unit[3..].iter_mut().for_each(|v| *v /= norm);
    let q = [0.9, -2.1];
    let mut data = Data::new(&robot);
    let mut poses = vec![0.0; 7 * robot.frames().len()];
    algorithms::frame_poses(&robot, &mut data, &base, &q, &mut poses).unwrap();
    let reference = reference_poses(&unit, &[("j1", q[0]), ("j2", q[1])]);
    for (name, pose) in robot.frame_names().iter().zip(poses.chunks_exact(7)) {
        let (axes, origin) = reference[*name];
        let position = Vec3::new(pose[0], pose[1], pose[2]);
        assert!(
            (position - origin).norm() < 1e-14,
            "{name}: {position:?} vs {origin:?}"
        );
        assert!(
            (rotation(&pose[3..]) - axes).norm() < 1e-14,
            "{name}: axes differ"
        );
        assert!(pose[6] >= 0.0, "{name}: w < 0");
        let quat_norm = pose[3..].iter().map(|v| v * v).sum::<f64>();
        assert!((quat_norm - 1.0).abs() < 1e-14);
    }
}

#[test]
fn frame_poses_agree_with_body_poses_and_the_ee_pose() {
    let robot = Robot::space_arm();
    let base = [1.0, 2.0, 3.0, 0.2, 0.1, -0.3, 0.9];
    let q = [0.3, -0.2, 0.5, 1.1, -0.7, 0.4, 2.0];
    let mut data = Data::new(&robot);
    let mut poses = vec![0.0; 7 * robot.frames().len()];
    algorithms::frame_poses(&robot, &mut data, &base, &q, &mut poses).unwrap();
    let bodies = algorithms::body_poses(&robot, &base, &q).unwrap();
    for (i, name) in robot.body_names().iter().enumerate() {
        let k = robot.frame_index(name).unwrap();
        for (a, b) in poses[7 * k..7 * k + 7].iter().zip(&bodies[i]) {
            assert!((a - b).abs() < 1e-14, "{name}");
        }
    }
    let joints = FlexibleJoints::uniform(7, 1e4, 0.1, 1.0, 0.0).unwrap();
    let arm = FlexibleArm::new(robot.clone(), joints).unwrap();
    let mut x = arm.rest_state();
    x[..7].copy_from_slice(&base);
    x[7..14].copy_from_slice(&q);
    let ee = arm.ee_pose(&x, 0);
    let k = robot.frame_index(robot.ee_link()).unwrap();
    for (a, b) in poses[7 * k..7 * k + 7].iter().zip(&ee) {
        assert!((a - b).abs() < 1e-14);
    }
}

#[test]
fn frame_poses_check_their_arguments() {
    let robot = robot();
    let mut data = Data::new(&robot);
    let mut poses = vec![0.0; 7 * robot.frames().len()];
    let base = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let short = algorithms::frame_poses(&robot, &mut data, &base, &[0.0; 2], &mut poses[..7]);
    assert!(short.unwrap_err().to_string().contains("frame poses (out)"));
    let zero = [0.0; 7];
    let bad = algorithms::frame_poses(&robot, &mut data, &zero, &[0.0; 2], &mut poses);
    assert!(bad.unwrap_err().to_string().contains("zero norm"));
    let bad_q = algorithms::frame_poses(&robot, &mut data, &base, &[0.0; 3], &mut poses);
    assert!(bad_q.unwrap_err().to_string().contains("q"));
    // a quaternion whose norm overflows is refused, not normalised to a wrong rotation
    let huge = [0.0, 0.0, 0.0, 1e200, 0.0, 0.0, 0.0];
    let overflow = algorithms::frame_poses(&robot, &mut data, &huge, &[0.0; 2], &mut poses);
    assert!(overflow
        .unwrap_err()
        .to_string()
        .contains("too large to normalise"));
}

#[test]
fn visuals_are_read_with_their_colours_and_bad_ones_kept_as_malformed() {
    let robot = robot();
    let visuals = robot.visuals();
    assert_eq!(visuals.len(), 6);
    assert_eq!(visuals[0].frame, 0);
    assert_eq!(
        visuals[0].geometry,
        Geometry::Box {
            size: [1.0, 0.8, 0.6]
        }
    );
    assert_eq!(visuals[0].color, Some([0.9, 0.7, 0.2, 1.0]));
    match &visuals[1].geometry {
        Geometry::Malformed { message } => assert!(message.contains("no shape"), "{message}"),
        other => panic!("{other:?}"),
    }
    assert_eq!(
        visuals[2].geometry,
        Geometry::Cylinder {
            radius: 0.05,
            length: 0.8
        }
    );
    assert_eq!(visuals[2].color, Some([0.1, 0.2, 0.3, 0.5]));
    assert_eq!(
        visuals[2].origin,
        Transform::from_xyz_rpy([0.4, 0.0, 0.0], [0.0, std::f64::consts::FRAC_PI_2, 0.0])
    );
    assert_eq!(visuals[3].geometry, Geometry::Sphere { radius: 0.07 });
    assert_eq!(visuals[3].frame, 2);
    assert_eq!(
        visuals[4].geometry,
        Geometry::Mesh {
            filename: "package://gripper_pkg/meshes/tool.stl".into(),
            scale: [0.001; 3]
        }
    );
    match &visuals[5].geometry {
        Geometry::Malformed { message } => {
            assert!(message.contains("expected three numbers"), "{message}");
            assert!(
                message.starts_with("line 45: <box size=\"0.1 0.2\">"),
                "{message}"
            );
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_material_given_its_colour_in_one_visual_colours_the_others() {
    let xml = r#"<robot name="r"><link name="a">
      <inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
      <visual><geometry><box size="1 1 1"/></geometry><material name="blue"><color rgba="0 0 1 1"/></material></visual>
      <visual><geometry><sphere radius="1"/></geometry><material name="blue"/></visual>
      <visual><geometry><sphere radius="1"/></geometry><material name="other"/></visual>
      <visual><geometry><sphere radius="1"/></geometry><material><color rgba="1 z 0 1"/></material></visual>
    </link></robot>"#;
    let robot = Robot::from_urdf_string(xml, &UrdfOptions::default()).unwrap();
    let colors: Vec<_> = robot.visuals().iter().map(|v| v.color).collect();
    assert_eq!(
        colors[..3],
        [Some([0.0, 0.0, 1.0, 1.0]), Some([0.0, 0.0, 1.0, 1.0]), None]
    );
    match &robot.visuals()[3].geometry {
        Geometry::Malformed { message } => assert_eq!(
            message,
            "line 6: <color rgba=\"1 z 0 1\">: expected four numbers between 0 and 1"
        ),
        other => panic!("{other:?}"),
    }
}

#[test]
fn malformed_visuals_never_fail_the_model() {
    let cases = [
        r#"<visual><geometry><box size="1 nan 1"/></geometry></visual>"#,
        r#"<visual><geometry><cylinder radius="-1" length="1"/></geometry></visual>"#,
        r#"<visual><geometry><sphere/></geometry></visual>"#,
        r#"<visual><geometry><sphere radius="0"/></geometry></visual>"#,
        r#"<visual><geometry><mesh/></geometry></visual>"#,
        r#"<visual><geometry><mesh filename="a.stl" scale="0 1 1"/></geometry></visual>"#,
        r#"<visual><geometry><box size="1 1 1"/><sphere radius="1"/></geometry></visual>"#,
        r#"<visual><origin xyz="0 0 1e300"/><geometry><box size="1 1 1"/></geometry></visual>"#,
        r#"<visual><origin xyz="inf 0 0"/><geometry><box size="1 1 1"/></geometry></visual>"#,
        r#"<visual><geometry><box size="1 1 1"/></geometry><material><color rgba="2 0 0 1"/></material></visual>"#,
    ];
    for visual in cases {
        let xml = format!(
            r#"<robot name="r"><link name="a">{visual}<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>"#
        );
        let robot = Robot::from_urdf_string(&xml, &UrdfOptions::default())
            .unwrap_or_else(|e| panic!("{visual}: {e}"));
        assert!(
            matches!(robot.visuals()[0].geometry, Geometry::Malformed { .. }),
            "{visual}: {:?}",
            robot.visuals()[0]
        );
        let scene = robot.scene(&MeshSearch::default());
        assert_eq!(scene.warnings.len(), 1, "{visual}");
        assert!(
            scene.warnings[0].starts_with("link 'a', visual 1: "),
            "{}",
            scene.warnings[0]
        );
        assert!(scene.shapes.iter().all(|s| s.stand_in));
    }
}

#[test]
fn the_scene_finds_meshes_through_the_package_above_the_urdf() {
    let root = package_tree("above", true);
    let urdf = root.join("gripper_pkg/urdf/robot.urdf");
    let robot = Robot::from_urdf(&urdf, &options()).unwrap();
    assert_eq!(
        robot.urdf_dir(),
        Some(root.join("gripper_pkg/urdf").as_path())
    );
    let search = MeshSearch {
        ros_package_path: Some(String::new()),
        ..MeshSearch::default()
    };
    let scene = robot.scene(&search);
    // the base's shapeless visual and the finger's bad box are the two warnings
    assert_eq!(scene.warnings.len(), 2, "{:?}", scene.warnings);
    assert!(scene.warnings[0].starts_with("link 'base', visual 2: "));
    assert!(scene.warnings[1].starts_with("link 'finger_link', visual 1: line 45"));
    let mesh = scene
        .shapes
        .iter()
        .find(|s| matches!(s.geometry, Geometry::Mesh { .. }))
        .unwrap();
    assert_eq!(mesh.frame, 4);
    assert_eq!(
        mesh.mesh,
        Some((root.join("gripper_pkg/meshes/tool.stl"), MeshFormat::Stl))
    );
    assert!(!mesh.stand_in);
    // l2 has no visual: a capsule to each child's joint, grey
    let l2: Vec<_> = scene.shapes.iter().filter(|s| s.frame == 3).collect();
    assert_eq!(l2.len(), 2);
    let lengths: Vec<f64> = l2
        .iter()
        .map(|s| match s.geometry {
            Geometry::Capsule { length, .. } => length,
            _ => panic!("{s:?}"),
        })
        .collect();
    assert!((lengths[0] - 0.6).abs() < 1e-15);
    assert!((lengths[1] - (0.09f64 + 0.01).sqrt()).abs() < 1e-15);
    // a tenth of the segment, kept within 1 and 6 cm
    let radii: Vec<f64> = l2
        .iter()
        .map(|s| match s.geometry {
            Geometry::Capsule { radius, .. } => radius,
            _ => unreachable!(),
        })
        .collect();
    assert_eq!(radii[0], 0.06);
    assert!((radii[1] - 0.1 * (0.09f64 + 0.01).sqrt()).abs() < 1e-16);
    // the capsule's axis points at the child's joint, from half-way
    let to_tool = &l2[0].origin;
    assert!((to_tool.translation - Vec3::new(0.3, 0.0, 0.0)).norm() < 1e-15);
    let axis = to_tool.rotation.transpose() * Vec3::z();
    assert!((axis - Vec3::x()).norm() < 1e-15);
    assert!(l2.iter().all(|s| !s.stand_in && s.color.is_some()));
    // the base keeps its good box and gets a stand-in for the shapeless visual
    let base: Vec<_> = scene.shapes.iter().filter(|s| s.frame == 0).collect();
    assert_eq!(base.iter().filter(|s| s.stand_in).count(), 1);
    assert_eq!(base.iter().filter(|s| !s.stand_in).count(), 1);
    // shapes come in frame order
    assert!(scene.shapes.windows(2).all(|w| w[0].frame <= w[1].frame));
    std::fs::remove_dir_all(root).unwrap();
}

#[test]
fn a_missing_mesh_warns_with_the_link_and_file_and_gets_a_stand_in() {
    let root = package_tree("missing", false);
    let robot = Robot::from_urdf(root.join("gripper_pkg/urdf/robot.urdf"), &options()).unwrap();
    let search = MeshSearch {
        ros_package_path: Some(String::new()),
        ..MeshSearch::default()
    };
    let scene = robot.scene(&search);
    let warning = scene
        .warnings
        .iter()
        .find(|w| w.starts_with("link 'tool'"))
        .unwrap();
    let expected = format!(
        "link 'tool', mesh 'package://gripper_pkg/meshes/tool.stl': no file at {} (package \
         'gripper_pkg' is {}); drawn as a stand-in",
        root.join("gripper_pkg/meshes/tool.stl").display(),
        root.join("gripper_pkg").display()
    );
    assert_eq!(warning, &expected);
    let tool: Vec<_> = scene.shapes.iter().filter(|s| s.frame == 4).collect();
    assert_eq!(tool.len(), 1);
    assert!(tool[0].stand_in);
    assert_eq!(tool[0].geometry, Geometry::Sphere { radius: 0.04 });
    // a string URDF has no directory: the package is unknown
    let robot = Robot::from_urdf_string(URDF, &options()).unwrap();
    let scene = robot.scene(&search);
    assert!(scene
        .warnings
        .iter()
        .any(|w| w
            .contains("package 'gripper_pkg' not found: give its directory in the package map")));
    std::fs::remove_dir_all(root).unwrap();
}

#[test]
fn packages_resolve_through_the_map_then_ros_package_path() {
    let root = package_tree("map", true);
    let pkg = root.join("gripper_pkg");
    let file = pkg.join("meshes/tool.stl");
    let name = "package://gripper_pkg/meshes/tool.stl";
    let none = Some(String::new());
    let map = MeshSearch {
        packages: BTreeMap::from([("gripper_pkg".to_string(), pkg.clone())]),
        ros_package_path: none.clone(),
    };
    assert_eq!(map.resolve(name, None), Ok(file.clone()));
    let ros = MeshSearch {
        ros_package_path: Some(format!("/nonexistent:{}", root.display())),
        ..MeshSearch::default()
    };
    assert_eq!(ros.resolve(name, None), Ok(file.clone()));
    let ros_itself = MeshSearch {
        ros_package_path: Some(pkg.display().to_string()),
        ..MeshSearch::default()
    };
    assert_eq!(ros_itself.resolve(name, None), Ok(file.clone()));
    // the map wins over the directories above the URDF
    let elsewhere = root.join("copy");
    std::fs::create_dir_all(elsewhere.join("meshes")).unwrap();
    std::fs::write(elsewhere.join("meshes/tool.stl"), stl_triangle()).unwrap();
    let first = MeshSearch {
        packages: BTreeMap::from([("gripper_pkg".to_string(), elsewhere.clone())]),
        ros_package_path: none.clone(),
    };
    assert_eq!(
        first.resolve(name, Some(&pkg.join("urdf"))),
        Ok(elsewhere.join("meshes/tool.stl"))
    );
    // relative, absolute and file:// names
    let plain = MeshSearch {
        ros_package_path: none,
        ..MeshSearch::default()
    };
    assert_eq!(
        plain.resolve("../meshes/tool.stl", Some(&pkg.join("urdf"))),
        Ok(pkg.join("urdf/../meshes/tool.stl"))
    );
    let absolute = file.display().to_string();
    assert_eq!(plain.resolve(&absolute, None), Ok(file.clone()));
    assert_eq!(
        plain.resolve(&format!("file://{absolute}"), None),
        Ok(file.clone())
    );
    let missing = plain.resolve("nope.stl", Some(Path::new("/tmp")));
    assert_eq!(missing, Err("no file at /tmp/nope.stl".to_string()));
    assert_eq!(
        plain.resolve(&format!("file://localhost{absolute}"), None),
        Ok(file.clone())
    );
    assert_eq!(
        plain.resolve("meshes/tool.stl", None),
        Err(
            "the relative path 'meshes/tool.stl' needs the URDF file's folder: load the URDF \
             from its file, or name the mesh with package:// or an absolute path"
                .to_string()
        )
    );
    // package names and paths that leave the package
    assert_eq!(
        map.resolve("package:///meshes/tool.stl", Some(&pkg.join("urdf"))),
        Err("no package name after package://".to_string())
    );
    for escape in [
        "package://gripper_pkg/../gripper_pkg/meshes/tool.stl",
        "package://gripper_pkg//etc/passwd",
    ] {
        let error = map.resolve(escape, None).unwrap_err();
        assert!(
            error.contains("leaves the package 'gripper_pkg'"),
            "{error}"
        );
    }
    // (issue 24) `..` as the package name looked in the folder above each candidate directory:
    // root/outside/secret.stl was found from a URDF in root/gripper_pkg/urdf
    std::fs::create_dir_all(root.join("outside")).unwrap();
    std::fs::write(root.join("outside/secret.stl"), stl_triangle()).unwrap();
    for name in ["..", "."] {
        let escape = format!("package://{name}/outside/secret.stl");
        assert_eq!(
            map.resolve(&escape, Some(&pkg.join("urdf"))),
            Err(format!(
                "'{name}' is not a package name (package://NAME/path names a file inside the \
                 package NAME)"
            ))
        );
    }
    // a symbolic link inside the package to a file outside it is refused; one that stays
    // inside is followed
    #[cfg(unix)]
    {
        let link = pkg.join("meshes/secret.stl");
        std::os::unix::fs::symlink(root.join("outside/secret.stl"), &link).unwrap();
        let error = map
            .resolve("package://gripper_pkg/meshes/secret.stl", None)
            .unwrap_err();
        assert!(
            error.starts_with("the path 'meshes/secret.stl' leaves the package 'gripper_pkg' (")
                && error.contains("once links are resolved"),
            "{error}"
        );
        std::os::unix::fs::symlink(pkg.join("meshes/tool.stl"), pkg.join("meshes/alias.stl"))
            .unwrap();
        assert_eq!(
            map.resolve("package://gripper_pkg/meshes/alias.stl", None),
            Ok(pkg.join("meshes/alias.stl"))
        );
    }
    std::fs::remove_dir_all(root).unwrap();
}

#[test]
fn mesh_files_are_checked_by_their_bytes() {
    let stl = stl_triangle();
    assert_eq!(check_mesh_bytes(MeshFormat::Stl, &stl), Ok(()));
    assert!(check_mesh_bytes(MeshFormat::Stl, &stl[..133]).is_err());
    let mut zero = stl.clone();
    zero[80..84].copy_from_slice(&0u32.to_le_bytes());
    zero.truncate(84);
    assert!(check_mesh_bytes(MeshFormat::Stl, &zero).is_err());
    let ascii =
        b"  solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nendloop\nendfacet\nendsolid";
    assert_eq!(check_mesh_bytes(MeshFormat::Stl, ascii), Ok(()));
    assert!(check_mesh_bytes(MeshFormat::Stl, b"solid but nothing else").is_err());
    assert!(check_mesh_bytes(MeshFormat::Stl, b"garbage").is_err());
    assert_eq!(
        check_mesh_bytes(
            MeshFormat::Dae,
            b"<?xml?><COLLADA version=\"1.4\"></COLLADA>"
        ),
        Ok(())
    );
    assert_eq!(
        check_mesh_bytes(MeshFormat::Dae, b"<?xml version=\"1.0\"?><mesh/>"),
        Err("not a COLLADA file: no <COLLADA> element".into())
    );
    let truncated = b"<?xml version=\"1.0\"?><COLLADA><library_geometries><geometry>";
    assert_eq!(
        check_mesh_bytes(MeshFormat::Dae, truncated),
        Err("not a COLLADA file: the XML ends inside an element".into())
    );
    let mismatched = b"<COLLADA><asset></COLLADA>";
    assert!(check_mesh_bytes(MeshFormat::Dae, mismatched)
        .unwrap_err()
        .starts_with("not a COLLADA file: XML error at byte"));
    assert_eq!(
        check_mesh_bytes(MeshFormat::Dae, b"<COLLADA>\xff</COLLADA>"),
        Err("not a COLLADA file: not UTF-8 text (byte 9)".into())
    );
    // the root element decides, whether empty or not
    let no_collada = Err("not a COLLADA file: no <COLLADA> element".to_string());
    assert_eq!(check_mesh_bytes(MeshFormat::Dae, b"<COLLADA/>"), Ok(()));
    assert_eq!(
        check_mesh_bytes(MeshFormat::Dae, b"<a><COLLADA/></a>"),
        no_collada
    );
    assert_eq!(
        check_mesh_bytes(MeshFormat::Dae, b"<a><COLLADA></COLLADA></a>"),
        no_collada
    );
    assert_eq!(
        check_mesh_bytes(MeshFormat::Dae, b"<a/><COLLADA/>"),
        no_collada
    );
    assert_eq!(
        check_mesh_bytes(MeshFormat::Dae, b"<a></a><COLLADA></COLLADA>"),
        no_collada
    );
    let extensions = [MeshFormat::Stl, MeshFormat::Dae, MeshFormat::Obj].map(|f| f.extension());
    assert_eq!(extensions, ["stl", "dae", "obj"]);
    assert_eq!(
        check_mesh_bytes(
            MeshFormat::Obj,
            b"# o\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
        ),
        Ok(())
    );
    assert!(check_mesh_bytes(MeshFormat::Obj, b"v 0 0 0\n").is_err());
    assert!(check_mesh_bytes(MeshFormat::Obj, b"vt 0 0\nfo 1\n").is_err());
    // by file: the extension chooses the format
    let dir = std::env::temp_dir().join(format!("orbitflex_mesh_check_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("a.STL"), &stl).unwrap();
    std::fs::write(dir.join("b.ply"), &stl).unwrap();
    std::fs::write(dir.join("c.dae"), &stl).unwrap();
    assert_eq!(
        orbitflex::check_mesh_file(&dir.join("a.STL")),
        Ok(MeshFormat::Stl)
    );
    assert_eq!(
        orbitflex::check_mesh_file(&dir.join("b.ply")),
        Err("unsupported mesh format '.ply'; expected .stl, .dae or .obj".into())
    );
    assert_eq!(
        orbitflex::check_mesh_file(&dir.join("c.dae")),
        Err("not a COLLADA file: not UTF-8 text (byte 94)".into())
    );
    // at most MAX_MESH_BYTES are read: one byte more is refused, the limit itself is checked
    let big = dir.join("big.stl");
    let file = std::fs::File::create(&big).unwrap();
    file.set_len(orbitflex::MAX_MESH_BYTES + 1).unwrap();
    assert_eq!(
        orbitflex::check_mesh_file(&big),
        Err("more than the 64000000 bytes read".into())
    );
    file.set_len(orbitflex::MAX_MESH_BYTES).unwrap();
    assert!(orbitflex::check_mesh_file(&big)
        .unwrap_err()
        .starts_with("not an STL file: 64000000 bytes"));
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn built_models_have_a_frame_per_body_and_for_the_ee() {
    let robot = orbitflex::testing::random_chain(3, 7);
    let names: Vec<String> = robot.frame_names().iter().map(|s| s.to_string()).collect();
    let mut expected: Vec<String> = robot.body_names().to_vec();
    if !expected.contains(&robot.ee_link().to_string()) {
        expected.push(robot.ee_link().to_string());
    }
    assert_eq!(names, expected);
    let parents: Vec<Option<usize>> = robot.frames().iter().map(|f| f.parent).collect();
    assert_eq!(parents[..4], [None, Some(0), Some(1), Some(2)]);
    for (k, joint) in robot.joints().iter().enumerate() {
        assert_eq!(robot.frames()[k + 1].joint_origin, joint.origin);
    }
    assert_eq!(robot.frames()[0].joint_origin, Transform::identity());
    // the EE frame sits where the EE pose is
    let joints = FlexibleJoints::uniform(3, 1e4, 0.1, 1.0, 0.0).unwrap();
    let arm = FlexibleArm::new(robot.clone(), joints).unwrap();
    let mut x = arm.rest_state();
    x[7..10].copy_from_slice(&[0.4, -1.0, 2.0]);
    let mut poses = vec![0.0; 7 * names.len()];
    let mut data = Data::new(&robot);
    algorithms::frame_poses(&robot, &mut data, &x[..7], &x[7..10], &mut poses).unwrap();
    let k = robot.frame_index(robot.ee_link()).unwrap();
    for (a, b) in poses[7 * k..7 * k + 7].iter().zip(arm.ee_pose(&x, 0)) {
        assert!((a - b).abs() < 1e-14);
    }
    // the stick figure: a capsule per parent-child pair with an offset, a sphere for leaves
    let skeleton = robot.skeleton();
    assert!(skeleton
        .iter()
        .all(|s| s.color.is_none() && s.mesh.is_none()));
    assert!(skeleton
        .iter()
        .any(|s| matches!(s.geometry, Geometry::Capsule { .. })));
}

#[test]
fn the_builder_checks_frames_and_visuals() {
    use orbitflex::spatial::Inertia;
    use orbitflex::{LinkFrame, Visual};
    let inertia = Inertia::from_com(1.0, Vec3::zeros(), Mat3::identity());
    let start = || {
        RobotBuilder::new("r", "a", inertia).joint(
            "j",
            Transform::identity(),
            Vec3::z(),
            "b",
            inertia,
        )
    };
    let frame = |name: &str, body: usize, parent: Option<usize>| LinkFrame {
        name: name.into(),
        body,
        placement: Transform::identity(),
        parent,
        joint_origin: Transform::identity(),
    };
    let error = |b: RobotBuilder| b.build().unwrap_err().to_string();
    let twice = start().frames(vec![frame("a", 0, None), frame("a", 1, Some(0))]);
    assert!(error(twice).contains("frame 'a' is named twice"));
    let no_body = start().frames(vec![frame("a", 0, None), frame("b", 2, Some(0))]);
    assert!(error(no_body).contains("frame 'b': body 2 does not exist (the model has 2 bodies)"));
    let late = start().frames(vec![frame("a", 0, Some(1)), frame("b", 1, None)]);
    assert!(error(late).contains("frame 'a': its parent frame must come before it"));
    let visual = Visual {
        frame: 2,
        origin: Transform::identity(),
        geometry: Geometry::Sphere { radius: 1.0 },
        color: None,
    };
    let stray = start().visuals(vec![visual]);
    assert!(error(stray).contains("a visual names frame 2; the model has 2 frames"));
}

#[test]
fn along_a_trajectory_frame_poses_equal_single_calls() {
    let robot = Robot::from_urdf_string(URDF, &options()).unwrap();
    let joints = FlexibleJoints::uniform(2, 50.0, 0.01, 0.5, 0.0).unwrap();
    let arm = FlexibleArm::new(robot.clone(), joints).unwrap();
    let mut x0 = arm.rest_state();
    x0[7 + 2..7 + 4].copy_from_slice(&[0.3, -0.2]); // θ ≠ q: the springs start loaded
    let traj = arm
        .simulate(&x0, 1e-3, 50, &mut Schedule::Zero, &Wrenches::ZERO)
        .unwrap();
    let rows = traj.rows();
    let frames = robot.frames().len();
    let link = rows.frame_poses(&arm, None);
    let motor = rows.frame_poses(&arm, Some(3.0));
    let mut data = Data::new(&robot);
    let mut one = vec![0.0; 7 * frames];
    for (k, x) in rows.iter().enumerate() {
        let (q, theta) = (&x[7..9], &x[9..11]);
        algorithms::frame_poses(&robot, &mut data, &x[..7], q, &mut one).unwrap();
        assert_eq!(&link[7 * frames * k..7 * frames * (k + 1)], &one[..]);
        let ghost: Vec<f64> = q
            .iter()
            .zip(theta)
            .map(|(q, t)| q + 3.0 * (t - q))
            .collect();
        algorithms::frame_poses(&robot, &mut data, &x[..7], &ghost, &mut one).unwrap();
        assert_eq!(&motor[7 * frames * k..7 * frames * (k + 1)], &one[..]);
    }
    assert_ne!(link, motor);
    // chosen rows only, in the order asked
    let width = 7 * frames;
    let some = rows.frame_poses_at(&arm, None, &[7, 0, 7]);
    assert_eq!(&some[..width], &link[7 * width..8 * width]);
    assert_eq!(&some[width..2 * width], &link[..width]);
    assert_eq!(&some[2 * width..], &link[7 * width..8 * width]);
}

/// A binary STL of `triangles` zero triangles, written sparse (the zeros are not stored).
fn sparse_stl(path: &Path, triangles: u32) {
    use std::io::Write;
    let mut file = std::fs::File::create(path).unwrap();
    file.write_all(&[0u8; 80]).unwrap();
    file.write_all(&triangles.to_le_bytes()).unwrap();
    file.set_len(84 + 50 * u64::from(triangles)).unwrap();
}

#[test]
fn one_scene_reads_at_most_its_mesh_budget() {
    let dir = std::env::temp_dir().join(format!("orbitflex_mesh_budget_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // five distinct 60 MB files (240 MB fit in the 256 MB budget, the fifth does not), and the
    // first one again, which costs nothing more
    let visuals: String = (0..5)
        .chain([0])
        .map(|k| format!(r#"<visual><geometry><mesh filename="m{k}.stl"/></geometry></visual>"#))
        .collect();
    for k in 0..5 {
        sparse_stl(&dir.join(format!("m{k}.stl")), 1_200_000);
    }
    let xml = format!(
        r#"<robot name="r"><link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>{visuals}</link></robot>"#
    );
    std::fs::write(dir.join("r.urdf"), xml).unwrap();
    let robot = Robot::from_urdf(dir.join("r.urdf"), &UrdfOptions::default()).unwrap();
    let scene = robot.scene(&MeshSearch::default());
    assert_eq!(
        scene.warnings,
        [
            "link 'a', mesh 'm4.stl': the meshes would pass 256000000 bytes in all; drawn as a \
          stand-in"
        ]
    );
    let meshes = scene.shapes.iter().filter(|s| s.mesh.is_some()).count();
    assert_eq!(meshes, 5);
    // exactly the budget: four ASCII STLs of 64 MB each (a header, then sparse zeros)
    let visuals: String = (0..4)
        .map(|k| format!(r#"<visual><geometry><mesh filename="a{k}.stl"/></geometry></visual>"#))
        .collect();
    for k in 0..4 {
        use std::io::Write;
        let mut file = std::fs::File::create(dir.join(format!("a{k}.stl"))).unwrap();
        file.write_all(b"solid s\nfacet normal 0 0 1\n").unwrap();
        file.set_len(orbitflex::MAX_MESH_BYTES).unwrap();
    }
    let xml = format!(
        r#"<robot name="r"><link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>{visuals}</link></robot>"#
    );
    std::fs::write(dir.join("exact.urdf"), xml).unwrap();
    let robot = Robot::from_urdf(dir.join("exact.urdf"), &UrdfOptions::default()).unwrap();
    let scene = robot.scene(&MeshSearch::default());
    assert_eq!(scene.warnings, Vec::<String>::new());
    assert_eq!(
        4 * orbitflex::MAX_MESH_BYTES,
        orbitflex::MAX_SCENE_MESH_BYTES
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_capsule_to_a_child_straight_below_points_down() {
    let xml = r#"<robot name="r">
      <link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
      <joint name="f" type="fixed"><parent link="a"/><child link="b"/><origin xyz="0 0 -2"/></joint>
      <link name="b"/></robot>"#;
    let robot = Robot::from_urdf_string(xml, &UrdfOptions::default()).unwrap();
    let capsule = &robot.skeleton()[0];
    assert_eq!(
        capsule.geometry,
        Geometry::Capsule {
            radius: 0.06,
            length: 2.0
        }
    );
    let rotation = capsule.origin.rotation;
    assert_eq!(rotation.transpose() * Vec3::z(), -Vec3::z());
    assert!((rotation * rotation.transpose() - Mat3::identity()).norm() < 1e-15);
    assert!((rotation.determinant() - 1.0).abs() < 1e-15);
    assert_eq!(capsule.origin.translation, Vec3::new(0.0, 0.0, -1.0));
}

#[test]
fn a_child_at_the_link_origin_gives_a_sphere_not_a_capsule() {
    let xml = r#"<robot name="r">
      <link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
      <joint name="f" type="fixed"><parent link="a"/><child link="b"/></joint>
      <link name="b"/></robot>"#;
    let robot = Robot::from_urdf_string(xml, &UrdfOptions::default()).unwrap();
    let shapes = robot.skeleton();
    assert_eq!(shapes.len(), 2);
    assert!(shapes
        .iter()
        .all(|s| s.geometry == Geometry::Sphere { radius: 0.04 }));
}
