//! Trajectory generation: the flexible-joint inverse dynamics (algebraic exactness against the
//! forward model, exact time derivatives) and the minimum-time slew planner.

use orbitflex::planning::{plan_slew, Constraint, Limits, Plan};
use orbitflex::testing::{random_chain, Rng};
use orbitflex::{
    BaseMode, FlexibleArm, FlexibleInverse, FlexibleJoints, Inputs, LinkMotion, Loads, MotorPD,
    Robot, Schedule, StateSpec,
};

/// Joint parameters with spread: k 200–800 N·m/rad, j 0.05–0.2 kg·m², β 0.1–0.5 N·m·s/rad and
/// damping `d` (N·m·s/rad).
fn arm(robot: Robot, seed: u64, damping: f64) -> FlexibleArm {
    let n = robot.dof();
    let mut rng = Rng::new(seed);
    let joints = FlexibleJoints::new(
        rng.vector(n, 200.0, 800.0),
        rng.vector(n, 0.05, 0.2),
        vec![damping; n],
        rng.vector(n, 0.1, 0.5),
    )
    .unwrap();
    FlexibleArm::new(robot, joints).unwrap()
}

/// A link motion with random angles and derivatives.
fn motion(n: usize, seed: u64) -> [Vec<f64>; 5] {
    let mut rng = Rng::new(seed);
    std::array::from_fn(|k| {
        rng.vector(n, -1.0, 1.0)
            .iter()
            .map(|v| v / (1.0 + k as f64))
            .collect()
    })
}

fn link_motion(m: &[Vec<f64>; 5]) -> LinkMotion<'_> {
    LinkMotion {
        q: &m[0],
        qd: &m[1],
        qdd: &m[2],
        qddd: &m[3],
        qdddd: &m[4],
    }
}

fn relative(got: &[f64], want: &[f64]) -> f64 {
    let scale = want.iter().fold(1e-300_f64, |a, v| a.max(v.abs()));
    got.iter()
        .zip(want)
        .fold(0.0_f64, |a, (g, w)| a.max((g - w).abs()))
        / scale
}

/// Builds the state the inverse dynamics describes and runs the forward model on it with the
/// returned torques and base wrench; returns (q̈, θ̈, α_B classical) from the derivative.
fn forward(arm: &FlexibleArm, m: &[Vec<f64>; 5], out: &FlexibleInverse) -> [Vec<f64>; 3] {
    let x = arm
        .state(&StateSpec {
            q: Some(&m[0]),
            qd: Some(&m[1]),
            theta: Some(&out.theta),
            theta_dot: Some(&out.theta_dot),
            base_twist: Some(&out.base_twist),
            base_pose: Some(&[0.3, -0.2, 0.1, 0.1, 0.2, -0.3, 0.9]),
        })
        .unwrap();
    let loads = Loads::from_slices(Some(&out.base_wrench), None).unwrap();
    let mut xdot = vec![0.0; x.len()];
    let mut ws = arm.workspace();
    arm.derivative(
        &mut ws,
        &x,
        &Inputs {
            u: &out.u,
            loads,
            wheel_torque: &[],
        },
        &mut xdot,
    )
    .unwrap();
    let layout = arm.layout();
    let twist_rate = &xdot[layout.base_twist()];
    let (w, v) = (&out.base_twist[..3], &out.base_twist[3..]);
    let w_cross_v = [
        w[1] * v[2] - w[2] * v[1],
        w[2] * v[0] - w[0] * v[2],
        w[0] * v[1] - w[1] * v[0],
    ];
    let mut acc = twist_rate.to_vec();
    for k in 0..3 {
        acc[3 + k] += w_cross_v[k];
    }
    [
        xdot[layout.qd()].to_vec(),
        xdot[layout.theta_dot()].to_vec(),
        acc,
    ]
}

fn check_exactness(arm: &FlexibleArm, seed: u64) {
    let n = arm.dof();
    let m = motion(n, seed);
    let damped = arm.joints().damping.iter().any(|&d| d > 0.0);
    let deflection: Vec<f64> = Rng::new(seed + 1).vector(n, -0.01, 0.01);
    for base in [BaseMode::Held, BaseMode::Free] {
        let out = arm
            .inverse_dynamics(&link_motion(&m), base, damped.then_some(&deflection[..]))
            .unwrap();
        let [qdd, theta_ddot, base_acc] = forward(arm, &m, &out);
        assert!(
            relative(&qdd, &m[2]) < 1e-9,
            "{base:?} q̈: {}",
            relative(&qdd, &m[2])
        );
        assert!(
            relative(&theta_ddot, &out.theta_ddot) < 1e-9,
            "{base:?} θ̈: {}",
            relative(&theta_ddot, &out.theta_ddot)
        );
        match base {
            BaseMode::Held => {
                assert_eq!(out.base_twist, [0.0; 6]);
                assert_eq!(out.base_acc, [0.0; 6]);
                assert!(base_acc.iter().all(|a| a.abs() < 1e-9), "{base_acc:?}");
                assert!(out.base_wrench.iter().any(|f| f.abs() > 1e-3));
            }
            BaseMode::Free => {
                assert_eq!(out.base_wrench, [0.0; 6]);
                assert!(out.base_twist.iter().any(|v| v.abs() > 1e-3));
                assert!(
                    relative(&base_acc, &out.base_acc) < 1e-9,
                    "α_B: {}",
                    relative(&base_acc, &out.base_acc)
                );
                // zero momentum
                let x = arm
                    .state(&StateSpec {
                        q: Some(&m[0]),
                        qd: Some(&m[1]),
                        base_twist: Some(&out.base_twist),
                        ..StateSpec::default()
                    })
                    .unwrap();
                let h = arm.momentum(&mut arm.workspace(), &x);
                assert!(h.iter().all(|v| v.abs() < 1e-10), "{h:?}");
            }
        }
    }
}

#[test]
fn inverse_dynamics_is_exact_against_the_forward_model() {
    for (i, robot) in [Robot::space_arm(), random_chain(5, 11), random_chain(9, 12)]
        .into_iter()
        .enumerate()
    {
        check_exactness(&arm(robot.clone(), 3 + i as u64, 0.0), 20 + i as u64);
        check_exactness(&arm(robot, 3 + i as u64, 0.7), 30 + i as u64);
    }
}

/// `q(t)` is a polynomial per joint; its derivatives at `t` in closed form.
fn polynomial_motion(coeffs: &[[f64; 7]], t: f64) -> [Vec<f64>; 5] {
    std::array::from_fn(|k| {
        coeffs
            .iter()
            .map(|c| {
                (k..c.len())
                    .map(|i| {
                        let falling: f64 = (0..k).map(|j| (i - j) as f64).product();
                        c[i] * falling * t.powi((i - k) as i32)
                    })
                    .sum()
            })
            .collect()
    })
}

#[test]
fn motor_rates_are_the_time_derivatives_of_the_motor_angles() {
    for (robot, seed) in [(Robot::space_arm(), 1), (random_chain(6, 5), 2)] {
        let arm = arm(robot, seed, 0.0);
        let n = arm.dof();
        let mut rng = Rng::new(seed + 10);
        let coeffs: Vec<[f64; 7]> = (0..n)
            .map(|_| std::array::from_fn(|_| rng.range(-1.0, 1.0)))
            .collect();
        for base in [BaseMode::Held, BaseMode::Free] {
            let at = |t: f64| {
                arm.inverse_dynamics(&link_motion(&polynomial_motion(&coeffs, t)), base, None)
                    .unwrap()
            };
            // central differences with one Richardson step: O(h⁴) truncation error
            let (t, h) = (0.4, 1e-3);
            let now = at(t);
            let (before, after) = (at(t - h), at(t + h));
            let (near_before, near_after) = (at(t - h / 2.0), at(t + h / 2.0));
            let richardson = |f: &dyn Fn(&FlexibleInverse) -> f64| {
                let wide = (f(&after) - f(&before)) / (2.0 * h);
                let narrow = (f(&near_after) - f(&near_before)) / h;
                (4.0 * narrow - wide) / 3.0
            };
            for i in 0..n {
                let rate = richardson(&|o| o.theta[i]);
                let acc = richardson(&|o| o.theta_dot[i]);
                assert!(
                    (rate - now.theta_dot[i]).abs() < 1e-6 * (1.0 + now.theta_dot[i].abs()),
                    "{base:?} θ̇[{i}]: {rate} vs {}",
                    now.theta_dot[i]
                );
                assert!(
                    (acc - now.theta_ddot[i]).abs() < 1e-6 * (1.0 + now.theta_ddot[i].abs()),
                    "{base:?} θ̈[{i}]: {acc} vs {}",
                    now.theta_ddot[i]
                );
                // the deflection is visible: the test would pass with θ = q otherwise
                assert!((now.theta[i] - polynomial_motion(&coeffs, t)[0][i]).abs() > 1e-6);
            }
            if base == BaseMode::Free {
                for k in 0..6 {
                    let acc = richardson(&|o| o.base_twist[k]);
                    let spatial = now.base_acc[k]
                        - if k >= 3 {
                            let (w, v) = (&now.base_twist[..3], &now.base_twist[3..]);
                            let c = [
                                w[1] * v[2] - w[2] * v[1],
                                w[2] * v[0] - w[0] * v[2],
                                w[0] * v[1] - w[1] * v[0],
                            ];
                            c[k - 3]
                        } else {
                            0.0
                        };
                    assert!((acc - spatial).abs() < 1e-6, "V̇_B[{k}]: {acc} vs {spatial}");
                }
            }
        }
    }
}

#[test]
fn inverse_dynamics_rejects_bad_arguments_with_what_and_where() {
    let arm = arm(Robot::space_arm(), 1, 0.0);
    let n = arm.dof();
    let mut m = motion(n, 4);
    let err = arm
        .inverse_dynamics(&link_motion(&m), BaseMode::Held, Some(&vec![0.0; n]))
        .unwrap_err()
        .to_string();
    assert!(err.contains("deflection") && err.contains("omit"), "{err}");
    m[3][2] = f64::NAN;
    let err = arm
        .inverse_dynamics(&link_motion(&m), BaseMode::Held, None)
        .unwrap_err()
        .to_string();
    assert!(err.starts_with("qddd: element 2 is not finite"), "{err}");
    m[3].pop();
    let err = arm
        .inverse_dynamics(&link_motion(&m), BaseMode::Free, None)
        .unwrap_err()
        .to_string();
    assert_eq!(err, "qddd: expected length 7, given length 6");
    let damped = self::arm(Robot::space_arm(), 1, 0.5);
    let m = motion(n, 4);
    let err = damped
        .inverse_dynamics(&link_motion(&m), BaseMode::Held, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("deflection") && err.contains("d > 0"), "{err}");
    let err = BaseMode::from_name("fixed").unwrap_err().to_string();
    assert_eq!(err, "base: expected \"held\" or \"free\", given \"fixed\"");
}

