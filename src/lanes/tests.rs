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
                wheel_torque: &[],
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

/// Run `r`'s arm with four reaction wheels of its own (random axes, positions, masses,
/// inertias and friction per run; torque limit 0.3 N·m, speed limit `300 + 10 r` rad/s).
fn wheeled(r: usize) -> FlexibleArm {
    let random = crate::testing::random_wheels(4, 3 + r as u64, 0.3);
    let wheels = random
        .wheels()
        .iter()
        .map(|w| crate::flex::Wheel {
            max_speed: 300.0 + 10.0 * r as f64,
            ..*w
        })
        .collect();
    arm(Robot::space_arm())
        .with_wheels(crate::flex::ReactionWheels::new(wheels).unwrap())
        .unwrap()
}

/// Lane groups of `W` with reaction wheels dispersed per lane against `FlexibleArm::step` run
/// by run: the same wheel commands, saturated by the scalar code at each lane's state (as the
/// `Stepper` does before a step in lanes), motor torques and base wrenches per run; every state
/// bit for bit. Returns how many commands were clipped to the torque limit and how many cut at
/// the speed limit.
fn wheel_case<const W: usize>(runs: usize, steps: usize, portable: bool) -> (usize, usize) {
    let dt = 1e-3;
    let arms: Vec<FlexibleArm> = (0..runs).map(wheeled).collect();
    let (n, len, k) = (7, arms[0].layout().len(), 4);
    let x0: Vec<Vec<f64>> = (0..runs)
        .map(|r| {
            let (q, twist, qd) = random_state(arms[r].robot(), 90 + r as u64);
            let pose = [
                0.1,
                -0.2 * r as f64,
                0.3,
                0.1,
                -0.2,
                0.3 + 0.1 * r as f64,
                0.9,
            ];
            let mut x = arms[r]
                .state(&StateSpec {
                    q: Some(&q),
                    qd: Some(&qd),
                    base_twist: Some(&twist),
                    base_pose: Some(&pose),
                    ..StateSpec::default()
                })
                .unwrap();
            // wheels 0 and 2 just below their limit, 1 just beyond it, 3 well inside
            let limit = 300.0 + 10.0 * r as f64;
            let speeds = [limit - 1e-3, -(limit + 0.5), limit - 0.2, 50.0 * r as f64];
            x[arms[r].layout().wheel_speed()].copy_from_slice(&speeds);
            x
        })
        .collect();
    let command = |r: usize, step: usize, w: usize| 0.5 * ((r + 3 * step + 7 * w) as f64).sin();
    let motor = |r: usize, i: usize| 0.2 * (r as f64 - 2.0) + 0.1 * i as f64;
    let base = |r: usize, j: usize| 0.5 * ((r + 2 * j) as f64 * 0.7).cos();
    let (mut clipped, mut cut) = (0, 0);
    // the scalar runs
    let mut expected = Vec::new();
    for r in 0..runs {
        let mut ws = arms[r].workspace();
        let mut x = x0[r].clone();
        let mut states = x.clone();
        let u: Vec<f64> = (0..n).map(|i| motor(r, i)).collect();
        let fb: Vec<f64> = (0..6).map(|j| base(r, j)).collect();
        for step in 0..steps {
            let cmd: Vec<f64> = (0..k).map(|w| command(r, step, w)).collect();
            let inputs = crate::flex::Inputs {
                u: &u,
                loads: crate::Loads {
                    base_wrench: crate::spatial::Force::from_slice(&fb),
                    ee_wrench: &[],
                },
                wheel_torque: &cmd,
            };
            arms[r].step(&mut ws, &mut x, dt, &inputs).unwrap();
            states.extend_from_slice(&x);
        }
        expected.push(states);
    }
    for (g0, group) in arms.chunks(W).enumerate() {
        let first = g0 * W;
        let mut g = LaneGroup::<W>::new(&group[0]);
        let mut states: Vec<Vec<f64>> = Vec::new();
        for (j, a) in group.iter().enumerate() {
            g.set_arm(j, a);
            g.set_state(j, &x0[first + j]);
            states.push(x0[first + j].clone());
        }
        for j in group.len()..W {
            g.park(j, 0);
        }
        let lane_of = |f: &dyn Fn(usize) -> f64| {
            let mut l = L::<W>::zero();
            for j in 0..group.len() {
                l.0[j] = f(first + j);
            }
            l
        };
        let u: Vec<L<W>> = (0..n).map(|i| lane_of(&|r| motor(r, i))).collect();
        let at = |j: usize| lane_of(&|r| base(r, j));
        let fb = Sv::new(V3::new(at(0), at(1), at(2)), V3::new(at(3), at(4), at(5)));
        let mut wheel = vec![L::<W>::zero(); k];
        let mut x = vec![0.0; len];
        let mut applied = vec![0.0; k];
        for step in 0..steps {
            for (j, a) in group.iter().enumerate() {
                g.state(j, &mut x);
                let cmd: Vec<f64> = (0..k).map(|w| command(first + j, step, w)).collect();
                let speed = &x[a.layout().wheel_speed()];
                a.wheels().unwrap().saturate(&cmd, speed, &mut applied);
                for w in 0..k {
                    wheel[w].0[j] = applied[w];
                    clipped += usize::from(applied[w].abs() == 0.3);
                    cut += usize::from(applied[w] == 0.0 && cmd[w] != 0.0);
                }
            }
            let inputs = LaneInputs {
                u: &u,
                base_wrench: &fb,
                ee_wrench: &[],
                wheel_torque: &wheel,
            };
            let ok = if portable {
                g.step_kernel(&group[0], dt, &inputs)
            } else {
                g.step(&group[0], dt, &inputs)
            };
            assert!(ok.iter().all(|&o| o), "step {step}");
            for (j, s) in states.iter_mut().enumerate() {
                g.state(j, &mut x);
                s.extend_from_slice(&x);
            }
        }
        for (j, got) in states.iter().enumerate() {
            let want = &expected[first + j];
            assert_eq!(want.len(), got.len());
            for (e, (a, b)) in want.iter().zip(got).enumerate() {
                assert_eq!(
                    a.to_bits(),
                    b.to_bits(),
                    "run {}, step {}, element {} ({a:e} vs {b:e}; W = {W}, portable {portable})",
                    first + j,
                    e / len,
                    e % len
                );
            }
        }
    }
    (clipped, cut)
}

#[test]
fn lanes_with_reaction_wheels_equal_the_scalar_step() {
    for portable in [false, true] {
        for (clipped, cut) in [
            wheel_case::<4>(6, 30, portable),
            wheel_case::<8>(6, 30, portable),
        ] {
            assert!(
                clipped > 0 && cut > 0,
                "the limits must act for the test to mean anything: {clipped} clipped, {cut} cut"
            );
        }
    }
}
