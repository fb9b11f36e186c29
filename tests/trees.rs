//! Kinematic trees with several end-effectors: the recursive algorithms against the tree operator
//! form, the URDF and builder rules for trees, and the invariants of the flexible simulation on
//! the built-in dual-arm servicer.

use nalgebra::{DMatrix, DVector, Vector6};
use orbitflex::algorithms::{self, Data};
use orbitflex::spatial::{Inertia, Mat3, Transform, Vec3};
use orbitflex::testing::{random_chain, random_state, random_tree_all_leaves, Rng};
use orbitflex::{
    ArmWorkspace, FlexibleArm, FlexibleJoints, Inputs, Loads, Method, Operators, RigidState, Robot,
    RobotBuilder, Schedule, StateSpec, UrdfOptions, Wrenches,
};

/// Depth-first shapes: a trunk with two branches, three arms on the base with a fork, and a
/// star of single joints on the base.
const SHAPES: [&[usize]; 3] = [
    &[0, 0, 1, 2, 2, 4, 1, 6],
    &[0, 0, 1, 2, 1, 4, 0, 6, 6, 0],
    &[0, 0, 0, 0, 0],
];

fn rel(got: &[f64], want: &[f64]) -> f64 {
    let scale = want.iter().fold(1.0_f64, |m, v| m.max(v.abs()));
    got.iter()
        .zip(want)
        .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
        / scale
}

/// Every recursive result equals the dense tree operator form, with one wrench per end-effector.
#[test]
fn recursive_algorithms_equal_the_tree_operator_form() {
    for (s, parents) in SHAPES.iter().enumerate() {
        for seed in 0..3 {
            let robot = random_tree_all_leaves(parents, seed);
            let (n, k) = (robot.dof(), robot.end_effectors().len());
            assert!(k >= 2, "shape {s} has several leaves");
            let (q, v, qd) = random_state(&robot, seed);
            let mut rng = Rng::new(seed + 3);
            let (tau, fb, f, acc) = (
                rng.vector(n, -5.0, 5.0),
                rng.vector(6, -5.0, 5.0),
                rng.vector(6 * k, -5.0, 5.0),
                rng.vector(6 + n, -2.0, 2.0),
            );
            let state = RigidState::new(&q, &v, &qd);
            let ops = Operators::new(&robot, &state).unwrap();
            let label = format!("shape {s} seed {seed}");
            let mut data = Data::new(&robot);

            let m = algorithms::crba(&robot, &mut data, &q).unwrap().clone();
            assert!(
                rel(m.as_slice(), ops.mass_matrix().as_slice()) < 1e-12,
                "{label}: M"
            );
            let c = algorithms::bias_forces(&robot, &mut data, &state)
                .unwrap()
                .clone();
            assert!(
                rel(c.as_slice(), ops.bias_forces().as_slice()) < 1e-12,
                "{label}: C"
            );

            let loads = Loads::from_slices(Some(&fb), Some(&f)).unwrap();
            let a = algorithms::aba(&robot, &mut data, &state, &tau, &loads)
                .unwrap()
                .clone();
            let a_ops = ops.forward_dynamics(&tau, &loads).unwrap();
            assert!(rel(a.as_slice(), a_ops.as_slice()) < 1e-9, "{label}: FD");

            let g = algorithms::rnea(&robot, &mut data, &state, &acc[..6], &acc[6..], &f)
                .unwrap()
                .clone();
            let g_ops = ops.inverse_dynamics(&acc[..6], &acc[6..], &f).unwrap();
            assert!(rel(g.as_slice(), g_ops.as_slice()) < 1e-12, "{label}: ID");

            // B has one block column per end-effector, J and Φ_{e,B} are stacked per EE
            assert_eq!(ops.b_ee.shape(), (6 * n, 6 * k));
            assert_eq!(ops.j.shape(), (6 * k, n));
            assert_eq!(ops.phi_ee_base.shape(), (6 * k, 6));
            for (e, ee) in robot.end_effectors().iter().enumerate() {
                algorithms::ee_jacobian(&robot, &mut data, &q, e).unwrap();
                let j_ops = ops.j.rows(6 * e, 6).into_owned();
                assert!((&data.jacobian - &j_ops).amax() < 1e-12, "{label}: J_{e}");
                let phi = ops.phi_ee_base.rows(6 * e, 6).into_owned();
                assert!((data.ee_base - phi).amax() < 1e-12, "{label}: Φ_{e}B");
                let path: Vec<usize> = robot.path_to_base(ee.body).collect();
                for body in 1..=n {
                    let moved = data.jacobian.column(body - 1).amax() > 0.0;
                    assert_eq!(moved, path.contains(&body), "{label}: J_{e} column {body}");
                }
            }
            // the force map is the transpose of the stacked twist map
            let map = ops.ee_force_map();
            assert_eq!(map.shape(), (6 + n, 6 * k));
            assert_eq!(map.view((0, 0), (6, 6 * k)), ops.phi_ee_base.transpose());
        }
    }
}

