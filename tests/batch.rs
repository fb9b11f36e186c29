//! `simulate_batch`: a batch equals its runs made one by one, bit for bit, for any number of
//! threads; inputs broadcast over the run axis; a failing run leaves the others complete.

use orbitflex::integrate::batch::{
    simulate_batch, simulate_batch_with_lanes, Batch, BatchControl, BatchInput, BatchRecord,
    BatchSettings, BatchWatch, Lanes, PerRun, RunStatus,
};
use orbitflex::integrate::{is_recorded, Controller, Drive, Run, Schedule, Wrenches};
use orbitflex::testing::random_chain;
use orbitflex::{Error, FlexibleArm, FlexibleJoints, MotorPD, Trajectory};
use std::sync::atomic::{AtomicBool, Ordering};

const N: usize = 3;
const STEPS: usize = 40;
const DT: f64 = 2e-3;

fn arm(stiffness: f64) -> FlexibleArm {
    FlexibleArm::new(
        random_chain(N, 5),
        FlexibleJoints::uniform(N, stiffness, 0.1, 0.5, 0.1).unwrap(),
    )
    .unwrap()
}

/// Four starts: rest, and three with different link speeds.
fn starts(arm: &FlexibleArm) -> Vec<f64> {
    let layout = arm.layout();
    (0..4)
        .flat_map(|b| {
            let mut x = arm.rest_state();
            for (i, v) in x[layout.qd()].iter_mut().enumerate() {
                *v = 0.1 * b as f64 - 0.05 * i as f64;
            }
            x[layout.base_twist()][2] = 0.01 * b as f64;
            x
        })
        .collect()
}

/// Torque tables (4, STEPS, N), a different sine per run and joint; run 2 gets a torque that
/// makes its state overflow at step 17 when `poison` is set.
fn torques(poison: bool) -> Vec<f64> {
    let mut u = Vec::new();
    for b in 0..4 {
        for k in 0..STEPS {
            for i in 0..N {
                let t = k as f64 * DT;
                let bad = poison && b == 2 && k == 17;
                u.push(if bad {
                    1e308
                } else {
                    (b as f64 + 1.0) * (20.0 * t + i as f64).sin()
                });
            }
        }
    }
    u
}

fn single(
    arm: &FlexibleArm,
    x0: &[f64],
    u: &mut dyn Controller,
    wrenches: &Wrenches,
) -> Result<Trajectory, Trajectory> {
    arm.simulate_observed(x0, DT, STEPS, u, wrenches)
}

trait Observed {
    fn simulate_observed(
        &self,
        x0: &[f64],
        dt: f64,
        steps: usize,
        u: &mut dyn Controller,
        wrenches: &Wrenches,
    ) -> Result<Trajectory, Trajectory>;
}

impl Observed for FlexibleArm {
    fn simulate_observed(
        &self,
        x0: &[f64],
        dt: f64,
        steps: usize,
        u: &mut dyn Controller,
        wrenches: &Wrenches,
    ) -> Result<Trajectory, Trajectory> {
        orbitflex::integrate::simulate(
            self,
            &Run::new(x0, dt, steps),
            &mut Drive::new(u, &mut wrenches.clone()),
            &mut orbitflex::integrate::Unobserved,
        )
        .map_err(|f| f.trajectory)
    }
}

/// Compares run `b` of the record with the single run `traj`, bit for bit, under the rule of
/// `record_every`; the rows after a failure must be NaN.
fn assert_run_equals(record: &BatchRecord, b: usize, traj: &Trajectory, every: usize) {
    let layout = record.layout;
    let (len, n) = (layout.len(), layout.n);
    let run_x = &record.x[b * record.rows * len..(b + 1) * record.rows * len];
    let run_u = &record.u[b * (record.rows - 1) * n..(b + 1) * (record.rows - 1) * n];
    let kept: Vec<usize> = (0..=STEPS)
        .filter(|&j| is_recorded(j, STEPS, every))
        .collect();
    assert_eq!(kept.len(), record.rows);
    let complete = traj.len() == STEPS + 1;
    for (slot, &j) in kept.iter().enumerate() {
        let row = &run_x[slot * len..(slot + 1) * len];
        if j < traj.len() {
            assert_eq!(row, traj.state(j), "run {b}, row {j}");
            assert_eq!(record.t[slot].to_bits(), traj.t[j].to_bits());
        } else {
            assert!(
                row.iter().all(|v| v.is_nan()),
                "run {b}, row {j} after the failure"
            );
        }
        if j < STEPS {
            let u = &run_u[slot * n..(slot + 1) * n];
            if j + 1 < traj.len() {
                assert_eq!(u, &traj.u[j * n..(j + 1) * n], "run {b}, input {j}");
            } else {
                assert!(u.iter().all(|v| v.is_nan()), "run {b}, input {j}");
            }
        }
    }
    // the final state: the last good one
    let last = traj.state(traj.len() - 1);
    assert_eq!(&record.final_state[b * len..(b + 1) * len], last);
    // the summaries, over every row and every input of the single run
    for i in 0..n {
        let deflection = (0..traj.len())
            .map(|j| {
                let x = traj.state(j);
                (x[layout.theta()][i] - x[layout.q()][i]).abs()
            })
            .fold(0.0, f64::max);
        assert_eq!(record.peak_deflection[b * n + i], deflection);
        let torque = (0..traj.len() - 1)
            .map(|j| traj.u[j * n + i].abs())
            .fold(0.0, f64::max);
        assert_eq!(record.peak_torque[b * n + i], torque);
    }
    assert_eq!(record.status[b].failed_step().is_none(), complete);
}