/// The built-in arm with its built-in joints (k 2e3–1e4 N·m/rad, d = 0.2, β = 1).
fn space_arm() -> FlexibleArm {
    FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap()
}

const GOAL: [f64; 7] = [0.8, -0.6, 0.5, 1.0, -0.7, 0.6, 0.9];

/// The test slew's limits; base limits for a held base only.
fn space_limits(base: BaseMode) -> Limits {
    let held = base == BaseMode::Held;
    Limits::new(
        vec![60.0, 60.0, 60.0, 30.0, 15.0, 15.0, 15.0],
        vec![0.5],
        held.then_some(80.0),
        held.then_some(60.0),
    )
    .unwrap()
}

/// Every limit holds at `count` evenly spaced instants evaluated afresh (not the planner's
/// samples), and the largest ratio, which must be the binding one, is at least 99.5%.
fn check_limits(plan: &Plan, count: usize) {
    let limits = plan.limits().for_joints(plan.arm().dof()).unwrap();
    let mut worst: f64 = 0.0;
    for k in 0..=count {
        let t = plan.duration() * k as f64 / count as f64;
        let p = plan.evaluate(t).unwrap();
        for i in 0..p.flexible.u.len() {
            worst = worst.max(p.flexible.u[i].abs() / limits.motor_torque[i]);
            worst = worst.max(p.qd[i].abs() / limits.joint_speed[i]);
        }
        if plan.base() == BaseMode::Held {
            let f = p.flexible.base_wrench;
            let (moment, force) = (
                (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt(),
                (f[3] * f[3] + f[4] * f[4] + f[5] * f[5]).sqrt(),
            );
            worst = worst.max(limits.base_torque.map_or(0.0, |l| moment / l));
            worst = worst.max(limits.base_force.map_or(0.0, |l| force / l));
        }
    }
    assert!(
        worst <= 1.0 + 1e-9,
        "a limit is exceeded between samples: {worst}"
    );
    assert!(worst >= 0.995, "no limit is active: {worst}");
    let b = plan.binding();
    assert!((b.value / b.limit - 1.0).abs() < 1e-8, "{b:?}");
}

#[test]
fn the_built_in_slews_are_as_short_as_their_limits_allow() {
    let arm = space_arm();
    let held = plan_slew(
        &arm,
        &GOAL,
        None,
        &space_limits(BaseMode::Held),
        BaseMode::Held,
        &[],
    )
    .unwrap();
    check_limits(&held, 4000);
    let b = held.binding();
    assert_eq!((b.constraint, b.joint), (Constraint::BaseTorque, None));
    assert!(
        (held.duration() - 13.050_452_5).abs() < 1e-6,
        "{}",
        held.duration()
    );
    // the torque norm peaks at 7.64509 s (a 4e-6 s grid of evaluate() around it agrees)
    assert!((b.time - 7.645_089_3).abs() < 1e-6, "{}", b.time);
    let free = plan_slew(
        &arm,
        &GOAL,
        None,
        &space_limits(BaseMode::Free),
        BaseMode::Free,
        &[],
    )
    .unwrap();
    check_limits(&free, 4000);
    let b = free.binding();
    assert_eq!((b.constraint, b.joint), (Constraint::MotorTorque, Some(3)));
    assert!(
        (free.duration() - 5.789_480_9).abs() < 1e-6,
        "{}",
        free.duration()
    );
    // a slow joint-speed bound binds exactly at s = 1/2, T = |Δ| σ'(1/2) / q̇_max
    let slow = Limits::new(vec![1e4], vec![0.05], None, None).unwrap();
    let plan = plan_slew(&arm, &GOAL, None, &slow, BaseMode::Held, &[]).unwrap();
    assert_eq!(plan.binding().constraint, Constraint::JointSpeed);
    assert_eq!(plan.binding().joint, Some(3));
    let expected = 1.0 * (315.0 / 128.0) / 0.05;
    assert!(
        (plan.duration() - expected).abs() < 1e-9 * expected,
        "{}",
        plan.duration()
    );
    assert!((plan.binding().time - expected / 2.0).abs() < 1e-9 * expected);
}

#[test]
fn plans_on_a_random_chain_respect_their_limits() {
    let arm = arm(random_chain(6, 21), 8, 0.3);
    let goal: Vec<f64> = Rng::new(5).vector(6, -1.0, 1.0);
    let start: Vec<f64> = Rng::new(6).vector(6, -0.5, 0.5);
    let waypoint: Vec<f64> = Rng::new(7).vector(6, -1.0, 1.0);
    for base in [BaseMode::Held, BaseMode::Free] {
        let held = base == BaseMode::Held;
        let limits = Limits::new(
            vec![5.0],
            vec![1.0, 1.2, 0.8, 1.0, 2.0, 2.0],
            held.then_some(20.0),
            held.then_some(10.0),
        )
        .unwrap();
        let plan = plan_slew(
            &arm,
            &goal,
            Some(&start),
            &limits,
            base,
            std::slice::from_ref(&waypoint),
        )
        .unwrap();
        check_limits(&plan, 3000);
        // the plan stops at the waypoint, at rest
        let join = plan.segment_durations()[0];
        let p = plan.evaluate(join).unwrap();
        for (i, w) in waypoint.iter().enumerate() {
            assert!((p.q[i] - w).abs() < 1e-12);
            assert!(p.qd[i].abs() < 1e-12 && p.qdd[i].abs() < 1e-12);
        }
        let end = plan.evaluate(plan.duration()).unwrap();
        assert!(end.q.iter().zip(&goal).all(|(a, b)| (a - b).abs() < 1e-12));
        assert_eq!(plan.bindings().len(), 2);
    }
}

/// θ̇ and θ̈ of a plan with damped joints, where the deflection comes from integrating
/// `d δ̇ + k δ = τ`, are the time derivatives of its θ (central differences with a Richardson step).
#[test]
fn a_damped_plan_has_consistent_motor_rates() {
    let mut joints = FlexibleJoints::space_arm();
    joints.damping = vec![40.0, 40.0, 40.0, 20.0, 10.0, 10.0, 10.0]; // d/k from 4 ms to 5 ms
    let arm = FlexibleArm::new(Robot::space_arm(), joints).unwrap();
    let plan = plan_slew(
        &arm,
        &GOAL,
        None,
        &space_limits(BaseMode::Free),
        BaseMode::Free,
        &[],
    )
    .unwrap();
    let h = 1e-3;
    for t in [0.7, 2.3, 4.0] {
        let at = |t: f64| plan.evaluate(t).unwrap();
        let (now, a, b, c, d) = (
            at(t),
            at(t - h),
            at(t + h),
            at(t - h / 2.0),
            at(t + h / 2.0),
        );
        let richardson = |f: &dyn Fn(&orbitflex::planning::PlanPoint) -> f64| {
            (4.0 * (f(&d) - f(&c)) / h - (f(&b) - f(&a)) / (2.0 * h)) / 3.0
        };
        for i in 0..7 {
            let rate = richardson(&|p| p.flexible.theta[i]);
            let acc = richardson(&|p| p.flexible.theta_dot[i]);
            assert!(
                (rate - now.flexible.theta_dot[i]).abs()
                    < 1e-6 * (1.0 + now.flexible.theta_dot[i].abs()),
                "t={t} θ̇[{i}]: {rate} vs {}",
                now.flexible.theta_dot[i]
            );
            assert!(
                (acc - now.flexible.theta_ddot[i]).abs()
                    < 1e-6 * (1.0 + now.flexible.theta_ddot[i].abs()),
                "t={t} θ̈[{i}]: {acc} vs {}",
                now.flexible.theta_ddot[i]
            );
        }
        // and the plan's instant agrees with the pointwise inverse dynamics given its deflection
        let deflection: Vec<f64> = now
            .flexible
            .theta
            .iter()
            .zip(&now.q)
            .map(|(a, b)| a - b)
            .collect();
        let motion = [
            now.q.clone(),
            now.qd.clone(),
            now.qdd.clone(),
            at_derivative(&plan, t, 3),
            at_derivative(&plan, t, 4),
        ];
        let point = arm
            .inverse_dynamics(&link_motion(&motion), BaseMode::Free, Some(&deflection))
            .unwrap();
        assert!(
            relative(&point.u, &now.flexible.u) < 1e-9,
            "{}",
            relative(&point.u, &now.flexible.u)
        );
        assert!(relative(&point.base_twist, &now.flexible.base_twist) < 1e-12);
    }
}

/// `q⃛` or `q⁗` of a single-segment plan at `t`, from the path shape.
fn at_derivative(plan: &Plan, t: f64, order: usize) -> Vec<f64> {
    let (start, goal) = (&plan.stops()[0], &plan.stops()[1]);
    let duration = plan.duration();
    let sig = orbitflex::planning::sigma(t / duration);
    start
        .iter()
        .zip(goal)
        .map(|(a, b)| (b - a) * sig[order] / duration.powi(order as i32))
        .collect()
}

#[test]
fn the_flexible_plan_is_followed_and_the_rigid_one_is_not() {
    let arm = space_arm();
    let (kp, kd) = (vec![1000.0; 7], vec![100.0; 7]);
    for base in [BaseMode::Held, BaseMode::Free] {
        let plan = plan_slew(&arm, &GOAL, None, &space_limits(base), base, &[]).unwrap();
        let flexible = plan.track(1e-3, &kp, &kd, 2.0).unwrap();
        assert!(
            flexible.tracking_error < 1e-5,
            "{base:?}: {}",
            flexible.tracking_error
        );
        assert!(
            flexible.base_position_error < 1e-5,
            "{}",
            flexible.base_position_error
        );
        assert!(
            flexible.base_attitude_error < 1e-5,
            "{}",
            flexible.base_attitude_error
        );
        let rigid_plan = plan.rigid().unwrap();
        assert!(rigid_plan.is_rigid() && !plan.is_rigid());
        let rigid = rigid_plan.track(1e-3, &kp, &kd, 2.0).unwrap();
        assert!(
            rigid.tracking_error > 1e-3,
            "{base:?}: {}",
            rigid.tracking_error
        );
        assert!(
            rigid.residual_deflection > 10.0 * flexible.residual_deflection,
            "{base:?}: {} vs {}",
            rigid.residual_deflection,
            flexible.residual_deflection
        );
        let steps = ((plan.duration() + 2.0) / 1e-3).ceil() as usize;
        assert_eq!(flexible.trajectory.len(), steps + 1);
    }
}

/// The measures recomputed from the trajectory, independently of `track`.
#[test]
fn tracking_measures_are_what_they_say() {
    let arm = space_arm();
    let plan = plan_slew(
        &arm,
        &GOAL,
        None,
        &space_limits(BaseMode::Free),
        BaseMode::Free,
        &[],
    )
    .unwrap()
    .rigid()
    .unwrap();
    let dt = 2e-3;
    // settle = 0: only the final state is at or after the slew's end
    let run = plan.track(dt, &[1000.0; 7], &[100.0; 7], 0.0).unwrap();
    let traj = &run.trajectory;
    let layout = arm.layout();
    let last = traj.state(traj.len() - 1);
    let final_deflection = (0..7)
        .map(|i| (last[layout.theta()][i] - last[layout.q()][i]).abs())
        .fold(0.0, f64::max);
    assert!(traj.t[traj.len() - 2] < plan.duration() && traj.t[traj.len() - 1] >= plan.duration());
    assert_eq!(run.residual_deflection, final_deflection);
    assert!(final_deflection > 1e-5, "{final_deflection}");
    let final_error = (0..7)
        .map(|i| (last[layout.q()][i] - GOAL[i]).abs())
        .fold(0.0, f64::max);
    assert_eq!(run.residual_link_error, final_error);
    let mut peak = [0.0_f64; 7];
    for row in traj.u.chunks_exact(7) {
        for i in 0..7 {
            peak[i] = peak[i].max(row[i].abs());
        }
    }
    assert_eq!(run.peak_motor_torque, peak.to_vec());
    let mut worst: f64 = 0.0;
    for k in (0..traj.len()).step_by(7) {
        let planned = plan.evaluate(traj.t[k]).unwrap();
        let q = &traj.state(k)[layout.q()];
        for (a, b) in q.iter().zip(&planned.q) {
            worst = worst.max((a - b).abs());
        }
    }
    assert!(
        worst <= run.tracking_error && worst > 0.9 * run.tracking_error,
        "{worst} vs {}",
        run.tracking_error
    );
}

#[test]
fn planning_rejects_bad_requests_with_what_and_where() {
    let arm = space_arm();
    let message = |r: orbitflex::Result<Plan>| r.unwrap_err().to_string();
    let limits = space_limits(BaseMode::Held);
    assert_eq!(
        Limits::new(vec![1.0, 0.0], vec![1.0], None, None)
            .unwrap_err()
            .to_string(),
        "motor_torque[1]: expected a finite limit > 0, given 0"
    );
    assert_eq!(
        Limits::new(vec![1.0], vec![f64::NAN], None, None)
            .unwrap_err()
            .to_string(),
        "joint_speed: expected a finite limit > 0, given NaN"
    );
    assert_eq!(
        Limits::new(vec![1.0], vec![1.0], Some(-3.0), None)
            .unwrap_err()
            .to_string(),
        "base_force: expected a finite limit > 0, given -3"
    );
    assert_eq!(
        Limits::new(vec![], vec![1.0], None, None)
            .unwrap_err()
            .to_string(),
        "motor_torque: expected one value per joint, or one for all, given no values"
    );
    let three = Limits::new(vec![1.0; 3], vec![1.0], None, None).unwrap();
    assert_eq!(
        message(plan_slew(&arm, &GOAL, None, &three, BaseMode::Held, &[])),
        "limits.motor_torque: expected 7 values (one per joint) or 1 (for all), given 3 values"
    );
    assert_eq!(
        message(plan_slew(
            &arm,
            &[0.0; 7],
            None,
            &limits,
            BaseMode::Held,
            &[]
        )),
        "q_goal: equals q_start (to 1e-12 rad): there is nothing to slew"
    );
    assert_eq!(
        message(plan_slew(
            &arm,
            &GOAL,
            None,
            &limits,
            BaseMode::Held,
            &[GOAL.to_vec()]
        )),
        "q_goal: equals waypoints[0] (to 1e-12 rad): there is nothing to slew"
    );
    assert_eq!(
        message(plan_slew(
            &arm,
            &GOAL,
            None,
            &limits,
            BaseMode::Held,
            &[vec![0.0; 6]]
        )),
        "waypoints[0]: expected length 7, given length 6"
    );
    let mut near = GOAL;
    near[2] += 1e-13;
    assert_eq!(
        message(plan_slew(
            &arm,
            &GOAL,
            Some(&near),
            &limits,
            BaseMode::Held,
            &[]
        )),
        "q_goal: equals q_start (to 1e-12 rad): there is nothing to slew"
    );
    assert_eq!(
        message(plan_slew(&arm, &GOAL, None, &limits, BaseMode::Free, &[])),
        "limits: base_force and base_torque bound the wrench that holds a held base; a free base \
         receives none (base = \"free\"): leave them out"
    );
    // the fields are public: a plan checks them again
    for (speed, shown) in [(0.0, "0"), (-0.5, "-0.5"), (f64::NAN, "NaN")] {
        let mut bad = space_limits(BaseMode::Held);
        bad.joint_speed = vec![speed];
        assert_eq!(
            message(plan_slew(&arm, &GOAL, None, &bad, BaseMode::Held, &[])),
            format!("joint_speed: expected a finite limit > 0, given {shown}")
        );
    }
    // a tiny slew still gets a finite, feasible plan (no NaN counts as within the limits)
    let mut close = [0.0; 7];
    close[0] = 1e-9;
    let tiny_plan = plan_slew(&arm, &close, None, &limits, BaseMode::Held, &[]).unwrap();
    assert!(tiny_plan.duration().is_finite() && tiny_plan.duration() > 0.0);
    check_limits(&tiny_plan, 200);
    // reachable in principle (zero gravity), but only after about 1e150 s
    let tiny = Limits::new(vec![1e-300], vec![1.0], None, None).unwrap();
    let err = message(plan_slew(&arm, &GOAL, None, &tiny, BaseMode::Held, &[]));
    assert!(
        err.starts_with("limits: no duration up to 1e9 s meets them: motor_torque[")
            && err.ends_with(", over its limit of 1e-300"),
        "{err}"
    );
    // a huge speed limit (no speed limit, in effect) plans what a merely generous one does: the
    // search starts from 1 ns and still brackets the torque-bound duration
    for huge in [1e18, f64::MAX] {
        let unbounded = Limits::new(
            space_limits(BaseMode::Free).motor_torque,
            vec![huge],
            None,
            None,
        )
        .unwrap();
        let plan = plan_slew(&arm, &GOAL, None, &unbounded, BaseMode::Free, &[]).unwrap();
        let generous = Limits::new(
            space_limits(BaseMode::Free).motor_torque,
            vec![1e3],
            None,
            None,
        )
        .unwrap();
        let reference = plan_slew(&arm, &GOAL, None, &generous, BaseMode::Free, &[]).unwrap();
        assert_eq!(plan.binding().constraint, Constraint::MotorTorque);
        assert!(
            (plan.duration() / reference.duration() - 1.0).abs() < 2e-10,
            "{} vs {}",
            plan.duration(),
            reference.duration()
        );
    }
    let plan = plan_slew(&arm, &GOAL, None, &limits, BaseMode::Held, &[]).unwrap();
    assert!(plan.reference(0.0, None).is_err());
    assert!(plan
        .track(1e-3, &[1.0; 6], &[1.0; 7], 1.0)
        .unwrap_err()
        .to_string()
        .starts_with("kp"));
    assert_eq!(
        plan.track(1e-3, &[1.0; 7], &[1.0; 7], -1.0)
            .unwrap_err()
            .to_string(),
        "settle: expected a finite time ≥ 0 (s), given -1"
    );
    // a step longer than the plan cannot follow it
    let long = plan.duration() * 1.5;
    let refused = |r: orbitflex::Result<orbitflex::planning::Tracking>| r.unwrap_err().to_string();
    assert!(refused(plan.track(long, &[1.0; 7], &[1.0; 7], 0.0))
        .starts_with(&format!("dt: {long} s is longer than the plan (")));
    // past the stability limit of the tracking loop (computed here independently) the run
    // would diverge: refused before it starts; just inside, it runs
    let (kp, kd) = ([1000.0; 7], [100.0; 7]);
    let probe = MotorPD::new(
        kp.to_vec(),
        kd.to_vec(),
        Schedule::Zero,
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let limit = arm
        .rk4_stability_limit(&plan.initial_state(), &probe)
        .unwrap()
        .dt;
    let err = refused(plan.track(limit * 1.01, &kp, &kd, 0.0));
    assert!(
        err.starts_with("dt: ")
            && err.contains(&format!("past the RK4 stability limit {limit:.4e} s")),
        "{err}"
    );
    assert!(plan.track(limit * 0.99, &kp, &kd, 0.0).is_ok());
}

#[test]
fn references_average_the_feedforward_and_cover_the_run() {
    let arm = space_arm();
    let plan = plan_slew(
        &arm,
        &GOAL,
        None,
        &space_limits(BaseMode::Held),
        BaseMode::Held,
        &[],
    )
    .unwrap();
    let dt = 0.01;
    let r = plan.reference(dt, Some(1400)).unwrap();
    assert_eq!(
        (r.steps, r.u.len(), r.base_wrench.len(), r.base_pose.len()),
        (1400, 9800, 8400, 9807)
    );
    // Simpson's average of a smooth u against a fine midpoint rule
    let k = 400;
    for i in 0..7 {
        let fine: f64 = (0..200)
            .map(|m| {
                plan.evaluate((k as f64 + (m as f64 + 0.5) / 200.0) * dt)
                    .unwrap()
                    .flexible
                    .u[i]
            })
            .sum::<f64>()
            / 200.0;
        assert!(
            (r.u[k * 7 + i] - fine).abs() < 1e-6 * (1.0 + fine.abs()),
            "{i}: {} vs {fine}",
            r.u[k * 7 + i]
        );
        let start = plan.evaluate(k as f64 * dt).unwrap();
        assert_eq!(r.theta_ref[k * 7 + i], start.flexible.theta[i]);
    }
    // after the slew: the goal at rest, no torque
    let last = &r.u[1399 * 7..];
    assert!(last.iter().all(|u| u.abs() < 1e-12), "{last:?}");
    assert!(r.q[1399 * 7..]
        .iter()
        .zip(GOAL)
        .all(|(a, b)| (a - b).abs() < 1e-12));
    assert_eq!(
        plan.reference(dt, None).unwrap().steps,
        (plan.duration() / dt).ceil() as usize
    );
}

// ---- Tests that pin behaviour the mutation run (cargo mutants on src/planning/) found unchecked.

/// `(k, j, d, β)` of a slowly relaxing damped spring: `d/k = 0.5 s`, comparable to a slew, so
/// the deflection a segment leaves is visible; `j λ² ≠ β λ` (`λ = k/d`), so a relaxing spring
/// needs a motor torque.
const SLOW_SPRING: (f64, f64, f64, f64) = (200.0, 0.3, 100.0, 1.0);

/// The built-in arm with [`SLOW_SPRING`] joints.
fn slow_spring_arm() -> FlexibleArm {
    let (k, j, d, beta) = SLOW_SPRING;
    FlexibleArm::new(
        Robot::space_arm(),
        FlexibleJoints::uniform(7, k, j, d, beta).unwrap(),
    )
    .unwrap()
}

/// At a waypoint the links rest (`q̇ = q̈ = q⃛ = q⁗ = 0`, so `τ = τ̇ = 0`), but a slow damped spring
/// still carries the deflection the first segment left: there `d δ̇ + k δ = 0`, so
/// `θ̇ = δ̇ = −(k/d) δ`, `θ̈ = δ̈ = (k/d)² δ` and `u = j θ̈ + β θ̇`.
#[test]
fn a_slow_damped_spring_relaxes_through_a_waypoint() {
    let arm = slow_spring_arm();
    let (k, j, d, beta) = SLOW_SPRING;
    let waypoint: Vec<f64> = GOAL.iter().map(|g| 0.5 * g).collect();
    let limits = space_limits(BaseMode::Free);
    let plan = plan_slew(&arm, &GOAL, None, &limits, BaseMode::Free, &[waypoint]).unwrap();
    let join = plan.segment_durations()[0];
    let p = plan.evaluate(join).unwrap();
    let before = plan.evaluate(join - 1e-9).unwrap();
    let lambda = k / d;
    for i in 0..7 {
        let delta = p.deflection[i];
        assert_eq!((p.qd[i], p.qdd[i], p.flexible.tau[i]), (0.0, 0.0, 0.0));
        // the spring has not relaxed (joint 6 least: 3e-5 rad), and the plan hands it on
        // continuously from the first segment
        assert!(delta.abs() > 1e-5, "{i}: {delta}");
        assert!((before.deflection[i] - delta).abs() < 1e-8 * delta.abs());
        let (rate, acc) = (-lambda * delta, lambda * lambda * delta);
        assert!(
            (p.flexible.theta_dot[i] - rate).abs() < 1e-14 * rate.abs(),
            "{i}: {} vs {rate}",
            p.flexible.theta_dot[i]
        );
        assert!(
            (p.flexible.theta_ddot[i] - acc).abs() < 1e-14 * acc.abs(),
            "{i}: {} vs {acc}",
            p.flexible.theta_ddot[i]
        );
        let u = j * acc + beta * rate;
        assert!(
            (p.flexible.u[i] - u).abs() < 1e-14 * u.abs().max(1.0),
            "{i}: {} vs {u}",
            p.flexible.u[i]
        );
    }
}

/// A free base receives no actuator wrench: either base limit alone is refused, not only both.
#[test]
fn a_free_base_refuses_either_base_limit_alone() {
    let arm = space_arm();
    for (force, torque) in [(Some(80.0), None), (None, Some(60.0))] {
        let limits = Limits::new(vec![30.0], vec![0.5], force, torque).unwrap();
        let err = plan_slew(&arm, &GOAL, None, &limits, BaseMode::Free, &[])
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("limits: base_force and base_torque bound the wrench"),
            "{err}"
        );
    }
}

/// Each segment reports its own binding limit (segment index, absolute time within the segment,
/// the value `evaluate` shows there, at ratio 1), and `binding()` is the longest segment's.
#[test]
fn each_segment_binds_and_the_plan_reports_its_longest() {
    let arm = space_arm();
    // a short first hop, then the long slew: the second segment is the longer one
    let waypoint: Vec<f64> = GOAL.iter().map(|g| 0.1 * g).collect();
    let plan = plan_slew(
        &arm,
        &GOAL,
        None,
        &space_limits(BaseMode::Held),
        BaseMode::Held,
        &[waypoint],
    )
    .unwrap();
    let durations = plan.segment_durations();
    assert!(durations[1] > 2.0 * durations[0], "{durations:?}");
    assert_eq!(plan.duration(), durations[0] + durations[1]);
    let bindings = plan.bindings();
    assert_eq!(plan.binding(), &bindings[1]);
    let limits = plan.limits();
    let mut t0 = 0.0;
    for (k, b) in bindings.iter().enumerate() {
        assert_eq!(b.segment, k);
        assert!(
            b.time > t0 && b.time < t0 + durations[k],
            "segment {k}: {} not in ({t0}, {})",
            b.time,
            t0 + durations[k]
        );
        assert!((b.value / b.limit - 1.0).abs() < 1e-8, "{b:?}");
        // the reported value is the quantity at the reported instant
        let p = plan.evaluate(b.time).unwrap();
        let (value, limit) = match (b.constraint, b.joint) {
            (Constraint::MotorTorque, Some(j)) => (p.flexible.u[j].abs(), limits.motor_torque[j]),
            (Constraint::JointSpeed, Some(j)) => (p.qd[j].abs(), limits.joint_speed[j]),
            (Constraint::BaseTorque, None) => (
                p.flexible.base_wrench[..3]
                    .iter()
                    .map(|f| f * f)
                    .sum::<f64>()
                    .sqrt(),
                limits.base_torque.unwrap(),
            ),
            (Constraint::BaseForce, None) => (
                p.flexible.base_wrench[3..]
                    .iter()
                    .map(|f| f * f)
                    .sum::<f64>()
                    .sqrt(),
                limits.base_force.unwrap(),
            ),
            other => panic!("{other:?}"),
        };
        assert_eq!(b.limit, limit);
        assert!((value - b.value).abs() < 1e-9 * b.value, "{value} vs {b:?}");
        t0 += durations[k];
    }
}

/// After the end the links rest at the goal (`τ = 0`), so a damped spring's leftover deflection
/// decays freely: `δ(T + t) = δ(T) e^{−k t/d}`, `θ̇ = δ̇ = −(k/d) δ`, `θ̈ = (k/d)² δ` and
/// `u = j θ̈ + β θ̇`. The reference tables after the end show the same instants.
#[test]
fn after_the_end_a_damped_spring_decays_freely() {
    let arm = slow_spring_arm();
    let (k, j, d, beta) = SLOW_SPRING;
    let lambda = k / d;
    let plan = plan_slew(
        &arm,
        &GOAL,
        None,
        &space_limits(BaseMode::Held),
        BaseMode::Held,
        &[],
    )
    .unwrap();
    let end = plan.duration();
    let at_end = plan.evaluate(end).unwrap();
    for wait in [0.05, 0.3, 1.7] {
        let p = plan.evaluate(end + wait).unwrap();
        for (i, &goal) in GOAL.iter().enumerate() {
            let delta = at_end.deflection[i] * (-lambda * wait).exp();
            // the spring has not relaxed at the end (joint 6 least: 8e-7 rad)
            assert!(
                at_end.deflection[i].abs() > 1e-7,
                "{i}: {}",
                at_end.deflection[i]
            );
            assert!(
                (p.deflection[i] - delta).abs() < 1e-14 * delta.abs(),
                "{i}: {} vs {delta}",
                p.deflection[i]
            );
            assert_eq!(
                (p.q[i], p.qd[i], p.qdd[i], p.flexible.tau[i]),
                (goal, 0.0, 0.0, 0.0)
            );
            assert!((p.flexible.theta[i] - (goal + delta)).abs() < 1e-15);
            let (rate, acc) = (-lambda * delta, lambda * lambda * delta);
            assert!((p.flexible.theta_dot[i] - rate).abs() < 1e-14 * rate.abs());
            assert!((p.flexible.theta_ddot[i] - acc).abs() < 1e-14 * acc.abs());
            let u = j * acc + beta * rate;
            assert!(
                (p.flexible.u[i] - u).abs() < 1e-14 * u.abs(),
                "{i}: {} vs {u}",
                p.flexible.u[i]
            );
        }
    }
    // the per-step tables before and after the end are those instants (θ_ref, θ̇_ref at each
    // step's start, u as Simpson's average of the start, middle and end)
    let dt = 0.05;
    let steps = (end / dt).ceil() as usize + 20;
    let r = plan.reference(dt, Some(steps)).unwrap();
    for k in [steps / 2, steps - 10, steps - 1] {
        let t = k as f64 * dt;
        let (a, m, b) = (
            plan.evaluate(t).unwrap(),
            plan.evaluate(t + 0.5 * dt).unwrap(),
            plan.evaluate(t + dt).unwrap(),
        );
        for i in 0..7 {
            assert_eq!(r.theta_ref[k * 7 + i], a.flexible.theta[i], "{k} {i}");
            assert_eq!(
                r.theta_dot_ref[k * 7 + i],
                a.flexible.theta_dot[i],
                "{k} {i}"
            );
            assert_eq!(r.q[k * 7 + i], a.q[i], "{k} {i}");
            let u = (a.flexible.u[i] + 4.0 * m.flexible.u[i] + b.flexible.u[i]) / 6.0;
            assert!(
                (r.u[k * 7 + i] - u).abs() <= 1e-15 * u.abs().max(1e-300),
                "{k} {i}"
            );
        }
        for c in 0..6 {
            let f = (a.flexible.base_wrench[c]
                + 4.0 * m.flexible.base_wrench[c]
                + b.flexible.base_wrench[c])
                / 6.0;
            assert!(
                (r.base_wrench[k * 6 + c] - f).abs() <= 1e-15 * f.abs(),
                "{k} {c}"
            );
        }
    }
    assert_eq!(r.q[steps * 7..], GOAL);
}

/// The plan's sample table is the plan at those instants: times from 0 to the end, increasing,
/// the join of two segments once; every row what `evaluate` computes afresh there.
#[test]
fn samples_are_the_plan_at_the_sample_times() {
    let arm = arm(random_chain(6, 21), 8, 0.3);
    let goal: Vec<f64> = Rng::new(5).vector(6, -1.0, 1.0);
    let waypoint: Vec<f64> = Rng::new(7).vector(6, -1.0, 1.0);
    for base in [BaseMode::Held, BaseMode::Free] {
        let held = base == BaseMode::Held;
        let limits = Limits::new(
            vec![5.0],
            vec![1.0, 1.2, 0.8, 1.0, 2.0, 2.0],
            held.then_some(20.0),
            held.then_some(10.0),
        )
        .unwrap();
        let plan = plan_slew(
            &arm,
            &goal,
            None,
            &limits,
            base,
            std::slice::from_ref(&waypoint),
        )
        .unwrap();
        let s = plan.samples();
        let rows = s.t.len();
        assert!(rows > 2 * 512, "{rows}");
        assert_eq!(s.t[0], 0.0);
        assert!((s.t[rows - 1] - plan.duration()).abs() < 1e-12 * plan.duration());
        assert!(s.t.windows(2).all(|w| w[1] > w[0]), "not increasing");
        let join = plan.segment_durations()[0];
        assert_eq!(s.t.iter().filter(|t| (*t - join).abs() < 1e-9).count(), 1);
        for (name, table, width) in [
            ("q", &s.q, 6),
            ("qd", &s.qd, 6),
            ("qdd", &s.qdd, 6),
            ("theta", &s.theta, 6),
            ("theta_dot", &s.theta_dot, 6),
            ("u", &s.u, 6),
            ("tau", &s.tau, 6),
            ("base_wrench", &s.base_wrench, 6),
            ("base_twist", &s.base_twist, 6),
            ("base_pose", &s.base_pose, 7),
        ] {
            assert_eq!(table.len(), rows * width, "{name}");
        }
        for row in (0..rows).step_by(37).chain([rows - 1]) {
            let p = plan.evaluate(s.t[row]).unwrap();
            let (wrench, twist) = (&p.flexible.base_wrench[..], &p.flexible.base_twist[..]);
            for (name, table, want) in [
                ("q", &s.q, &p.q[..]),
                ("qd", &s.qd, &p.qd),
                ("qdd", &s.qdd, &p.qdd),
                ("theta", &s.theta, &p.flexible.theta),
                ("theta_dot", &s.theta_dot, &p.flexible.theta_dot),
                ("u", &s.u, &p.flexible.u),
                ("tau", &s.tau, &p.flexible.tau),
                ("base_wrench", &s.base_wrench, wrench),
                ("base_twist", &s.base_twist, twist),
            ] {
                // to 1e-9 of the quantity's largest value over the plan (the deflection is
                // integrated from another sample; the time goes through t = t0 + s T and back)
                let scale = table.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
                let width = want.len();
                let got = &table[row * width..(row + 1) * width];
                let error = got
                    .iter()
                    .zip(want)
                    .fold(0.0_f64, |a, (g, w)| a.max((g - w).abs()));
                assert!(
                    error <= 1e-9 * scale,
                    "{base:?} {name} row {row}: {got:?} vs {want:?}"
                );
            }
            let wrench = &s.base_wrench[row * 6..(row + 1) * 6];
            let twist = &s.base_twist[row * 6..(row + 1) * 6];
            if held {
                assert_eq!(twist, [0.0; 6]);
                assert_eq!(
                    s.base_pose[row * 7..(row + 1) * 7],
                    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
                );
            } else {
                assert_eq!(wrench, [0.0; 6]);
            }
        }
        if !held {
            // the base pose, integrated over the samples in s, against the reference's RK4 in t
            // at 4096 steps across the plan (two integrations of the same kinematics)
            let steps = 4096;
            let r = plan
                .reference(plan.duration() / steps as f64, Some(steps))
                .unwrap();
            let (mine, theirs) = (&s.base_pose[(rows - 1) * 7..], &r.base_pose[steps * 7..]);
            assert!(relative(mine, theirs) < 1e-9, "{mine:?} vs {theirs:?}");
            // the base moved (so the comparison says something)
            assert!(mine[..3].iter().any(|x| x.abs() > 1e-3), "{mine:?}");
        }
    }
}

/// The names the bindings and messages use, both ways; and what a plan says it was planned for:
/// its stops, base mode, per-joint limits, and the state a run of it starts from (`q = θ` the
/// start, at rest, base at the origin with identity attitude).
#[test]
fn names_and_what_a_plan_was_planned_for() {
    for (mode, name) in [(BaseMode::Held, "held"), (BaseMode::Free, "free")] {
        assert_eq!(mode.name(), name);
        assert_eq!(BaseMode::from_name(name).unwrap(), mode);
    }
    for (c, name) in [
        (Constraint::MotorTorque, "motor_torque"),
        (Constraint::JointSpeed, "joint_speed"),
        (Constraint::BaseForce, "base_force"),
        (Constraint::BaseTorque, "base_torque"),
    ] {
        assert_eq!(c.name(), name);
    }
    assert_eq!(
        Limits::uniform(30.0, 0.5).unwrap(),
        Limits::new(vec![30.0], vec![0.5], None, None).unwrap()
    );
    let arm = space_arm();
    let start = [0.1, 0.2, -0.3, 0.0, 0.1, -0.1, 0.2];
    let waypoint = vec![0.3; 7];
    for base in [BaseMode::Held, BaseMode::Free] {
        let limits = space_limits(base);
        let plan = plan_slew(
            &arm,
            &GOAL,
            Some(&start),
            &limits,
            base,
            std::slice::from_ref(&waypoint),
        )
        .unwrap();
        assert_eq!(plan.base(), base);
        assert_eq!(plan.arm().dof(), 7);
        assert_eq!(
            plan.stops(),
            [start.to_vec(), waypoint.clone(), GOAL.to_vec()]
        );
        let expanded = plan.limits();
        assert_eq!(expanded.motor_torque, limits.motor_torque);
        assert_eq!(expanded.joint_speed, vec![0.5; 7]);
        assert_eq!(
            (expanded.base_force, expanded.base_torque),
            (limits.base_force, limits.base_torque)
        );
        let layout = arm.layout();
        let x = plan.initial_state();
        assert_eq!(x.len(), layout.len());
        assert_eq!(x[layout.q()], start);
        assert_eq!(x[layout.theta()], start);
        assert_eq!(x[layout.base_pose()], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        for rates in [layout.base_twist(), layout.qd(), layout.theta_dot()] {
            assert!(x[rates].iter().all(|v| *v == 0.0));
        }
    }
}

/// `reference_with` and `tracking_setup_with` ask whether to go on every 4096 steps (after steps
/// 4095, 8191, …) and give up with `None` when told to; otherwise they build what `reference`
/// and `tracking_setup` build. The setup's tables are the reference's: θ_ref, θ̇_ref and the
/// feedforward for the PD, the base wrench for a held base (none for a free one), and the run
/// covers the slew and the settling time.
#[test]
fn long_table_builds_ask_to_go_on_and_the_setup_runs_on_the_reference() {
    let arm = space_arm();
    let (kp, kd) = (vec![1000.0; 7], vec![100.0; 7]);
    for base in [BaseMode::Held, BaseMode::Free] {
        let plan = plan_slew(&arm, &GOAL, None, &space_limits(base), base, &[]).unwrap();
        if base == BaseMode::Held {
            // 100 steps in the plan, the rest at rest after it (cheap)
            let (dt, steps) = (plan.duration() / 100.0, 8200);
            let mut asked = Vec::new();
            let r = plan
                .reference_with(dt, Some(steps), &mut |k| {
                    asked.push(k);
                    true
                })
                .unwrap()
                .unwrap();
            assert_eq!(asked, [4095, 8191]);
            assert_eq!(
                (r.steps, r.u.len(), r.q.len()),
                (steps, steps * 7, (steps + 1) * 7)
            );
            let mut asked = Vec::new();
            let stopped = plan
                .reference_with(dt, Some(steps), &mut |k| {
                    asked.push(k);
                    k < 8000
                })
                .unwrap();
            assert!(stopped.is_none());
            assert_eq!(asked, [4095, 8191]);
        }
        // the run: the slew plus 0.5 s of settling, in whole steps
        let (dt, settle) = (4e-3, 0.5);
        let setup = plan.tracking_setup(dt, &kp, &kd, settle).unwrap();
        let covering = ((plan.duration() + settle) / dt).ceil() as usize;
        assert_eq!(setup.steps, covering);
        let r = &setup.reference;
        assert_eq!((r.dt, r.steps), (dt, covering));
        let table = |values: &Vec<f64>, width| Schedule::Table {
            values: values.clone(),
            width,
        };
        assert_eq!(
            setup.pd,
            MotorPD::new(
                kp.clone(),
                kd.clone(),
                table(&r.theta_ref, 7),
                table(&r.theta_dot_ref, 7),
                table(&r.u, 7),
            )
            .unwrap()
        );
        assert_eq!(setup.wrenches.ee, Schedule::Zero);
        match base {
            BaseMode::Held => assert_eq!(setup.wrenches.base, table(&r.base_wrench, 6)),
            BaseMode::Free => assert_eq!(setup.wrenches.base, Schedule::Zero),
        }
        // with 20 s of settling the tables pass 4096 steps: asked, and stopped
        let stopped = plan
            .tracking_setup_with(dt, &kp, &kd, 20.0, &mut |_| false)
            .unwrap();
        assert!(stopped.is_none());
    }
}

/// A motion whose inverse dynamics overflow (`τ` grows as `q̇²`: `(1e160)²` is past `f64`) is an
/// error that names it, not a table of infinities; the same motion slowed down is fine.
#[test]
fn inverse_dynamics_that_overflow_are_an_error() {
    let arm = space_arm();
    let m = motion(7, 9);
    for (scale, overflows) in [(1e160, true), (1e3, false)] {
        let qd: Vec<f64> = m[1].iter().map(|v| v * scale).collect();
        let fast = LinkMotion {
            qd: &qd,
            ..link_motion(&m)
        };
        for base in [BaseMode::Held, BaseMode::Free] {
            let out = arm.inverse_dynamics(&fast, base, Some(&[0.0; 7]));
            match out {
                Err(e) if overflows => assert!(
                    e.to_string()
                        .starts_with("motion: too large for floating point"),
                    "{e}"
                ),
                Ok(out) if !overflows => assert!(out.u.iter().all(|u| u.is_finite())),
                other => panic!("{scale:e} {base:?}: {other:?}"),
            }
        }
    }
}

/// With undamped joints the deflection is a function of the instant, `δ = τ/k` (and its rates
/// `τ̇/k`, `τ̈/k`): the plan at any instant is `FlexibleArm::inverse_dynamics` of its link motion
/// there, computed independently from `q … q⁗` (no deflection passed).
#[test]
fn an_undamped_plan_is_the_pointwise_inverse_dynamics() {
    let mut joints = FlexibleJoints::space_arm();
    joints.damping = vec![0.0; 7];
    let arm = FlexibleArm::new(Robot::space_arm(), joints).unwrap();
    for base in [BaseMode::Held, BaseMode::Free] {
        let plan = plan_slew(&arm, &GOAL, None, &space_limits(base), base, &[]).unwrap();
        // after the end the links rest (τ = 0), so an undamped spring is relaxed at once
        let after = plan.evaluate(plan.duration() + 0.7).unwrap();
        assert_eq!(after.flexible.theta, GOAL);
        assert_eq!(after.deflection, [0.0; 7]);
        assert!(after
            .flexible
            .theta_dot
            .iter()
            .chain(&after.flexible.u)
            .all(|v| *v == 0.0));
        for fraction in [0.13, 0.5, 0.77] {
            let t = fraction * plan.duration();
            let now = plan.evaluate(t).unwrap();
            let motion = [
                now.q.clone(),
                now.qd.clone(),
                now.qdd.clone(),
                at_derivative(&plan, t, 3),
                at_derivative(&plan, t, 4),
            ];
            let point = arm
                .inverse_dynamics(&link_motion(&motion), base, None)
                .unwrap();
            for (name, got, want) in [
                ("theta", &now.flexible.theta, &point.theta),
                ("theta_dot", &now.flexible.theta_dot, &point.theta_dot),
                ("theta_ddot", &now.flexible.theta_ddot, &point.theta_ddot),
                ("u", &now.flexible.u, &point.u),
                ("tau", &now.flexible.tau, &point.tau),
            ] {
                assert!(
                    relative(got, want) < 1e-10,
                    "{base:?} t={t} {name}: {got:?} vs {want:?}"
                );
            }
            // δ = τ/k, and the deflection is visible (θ ≠ q, θ̇ ≠ q̇, θ̈ ≠ q̈)
            let largest = |a: &[f64], b: &[f64]| {
                a.iter()
                    .zip(b)
                    .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()))
            };
            for i in 0..7 {
                let k = arm.joints().stiffness[i];
                assert!((now.deflection[i] - now.flexible.tau[i] / k).abs() < 1e-15);
            }
            assert!(largest(&now.flexible.theta, &now.q) > 5e-4);
            assert!(largest(&now.flexible.theta_dot, &now.qd) > 5e-4);
            assert!(largest(&now.flexible.theta_ddot, &now.qdd) > 5e-4);
        }
    }
}