/// On a chain the tree operators are today's: `B` has one block column, non-zero only in the last
/// block, `Φ_{n+1,e}ᵀ`.
#[test]
fn on_a_chain_the_operators_keep_their_shapes() {
    let robot = random_chain(5, 2);
    assert!(robot.is_chain());
    assert!(!random_tree_all_leaves(SHAPES[2], 2).is_chain());
    let (q, v, qd) = random_state(&robot, 2);
    let ops = Operators::new(&robot, &RigidState::new(&q, &v, &qd)).unwrap();
    assert_eq!(ops.b_ee.shape(), (30, 6));
    assert_eq!(ops.b_ee.rows(0, 24).amax(), 0.0);
    let last = ops.b_ee.view((24, 0), (6, 6)).into_owned();
    let expected = robot.ee_transform().matrix().transpose();
    assert_eq!(last, DMatrix::from_column_slice(6, 6, expected.as_slice()));
    assert_eq!(ops.j.shape(), (6, 5));
    assert_eq!(ops.phi_ee_base.shape(), (6, 6));
}

/// An EE wrench whose length is not 6 per end-effector is refused by every entry point, with the
/// end-effectors named.
#[test]
fn ee_wrench_length_is_one_wrench_per_end_effector() {
    let robot = random_tree_all_leaves(SHAPES[2], 1);
    let n = robot.dof();
    let (q, v, qd) = random_state(&robot, 1);
    let state = RigidState::new(&q, &v, &qd);
    let mut data = Data::new(&robot);
    let six = [0.0; 6];
    let loads = Loads::from_slices(None, Some(&six)).unwrap();
    let err = algorithms::aba(&robot, &mut data, &state, &vec![0.0; n], &loads)
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "ee_wrench: expected 24 numbers (one [moment; force] per end-effector: ee1, ee2, ee3, \
         ee4), given 6"
    );
    let err = algorithms::rnea(&robot, &mut data, &state, &[0.0; 6], &vec![0.0; n], &six)
        .unwrap_err()
        .to_string();
    assert!(err.contains("expected 24 numbers"), "{err}");
    let ops = Operators::new(&robot, &state).unwrap();
    assert!(ops.forward_dynamics(&vec![0.0; n], &loads).is_err());
    assert!(ops
        .inverse_dynamics(&[0.0; 6], &vec![0.0; n], &six)
        .is_err());
    // and not a whole number of wrenches at all
    assert!(Loads::from_slices(None, Some(&[0.0; 7])).is_err());
    // no wrench at all is the same as zeros
    let none = algorithms::aba(&robot, &mut data, &state, &vec![1.0; n], &Loads::ZERO)
        .unwrap()
        .clone();
    let zeros = [0.0; 24];
    let zero = Loads::from_slices(None, Some(&zeros)).unwrap();
    let with = algorithms::aba(&robot, &mut data, &state, &vec![1.0; n], &zero).unwrap();
    assert_eq!(&none, with);
}

