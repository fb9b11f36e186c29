//! Pinned values for the simulator's contract: the RK4 step, the EE pose, times, controllers,
//! joint parameters and every input check. These catch mutations that the invariant tests
//! (momentum, energy, order of convergence) let through.

use orbitflex::integrate::{self, Controller, MotorPD, Schedule, Wrenches};
use orbitflex::spatial::{Inertia, Mat3, Transform, Vec3};
use orbitflex::{FlexibleArm, FlexibleJoints, Inputs, Loads, Robot, RobotBuilder, StateSpec};

/// A bus with one link turning about z, 0.5 m out along x; the EE 0.3 m further out.
fn one_link() -> Robot {
    RobotBuilder::new(
        "one",
        "bus",
        Inertia::from_com(50.0, Vec3::zeros(), Mat3::identity() * 5.0),
    )
    .joint(
        "yaw",
        Transform::from_xyz_rpy([0.5, 0.0, 0.0], [0.0; 3]),
        Vec3::z(),
        "link",
        Inertia::from_com(2.0, Vec3::new(0.2, 0.0, 0.0), Mat3::identity() * 0.05),
    )
    .ee("tool", Transform::from_xyz_rpy([0.3, 0.0, 0.0], [0.0; 3]))
    .build()
    .unwrap()
}

fn one_link_arm() -> FlexibleArm {
    FlexibleArm::new(
        one_link(),
        FlexibleJoints::new(vec![300.0], vec![0.2], vec![0.5], vec![0.1]).unwrap(),
    )
    .unwrap()
}

fn moving(arm: &FlexibleArm) -> Vec<f64> {
    let half = 0.5f64.sqrt() * (0.3f64).sin();
    arm.state(&StateSpec {
        q: Some(&[0.4]),
        theta: Some(&[0.45]),
        qd: Some(&[0.3]),
        theta_dot: Some(&[-0.2]),
        base_pose: Some(&[0.1, 0.2, 0.3, half, 0.0, half, (0.3f64).cos()]),
        base_twist: Some(&[0.01, -0.02, 0.03, 0.1, 0.0, -0.05]),
    })
    .unwrap()
}