/// The ratio of every limited quantity to its bound at each sample of segment `k` of `plan`
/// (channels: motor torque and joint speed per joint, base moment and force), with the samples'
/// `s`.
fn sample_ratios(plan: &Plan, k: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = plan.arm().dof();
    let limits = plan.limits();
    let samples = plan.samples();
    let durations = plan.segment_durations();
    let t0: f64 = durations[..k].iter().sum();
    let (mut s, mut channels) = (Vec::new(), vec![Vec::new(); 2 * n + 2]);
    for (row, t) in samples.t.iter().enumerate() {
        if *t < t0 - 1e-9 || *t > t0 + durations[k] + 1e-9 {
            continue;
        }
        s.push((t - t0) / durations[k]);
        for i in 0..n {
            channels[i].push(samples.u[row * n + i].abs() / limits.motor_torque[i]);
            channels[n + i].push(samples.qd[row * n + i].abs() / limits.joint_speed[i]);
        }
        let f = &samples.base_wrench[row * 6..row * 6 + 6];
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        channels[2 * n].push(limits.base_torque.map_or(0.0, |l| norm(&f[..3]) / l));
        channels[2 * n + 1].push(limits.base_force.map_or(0.0, |l| norm(&f[3..]) / l));
    }
    (s, channels)
}

