//! Reaction wheels on the bus (docs/model.md, "Reaction wheels"): the closed-form wheel dynamics
//! against the same robot with each wheel a URDF link on a continuous joint (our own verified
//! articulated-body algorithm on `ReactionWheels::to_urdf`; the Python suite checks the same
//! against Pinocchio), the conserved quantities, the power balance, the limits, batch runs and
//! bad input.

use orbitflex::algorithms::{self, Data};
use orbitflex::control::{AttitudePD, AttitudeTarget, Controller, MotorPD, Sampled};
use orbitflex::flex::{saturated_torque, ReactionWheels, Wheel};
use orbitflex::integrate::batch::{
    simulate_batch, Batch, BatchControl, BatchInput, BatchSettings, BatchWatch, PerRun, SampleClock,
};
use orbitflex::integrate::{Drive, Run, Unobserved};
use orbitflex::spatial::Vec3;
use orbitflex::testing::{random_chain, random_joints, random_tree_all_leaves, Rng};
use orbitflex::{
    FlexibleArm, FlexibleJoints, Inputs, Loads, RigidState, Robot, Schedule, StateSpec,
    UrdfOptions, Wrenches,
};

/// `k` random wheels ([`orbitflex::testing::random_wheels`]), torque limit 1.0 N·m.
fn random_wheels(k: usize, seed: u64) -> ReactionWheels {
    orbitflex::testing::random_wheels(k, seed, 1.0)
}

/// Four wheels in a pyramid (axes 54.7° from the base z axis), as on many spacecraft.
fn pyramid() -> ReactionWheels {
    let tilt = (1.0f64 / 3.0).sqrt();
    let side = (2.0f64 / 3.0).sqrt();
    let wheels = (0..4)
        .map(|w| {
            let phi = std::f64::consts::FRAC_PI_2 * w as f64 + 0.3;
            Wheel {
                axis: [side * phi.cos(), side * phi.sin(), tilt],
                position: [0.3 * phi.cos(), 0.3 * phi.sin(), -0.4],
                mass: 4.0,
                spin_inertia: 0.04,
                transverse_inertia: 0.025,
                max_torque: 0.2,
                max_speed: 600.0,
                friction: 0.0,
            }
        })
        .collect();
    ReactionWheels::new(wheels).unwrap()
}

/// A random state of `arm` with rates in ±1 and wheel speeds up to ±`speed` rad/s.
fn random_state(arm: &FlexibleArm, seed: u64, speed: f64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let n = arm.dof();
    let layout = arm.layout();
    let quat = rng.vector(4, -1.0, 1.0);
    let pose = [&rng.vector(3, -1.0, 1.0)[..], &quat].concat();
    let mut x = arm
        .state(&StateSpec {
            q: Some(&rng.vector(n, -3.0, 3.0)),
            theta: Some(&rng.vector(n, -3.0, 3.0)),
            qd: Some(&rng.vector(n, -1.0, 1.0)),
            theta_dot: Some(&rng.vector(n, -1.0, 1.0)),
            base_pose: Some(&pose),
            base_twist: Some(&rng.vector(6, -1.0, 1.0)),
        })
        .unwrap();
    x[layout.wheel_speed()].copy_from_slice(&rng.vector(layout.wheels, -speed, speed));
    x
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |m, x| m.max(x.abs()))
}

/// The robots of the equivalence test: random chains and trees, the built-in arms.
fn robots() -> Vec<(String, Robot)> {
    let mut out = vec![
        ("space_arm".to_string(), Robot::space_arm()),
        ("dual_arm".to_string(), Robot::dual_arm()),
    ];
    for seed in 0..3 {
        out.push((format!("chain {seed}"), random_chain(6, seed)));
        out.push((
            format!("tree {seed}"),
            random_tree_all_leaves(&[0, 0, 1, 2, 1, 4, 0], seed),
        ));
    }
    out
}

