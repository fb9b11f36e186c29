//! Capture in a run (issue 29, phase 2): the target propagated in the same RK4 step as the arm,
//! the trigger at the right step and not at all when the EE never gets near, momentum across the
//! event, the target welded to the EE after it, and bad tolerances refused.

use orbitflex::capture::{
    simulate_capture_into, Approach, CaptureRecord, CaptureRun, CaptureWhen, Target, TargetMotion,
    TARGET_STATE_LEN,
};
use orbitflex::integrate::{
    Drive, MotorPD, OdeSystem, Rk4, Run, Schedule, Trajectory, Unobserved, Wrenches,
};
use orbitflex::spatial::{normalise_quaternion, Mat3, Vec3};
use orbitflex::{FlexibleArm, FlexibleJoints, Inputs, ModelWorkspace, Robot};

fn space_arm() -> FlexibleArm {
    FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap()
}

/// A 200 kg target whose handle frame is the EE frame at rest, shifted by `offset` (m,
/// inertial), drifting with `velocity` (m/s, inertial = target axes here) and spinning at
/// `omega` (rad/s, target axes).
fn target_near_ee(
    arm: &FlexibleArm,
    offset: [f64; 3],
    velocity: [f64; 3],
    omega: [f64; 3],
) -> Target {
    let mut pose = arm.ee_pose(&arm.rest_state(), 0);
    for i in 0..3 {
        pose[i] += offset[i];
    }
    // the target frame has the EE's axes and the handle at its origin: its velocity in target
    // axes is the inertial one turned by the EE's attitude
    let axes = orbitflex::spatial::quaternion_to_rotation(&pose[3..]);
    let v = axes.transpose() * Vec3::from(velocity);
    Target::new(
        200.0,
        Mat3::from_diagonal(&Vec3::new(40.0, 50.0, 60.0)),
        &pose,
        &[omega[0], omega[1], omega[2], v[0], v[1], v[2]],
        &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
    )
    .unwrap()
}

fn run_with(
    arm: &FlexibleArm,
    target: &Target,
    when: CaptureWhen,
    dt: f64,
    steps: usize,
    u: &mut dyn orbitflex::Controller,
) -> (Trajectory, CaptureRecord) {
    let x0 = arm.rest_state();
    let mut wrenches = Wrenches::ZERO;
    let mut drive = Drive::new(u, &mut wrenches);
    let run = Run::new(&x0, dt, steps);
    let mut traj = Trajectory::reserved(arm.layout(), steps, 1).unwrap();
    let capturing = CaptureRun {
        target,
        when,
        ee: None,
    };
    let record = simulate_capture_into(
        arm,
        &run,
        &mut drive,
        &capturing,
        &mut Unobserved,
        &mut traj,
    )
    .unwrap();
    (traj, record)
}