/// Peak refinement (module docs of `slew`): the samples beyond the uniform 512 per segment sit
/// at the vertices of peaks within 2% of their limits. So every sample off the uniform grid is
/// where some quantity is within about 2% of its limit, and every local peak of a quantity above
/// 98% of its limit is sampled at its top (the parabola through it and its neighbours peaks
/// there, not up to half an interval away as on the bare grid).
#[test]
fn refined_samples_sit_on_the_tops_of_the_near_limit_peaks() {
    let arm = space_arm();
    let waypoint = vec![0.3, -0.2, 0.1, 0.5, -0.3, 0.2, 0.4];
    // held with both base limits (the moment binds), held with a base force limit that binds,
    // free (a motor torque binds)
    let motor = space_limits(BaseMode::Free).motor_torque;
    let force_bound = Limits::new(motor.clone(), vec![0.5], Some(5.0), None).unwrap();
    for (base, limits) in [
        (BaseMode::Held, space_limits(BaseMode::Held)),
        (BaseMode::Held, force_bound),
        (BaseMode::Free, space_limits(BaseMode::Free)),
    ] {
        let plan = plan_slew(
            &arm,
            &GOAL,
            None,
            &limits,
            base,
            std::slice::from_ref(&waypoint),
        )
        .unwrap();
        for k in 0..2 {
            let (s, channels) = sample_ratios(&plan, k);
            for (j, sj) in s.iter().enumerate() {
                let on_grid = (sj * 512.0 - (sj * 512.0).round()).abs() < 1e-9;
                let worst = channels.iter().map(|c| c[j]).fold(0.0_f64, f64::max);
                assert!(
                    on_grid || worst > 0.975,
                    "{base:?} segment {k}: a sample at s = {sj} where the largest ratio is {worst}"
                );
            }
            let mut peaks = Vec::new();
            for (c, ratios) in channels.iter().enumerate() {
                for j in 1..s.len() - 1 {
                    let (a, b, d) = (ratios[j - 1], ratios[j], ratios[j + 1]);
                    if b >= 0.98 && b > a && b > d {
                        // the vertex of the parabola through the three samples
                        let (x0, x1, x2) = (s[j - 1], s[j], s[j + 1]);
                        let (d01, d12) = ((b - a) / (x1 - x0), (d - b) / (x2 - x1));
                        let curvature = (d12 - d01) / (x2 - x0);
                        let vertex = 0.5 * (x0 + x1) - d01 / (2.0 * curvature);
                        // refined: 1e-9 or closer; on the bare grid up to 1e-3
                        assert!(
                            (vertex - x1).abs() < 1e-6,
                            "{base:?} segment {k} channel {c}: peak sampled at s = {x1}, its top \
                             is at {vertex}"
                        );
                        peaks.push(c);
                    }
                }
            }
            // the binding limit's peak is among them (so the check says something)
            assert!(!peaks.is_empty(), "{base:?} segment {k}");
        }
    }
}