/// `derivative` with wheels equals the articulated-body algorithm on the robot of
/// `wheels.to_urdf(robot)`, where each wheel is a link on a continuous joint of the root (joint
/// rate `Ω`, joint torque `u − c Ω`, the wheel angle arbitrary), at random states, spring
/// torques, motor and wheel torques and base and EE wrenches.
///
/// Bounds. The kinematic and motor blocks (`ṙ, quat', q̇, θ̇, θ̈`) do not depend on the wheels'
/// treatment at all: they must agree to round-off, 1e-12 relative. The accelerations differ by
/// the order of the floating-point operations: the URDF form carries each wheel's gyroscopic
/// terms `J_s Ω ω` (up to 0.1 · 600 · 1 = 60 N·m here) through its body's bias force and the
/// base's articulated inertia, where they cancel against `ω × h` only to round-off, ε · 60 ≈
/// 1e-14 N·m, amplified by at most the inverse of the smallest articulated inertia (≈ 1e-2
/// kg·m² for the wheels' `J_s`): ≈ 1e-12 rad/s² against accelerations of order 1–1e3. A
/// relative bound of 1e-10 on the accelerations is the issue's, and leaves two orders of margin.
#[test]
fn derivative_equals_the_wheels_as_urdf_links() {
    let mut worst = (0.0f64, 0.0f64);
    for (name, robot) in robots() {
        for seed in 0..3u64 {
            let n = robot.dof();
            let k = 1 + (seed as usize) * 2;
            let wheels = random_wheels(k, seed + 17);
            let xml = wheels.to_urdf(&robot).unwrap();
            let options = UrdfOptions {
                ee_links: robot.ee_links().iter().map(|s| s.to_string()).collect(),
                ..UrdfOptions::default()
            };
            let rigid = Robot::from_urdf_string(&xml, &options).unwrap();
            assert_eq!(rigid.dof(), n + k, "{name}");
            let arm = FlexibleArm::new(robot.clone(), random_joints(n, seed))
                .unwrap()
                .with_wheels(wheels.clone())
                .unwrap();
            let layout = arm.layout();
            let x = random_state(&arm, seed + 5, 600.0);
            let mut rng = Rng::new(seed + 99);
            let u = rng.vector(n, -5.0, 5.0);
            let u_w = rng.vector(k, -0.9, 0.9);
            let fb = rng.vector(6, -5.0, 5.0);
            let fe = rng.vector(6 * robot.end_effectors().len(), -2.0, 2.0);
            let loads = Loads::from_slices(Some(&fb), Some(&fe)).unwrap();
            let mut ws = arm.workspace();
            let mut xdot = vec![0.0; layout.len()];
            arm.derivative(
                &mut ws,
                &x,
                &Inputs {
                    u: &u,
                    loads,
                    wheel_torque: &u_w,
                },
                &mut xdot,
            )
            .unwrap();

            // the same system, rigid, with the wheels as joints (matched by name)
            let names = rigid.joint_names();
            let index = |joint: &str| names.iter().position(|&j| j == joint).unwrap();
            let s = layout.split(&x);
            let mut tau_spring = vec![0.0; n];
            arm.spring_torque(&x, &mut tau_spring);
            let (mut q, mut qd, mut tau) = (vec![0.0; n + k], vec![0.0; n + k], vec![0.0; n + k]);
            for (i, joint) in robot.joint_names().iter().enumerate() {
                let j = index(joint);
                (q[j], qd[j], tau[j]) = (s.q[i], s.qd[i], tau_spring[i]);
            }
            for (w, wheel) in wheels.wheels().iter().enumerate() {
                let j = index(&ReactionWheels::urdf_names(w).1);
                let speed = s.wheel_speed[w];
                (q[j], qd[j], tau[j]) =
                    (rng.range(-3.0, 3.0), speed, u_w[w] - wheel.friction * speed);
            }
            let mut data = Data::new(&rigid);
            let acc = algorithms::aba(
                &rigid,
                &mut data,
                &RigidState::new(&q, s.base_twist, &qd),
                &tau,
                &loads,
            )
            .unwrap()
            .as_slice()
            .to_vec();

            // ours, in the same terms: α_B = [ω̇; v̇ + ω × v], q̈, Ω̇
            let (omega, v) = (s.omega(), s.velocity());
            let twist_rate = &xdot[layout.base_twist()];
            let v_dot = Vec3::new(twist_rate[3], twist_rate[4], twist_rate[5]) + omega.cross(&v);
            let mut ours = vec![0.0; 6 + n + k];
            ours[..3].copy_from_slice(&twist_rate[..3]);
            ours[3..6].copy_from_slice(v_dot.as_slice());
            for (i, joint) in robot.joint_names().iter().enumerate() {
                ours[6 + index(joint)] = xdot[layout.qd()][i];
            }
            for w in 0..k {
                ours[6 + index(&ReactionWheels::urdf_names(w).1)] = xdot[layout.wheel_speed()][w];
            }
            let scale = max_abs(&acc).max(1.0);
            let err: f64 = ours
                .iter()
                .zip(&acc)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()))
                / scale;
            assert!(
                err < 1e-10,
                "{name}, seed {seed}: accelerations differ by {err:e}"
            );

            // the kinematic and motor blocks: from the same formulas as without wheels
            let plain = FlexibleArm::new(robot.clone(), random_joints(n, seed)).unwrap();
            let mut plain_dot = vec![0.0; plain.layout().len()];
            let x_plain = &x[..plain.layout().len()];
            plain
                .derivative(
                    &mut plain.workspace(),
                    x_plain,
                    &Inputs::torques(&u),
                    &mut plain_dot,
                )
                .unwrap();
            for range in [
                layout.base_pose(),
                layout.q(),
                layout.theta(),
                layout.theta_dot(),
            ] {
                let e = max_abs(
                    &xdot[range.clone()]
                        .iter()
                        .zip(&plain_dot[range.clone()])
                        .map(|(a, b)| a - b)
                        .collect::<Vec<_>>(),
                ) / max_abs(&plain_dot[range.clone()]).max(1.0);
                assert!(e < 1e-12, "{name}: block {range:?} differs by {e:e}");
            }
            worst = (worst.0.max(err), worst.1.max(scale));
        }
    }
    eprintln!(
        "worst relative acceleration error {:e} (scale up to {:e})",
        worst.0, worst.1
    );
}

/// Without wheels nothing changes: the state, its slices and the derivative are those of the
/// arm alone; with wheels the arm's blocks keep their places and the speeds come last.
#[test]
fn the_layout_appends_the_wheel_speeds() {
    let robot = Robot::space_arm();
    let arm = FlexibleArm::new(robot.clone(), FlexibleJoints::space_arm()).unwrap();
    assert_eq!(arm.layout().len(), 41);
    assert!(arm.layout().wheel_speed().is_empty());
    let wheeled = arm.clone().with_wheels(pyramid()).unwrap();
    let layout = wheeled.layout();
    assert_eq!(layout.len(), 45);
    assert_eq!(layout.wheel_speed(), 41..45);
    assert_eq!(layout.theta_dot(), arm.layout().theta_dot());
    assert_eq!(layout.tangent_len(), 44);
    assert_eq!(
        layout.element_names(&robot.joint_names())[41..],
        [
            "wheel_speed[0]",
            "wheel_speed[1]",
            "wheel_speed[2]",
            "wheel_speed[3]"
        ]
    );
    // the user's robot is kept; the dynamics run on the bus with the wheels' mass added
    assert_eq!(wheeled.robot(), &robot);
    let added = wheeled.rigid_model().inertias()[0].mass - robot.inertias()[0].mass;
    assert!((added - 16.0).abs() < 1e-12, "{added}");
    assert_eq!(wheeled.rest_state()[41..], [0.0; 4]);
}

