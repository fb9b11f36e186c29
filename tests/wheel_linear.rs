//! The linear model of an arm with reaction wheels: the Jacobians of `derivative` against
//! central differences (the reference), the wheel-torque inputs, the saturation's slope, and the
//! attitude loop's modes against closed forms and a simulation.

use nalgebra::DMatrix;
use orbitflex::flex::{ReactionWheels, Wheel};
use orbitflex::testing::{random_chain, random_joints, random_tree_all_leaves, Rng};
use orbitflex::{FlexibleArm, Inputs, Loads, Robot, StateSpec};

/// `k` wheels with random unit axes (not aligned with the base axes), centres within 0.8 m,
/// 1–10 kg, `J_s` 0.01–0.1 kg·m², `J_t` in `[J_s/2, J_s]`, friction 0–0.01 N·m·s, limits wide
/// enough that the torques here pass unclipped.
fn random_wheels(k: usize, seed: u64) -> ReactionWheels {
    let mut rng = Rng::new(seed);
    let wheels = (0..k)
        .map(|_| {
            let spin = rng.range(0.01, 0.1);
            let a = rng.unit();
            Wheel {
                axis: [a.x, a.y, a.z],
                position: [
                    rng.range(-0.8, 0.8),
                    rng.range(-0.8, 0.8),
                    rng.range(-0.8, 0.8),
                ],
                mass: rng.range(1.0, 10.0),
                spin_inertia: spin,
                transverse_inertia: rng.range(0.5 * spin, spin),
                max_torque: 10.0,
                max_speed: 1e4,
                friction: rng.range(0.0, 0.01),
            }
        })
        .collect();
    ReactionWheels::new(wheels).unwrap()
}

fn wheeled(robot: Robot, k: usize, seed: u64) -> FlexibleArm {
    let n = robot.dof();
    FlexibleArm::new(robot, random_joints(n, seed))
        .unwrap()
        .with_wheels(random_wheels(k, seed + 7))
        .unwrap()
}

/// A random state: angles ±1, small deflections, rates ±0.5, base twist ±0.3, wheel speeds
/// ±`speed`.
fn state(arm: &FlexibleArm, seed: u64, speed: f64) -> Vec<f64> {
    let n = arm.dof();
    let mut rng = Rng::new(seed + 3);
    let q = rng.vector(n, -1.0, 1.0);
    let theta: Vec<f64> = q.iter().map(|v| v + rng.range(-0.05, 0.05)).collect();
    let (qd, td, twist) = (
        rng.vector(n, -0.5, 0.5),
        rng.vector(n, -0.5, 0.5),
        rng.vector(6, -0.3, 0.3),
    );
    let pose = [0.4, -0.3, 0.2, 0.2, -0.4, 0.3, 0.8];
    let mut x = arm
        .state(&StateSpec {
            q: Some(&q),
            theta: Some(&theta),
            qd: Some(&qd),
            theta_dot: Some(&td),
            base_pose: Some(&pose),
            base_twist: Some(&twist),
        })
        .unwrap();
    let k = arm.layout().wheels;
    x[arm.layout().wheel_speed()].copy_from_slice(&rng.vector(k, -speed, speed));
    x
}

/// The dynamic part `ẋ[7..]` (every block after the pose: additive in the tangent, so its
/// derivative along `x ⊕ dx` is row `6 + i` of `F`).
fn rates(arm: &FlexibleArm, x: &[f64], inputs: &Inputs) -> Vec<f64> {
    let mut xdot = vec![0.0; x.len()];
    arm.derivative(&mut arm.workspace(), x, inputs, &mut xdot)
        .unwrap();
    xdot[7..].to_vec()
}