/// The arm at rest with no torque stays at rest exactly; the target drifts towards the EE at
/// 1 cm/s from 0.1 m: its distance at step k is 0.1 − 0.01 k dt, so with dt = 0.01 s and a
/// tolerance of 0.05055 m the first step within it is k = 495 (0.0505 m, 5e-5 m inside; k = 494
/// is at 0.0506 m, 5e-5 m outside: far from round-off).
#[test]
fn the_capture_triggers_at_the_first_step_within_the_tolerances() {
    let arm = space_arm();
    let target = target_near_ee(&arm, [0.1, 0.0, 0.0], [-0.01, 0.0, 0.0], [0.0; 3]);
    let when = CaptureWhen::new(0.05055, 0.02, 0.01).unwrap();
    let mut zero = Schedule::Zero;
    let (traj, record) = run_with(&arm, &target, when, 0.01, 600, &mut zero);
    assert_eq!(record.events.len(), 1);
    let event = &record.events[0];
    assert_eq!(event.step, 495);
    assert_eq!(event.time, 495.0 * 0.01);
    assert!((event.approach.distance - 0.0505).abs() < 1e-12);
    assert!((event.approach.speed - 0.01).abs() < 1e-12);
    assert!(event.approach.angle < 1e-12);
    // the kept row at the event is the state before the impulse
    assert_eq!(traj.state(495), &event.x_before[..]);
    assert_eq!(&event.target_before[..], &record.target[495 * 13..496 * 13]);
    // one target row per arm row
    assert_eq!(record.rows(), traj.len());
    assert!(record.arm_after.is_some());
    // a head-on 200 kg target at 1 cm/s: the energy lost is positive and at most its kinetic
    // energy relative to the arm at rest (½ m v² = 0.01 J)
    assert!(event.energy_loss > 0.0 && event.energy_loss < 0.01);
    // the impulse the EE exerts pushes the target back (+x inertial); not exactly along x, since
    // the arm's inverse inertia at the EE is not isotropic. Its work on the relative motion is
    // the energy lost: ½ V_relᵀ F
    let work = 0.5
        * event
            .relative_twist
            .to_vector()
            .dot(&event.impulse.to_vector());
    assert!((work - event.energy_loss).abs() < 1e-12 * event.energy_loss);
    let ee = arm.ee_pose(&event.x_before, 0);
    let force = orbitflex::spatial::quaternion_to_rotation(&ee[3..]) * event.impulse.linear;
    assert!(
        force[0] > 2.0 * force[1].abs().max(force[2].abs()),
        "{force}"
    );
}

#[test]
fn no_capture_when_the_ee_never_gets_near() {
    let arm = space_arm();
    // moving away, tumbling
    let target = target_near_ee(&arm, [0.3, 0.0, 0.0], [0.01, 0.0, 0.0], [0.0, 0.0, 0.035]);
    let when = CaptureWhen::new(0.05, 0.05, 0.2).unwrap();
    let mut pd = pd(&arm);
    let (traj, record) = run_with(&arm, &target, when, 0.005, 400, &mut pd);
    assert!(record.events.is_empty());
    assert!(record.arm_after.is_none());
    // the arm's rows are those of the run without a target, bit for bit
    let mut pd = self::pd(&arm);
    let plain = arm
        .simulate(&arm.rest_state(), 0.005, 400, &mut pd, &Wrenches::ZERO)
        .unwrap();
    assert_eq!(traj.x, plain.x);
    assert_eq!(traj.u, plain.u);
}

fn pd(arm: &FlexibleArm) -> MotorPD {
    let n = arm.dof();
    MotorPD::new(
        vec![400.0; n],
        vec![150.0; n],
        Schedule::Constant(vec![0.05; n]),
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap()
}

/// `[arm | target]` as one system: the arm's derivative and the target's, both quaternions
/// renormalised after the step.
struct Pair<'a> {
    arm: &'a FlexibleArm,
    ws: ModelWorkspace,
    u: Vec<f64>,
    target: &'a Target,
}

impl OdeSystem for Pair<'_> {
    fn state_len(&self) -> usize {
        self.arm.layout().len() + TARGET_STATE_LEN
    }
    fn derivative(&mut self, x: &[f64], xdot: &mut [f64]) -> orbitflex::Result<()> {
        let len = self.arm.layout().len();
        self.arm.derivative(
            &mut self.ws,
            &x[..len],
            &Inputs::torques(&self.u),
            &mut xdot[..len],
        )?;
        TargetMotion {
            inertia: self.target.spatial_inertia(),
        }
        .derivative(&x[len..], &mut xdot[len..])
    }
    fn project(&mut self, x: &mut [f64]) {
        let layout = self.arm.layout();
        let len = layout.len();
        normalise_quaternion(&mut x[layout.quaternion()]);
        normalise_quaternion(&mut x[len + 3..len + 7]);
    }
}