/// One step is exactly the classic RK4 combination of four derivatives, then the quaternion is
/// rescaled.
#[test]
fn step_is_the_classic_rk4_combination() {
    let arm = one_link_arm();
    let mut ws = arm.workspace();
    let x = moving(&arm);
    let (u, dt) = ([1.5], 0.01);
    let loads =
        Loads::from_slices(Some(&[0.1, 0.2, 0.3, 1.0, -1.0, 0.5]), Some(&[0.0; 6])).unwrap();
    let inputs = Inputs {
        u: &u,
        loads,
        wheel_torque: &[],
    };
    let f = |ws: &mut orbitflex::ArmWorkspace, x: &[f64]| {
        let mut d = vec![0.0; x.len()];
        arm.derivative(ws, x, &inputs, &mut d).unwrap();
        d
    };
    let add = |x: &[f64], h: f64, k: &[f64]| -> Vec<f64> {
        x.iter().zip(k).map(|(a, b)| a + h * b).collect()
    };
    let k1 = f(&mut ws, &x);
    let k2 = f(&mut ws, &add(&x, 0.5 * dt, &k1));
    let k3 = f(&mut ws, &add(&x, 0.5 * dt, &k2));
    let k4 = f(&mut ws, &add(&x, dt, &k3));
    let mut want: Vec<f64> = (0..x.len())
        .map(|i| x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
        .collect();
    orbitflex::flex::normalise_quaternion(&mut want[3..7]);
    let mut got = x.clone();
    arm.step(&mut ws, &mut got, dt, &inputs).unwrap();
    assert_eq!(got, want);
    // and simulate takes the same step
    let traj = arm
        .simulate(
            &x,
            dt,
            1,
            &mut Schedule::Constant(u.to_vec()),
            &Wrenches {
                base: Schedule::Constant(vec![0.1, 0.2, 0.3, 1.0, -1.0, 0.5]),
                ee: Schedule::Zero,
                wheel_torque: orbitflex::Schedule::Zero,
            },
        )
        .unwrap();
    assert_eq!(traj.state(1), want.as_slice());
    assert_eq!(traj.u, u.to_vec());
}

/// The EE pose by hand: the base at r turned 90° about z, the joint at 45°.
#[test]
fn ee_pose_by_hand() {
    let arm = one_link_arm();
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let x = arm
        .state(&StateSpec {
            q: Some(&[std::f64::consts::FRAC_PI_4]),
            base_pose: Some(&[1.0, 2.0, 3.0, 0.0, 0.0, s, s]),
            ..StateSpec::default()
        })
        .unwrap();
    let pose = arm.ee_pose(&x, 0);
    // r + Rz(90°) (0.5 e_x + Rz(45°) 0.3 e_x)
    let c = 0.3 * s;
    let want_position = [1.0 - c, 2.0 + 0.5 + c, 3.0];
    for (g, w) in pose[..3].iter().zip(want_position) {
        assert!((g - w).abs() < 1e-15, "{pose:?}");
    }
    let half = 135f64.to_radians() / 2.0;
    let want_quat = [0.0, 0.0, half.sin(), half.cos()];
    for (g, w) in pose[3..].iter().zip(want_quat) {
        assert!((g - w).abs() < 1e-15, "{pose:?}");
    }
    // the scalar part is kept non-negative: a base turned by −90° about −z is the same
    let mut flipped = x.clone();
    flipped[3..7].iter_mut().for_each(|v| *v = -*v);
    assert_eq!(arm.ee_pose(&flipped, 0), pose);
    // along rows of states
    let rows: Vec<f64> = [x.clone(), moving(&arm)].concat();
    let along = orbitflex::integrate::StateRows {
        layout: arm.layout(),
        x: &rows,
    }
    .ee_pose(&arm);
    assert_eq!(&along[..7], &pose);
    assert_eq!(&along[7..], &arm.ee_pose(&moving(&arm), 0));
}

/// Times are `k dt` exactly, and a controller is asked at `t = k dt` with the state of step k.
#[test]
fn times_and_controller_calls() {
    struct Recorder(Vec<(usize, f64, f64)>);
    impl Controller for Recorder {
        fn output(
            &mut self,
            step: usize,
            t: f64,
            x: &[f64],
            u: &mut [f64],
        ) -> orbitflex::Result<()> {
            self.0.push((step, t, x[7]));
            u[0] = 0.25 * step as f64;
            Ok(())
        }
    }
    let arm = one_link_arm();
    let dt = 0.003;
    let mut recorder = Recorder(Vec::new());
    let traj = arm
        .simulate(&moving(&arm), dt, 4, &mut recorder, &Wrenches::ZERO)
        .unwrap();
    assert_eq!(traj.t, vec![0.0, dt, 2.0 * dt, 3.0 * dt, 4.0 * dt]);
    for (k, (step, t, q)) in recorder.0.iter().enumerate() {
        assert_eq!((*step, *t, *q), (k, k as f64 * dt, traj.state(k)[7]));
    }
    assert_eq!(traj.u, vec![0.0, 0.25, 0.5, 0.75]);
}

/// `u = kp (θ_ref − θ) + kd (θ̇_ref − θ̇) + u_ff`, with tabulated references and feedforward.
#[test]
fn motor_pd_with_feedforward_by_value() {
    let arm = one_link_arm();
    let mut pd = MotorPD::new(
        vec![40.0],
        vec![3.0],
        Schedule::Table {
            values: vec![0.1, 0.2, 0.3],
            width: 1,
        },
        Schedule::Table {
            values: vec![1.0, -1.0, 0.5],
            width: 1,
        },
        Schedule::Table {
            values: vec![0.7, 0.0, -0.7],
            width: 1,
        },
    )
    .unwrap();
    let traj = arm
        .simulate(&moving(&arm), 1e-3, 3, &mut pd, &Wrenches::ZERO)
        .unwrap();
    let layout = arm.layout();
    for k in 0..3 {
        let s = layout.split(traj.state(k));
        let reference = [0.1, 0.2, 0.3][k];
        let rate = [1.0, -1.0, 0.5][k];
        let ff = [0.7, 0.0, -0.7][k];
        let want = 40.0 * (reference - s.theta[0]) + 3.0 * (rate - s.theta_dot[0]) + ff;
        assert_eq!(traj.u[k], want);
    }
    // a table shorter than the run is refused before the first step
    let failure = arm
        .simulate(&moving(&arm), 1e-3, 4, &mut pd, &Wrenches::ZERO)
        .unwrap_err();
    assert_eq!(
        failure.error.to_string(),
        "theta_ref: expected at least 4 rows (one per step), given 3 rows"
    );
    assert!(failure.trajectory.is_empty());
}

#[test]
fn gear_data_reflects_the_rotor_inertia() {
    let joints = FlexibleJoints::from_gear(
        vec![1e4, 2e4],
        &[100.0, 160.0],
        &[2e-5, 4e-5],
        vec![0.0; 2],
        vec![1.0; 2],
    )
    .unwrap();
    assert_eq!(
        joints.motor_inertia,
        vec![100.0 * 100.0 * 2e-5, 160.0 * 160.0 * 4e-5]
    );
    let builtin = FlexibleJoints::space_arm();
    assert_eq!(builtin.stiffness, vec![1e4, 1e4, 1e4, 5e3, 2e3, 2e3, 2e3]);
    assert_eq!(builtin.motor_inertia[0], 160.0 * 160.0 * 4e-5);
    assert_eq!(builtin.motor_inertia[6], 160.0 * 160.0 * 1.5e-5);
    assert_eq!((builtin.damping[3], builtin.motor_damping[3]), (0.2, 1.0));
    for (g, r, word) in [
        (0.0, 1e-5, "gear_ratio"),
        (-160.0, 1e-5, "gear_ratio"),
        (f64::NAN, 1e-5, "gear_ratio"),
        (160.0, 0.0, "rotor_inertia"),
        (1e200, 1e-5, "not a finite positive number"),
    ] {
        let e = FlexibleJoints::from_gear(vec![1.0], &[g], &[r], vec![0.0], vec![0.0]).unwrap_err();
        assert!(e.to_string().contains(word), "{g} {r}: {e}");
    }
}

/// The closed-loop stability limit of the built-in arm, pinned: open loop at rest, and with the
/// README's PD (the held derivative gain sets it).
#[test]
fn stability_limits_pinned() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let x = arm.rest_state();
    let open = arm.rk4_stability_limit(&x, &Schedule::Zero).unwrap();
    assert!((open.dt - 1.05527e-2).abs() < 2e-3 * 1.05527e-2, "{open:?}");
    let pd = MotorPD::new(
        vec![2000.0; 7],
        vec![800.0; 7],
        Schedule::Zero,
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let closed = arm.rk4_stability_limit(&x, &pd).unwrap();
    assert!((closed.dt - 9.596e-4).abs() < 2e-3 * 9.596e-4, "{closed:?}");
    // a controller whose feedback is unknown is analysed open loop, and says so
    struct Opaque;
    impl Controller for Opaque {
        fn output(&mut self, _: usize, _: f64, _: &[f64], _: &mut [f64]) -> orbitflex::Result<()> {
            Ok(())
        }
    }
    // a soft PD barely changes it (and its closed loop, with exact zero eigenvalues from the
    // free base, is solved: the eigenvalue iteration once cycled on it)
    let soft = MotorPD::new(
        vec![50.0; 7],
        vec![5.0; 7],
        Schedule::Zero,
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let soft = arm.rk4_stability_limit(&x, &soft).unwrap();
    assert!((soft.dt - 1.05495e-2).abs() < 2e-3 * 1.05495e-2, "{soft:?}");
    let unknown = arm.rk4_stability_limit(&x, &Opaque).unwrap();
    assert!(unknown.open_loop && !open.open_loop);
    assert_eq!(unknown.dt, open.dt);
}

/// Very stiff joints (k/j = 1e11 s⁻²) have a finite limit that scales as 1/√k: the scan once
/// gave up at a million times the largest entry of the Jacobian (k/j, not √(k/j)) and reported
/// no limit, so a run that diverged at once was not warned about.
#[test]
fn stiff_joints_have_a_finite_limit() {
    let limit = |k: f64| {
        let arm = FlexibleArm::new(
            Robot::space_arm(),
            FlexibleJoints::uniform(7, k, 1e-3, 0.0, 0.0).unwrap(),
        )
        .unwrap();
        arm.rk4_stability_limit(&arm.rest_state(), &Schedule::Zero)
            .unwrap()
            .dt
    };
    let (soft, stiff) = (limit(1e6), limit(1e8));
    assert!(stiff.is_finite(), "{stiff}");
    assert!((soft / stiff - 10.0).abs() < 0.05, "{soft} / {stiff}");
}

#[test]
fn input_checks_say_what_is_wrong() {
    let check = |r: orbitflex::Result<()>, want: &str| {
        assert_eq!(r.unwrap_err().to_string(), want);
    };
    let table = Schedule::Table {
        values: vec![0.0; 6],
        width: 2,
    };
    check(
        table.check("u", 3, None),
        "u: expected a table of shape (steps, 3), given shape (3, 2)",
    );
    check(
        table.check("u", 2, Some(4)),
        "u: expected a table of shape (4, 2), given shape (3, 2)",
    );
    assert!(table.check("u", 2, Some(3)).is_ok());
    check(
        Schedule::Constant(vec![1.0, f64::NAN]).check("base_wrench", 2, None),
        "base_wrench: element 1 is not finite (NaN)",
    );
    check(
        Schedule::Table {
            values: vec![0.0, f64::INFINITY],
            width: 1,
        }
        .check("ee_wrench", 1, Some(2)),
        "ee_wrench: element 1 is not finite (inf)",
    );
    check(
        table.check_covers("theta_ref", 4),
        "theta_ref: expected at least 4 rows (one per step), given 3 rows",
    );
    assert!(table.check_covers("theta_ref", 3).is_ok());
    for (dt, shown) in [
        (0.0, "0"),
        (-1.0, "-1"),
        (f64::NAN, "NaN"),
        (f64::INFINITY, "inf"),
    ] {
        check(
            orbitflex::args::check_dt(dt),
            &format!("dt: expected a finite step > 0 s, given {shown}"),
        );
    }
    assert!(orbitflex::args::check_dt(1e-9).is_ok());
    check(
        FlexibleJoints::new(vec![1.0, 0.0], vec![1.0; 2], vec![0.0; 2], vec![0.0; 2]).map(|_| ()),
        "stiffness[1]: expected > 0, given 0",
    );
    check(
        FlexibleJoints::new(vec![1.0], vec![1.0], vec![-0.5], vec![0.0]).map(|_| ()),
        "damping[0]: expected >= 0, given -0.5",
    );
    assert!(FlexibleJoints::new(vec![1.0], vec![1.0], vec![0.0], vec![0.0]).is_ok());
    check(
        MotorPD::new(
            vec![1.0],
            vec![-1.0],
            Schedule::Zero,
            Schedule::Zero,
            Schedule::Zero,
        )
        .map(|_| ()),
        "kd[0]: expected >= 0, given -1",
    );
    let names = ["a"];
    for (text, word) in [
        (
            "[defaults]\nstiffness = 1.0\ngear_ratio = -5.0\nrotor_inertia = 1e-5\n",
            "gear_ratio",
        ),
        (
            "[defaults]\nstiffness = nan\nmotor_inertia = 1.0\n",
            "stiffness must be a finite number > 0, given NaN",
        ),
        (
            "[defaults]\nstiffness = 1.0\nmotor_inertia = 1.0\ndamping = -1.0\n",
            "damping must be a finite number >= 0, given -1",
        ),
    ] {
        let e = FlexibleJoints::from_toml_str(text, &names, "t.toml").unwrap_err();
        assert!(
            e.to_string().contains(word) && e.to_string().starts_with("t.toml"),
            "{e}"
        );
    }
    // a run checks its arguments before its first step
    let arm = one_link_arm();
    let x = moving(&arm);
    let run = |dt: f64, wrenches: &Wrenches| {
        let mut u = Schedule::Zero;
        integrate::Run::new(&x, dt, 5)
            .check(&arm, &integrate::Drive::new(&mut u, &mut wrenches.clone()))
    };
    check(
        run(0.0, &Wrenches::ZERO),
        "dt: expected a finite step > 0 s, given 0",
    );
    check(
        run(
            1e-3,
            &Wrenches {
                base: Schedule::Constant(vec![0.0; 5]),
                ee: Schedule::Zero,
                wheel_torque: orbitflex::Schedule::Zero,
            },
        ),
        "base_wrench: expected length 6, given length 5",
    );
    check(
        integrate::Run::new(&x[..5], 1e-3, 5).check(
            &arm,
            &integrate::Drive::new(&mut Schedule::Zero, &mut Wrenches::default()),
        ),
        "x0: expected length 17, given length 5",
    );
}

/// A fuzzer's model: a base of 4e-320 kg (a subnormal mass) loaded, and its forward dynamics
/// overflowed to infinity. Positive masses below `MIN_MASS` are refused with a clear message.
#[test]
fn a_subnormal_mass_is_refused_where_the_model_loads() {
    let xml = r#"<?xml version="1.0"?>
<robot name="fuzz">
<link name="l0"><inertial><origin xyz="-7.5625 2.75 2.75" rpy="0 0 0"/><mass value="4e-320"/><inertia ixx="11297e33" iyy="11297e33" izz="4e-320" ixy="33e0" ixz="0" iyz="0"/></inertial></link>
</robot>"#;
    let error = orbitflex::Robot::from_urdf_string(xml, &orbitflex::UrdfOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("l0") && error.contains("smaller than the 1e-30 kg supported"),
        "{error}"
    );
}

/// The recursive algorithms' argument checks: lengths and finiteness, with the name, the index
/// and the value in the message (the fast path that lets good arguments through must not let a
/// bad one through).
#[test]
fn dynamics_argument_checks_name_the_bad_element() {
    use orbitflex::algorithms::{self, Data};
    use orbitflex::spatial::Force;
    use orbitflex::RigidState;
    let robot = one_link();
    let mut data = Data::new(&robot);
    let twist = [0.0; 6];
    let good = RigidState::new(&[0.1], &twist, &[0.2]);
    let mut aba = |state: &RigidState, tau: &[f64], loads: &Loads| {
        algorithms::aba(&robot, &mut data, state, tau, loads)
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    let mut wrench = [0.0; 6];
    wrench[4] = f64::INFINITY;
    let base = Loads {
        base_wrench: Force::from_slice(&wrench),
        ee_wrench: &[],
    };
    let ee = Loads {
        base_wrench: Force::ZERO,
        ee_wrench: &wrench,
    };
    assert_eq!(
        aba(&good, &[1.0], &base),
        Err("base_wrench: element 4 is not finite (inf)".into())
    );
    assert_eq!(
        aba(&good, &[1.0], &ee),
        Err("ee_wrench: element 4 is not finite (inf)".into())
    );
    assert_eq!(
        aba(&good, &[f64::NAN], &Loads::ZERO),
        Err("tau: element 0 is not finite (NaN)".into())
    );
    let bad = RigidState::new(&[0.1], &twist, &[f64::NEG_INFINITY]);
    assert_eq!(
        aba(&bad, &[1.0], &Loads::ZERO),
        Err("qd: element 0 is not finite (-inf)".into())
    );
    let long = aba(&good, &[1.0, 2.0], &Loads::ZERO).unwrap_err();
    assert!(
        long.starts_with("tau") && long.contains("length 1") && long.contains("length 2"),
        "{long}"
    );
    assert_eq!(aba(&good, &[1.0], &Loads::ZERO), Ok(()));
}

/// A payload joins the body that carries the EE frame, wherever it sits in the tree (not the
/// last body), moved there through the EE frame's placement.
#[test]
fn a_payload_joins_the_ee_body() {
    use orbitflex::testing::{random_tree, TREE_THREE_ARMS};
    let robot = random_tree(TREE_THREE_ARMS, 5);
    assert_eq!(robot.ee_body(), 5);
    let payload = Inertia::from_com(20.0, Vec3::new(0.0, 0.0, 0.1), Mat3::identity() * 0.3);
    let loaded = robot.with_payload(payload).unwrap();
    let moved = payload.transformed_to_parent(robot.ee_transform());
    for (i, (before, after)) in robot.inertias().iter().zip(loaded.inertias()).enumerate() {
        if i == 5 {
            let expected = before.add(&moved);
            assert!((after.mass - expected.mass).abs() < 1e-12);
            assert!((after.com - expected.com).norm() < 1e-12);
            assert!((after.rotational - expected.rotational).norm() < 1e-12);
        } else {
            assert_eq!(after, before, "body {i}");
        }
    }
    // with several end-effectors, which one holds the payload is ambiguous
    let several = orbitflex::testing::random_tree_all_leaves(TREE_THREE_ARMS.0, 5);
    let err = several.with_payload(payload).unwrap_err().to_string();
    assert!(
        err.contains("5 end-effectors") && err.contains("'ee3'"),
        "{err}"
    );
}

#[test]
fn models_and_plans_may_be_shared_between_threads() {
    // docs/threads_and_interrupts.md: Robot, FlexibleArm and Plan are Send + Sync; a Data or an
    // ArmWorkspace moves between threads (Send) and is used by one at a time (&mut)
    fn shared<T: Send + Sync>() {}
    fn sent<T: Send>() {}
    shared::<orbitflex::Robot>();
    shared::<orbitflex::FlexibleArm>();
    shared::<orbitflex::Plan>();
    shared::<orbitflex::Trajectory>();
    sent::<orbitflex::Data>();
    sent::<orbitflex::ArmWorkspace>();
}

#[test]
fn singular_joints_are_refused_relative_to_their_own_links() {
    let bus = |m: f64| Inertia::from_com(m, Vec3::zeros(), Mat3::identity() * m);
    let at = |x: f64| Transform::from_xyz_rpy([x, 0.0, 0.0], [0.0; 3]);
    let build = |base: Inertia, links: &[(Transform, Inertia)]| {
        let mut b = RobotBuilder::new("r", "bus", base);
        for (k, (origin, inertia)) in links.iter().enumerate() {
            b = b.joint(
                &format!("j{k}"),
                *origin,
                Vec3::z(),
                &format!("l{k}"),
                *inertia,
            );
        }
        b.build()
    };
    let link = Inertia::from_com(2.0, Vec3::new(0.3, 0.0, 0.0), Mat3::identity() * 0.01);
    let refused = |r: orbitflex::Result<Robot>, joint: &str| match r {
        Err(e) => assert!(
            e.to_string().contains(&format!(
                "joint '{joint}' moves links with no inertia about its axis"
            )),
            "{e}"
        ),
        Ok(_) => panic!("joint '{joint}' accepted"),
    };
    // (issue 24) a heavy bus does not make a light link singular
    assert!(build(bus(1e10), &[(at(0.5), link)]).is_ok());
    // a massless link is singular, whatever the bus
    refused(build(bus(500.0), &[(at(0.5), Inertia::zero())]), "j0");
    // a needle along the joint axis: 1e-8 kg·m² about it against 2e6 across, a pivot at
    // round-off level relative to the joint's own links
    let needle = Inertia::from_com(
        1.0,
        Vec3::new(0.0, 0.0, 1e3),
        Mat3::from_diagonal(&Vec3::new(1.0, 1.0, 1e-8)),
    );
    refused(build(bus(500.0), &[(at(0.5), needle)]), "j0");
    // two joints on one axis with a massless link between: the second takes all the inertia
    // about the axis, and the first has none left (the reduced inertia shows it)
    refused(
        build(bus(500.0), &[(at(0.5), Inertia::zero()), (at(0.0), link)]),
        "j0",
    );
}