/// Total momentum of bus, arm and wheels (locked and spin parts) without external wrench, with
/// the wheels spinning fast, motor and wheel torques and wheel friction: constant up to RK4's
/// truncation error, which falls as dt⁴ (ratio ≈ 16 per halving; > 10 required).
#[test]
fn momentum_is_conserved_and_its_drift_falls_as_dt4() {
    let robot = random_chain(5, 3);
    let wheels = random_wheels(4, 8);
    let arm = FlexibleArm::new(robot, random_joints(5, 3))
        .unwrap()
        .with_wheels(wheels)
        .unwrap();
    let x0 = random_state(&arm, 4, 300.0);
    let mut ws = arm.workspace();
    let h0 = arm.momentum(&mut ws, &x0);
    // the spin part is there: a wheel spinning at 300 rad/s carries several N·m·s
    assert!(max_abs(&h0[..3]) > 1.0, "{h0:?}");
    let drift = |dt: f64| {
        let steps = (0.4 / dt).round() as usize;
        let wrenches = Wrenches {
            wheel_torque: Schedule::Constant(vec![0.5, -0.7, 0.3, -0.2]),
            ..Wrenches::ZERO
        };
        let traj = arm
            .simulate(
                &x0,
                dt,
                steps,
                &mut Schedule::Constant(vec![2.0; 5]),
                &wrenches,
            )
            .unwrap();
        let h = traj.rows().momentum(&arm);
        h.chunks(6)
            .flat_map(|row| row.iter().zip(&h0).map(|(a, b)| (a - b).abs()))
            .fold(0.0f64, f64::max)
    };
    let (coarse, fine) = (drift(2e-3), drift(1e-3));
    let size = h0.iter().map(|v| v * v).sum::<f64>().sqrt();
    eprintln!(
        "momentum {size:e}, drift {coarse:e} (dt 2 ms), {fine:e} (1 ms): ratio {}",
        coarse / fine
    );
    // the random joints ring at up to √(800 (1/0.1 + 1/m)) ≈ 100 rad/s: h ω ≈ 0.2 at 2 ms
    assert!(coarse < 1e-4 * size, "{coarse:e} of {size:e}");
    assert!(coarse / fine > 10.0, "drift {coarse:e} -> {fine:e}");
}

/// The power balance of the wheel equations at random states: `dE/dt` (central difference of
/// the energy along `ẋ`) equals `u·θ̇ − Σ d (θ̇ − q̇)² − Σ β θ̇² + Σ (u_w − c Ω) Ω + f_B·V_B`.
/// The difference quotient with h = 1e-6 s is exact to O(h²) ≈ 1e-12 relative to the energy's
/// second derivative; we ask 1e-6 relative to the largest power term.
#[test]
fn energy_changes_at_the_rate_of_the_work_done() {
    for seed in 0..4u64 {
        let robot = random_chain(4, seed);
        let wheels = random_wheels(3, seed);
        let joints = random_joints(4, seed + 1);
        let arm = FlexibleArm::new(robot, joints.clone())
            .unwrap()
            .with_wheels(wheels.clone())
            .unwrap();
        let layout = arm.layout();
        let x = random_state(&arm, seed, 200.0);
        let mut rng = Rng::new(seed);
        let (u, u_w, fb) = (
            rng.vector(4, -3.0, 3.0),
            rng.vector(3, -0.5, 0.5),
            rng.vector(6, -3.0, 3.0),
        );
        let inputs = Inputs {
            u: &u,
            loads: Loads::from_slices(Some(&fb), None).unwrap(),
            wheel_torque: &u_w,
        };
        let mut ws = arm.workspace();
        let mut xdot = vec![0.0; layout.len()];
        arm.derivative(&mut ws, &x, &inputs, &mut xdot).unwrap();
        let h = 1e-6;
        let at = |sign: f64, ws: &mut orbitflex::ArmWorkspace| {
            let y: Vec<f64> = x.iter().zip(&xdot).map(|(a, b)| a + sign * h * b).collect();
            arm.energy(ws, &y)
        };
        let rate = (at(1.0, &mut ws) - at(-1.0, &mut ws)) / (2.0 * h);
        let s = layout.split(&x);
        let mut terms = vec![];
        for (i, u) in u.iter().enumerate() {
            terms.push(u * s.theta_dot[i]);
            terms.push(-joints.damping[i] * (s.theta_dot[i] - s.qd[i]).powi(2));
            terms.push(-joints.motor_damping[i] * s.theta_dot[i].powi(2));
        }
        for (w, wheel) in wheels.wheels().iter().enumerate() {
            let speed = s.wheel_speed[w];
            terms.push((u_w[w] - wheel.friction * speed) * speed);
        }
        terms.extend(fb.iter().zip(s.base_twist).map(|(f, v)| f * v));
        let power: f64 = terms.iter().sum();
        let scale = max_abs(&terms);
        assert!(
            (rate - power).abs() < 1e-6 * scale,
            "seed {seed}: dE/dt {rate} against the power {power} (terms up to {scale})"
        );
    }
}

