//! The flexible-joint simulator checked through the invariants of model §6.

use orbitflex::testing::{random_chain, Rng};
use orbitflex::{
    ArmWorkspace, Controller, FlexibleArm, FlexibleJoints, Inputs, Loads, MotorPD, RigidState,
    Robot, Schedule, StateSpec, Wrenches,
};

fn arm(n: usize, seed: u64, damping: f64, motor_damping: f64) -> FlexibleArm {
    let robot = random_chain(n, seed);
    let mut rng = Rng::new(seed);
    let joints = FlexibleJoints::new(
        rng.vector(n, 200.0, 800.0),
        rng.vector(n, 0.05, 0.2),
        vec![damping; n],
        vec![motor_damping; n],
    )
    .unwrap();
    FlexibleArm::new(robot, joints).unwrap()
}

fn moving_state(arm: &FlexibleArm, seed: u64) -> Vec<f64> {
    let n = arm.robot().dof();
    let mut rng = Rng::new(seed + 7);
    let q = rng.vector(n, -1.0, 1.0);
    let theta: Vec<f64> = q.iter().map(|v| v + rng.range(-0.05, 0.05)).collect();
    let (qd, theta_dot, twist) = (
        rng.vector(n, -0.5, 0.5),
        rng.vector(n, -0.5, 0.5),
        rng.vector(6, -0.3, 0.3),
    );
    arm.state(&StateSpec {
        q: Some(&q),
        theta: Some(&theta),
        qd: Some(&qd),
        theta_dot: Some(&theta_dot),
        base_pose: Some(&[0.3, -0.2, 0.1, 0.1, 0.2, -0.3, 0.9]),
        base_twist: Some(&twist),
    })
    .unwrap()
}

/// Time-varying torques, a different sine per joint.
struct Sines;
impl Controller for Sines {
    fn output(&mut self, _: usize, t: f64, _: &[f64], u: &mut [f64]) -> orbitflex::Result<()> {
        for (i, ui) in u.iter_mut().enumerate() {
            *ui = 3.0 * (2.0 * t + i as f64).sin();
        }
        Ok(())
    }
}

/// Momentum in the inertial frame is not a linear function of the state, so RK4 keeps it only
/// to its truncation error: the drift must fall like dt⁴ until it reaches round-off.
#[test]
fn momentum_is_constant_when_free_floating_with_any_torques() {
    let arm = arm(5, 1, 0.5, 0.2);
    let x0 = moving_state(&arm, 1);
    let drift = |dt: f64| {
        let traj = arm
            .simulate(&x0, dt, (1.0 / dt) as usize, &mut Sines, &Wrenches::ZERO)
            .unwrap();
        let h = traj.rows().momentum(&arm);
        let scale = h[..6].iter().map(|v| v.abs()).fold(1.0, f64::max);
        let worst = (6..h.len())
            .map(|k| (h[k] - h[k % 6]).abs())
            .fold(0.0, f64::max);
        worst / scale
    };
    let (coarse, fine, finest) = (drift(1e-3), drift(5e-4), drift(1.25e-4));
    assert!(coarse < 1e-9, "relative momentum drift {coarse:e}");
    assert!(
        coarse / fine > 12.0,
        "drift should fall like dt⁴: {coarse:e} -> {fine:e}"
    );
    assert!(finest < 1e-12, "round-off level at small dt: {finest:e}");
    // and a base wrench does change it: the test can fail
    let push = Schedule::Constant(vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0]);
    let traj = arm
        .simulate(
            &x0,
            1e-3,
            100,
            &mut Sines,
            &Wrenches {
                base: push,
                ee: Schedule::Zero,
                wheel_torque: orbitflex::Schedule::Zero,
            },
        )
        .unwrap();
    let h2 = traj.rows().momentum(&arm);
    let r0 = orbitflex::spatial::quaternion_to_rotation(&x0[3..7]);
    // 1 N along the base x axis for 0.1 s: the base turns slowly, so nearly R_B e_x × 0.1 N s
    let expected = r0.column(0) * 0.1;
    let got = nalgebra::Vector3::new(
        h2[600 + 3] - h2[3],
        h2[600 + 4] - h2[4],
        h2[600 + 5] - h2[5],
    );
    assert!(
        (got - expected).norm() < 0.1 * 0.1,
        "impulse {got} vs {expected}"
    );
}