/// Before the capture, each step is one RK4 step of the system `[arm | target]`: the same
/// numbers, bit for bit, as the run's rows (arm and target) with torques held.
#[test]
fn the_target_moves_in_the_same_rk4_step_as_the_arm() {
    let arm = space_arm();
    let target = target_near_ee(
        &arm,
        [0.4, 0.1, 0.0],
        [0.002, 0.0, 0.001],
        [0.01, 0.02, 0.035],
    );
    let when = CaptureWhen::new(1e-3, 1e-3, 1e-3).unwrap();
    let n = arm.dof();
    let torque = vec![0.3; n];
    let mut u = Schedule::Constant(torque.clone());
    let (traj, record) = run_with(&arm, &target, when, 0.002, 50, &mut u);
    assert!(record.events.is_empty());
    let len = arm.layout().len();
    let mut pair = Pair {
        arm: &arm,
        ws: ModelWorkspace::new(&arm),
        u: torque,
        target: &target,
    };
    let mut rk4 = Rk4::new(len + TARGET_STATE_LEN);
    let mut x: Vec<f64> = arm.rest_state();
    x.extend_from_slice(&target.state());
    for k in 0..50 {
        rk4.step(&mut pair, &mut x, 0.002).unwrap();
        assert_eq!(&x[..len], traj.state(k + 1), "arm, row {}", k + 1);
        assert_eq!(
            &x[len..],
            &record.target[(k + 1) * 13..(k + 2) * 13],
            "target, row {}",
            k + 1
        );
    }
}

/// A tumbling target caught by an arm that is moving under its PD: the total momentum of arm and
/// target just before equals the combined arm's just after, to 1e-12 relative (the impulse is
/// internal), and the target stays welded to the EE after (its handle at a fixed distance and
/// angle from the EE, its state consistent with the EE's).
#[test]
fn momentum_across_the_event_and_the_target_welded_after() {
    let arm = space_arm();
    // where the EE is at t* = 0.6 s under the PD: the handle (at the target's centre of mass,
    // which moves in a straight line) gets there at t*
    let (dt, meet) = (0.002, 300);
    let mut pd = self::pd(&arm);
    let plain = arm
        .simulate(&arm.rest_state(), dt, meet, &mut pd, &Wrenches::ZERO)
        .unwrap();
    let (start, end) = (
        arm.ee_pose(plain.state(0), 0),
        arm.ee_pose(plain.state(meet), 0),
    );
    let velocity = [-0.02, -0.01, 0.005];
    let t_meet = meet as f64 * dt;
    let offset: [f64; 3] = std::array::from_fn(|i| end[i] - start[i] - velocity[i] * t_meet);
    let target = target_near_ee(&arm, offset, velocity, [0.0, 0.01, 0.035]);
    let when = CaptureWhen::new(0.03, 0.5, 0.3).unwrap();
    let mut pd = self::pd(&arm);
    let (traj, record) = run_with(&arm, &target, when, dt, 1500, &mut pd);
    assert_eq!(record.events.len(), 1);
    let e = &record.events[0];
    let scale = e
        .momentum_before
        .iter()
        .map(|v| v.abs())
        .fold(0.0, f64::max);
    assert!(scale > 1e-3);
    for i in 0..6 {
        assert!(
            (e.momentum_before[i] - e.momentum_after[i]).abs() <= 1e-12 * scale,
            "momentum[{i}]: {} vs {}",
            e.momentum_before[i],
            e.momentum_after[i]
        );
    }
    // the total momentum along the run (arm and free target, then the combined arm): the row
    // at the event is the state before it, so it is the event's momentum before
    let h = record.momentum(&arm, &traj.t, &traj.x);
    let at = &h[e.step * 6..e.step * 6 + 6];
    for (i, (a, b)) in at.iter().zip(e.momentum_before).enumerate() {
        assert!((a - b).abs() <= 1e-14 * scale, "row momentum[{i}]");
    }
    // row 0 is the arm at rest and the free target: the target's momentum alone
    let h0 = target.momentum();
    for (i, (a, b)) in h[..6].iter().zip(h0).enumerate() {
        assert!(
            (a - b).abs() <= 1e-14 * scale,
            "row 0 momentum[{i}]: {a} vs {b}"
        );
    }
    // after the capture the rows are the combined arm's; its momentum there equals that of the
    // arm without the payload plus the welded target's (the target's twist is the EE's carried
    // to it), so reading the rows after with either gives the same numbers to round-off
    let combined = record.arm_after.as_ref().unwrap();
    let last = traj.len() - 1;
    let after_arm = combined.momentum(&mut ModelWorkspace::new(combined), traj.state(last));
    for (i, (a, b)) in h[last * 6..last * 6 + 6].iter().zip(after_arm).enumerate() {
        assert!(
            (a - b).abs() <= 1e-14 * scale,
            "last row momentum[{i}]: {a} vs {b}"
        );
    }
    // the energy: the row at the event (arm and free target) less the event's loss is the
    // combined arm's energy just after (spring and motor energies are untouched by the impulse)
    let energy = record.energy(&arm, &traj.t, &traj.x);
    let after = combined.energy(&mut ModelWorkspace::new(combined), &e.x_after);
    assert!(
        (energy[e.step] - e.energy_loss - after).abs() <= 1e-12 * energy[e.step],
        "{} - {} vs {after}",
        energy[e.step],
        e.energy_loss
    );
    // the motors keep their rates; the links jump
    let layout = arm.layout();
    assert_eq!(
        &e.x_before[layout.theta_dot()],
        &e.x_after[layout.theta_dot()]
    );
    assert_ne!(&e.x_before[layout.qd()], &e.x_after[layout.qd()]);
    // after: the handle keeps the distance and angle it had to the EE at the capture
    let combined = record.arm_after.as_ref().unwrap();
    for k in (e.step + 1..traj.len()).step_by(97) {
        let x = traj.state(k);
        let t = target
            .at_state(&record.target[k * 13..(k + 1) * 13])
            .unwrap();
        let mut data = orbitflex::Data::new(combined.robot());
        let a = Approach::measure(combined, &mut data, x, &t, 0);
        assert!((a.distance - e.approach.distance).abs() < 1e-9, "row {k}");
        assert!((a.angle - e.approach.angle).abs() < 1e-9, "row {k}");
        // no relative motion: the target's twist is the EE's
        assert!(a.speed < 1e-12, "row {k}: {}", a.speed);
    }
}