/// A wrench on one end-effector moves only that end-effector's joints' torques, as `J_eᵀ f_e`.
#[test]
fn each_wrench_acts_through_its_own_jacobian() {
    let robot = random_tree_all_leaves(SHAPES[1], 4);
    let (n, k) = (robot.dof(), robot.end_effectors().len());
    let (q, v, qd) = random_state(&robot, 4);
    let state = RigidState::new(&q, &v, &qd);
    let mut data = Data::new(&robot);
    let acc = vec![0.1; 6 + n];
    let free = algorithms::rnea(&robot, &mut data, &state, &acc[..6], &acc[6..], &[])
        .unwrap()
        .clone();
    for e in 0..k {
        let mut f = vec![0.0; 6 * k];
        let w = [0.3, -0.2, 0.5, 4.0, -1.0, 2.0];
        f[6 * e..6 * e + 6].copy_from_slice(&w);
        let loaded = algorithms::rnea(&robot, &mut data, &state, &acc[..6], &acc[6..], &f)
            .unwrap()
            .clone();
        algorithms::ee_jacobian(&robot, &mut data, &q, e).unwrap();
        let w = Vector6::from_column_slice(&w);
        let joints = data.jacobian.transpose() * DVector::from_column_slice(w.as_slice());
        let base = data.ee_base.transpose() * w;
        let diff = &loaded - &free;
        assert!((diff.rows(0, 6) - DVector::from_column_slice(base.as_slice())).amax() < 1e-12);
        assert!((diff.rows(6, n) - joints).amax() < 1e-12, "EE {e}");
    }
}

const BRANCHED: &str = r#"<robot name="branched">
  <link name="bus"><inertial><mass value="100"/><inertia ixx="10" iyy="10" izz="10" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="b1"><inertial><mass value="2"/><origin xyz="0.2 0 0"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="b2"><inertial><mass value="2"/><origin xyz="0.2 0 0"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="a1"><inertial><mass value="2"/><origin xyz="0.2 0 0"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="a2"><inertial><mass value="2"/><origin xyz="0.2 0 0"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="tip_b"/>
  <link name="slider"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="jb2" type="revolute"><parent link="b1"/><child link="b2"/><origin xyz="0.4 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="ja1" type="continuous"><parent link="bus"/><child link="a1"/><origin xyz="0.5 0.3 0"/><axis xyz="0 0 1"/></joint>
  <joint name="ja2" type="revolute"><parent link="a1"/><child link="a2"/><origin xyz="0.4 0 0"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="jb1" type="continuous"><parent link="bus"/><child link="b1"/><origin xyz="0.5 -0.3 0"/><axis xyz="0 0 1"/></joint>
  <joint name="tb" type="fixed"><parent link="b2"/><child link="tip_b"/><origin xyz="0.4 0 0"/></joint>
  <joint name="slide" type="prismatic"><parent link="a1"/><child link="slider"/><axis xyz="1 0 0"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint>
</robot>"#;

/// A branched URDF written in no particular order loads as a tree numbered depth-first (children
/// in the order of their joints in the file), with every leaf an end-effector by default.
#[test]
fn branched_urdf_loads_depth_first_with_every_leaf() {
    let options = UrdfOptions {
        locked_joints: vec!["slide".into()],
        ..UrdfOptions::default()
    };
    let robot = Robot::from_urdf_string(BRANCHED, &options).unwrap();
    // bus's joints in file order: ja1, then jb1; a1's: ja2 (slide is locked)
    assert_eq!(robot.joint_names(), ["ja1", "ja2", "jb1", "jb2"]);
    assert_eq!(robot.parents(), [0, 0, 1, 0, 3]);
    assert_eq!(robot.subtree_sizes(), [5, 2, 1, 2, 1]);
    let children: Vec<Vec<usize>> = vec![vec![1, 3], vec![2], vec![], vec![4], vec![]];
    assert_eq!(robot.children(), children);
    assert!(!robot.is_chain());
    assert_eq!(robot.ee_links(), ["a2", "tip_b"]);
    assert_eq!(robot.end_effectors()[1].body, 4);
    assert_eq!(
        robot.end_effectors()[1].transform.translation,
        Vec3::new(0.4, 0.0, 0.0)
    );
    // with the whole first arm below a1 locked, a1 (which carries it) is that arm's end-effector
    let hand = UrdfOptions {
        locked_joints: vec!["slide".into(), "ja2".into()],
        ..UrdfOptions::default()
    };
    let robot = Robot::from_urdf_string(BRANCHED, &hand).unwrap();
    assert_eq!(robot.ee_links(), ["a1", "tip_b"]);
    assert_eq!(robot.joint_names(), ["ja1", "jb1", "jb2"]);
    // the locked slider's leaf counts once the lock-free leaves are named
    let named = UrdfOptions {
        ee_links: vec!["tip_b".into(), "slider".into(), "a1".into()],
        ..options.clone()
    };
    let robot = Robot::from_urdf_string(BRANCHED, &named).unwrap();
    assert_eq!(robot.ee_links(), ["tip_b", "slider", "a1"]);
    assert_eq!(robot.end_effectors()[2].body, 1);
    // ee_link is one end-effector, as before
    let one = UrdfOptions {
        ee_link: Some("a2".into()),
        ..options.clone()
    };
    let robot = Robot::from_urdf_string(BRANCHED, &one).unwrap();
    assert_eq!(robot.ee_links(), ["a2"]);
    assert_eq!(robot.dof(), 4);
}