#[test]
fn energy_is_conserved_without_input_or_damping_up_to_rk4_error() {
    let arm = arm(4, 2, 0.0, 0.0);
    let x0 = moving_state(&arm, 2);
    let mut ws = ArmWorkspace::new(&arm);
    let e0 = arm.energy(&mut ws, &x0);
    let drift = |dt: f64| {
        let steps = (0.5 / dt) as usize;
        let traj = arm
            .simulate(&x0, dt, steps, &mut Schedule::Zero, &Wrenches::ZERO)
            .unwrap();
        let e = traj.rows().energy(&arm);
        e.iter().map(|v| (v - e0).abs()).fold(0.0, f64::max)
    };
    let (coarse, fine) = (drift(2e-3), drift(1e-3));
    assert!(fine < 1e-6 * e0, "energy drift {fine:e} of {e0}");
    // RK4's energy error falls with dt like dt⁴ (a correct RK4, not a lucky one).
    assert!(coarse / fine > 10.0, "energy drift ratio {}", coarse / fine);
}

/// Power `dE/dt` from model §6.3 at state `x` with inputs.
fn power(arm: &FlexibleArm, x: &[f64], u: &[f64], fb: &[f64], f: &[f64]) -> f64 {
    let l = arm.layout();
    let p = arm.joints();
    let (q, qd, td) = (&x[l.q()], &x[l.qd()], &x[l.theta_dot()]);
    let mut pw = 0.0;
    for i in 0..l.n {
        pw += u[i] * td[i]
            - p.damping[i] * (td[i] - qd[i]).powi(2)
            - p.motor_damping[i] * td[i] * td[i];
    }
    let v_b = &x[l.base_twist()];
    pw += fb.iter().zip(v_b).map(|(a, b)| a * b).sum::<f64>();
    // V_{n+1} = Φ_{n+1,B} V_B + J q̇
    let j = arm.robot().ee_jacobian(q, None).unwrap();
    let phi = arm.robot().ee_base_operator(q, None).unwrap();
    let v_ee = phi * nalgebra::Vector6::from_column_slice(v_b)
        + nalgebra::Vector6::from_column_slice(
            (j * nalgebra::DVector::from_column_slice(qd)).as_slice(),
        );
    pw - f.iter().zip(v_ee.iter()).map(|(a, b)| a * b).sum::<f64>()
}

#[test]
fn power_balance_holds_pointwise_with_all_inputs() {
    let arm = arm(6, 3, 0.7, 0.3);
    let mut ws = ArmWorkspace::new(&arm);
    let mut rng = Rng::new(3);
    for seed in 0..5 {
        let x = moving_state(&arm, seed);
        let (u, fb, f) = (
            rng.vector(6, -5.0, 5.0),
            rng.vector(6, -5.0, 5.0),
            rng.vector(6, -5.0, 5.0),
        );
        let mut xdot = vec![0.0; x.len()];
        let loads = Loads::from_slices(Some(&fb), Some(&f)).unwrap();
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
        let de =
            (arm.energy(&mut ws, &shifted(1.0)) - arm.energy(&mut ws, &shifted(-1.0))) / (2.0 * h);
        let p = power(&arm, &x, &u, &fb, &f);
        assert!(
            (de - p).abs() < 1e-6 * (1.0 + p.abs()),
            "dE/dt {de} vs power {p}"
        );
    }
}