/// With no torque on the wheels, no friction and a conservative arm, the energy (including the
/// spin energy) is constant to RK4 accuracy, its drift falling as dt⁴, while the wheels spin
/// fast and the bus turns.
#[test]
fn energy_is_conserved_without_wheel_torque_or_friction() {
    let robot = Robot::space_arm();
    let joints = FlexibleJoints::uniform(7, 2e3, 0.5, 0.0, 0.0).unwrap();
    let arm = FlexibleArm::new(robot, joints)
        .unwrap()
        .with_wheels(pyramid())
        .unwrap();
    let layout = arm.layout();
    let mut rng = Rng::new(3);
    let q = rng.vector(7, -1.0, 1.0);
    let theta: Vec<f64> = q.iter().map(|q| q + rng.range(-0.02, 0.02)).collect();
    let mut x0 = arm
        .state(&StateSpec {
            q: Some(&q),
            theta: Some(&theta),
            qd: Some(&rng.vector(7, -0.3, 0.3)),
            base_twist: Some(&rng.vector(6, -0.2, 0.2)),
            ..StateSpec::default()
        })
        .unwrap();
    x0[layout.wheel_speed()].copy_from_slice(&[300.0, -200.0, 100.0, 250.0]);
    let drift = |dt: f64| {
        let steps = (0.5 / dt).round() as usize;
        let traj = arm
            .simulate(&x0, dt, steps, &mut Schedule::Zero, &Wrenches::ZERO)
            .unwrap();
        let e = traj.rows().energy(&arm);
        (e[0], e.iter().fold(0.0f64, |m, v| m.max((v - e[0]).abs())))
    };
    // the wrist joints ring near √(2e3 (1/0.5 + 1/m)) ≈ 140 rad/s: h ω ≈ 0.14 at 1 ms
    let ((e0, coarse), (_, fine)) = (drift(1e-3), drift(5e-4));
    eprintln!("energy {e0:e} J, drift {coarse:e} J (dt 1 ms), {fine:e} J (0.5 ms)");
    assert!(coarse < 1e-6 * e0, "{coarse:e} of {e0:e}");
    assert!(coarse / fine > 10.0, "drift {coarse:e} -> {fine:e}");
}

/// The limits, Basilisk's way: a command beyond `max_torque` is clipped (and the clipped torque
/// is what is recorded and what acts); a wheel driven to `max_speed` gets no more torque that
/// would speed it up, while a torque that slows it passes.
#[test]
fn torques_are_clipped_and_a_wheel_stops_at_its_speed_limit() {
    let wheel = pyramid().wheels()[0];
    assert_eq!(saturated_torque(&wheel, 5.0, 0.0), 0.2);
    assert_eq!(saturated_torque(&wheel, -5.0, 0.0), -0.2);
    assert_eq!(saturated_torque(&wheel, 0.1, 599.0), 0.1);
    assert_eq!(saturated_torque(&wheel, 0.1, 600.0), 0.0);
    assert_eq!(saturated_torque(&wheel, -0.1, 600.0), -0.1);
    assert_eq!(saturated_torque(&wheel, -0.1, -600.0), 0.0);
    assert_eq!(saturated_torque(&wheel, 0.1, -601.0), 0.1);

    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())
        .unwrap()
        .with_wheels(pyramid())
        .unwrap();
    let layout = arm.layout();
    let x0 = arm.rest_state();
    // beyond the limit: the same run as with the limit itself, and the limit recorded
    let run = |command: f64| {
        let wrenches = Wrenches {
            wheel_torque: Schedule::Constant(vec![command, 0.0, -command, 0.0]),
            ..Wrenches::ZERO
        };
        arm.simulate(&x0, 1e-3, 20, &mut Schedule::Zero, &wrenches)
            .unwrap()
    };
    let (over, at_limit) = (run(3.0), run(0.2));
    assert_eq!(over.x, at_limit.x);
    assert_eq!(over.u, at_limit.u);
    assert_eq!(over.u[7..11], [0.2, 0.0, -0.2, 0.0]);
    assert_eq!(over.u.len(), 20 * layout.inputs_len());

    // driven to max_speed: starting just below it with full torque, the wheel crosses the limit
    // within a step, then its torque is cut; a torque that slows it then acts again
    let mut x = arm.rest_state();
    x[layout.wheel_speed()][0] = 599.9;
    let wrenches = Wrenches {
        wheel_torque: Schedule::Constant(vec![0.2, 0.0, 0.0, 0.0]),
        ..Wrenches::ZERO
    };
    let traj = arm
        .simulate(&x, 1e-2, 200, &mut Schedule::Zero, &wrenches)
        .unwrap();
    let speeds: Vec<f64> = traj
        .rows()
        .iter()
        .map(|x| x[layout.wheel_speed()][0])
        .collect();
    let applied: Vec<f64> = traj.u.chunks(layout.inputs_len()).map(|u| u[7]).collect();
    let first_over = speeds.iter().position(|&s| s >= 600.0).unwrap();
    assert!(first_over >= 1 && applied[..first_over].iter().all(|&u| u == 0.2));
    for (s, u) in speeds.iter().zip(&applied) {
        assert_eq!(*u, if *s >= 600.0 { 0.0 } else { 0.2 }, "speed {s}");
    }
    // one step of 0.2 N·m for 10 ms on 0.04 kg·m² adds at most 0.05 rad/s (plus the bus's share)
    assert!(max_abs(&speeds) < 600.06, "{}", max_abs(&speeds));
    let mut ws = arm.workspace();
    let mut y = traj.rows().row(traj.len() - 1).to_vec();
    let before = y[layout.wheel_speed()][0];
    let slow = [-0.2, 0.0, 0.0, 0.0];
    arm.step(
        &mut ws,
        &mut y,
        1e-2,
        &Inputs {
            wheel_torque: &slow,
            ..Inputs::torques(&[0.0; 7])
        },
    )
    .unwrap();
    assert!(y[layout.wheel_speed()][0] < before - 0.03);
}

