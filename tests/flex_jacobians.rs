//! The flexible arm's Jacobians (continuous time and one RK4 step) against central differences
//! on the tangent space, and the tangent space's own identities.

use nalgebra::DMatrix;
use orbitflex::testing::{random_chain, random_joints, random_tree, Rng, TREE_THREE_ARMS};
use orbitflex::{FlexibleArm, Inputs, Loads, Robot, StateSpec};

fn rel(got: &DMatrix<f64>, want: &DMatrix<f64>) -> f64 {
    (got - want).amax() / want.amax().max(1.0)
}

fn arm(robot: Robot, seed: u64) -> FlexibleArm {
    let n = robot.dof();
    FlexibleArm::new(robot, random_joints(n, seed)).unwrap()
}

fn state(arm: &FlexibleArm, seed: u64) -> Vec<f64> {
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
    arm.state(&StateSpec {
        q: Some(&q),
        theta: Some(&theta),
        qd: Some(&qd),
        theta_dot: Some(&td),
        base_pose: Some(&pose),
        base_twist: Some(&twist),
    })
    .unwrap()
}

struct In {
    u: Vec<f64>,
    fb: Vec<f64>,
    f: Vec<f64>,
}

impl In {
    fn new(n: usize, seed: u64) -> Self {
        let mut rng = Rng::new(seed + 11);
        Self {
            u: rng.vector(n, -3.0, 3.0),
            fb: rng.vector(6, -3.0, 3.0),
            f: rng.vector(6, -3.0, 3.0),
        }
    }
    fn inputs(&self) -> Inputs<'_> {
        Inputs {
            u: &self.u,
            loads: Loads::from_slices(Some(&self.fb), Some(&self.f)).unwrap(),
            wheel_torque: &[],
        }
    }
}

/// Central differences of a map from the state's tangent at `x` to a tangent (at `base`).
fn tangent_fd(
    arm: &FlexibleArm,
    x: &[f64],
    h: f64,
    mut eval: impl FnMut(&[f64]) -> Vec<f64>,
) -> DMatrix<f64> {
    let t = arm.tangent_size();
    let mut out = DMatrix::zeros(t, t);
    for k in 0..t {
        let mut dx = vec![0.0; t];
        dx[k] = h;
        let plus = eval(&arm.integrate(x, &dx).unwrap());
        dx[k] = -h;
        let minus = eval(&arm.integrate(x, &dx).unwrap());
        for r in 0..t {
            out[(r, k)] = (plus[r] - minus[r]) / (2.0 * h);
        }
    }
    out
}

/// Central differences of a map from an input vector to a tangent.
fn input_fd(
    v: &[f64],
    rows: usize,
    h: f64,
    mut eval: impl FnMut(&[f64]) -> Vec<f64>,
) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(rows, v.len());
    let mut p = v.to_vec();
    for k in 0..v.len() {
        p[k] = v[k] + h;
        let plus = eval(&p);
        p[k] = v[k] - h;
        let minus = eval(&p);
        p[k] = v[k];
        for r in 0..rows {
            out[(r, k)] = (plus[r] - minus[r]) / (2.0 * h);
        }
    }
    out
}

fn check_step(arm: &FlexibleArm, seed: u64, dt: f64, label: &str) {
    let x = state(arm, seed);
    let inp = In::new(arm.dof(), seed);
    let mut ws = arm.workspace();
    let step = |x: &[f64], u: &[f64], fb: &[f64], f: &[f64]| -> Vec<f64> {
        let mut ws = arm.workspace();
        let mut y = x.to_vec();
        let inputs = Inputs {
            u,
            loads: Loads::from_slices(Some(fb), Some(f)).unwrap(),
            wheel_torque: &[],
        };
        arm.step(&mut ws, &mut y, dt, &inputs).unwrap();
        y
    };
    let nominal = step(&x, &inp.u, &inp.fb, &inp.f);
    let to_tangent = |y: Vec<f64>| arm.difference(&nominal, &y).unwrap();
    let j = arm.step_jacobians(&mut ws, &x, dt, &inp.inputs()).unwrap();
    let h = 1e-6;
    let t = arm.tangent_size();
    let a = tangent_fd(arm, &x, h, |y| to_tangent(step(y, &inp.u, &inp.fb, &inp.f)));
    assert!(rel(&j.x, &a) < 1e-6, "{label}: A {}", rel(&j.x, &a));
    let b = input_fd(&inp.u, t, h, |u| to_tangent(step(&x, u, &inp.fb, &inp.f)));
    assert!(rel(&j.u, &b) < 1e-6, "{label}: B_u {}", rel(&j.u, &b));
    let b = input_fd(&inp.fb, t, h, |fb| to_tangent(step(&x, &inp.u, fb, &inp.f)));
    assert!(
        rel(&j.base_wrench, &b) < 1e-6,
        "{label}: B_fB {}",
        rel(&j.base_wrench, &b)
    );
    let b = input_fd(&inp.f, t, h, |f| to_tangent(step(&x, &inp.u, &inp.fb, f)));
    assert!(
        rel(&j.ee_wrench, &b) < 1e-6,
        "{label}: B_f {}",
        rel(&j.ee_wrench, &b)
    );
}