#[test]
fn power_balance_integrates_along_a_run() {
    let arm = arm(4, 4, 0.5, 0.2);
    let x0 = moving_state(&arm, 4);
    let n = 4;
    let residual = |dt: f64| {
        let steps = (0.4 / dt) as usize;
        let mut rng = Rng::new(11);
        let u_table: Vec<f64> = (0..steps)
            .flat_map(|k| (0..n).map(move |i| 2.0 * ((k as f64) * dt * 3.0 + i as f64).sin()))
            .collect();
        let fb: Vec<f64> = rng.vector(6, -2.0, 2.0);
        let f: Vec<f64> = rng.vector(6, -2.0, 2.0);
        let mut u = Schedule::Table {
            values: u_table.clone(),
            width: n,
        };
        let traj = arm
            .simulate(
                &x0,
                dt,
                steps,
                &mut u,
                &Wrenches {
                    base: Schedule::Constant(fb.clone()),
                    ee: Schedule::Constant(f.clone()),
                    wheel_torque: orbitflex::Schedule::Zero,
                },
            )
            .unwrap();
        let e = traj.rows().energy(&arm);
        let mut work = 0.0;
        for k in 0..steps {
            let uk = &u_table[k * n..(k + 1) * n];
            work += 0.5
                * dt
                * (power(&arm, traj.state(k), uk, &fb, &f)
                    + power(&arm, traj.state(k + 1), uk, &fb, &f));
        }
        ((e[steps] - e[0]) - work).abs()
    };
    let (coarse, fine) = (residual(2e-3), residual(1e-3));
    assert!(fine < 1e-5, "energy balance residual {fine:e}");
    // trapezoid rule: second order
    assert!(coarse / fine > 3.0, "ratio {}", coarse / fine);
}

#[test]
fn rk4_error_falls_sixteenfold_per_halving() {
    let arm = arm(3, 5, 0.3, 0.1);
    let x0 = moving_state(&arm, 5);
    let t_end: f64 = 0.4;
    let run = |dt: f64| {
        let steps = (t_end / dt).round() as usize;
        let traj = arm
            .simulate(
                &x0,
                dt,
                steps,
                &mut Schedule::Constant(vec![1.0, -2.0, 0.5]),
                &Wrenches::ZERO,
            )
            .unwrap();
        traj.state(steps).to_vec()
    };
    let reference = run(t_end / 10240.0);
    let err = |dt: f64| {
        run(dt)
            .iter()
            .zip(&reference)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    };
    let errors: Vec<f64> = [t_end / 160.0, t_end / 320.0, t_end / 640.0]
        .iter()
        .map(|&dt| err(dt))
        .collect();
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (12.0..20.0).contains(&ratio),
            "error ratio {ratio} (errors {errors:?})"
        );
    }
}

