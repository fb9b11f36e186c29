//! `simulate_batch` in SIMD lanes equals the scalar batch bit for bit: every row, input, final
//! state, summary and status, for lanes of 4 and 8 (on any processor: 8 lanes run two AVX2
//! registers per number where there is no AVX-512) and the automatic choice, against
//! `Lanes::Off`. Batches whose size is not a multiple of the width, chains and trees, per-run
//! arms of one robot with dispersed joint parameters and payloads (one lane group) beside an
//! arm of another robot, torque tables and per-run PD controllers, wrench tables, runs that diverge (the
//! kernel's failure re-run by the scalar step for its message), `record_every` not dividing the
//! steps, and summaries only; arms with reaction wheels (dispersed per run) under wheel torque
//! tables, `AttitudePD`s and sampled controllers, their limits reached.

use orbitflex::control::{AttitudePD, AttitudeTarget};
use orbitflex::flex::{ReactionWheels, Wheel};
use orbitflex::integrate::batch::{
    simulate_batch_with_lanes, Batch, BatchControl, BatchInput, BatchRecord, BatchSettings,
    BatchWatch, Lanes, PerRun, RunStatus, SampleClock,
};
use orbitflex::integrate::{Drive, Run, Schedule, Wrenches};
use orbitflex::lanes::shares_kernel;
use orbitflex::spatial::{Inertia, Mat3, Vec3};
use orbitflex::testing::{random_chain, random_state, random_tree, TREE_THREE_ARMS};
use orbitflex::{FlexibleArm, FlexibleJoints, MotorPD, Robot, StateSpec};

const RUNS: usize = 11;

/// Run `r`'s arm: the robot with the joints dispersed per run.
fn arm(robot: &Robot, r: usize) -> FlexibleArm {
    let n = robot.dof();
    let f = 1.0 + 0.05 * r as f64;
    let joints = FlexibleJoints::new(
        (0..n).map(|i| f * (3e3 + 400.0 * i as f64)).collect(),
        (0..n).map(|i| f * (0.5 + 0.1 * i as f64)).collect(),
        (0..n).map(|i| (2.0 + 0.3 * i as f64) / f).collect(),
        (0..n).map(|i| 0.2 * i as f64 * f).collect(),
    )
    .unwrap();
    FlexibleArm::new(robot.clone(), joints).unwrap()
}

fn start(arm: &FlexibleArm, r: usize) -> Vec<f64> {
    let (q, twist, qd) = random_state(arm.robot(), 70 + r as u64);
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
    arm.state(&StateSpec {
        q: Some(&q),
        theta: Some(&theta),
        qd: Some(&qd),
        base_twist: Some(&twist),
        base_pose: Some(&pose),
        ..StateSpec::default()
    })
    .unwrap()
}

/// `(runs, steps, width)` sines, a different phase per run.
fn table(runs: usize, steps: usize, width: usize, scale: f64) -> Vec<f64> {
    (0..runs * steps * width)
        .map(|k| scale * (k as f64 * 0.37).sin())
        .collect()
}

fn same_bits(a: &[f64], b: &[f64], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    for (j, (x, y)) in a.iter().zip(b).enumerate() {
        assert_eq!(x.to_bits(), y.to_bits(), "{what}[{j}]: {x:e} vs {y:e}");
    }
}

fn same_record(a: &BatchRecord, b: &BatchRecord, what: &str) {
    assert_eq!(a.status, b.status, "{what}: statuses");
    assert_eq!((a.runs, a.rows), (b.runs, b.rows));
    same_bits(&a.t, &b.t, &format!("{what}: t"));
    same_bits(&a.x, &b.x, &format!("{what}: x"));
    same_bits(&a.u, &b.u, &format!("{what}: u"));
    same_bits(
        &a.final_state,
        &b.final_state,
        &format!("{what}: final_state"),
    );
    same_bits(
        &a.peak_deflection,
        &b.peak_deflection,
        &format!("{what}: peaks"),
    );
    same_bits(
        &a.peak_torque,
        &b.peak_torque,
        &format!("{what}: peak torques"),
    );
}

