//! Capture of a free-flying target (issue 29, phase 1): the `Target` as a torque-free rigid body,
//! and the grasp impulse checked through its invariants (momentum, energy), against a dense KKT
//! solve of the impulse–momentum balance, and against `with_payload`. Pinocchio's
//! `impulseDynamics` is the oracle in `tests/python/test_capture.py`.

use nalgebra::{DMatrix, DVector};
use orbitflex::algorithms::{self, Data};
use orbitflex::capture::{capture, rigid_body_derivative, Capture, Target};
use orbitflex::spatial::{quaternion_to_rotation, Force, Inertia, Mat3, Motion, Transform, Vec3};
use orbitflex::testing::{random_chain, random_joints, random_tree, random_tree_all_leaves, Rng};
use orbitflex::testing::{TREE_ONE_TRUNK, TREE_THREE_ARMS};
use orbitflex::{FlexibleArm, Inputs, ReactionWheels, Robot, StateSpec, Wheel};

/// Random arms: chains of 3 to 8 joints, two trees with one EE, a tree with an EE on every leaf.
fn arms() -> Vec<(String, FlexibleArm)> {
    let mut out = Vec::new();
    for (seed, n) in [(1u64, 3usize), (2, 5), (3, 8)] {
        out.push((format!("chain n={n}"), random_chain(n, seed)));
    }
    out.push(("tree one trunk".into(), random_tree(TREE_ONE_TRUNK, 4)));
    out.push(("tree three arms".into(), random_tree(TREE_THREE_ARMS, 5)));
    out.push((
        "tree, EE on every leaf".into(),
        random_tree_all_leaves(&[0, 0, 1, 2, 1, 4, 0, 6], 6),
    ));
    out.push(("space arm".into(), Robot::space_arm()));
    out.into_iter()
        .map(|(name, robot)| {
            let joints = random_joints(robot.dof(), 7);
            (name, FlexibleArm::new(robot, joints).unwrap())
        })
        .collect()
}

fn random_quaternion(rng: &mut Rng) -> [f64; 4] {
    let q = nalgebra::UnitQuaternion::from_rotation_matrix(
        &nalgebra::Rotation3::from_matrix_unchecked(rng.rotation()),
    );
    let c = q.coords;
    [c[0], c[1], c[2], c[3]]
}

/// A random state of `arm`: any base pose, angles, rates, stretched springs, motor rates.
fn random_arm_state(arm: &FlexibleArm, rng: &mut Rng) -> Vec<f64> {
    let n = arm.dof();
    let quat = random_quaternion(rng);
    let pose = [
        rng.range(-2.0, 2.0),
        rng.range(-2.0, 2.0),
        rng.range(-2.0, 2.0),
        quat[0],
        quat[1],
        quat[2],
        quat[3],
    ];
    let (q, theta) = (rng.vector(n, -3.0, 3.0), rng.vector(n, -3.0, 3.0));
    let (qd, theta_dot) = (rng.vector(n, -1.0, 1.0), rng.vector(n, -1.0, 1.0));
    let twist = rng.vector(6, -0.5, 0.5);
    arm.state(&StateSpec {
        q: Some(&q),
        theta: Some(&theta),
        qd: Some(&qd),
        theta_dot: Some(&theta_dot),
        base_pose: Some(&pose),
        base_twist: Some(&twist),
    })
    .unwrap()
}