fn check_derivative(arm: &FlexibleArm, seed: u64, label: &str) {
    let x = state(arm, seed);
    let inp = In::new(arm.dof(), seed);
    let mut ws = arm.workspace();
    let j = arm
        .derivative_jacobians(&mut ws, &x, &inp.inputs())
        .unwrap();
    // The error-state derivative of a tangent perturbation: d/dt (x̄ ⊖ ... ) is the derivative of
    // difference(x̄(t), x(t)) at t = 0 for x(0) = x̄(0) ⊕ dx; by finite differences in time over
    // a tiny RK4 step, F dx = (difference(x̄(ε), x(ε)) − dx)/ε to O(ε).
    let eps = 1e-7;
    let t = arm.tangent_size();
    let flow = |y: &[f64]| -> Vec<f64> {
        let mut ws = arm.workspace();
        let mut z = y.to_vec();
        arm.step(&mut ws, &mut z, eps, &inp.inputs()).unwrap();
        z
    };
    let bar = flow(&x);
    let mut f = DMatrix::zeros(t, t);
    let h = 1e-4;
    for k in 0..t {
        let mut dx = vec![0.0; t];
        dx[k] = h;
        let plus = arm
            .difference(&bar, &flow(&arm.integrate(&x, &dx).unwrap()))
            .unwrap();
        dx[k] = -h;
        let minus = arm
            .difference(&bar, &flow(&arm.integrate(&x, &dx).unwrap()))
            .unwrap();
        for r in 0..t {
            let dflow = (plus[r] - minus[r]) / (2.0 * h);
            f[(r, k)] = (dflow - if r == k { 1.0 } else { 0.0 }) / eps;
        }
    }
    assert!(rel(&j.x, &f) < 1e-4, "{label}: F {}", rel(&j.x, &f));
    // The δφ block is −[ω_B]× (the perturbation lives in the turning base frame).
    let omega = &x[arm.layout().base_twist()][..3];
    assert!((j.x[(3, 4)] - omega[2]).abs() < 1e-14 && (j.x[(4, 3)] + omega[2]).abs() < 1e-14);
    // one step's Jacobian is I + dt F + O(dt²)
    let dt = 1e-5;
    let a = arm.step_jacobians(&mut ws, &x, dt, &inp.inputs()).unwrap();
    let first_order = DMatrix::identity(t, t) + &j.x * dt;
    assert!(
        (&a.x - first_order).amax() < 1e-3 * dt * j.x.amax(),
        "{label}: A − (I + dt F)"
    );
}

#[test]
fn step_jacobians_equal_central_differences() {
    for (n, seed) in [(1, 1), (3, 2), (5, 3)] {
        check_step(
            &arm(random_chain(n, seed), seed),
            seed,
            2e-3,
            &format!("chain n={n}"),
        );
    }
    check_step(&arm(Robot::space_arm(), 4), 4, 1e-3, "space arm");
    check_step(
        &arm(random_tree(TREE_THREE_ARMS, 5), 5),
        5,
        2e-3,
        "three-arm tree",
    );
    // above 40 joints the stage products are directional derivatives, not dense products
    check_step(&arm(random_chain(42, 6), 6), 6, 2e-3, "chain n=42");
}

#[test]
fn derivative_jacobians_are_the_error_state_linearisation() {
    check_derivative(&arm(random_chain(4, 5), 5), 5, "chain n=4");
    check_derivative(&arm(Robot::space_arm(), 6), 6, "space arm");
}

#[test]
fn integrate_and_difference_are_inverse() {
    let arm = arm(random_chain(3, 7), 7);
    let x = state(&arm, 7);
    let mut rng = Rng::new(8);
    for _ in 0..20 {
        let dx = rng.vector(arm.tangent_size(), -1.5, 1.5);
        let y = arm.integrate(&x, &dx).unwrap();
        let back = arm.difference(&x, &y).unwrap();
        let err = dx
            .iter()
            .zip(&back)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // rotations by more than π come back the short way; these stay within it
        assert!(err < 1e-12, "{err}");
        let again = arm.integrate(&x, &back).unwrap();
        let err = y
            .iter()
            .zip(&again)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-14, "{err}");
    }
}