/// `derivative` saturates as the step does: a command beyond the limit gives the derivative of
/// the limit.
#[test]
fn derivative_applies_the_limits() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())
        .unwrap()
        .with_wheels(pyramid())
        .unwrap();
    let x = random_state(&arm, 2, 100.0);
    let mut ws = arm.workspace();
    let u = [0.0; 7];
    let xdot = |command: &[f64], ws: &mut orbitflex::ArmWorkspace| {
        let mut out = vec![0.0; x.len()];
        let inputs = Inputs {
            wheel_torque: command,
            ..Inputs::torques(&u)
        };
        arm.derivative(ws, &x, &inputs, &mut out).unwrap();
        out
    };
    assert_eq!(
        xdot(&[9.0, -9.0, 0.1, 0.0], &mut ws),
        xdot(&[0.2, -0.2, 0.1, 0.0], &mut ws)
    );
    assert_ne!(
        xdot(&[0.1, 0.0, 0.0, 0.0], &mut ws),
        xdot(&[0.0; 4], &mut ws)
    );
}

/// A batch of arms with wheels equals the single runs bit for bit, the applied wheel torques
/// included.
#[test]
fn batch_with_wheels_equals_single_runs() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())
        .unwrap()
        .with_wheels(pyramid())
        .unwrap();
    let (runs, steps, len) = (3, 40, arm.layout().len());
    let x0: Vec<f64> = (0..runs)
        .flat_map(|b| random_state(&arm, b as u64, 599.0))
        .collect();
    let mut rng = Rng::new(7);
    let table = rng.vector(runs * steps * 4, -0.5, 0.5);
    let u = rng.vector(runs * 7, -1.0, 1.0);
    let batch = Batch {
        runs,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[runs, len], runs, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::new("u", &u, &[runs, 7], runs, Some(steps), 7).unwrap()),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::Open(
            BatchInput::new(
                "wheel_torque",
                &table,
                &[runs, steps, 4],
                runs,
                Some(steps),
                4,
            )
            .unwrap(),
        ),
    };
    let settings = BatchSettings {
        dt: 2e-3,
        steps,
        record_every: 1,
        keep_rows: true,
        threads: Some(2),
    };
    let record = simulate_batch(&batch, &settings, &BatchWatch::default()).unwrap();
    for b in 0..runs {
        let wrenches = Wrenches {
            wheel_torque: Schedule::Table {
                values: table[b * steps * 4..(b + 1) * steps * 4].to_vec(),
                width: 4,
            },
            ..Wrenches::ZERO
        };
        let single = arm
            .simulate(
                &x0[b * len..(b + 1) * len],
                2e-3,
                steps,
                &mut Schedule::Constant(u[b * 7..(b + 1) * 7].to_vec()),
                &wrenches,
            )
            .unwrap();
        assert_eq!(record.run(b), Some(single.clone()), "run {b}");
        // near max_speed some commands were cut: the record holds what acted
        assert_eq!(single.u.len(), steps * 11);
    }
}

/// The controllers of `runs` runs: motor PDs and attitude PDs with gains that differ per run.
fn controllers(arm: &FlexibleArm, runs: usize) -> (Vec<MotorPD>, Vec<AttitudePD>) {
    let n = arm.dof();
    let allocation = arm.wheels().unwrap().allocation().unwrap();
    let motors = (0..runs)
        .map(|b| {
            let kp = vec![20.0 + 5.0 * b as f64; n];
            let kd = vec![2.0 + b as f64; n];
            let reference = Schedule::Constant(vec![0.1 * b as f64; n]);
            MotorPD::new(kp, kd, reference, Schedule::Zero, Schedule::Zero).unwrap()
        })
        .collect();
    let attitudes = (0..runs)
        .map(|b| {
            let kp = [0.5 + 0.1 * b as f64, 0.6, 0.7];
            let kd = [1.5, 1.5 + 0.2 * b as f64, 1.0];
            AttitudePD::new(kp, kd, AttitudeTarget::Initial, allocation.clone()).unwrap()
        })
        .collect();
    (motors, attitudes)
}