/// A random target of 20 to 300 kg, its COM offset from its frame, its frame near the EE of
/// `arm` at `x` (within 0.5 m, any attitude), tumbling and drifting.
fn random_target(arm: &FlexibleArm, x: &[f64], ee: usize, rng: &mut Rng) -> Target {
    let mass = rng.range(20.0, 300.0);
    let (a, b) = (rng.range(0.2, 1.0), rng.range(0.2, 1.0));
    let c = rng.range((a - b).abs() + 0.05, a + b);
    let r = rng.rotation();
    let inertia = r * Mat3::from_diagonal(&Vec3::new(a, b, c)) * r.transpose() * mass;
    let at = arm.ee_pose(x, ee);
    let quat = random_quaternion(rng);
    let offset = rng.unit() * rng.range(0.0, 0.5);
    let pose = [
        at[0] + offset.x,
        at[1] + offset.y,
        at[2] + offset.z,
        quat[0],
        quat[1],
        quat[2],
        quat[3],
    ];
    let twist = rng.vector(6, -0.3, 0.3);
    let g = random_quaternion(rng);
    let grasp = [0.3, -0.2, 0.4, g[0], g[1], g[2], g[3]];
    Target::new(mass, inertia, &pose, &twist, &grasp)
        .unwrap()
        .with_com(rng.unit() * rng.range(0.0, 0.4))
        .unwrap()
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

fn sub(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

fn add(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x + y).collect()
}

/// Every (arm, EE, state, target) case: 7 arms, every EE, 4 random states each.
fn cases() -> Vec<(String, FlexibleArm, usize, Vec<f64>, Target)> {
    let mut out = Vec::new();
    let mut rng = Rng::new(29);
    for (name, arm) in arms() {
        for ee in 0..arm.robot().end_effectors().len() {
            for trial in 0..4 {
                let x = random_arm_state(&arm, &mut rng);
                let target = random_target(&arm, &x, ee, &mut rng);
                out.push((
                    format!("{name}, EE {ee}, trial {trial}"),
                    arm.clone(),
                    ee,
                    x,
                    target,
                ));
            }
        }
    }
    out
}

/// Total linear and angular momentum (inertial origin, inertial axes) of arm and target just
/// before equals that just after, both of the combined arm and of the arm plus the target at
/// its new twist.
///
/// The balance is exact: the impulse is internal. Round-off: each momentum is a sum of O(n)
/// products of magnitudes bounded by the parts' momenta, and `ν⁺` comes from a backward-stable
/// 6×6 Cholesky solve whose residual `‖A F̂ − V_rel‖ ≲ 6 ε ‖A‖ ‖F̂‖` changes the momenta by
/// `ε`-relative amounts of `‖F̂‖` (itself ≤ the parts' momenta, as it stops their relative
/// motion). So the error is a few hundred `ε` ≈ 1e-13 of the parts' momentum norms at most:
/// 1e-12 relative to them.
#[test]
fn momentum_is_kept_across_the_capture() {
    let mut worst: f64 = 0.0;
    for (label, arm, ee, x, target) in cases() {
        let before_arm = arm.momentum(&mut arm.workspace(), &x);
        let h_target = target.momentum();
        let before = add(&before_arm, &h_target);
        let scale = norm(&before_arm) + norm(&h_target);
        let c = capture(&arm, &x, &target, Some(ee)).unwrap();
        let combined = c.arm.momentum(&mut c.arm.workspace(), &c.x);
        let err = norm(&sub(&combined, &before)) / scale;
        assert!(err < 1e-12, "{label}: combined arm momentum off by {err:e}");
        // the arm at ν⁺ and the target at W⁺ as separate bodies
        let mut state = target.state();
        c.target_twist.write_to(&mut state[7..]);
        let moved = target.at_state(&state).unwrap();
        let split = add(&arm.momentum(&mut arm.workspace(), &c.x), &moved.momentum());
        let err_split = norm(&sub(&split, &before)) / scale;
        assert!(
            err_split < 1e-12,
            "{label}: arm + target off by {err_split:e}"
        );
        // the impulse is not zero: the test would see a capture that did nothing
        assert!(
            norm(&sub(&arm.momentum(&mut arm.workspace(), &c.x), &before_arm)) > 1e-3 * scale,
            "{label}: no momentum exchanged"
        );
        worst = worst.max(err).max(err_split);
    }
    eprintln!("worst relative momentum error {worst:e}");
}

/// The energy lost is ≥ 0 and is what the total energy loses: arm (rigid, motors, springs) plus
/// target before, the combined arm after.
///
/// Bound: `E_before − E_after` is a difference of sums of O(n) terms each exact to a few `ε`,
/// so it carries an absolute error of a few hundred `ε E_before`; `ν⁺`'s solve error adds a
/// first-order change `ν⁺ᵀ 𝓜 δν` of the same relative size. 1e-12 `E_before` has a margin of
/// 10× over that and is far below any physical slip (a lost term is ≥ 1e-3 of `E`).
#[test]
fn energy_loss_is_what_the_energy_loses() {
    for (label, arm, ee, x, target) in cases() {
        let e_before = arm.energy(&mut arm.workspace(), &x) + target.kinetic_energy();
        let c = capture(&arm, &x, &target, Some(ee)).unwrap();
        let e_after = c.arm.energy(&mut c.arm.workspace(), &c.x);
        assert!(c.energy_loss > 0.0, "{label}: loss {}", c.energy_loss);
        let err = (e_before - e_after - c.energy_loss).abs() / e_before;
        assert!(err < 1e-12, "{label}: ΔE − loss off by {err:e} of E");
        // ½ V_relᵀ F, the quadratic form written another way
        let form = 0.5 * c.relative_twist.dot(&c.impulse);
        assert!(
            (form - c.energy_loss).abs() <= 1e-12 * c.energy_loss,
            "{label}"
        );
    }
}

/// A target already moving with the EE (zero relative twist) is captured without an impulse
/// and without a loss.
#[test]
fn no_relative_twist_no_impulse_no_loss() {
    let mut rng = Rng::new(3);
    for (label, arm) in arms() {
        // exactly: arm at rest, target at rest
        let x = {
            let mut x = random_arm_state(&arm, &mut rng);
            let layout = arm.layout();
            x[layout.base_twist()].fill(0.0);
            x[layout.qd()].fill(0.0);
            x
        };
        let ee = 0;
        let target = random_target(&arm, &x, ee, &mut rng);
        let mut state = target.state();
        state[7..].fill(0.0);
        let still = target.at_state(&state).unwrap();
        let c = capture(&arm, &x, &still, Some(ee)).unwrap();
        assert_eq!(c.energy_loss, 0.0, "{label}");
        assert_eq!(c.impulse, Force::ZERO, "{label}");
        assert_eq!(c.x, x, "{label}");

        // moving: the target's twist is the EE's carried to the target frame
        let x = random_arm_state(&arm, &mut rng);
        let target = random_target(&arm, &x, ee, &mut rng);
        let probe = capture(&arm, &x, &target, Some(ee)).unwrap();
        // W = X⁻¹ V_e = W_old + X⁻¹ V_rel
        let x_et = relative_transform(&arm, &x, &target, ee);
        let w = *target.twist() + x_et.apply_motion_inverse(&probe.relative_twist);
        let mut state = target.state();
        w.write_to(&mut state[7..]);
        let along = target.at_state(&state).unwrap();
        let c = capture(&arm, &x, &along, Some(ee)).unwrap();
        let e = arm.energy(&mut arm.workspace(), &x) + along.kinetic_energy();
        // V_rel is round-off, ~1e-15 of the twists: the loss is its square
        assert!(
            c.energy_loss < 1e-24 * e,
            "{label}: loss {:e}",
            c.energy_loss
        );
        let f = c.impulse.to_array();
        let momentum = norm(&along.momentum()) + norm(&arm.momentum(&mut arm.workspace(), &x));
        assert!(norm(&f) < 1e-12 * momentum, "{label}: impulse {f:?}");
        assert!(
            probe.energy_loss > 1e-6 * e,
            "{label}: the probe had a real relative twist"
        );
    }
}

/// `X = Φ_{e,t}` from the public poses (an independent path: quaternions of the EE pose).
fn relative_transform(arm: &FlexibleArm, x: &[f64], target: &Target, ee: usize) -> Transform {
    let e = arm.ee_pose(x, ee);
    let ee_axes = quaternion_to_rotation(&e[3..]);
    let t = target.pose();
    let t_axes = quaternion_to_rotation(&t[3..]);
    let delta = Vec3::new(e[0] - t[0], e[1] - t[1], e[2] - t[2]);
    Transform::new(ee_axes.transpose() * t_axes, t_axes.transpose() * delta)
}

/// The dense KKT system of the impulse–momentum balance, solved by LU:
///
/// ```text
/// [ 𝓜   0    Gᵀ ] [Δν ]   [ 0      ]
/// [ 0   Y_e  −𝟙 ] [ΔW_e] = [ 0      ]
/// [ G   −𝟙   0  ] [F  ]   [ −V_rel ]
/// ```
///
/// with `𝓜` from the CRBA, `G = [Φ_{e,B} J_e]`, `Y_e` the target's inertia moved to the EE by the
/// independent `Inertia::transformed_to_parent`. Agreement to 1e-10: the KKT matrix mixes kg and
/// kg·m² with unit couplings; its condition number on these models is below 1e5, so LU is good
/// to ~1e-11 relative.
#[test]
fn impulse_equals_the_dense_kkt_solution() {
    for (label, arm, ee, x, target) in cases() {
        let robot = arm.robot();
        let n = robot.dof();
        let layout = arm.layout();
        let s = layout.split(&x);
        let mut data = Data::new(robot);
        let m = algorithms::crba(robot, &mut data, s.q).unwrap().clone();
        algorithms::ee_jacobian(robot, &mut data, s.q, ee).unwrap();
        let mut g = DMatrix::zeros(6, 6 + n);
        g.view_mut((0, 0), (6, 6)).copy_from(&data.ee_base);
        g.view_mut((0, 6), (6, n)).copy_from(&data.jacobian);
        let x_et = relative_transform(&arm, &x, &target, ee);
        let y_e = target
            .spatial_inertia()
            .transformed_to_parent(&x_et.inverse())
            .matrix();
        let nu = DVector::from_iterator(6 + n, s.base_twist.iter().chain(s.qd).copied());
        let w_e = x_et.apply_motion(target.twist()).to_vector();
        let v_rel = &g * &nu - DVector::from_column_slice(w_e.as_slice());

        let size = 6 + n + 12;
        let mut k = DMatrix::zeros(size, size);
        k.view_mut((0, 0), (6 + n, 6 + n)).copy_from(&m);
        k.view_mut((0, 12 + n), (6 + n, 6))
            .copy_from(&g.transpose());
        k.view_mut((6 + n, 6 + n), (6, 6)).copy_from(&y_e);
        k.view_mut((6 + n, 12 + n), (6, 6))
            .copy_from(&(-DMatrix::<f64>::identity(6, 6)));
        k.view_mut((12 + n, 0), (6, 6 + n)).copy_from(&g);
        k.view_mut((12 + n, 6 + n), (6, 6))
            .copy_from(&(-DMatrix::<f64>::identity(6, 6)));
        let mut rhs = DVector::zeros(size);
        rhs.rows_mut(12 + n, 6).copy_from(&(-&v_rel));
        let sol = k.lu().solve(&rhs).unwrap();

        let c = capture(&arm, &x, &target, Some(ee)).unwrap();
        let f = sol.rows(12 + n, 6);
        let err_f = (DVector::from_column_slice(&c.impulse.to_array()) - f).norm() / f.norm();
        assert!(err_f < 1e-10, "{label}: impulse off by {err_f:e}");
        let nu_after = &nu + sol.rows(0, 6 + n);
        let after = layout.split(&c.x);
        let got = DVector::from_iterator(6 + n, after.base_twist.iter().chain(after.qd).copied());
        let err = (got - &nu_after).norm() / nu_after.norm().max(nu.norm());
        assert!(err < 1e-10, "{label}: ν⁺ off by {err:e}");
        // the target's own impulse response W + Y⁻¹ Xᵀ F is the twist reported
        let dw = sol.rows(6 + n, 6);
        let w_after = x_et.apply_motion_inverse(&Motion::from_slice(
            (DVector::from_column_slice(w_e.as_slice()) + dw).as_slice(),
        ));
        let err_w = norm(&sub(&c.target_twist.to_array(), &w_after.to_array()))
            / norm(&w_after.to_array()).max(norm(&target.twist().to_array()));
        assert!(err_w < 1e-10, "{label}: W⁺ off by {err_w:e}");
        assert!(
            (c.energy_loss - 0.5 * v_rel.dot(&f)).abs() < 1e-10 * c.energy_loss,
            "{label}: loss"
        );
    }
}

/// The springs carry no impulse: poses, angles and motor rates are kept bit for bit; the base
/// twist and the link rates change.
#[test]
fn only_the_link_side_jumps() {
    for (label, arm, ee, x, target) in cases() {
        let c = capture(&arm, &x, &target, Some(ee)).unwrap();
        let layout = arm.layout();
        for (block, range) in [
            ("base pose", layout.base_pose()),
            ("q", layout.q()),
            ("theta", layout.theta()),
            ("theta_dot", layout.theta_dot()),
        ] {
            assert_eq!(&c.x[range.clone()], &x[range], "{label}: {block}");
        }
        assert_ne!(
            &c.x[layout.base_twist()],
            &x[layout.base_twist()],
            "{label}"
        );
        assert_ne!(&c.x[layout.qd()], &x[layout.qd()], "{label}");
        assert_eq!(c.x.len(), x.len());
        assert_eq!(c.ee, ee);
    }
}

/// The combined arm is `with_payload` of the target at its relative pose: bit for bit with the
/// payload the capture reports, and to round-off with the target moved to the EE independently.
#[test]
fn the_combined_arm_is_the_arm_with_the_target_as_payload() {
    for (label, arm, ee, x, target) in cases() {
        let c = capture(&arm, &x, &target, Some(ee)).unwrap();
        let robot = arm.robot();
        let payload = Inertia::from_com(target.mass(), c.payload_com, c.payload_inertia);
        assert_eq!(payload, c.payload, "{label}");
        let loaded = FlexibleArm::new(
            robot.with_payload_at(payload, ee).unwrap(),
            arm.joints().clone(),
        )
        .unwrap();
        let (mut ws_a, mut ws_b) = (c.arm.workspace(), loaded.workspace());
        let n = arm.dof();
        let u = vec![0.5; n];
        let (mut da, mut db) = (vec![0.0; x.len()], vec![0.0; x.len()]);
        c.arm
            .derivative(&mut ws_a, &c.x, &Inputs::torques(&u), &mut da)
            .unwrap();
        loaded
            .derivative(&mut ws_b, &c.x, &Inputs::torques(&u), &mut db)
            .unwrap();
        assert_eq!(da, db, "{label}: derivative");
        let q = &c.x[arm.layout().q()];
        let ma = c
            .arm
            .robot()
            .mass_matrix(q, orbitflex::Method::Recursive)
            .unwrap();
        let mb = loaded
            .robot()
            .mass_matrix(q, orbitflex::Method::Recursive)
            .unwrap();
        assert_eq!(ma, mb, "{label}: mass matrix");

        // independently: the target's spatial inertia moved to the EE frame
        let x_et = relative_transform(&arm, &x, &target, ee);
        let moved = target
            .spatial_inertia()
            .transformed_to_parent(&x_et.inverse());
        let err = (moved.matrix() - c.payload.matrix()).amax() / moved.matrix().amax();
        assert!(err < 1e-12, "{label}: payload off by {err:e}");
        let total = |r: &Robot| r.inertias().iter().map(|i| i.mass).sum::<f64>();
        assert!(
            (total(c.arm.robot()) - total(robot) - target.mass()).abs() < 1e-9,
            "{label}"
        );
    }
}

/// The free body: its derivative satisfies the Newton–Euler equations in the spatial form the
/// arm's base uses, `Y α + b = 0` with `α = [ω̇; v̇ + ω × v]` (A.9, A.10), and keeps its
/// momentum and energy (their rates along the derivative are zero).
#[test]
fn the_target_moves_as_a_free_rigid_body() {
    let mut rng = Rng::new(11);
    let arm = &arms()[0].1;
    for _ in 0..20 {
        let x = random_arm_state(arm, &mut rng);
        let target = random_target(arm, &x, 0, &mut rng);
        let s = target.state();
        let d = target.derivative();
        let mut direct = [0.0; 13];
        rigid_body_derivative(target.spatial_inertia(), &s, &mut direct);
        assert_eq!(d, direct);
        let omega = Vec3::new(s[7], s[8], s[9]);
        let v = Vec3::new(s[10], s[11], s[12]);
        let alpha = Motion::new(
            Vec3::new(d[7], d[8], d[9]),
            Vec3::new(d[10], d[11], d[12]) + omega.cross(&v),
        );
        let y = target.spatial_inertia();
        let residual = y.apply(&alpha) + orbitflex::spatial::bias_force(y, &omega);
        let scale = y.apply(&Motion::new(omega, v)).to_vector().norm() * omega.norm().max(1e-3);
        assert!(
            residual.to_vector().norm() < 1e-12 * scale,
            "Newton–Euler residual {:e}",
            residual.to_vector().norm()
        );
        // pose kinematics
        let r = quaternion_to_rotation(&s[3..7]);
        let r_dot = r * v;
        for i in 0..3 {
            assert!((d[i] - r_dot[i]).abs() < 1e-14 * (1.0 + v.norm()));
        }
        // d/dt of the inertial momentum and of the energy by central differences: O(ε²) ≈ 1e-12
        let eps = 1e-6;
        let shifted = |sign: f64| {
            let state: Vec<f64> = s.iter().zip(&d).map(|(a, b)| a + sign * eps * b).collect();
            target.at_state(&state).unwrap()
        };
        let (plus, minus) = (shifted(1.0), shifted(-1.0));
        let rate = sub(&plus.momentum(), &minus.momentum());
        let h = norm(&target.momentum()) + 1.0;
        assert!(
            norm(&rate) / (2.0 * eps) < 1e-7 * h,
            "momentum rate {:?}",
            rate
        );
        let e_rate = (plus.kinetic_energy() - minus.kinetic_energy()) / (2.0 * eps);
        assert!(
            e_rate.abs() < 1e-7 * (target.kinetic_energy() + 1.0),
            "{e_rate}"
        );
    }
}

/// A symmetric top (moments `A, A, C`) with a transverse rate precesses in its body frame at
/// `Ω = (C − A)/A ω_z` (Euler's closed form): `ω̇_x = −Ω ω_y`, `ω̇_y = Ω ω_x`, `ω̇_z = 0`.
#[test]
fn a_symmetric_top_precesses_at_eulers_rate() {
    let (a, c) = (30.0, 50.0);
    let target = Target::new(
        100.0,
        Mat3::from_diagonal(&Vec3::new(a, a, c)),
        &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        &[0.1, 0.05, 0.3, 0.0, 0.0, 0.0],
        &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
    )
    .unwrap();
    let d = target.derivative();
    let omega_p = (c - a) / a * 0.3;
    // A ω̇_x = (A − C) ω_y ω_z, A ω̇_y = (C − A) ω_z ω_x, ω̇_z = 0
    assert!((d[7] + omega_p * 0.05).abs() < 1e-15);
    assert!((d[8] - omega_p * 0.1).abs() < 1e-15);
    assert!(d[9].abs() < 1e-17);
    // a body frame at the COM does not drift relative to it
    assert_eq!(&d[10..13], &[0.0; 3]);
}

/// Bad targets and bad capture arguments get errors naming what, where, expected and given.
#[test]
fn bad_input_is_named() {
    let good = Mat3::from_diagonal(&Vec3::new(4.0, 5.0, 6.0));
    let pose = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0];
    let twist = [0.0; 6];
    let grasp = pose;
    let err = |r: orbitflex::Result<Target>| r.unwrap_err().to_string();
    let mut not_symmetric = good;
    not_symmetric[(0, 1)] = 1.0;
    let cases: Vec<(orbitflex::Result<Target>, &str)> = vec![
        (
            Target::new(0.0, good, &pose, &twist, &grasp),
            "target 'target': mass: expected a mass > 0 kg (a free body), given 0",
        ),
        (
            Target::new(-3.0, good, &pose, &twist, &grasp),
            "given -3",
        ),
        (
            Target::new(f64::NAN, good, &pose, &twist, &grasp),
            "given NaN",
        ),
        (
            Target::new(1.0, not_symmetric, &pose, &twist, &grasp),
            "target 'target': inertia: inertia matrix is not symmetric",
        ),
        (
            Target::new(1.0, Mat3::from_diagonal(&Vec3::new(-1.0, 5.0, 6.0)), &pose, &twist, &grasp),
            "inertia is not positive definite",
        ),
        (
            Target::new(1.0, Mat3::from_diagonal(&Vec3::new(0.0, 5.0, 5.0)), &pose, &twist, &grasp),
            "expected every moment > 0",
        ),
        (
            Target::new(1.0, Mat3::from_diagonal(&Vec3::new(1.0, 1.0, 6.0)), &pose, &twist, &grasp),
            "triangle inequality",
        ),
        (
            Target::new(1.0, good, &pose[..6], &twist, &grasp),
            "target 'target': pose: expected length 7, given length 6",
        ),
        (
            Target::new(1.0, good, &pose, &[0.0, f64::INFINITY, 0.0, 0.0, 0.0, 0.0], &grasp),
            "target 'target': twist: element 1 is not finite (inf)",
        ),
        (
            Target::new(1.0, good, &[0.0; 7], &twist, &grasp),
            "target 'target': pose: the quaternion (elements 3..7, x y z w) has norm 0e0",
        ),
        (
            Target::new(1.0, good, &pose, &twist, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.5]),
            "target 'target': grasp: the quaternion (elements 3..7, x y z w) has norm 0.7071067811865476; expected a unit quaternion (norm 1 within 1e-6)",
        ),
        (
            Target::new(1.0, good, &pose, &twist, &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.00001]),
            "grasp: the quaternion",
        ),
        (
            Target::new(1.0, good, &pose, &twist, &grasp)
                .unwrap()
                .named("debris")
                .with_com(Vec3::new(0.0, f64::NAN, 0.0)),
            "target 'debris': com: element 1 is not finite (NaN)",
        ),
    ];
    for (result, expected) in cases {
        let message = err(result);
        assert!(message.contains(expected), "{message:?} lacks {expected:?}");
    }
    // a grasp quaternion within six printed digits of unit is accepted and normalised
    // cos 45° printed to six digits
    let six = (std::f64::consts::FRAC_1_SQRT_2 * 1e6).round() / 1e6;
    let nearly = [0.0, 0.0, 0.0, 0.0, 0.0, six, six];
    let t = Target::new(1.0, good, &pose, &twist, &nearly).unwrap();
    let g = t.grasp();
    assert!((g[5] * g[5] + g[6] * g[6] - 1.0).abs() < 1e-15);
    assert!(t
        .at_state(&[0.0; 12])
        .unwrap_err()
        .to_string()
        .contains("state: expected length 13"));

    let (_, arm) = arms().remove(0);
    let x = arm.rest_state();
    let target = Target::new(1.0, good, &pose, &twist, &grasp).unwrap();
    let e = capture(&arm, &x[1..], &target, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("x (state): expected length"), "{e}");
    let e = capture(&arm, &x, &target, Some(1)).unwrap_err().to_string();
    assert!(e.contains("end-effector index 1 is out of range"), "{e}");
    let (_, tree) = arms().remove(5);
    let e = capture(&tree, &tree.rest_state(), &target, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("say which one with ee="), "{e}");
}