#[test]
fn tolerances_must_be_finite_and_positive() {
    for (d, s, a, what) in [
        (0.0, 0.1, 0.1, "CaptureWhen.distance"),
        (0.1, -1.0, 0.1, "CaptureWhen.speed"),
        (0.1, 0.1, f64::NAN, "CaptureWhen.angle"),
        (f64::INFINITY, 0.1, 0.1, "CaptureWhen.distance"),
    ] {
        let e = CaptureWhen::new(d, s, a).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains(what) && text.contains("expected a finite tolerance > 0"),
            "{text}"
        );
    }
    // a value built without `new` is checked by the run
    let arm = space_arm();
    let target = target_near_ee(&arm, [0.1, 0.0, 0.0], [0.0; 3], [0.0; 3]);
    let x0 = arm.rest_state();
    let mut zero = Schedule::Zero;
    let mut wrenches = Wrenches::ZERO;
    let mut drive = Drive::new(&mut zero, &mut wrenches);
    let mut traj = Trajectory::reserved(arm.layout(), 10, 1).unwrap();
    let capturing = CaptureRun {
        target: &target,
        when: CaptureWhen {
            distance: 0.1,
            speed: 0.0,
            angle: 0.1,
        },
        ee: None,
    };
    let failure = simulate_capture_into(
        &arm,
        &Run::new(&x0, 0.01, 10),
        &mut drive,
        &capturing,
        &mut Unobserved,
        &mut traj,
    )
    .unwrap_err();
    assert!(failure.error.to_string().contains("CaptureWhen.speed"));
    assert!(traj.is_empty());
}

