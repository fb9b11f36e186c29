//! Each lane equals the scalar run of the same inputs bit for bit: `simulate` with a
//! [`MotorPD`] and per-step wrench tables, against a lane group stepping with the same
//! controller law and table rows, for 4 and 8 lanes (the AVX2 and AVX-512 copies where the
//! processor has them) and the portable code, groups not filled (6 runs in groups of 4 and 8),
//! and runs that fail (masked, their last good state kept).

use super::{LaneGroup, LaneInputs, Sv, L, V3};
use crate::flex::{FlexibleArm, FlexibleJoints, StateSpec};
use crate::testing::{random_chain, random_state, random_tree, TREE_THREE_ARMS};
use crate::{MotorPD, Robot};
use crate::{Schedule, Wrenches};

/// One run: its initial state, its controller and its wrench tables.
struct Run {
    x0: Vec<f64>,
    kp: Vec<f64>,
    kd: Vec<f64>,
    theta_ref: Vec<f64>,
    feedforward: Vec<f64>,
    base: Vec<f64>,
    ee: Vec<f64>,
}

fn arm(robot: Robot) -> FlexibleArm {
    let n = robot.dof();
    let joints = FlexibleJoints::new(
        (0..n).map(|i| 3e3 + 500.0 * i as f64).collect(),
        (0..n).map(|i| 0.5 + 0.1 * i as f64).collect(),
        (0..n).map(|i| 2.0 + 0.3 * i as f64).collect(),
        (0..n).map(|i| 0.2 * i as f64).collect(),
    )
    .unwrap();
    FlexibleArm::new(robot, joints).unwrap()
}

fn runs(arm: &FlexibleArm, count: usize, steps: usize, diverging: &[usize]) -> Vec<Run> {
    let robot = arm.robot();
    let (n, ees) = (robot.dof(), robot.end_effectors().len());
    (0..count)
        .map(|r| {
            let (q, twist, qd) = random_state(robot, 40 + r as u64);
            let theta: Vec<f64> = q.iter().map(|v| v + 0.01 * r as f64).collect();
            let pose = [
                0.1 * r as f64,
                -0.2,
                0.3,
                0.1,
                -0.2,
                0.3 + 0.1 * r as f64,
                0.9,
            ];
            let x0 = arm
                .state(&StateSpec {
                    q: Some(&q),
                    theta: Some(&theta),
                    qd: Some(&qd),
                    base_twist: Some(&twist),
                    base_pose: Some(&pose),
                    ..StateSpec::default()
                })
                .unwrap();
            // a gain far past the RK4 limit makes the run diverge within a few steps
            let kp = if diverging.contains(&r) {
                1e12
            } else {
                200.0 + 10.0 * r as f64
            };
            let table = |width: usize, scale: f64| -> Vec<f64> {
                (0..steps * width)
                    .map(|k| scale * ((k + 7 * r) as f64 * 0.37).sin())
                    .collect()
            };
            Run {
                x0,
                kp: vec![kp; n],
                kd: (0..n).map(|i| 20.0 + i as f64 + r as f64).collect(),
                theta_ref: (0..n).map(|i| 0.1 * i as f64 - 0.05 * r as f64).collect(),
                feedforward: (0..n).map(|i| 0.5 * i as f64 * (r as f64 - 1.0)).collect(),
                base: table(6, 2.0),
                ee: table(6 * ees, 1.0),
            }
        })
        .collect()
}

/// The scalar reference: `simulate`, its states, and the failing step if any.
fn scalar(arm: &FlexibleArm, run: &Run, dt: f64, steps: usize) -> (Vec<f64>, Option<usize>) {
    let n = arm.dof();
    let mut pd = MotorPD::new(
        run.kp.clone(),
        run.kd.clone(),
        Schedule::Constant(run.theta_ref.clone()),
        Schedule::Zero,
        Schedule::Constant(run.feedforward.clone()),
    )
    .unwrap();
    assert_eq!(pd.dof(), n);
    let wrenches = Wrenches {
        base: Schedule::Table {
            values: run.base.clone(),
            width: 6,
        },
        ee: Schedule::Table {
            values: run.ee.clone(),
            width: run.ee.len() / steps,
        },
        wheel_torque: Schedule::Zero,
    };
    match arm.simulate(&run.x0, dt, steps, &mut pd, &wrenches) {
        Ok(traj) => (traj.x, None),
        Err(failure) => match failure.error {
            crate::Error::Simulation { step, .. } => (failure.trajectory.x, Some(step)),
            other => panic!("unexpected error {other}"),
        },
    }
}