/// `record.run(b)` equals the record of the same single run made with `record_every`.
fn assert_run_record(
    record: &BatchRecord,
    b: usize,
    arm: &FlexibleArm,
    x0: &[f64],
    u: &mut dyn Controller,
    wrenches: &Wrenches,
) {
    let every = record.record_every;
    let mut traj = Trajectory::empty(arm.layout());
    let outcome = orbitflex::integrate::simulate_into(
        arm,
        &Run::new(x0, DT, STEPS).recording_every(every),
        &mut Drive::new(u, &mut wrenches.clone()),
        &mut orbitflex::integrate::Unobserved,
        &mut traj,
    );
    assert_eq!(outcome.is_err(), record.status[b].failed_step().is_some());
    assert_eq!(
        record.run(b),
        Some(traj),
        "run {b} as a Trajectory (record_every {every})"
    );
}

fn settings(every: usize, threads: usize) -> BatchSettings {
    BatchSettings {
        dt: DT,
        steps: STEPS,
        record_every: every,
        keep_rows: true,
        threads: Some(threads),
    }
}

#[test]
fn open_loop_batch_equals_single_runs_for_any_threads_and_record_every() {
    let arm = arm(400.0);
    let x0 = starts(&arm);
    let len = arm.layout().len();
    let u = torques(false);
    let fb = [0.3, -0.2, 0.1, 1.0, 0.0, -0.5];
    let batch = Batch {
        runs: 4,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[4, len], 4, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::new("u", &u, &[4, STEPS, N], 4, Some(STEPS), N).unwrap()),
        base_wrench: BatchInput::new("base_wrench", &fb, &[6], 4, Some(STEPS), 6).unwrap(),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    for every in [1, 3, 40, 41] {
        let mut records = Vec::new();
        for threads in [1, 2, 3] {
            let record =
                simulate_batch(&batch, &settings(every, threads), &BatchWatch::default()).unwrap();
            for b in 0..4 {
                let mut table = Schedule::Table {
                    values: u[b * STEPS * N..(b + 1) * STEPS * N].to_vec(),
                    width: N,
                };
                let wrenches = Wrenches {
                    base: Schedule::Constant(fb.to_vec()),
                    ee: Schedule::Zero,
                    wheel_torque: orbitflex::Schedule::Zero,
                };
                let traj = single(
                    &arm,
                    &x0[b * len..(b + 1) * len],
                    &mut table.clone(),
                    &wrenches,
                )
                .expect("run completes");
                assert_run_equals(&record, b, &traj, every);
                assert_run_record(
                    &record,
                    b,
                    &arm,
                    &x0[b * len..(b + 1) * len],
                    &mut table,
                    &wrenches,
                );
            }
            records.push(record);
        }
        // NaN-free records: compare the bits directly
        assert!(records.windows(2).all(|w| w[0] == w[1]));
    }
}