/// The duration search: when the speed bound alone allows every other limit, the duration is
/// its closed form `T = |Δ|max σ'(½) / q̇_max` to round-off (no bisection); otherwise the binding
/// limit is active to the bisection's relative 1e-10 in `w = 1/T` (its ratio, which scales as
/// at most `w⁴`, within `4e-10` below 1), in every segment.
#[test]
fn durations_are_exact_for_the_speed_bound_and_bisected_to_1e_10_otherwise() {
    let arm = space_arm();
    // σ'(½) = 315/128; joint 3 moves farthest (1 rad)
    let slow = Limits::new(vec![1e4], vec![0.05], None, None).unwrap();
    for base in [BaseMode::Held, BaseMode::Free] {
        let plan = plan_slew(&arm, &GOAL, None, &slow, base, &[]).unwrap();
        let expected = 1.0 * (315.0 / 128.0) / 0.05;
        assert!(
            (plan.duration() / expected - 1.0).abs() < 1e-14,
            "{} vs {expected}",
            plan.duration()
        );
    }
    let waypoint = vec![0.3, -0.2, 0.1, 0.5, -0.3, 0.2, 0.4];
    for base in [BaseMode::Held, BaseMode::Free] {
        let plan = plan_slew(
            &arm,
            &GOAL,
            None,
            &space_limits(base),
            base,
            std::slice::from_ref(&waypoint),
        )
        .unwrap();
        for b in plan.bindings() {
            let ratio = b.value / b.limit;
            assert!(
                ratio <= 1.0 && ratio > 1.0 - 4e-10,
                "{b:?}: 1 - {}",
                1.0 - ratio
            );
        }
    }
}