/// The batch under every lane choice equals it under `Lanes::Off`; returns the scalar record.
fn all_lanes_equal_scalar(batch: &Batch<'_>, settings: &BatchSettings) -> BatchRecord {
    let run = |lanes| simulate_batch_with_lanes(batch, settings, &BatchWatch::default(), lanes);
    let scalar = run(Lanes::Off).unwrap();
    for lanes in [Lanes::Width(4), Lanes::Width(8), Lanes::Auto] {
        let got = run(lanes).unwrap();
        same_record(&got, &scalar, &format!("{lanes:?}"));
    }
    scalar
}

/// Per-run arms (dispersed joints; run 5 on another robot), per-run PD controllers (runs 2 and
/// 9 far past the RK4 limit: they diverge), EE and base wrench tables.
fn pd_batch_case(robot: &Robot, other: &Robot, steps: usize, every: usize, keep_rows: bool) {
    // runs 3 and 7 hold payloads of their own: same structure, other inertias (one group)
    let loaded = |mass: f64| {
        let payload = Inertia::from_com(mass, Vec3::new(0.0, 0.02, 0.1), Mat3::identity() * 0.01);
        robot.with_payload_at(payload, 0).unwrap()
    };
    let arms: Vec<FlexibleArm> = (0..RUNS)
        .map(|r| match r {
            5 => arm(other, r),
            3 | 7 => arm(&loaded(5.0 * r as f64), r),
            _ => arm(robot, r),
        })
        .collect();
    assert!(shares_kernel(&arms[0], &arms[3]) && shares_kernel(&arms[7], &arms[1]));
    assert!(!shares_kernel(&arms[0], &arms[5]));
    let n = robot.dof();
    let len = arms[0].layout().len();
    let x0: Vec<f64> = arms
        .iter()
        .enumerate()
        .flat_map(|(r, a)| start(a, r))
        .collect();
    let pds: Vec<MotorPD> = (0..RUNS)
        .map(|r| {
            let kp = if r == 2 || r == 9 {
                1e12
            } else {
                200.0 + 10.0 * r as f64
            };
            MotorPD::new(
                vec![kp; n],
                (0..n).map(|i| 20.0 + i as f64 + r as f64).collect(),
                Schedule::Constant((0..n).map(|i| 0.1 * i as f64 - 0.05 * r as f64).collect()),
                Schedule::Zero,
                Schedule::Constant(vec![0.3 * r as f64; n]),
            )
            .unwrap()
        })
        .collect();
    let ees = 6 * robot.end_effectors().len();
    let fee = table(RUNS, steps, ees, 1.0);
    let fb = table(RUNS, steps, 6, 2.0);
    let arm_refs: Vec<&FlexibleArm> = arms.iter().collect();
    let pd_refs: Vec<&MotorPD> = pds.iter().collect();
    let batch = Batch {
        runs: RUNS,
        arms: PerRun::Each(&arm_refs),
        x0: BatchInput::new("x0s", &x0, &[RUNS, len], RUNS, None, len).unwrap(),
        u: BatchControl::Pd(PerRun::Each(&pd_refs)),
        base_wrench: BatchInput::new("base_wrench", &fb, &[RUNS, steps, 6], RUNS, Some(steps), 6)
            .unwrap(),
        ee_wrench: BatchInput::new(
            "ee_wrench",
            &fee,
            &[RUNS, steps, ees],
            RUNS,
            Some(steps),
            ees,
        )
        .unwrap(),
        wheel_torque: BatchControl::zero(0),
    };
    let settings = BatchSettings {
        dt: 1e-3,
        steps,
        record_every: every,
        keep_rows,
        threads: Some(2),
    };
    let record = all_lanes_equal_scalar(&batch, &settings);
    for r in [2, 9] {
        assert!(
            matches!(record.status[r], RunStatus::Failed { .. }),
            "run {r} must diverge for the test to mean anything: {:?}",
            record.status[r]
        );
    }
    assert!(
        record
            .status
            .iter()
            .filter(|s| **s == RunStatus::Finished)
            .count()
            >= RUNS - 2
    );
    // and the scalar batch is each run's `simulate` (rows kept every step, when asked)
    if keep_rows && every == 1 {
        for r in [0, 2, 5] {
            let mut pd = pds[r].clone();
            let mut wrenches = Wrenches {
                base: Schedule::Table {
                    values: fb[r * steps * 6..(r + 1) * steps * 6].to_vec(),
                    width: 6,
                },
                ee: Schedule::Table {
                    values: fee[r * steps * ees..(r + 1) * steps * ees].to_vec(),
                    width: ees,
                },
                wheel_torque: Schedule::Zero,
            };
            let traj = orbitflex::integrate::simulate(
                &arms[r],
                &Run::new(&x0[r * len..(r + 1) * len], 1e-3, steps),
                &mut Drive::new(&mut pd, &mut wrenches),
                &mut orbitflex::integrate::Unobserved,
            )
            .unwrap_or_else(|f| f.trajectory);
            let run = record.run(r).unwrap();
            same_bits(&run.x, &traj.x, &format!("run {r} against simulate"));
            same_bits(&run.u, &traj.u, &format!("run {r} inputs against simulate"));
        }
    }
}