#[test]
fn tree_urdf_errors_name_what_is_wrong() {
    let load = |options: UrdfOptions| {
        Robot::from_urdf_string(BRANCHED, &options)
            .unwrap_err()
            .to_string()
    };
    // a prismatic joint is still refused unless locked, wherever it sits
    assert_eq!(
        load(UrdfOptions::default()),
        "<urdf string>: joint 'slide' has type 'prismatic'; orbitflex models revolute and \
         continuous joints only (lock it with locked_joints=[\"slide\"] to treat it as fixed)"
    );
    // every unsupported joint in one message, and one locked_joints list that holds them all
    // (with those already locked): following the advice works the first time
    let two = BRANCHED.replace(
        r#"<joint name="tb" type="fixed">"#,
        r#"<joint name="tb" type="planar">"#,
    );
    let err = Robot::from_urdf_string(
        &two,
        &UrdfOptions {
            locked_joints: vec!["ja2".into()],
            ..UrdfOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert_eq!(
        err,
        "<urdf string>: 2 joints have types orbitflex does not model: 'tb' (planar), 'slide' \
         (prismatic); orbitflex models revolute and continuous joints only (lock them with \
         locked_joints=[\"ja2\", \"tb\", \"slide\"] to treat them as fixed)"
    );
    let advised = UrdfOptions {
        locked_joints: vec!["ja2".into(), "tb".into(), "slide".into()],
        ..UrdfOptions::default()
    };
    assert_eq!(
        Robot::from_urdf_string(&two, &advised)
            .unwrap()
            .joint_names(),
        ["ja1", "jb1", "jb2"]
    );
    let locked = || UrdfOptions {
        locked_joints: vec!["slide".into()],
        ..UrdfOptions::default()
    };
    let err = load(UrdfOptions {
        ee_links: vec!["a2".into(), "nope".into()],
        ..locked()
    });
    assert!(err.contains("unknown link (ee_links) 'nope'"), "{err}");
    let err = load(UrdfOptions {
        ee_links: vec!["a2".into(), "a2".into()],
        ..locked()
    });
    assert!(err.contains("'a2' is listed twice"), "{err}");
    let err = load(UrdfOptions {
        ee_link: Some("a2".into()),
        ee_links: vec!["tip_b".into()],
        ..locked()
    });
    assert!(err.contains("not both"), "{err}");
}

fn link() -> Inertia {
    Inertia::from_com(2.0, Vec3::new(0.3, 0.0, 0.0), Mat3::identity() * 0.1)
}

fn at(x: f64, y: f64) -> Transform {
    Transform::from_xyz_rpy([x, y, 0.0], [0.0; 3])
}

/// The builder makes trees with `joint_on` and names end-effectors anywhere; without any, each
/// leaf gets one.
#[test]
fn builder_makes_trees() {
    let base = Inertia::from_com(50.0, Vec3::zeros(), Mat3::identity() * 5.0);
    let tree = RobotBuilder::new("two_arms", "bus", base)
        .joint_on("bus", "l1", at(0.5, 0.3), Vec3::z(), "left1", link())
        .joint("l2", at(0.6, 0.0), Vec3::y(), "left2", link())
        .joint_on("bus", "r1", at(0.5, -0.3), Vec3::z(), "right1", link())
        .joint_on("right1", "r2", at(0.6, 0.0), Vec3::y(), "right2", link());
    let robot = tree.clone().build().unwrap();
    assert_eq!(robot.parents(), [0, 0, 1, 0, 3]);
    assert_eq!(robot.ee_links(), ["left2", "right2"]);
    let robot = tree
        .clone()
        .end_effector("grip", "right2", at(0.5, 0.0))
        .end_effector("camera", "bus", at(0.75, 0.0))
        .build()
        .unwrap();
    assert_eq!(robot.ee_links(), ["grip", "camera"]);
    assert_eq!(robot.end_effectors()[1].body, 0);
    assert_eq!(
        robot.ee_index("camera").unwrap(),
        1,
        "indexes follow the order given"
    );
    let err = robot.ee_index("gripper").unwrap_err().to_string();
    assert_eq!(
        err,
        "ee: no end-effector named \"gripper\"; the end-effectors are 'grip', 'camera'"
    );
    let err = robot.ee_jacobian(&[0.0; 4], None).unwrap_err().to_string();
    assert_eq!(
        err,
        "ee: the robot has 2 end-effectors ('grip', 'camera'); say which one with ee= (a name \
         or an index)"
    );
    assert!(robot.ee_jacobian(&[0.0; 4], Some(2)).is_err());
    // a Jacobian column is zero for joints that do not move that end-effector
    let camera = robot.ee_jacobian(&[0.1; 4], Some(1)).unwrap();
    assert_eq!(camera.amax(), 0.0);
    let grip = robot.ee_jacobian(&[0.1; 4], Some(0)).unwrap();
    assert_eq!(grip.column(0).amax(), 0.0);
    assert!(grip.column(3).amax() > 0.0);

    // refused: not depth-first, an unknown parent, an EE on an unknown link, a duplicate EE
    let err = RobotBuilder::new("t", "bus", base)
        .joint_on("bus", "l1", at(0.5, 0.3), Vec3::z(), "left1", link())
        .joint_on("bus", "r1", at(0.5, -0.3), Vec3::z(), "right1", link())
        .joint_on("left1", "l2", at(0.6, 0.0), Vec3::y(), "left2", link())
        .build()
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "<builder>: joint 'l2' hangs from 'left1', whose subtree was already closed by 'right1': \
         add the bodies depth-first (each branch complete before the next)"
    );
    let err = RobotBuilder::new("t", "bus", base)
        .joint_on("nowhere", "l1", at(0.5, 0.3), Vec3::z(), "left1", link())
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("joint 'l1': its parent link is not defined"),
        "{err}"
    );
    let err = RobotBuilder::new("t", "bus", base)
        .joint("l1", at(0.5, 0.3), Vec3::z(), "left1", link())
        .end_effector("tool", "nowhere", at(0.1, 0.0))
        .build()
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("end-effector 'tool' is placed on a link that is not defined"),
        "{err}"
    );
    let err = RobotBuilder::new("t", "bus", base)
        .joint("l1", at(0.5, 0.3), Vec3::z(), "left1", link())
        .ee("tool", at(0.1, 0.0))
        .ee("tool", at(0.2, 0.0))
        .build()
        .unwrap_err()
        .to_string();
    assert!(err.contains("end-effector 'tool' is named twice"), "{err}");
}