/// Per-step tables whose steps end at an infinite time are refused (not tables of NaN).
#[test]
fn references_that_end_at_an_infinite_time_are_refused() {
    let plan = plan_slew(
        &space_arm(),
        &GOAL,
        None,
        &space_limits(BaseMode::Held),
        BaseMode::Held,
        &[],
    )
    .unwrap();
    // 1e308 s is a valid step, but three of them overflow
    let err = plan.reference(1e308, Some(3)).unwrap_err();
    assert_eq!(
        err.to_string(),
        "dt: 3 steps of 1e308 s do not end at a finite time"
    );
}

/// The planned base pose of a free base follows the base twist the plan gives: `ṙ = R v` and
/// `quat' = ½ quat ⊗ ω` (body-frame twist, `quat` as `(x, y, z, w)`). Checked step by step on
/// the reference's poses: the rotation from one pose to the next is `ω dt` and the displacement
/// `R v dt`, with the twist at the step's middle (midpoint rule, `O(dt²)`), and every attitude is
/// a unit quaternion. The tables' last pose is where the sample table's integration in `s` ends.
#[test]
fn the_planned_base_pose_follows_the_planned_twist() {
    let product = |a: &[f64], b: &[f64]| -> [f64; 4] {
        let (av, bv) = ([a[0], a[1], a[2]], [b[0], b[1], b[2]]);
        let cross = [
            av[1] * bv[2] - av[2] * bv[1],
            av[2] * bv[0] - av[0] * bv[2],
            av[0] * bv[1] - av[1] * bv[0],
        ];
        let dot = av[0] * bv[0] + av[1] * bv[1] + av[2] * bv[2];
        let v: [f64; 3] = std::array::from_fn(|i| a[3] * bv[i] + b[3] * av[i] + cross[i]);
        [v[0], v[1], v[2], a[3] * b[3] - dot]
    };
    let conjugate = |q: &[f64]| [-q[0], -q[1], -q[2], q[3]];
    let plan = plan_slew(
        &space_arm(),
        &GOAL,
        None,
        &space_limits(BaseMode::Free),
        BaseMode::Free,
        &[],
    )
    .unwrap();
    let steps = 2000;
    let dt = plan.duration() / steps as f64;
    let r = plan.reference(dt, Some(steps)).unwrap();
    let (mut largest_w, mut largest_v) = (0.0_f64, 0.0_f64);
    let (mut error_w, mut error_v) = (0.0_f64, 0.0_f64);
    for k in (0..steps).step_by(50) {
        let (a, b) = (
            &r.base_pose[7 * k..7 * k + 7],
            &r.base_pose[7 * k + 7..7 * k + 14],
        );
        for q in [&a[3..], &b[3..]] {
            let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!((norm - 1.0).abs() < 1e-12, "step {k}: |quat| = {norm}");
        }
        let twist = plan
            .evaluate((k as f64 + 0.5) * dt)
            .unwrap()
            .flexible
            .base_twist;
        let relative = product(&conjugate(&a[3..]), &b[3..]);
        for i in 0..3 {
            let rate = 2.0 * relative[i] / dt;
            error_w = error_w.max((rate - twist[i]).abs());
            largest_w = largest_w.max(twist[i].abs());
        }
        // R v at the middle: v rotated by the attitude halfway
        let half: Vec<f64> = (0..4).map(|i| 0.5 * (a[3 + i] + b[3 + i])).collect();
        let norm = half.iter().map(|x| x * x).sum::<f64>().sqrt();
        let half: Vec<f64> = half.iter().map(|x| x / norm).collect();
        let v = [twist[3], twist[4], twist[5], 0.0];
        let rotated = product(&product(&half, &v), &conjugate(&half));
        for i in 0..3 {
            let rate = (b[i] - a[i]) / dt;
            error_v = error_v.max((rate - rotated[i]).abs());
            largest_v = largest_v.max(rotated[i].abs());
        }
    }
    assert!(
        largest_w > 1e-3 && largest_v > 1e-3,
        "{largest_w} {largest_v}"
    );
    assert!(error_w < 1e-5 * largest_w, "{error_w} of {largest_w}");
    assert!(error_v < 1e-5 * largest_v, "{error_v} of {largest_v}");
    // the sample table's pose, integrated in s over the samples, ends where this one does
    let samples = plan.samples();
    let last = samples.t.len() - 1;
    let (mine, theirs) = (&samples.base_pose[7 * last..], &r.base_pose[7 * steps..]);
    for i in 0..7 {
        assert!((mine[i] - theirs[i]).abs() < 1e-9, "{mine:?} vs {theirs:?}");
    }
}