/// The capture is O(n) and Capture is a plain value: cloning it keeps everything.
#[test]
fn capture_is_a_value() {
    let (_, arm) = arms().remove(1);
    let mut rng = Rng::new(5);
    let x = random_arm_state(&arm, &mut rng);
    let target = random_target(&arm, &x, 0, &mut rng);
    let c: Capture = capture(&arm, &x, &target, None).unwrap();
    let d = c.clone();
    assert_eq!(c.x, d.x);
    assert_eq!(c.impulse, d.impulse);
    let again = capture(&arm, &x, &target, None).unwrap();
    assert_eq!(again.x, c.x, "deterministic");
}

/// With reaction wheels spinning on the bus: momentum (spin included) and energy balance across
/// the capture as without (same bounds, same reasons), the wheels keep their absolute axial rate
/// `a·ω_B + Ω` (no impulsive torque about their axes), and the combined arm keeps the wheels.
#[test]
fn a_capture_with_reaction_wheels_keeps_momentum_and_the_wheels_spin() {
    let mut rng = Rng::new(2926);
    let robot = Robot::space_arm();
    let wheels: Vec<Wheel> = (0..4)
        .map(|w| {
            let phi = std::f64::consts::FRAC_PI_2 * w as f64 + 0.4;
            let (side, tilt) = ((2.0f64 / 3.0).sqrt(), (1.0f64 / 3.0).sqrt());
            Wheel {
                axis: [side * phi.cos(), side * phi.sin(), tilt],
                position: [0.4 * phi.cos(), 0.4 * phi.sin(), -0.45],
                mass: 8.0,
                spin_inertia: 0.2,
                transverse_inertia: 0.12,
                max_torque: 1.0,
                max_speed: 1e3,
                friction: 0.0,
            }
        })
        .collect();
    let arm = FlexibleArm::new(robot.clone(), random_joints(robot.dof(), 7))
        .unwrap()
        .with_wheels(ReactionWheels::new(wheels).unwrap())
        .unwrap();
    let layout = arm.layout();
    for trial in 0..4 {
        let mut x = random_arm_state(
            &FlexibleArm::new(robot.clone(), arm.joints().clone()).unwrap(),
            &mut rng,
        );
        x.extend(rng.vector(4, -300.0, 300.0));
        let target = random_target(&arm, &x, 0, &mut rng);
        let before_arm = arm.momentum(&mut arm.workspace(), &x);
        let before = add(&before_arm, &target.momentum());
        let scale = norm(&before_arm) + norm(&target.momentum());
        let c = capture(&arm, &x, &target, None).unwrap();
        assert_eq!(
            c.arm.layout(),
            layout,
            "trial {trial}: the wheels stay on the combined arm"
        );
        let after = c.arm.momentum(&mut c.arm.workspace(), &c.x);
        let err = norm(&sub(&after, &before)) / scale;
        assert!(err < 1e-12, "trial {trial}: momentum off by {err:e}");
        let e_before = arm.energy(&mut arm.workspace(), &x) + target.kinetic_energy();
        let e_after = c.arm.energy(&mut c.arm.workspace(), &c.x);
        let e_err = (e_before - e_after - c.energy_loss).abs() / e_before;
        assert!(e_err < 1e-12, "trial {trial}: ΔE − loss off by {e_err:e}");
        let omega = |x: &[f64]| Vec3::from_column_slice(&x[layout.base_twist()][..3]);
        assert!(
            (omega(&c.x) - omega(&x)).norm() > 1e-6,
            "trial {trial}: the bus rate changed"
        );
        for (w, wheel) in arm.wheels().unwrap().wheels().iter().enumerate() {
            let a = Vec3::from(wheel.axis);
            let (s0, s1) = (x[layout.wheel_speed()][w], c.x[layout.wheel_speed()][w]);
            let axial = |s: f64, x: &[f64]| a.dot(&omega(x)) + s;
            assert!(
                (axial(s1, &c.x) - axial(s0, &x)).abs() <= 1e-12 * axial(s0, &x).abs().max(1.0),
                "trial {trial}, wheel {w}"
            );
        }
    }
}