/// The dual-arm servicer: two 7-joint arms on the bus, mirror images of each other.
#[test]
fn dual_arm_servicer_is_two_mirrored_arms() {
    let robot = Robot::dual_arm();
    assert_eq!(robot.dof(), 14);
    assert_eq!(robot.ee_links(), ["left_ee", "right_ee"]);
    let mut parents = vec![0];
    parents.extend(0..7);
    parents.push(0);
    parents.extend(8..14);
    assert_eq!(robot.parents(), parents.as_slice());
    assert!((robot.total_mass() - 672.0).abs() < 1e-9);
    // equal joint angles: right_ee is left_ee mirrored in the bus x-z plane
    let q: Vec<f64> = [0.3, -0.4, 0.5, 0.9, -0.2, 0.3, 0.7].repeat(2);
    let poses = algorithms::body_poses(&robot, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], &q).unwrap();
    let (left, right) = (poses[15], poses[16]);
    assert!((left[0] - right[0]).abs() < 1e-12 && (left[1] + right[1]).abs() < 1e-12);
    assert!((left[2] - right[2]).abs() < 1e-12);
}

fn dual_arm(damping: bool) -> FlexibleArm {
    let mut joints = FlexibleJoints::dual_arm();
    if !damping {
        joints.damping.fill(0.0);
        joints.motor_damping.fill(0.0);
    }
    FlexibleArm::new(Robot::dual_arm(), joints).unwrap()
}