/// A batch whose wheels are held by an `AttitudePD` (one shared, or one per run) and whose
/// motors and wheels run at their own rates (`Sampled`, periods of whole and of non-whole steps,
/// with delays) equals the single runs with the same controllers bit for bit, for 1, 2 and 3
/// threads; each run starts from a copy (the latched attitude and the held rows are its own).
#[test]
fn batch_with_attitude_pd_and_sampled_equals_single_runs() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())
        .unwrap()
        .with_wheels(pyramid())
        .unwrap();
    let (runs, steps, dt, len) = (4, 60, 2e-3, arm.layout().len());
    let x0: Vec<f64> = (0..runs)
        .flat_map(|b| random_state(&arm, 40 + b as u64, 100.0))
        .collect();
    let (motors, attitudes) = controllers(&arm, runs);
    let motor_refs: Vec<&MotorPD> = motors.iter().collect();
    let attitude_refs: Vec<&AttitudePD> = attitudes.iter().collect();
    // 1/(3 dt): a sample every 3 steps; 170 Hz: every 2.94 steps
    let every3 = SampleClock {
        rate_hz: 1.0 / (3.0 * dt),
        delay: 1,
    };
    let odd = SampleClock {
        rate_hz: 170.0,
        delay: 2,
    };
    let u_pd = BatchControl::Pd(PerRun::Each(&motor_refs));
    let w_pd = BatchControl::Attitude(PerRun::Each(&attitude_refs));
    let cases: [(
        BatchControl,
        BatchControl,
        Option<SampleClock>,
        Option<SampleClock>,
    ); 3] = [
        (
            BatchControl::zero(7),
            BatchControl::Attitude(PerRun::All(&attitudes[1])),
            None,
            None,
        ),
        (
            BatchControl::Sampled(&u_pd, every3),
            BatchControl::Sampled(&w_pd, odd),
            Some(every3),
            Some(odd),
        ),
        (
            u_pd,
            BatchControl::Sampled(&w_pd, every3),
            None,
            Some(every3),
        ),
    ];
    for (case, (u, wheel_torque, u_clock, w_clock)) in cases.into_iter().enumerate() {
        let batch = Batch {
            runs,
            arms: PerRun::All(&arm),
            x0: BatchInput::new("x0s", &x0, &[runs, len], runs, None, len).unwrap(),
            u,
            base_wrench: BatchInput::zero(6),
            ee_wrench: BatchInput::zero(6),
            wheel_torque,
        };
        let mut records = (1..=3).map(|threads| {
            let settings = BatchSettings {
                dt,
                steps,
                record_every: 1,
                keep_rows: true,
                threads: Some(threads),
            };
            simulate_batch(&batch, &settings, &BatchWatch::default()).unwrap()
        });
        let record = records.next().unwrap();
        for other in records {
            assert_eq!(other.x, record.x, "case {case}");
            assert_eq!(other.u, record.u, "case {case}");
        }
        for b in 0..runs {
            let sampled =
                |inner: Box<dyn Controller + Send>, clock: Option<SampleClock>| match clock {
                    Some(c) => Box::new(Sampled::new(inner, c.rate_hz, c.delay).unwrap())
                        as Box<dyn Controller + Send>,
                    None => inner,
                };
            let mut u: Box<dyn Controller + Send> = match case {
                0 => Box::new(Schedule::Zero),
                _ => sampled(Box::new(motors[b].clone()), u_clock),
            };
            let attitude = if case == 0 { 1 } else { b };
            let mut wheels = sampled(Box::new(attitudes[attitude].clone()), w_clock);
            let single = orbitflex::integrate::simulate(
                &arm,
                &Run::new(&x0[b * len..(b + 1) * len], dt, steps),
                &mut Drive {
                    u: &mut *u,
                    base_wrench: &mut Schedule::Zero,
                    ee_wrench: &mut Schedule::Zero,
                    wheel_torque: &mut *wheels,
                },
                &mut Unobserved,
            )
            .unwrap();
            assert_eq!(record.run(b), Some(single.clone()), "case {case}, run {b}");
            // the wheels did work: the applied torques are not all zero
            let applied: Vec<f64> = single.u.chunks(11).flat_map(|r| r[7..].to_vec()).collect();
            assert!(max_abs(&applied) > 1e-3, "case {case}, run {b}");
        }
    }
}

/// A controller on the wrong channel, a per-run sequence of the wrong length, a sampled
/// control inside another and a bad rate are each refused before any step, naming the channel.
#[test]
fn bad_batch_controllers_are_refused_clearly() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())
        .unwrap()
        .with_wheels(pyramid())
        .unwrap();
    let (motors, attitudes) = controllers(&arm, 3);
    let x0 = arm.rest_state();
    let len = x0.len();
    let two: Vec<&AttitudePD> = attitudes.iter().take(2).collect();
    let inner = BatchControl::Attitude(PerRun::All(&attitudes[0]));
    let nested = BatchControl::Sampled(
        &inner,
        SampleClock {
            rate_hz: 10.0,
            delay: 0,
        },
    );
    let settings = BatchSettings {
        dt: 1e-3,
        steps: 5,
        record_every: 1,
        keep_rows: true,
        threads: Some(1),
    };
    let error = |u: BatchControl, wheel_torque: BatchControl| {
        let batch = Batch {
            runs: 3,
            arms: PerRun::All(&arm),
            x0: BatchInput::new("x0s", &x0, &[len], 3, None, len).unwrap(),
            u,
            base_wrench: BatchInput::zero(6),
            ee_wrench: BatchInput::zero(6),
            wheel_torque,
        };
        simulate_batch(&batch, &settings, &BatchWatch::default())
            .unwrap_err()
            .to_string()
    };
    let idle = BatchControl::zero(7);
    assert_eq!(
        error(idle, BatchControl::Pd(PerRun::All(&motors[0]))),
        "wheel_torque: a MotorPD drives the motors (u), not the reaction wheels; give wheel \
         torques or an AttitudePD"
    );
    assert_eq!(
        error(
            BatchControl::Attitude(PerRun::All(&attitudes[0])),
            BatchControl::zero(4)
        ),
        "u: an AttitudePD drives the reaction wheels (wheel_torque), not the motors; give motor \
         torques or a MotorPD"
    );
    assert_eq!(
        error(idle, BatchControl::Attitude(PerRun::Each(&two))),
        "wheel_torque: expected 3 AttitudePD controllers (one per run), given 2"
    );
    let clock = SampleClock {
        rate_hz: 10.0,
        delay: 0,
    };
    assert_eq!(
        error(idle, BatchControl::Sampled(&nested, clock)),
        "wheel_torque: a sampled control inside a sampled control; sample it once, at the rate \
         it runs at"
    );
    let bad = SampleClock {
        rate_hz: -1.0,
        delay: 0,
    };
    assert_eq!(
        error(BatchControl::Sampled(&idle, bad), BatchControl::zero(4)),
        "rate_hz: expected a finite rate > 0 (Hz), given -1"
    );
    // an attitude controller for three wheels on arms with four
    let three = AttitudePD::new(
        [1.0; 3],
        [1.0; 3],
        AttitudeTarget::Initial,
        vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
    )
    .unwrap();
    let e = error(idle, BatchControl::Attitude(PerRun::All(&three)));
    assert!(
        e.starts_with("wheel_torque (run 0): expected an AttitudePD for 4 wheels"),
        "{e}"
    );
}