/// A plan shorter than a second: its per-step tables after the end still hold the goal at rest
/// (the rest point is taken after the end, whatever the plan's length).
#[test]
fn a_short_plans_tables_hold_the_goal_after_it() {
    let goal: Vec<f64> = GOAL.iter().map(|g| 1e-4 * g).collect();
    let plan = plan_slew(
        &space_arm(),
        &goal,
        None,
        &space_limits(BaseMode::Held),
        BaseMode::Held,
        &[],
    )
    .unwrap();
    assert!(plan.duration() < 0.5, "{}", plan.duration());
    let dt = 0.01;
    let steps = (plan.duration() / dt).ceil() as usize + 10;
    let r = plan.reference(dt, Some(steps)).unwrap();
    for k in steps - 5..=steps {
        let after = plan.evaluate(k as f64 * dt).unwrap();
        assert_eq!(r.q[k * 7..(k + 1) * 7], goal[..], "row {k}");
        assert_eq!(after.q, goal);
        if k < steps {
            assert_eq!(
                r.theta_ref[k * 7..(k + 1) * 7],
                after.flexible.theta[..],
                "row {k}"
            );
        }
    }
}

#[test]
fn plans_stay_between_the_shortest_and_the_longest_duration_planned() {
    // (issue 24) a speed limit asking for 7e9 s gave a plan of that length, though no segment
    // is planned longer than 1e9 s; limits too loose to bind at 1 ns were reported as binding
    let message = |r: orbitflex::Result<Plan>| r.unwrap_err().to_string();
    let arm = space_arm();
    let slow = Limits::new(vec![1e-10], vec![1e-10], None, None).unwrap();
    let err = message(plan_slew(&arm, &GOAL, None, &slow, BaseMode::Held, &[]));
    assert!(
        err.starts_with("limits: no duration up to 1e9 s meets them: ")
            && err.contains(" at 1e9 s, over its limit of 1e-10"),
        "{err}"
    );
    let loose = Limits::new(vec![1e300], vec![1e300], None, None).unwrap();
    let err = message(plan_slew(&arm, &GOAL, None, &loose, BaseMode::Free, &[]));
    assert!(err.contains("so none of them binds"), "{err}");
    // just within: the speed limit alone gives 5.5e8 s (|Δ| σ'(½) / q̇_max)
    let long = Limits::new(vec![1e-6], vec![4e-9], None, None).unwrap();
    let plan = plan_slew(&arm, &GOAL, None, &long, BaseMode::Held, &[]).unwrap();
    assert!(
        plan.duration() > 5e8 && plan.duration() <= 1e9,
        "{}",
        plan.duration()
    );
    // a slew too large for floating point names the stop it ends at (on continuous joints:
    // the space arm's revolute joints would refuse such a goal for its position limits)
    let huge = [1e100; 7];
    let continuous =
        orbitflex::SPACE_ARM_URDF.replace(r#"type="revolute""#, r#"type="continuous""#);
    let robot = Robot::from_urdf_string(&continuous, &orbitflex::UrdfOptions::default()).unwrap();
    let free_arm = FlexibleArm::new(robot, FlexibleJoints::space_arm()).unwrap();
    let err = message(plan_slew(
        &free_arm,
        &huge,
        None,
        &space_limits(BaseMode::Held),
        BaseMode::Held,
        &[],
    ));
    assert!(
        err.starts_with("q_goal: too large for floating point: the slew from q_start"),
        "{err}"
    );
}

/// `σ⁽ᵏ⁾(s)` by compensated Horner on the monomial coefficients (Graillat, Langlois & Louvet's
/// error-free transformations): as accurate as Horner in twice the working precision, so a
/// reference to about 1e-30 relative of the terms' scale.
fn sigma_reference(s: f64, k: usize) -> f64 {
    const C: [f64; 10] = [0.0, 0.0, 0.0, 0.0, 0.0, 126.0, -420.0, 540.0, -315.0, 70.0];
    let two_sum = |a: f64, b: f64| {
        let x = a + b;
        let z = x - a;
        (x, (a - (x - z)) + (b - z))
    };
    let two_product = |a: f64, b: f64| {
        let x = a * b;
        (x, a.mul_add(b, -x))
    };
    let (mut hi, mut lo) = (0.0, 0.0);
    for i in (k..10).rev() {
        let falling: f64 = (0..k).map(|j| (i - j) as f64).product();
        let (p, e_p) = two_product(hi, s);
        let (sum, e_s) = two_sum(p, C[i] * falling);
        hi = sum;
        lo = lo * s + (e_p + e_s);
    }
    hi + lo
}

#[test]
fn the_path_shape_is_accurate_to_a_few_ulps() {
    // The monomial form 126 s⁵ − 420 s⁶ + … cancels (126 − 420 + 540 − 315 + 70 = 1): 350 ulps
    // off in σ' at s = 0.76, a million near s = 1, and its last bits moved with the processor.
    // The factored forms are within a few ulps of σ⁽ᵏ⁾, or, near a root of σ''' or σ'''', of
    // the size of the factors that cancel there (the function's own conditioning in s).
    for i in 0..=4096 {
        let s = i as f64 / 4096.0 + if i % 3 == 1 { 1e-7 } else { 0.0 };
        let s = s.min(1.0);
        let got = orbitflex::planning::sigma(s);
        let u = s * (1.0 - s);
        for (k, &value) in got.iter().enumerate() {
            let want = sigma_reference(s, k);
            // relative to the value, or near a root to the size of the factors that cancel there
            let size = match k {
                3 => want.abs().max(2520.0 * 3.0 * u * u),
                4 => want.abs().max(15120.0 * u),
                _ => want.abs(),
            };
            let ulps = (value - want).abs() / (f64::EPSILON * size.max(f64::MIN_POSITIVE));
            assert!(
                ulps <= 16.0,
                "σ^({k})({s}) = {value} vs {want}: {ulps:.1} ulps"
            );
        }
    }
    assert_eq!(orbitflex::planning::sigma(0.0), [0.0; 5]);
    assert_eq!(orbitflex::planning::sigma(1.0)[..3], [1.0, 0.0, 0.0]);
}

#[test]
fn the_model_s_limits_are_read_planned_under_and_enforced() {
    use orbitflex::{JointLimits, UrdfOptions};
    let robot = Robot::space_arm();
    assert_eq!(
        robot.velocity_limits(),
        [0.15, 0.15, 0.15, 0.2, 0.3, 0.3, 0.4]
    );
    assert_eq!(
        robot.effort_limits(),
        [250.0, 250.0, 250.0, 200.0, 100.0, 80.0, 60.0]
    );
    assert_eq!(robot.position_limits()[6], (-3.05, 3.05));
    assert_eq!(
        robot.joints()[3].limits,
        JointLimits {
            position: Some((-2.6, 2.6)),
            velocity: Some(0.2),
            effort: Some(200.0),
        }
    );
    // a continuous joint turns freely, whatever its <limit> says of lower and upper
    let continuous = orbitflex::SPACE_ARM_URDF.replacen(
        r#"name="shoulder_roll" type="revolute""#,
        r#"name="shoulder_roll" type="continuous""#,
        1,
    );
    let robot_c = Robot::from_urdf_string(&continuous, &UrdfOptions::default()).unwrap();
    assert_eq!(
        robot_c.position_limits()[0],
        (f64::NEG_INFINITY, f64::INFINITY)
    );
    assert_eq!(robot_c.velocity_limits()[0], 0.15);
    // a revolute <limit> with neither bound states no range; with one, the other is 0 (URDF)
    let partial = orbitflex::SPACE_ARM_URDF
        .replacen(
            r#"lower="-3.05" upper="3.05" effort="250""#,
            r#"effort="250""#,
            1,
        )
        .replacen(
            r#"lower="-2.6" upper="2.6" effort="250""#,
            r#"lower="-2.6" effort="250""#,
            1,
        );
    let robot_p = Robot::from_urdf_string(&partial, &UrdfOptions::default()).unwrap();
    assert_eq!(robot_p.joints()[0].limits.position, None);
    assert_eq!(robot_p.joints()[0].limits.effort, Some(250.0));
    assert_eq!(robot_p.joints()[1].limits.position, Some((-2.6, 0.0)));
    // Limits::from_robot: effort as the motor torque, velocity as the joint speed
    let limits = Limits::from_robot(&robot, None, Some(40.0)).unwrap();
    assert_eq!(limits.motor_torque, robot.effort_limits());
    assert_eq!(limits.joint_speed, robot.velocity_limits());
    assert_eq!(limits.base_torque, Some(40.0));
    let limits = Limits::from_robot(&robot, None, None).unwrap();
    assert!(limits.exceeding(&robot).unwrap().is_empty());
    let fast = Limits::new(vec![250.0], vec![0.2], None, None).unwrap();
    assert_eq!(
        fast.exceeding(&robot).unwrap(),
        [
            "motor_torque (N·m): 'elbow_pitch' 250 > 200, 'wrist_pitch' 250 > 100, 'wrist_yaw' \
             250 > 80, 'wrist_roll' 250 > 60",
            "joint_speed (rad/s): 'shoulder_roll' 0.2 > 0.15, 'shoulder_yaw' 0.2 > 0.15, \
             'shoulder_pitch' 0.2 > 0.15"
        ]
    );
    // a model without them says so, per joint
    let unlimited = orbitflex::SPACE_ARM_URDF.replace(r#" effort="80" velocity="0.3""#, "");
    let robot_u = Robot::from_urdf_string(&unlimited, &UrdfOptions::default()).unwrap();
    assert_eq!(robot_u.velocity_limits()[5], f64::INFINITY);
    assert_eq!(robot_u.joints()[5].limits.position, Some((-2.0, 2.0)));
    let err = Limits::from_robot(&robot_u, None, None)
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "motor_torque: the model (<urdf string>) states no effort limit (<limit effort=\"…\">), or \
         a zero one, for 'wrist_yaw'; give motor_torque yourself"
    );
    // the stops must lie within the position limits
    let arm = FlexibleArm::new(robot, FlexibleJoints::space_arm()).unwrap();
    let mut goal = vec![0.0; 7];
    goal[6] = 5.0;
    let err = plan_slew(&arm, &goal, None, &limits, BaseMode::Free, &[])
        .unwrap_err()
        .to_string();
    assert_eq!(
        err,
        "q_goal: joint 6 ('wrist_roll') = 5 rad is outside its position limits [-3.05, 3.05] rad \
         (the model's <limit lower upper>)"
    );
    for bound in [-3.05, 3.05] {
        goal[6] = bound; // on the bound is within
        assert!(plan_slew(&arm, &goal, None, &limits, BaseMode::Free, &[]).is_ok());
    }
    // a zero effort limit is no limit to plan under, said as such
    let zero = orbitflex::SPACE_ARM_URDF.replacen(r#"effort="60""#, r#"effort="0""#, 1);
    let robot_z = Robot::from_urdf_string(&zero, &UrdfOptions::default()).unwrap();
    let err = Limits::from_robot(&robot_z, None, None)
        .unwrap_err()
        .to_string();
    assert!(err.contains("or a zero one, for 'wrist_roll' (0)"), "{err}");
    // the builder checks what it is given, naming the joint
    use orbitflex::spatial::{Inertia, Mat3, Transform, Vec3};
    let bad = |limits: JointLimits| {
        let link = Inertia::from_com(2.0, Vec3::new(0.5, 0.0, 0.0), Mat3::identity() * 0.1);
        let bus = Inertia::from_com(100.0, Vec3::zeros(), Mat3::identity() * 20.0);
        orbitflex::RobotBuilder::new("one", "bus", bus)
            .joint("hinge", Transform::identity(), Vec3::z(), "arm", link)
            .limits(limits)
            .build()
            .map(|r| r.joints()[0].limits)
            .map_err(|e| e.to_string())
    };
    assert_eq!(
        bad(JointLimits {
            position: Some((1.0, -1.0)),
            ..JointLimits::NONE
        })
        .unwrap_err(),
        "<builder>: joint 'hinge': position limits: expected finite lower <= upper (rad), given \
         lower = 1, upper = -1"
    );
    for (velocity, effort) in [(Some(-1.0), None), (None, Some(f64::NAN))] {
        assert!(bad(JointLimits {
            velocity,
            effort,
            ..JointLimits::NONE
        })
        .is_err());
    }
    let fine = JointLimits {
        position: Some((-1.0, 1.0)),
        velocity: Some(0.0),
        effort: Some(3.0),
    };
    assert_eq!(bad(fine).unwrap(), fine);
}

/// Per-axis base bounds (`BaseLimits`), closed forms on a rotor: a disc (`I_l = 3` kg·m² about
/// its axis) on a joint along the bus's z axis (`I_b = 50`), every centre of mass on that axis.
/// Free: `ω_z = −I_l/(I_b + I_l) q̇`, so a bound `L` on `|ω_z|` gives
/// `T = I_l/(I_b + I_l) Δ σ'max / L`, `σ'max = 630/256`. Held: `n_z = I_l q̈`, so
/// `T = √(I_l Δ σ''max / L)`, `σ''max = 2520 (3/14)³/√7`. The planner bisects to 1e-10 and
/// refines its samples onto the peak (a parabola's vertex, O(h³) with h = 1/512): 1e-7.
#[test]
fn base_axis_limits_closed_forms_on_a_rotor() {
    use orbitflex::planning::{BaseBound, BaseLimits};
    let urdf = r#"<robot name="rotor">
<link name="bus"><inertial><origin xyz="0 0 0"/><mass value="100"/>
  <inertia ixx="30" iyy="40" izz="50" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j" type="revolute"><parent link="bus"/><child link="disc"/><origin xyz="0 0 0.5"/>
  <axis xyz="0 0 1"/><limit effort="1e6" velocity="1e3" lower="-10" upper="10"/></joint>
<link name="disc"><inertial><origin xyz="0 0 0.2"/><mass value="10"/>
  <inertia ixx="2" iyy="2" izz="3" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>"#;
    let robot = Robot::from_urdf_string(urdf, &orbitflex::UrdfOptions::default()).unwrap();
    let joints = FlexibleJoints::new(vec![1e4], vec![0.5], vec![0.0], vec![0.0]).unwrap();
    let arm = FlexibleArm::new(robot, joints).unwrap();
    let loose = Limits::uniform(1e6, 1e3).unwrap();
    let (rate, torque) = (0.01, 2.0);
    let free = loose
        .clone()
        .with_base_axes(BaseLimits {
            rate: Some([1.0, 1.0, rate]),
            ..Default::default()
        })
        .unwrap();
    let plan = plan_slew(&arm, &[1.0], None, &free, BaseMode::Free, &[]).unwrap();
    let expected = 3.0 / 53.0 * (630.0 / 256.0) / rate;
    assert!(
        (plan.duration() / expected - 1.0).abs() < 1e-7,
        "{}",
        plan.duration()
    );
    let b = plan.binding();
    assert_eq!(
        (b.constraint, b.joint, b.axis),
        (Constraint::Base(BaseBound::RateAxis), None, Some(2))
    );
    assert!((b.value / rate - 1.0).abs() < 1e-7);
    let held = loose
        .with_base_axes(BaseLimits {
            torque: Some([1e3, 1e3, torque]),
            ..Default::default()
        })
        .unwrap();
    let plan = plan_slew(&arm, &[1.0], None, &held, BaseMode::Held, &[]).unwrap();
    let sigma2 = 2520.0 * (3.0f64 / 14.0).powi(3) / 7f64.sqrt();
    let expected = (3.0 * sigma2 / torque).sqrt();
    assert!(
        (plan.duration() / expected - 1.0).abs() < 1e-7,
        "{}",
        plan.duration()
    );
    assert_eq!(plan.binding().axis, Some(2));
    assert_eq!(plan.binding().constraint.name(), "base_torque_axes");
    // a free bound on a held plan is refused, naming it
    let e = plan_slew(&arm, &[1.0], None, &free, BaseMode::Held, &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("limits.base_rate_axes: bounds the motion of a free-floating base"),
        "{e}"
    );
}

/// Held moment bounds about the system centre of mass (`BasePoint::SystemCom`), closed form on a
/// one-link arm: a bus of mass `M = 100` kg with its centre at its origin, and a link on a joint
/// at the origin along `z_B`, of mass `m = 10` kg, centre at `l = 0.5` m from the axis and
/// `I_l = 0.2` kg·m² about its centre. The link's centre `p = l (cos q, sin q, 0)` moves on a
/// circle, so the holding force is `F_B = m p̈` and its moment about the origin is
/// `n_B = (I_l + m l²) q̈ ẑ`. The system COM is `r_c = m p / (M + m)`, and with
/// `p × p̈ = l² q̈ ẑ` the moment about it is
/// `n_C = n_B − r_c × F_B = (I_l + μ l²) q̈ ẑ`, `μ = m M / (M + m)` the reduced mass: the link
/// turns about the shared centre, not about the joint. A bound `L` on `|n_z|` gives
/// `T = √(I Δ σ''max / L)` with `I = I_l + μ l²` about the COM and `I_l + m l²` about the origin
/// (tolerance as in the rotor test above).
#[test]
fn held_moment_bounds_about_the_system_com_closed_form() {
    use orbitflex::planning::{BaseBound, BaseLimits, BasePoint};
    let urdf = r#"<robot name="one_link">
<link name="bus"><inertial><origin xyz="0 0 0"/><mass value="100"/>
  <inertia ixx="30" iyy="40" izz="50" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j" type="revolute"><parent link="bus"/><child link="link"/><origin xyz="0 0 0"/>
  <axis xyz="0 0 1"/><limit effort="1e6" velocity="1e3" lower="-10" upper="10"/></joint>
<link name="link"><inertial><origin xyz="0.5 0 0"/><mass value="10"/>
  <inertia ixx="0.1" iyy="0.2" izz="0.2" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>"#;
    let robot = Robot::from_urdf_string(urdf, &orbitflex::UrdfOptions::default()).unwrap();
    let joints = FlexibleJoints::new(vec![1e4], vec![0.5], vec![0.0], vec![0.0]).unwrap();
    let arm = FlexibleArm::new(robot, joints).unwrap();
    let (big_m, m, l, i_l) = (100.0, 10.0, 0.5, 0.2);
    let mu = m * big_m / (big_m + m);
    let sigma2 = 2520.0 * (3.0f64 / 14.0).powi(3) / 7f64.sqrt();
    let (delta, torque) = (1.2, 0.8);
    for (point, inertia) in [
        (BasePoint::Origin, i_l + m * l * l),
        (BasePoint::SystemCom, i_l + mu * l * l),
    ] {
        for norm in [false, true] {
            let mut limits = Limits::uniform(1e6, 1e3)
                .unwrap()
                .with_base_axes(BaseLimits {
                    torque: (!norm).then_some([1e3, 1e3, torque]),
                    point,
                    ..Default::default()
                })
                .unwrap();
            if norm {
                limits.base_torque = Some(torque);
            }
            let plan = plan_slew(&arm, &[delta], None, &limits, BaseMode::Held, &[]).unwrap();
            let expected = (inertia * delta * sigma2 / torque).sqrt();
            assert!(
                (plan.duration() / expected - 1.0).abs() < 1e-7,
                "{point:?} norm {norm}: {} against {expected}",
                plan.duration()
            );
            let b = plan.binding();
            let want = if norm {
                (Constraint::BaseTorque, None)
            } else {
                (Constraint::Base(BaseBound::TorqueAxis), Some(2))
            };
            assert_eq!(
                (b.constraint, b.axis, b.point),
                (want.0, want.1, Some(point))
            );
            assert!((b.value / torque - 1.0).abs() < 1e-7, "{}", b.value);
            // at every sample the transferred moment is the closed form, and within the bound
            let s = plan.samples();
            for k in 0..s.t.len() {
                let f: [f64; 6] = s.base_wrench[6 * k..6 * k + 6].try_into().unwrap();
                let q = s.q[k];
                let com = [
                    m * l * q.cos() / (big_m + m),
                    m * l * q.sin() / (big_m + m),
                    0.0,
                ];
                let n = point.wrench(&f, &com);
                // round-off: a few ulps of the largest terms, `m l² (|q̈| + q̇²)`
                let scale = (i_l + m * l * l) * (s.qdd[k].abs() + s.qd[k] * s.qd[k]);
                let err = (n[2] - inertia * s.qdd[k]).abs();
                assert!(
                    err <= 1e-14 * scale + 1e-300,
                    "{point:?} sample {k}: {err:e}"
                );
                assert!(n[2].abs() <= torque * (1.0 + 1e-9));
                assert_eq!(&n[3..], &f[3..]);
            }
        }
    }
    // the origin's bindings name no point for the other limits
    let plain = plan_slew(
        &arm,
        &[delta],
        None,
        &Limits::uniform(1.0, 1e3).unwrap(),
        BaseMode::Held,
        &[],
    )
    .unwrap();
    assert_eq!(plain.binding().point, None);
    // a free base refuses the COM, saying why
    let com = Limits::uniform(1e6, 1e3)
        .unwrap()
        .with_base_axes(BaseLimits {
            rate_norm: Some(0.1),
            point: BasePoint::SystemCom,
            ..Default::default()
        })
        .unwrap();
    let e = plan_slew(&arm, &[delta], None, &com, BaseMode::Free, &[])
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("limits.base_point: \"com\" names the point a held base's moment bounds")
            && e.contains("the system COM stays still"),
        "{e}"
    );
}