fn moving(arm: &FlexibleArm) -> Vec<f64> {
    let mut rng = Rng::new(11);
    let q = rng.vector(14, -0.8, 0.8);
    let theta: Vec<f64> = q.iter().map(|v| v + rng.range(-0.01, 0.01)).collect();
    arm.state(&StateSpec {
        q: Some(&q),
        theta: Some(&theta),
        qd: Some(&rng.vector(14, -0.3, 0.3)),
        theta_dot: Some(&rng.vector(14, -0.3, 0.3)),
        base_pose: Some(&[1.0, -2.0, 0.5, 0.1, -0.2, 0.3, 0.9]),
        base_twist: Some(&rng.vector(6, -0.05, 0.05)),
    })
    .unwrap()
}

/// Free floating with torques on every joint: the momentum stays at its start value to
/// round-off; without damping or input the energy stays to RK4's error, falling like dt⁴.
#[test]
fn dual_arm_keeps_momentum_and_energy() {
    let arm = dual_arm(true);
    let x0 = moving(&arm);
    let torques: Vec<f64> = (0..14).map(|i| (i as f64 - 6.5) * 0.5).collect();
    // momentum in the inertial frame is not linear in the state: RK4 keeps it to its truncation
    // error, which falls like dt⁴ down to round-off
    let drift = |dt: f64| {
        let mut u = Schedule::Constant(torques.clone());
        let traj = arm
            .simulate(&x0, dt, (0.3 / dt) as usize, &mut u, &Wrenches::ZERO)
            .unwrap();
        let h = traj.rows().momentum(&arm);
        let scale = h[..6].iter().fold(1.0_f64, |m, v| m.max(v.abs()));
        (6..h.len()).fold(0.0_f64, |m, k| m.max((h[k] - h[k % 6]).abs())) / scale
    };
    let (coarse, fine, finest) = (drift(1e-3), drift(5e-4), drift(1.25e-4));
    assert!(coarse < 1e-8, "momentum drift {coarse:e}");
    assert!(
        coarse / fine > 12.0,
        "drift should fall like dt⁴: {coarse:e} -> {fine:e}"
    );
    assert!(finest < 1e-12, "round-off level at small dt: {finest:e}");
    let mut u = Schedule::Constant(torques.clone());
    let traj = arm
        .simulate(&x0, 1e-3, 300, &mut u, &Wrenches::ZERO)
        .unwrap();
    // each end-effector's pose is a row of the trajectory's EE poses
    let poses = traj.rows().ee_pose(&arm);
    assert_eq!(poses.len(), 301 * 2 * 7);
    let last = traj.rows().iter().last().unwrap();
    assert_eq!(&poses[300 * 14 + 7..], arm.ee_pose(last, 1));

    let arm = dual_arm(false);
    let mut ws = ArmWorkspace::new(&arm);
    let e0 = arm.energy(&mut ws, &x0);
    let energy_drift = |dt: f64| {
        let traj = arm
            .simulate(
                &x0,
                dt,
                (0.3 / dt) as usize,
                &mut Schedule::Zero,
                &Wrenches::ZERO,
            )
            .unwrap();
        traj.rows()
            .energy(&arm)
            .iter()
            .fold(0.0_f64, |m, e| m.max((e - e0).abs()))
    };
    let (coarse, fine) = (energy_drift(1e-3), energy_drift(5e-4));
    // the bound of the chain test (tests/simulation.rs); the ratio is the check that matters
    assert!(fine < 1e-6 * e0, "energy drift {fine:e} of {e0}");
    assert!(coarse / fine > 10.0, "drift ratio {}", coarse / fine);
}