/// Each bad wheel parameter is named, with what was expected and what was given.
#[test]
fn bad_wheels_are_refused_clearly() {
    let good = pyramid().wheels()[0];
    let err = |wheel: Wheel| {
        ReactionWheels::new(vec![good, wheel])
            .unwrap_err()
            .to_string()
    };
    assert_eq!(
        ReactionWheels::new(vec![]).unwrap_err().to_string(),
        "ReactionWheels: expected at least one wheel, given none (an arm without wheels takes \
         no ReactionWheels)"
    );
    assert!(err(Wheel {
        axis: [1.0, 1.0, 0.0],
        ..good
    })
    .starts_with("axes[1]: expected a unit vector (norm 1 within 1e-5), given [1.0, 1.0, 0.0]"));
    assert!(err(Wheel {
        axis: [0.0; 3],
        ..good
    })
    .starts_with("axes[1]: expected a unit vector"));
    assert_eq!(
        err(Wheel {
            position: [0.0, f64::NAN, 0.0],
            ..good
        }),
        "positions[1]: element 1 is not finite (NaN)"
    );
    assert_eq!(
        err(Wheel {
            spin_inertia: -0.1,
            ..good
        }),
        "spin_inertia[1]: expected a finite number > 0, given -0.1"
    );
    assert_eq!(
        err(Wheel { mass: 0.0, ..good }),
        "mass[1]: expected a finite number > 0, given 0"
    );
    assert_eq!(
        err(Wheel {
            max_speed: f64::NAN,
            ..good
        }),
        "max_speed[1]: expected a finite number > 0 (inf: no limit), given NaN"
    );
    assert_eq!(
        err(Wheel {
            friction: -1.0,
            ..good
        }),
        "friction[1]: expected a finite number >= 0, given -1"
    );
    let e = err(Wheel {
        transverse_inertia: 0.01,
        ..good
    });
    assert!(
        e.starts_with("transverse_inertia[1]: the wheel's inertia diag(J_t, J_t, J_s)")
            && e.contains("triangle inequality")
            && e.ends_with("transverse_inertia >= spin_inertia / 2 (0.02 kg·m² here)"),
        "{e}"
    );
    // a unit axis typed to five digits is taken (and normalised)
    let typed = ReactionWheels::new(vec![Wheel {
        axis: [0.57735, 0.57735, 0.57735],
        ..good
    }])
    .unwrap();
    assert!((Vec3::from(typed.wheels()[0].axis).norm() - 1.0).abs() < 1e-15);
    // unlimited torque and speed are allowed
    assert!(ReactionWheels::new(vec![Wheel {
        max_torque: f64::INFINITY,
        max_speed: f64::INFINITY,
        ..good
    }])
    .is_ok());
}

/// Wheel torques of the wrong length, to an arm without wheels, or not finite; the calls not
/// available with wheels yet say so.
#[test]
fn bad_wheel_torques_are_refused_clearly() {
    let plain = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let arm = plain.clone().with_wheels(pyramid()).unwrap();
    let u = [0.0; 7];
    let call = |arm: &FlexibleArm, w: &[f64]| {
        let x = arm.rest_state();
        let mut xdot = vec![0.0; x.len()];
        arm.derivative(
            &mut arm.workspace(),
            &x,
            &Inputs {
                wheel_torque: w,
                ..Inputs::torques(&u)
            },
            &mut xdot,
        )
        .unwrap_err()
        .to_string()
    };
    assert_eq!(
        call(&arm, &[0.1; 3]),
        "wheel_torque: expected length 4, given length 3"
    );
    assert_eq!(
        call(&arm, &[0.1, f64::INFINITY, 0.0, 0.0]),
        "wheel_torque: element 1 is not finite (inf)"
    );
    assert_eq!(
        call(&plain, &[0.1; 4]),
        "wheel_torque: expected none (the arm has no reaction wheels), given length 4"
    );
    let wrong_table = Wrenches {
        wheel_torque: Schedule::Table {
            values: vec![0.0; 12],
            width: 4,
        },
        ..Wrenches::ZERO
    };
    let e = arm
        .simulate(
            &arm.rest_state(),
            1e-3,
            5,
            &mut Schedule::Zero,
            &wrong_table,
        )
        .unwrap_err()
        .error
        .to_string();
    assert_eq!(
        e,
        "wheel_torque: expected a table of shape (5, 4), given shape (3, 4)"
    );
    let e = plain
        .simulate(
            &plain.rest_state(),
            1e-3,
            3,
            &mut Schedule::Zero,
            &wrong_table,
        )
        .unwrap_err()
        .error
        .to_string();
    assert!(
        e.starts_with("wheel_torque: the arm has no reaction wheels"),
        "{e}"
    );
    // the step's Jacobians are not there yet (the derivative's are: tests/wheel_linear.rs)
    let e = arm
        .step_jacobians(
            &mut arm.workspace(),
            &arm.rest_state(),
            1e-3,
            &Inputs::torques(&u),
        )
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "step_jacobians: not available yet for an arm with reaction wheels"
    );
    // a state of the arm without wheels is the wrong length for the arm with them
    let e = arm
        .check_state(&plain.rest_state())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "x (state): expected length 45, given length 41");
}