#[test]
fn failing_run_leaves_the_others_complete() {
    let arm = arm(400.0);
    let x0 = starts(&arm);
    let len = arm.layout().len();
    let u = torques(true);
    let batch = Batch {
        runs: 4,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[4, len], 4, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::new("u", &u, &[4, STEPS, N], 4, Some(STEPS), N).unwrap()),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    // 17 % 5 != 0 ends the record on the last good state; 17 % 17 == 0 on a kept row
    for (every, threads) in [(1, 2), (5, 1), (5, 2), (17, 2)] {
        let record =
            simulate_batch(&batch, &settings(every, threads), &BatchWatch::default()).unwrap();
        for b in 0..4 {
            let mut table = Schedule::Table {
                values: u[b * STEPS * N..(b + 1) * STEPS * N].to_vec(),
                width: N,
            };
            assert_run_record(
                &record,
                b,
                &arm,
                &x0[b * len..(b + 1) * len],
                &mut table.clone(),
                &Wrenches::ZERO,
            );
            let traj = single(
                &arm,
                &x0[b * len..(b + 1) * len],
                &mut table,
                &Wrenches::ZERO,
            );
            let (traj, failed) = match traj {
                Ok(t) => (t, false),
                Err(t) => (t, true),
            };
            assert_eq!(failed, b == 2);
            assert_run_equals(&record, b, &traj, every);
        }
        match &record.status[2] {
            RunStatus::Failed {
                step,
                time,
                message,
            } => {
                assert_eq!(*step, 17);
                assert_eq!(*time, 17.0 * DT);
                assert!(message.contains("diverged"), "{message}");
            }
            other => panic!("{other:?}"),
        }
    }
}

#[test]
fn dispersed_arms_and_controllers_per_run() {
    let arms: Vec<FlexibleArm> = [200.0, 400.0, 800.0, 1600.0].map(arm).into();
    let len = arms[0].layout().len();
    let x0 = starts(&arms[0]);
    let pds: Vec<MotorPD> = (0..4)
        .map(|b| {
            MotorPD::new(
                vec![20.0 + 5.0 * b as f64; N],
                vec![2.0; N],
                Schedule::Constant(vec![0.2, -0.1, 0.3]),
                Schedule::Zero,
                Schedule::Zero,
            )
            .unwrap()
        })
        .collect();
    let fee: Vec<f64> = (0..4 * 6).map(|k| 0.01 * k as f64).collect();
    let batch = Batch {
        runs: 4,
        arms: PerRun::Each(&arms.iter().collect::<Vec<_>>()),
        x0: BatchInput::new("x0s", &x0, &[4, len], 4, None, len).unwrap(),
        u: BatchControl::Pd(PerRun::Each(&pds.iter().collect::<Vec<_>>())),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::new("ee_wrench", &fee, &[4, 6], 4, Some(STEPS), 6).unwrap(),
        wheel_torque: BatchControl::zero(0),
    };
    let record = simulate_batch(&batch, &settings(2, 2), &BatchWatch::default()).unwrap();
    for b in 0..4 {
        let wrenches = Wrenches {
            base: Schedule::Zero,
            ee: Schedule::Constant(fee[b * 6..(b + 1) * 6].to_vec()),
            wheel_torque: orbitflex::Schedule::Zero,
        };
        let mut pd = pds[b].clone();
        assert_run_record(
            &record,
            b,
            &arms[b],
            &x0[b * len..(b + 1) * len],
            &mut pd.clone(),
            &wrenches,
        );
        let traj = single(&arms[b], &x0[b * len..(b + 1) * len], &mut pd, &wrenches).unwrap();
        assert_run_equals(&record, b, &traj, 2);
    }
    // a shared controller is copied for each run: every run starts from the same state
    let shared = Batch {
        u: BatchControl::Pd(PerRun::All(&pds[0])),
        arms: PerRun::All(&arms[0]),
        x0: BatchInput::new("x0s", &x0[..len], &[len], 3, None, len).unwrap(),
        runs: 3,
        ..batch
    };
    let e = simulate_batch(&shared, &settings(1, 2), &BatchWatch::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "ee_wrench: expected one row or table per run (3 runs), given 4"
    );
    let shared = Batch {
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
        ..shared
    };
    let record = simulate_batch(&shared, &settings(1, 2), &BatchWatch::default()).unwrap();
    let run = |b: usize| &record.x[b * record.rows * len..(b + 1) * record.rows * len];
    assert!(run(0) == run(1) && run(0) == run(2));
    assert_eq!(record.runs, 3);
}