/// Very stiff joints with small motor inertia behave like the rigid arm driven by `τ = u`.
#[test]
fn stiff_joints_track_the_rigid_arm() {
    let robot = random_chain(3, 6);
    let u = [0.8, -0.5, 0.3];
    let t_end: f64 = 0.3;
    // Rigid reference: RK4 on (q, V_B, q̇) with the rigid forward dynamics, tiny steps.
    let rigid = {
        let dt = 1e-4;
        let f = |q: &[f64], v: &[f64], qd: &[f64]| -> Vec<f64> {
            robot
                .forward_dynamics(
                    &RigidState::new(q, v, qd),
                    &u,
                    &Loads::ZERO,
                    orbitflex::Method::Recursive,
                )
                .unwrap()
                .as_slice()
                .to_vec()
        };
        let (mut q, mut v, mut qd) = (vec![0.0; 3], vec![0.0; 6], vec![0.0; 3]);
        for _ in 0..(t_end / dt).round() as usize {
            // state z = [q, V, q̇]; V's derivative: base-frame components of the twist
            let deriv = |q: &[f64], v: &[f64], qd: &[f64]| -> Vec<f64> {
                let a = f(q, v, qd);
                let w = nalgebra::Vector3::new(v[0], v[1], v[2]);
                let lin = nalgebra::Vector3::new(v[3], v[4], v[5]);
                let vdot = nalgebra::Vector3::new(a[3], a[4], a[5]) - w.cross(&lin);
                let mut out = qd.to_vec();
                out.extend_from_slice(&a[0..3]);
                out.extend_from_slice(vdot.as_slice());
                out.extend_from_slice(&a[6..9]);
                out
            };
            let z: Vec<f64> = q.iter().chain(&v).chain(&qd).copied().collect();
            let split = |z: &[f64]| (z[0..3].to_vec(), z[3..9].to_vec(), z[9..12].to_vec());
            let k1 = {
                let (a, b, c) = split(&z);
                deriv(&a, &b, &c)
            };
            let z2: Vec<f64> = z.iter().zip(&k1).map(|(a, k)| a + 0.5 * dt * k).collect();
            let k2 = {
                let (a, b, c) = split(&z2);
                deriv(&a, &b, &c)
            };
            let z3: Vec<f64> = z.iter().zip(&k2).map(|(a, k)| a + 0.5 * dt * k).collect();
            let k3 = {
                let (a, b, c) = split(&z3);
                deriv(&a, &b, &c)
            };
            let z4: Vec<f64> = z.iter().zip(&k3).map(|(a, k)| a + dt * k).collect();
            let k4 = {
                let (a, b, c) = split(&z4);
                deriv(&a, &b, &c)
            };
            let z: Vec<f64> = (0..12)
                .map(|i| z[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
                .collect();
            (q, v, qd) = split(&z);
        }
        q
    };
    let deviation = |k: f64, j: f64| {
        let d = 2.0 * (k * j).sqrt();
        let arm = FlexibleArm::new(
            robot.clone(),
            FlexibleJoints::uniform(3, k, j, d, 0.0).unwrap(),
        )
        .unwrap();
        let dt = 0.2
            * arm
                .rk4_stability_limit(&arm.rest_state(), &Schedule::Zero)
                .unwrap()
                .dt
                .min(j / d);
        let steps = (t_end / dt).ceil() as usize;
        let dt = t_end / steps as f64;
        let traj = arm
            .simulate(
                &arm.rest_state(),
                dt,
                steps,
                &mut Schedule::Constant(u.to_vec()),
                &Wrenches::ZERO,
            )
            .unwrap();
        let q = &traj.state(steps)[7..10];
        q.iter()
            .zip(&rigid)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    };
    // The rigid limit needs k → ∞ and j → 0: the motor inertia adds j q̈ to the link's load.
    let (soft, stiff) = (deviation(1e4, 1e-3), deviation(1e5, 1e-4));
    let travel = rigid.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(
        stiff < 2e-2 * travel,
        "deviation {stiff} of travel {travel}"
    );
    assert!(
        soft / stiff > 3.0,
        "deviation should shrink towards the rigid limit: {soft} -> {stiff}"
    );
}

#[test]
fn motor_pd_drives_the_motor_to_its_reference() {
    let robot = Robot::space_arm();
    let joints = FlexibleJoints::uniform(7, 1e4, 1.0, 5.0, 1.0).unwrap();
    let arm = FlexibleArm::new(robot, joints).unwrap();
    let target = vec![0.1; 7];
    let mut pd = MotorPD::new(
        vec![2000.0; 7],
        vec![800.0; 7],
        Schedule::Constant(target.clone()),
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let x0 = arm.rest_state();
    let traj = arm
        .simulate(&x0, 2e-3, 15000, &mut pd, &Wrenches::ZERO)
        .unwrap();
    let theta = &traj.state(15000)[14..21];
    for (a, b) in theta.iter().zip(&target) {
        assert!((a - b).abs() < 5e-3, "θ {a} vs reference {b}");
    }
}

#[test]
fn diverging_run_keeps_the_finite_steps() {
    let arm = arm(3, 8, 0.0, 0.0);
    let x0 = moving_state(&arm, 8);
    let dt = 20.0 * arm.rk4_stability_limit(&x0, &Schedule::Zero).unwrap().dt;
    let failure = arm
        .simulate(&x0, dt, 10_000, &mut Schedule::Zero, &Wrenches::ZERO)
        .unwrap_err();
    let message = failure.error.to_string();
    assert!(
        message.contains("step") && message.contains("diverged"),
        "{message}"
    );
    assert!(!failure.trajectory.is_empty());
    assert!(failure.trajectory.x.iter().all(|v| v.is_finite()));
    assert!(failure.trajectory.len() < 10_001);
}

#[test]
fn joint_parameters_from_toml() {
    let robot = Robot::space_arm();
    let names = robot.joint_names();
    let text = "[defaults]\nstiffness = 1e4\nmotor_inertia = 0.5\n[joints.elbow_pitch]\nstiffness = 2e3\ngear_ratio = 100.0\nrotor_inertia = 2e-5\ndamping = 3.0\n";
    let j = FlexibleJoints::from_toml_str(text, &names, "test").unwrap();
    let e = names.iter().position(|n| *n == "elbow_pitch").unwrap();
    assert_eq!(j.stiffness[e], 2e3);
    assert!((j.motor_inertia[e] - 0.2).abs() < 1e-12);
    assert_eq!(j.damping[e], 3.0);
    assert_eq!(j.stiffness[0], 1e4);
    let err = FlexibleJoints::from_toml_str("[joints.nope]\nstiffness = 1.0\n", &names, "test")
        .unwrap_err();
    assert!(err.to_string().contains("nope"), "{err}");
    let err = FlexibleJoints::from_toml_str("[defaults]\nmotor_inertia = 1.0\n", &names, "test")
        .unwrap_err();
    assert!(err.to_string().contains("stiffness"), "{err}");
    // a syntax error is one line: where (line, column of the offending character) and what
    let err = FlexibleJoints::from_toml_str("[defaults]\nstiffness = [1,\n", &names, "j.toml")
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "j.toml: malformed joint-parameter TOML: line 2, column 16: invalid array, expected `]`"
    );
    let err = FlexibleJoints::from_toml_str(
        "[defaults]\nstiffness = 1e4\nstiffness = 2\n",
        &names,
        "j.toml",
    )
    .unwrap_err();
    assert!(!err.to_string().contains('\n'), "{err}");
    assert!(
        err.to_string()
            .starts_with("j.toml: malformed joint-parameter TOML: line 3, column 1: "),
        "{err}"
    );
}

/// A controller or input table of the wrong size is an error before the run starts, not a panic or
/// a silent misread.
#[test]
fn wrongly_sized_controllers_are_errors() {
    let arm = arm(4, 9, 0.1, 0.1);
    let x0 = arm.rest_state();
    let mut small_pd = MotorPD::new(
        vec![1.0; 3],
        vec![1.0; 3],
        Schedule::Constant(vec![0.1; 3]),
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let mut big_pd = MotorPD::new(
        vec![1.0; 5],
        vec![1.0; 5],
        Schedule::Constant(vec![0.1; 5]),
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let mut narrow = Schedule::Constant(vec![1.0; 3]);
    let mut short = Schedule::Table {
        values: vec![0.0; 4 * 5],
        width: 4,
    };
    for (u, what) in [
        (&mut small_pd as &mut dyn Controller, "MotorPD"),
        (&mut big_pd as &mut dyn Controller, "MotorPD"),
        (&mut narrow as &mut dyn Controller, "u"),
        (&mut short as &mut dyn Controller, "u"),
    ] {
        let failure = arm.simulate(&x0, 1e-3, 10, u, &Wrenches::ZERO).unwrap_err();
        let message = failure.error.to_string();
        assert!(
            message.contains(what) && message.contains("expected"),
            "{message}"
        );
    }
}

/// Regression (issue: the stability check missed a divergence): the built-in arm with its joints
/// and `MotorPD(kp = 2000, kd = 800)` diverges at dt = 1 ms (at step 195), but the earlier
/// per-joint estimate put the limit at 1.34 ms and gave no warning. The PD holds its torque over
/// each step, so its derivative gain acts like forward Euler on the motor pole; the sampled-data
/// analysis finds the true limit, and a run just inside it is stable while one just outside
/// diverges.
#[test]
fn stability_limit_catches_the_held_motor_pd_divergence() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let pd = MotorPD::new(
        vec![2000.0; 7],
        vec![800.0; 7],
        Schedule::Constant(vec![0.2; 7]),
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let x0 = arm.rest_state();
    let warning = orbitflex::integrate::stability_warning(&arm, &x0, 1e-3, &pd).unwrap();
    assert!(
        warning
            .as_deref()
            .is_some_and(|w| w.contains("closed loop")),
        "{warning:?}"
    );
    let limit = arm.rk4_stability_limit(&x0, &pd).unwrap();
    assert!(!limit.open_loop && !limit.estimated);
    // the motor pole −(k_d + β)/j of the light wrist motors dominates
    let j = FlexibleJoints::space_arm().motor_inertia[6];
    assert!(
        (limit.fastest_mode.re + 801.0 / j).abs() < 0.01 * 801.0 / j,
        "{limit:?}"
    );
    let run = |dt: f64| {
        let mut pd = pd.clone();
        arm.simulate(&x0, dt, 20_000, &mut pd, &Wrenches::ZERO)
    };
    assert!(
        run(0.98 * limit.dt).is_ok(),
        "unstable inside the limit {}",
        limit.dt
    );
    let failure = run(1.02 * limit.dt).unwrap_err();
    assert!(failure.error.to_string().contains("diverged"));
    let message = run(1e-3).unwrap_err().error.to_string();
    assert!(message.contains("step 195"), "{message}");
    // Open loop (no feedback), the joints alone allow a step ten times larger.
    let open = arm.rk4_stability_limit(&x0, &Schedule::Zero).unwrap();
    assert!(open.dt > 10.0 * limit.dt, "{open:?}");
}

/// Above the dense limit each joint is analysed alone. On a chain at the limit, moving, the
/// dense analysis is right (a run just inside it is stable, one just outside diverges) and the
/// joint-by-joint estimate is within 35 % of it.
#[test]
fn joint_by_joint_stability_estimate_tracks_the_dense_analysis() {
    use orbitflex::flex::stability::{joint_by_joint_limit, DENSE_LIMIT};
    let n = DENSE_LIMIT;
    let arm = arm(n, 21, 0.5, 0.2);
    let x0 = moving_state(&arm, 21);
    let pd = MotorPD::new(
        vec![300.0; n],
        vec![60.0; n],
        Schedule::Constant(x0[arm.layout().theta()].to_vec()),
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let dense = arm.rk4_stability_limit(&x0, &pd).unwrap();
    assert!(!dense.estimated);
    let (estimate, _) = joint_by_joint_limit(&arm, &x0, &pd.feedback()).unwrap();
    let ratio = estimate / dense.dt;
    assert!((0.65..1.35).contains(&ratio), "{dense:?} vs {estimate}");
    let run = |dt: f64| {
        let mut pd = pd.clone();
        arm.simulate(&x0, dt, (2.0 / dt) as usize, &mut pd, &Wrenches::ZERO)
    };
    assert!(run(0.98 * dense.dt).is_ok());
    assert!(run(1.05 * dense.dt).is_err());
}

/// `P(s) = A(s) + (k_p + k_d s) B(s)` of one joint under its PD (docs/model.md §5.3), and the
/// sum of its terms' magnitudes (for a relative check).
fn closed_loop_polynomial(
    [j, m, k, d, beta]: [f64; 5],
    kp: f64,
    kd: f64,
    s: nalgebra::Complex<f64>,
) -> (nalgebra::Complex<f64>, f64) {
    let b = s * s * m + s * d + k;
    let a = b * (s * s * j + s * beta) + s * s * m * (s * d + k);
    let p = a + (s * kd + kp) * b;
    let scale = a.norm() + (s * kd + kp).norm() * b.norm();
    (p, scale)
}

#[test]
fn motor_pd_gains_place_the_requested_poles_on_each_joint() {
    use nalgebra::Complex;
    for seed in [3, 11] {
        let arm = arm(5, seed, 0.5, 0.05);
        let q = Rng::new(seed).vector(5, -1.0, 1.0);
        // the link inertia: the diagonal of M_r − M_br M_b⁻¹ M_rb, by the operator form
        let ops =
            orbitflex::Operators::new(arm.robot(), &RigidState::at_rest(&q, &[0.0; 5])).unwrap();
        let h = &ops.m_r - &ops.m_br * ops.m_b.clone().try_inverse().unwrap() * &ops.m_rb;
        for (hz, zeta) in [(0.5, 0.7), (1.0, 1.0), (0.8, 1.5), (0.3, 0.2)] {
            let gains = arm.motor_pd_gains(&q, hz, zeta).unwrap();
            let w = 2.0 * std::f64::consts::PI * hz;
            // the roots of s² + 2ζω s + ω²
            let disc = Complex::new(zeta * zeta - 1.0, 0.0).sqrt() * w;
            let roots = [
                Complex::new(-zeta * w, 0.0) + disc,
                Complex::new(-zeta * w, 0.0) - disc,
            ];
            let p = arm.joints();
            for i in 0..5 {
                let m = gains.link_inertia[i];
                assert!(
                    (m - h[(i, i)]).abs() < 1e-12 * h[(i, i)],
                    "{m} vs {}",
                    h[(i, i)]
                );
                let params = [
                    p.motor_inertia[i],
                    m,
                    p.stiffness[i],
                    p.damping[i],
                    p.motor_damping[i],
                ];
                assert!(gains.kp[i] > 0.0 && gains.kd[i] >= 0.0);
                if gains.kd[i] == 0.0 {
                    // clamped: the friction alone damps more than asked
                    continue;
                }
                for s in roots {
                    let (value, scale) =
                        closed_loop_polynomial(params, gains.kp[i], gains.kd[i], s);
                    assert!(
                        value.norm() < 1e-12 * scale,
                        "{seed} {hz} {zeta} joint {i}: {value}"
                    );
                }
            }
        }
    }
}

#[test]
fn motor_pd_gains_become_the_rigid_rule_for_stiff_joints_and_refuse_what_a_spring_cannot_carry() {
    let robot = Robot::space_arm();
    let stiff =
        FlexibleJoints::new(vec![1e14; 7], vec![0.8; 7], vec![0.0; 7], vec![0.3; 7]).unwrap();
    let arm = FlexibleArm::new(robot.clone(), stiff).unwrap();
    let (hz, zeta) = (0.4, 0.8);
    let w = 2.0 * std::f64::consts::PI * hz;
    let gains = arm.motor_pd_gains(&[0.0; 7], hz, zeta).unwrap();
    // the spring's correction is of relative size m ω²/k ≤ 1e-11 here
    for i in 0..7 {
        let inertia = 0.8 + gains.link_inertia[i];
        let (kp, kd) = (inertia * w * w, 2.0 * zeta * w * inertia - 0.3);
        assert!(
            (gains.kp[i] - kp).abs() < 1e-9 * kp,
            "{} vs {kp}",
            gains.kp[i]
        );
        assert!(
            (gains.kd[i] - kd.max(0.0)).abs() < 1e-9 * kd.abs(),
            "{} vs {kd}",
            gains.kd[i]
        );
    }
    // friction above the damping asked for: k_d = 0 (the wrist's 0.03 kg·m² link)
    assert_eq!(arm.motor_pd_gains(&[0.0; 7], hz, 0.05).unwrap().kd[6], 0.0);
    // the built-in arm: the documented gains (docs/model.md §5.3) and no dt anywhere
    let arm = FlexibleArm::new(robot, FlexibleJoints::space_arm()).unwrap();
    let gains = arm.motor_pd_gains(&[0.0; 7], 0.25, 1.0).unwrap();
    let kp = [20.75, 244.2, 238.2, 97.08, 5.785, 2.726, 1.021];
    let kd = [25.46, 318.1, 310.1, 125.1, 6.381, 2.473, 0.2998];
    for i in 0..7 {
        assert!(
            (gains.kp[i] / kp[i] - 1.0).abs() < 5e-4,
            "kp {i}: {}",
            gains.kp[i]
        );
        assert!(
            (gains.kd[i] / kd[i] - 1.0).abs() < 5e-4,
            "kd {i}: {}",
            gains.kd[i]
        );
    }
    // the shoulder's link (106 kg·m² on 1e4 N·m/rad) resonates at 1.55 Hz with its motor held
    let error = arm
        .motor_pd_gains(&[0.0; 7], 3.0, 1.0)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("bandwidth")
            && error
                .contains("1.547 Hz for joint 1 ('shoulder_yaw', 105.9 kg·m² on 10000 N·m/rad)")
            && !error.contains("joint 0"),
        "{error}"
    );
    for (hz, zeta, message) in [
        (0.0, 1.0, "bandwidth: expected a finite number > 0, given 0"),
        (
            f64::NAN,
            1.0,
            "bandwidth: expected a finite number > 0, given NaN",
        ),
        (
            0.2,
            0.0,
            "damping_ratio: expected a finite number > 0, given 0",
        ),
        (
            0.2,
            -1.0,
            "damping_ratio: expected a finite number > 0, given -1",
        ),
        (
            f64::INFINITY,
            1.0,
            "bandwidth: expected a finite number > 0, given inf",
        ),
    ] {
        let error = arm.motor_pd_gains(&[0.0; 7], hz, zeta).unwrap_err();
        assert_eq!(error.to_string(), message, "{hz} {zeta}");
    }
    assert!(arm.motor_pd_gains(&[0.0; 6], 0.25, 1.0).is_err());
}

/// `rk4_stability_exceeded(x, u, dt)` ends its search once it has found a stable step at or
/// above `dt`. Its answer must be the full limit's, `dt > limit.dt`, and where `dt` exceeds the
/// limit it must return the limit itself (every field, for the warning's message), for the dense
/// analysis, the joint-by-joint estimate, the open loop, a tumbling base, and arms with
/// reaction wheels (one whose friction sets the limit: a term of the minimum beside the loop's). Steps straddle each limit closely (1 ± 1e-9) and exactly.
#[test]
fn stability_exceeded_answers_as_the_full_limit_does() {
    use orbitflex::flex::stability::DENSE_LIMIT;
    let space = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let pd = |n: usize, kp: f64, kd: f64| {
        MotorPD::new(
            vec![kp; n],
            vec![kd; n],
            Schedule::Zero,
            Schedule::Zero,
            Schedule::Zero,
        )
        .unwrap()
    };
    let large = arm(DENSE_LIMIT + 4, 5, 0.5, 0.2);
    let with_wheels = |wheels: Vec<orbitflex::flex::Wheel>| {
        FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())
            .unwrap()
            .with_wheels(orbitflex::flex::ReactionWheels::new(wheels).unwrap())
            .unwrap()
    };
    let mut rough = orbitflex::testing::random_wheels(3, 4, 1.0)
        .wheels()
        .to_vec();
    let wheels = with_wheels(rough.clone());
    // a wheel whose friction limit (0.5 ms) is below the loop's (about 1 ms)
    let (spin, friction) = (rough[1].spin_inertia, 2.785 * rough[1].spin_inertia / 5e-4);
    rough[1].friction = friction;
    let rough = with_wheels(rough);
    let mut tumbling = space.rest_state();
    tumbling[space.layout().base_twist()][..3].copy_from_slice(&[40.0, -30.0, 20.0]);
    // what, arm, state, controller
    type Case<'a> = (&'a str, &'a FlexibleArm, Vec<f64>, Box<dyn Controller>);
    let cases: Vec<Case> = vec![
        (
            "dense",
            &space,
            space.rest_state(),
            Box::new(pd(7, 2000.0, 800.0)),
        ),
        (
            "dense, moving",
            &space,
            moving_state(&space, 3),
            Box::new(pd(7, 50.0, 5.0)),
        ),
        (
            "open loop",
            &space,
            space.rest_state(),
            Box::new(Schedule::Zero),
        ),
        ("tumbling", &space, tumbling, Box::new(pd(7, 50.0, 5.0))),
        (
            "estimated",
            &large,
            moving_state(&large, 5),
            Box::new(pd(large.dof(), 300.0, 60.0)),
        ),
        (
            "wheels",
            &wheels,
            wheels.rest_state(),
            Box::new(pd(7, 2000.0, 800.0)),
        ),
        (
            "wheel friction",
            &rough,
            rough.rest_state(),
            Box::new(pd(7, 2000.0, 800.0)),
        ),
    ];
    for (what, arm, x0, u) in &cases {
        let limit = arm.rk4_stability_limit(x0, u.as_ref()).unwrap();
        assert!(limit.dt.is_finite() && limit.dt > 0.0, "{what}: {limit:?}");
        if *what == "wheel friction" {
            // the friction pole −c/J_s of wheel 1 sets this one, not the arm's loop
            assert_eq!(limit.dt, 2.785 * spin / friction);
        }
        for factor in [1e-3, 0.5, 1.0 - 1e-9, 1.0, 1.0 + 1e-9, 1.0001, 2.0, 1e3] {
            let dt = limit.dt * factor;
            let exceeded = arm.rk4_stability_exceeded(x0, u.as_ref(), dt).unwrap();
            assert_eq!(
                exceeded,
                (dt > limit.dt).then_some(limit),
                "{what}: dt = {dt:e} against {limit:?}"
            );
        }
    }
}
