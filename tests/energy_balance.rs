//! The energy balance of a record (`Trajectory::energy_balance`, model §6.2): the arm's energy
//! changes by the motors' work less what the damping dissipates, to the quadrature's O(h²).

use orbitflex::control::Quintic;
use orbitflex::testing::{random_chain, Rng};
use orbitflex::{FlexibleArm, FlexibleJoints, MotorPD, Schedule, Wrenches};

fn arm(n: usize, seed: u64, damping: f64, motor_damping: f64) -> FlexibleArm {
    let mut rng = Rng::new(seed);
    let joints = FlexibleJoints::new(
        rng.vector(n, 200.0, 800.0),
        rng.vector(n, 0.05, 0.2),
        vec![damping; n],
        vec![motor_damping; n],
    )
    .unwrap();
    FlexibleArm::new(random_chain(n, seed), joints).unwrap()
}

/// A damped arm slewed by a motor PD on a quintic over `duration` s, `steps` steps of `dt`.
fn slew(arm: &FlexibleArm, dt: f64, steps: usize) -> orbitflex::Trajectory {
    let n = arm.robot().dof();
    let quintic = Quintic::new(&vec![0.0; n], &vec![0.5; n], 0.3).unwrap();
    let (theta, theta_dot) = quintic.schedules(dt, steps).unwrap();
    let mut pd = MotorPD::new(
        vec![40.0; n],
        vec![2.0; n],
        theta,
        theta_dot,
        Schedule::Zero,
    )
    .unwrap();
    arm.simulate(&arm.rest_state(), dt, steps, &mut pd, &Wrenches::ZERO)
        .unwrap()
}

/// The residual is the trapezoid rule's error on smooth power curves: O(h²). Halving the step
/// divides it by about 4 (the ratio of two O(h²) errors tends to 4; here within [3, 5]), and it
/// is a small share of the energy that flowed.
#[test]
fn the_balance_closes_to_second_order_in_the_step() {
    let arm = arm(4, 3, 0.8, 0.05);
    let balance = |dt: f64| {
        slew(&arm, dt, (0.4 / dt).round() as usize)
            .energy_balance(&arm)
            .unwrap()
    };
    let (coarse, fine) = (balance(2e-3), balance(1e-3));
    assert!(
        coarse.motor_work > 0.0 && coarse.dissipated > 0.0,
        "{coarse:?}"
    );
    let flow = coarse.motor_work.abs() + coarse.dissipated;
    assert!(coarse.residual().abs() < 1e-3 * flow, "{coarse:?}");
    let ratio = coarse.residual() / fine.residual();
    assert!(
        (3.0..5.0).contains(&ratio),
        "residual ratio {ratio}: {coarse:?} {fine:?}"
    );
}

/// The steps add up to the totals, and each step's change is the energy difference of its rows.
#[test]
fn steps_add_up_to_the_balance() {
    let arm = arm(3, 5, 0.5, 0.02);
    let traj = slew(&arm, 1e-3, 200);
    let steps = traj.energy_steps(&arm).unwrap();
    assert_eq!(steps.len(), 200);
    let energy = traj.rows().energy(&arm);
    for (k, s) in steps.iter().enumerate() {
        assert_eq!(s[0], energy[k + 1] - energy[k]);
        assert!(s[2] >= 0.0);
    }
    let total = traj.energy_balance(&arm).unwrap();
    assert_eq!(total.change, energy[200] - energy[0]);
    // plain sums differ from the compensated ones by at most 200 roundings of the total
    let (w, d): (f64, f64) = (
        steps.iter().map(|s| s[1]).sum(),
        steps.iter().map(|s| s[2]).sum(),
    );
    assert!((w - total.motor_work).abs() <= 200.0 * f64::EPSILON * w.abs());
    assert!((d - total.dissipated).abs() <= 200.0 * f64::EPSILON * d.abs());
}

/// Without damping and torque nothing flows: no work, nothing dissipated, exactly.
#[test]
fn an_undamped_free_arm_has_no_flow() {
    let arm = arm(3, 9, 0.0, 0.0);
    let mut x0 = arm.rest_state();
    x0[arm.layout().qd()].copy_from_slice(&[0.3; 3]);
    let traj = arm
        .simulate(&x0, 1e-3, 300, &mut Schedule::Zero, &Wrenches::ZERO)
        .unwrap();
    let b = traj.energy_balance(&arm).unwrap();
    assert_eq!((b.motor_work, b.dissipated), (0.0, 0.0));
}

#[test]
fn another_arm_is_refused() {
    let traj = slew(&arm(3, 5, 0.5, 0.02), 1e-3, 10);
    let e = traj.energy_balance(&arm(4, 5, 0.5, 0.02)).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("arm: expected an arm with the record's state of"),
        "{e}"
    );
}