#[test]
fn summaries_only_keeps_no_rows_and_the_same_summaries() {
    let arm = arm(400.0);
    let x0 = starts(&arm);
    let len = arm.layout().len();
    let u = torques(true);
    let batch = Batch {
        runs: 4,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[4, len], 4, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::new("u", &u, &[4, STEPS, N], 4, Some(STEPS), N).unwrap()),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let full = simulate_batch(&batch, &settings(1, 2), &BatchWatch::default()).unwrap();
    let lean = simulate_batch(
        &batch,
        &BatchSettings {
            keep_rows: false,
            ..settings(1, 2)
        },
        &BatchWatch::default(),
    )
    .unwrap();
    assert_eq!(
        (lean.rows, lean.x.len(), lean.u.len(), lean.t.len()),
        (0, 0, 0, 0)
    );
    assert_eq!(lean.run(0), None);
    assert!(full.run(3).is_some() && full.run(4).is_none());
    assert_eq!(lean.final_state.len(), 4 * len);
    for (a, b) in lean.final_state.iter().zip(&full.final_state) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    assert_eq!(lean.peak_deflection, full.peak_deflection);
    assert_eq!(lean.peak_torque, full.peak_torque);
    assert_eq!(lean.status, full.status);
}

#[test]
fn cancelled_batch_stops_every_run() {
    // one thread, three long runs; the flag is set 50 ms after the first run is over: the second
    // stops at its next look (every 16 steps), the third never starts
    let arm = arm(400.0);
    let len = arm.layout().len();
    let x0 = arm.rest_state();
    let batch = Batch {
        runs: 3,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[len], 3, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::zero(N)),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let watch = BatchWatch::default();
    let steps = 200_000;
    let settings = BatchSettings {
        steps,
        keep_rows: false,
        ..settings(1, 1)
    };
    // set when the batch returns or panics, so that the watcher never outlives it
    struct Over<'a>(&'a AtomicBool);
    impl Drop for Over<'_> {
        fn drop(&mut self) {
            self.0.store(true, Ordering::Relaxed);
        }
    }
    let over = AtomicBool::new(false);
    let record = std::thread::scope(|scope| {
        scope.spawn(|| {
            while watch.done.load(Ordering::Relaxed) == 0 && !over.load(Ordering::Relaxed) {
                std::thread::sleep(std::time::Duration::from_micros(200));
            }
            // the one thread went straight on to the second run, which takes over a second:
            // let it get going before the flag is set
            std::thread::sleep(std::time::Duration::from_millis(50));
            watch.cancel.store(true, Ordering::Relaxed);
        });
        let _over = Over(&over);
        // one run after another: the scalar path (tests/batch_lanes.rs cancels a lane group)
        simulate_batch_with_lanes(&batch, &settings, &watch, Lanes::Off).unwrap()
    });
    assert_eq!(record.status[0], RunStatus::Finished);
    match &record.status[1] {
        RunStatus::Failed { step, message, .. } => {
            assert!(*step > 0 && *step < steps && step % 16 == 0, "{step}");
            assert_eq!(message, "interrupted by the caller");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(record.status[2].failed_step(), Some(0));
    assert_eq!(watch.done.load(Ordering::Relaxed), 3);
}

#[test]
fn runs_not_started_when_cancelled_end_at_their_start() {
    // a batch cancelled before it starts: every run ends at its start
    let arm = arm(400.0);
    let len = arm.layout().len();
    let x0 = starts(&arm);
    let batch = Batch {
        runs: 4,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[4, len], 4, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::zero(N)),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let watch = BatchWatch::default();
    watch.cancel.store(true, Ordering::Relaxed);
    let record = simulate_batch(&batch, &settings(3, 2), &watch).unwrap();
    for b in 0..4 {
        assert_eq!(
            record.status[b],
            RunStatus::Failed {
                step: 0,
                time: 0.0,
                message: "interrupted by the caller".into()
            }
        );
        assert_eq!(
            &record.final_state[b * len..(b + 1) * len],
            &x0[b * len..(b + 1) * len]
        );
        let run = record.run(b).unwrap();
        assert_eq!((run.len(), run.u.len()), (1, 0));
        assert_eq!(run.state(0), &x0[b * len..(b + 1) * len]);
        assert!(
            record.x[b * record.rows * len + len..(b + 1) * record.rows * len]
                .iter()
                .all(|v| v.is_nan())
        );
    }
}

#[test]
fn a_table_for_other_steps_is_refused() {
    let arm = arm(400.0);
    let len = arm.layout().len();
    let x0 = arm.rest_state();
    let u = vec![0.0; 2 * 10 * N];
    let batch = Batch {
        runs: 2,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[len], 2, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::new("u", &u, &[2, 10, N], 2, Some(10), N).unwrap()),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    for steps in [5, 20] {
        let e = simulate_batch(
            &batch,
            &BatchSettings {
                steps,
                ..settings(1, 2)
            },
            &BatchWatch::default(),
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            format!("u: expected a table of {steps} rows (one per step), given 10 rows")
        );
    }
}

/// `unstable_runs` names each run whose `dt` is past the limit of its own arm, start and
/// feedback gains, with that limit, whether the runs share them or not.
#[test]
fn unstable_runs_are_named_with_their_own_limits() {
    let (soft, stiff) = (arm(400.0), arm(4e6));
    let len = soft.layout().len();
    let rest = soft.rest_state();
    let limit = |arm: &FlexibleArm, x0: &[f64], u: &dyn Controller| {
        arm.rk4_stability_limit(x0, u).unwrap().dt
    };
    let (l_soft, l_stiff) = (
        limit(&soft, &rest, &Schedule::Zero),
        limit(&stiff, &rest, &Schedule::Zero),
    );
    assert!(l_stiff < 0.5 * l_soft, "{l_stiff} {l_soft}");
    let zero = BatchControl::Open(BatchInput::zero(N));
    let shared_x0 = BatchInput::new("x0s", &rest, &[len], 3, None, len).unwrap();
    let batch = |arms, x0, u| Batch {
        runs: 3,
        arms,
        x0,
        u,
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    // arms per run: only the stiff one
    let arms = [&soft, &stiff, &soft];
    let dt = (l_stiff * l_soft).sqrt();
    let b = batch(PerRun::Each(&arms), shared_x0, zero);
    assert_eq!(b.unstable_runs(dt, Some(2)).unwrap(), [(1, l_stiff)]);
    assert_eq!(b.unstable_runs(0.5 * l_stiff, Some(2)).unwrap(), []);
    assert_eq!(b.unstable_runs(l_stiff, Some(2)).unwrap(), []); // at the limit: stable
                                                                // everything shared (open-loop torques differ per run, but have no feedback): every run
    let u = vec![0.5; 3 * N];
    let open = BatchControl::Open(BatchInput::new("u", &u, &[3, N], 3, Some(10), N).unwrap());
    let b = batch(PerRun::All(&soft), shared_x0, open);
    assert_eq!(
        b.unstable_runs(1.5 * l_soft, Some(1)).unwrap(),
        [(0, l_soft), (1, l_soft), (2, l_soft)]
    );
    // starts per run: a fast-spinning bus limits run 2 alone (the quaternion's own mode)
    let mut x0s = [rest.clone(), rest.clone(), rest.clone()].concat();
    x0s[2 * len + soft.layout().base_twist().start + 2] = 1000.0;
    let l_spin = limit(&soft, &x0s[2 * len..], &Schedule::Zero);
    assert!(l_spin < 0.5 * l_soft, "{l_spin}");
    let starts = BatchInput::new("x0s", &x0s, &[3, len], 3, None, len).unwrap();
    let b = batch(PerRun::All(&soft), starts, zero);
    assert_eq!(
        b.unstable_runs(0.5 * l_soft, Some(2)).unwrap(),
        [(2, l_spin)]
    );
    // gains per run: the stiff derivative gain of run 0 alone
    let pd = |kd: f64| {
        MotorPD::new(
            vec![50.0; N],
            vec![kd; N],
            Schedule::Zero,
            Schedule::Zero,
            Schedule::Zero,
        )
        .unwrap()
    };
    let (firm, gentle) = (pd(400.0), pd(1.0));
    let l_firm = limit(&soft, &rest, &firm);
    assert!(l_firm < 0.5 * l_soft, "{l_firm}");
    let pds = [&firm, &gentle, &gentle];
    let b = batch(
        PerRun::All(&soft),
        shared_x0,
        BatchControl::Pd(PerRun::Each(&pds)),
    );
    assert_eq!(
        b.unstable_runs(0.5 * l_soft, Some(2)).unwrap(),
        [(0, l_firm)]
    );
    // the same gains in every run: one limit for all
    let same = [&firm, &firm, &firm];
    let b = batch(
        PerRun::All(&soft),
        shared_x0,
        BatchControl::Pd(PerRun::Each(&same)),
    );
    assert_eq!(
        b.unstable_runs(0.5 * l_soft, Some(2)).unwrap(),
        [(0, l_firm), (1, l_firm), (2, l_firm)]
    );
}

/// A record that cannot fit is refused before anything is allocated, with what it needs.
#[test]
fn a_record_too_big_for_memory_is_refused() {
    let arm = arm(400.0);
    let len = arm.layout().len();
    let x0 = arm.rest_state();
    let batch = Batch {
        runs: 1000,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[len], 1000, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::zero(N)),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    // per run: 10⁷ + 1 rows of 25, 10⁷ torque rows of 3, the final state (25) and the two
    // summaries (3 each): 280,000,056 numbers; × 1000 runs × 8 bytes
    let e = simulate_batch(
        &batch,
        &BatchSettings {
            steps: 10_000_000,
            ..settings(1, 1)
        },
        &BatchWatch::default(),
    )
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "runs: the record of 1000 runs of 10000001 rows of 25 numbers needs 2240.0 GB, more than \
         the memory available; keep fewer rows (record_every), keep only the summaries \
         (keep_rows = false) or split the runs"
    );
    // more numbers than an address can hold
    let e = simulate_batch(
        &batch,
        &BatchSettings {
            steps: usize::MAX / 8,
            ..settings(1, 1)
        },
        &BatchWatch::default(),
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("needs more bytes than an address can hold"),
        "{e}"
    );
}

#[test]
fn argument_errors_name_the_run_and_the_shapes() {
    let arm = arm(400.0);
    let other = FlexibleArm::new(
        random_chain(2, 1),
        FlexibleJoints::uniform(2, 400.0, 0.1, 0.5, 0.1).unwrap(),
    )
    .unwrap();
    let len = arm.layout().len();
    let x0 = arm.rest_state();
    let arms = [arm.clone(), arm.clone(), other];
    let batch = Batch {
        runs: 3,
        arms: PerRun::Each(&arms.iter().collect::<Vec<_>>()),
        x0: BatchInput::new("x0s", &x0, &[len], 3, None, len).unwrap(),
        u: BatchControl::Open(BatchInput::zero(N)),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let e = simulate_batch(&batch, &settings(1, 1), &BatchWatch::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        "arms[2]: expected an arm with 3 joints (as run 0's), given one with 2 joints"
    );
    let u = vec![0.0; 2 * N];
    let short_table = [0.0, 0.0, 0.0, f64::NAN, 0.0, 0.0];
    let nan = Batch {
        runs: 2,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[len], 2, None, len).unwrap(),
        u: BatchControl::Open(
            BatchInput::new("u", &short_table, &[2, N], 2, Some(STEPS), N).unwrap(),
        ),
        ..batch
    };
    let e = simulate_batch(&nan, &settings(1, 2), &BatchWatch::default()).unwrap_err();
    assert!(matches!(e, Error::NonFinite { .. }));
    assert_eq!(e.to_string(), "u (run 1): element 0 is not finite (NaN)");
    let e = BatchInput::new("u", &u, &[2, 1, N], 2, Some(STEPS), N).unwrap_err();
    assert_eq!(
        e.to_string(),
        "u: expected shape (3,), (2, 3), (1, 3), (2, 40, 3) or (1, 40, 3), given shape (2, 1, 3)"
    );
    let e = simulate_batch(
        &Batch { runs: 0, ..nan },
        &settings(1, 1),
        &BatchWatch::default(),
    )
    .unwrap_err();
    assert_eq!(e.to_string(), "runs: expected at least one run, given 0");
}

#[test]
fn cancelled_checks_and_stability_limits_stop_with_interrupted() {
    // (issue 24) the checks and the per-run stability limits before a batch look at the flag
    // before each run: a batch of thousands of distinct arms stopped only when they were done
    let arms: Vec<FlexibleArm> = (0..8).map(|k| arm(400.0 + k as f64)).collect();
    let refs: Vec<&FlexibleArm> = arms.iter().collect();
    let x0 = arms[0].rest_state();
    let batch = Batch {
        runs: 8,
        arms: PerRun::Each(&refs),
        x0: BatchInput::new("x0s", &x0, &[x0.len()], 8, None, x0.len()).unwrap(),
        u: BatchControl::Open(BatchInput::zero(N)),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let watch = BatchWatch::default();
    assert!(batch.check_watched(&settings(1, 2), &watch).is_ok());
    assert_eq!(
        batch.unstable_runs_watched(DT, Some(2), &watch).unwrap(),
        vec![]
    );
    watch.cancel.store(true, Ordering::Relaxed);
    for result in [
        batch.check_watched(&settings(1, 2), &watch).map(|_| vec![]),
        batch.unstable_runs_watched(DT, Some(2), &watch),
    ] {
        match result {
            Err(Error::Interrupted { what }) => assert!(what.contains("runs"), "{what}"),
            other => panic!("{other:?}"),
        }
    }
}