/// `F[6.., :]`, `G_u`, `G_W` of `derivative_jacobians` against central differences of
/// `derivative` with wheels, on chains and a tree, wheel axes off the base axes, friction, wheel
/// speeds up to 300 rad/s, the bus turning, and wheel torques applied.
///
/// Bound: central differences with step `h` err by `h²/6 |∂³ẋ|` (truncation) plus
/// `ε |ẋ| / h` (rounding). `ẋ` is at most quadratic in the rates (gyroscopic `ω × J_s Ω a`,
/// Coriolis), smooth in the angles with derivatives of the order of `|ẋ|` itself, so with
/// `h = 1e-5` (angles and rates of order 1; wheel speeds scaled by `h Ω_max`) the error is
/// `≲ 1e-10 |ẋ| + 2e-11 |ẋ|`; relative to the largest entry of the Jacobian (≥ 1 here, the
/// identity blocks), `1e-7` holds with three orders to spare for the spread of entries.
#[test]
fn wheel_jacobians_equal_central_differences() {
    let robots: Vec<(Robot, &str)> = vec![
        (random_chain(1, 4), "chain 1"),
        (random_chain(4, 5), "chain 4"),
        (
            random_tree_all_leaves(&[0, 0, 1, 2, 1, 4, 0, 6], 6),
            "tree 7",
        ),
    ];
    for (seed, (robot, label)) in robots.into_iter().enumerate() {
        let seed = seed as u64 + 1;
        let k = [1, 3, 4][seed as usize - 1];
        let arm = wheeled(robot, k, seed);
        let n = arm.dof();
        let x = state(&arm, seed, 300.0);
        let mut rng = Rng::new(seed + 40);
        let u = rng.vector(n, -2.0, 2.0);
        let (fb, wheel_torque) = (rng.vector(6, -2.0, 2.0), rng.vector(k, -0.5, 0.5));
        let inputs = Inputs {
            u: &u,
            loads: Loads::from_slices(Some(&fb), None).unwrap(),
            wheel_torque: &wheel_torque,
        };
        let j = arm
            .derivative_jacobians(&mut arm.workspace(), &x, &inputs)
            .unwrap();
        let t = arm.tangent_size();
        assert_eq!(t, 12 + 4 * n + k);
        assert_eq!(j.wheel_torque.shape(), (t, k));
        let h = 1e-5;
        let rows = t - 6;
        let mut fd = DMatrix::zeros(rows, t);
        for c in 0..t {
            let mut dx = vec![0.0; t];
            // wheel speeds are hundreds of rad/s: a relative step
            dx[c] = if c >= 12 + 4 * n { h * 300.0 } else { h };
            let plus = rates(&arm, &arm.integrate(&x, &dx).unwrap(), &inputs);
            let step = dx[c];
            dx[c] = -step;
            let minus = rates(&arm, &arm.integrate(&x, &dx).unwrap(), &inputs);
            for r in 0..rows {
                fd[(r, c)] = (plus[r] - minus[r]) / (2.0 * step);
            }
        }
        let got = j.x.rows(6, rows).into_owned();
        let err = (&got - &fd).amax() / fd.amax().max(1.0);
        assert!(err < 1e-7, "{label}: F {err:e}");
        // the wheel torque columns: exact in the torque (linear within the limits)
        let mut fd_w = DMatrix::zeros(rows, k);
        for c in 0..k {
            let mut w = wheel_torque.clone();
            w[c] += 1e-3;
            let plus = rates(
                &arm,
                &x,
                &Inputs {
                    wheel_torque: &w,
                    ..inputs
                },
            );
            w[c] -= 2e-3;
            let minus = rates(
                &arm,
                &x,
                &Inputs {
                    wheel_torque: &w,
                    ..inputs
                },
            );
            for r in 0..rows {
                fd_w[(r, c)] = (plus[r] - minus[r]) / 2e-3;
            }
        }
        let got_w = j.wheel_torque.rows(6, rows).into_owned();
        let err = (&got_w - &fd_w).amax() / fd_w.amax();
        assert!(err < 1e-9, "{label}: G_W {err:e}");
        // and of the motor torques (they reach the wheels only through nothing: θ̈ rows)
        assert_eq!(j.u.rows(12 + 4 * n, k).amax(), 0.0);
    }
}

/// A command beyond `max_torque`, or one that would speed up a wheel at `max_speed`, is cut:
/// its column of `G_W` is zero; a command that slows the wheel down passes (slope 1).
#[test]
fn saturated_wheels_have_no_torque_slope() {
    let arm = wheeled(random_chain(2, 9), 2, 9);
    let mut x = state(&arm, 9, 10.0);
    let speed = arm.layout().wheel_speed();
    x[speed.start] = 1e4; // wheel 0 at max_speed
    x[speed.start + 1] = 5.0;
    let u = vec![0.0; 2];
    for (command, zero) in [([0.1, 20.0], [true, true]), ([-0.1, 1.0], [false, false])] {
        let inputs = Inputs {
            wheel_torque: &command,
            ..Inputs::torques(&u)
        };
        let j = arm
            .derivative_jacobians(&mut arm.workspace(), &x, &inputs)
            .unwrap();
        for (w, zero) in zero.into_iter().enumerate() {
            assert_eq!(j.wheel_torque.column(w).amax() == 0.0, zero, "{command:?}");
        }
    }
}