/// The scenario `s` run alone for `steps` steps, every `every`-th row kept.
fn scenario_run(
    s: &orbitflex::capture::CaptureScenario,
    steps: usize,
    every: usize,
) -> (Trajectory, CaptureRecord) {
    let mut pd = s.controller.clone();
    let mut wrenches = Wrenches::ZERO;
    let mut drive = Drive::new(&mut pd, &mut wrenches);
    let run = Run::new(&s.x0, s.dt, steps).recording_every(every);
    let mut traj = Trajectory::reserved(s.arm.layout(), steps, every).unwrap();
    let capturing = CaptureRun {
        target: &s.target,
        when: s.when,
        ee: None,
    };
    let record = simulate_capture_into(
        &s.arm,
        &run,
        &mut drive,
        &capturing,
        &mut Unobserved,
        &mut traj,
    )
    .unwrap();
    (traj, record)
}

/// The built-in scenario: the handle would reach the EE at 5 s drifting at 2 cm/s, so the 1 cm
/// tolerance is met 0.5 s before (the EE held by the PD barely moves), at a spin angle of about
/// 2 deg/s × 0.5 s = 1 deg; the capture happens once.
#[test]
fn the_built_in_scenario_captures_once_half_a_second_early() {
    let s = orbitflex::capture::capture_scenario().unwrap();
    let (_, record) = scenario_run(&s, (6.0 / s.dt) as usize, 10);
    assert_eq!(record.events.len(), 1);
    let e = &record.events[0];
    assert!((e.time - 4.5).abs() < 0.02, "{}", e.time);
    assert!(
        (e.approach.angle.to_degrees() - 1.0).abs() < 0.05,
        "{}",
        e.approach.angle
    );
    assert!(
        (e.approach.speed - 0.02).abs() < 0.002,
        "{}",
        e.approach.speed
    );
    assert!(e.energy_loss > 0.0);
}

/// Runs with targets in a batch (dispersed tumble rates, on 2 threads) are the single runs, bit
/// for bit: rows, target rows and events.
#[test]
fn a_batch_with_targets_equals_the_single_runs() {
    use orbitflex::capture::{
        capture_scenario_with, simulate_capture_batch, CaptureBatchSettings, CaptureCase,
    };
    use std::sync::atomic::{AtomicBool, AtomicUsize};
    let scenarios: Vec<_> = [1.0, 2.0, 3.5]
        .iter()
        .map(|&rate| capture_scenario_with(rate, 0.02, 0.6).unwrap())
        .collect();
    let (dt, steps) = (scenarios[0].dt, 1000);
    let cases: Vec<CaptureCase<'_>> = scenarios
        .iter()
        .map(|s| CaptureCase {
            arm: &s.arm,
            x0: &s.x0,
            controller: &s.controller,
            target: &s.target,
            wheel_torque: None,
        })
        .collect();
    let settings = CaptureBatchSettings {
        dt,
        steps,
        record_every: 3,
        when: scenarios[0].when,
        ee: None,
        threads: Some(2),
    };
    let outcomes = simulate_capture_batch(
        &cases,
        &settings,
        &AtomicBool::new(false),
        &AtomicUsize::new(0),
    )
    .unwrap();
    for (s, outcome) in scenarios.iter().zip(&outcomes) {
        assert!(outcome.error.is_none());
        let (traj, record) = scenario_run(s, steps, 3);
        assert_eq!(record.events.len(), 1);
        assert_eq!(outcome.trajectory.x, traj.x);
        assert_eq!(outcome.trajectory.u, traj.u);
        assert_eq!(outcome.record.target, record.target);
        assert_eq!(outcome.record.events[0].step, record.events[0].step);
        assert_eq!(outcome.record.events[0].x_after, record.events[0].x_after);
    }
}