#[test]
fn pd_batches_in_lanes_equal_the_scalar_batch_on_the_space_arm() {
    let robot = Robot::space_arm();
    let other = random_chain(robot.dof(), 11);
    pd_batch_case(&robot, &other, 30, 1, true);
    pd_batch_case(&robot, &other, 31, 4, true);
    pd_batch_case(&robot, &other, 31, 4, false);
}

#[test]
fn pd_batches_in_lanes_equal_the_scalar_batch_on_chains_and_trees() {
    let tree = random_tree(TREE_THREE_ARMS, 5);
    pd_batch_case(&tree, &random_tree(TREE_THREE_ARMS, 6), 25, 3, true);
    let chain = random_chain(9, 3);
    pd_batch_case(&chain, &random_chain(9, 4), 25, 1, true);
}

/// Open-loop torque tables, one shared arm, one start for all (broadcast), a run whose torque
/// overflows its state at step 13.
#[test]
fn open_loop_batches_in_lanes_equal_the_scalar_batch() {
    let robot = Robot::space_arm();
    let a = arm(&robot, 0);
    let (n, len, steps) = (robot.dof(), a.layout().len(), 40);
    let x0 = start(&a, 1);
    for runs in [1, 3, 4, 9, 17] {
        let mut u = table(runs, steps, n, 5.0);
        if runs > 3 {
            u[(3 * steps + 13) * n] = 1e308;
        }
        let batch = Batch {
            runs,
            arms: PerRun::All(&a),
            x0: BatchInput::new("x0s", &x0, &[len], runs, None, len).unwrap(),
            u: BatchControl::Open(
                BatchInput::new("u", &u, &[runs, steps, n], runs, Some(steps), n).unwrap(),
            ),
            base_wrench: BatchInput::zero(6),
            ee_wrench: BatchInput::zero(6),
            wheel_torque: BatchControl::zero(0),
        };
        let settings = BatchSettings {
            dt: 1e-3,
            steps,
            record_every: 3,
            keep_rows: true,
            threads: Some(2),
        };
        let record = all_lanes_equal_scalar(&batch, &settings);
        if runs > 3 {
            assert_eq!(
                record.status[3].failed_step(),
                Some(13),
                "{:?}",
                record.status[3]
            );
        }
    }
}