/// `Robot::to_urdf` loads back to the same dynamics (mass matrix and bias forces at a random
/// state), on a chain with rotated frames and on a tree.
#[test]
fn robot_urdf_round_trips() {
    for robot in [
        random_chain(6, 4),
        random_tree_all_leaves(&[0, 0, 1, 0, 3], 2),
        Robot::dual_arm(),
    ] {
        let options = UrdfOptions {
            ee_links: robot.ee_links().iter().map(|s| s.to_string()).collect(),
            ..UrdfOptions::default()
        };
        let again = Robot::from_urdf_string(&robot.to_urdf(), &options).unwrap();
        assert_eq!(again.joint_names(), robot.joint_names());
        assert_eq!(again.parents(), robot.parents());
        let (q, v, qd) = orbitflex::testing::random_state(&robot, 3);
        let mut d1 = Data::new(&robot);
        let mut d2 = Data::new(&again);
        let m1 = algorithms::crba(&robot, &mut d1, &q).unwrap().clone();
        let m2 = algorithms::crba(&again, &mut d2, &q).unwrap().clone();
        assert!(
            (&m1 - &m2).amax() < 1e-12 * m1.amax(),
            "{}",
            (&m1 - &m2).amax()
        );
        let rigid = RigidState::new(&q, &v, &qd);
        let tau = vec![0.3; robot.dof()];
        let a1 = algorithms::aba(&robot, &mut d1, &rigid, &tau, &Loads::ZERO)
            .unwrap()
            .clone();
        let a2 = algorithms::aba(&again, &mut d2, &rigid, &tau, &Loads::ZERO)
            .unwrap()
            .clone();
        assert!((&a1 - &a2).amax() < 1e-11 * a1.amax().max(1.0));
        let joints = FlexibleJoints::uniform(robot.dof(), 1e3, 1.0, 0.0, 0.0).unwrap();
        let arm1 = FlexibleArm::new(robot.clone(), joints.clone()).unwrap();
        let arm2 = FlexibleArm::new(again, joints).unwrap();
        let x = arm1
            .state(&StateSpec {
                q: Some(&q),
                ..StateSpec::default()
            })
            .unwrap();
        for e in 0..robot.end_effectors().len() {
            let (p1, p2) = (arm1.ee_pose(&x, e), arm2.ee_pose(&x, e));
            let gap = p1
                .iter()
                .zip(&p2)
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(gap < 1e-14, "EE {e}: {gap:e}");
        }
    }
}

/// Planning with wheels (phase 2): a held bus does not turn, so the plan and its holding wrench
/// are those of the arm without wheels, bit for bit; the wheels' demand is that wrench's moment
/// allocated and integrated, back to zero when the arm is at rest again; a free-floating plan
/// with rubbing wheels is refused (their friction turns the bus, which the plan does not model).
#[test]
fn planning_with_wheels() {
    let plain = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let arm = plain.clone().with_wheels(pyramid()).unwrap();
    let limits = orbitflex::Limits::from_robot(arm.robot(), None, None).unwrap();
    let plan =
        |arm: &FlexibleArm, base| orbitflex::plan_slew(arm, &[0.1; 7], None, &limits, base, &[]);
    let (held, held_plain) = (
        plan(&arm, orbitflex::BaseMode::Held).unwrap(),
        plan(&plain, orbitflex::BaseMode::Held).unwrap(),
    );
    assert_eq!(held.duration(), held_plain.duration());
    assert_eq!(held.samples(), held_plain.samples());
    let demand = held.wheel_demand(&pyramid()).unwrap();
    let last = demand.t.len() - 1;
    assert!(demand.peak_momentum > 0.0);
    assert!(demand.momentum[3 * last..]
        .iter()
        .all(|h| h.abs() < 1e-6 * demand.peak_momentum));
    assert!(plan(&arm, orbitflex::BaseMode::Free)
        .unwrap()
        .wheel_demand(&pyramid())
        .is_err());
    let rubbing: Vec<Wheel> = pyramid()
        .wheels()
        .iter()
        .map(|w| Wheel {
            friction: 0.01,
            ..*w
        })
        .collect();
    let rubbing = plain
        .with_wheels(ReactionWheels::new(rubbing).unwrap())
        .unwrap();
    let e = plan(&rubbing, orbitflex::BaseMode::Free)
        .unwrap_err()
        .to_string();
    assert!(e.contains("friction"), "{e}");
    assert!(plan(&rubbing, orbitflex::BaseMode::Held).is_ok());
}