/// `dE/dt` equals the power of the inputs: motor torques, base wrench and both EE wrenches
/// (`−f_eᵀ V_e`), less the damping.
#[test]
fn dual_arm_power_balance_with_both_wrenches() {
    let arm = dual_arm(true);
    let robot = arm.robot();
    let mut ws = ArmWorkspace::new(&arm);
    let mut rng = Rng::new(5);
    let x = moving(&arm);
    let l = arm.layout();
    let (u, fb, f) = (
        rng.vector(14, -5.0, 5.0),
        rng.vector(6, -5.0, 5.0),
        rng.vector(12, -5.0, 5.0),
    );
    let loads = Loads::from_slices(Some(&fb), Some(&f)).unwrap();
    let mut xdot = vec![0.0; x.len()];
    arm.derivative(
        &mut ws,
        &x,
        &Inputs {
            u: &u,
            loads,
            wheel_torque: &[],
        },
        &mut xdot,
    )
    .unwrap();
    let h = 1e-6;
    let shifted =
        |s: f64| -> Vec<f64> { x.iter().zip(&xdot).map(|(a, b)| a + s * h * b).collect() };
    let de = (arm.energy(&mut ws, &shifted(1.0)) - arm.energy(&mut ws, &shifted(-1.0))) / (2.0 * h);
    let (q, qd, td) = (&x[l.q()], &x[l.qd()], &x[l.theta_dot()]);
    let p = arm.joints();
    let mut power: f64 = (0..14)
        .map(|i| {
            u[i] * td[i]
                - p.damping[i] * (td[i] - qd[i]).powi(2)
                - p.motor_damping[i] * td[i] * td[i]
        })
        .sum();
    let v_b = Vector6::from_column_slice(&x[l.base_twist()]);
    power += fb.iter().zip(v_b.iter()).map(|(a, b)| a * b).sum::<f64>();
    for e in 0..2 {
        let j = robot.ee_jacobian(q, Some(e)).unwrap();
        let phi = robot.ee_base_operator(q, Some(e)).unwrap();
        let v_e =
            phi * v_b + Vector6::from_column_slice((j * DVector::from_column_slice(qd)).as_slice());
        power -= f[6 * e..6 * e + 6]
            .iter()
            .zip(v_e.iter())
            .map(|(a, b)| a * b)
            .sum::<f64>();
    }
    assert!(
        (de - power).abs() < 1e-6 * (1.0 + power.abs()),
        "dE/dt {de} vs power {power}"
    );
}

/// A run with a wrench schedule of width 12 (both end-effectors) and the operator method give
/// the recursive run's states.
#[test]
fn dual_arm_runs_with_both_wrenches_and_both_methods() {
    let arm = dual_arm(true);
    let x0 = moving(&arm);
    let wrenches = Wrenches {
        base: Schedule::Zero,
        ee: Schedule::Constant(vec![
            0.1, 0.0, -0.1, 1.0, 2.0, 0.0, 0.0, 0.2, 0.0, -1.0, 0.0, 3.0,
        ]),
        wheel_torque: orbitflex::Schedule::Zero,
    };
    let traj = arm
        .simulate(&x0, 1e-3, 50, &mut Schedule::Zero, &wrenches)
        .unwrap();
    let operator = arm.clone().with_method(Method::Operator);
    let reference = operator
        .simulate(&x0, 1e-3, 50, &mut Schedule::Zero, &wrenches)
        .unwrap();
    let last = traj.rows().iter().last().unwrap().to_vec();
    let want = reference.rows().iter().last().unwrap().to_vec();
    assert!(rel(&last, &want) < 1e-9);
    // a schedule of the single-EE width is refused, naming both end-effectors
    let narrow = Wrenches {
        base: Schedule::Zero,
        ee: Schedule::Constant(vec![0.0; 6]),
        wheel_torque: orbitflex::Schedule::Zero,
    };
    let err = arm
        .simulate(&x0, 1e-3, 5, &mut Schedule::Zero, &narrow)
        .unwrap_err()
        .error
        .to_string();
    assert!(err.contains("ee_wrench") && err.contains("12"), "{err}");
}

/// A workspace first used by a chain and then by a tree of the same size gives the tree's mass
/// matrix, zeros between branches included.
#[test]
fn crba_clears_entries_between_branches() {
    let tree = random_tree_all_leaves(SHAPES[1], 2);
    let chain = random_chain(tree.dof(), 2);
    let mut data = Data::new(&chain);
    let q = vec![0.4; tree.dof()];
    algorithms::crba(&chain, &mut data, &q).unwrap();
    let m = algorithms::crba(&tree, &mut data, &q).unwrap().clone();
    let reference = Operators::new(&tree, &RigidState::at_rest(&q, &vec![0.0; tree.dof()]))
        .unwrap()
        .mass_matrix();
    assert!(rel(m.as_slice(), reference.as_slice()) < 1e-12);
    // joints 1 (first arm) and 6 (second arm) are on different branches
    assert_eq!(m[(6, 11)], 0.0);
    assert_eq!(m[(11, 6)], 0.0);
}