/// The same runs in lane groups of `W`: the states after every step (a failed lane stops
/// recording at its last good state) and each run's failing step.
fn lanes<const W: usize>(
    arm: &FlexibleArm,
    runs: &[Run],
    dt: f64,
    steps: usize,
    portable: bool,
) -> Vec<(Vec<f64>, Option<usize>)> {
    let (n, len) = (arm.dof(), arm.layout().len());
    let ees = arm.robot().end_effectors().len();
    let mut out = Vec::new();
    for group in runs.chunks(W) {
        let mut g = LaneGroup::<W>::new(arm);
        let mut records: Vec<(Vec<f64>, Option<usize>)> = Vec::new();
        for (k, run) in group.iter().enumerate() {
            g.set_state(k, &run.x0);
            let mut x = vec![0.0; len];
            g.state(k, &mut x);
            records.push((x, None));
        }
        // unused lanes run a copy of lane 0
        for k in group.len()..W {
            g.park(k, 0);
        }
        let lane_of = |f: &dyn Fn(&Run) -> f64| {
            let mut l = L::<W>::zero();
            for (k, run) in group.iter().enumerate() {
                l.0[k] = f(run);
            }
            l
        };
        let per_joint = |f: &dyn Fn(&Run, usize) -> f64| -> Vec<L<W>> {
            (0..n).map(|i| lane_of(&|r| f(r, i))).collect()
        };
        let kp = per_joint(&|r, i| r.kp[i]);
        let kd = per_joint(&|r, i| r.kd[i]);
        let theta_ref = per_joint(&|r, i| r.theta_ref[i]);
        let rate_ref = vec![L::<W>::zero(); n];
        let ff = per_joint(&|r, i| r.feedforward[i]);
        let mut u = vec![L::<W>::zero(); n];
        let mut live: Vec<bool> = (0..W).map(|k| k < group.len()).collect();
        for step in 0..steps {
            g.motor_pd([&kp, &kd], &theta_ref, &rate_ref, &ff, &mut u);
            let wrench = |row: &dyn Fn(&Run) -> &[f64], width: usize, e: usize| {
                let at = |j: usize| lane_of(&|r| row(r)[step * width + 6 * e + j]);
                Sv::new(V3::new(at(0), at(1), at(2)), V3::new(at(3), at(4), at(5)))
            };
            let base = wrench(&|r| &r.base, 6, 0);
            let ee: Vec<Sv<W>> = (0..ees).map(|e| wrench(&|r| &r.ee, 6 * ees, e)).collect();
            let inputs = LaneInputs {
                u: &u,
                base_wrench: &base,
                ee_wrench: &ee,
            };
            let ok = if portable {
                g.step_kernel(arm, dt, &inputs)
            } else {
                g.step(arm, dt, &inputs)
            };
            for k in 0..group.len() {
                if !live[k] {
                    continue;
                }
                if ok[k] {
                    let mut x = vec![0.0; len];
                    g.state(k, &mut x);
                    records[k].0.extend_from_slice(&x);
                } else {
                    // the scalar run keeps its last good state as its final row
                    live[k] = false;
                    records[k].1 = Some(step);
                    let mut x = vec![0.0; len];
                    g.state(k, &mut x);
                    let last = &records[k].0[records[k].0.len() - len..];
                    assert_eq!(x, last, "a failed lane keeps its state before the step");
                    if let Some(from) = live.iter().position(|&l| l) {
                        g.park(k, from);
                    }
                }
            }
        }
        out.extend(records);
    }
    out
}

fn check<const W: usize>(arm: &FlexibleArm, runs: &[Run], dt: f64, steps: usize) {
    let expected: Vec<_> = runs.iter().map(|r| scalar(arm, r, dt, steps)).collect();
    for portable in [false, true] {
        let got = lanes::<W>(arm, runs, dt, steps, portable);
        for (r, (want, lane)) in expected.iter().zip(&got).enumerate() {
            assert_eq!(
                want.1, lane.1,
                "run {r}: failing step (W = {W}, portable {portable})"
            );
            assert_eq!(want.0.len(), lane.0.len(), "run {r}: rows (W = {W})");
            for (j, (a, b)) in want.0.iter().zip(&lane.0).enumerate() {
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "run {r}, element {j} of the record: {a:e} vs {b:e} (W = {W}, portable {portable})"
                );
            }
        }
    }
}

#[test]
fn lanes_equal_scalar_runs_bit_for_bit_on_the_space_arm() {
    let arm = arm(Robot::space_arm());
    let runs = runs(&arm, 6, 40, &[]);
    check::<4>(&arm, &runs, 1e-3, 40);
    check::<8>(&arm, &runs, 1e-3, 40);
}

#[test]
fn lanes_equal_scalar_runs_on_untilted_chains_and_trees() {
    for robot in [random_chain(9, 3), random_tree(TREE_THREE_ARMS, 5)] {
        let arm = arm(robot);
        let runs = runs(&arm, 5, 25, &[]);
        check::<4>(&arm, &runs, 5e-4, 25);
        check::<8>(&arm, &runs, 5e-4, 25);
    }
}

#[test]
fn failing_lanes_are_masked_and_keep_their_last_good_state() {
    let arm = arm(Robot::space_arm());
    let runs = runs(&arm, 7, 30, &[1, 4]);
    let (_, failed) = scalar(&arm, &runs[1], 1e-3, 30);
    assert!(
        failed.is_some(),
        "the reference run must diverge for this test to mean anything"
    );
    check::<4>(&arm, &runs, 1e-3, 30);
    check::<8>(&arm, &runs, 1e-3, 30);
}

#[test]
fn width_and_level_agree_with_the_processor() {
    let w = super::width();
    assert!([1, 4, 8].contains(&w));
    if super::level() == super::Level::Avx512 && std::env::var_os("ORBITFLEX_LANES").is_none() {
        assert_eq!(w, 8);
    }
}