/// A lane group cancelled mid-run: every run of it stops at the same look (every 16 steps) as
/// interrupted, keeping its rows; the progress counts all of them.
#[test]
fn a_cancelled_lane_group_stops_every_run_at_one_look() {
    use std::sync::atomic::Ordering;
    let a = arm(&Robot::space_arm(), 0);
    let len = a.layout().len();
    let x0 = start(&a, 2);
    let steps = 2_000_000;
    let batch = Batch {
        runs: 4,
        arms: PerRun::All(&a),
        x0: BatchInput::new("x0s", &x0, &[len], 4, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::zero(7)),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let settings = BatchSettings {
        dt: 1e-4,
        steps,
        record_every: 1000,
        keep_rows: true,
        threads: Some(1),
    };
    let watch = BatchWatch::default();
    let record = std::thread::scope(|scope| {
        scope.spawn(|| {
            std::thread::sleep(std::time::Duration::from_millis(100));
            watch.cancel.store(true, Ordering::Relaxed);
        });
        simulate_batch_with_lanes(&batch, &settings, &watch, Lanes::Width(4)).unwrap()
    });
    let step = record.status[0].failed_step().expect("interrupted");
    assert!(step > 0 && step < steps && step % 16 == 0, "{step}");
    for s in &record.status {
        assert_eq!(
            *s,
            RunStatus::Failed {
                step,
                time: step as f64 * 1e-4,
                message: "interrupted by the caller".into()
            }
        );
    }
    assert_eq!(watch.done.load(Ordering::Relaxed), 4);
    // the rows up to the look are kept, and the last good state is the one before it
    let run = record.run(1).unwrap();
    assert_eq!(run.t.len(), step / 1000 + 1 + usize::from(step % 1000 != 0));
    assert!(run.x.iter().all(|v| v.is_finite()));
}

/// Run `r`'s reaction wheels: a pyramid of four, dispersed per run (the axes tipped by
/// `0.01 r` rad, masses, positions, inertias, friction and limits of its own).
fn wheels(r: usize) -> ReactionWheels {
    let f = r as f64;
    let (tilt, phi0) = ((1.0f64 / 3.0).sqrt().acos() + 0.01 * f, 0.3 + 0.02 * f);
    let wheels = (0..4)
        .map(|w| {
            let phi = std::f64::consts::FRAC_PI_2 * w as f64 + phi0;
            Wheel {
                axis: [tilt.sin() * phi.cos(), tilt.sin() * phi.sin(), tilt.cos()],
                position: [0.3 * phi.cos(), 0.3 * phi.sin(), -0.4 + 0.01 * f],
                mass: 4.0 + 0.1 * f,
                spin_inertia: 0.04 * (1.0 + 0.02 * f),
                transverse_inertia: 0.025 * (1.0 + 0.02 * f),
                max_torque: 0.2 + 0.01 * f,
                max_speed: 600.0 - 5.0 * f,
                friction: 1e-4 * f,
            }
        })
        .collect();
    ReactionWheels::new(wheels).unwrap()
}

/// A start with the bus turning and every wheel near its speed limit (wheels 0 and 2 just
/// below it, wheel 1 just beyond it in the negative sense), so that commands are cut.
fn wheeled_start(arm: &FlexibleArm, r: usize) -> Vec<f64> {
    let mut x = start(arm, r);
    let limit = arm.wheels().unwrap().wheels()[0].max_speed;
    let speeds = [
        limit - 1e-3,
        -(limit + 0.5),
        limit - 0.3,
        40.0 * r as f64 - 200.0,
    ];
    x[arm.layout().wheel_speed()].copy_from_slice(&speeds);
    x
}

/// The wheel channels of [`wheel_batches_in_lanes_equal_the_scalar_batch`].
enum WheelCase {
    /// Torque tables on the motors and the wheels (run 3's motor torque overflows at step 13).
    Tables,
    /// `MotorPD` per run (runs 2 and 9 diverge), one `AttitudePD` shared.
    SharedAttitude,
    /// `MotorPD` and `AttitudePD` per run.
    AttitudePerRun,
    /// Both per run and sampled, with delays: the motors every 3 steps, the wheels at 170 Hz.
    Sampled,
}

/// 11 runs (groups of 4, 4, 2 or 8, 2 beside a run on another robot): arms with dispersed joints,
/// payloads on runs 3 and 7, dispersed wheels (run 5: another robot, its own group), base and
/// EE wrench tables, wheel speeds at their limits.
fn wheel_batch_case(case: WheelCase, steps: usize, every: usize, keep_rows: bool) {
    let robot = Robot::space_arm();
    let other = random_chain(7, 11);
    let loaded = |mass: f64| {
        let payload = Inertia::from_com(mass, Vec3::new(0.0, 0.02, 0.1), Mat3::identity() * 0.01);
        robot.with_payload_at(payload, 0).unwrap()
    };
    let arms: Vec<FlexibleArm> = (0..RUNS)
        .map(|r| {
            let base = match r {
                5 => arm(&other, r),
                3 | 7 => arm(&loaded(5.0 * r as f64), r),
                _ => arm(&robot, r),
            };
            base.with_wheels(wheels(r)).unwrap()
        })
        .collect();
    assert!(shares_kernel(&arms[0], &arms[3]) && !shares_kernel(&arms[0], &arms[5]));
    let bare = arm(&robot, 0);
    assert!(!shares_kernel(&arms[0], &bare), "as many wheels, or none");
    // the wheeled runs do go through the lanes: every run but run 5 in groups
    let (groups, scalar) = orbitflex::lanes::lane_groups(RUNS, 4, |r| Some(&arms[r]));
    assert_eq!((groups.len(), scalar), (3, vec![5]));
    let (n, k, len) = (7, 4, arms[0].layout().len());
    let x0: Vec<f64> = (0..RUNS).flat_map(|r| wheeled_start(&arms[r], r)).collect();
    let mut u_table = table(RUNS, steps, n, 5.0);
    u_table[(3 * steps + 13) * n] = 1e308;
    let w_table = table(RUNS, steps, k, 0.6);
    let motors: Vec<MotorPD> = (0..RUNS)
        .map(|r| {
            let kp = if r == 2 || r == 9 {
                1e12
            } else {
                200.0 + 10.0 * r as f64
            };
            MotorPD::new(
                vec![kp; n],
                (0..n).map(|i| 20.0 + i as f64 + r as f64).collect(),
                Schedule::Constant((0..n).map(|i| 0.1 * i as f64 - 0.05 * r as f64).collect()),
                Schedule::Zero,
                Schedule::Zero,
            )
            .unwrap()
        })
        .collect();
    let attitudes: Vec<AttitudePD> = (0..RUNS)
        .map(|r| {
            let kp = [0.5 + 0.1 * r as f64, 0.6, 0.7];
            let kd = [1.5, 1.5 + 0.2 * r as f64, 1.0];
            let allocation = arms[r].wheels().unwrap().allocation().unwrap();
            AttitudePD::new(kp, kd, AttitudeTarget::Initial, allocation).unwrap()
        })
        .collect();
    let arm_refs: Vec<&FlexibleArm> = arms.iter().collect();
    let motor_refs: Vec<&MotorPD> = motors.iter().collect();
    let attitude_refs: Vec<&AttitudePD> = attitudes.iter().collect();
    let (u_pd, w_pd) = (
        BatchControl::Pd(PerRun::Each(&motor_refs)),
        BatchControl::Attitude(PerRun::Each(&attitude_refs)),
    );
    let every3 = SampleClock {
        rate_hz: 1.0 / (3.0 * 1e-3),
        delay: 1,
    };
    let odd = SampleClock {
        rate_hz: 170.0,
        delay: 2,
    };
    let (u, wheel_torque) = match case {
        WheelCase::Tables => (
            BatchControl::Open(
                BatchInput::new("u", &u_table, &[RUNS, steps, n], RUNS, Some(steps), n).unwrap(),
            ),
            BatchControl::Open(
                BatchInput::new(
                    "wheel_torque",
                    &w_table,
                    &[RUNS, steps, k],
                    RUNS,
                    Some(steps),
                    k,
                )
                .unwrap(),
            ),
        ),
        WheelCase::SharedAttitude => (u_pd, BatchControl::Attitude(PerRun::All(&attitudes[1]))),
        WheelCase::AttitudePerRun => (u_pd, w_pd),
        WheelCase::Sampled => (
            BatchControl::Sampled(&u_pd, every3),
            BatchControl::Sampled(&w_pd, odd),
        ),
    };
    let ees = 6 * robot.end_effectors().len();
    let fee = table(RUNS, steps, ees, 1.0);
    let fb = table(RUNS, steps, 6, 2.0);
    let batch = Batch {
        runs: RUNS,
        arms: PerRun::Each(&arm_refs),
        x0: BatchInput::new("x0s", &x0, &[RUNS, len], RUNS, None, len).unwrap(),
        u,
        base_wrench: BatchInput::new("base_wrench", &fb, &[RUNS, steps, 6], RUNS, Some(steps), 6)
            .unwrap(),
        ee_wrench: BatchInput::new(
            "ee_wrench",
            &fee,
            &[RUNS, steps, ees],
            RUNS,
            Some(steps),
            ees,
        )
        .unwrap(),
        wheel_torque,
    };
    let settings = BatchSettings {
        dt: 1e-3,
        steps,
        record_every: every,
        keep_rows,
        threads: Some(2),
    };
    let record = all_lanes_equal_scalar(&batch, &settings);
    // what the test needs to mean anything: the failing runs fail, the others finish, the
    // wheels act, and (rows kept) their limits clip and cut commands
    let failing: &[usize] = match case {
        WheelCase::Tables => &[3],
        _ => &[2, 9],
    };
    for r in 0..RUNS {
        assert_eq!(
            record.status[r].failed_step().is_some(),
            failing.contains(&r),
            "run {r}: {:?}",
            record.status[r]
        );
    }
    if keep_rows && every == 1 {
        let (mut clipped, mut cut, mut acting) = (0, 0, 0.0f64);
        for r in 0..RUNS {
            let run = record.run(r).unwrap();
            let limit = arms[r].wheels().unwrap().wheels()[0].max_torque;
            for (s, row) in run.u.chunks(n + k).enumerate() {
                for w in 0..k {
                    let applied = row[n + w];
                    acting = acting.max(applied.abs());
                    clipped += usize::from(applied.abs() == limit);
                    if let WheelCase::Tables = case {
                        let command = w_table[(r * steps + s) * k + w];
                        cut += usize::from(applied == 0.0 && command != 0.0);
                    }
                }
            }
        }
        assert!(acting > 1e-3, "the wheels must act");
        if let WheelCase::Tables = case {
            assert!(clipped > 0 && cut > 0, "{clipped} clipped, {cut} cut");
        }
    }
}

/// Arms with reaction wheels in lanes equal the scalar batch bit for bit: wheel torque tables,
/// an `AttitudePD` shared and one per run, sampled `MotorPD`s and `AttitudePD`s with delays,
/// speed and torque limits reached, failing runs, `record_every` and summaries only.
#[test]
fn wheel_batches_in_lanes_equal_the_scalar_batch() {
    wheel_batch_case(WheelCase::Tables, 30, 1, true);
    wheel_batch_case(WheelCase::Tables, 31, 4, false);
    wheel_batch_case(WheelCase::SharedAttitude, 25, 1, true);
    wheel_batch_case(WheelCase::AttitudePerRun, 31, 3, true);
    wheel_batch_case(WheelCase::Sampled, 30, 1, true);
    wheel_batch_case(WheelCase::Sampled, 31, 4, true);
}
