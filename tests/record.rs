//! `record_every` and streaming: the rows a run keeps, bit for bit against the full run, on
//! success and on failure, in memory and in chunks.

use orbitflex::integrate::{
    is_recorded, recorded_rows, simulate_into, Chunks, Controller, Drive, Observer, Recorder, Run,
    Unobserved,
};
use orbitflex::testing::random_chain;
use orbitflex::{
    Error, FlexibleArm, FlexibleJoints, MotorPD, Robot, Schedule, Trajectory, Wrenches,
};

fn small_arm() -> FlexibleArm {
    let robot = random_chain(3, 5);
    FlexibleArm::new(
        robot,
        FlexibleJoints::uniform(3, 400.0, 0.1, 0.5, 0.1).unwrap(),
    )
    .unwrap()
}

/// Time-varying torques, a different sine per joint; fails at step `fail_at` if given.
#[derive(Clone)]
struct Sines {
    fail_at: Option<usize>,
}

impl Controller for Sines {
    fn output(&mut self, step: usize, t: f64, _: &[f64], u: &mut [f64]) -> orbitflex::Result<()> {
        if Some(step) == self.fail_at {
            return Err(Error::InvalidArgument {
                what: "test".into(),
                message: "planned failure".into(),
            });
        }
        for (i, ui) in u.iter_mut().enumerate() {
            *ui = 2.0 * (3.0 * t + i as f64).sin();
        }
        Ok(())
    }
}

const DT: f64 = 1e-3;

fn x0(arm: &FlexibleArm) -> Vec<f64> {
    let mut x = arm.rest_state();
    let qd = arm.layout().qd();
    x[qd.start] = 0.3; // a moving start
    x
}

/// A run into a fresh in-memory record: `(record, result)`.
fn run(
    arm: &FlexibleArm,
    steps: usize,
    every: usize,
    u: &mut dyn Controller,
) -> (Trajectory, orbitflex::Result<()>) {
    let mut traj = Trajectory::reserved(arm.layout(), steps, every).unwrap();
    let result = simulate_into(
        arm,
        &Run::new(&x0(arm), DT, steps).recording_every(every),
        &mut Drive::new(u, &mut Wrenches::default()),
        &mut Unobserved,
        &mut traj,
    );
    (traj, result)
}

/// The rows of `full` (a record_every = 1 run) that `every` keeps, as a record; inputs of the
/// steps starting at each kept row but the last; the last row `last` (the final row).
fn expected(full: &Trajectory, rows: &[usize]) -> Trajectory {
    let len = full.layout.len();
    let n = full.layout.n;
    let mut e = Trajectory::empty(full.layout);
    for (i, &j) in rows.iter().enumerate() {
        e.t.push(full.t[j]);
        e.x.extend_from_slice(&full.x[j * len..(j + 1) * len]);
        if i + 1 < rows.len() {
            e.u.extend_from_slice(&full.u[j * n..(j + 1) * n]);
        }
    }
    e
}

#[test]
fn row_rule_counts() {
    // the formula against the rule, every case from steps = 0 and k = 1 to k > steps
    for steps in 0..40 {
        for k in 1..45 {
            let kept = (0..=steps).filter(|&j| is_recorded(j, steps, k)).count();
            assert_eq!(recorded_rows(steps, k), kept, "steps {steps}, k {k}");
        }
    }
    assert_eq!(recorded_rows(10, 1), 11);
    assert_eq!(recorded_rows(10, 5), 3); // 0, 5, 10
    assert_eq!(recorded_rows(10, 3), 5); // 0, 3, 6, 9, 10
    assert_eq!(recorded_rows(10, 11), 2); // 0, 10
    assert_eq!(recorded_rows(0, 7), 1); // 0
    assert_eq!(recorded_rows(usize::MAX, 1), usize::MAX); // saturates
    assert!(is_recorded(10, 10, 3) && !is_recorded(8, 10, 3) && is_recorded(9, 10, 3));
}

#[test]
fn kept_rows_are_the_full_runs_rows_bit_for_bit() {
    let arm = small_arm();
    let steps = 100;
    let (full, ok) = run(&arm, steps, 1, &mut Sines { fail_at: None });
    ok.unwrap();
    assert_eq!((full.len(), full.u.len()), (101, 100 * 3));
    // record_every = 1 is the plain simulate, bit for bit
    let plain = arm
        .simulate(
            &x0(&arm),
            DT,
            steps,
            &mut Sines { fail_at: None },
            &Wrenches::ZERO,
        )
        .unwrap();
    assert_eq!(plain, full);
    for (k, rows) in [
        (1, (0..=100).collect::<Vec<_>>()),
        (10, (0..=100).step_by(10).collect()), // 10 divides 100: 11 rows
        (
            7,
            [(0..=98).step_by(7).collect::<Vec<_>>(), vec![100]].concat(),
        ), // 16 rows
        (100, vec![0, 100]),
        (150, vec![0, 100]), // k > steps: the start and the end
    ] {
        let (traj, ok) = run(&arm, steps, k, &mut Sines { fail_at: None });
        ok.unwrap();
        assert_eq!(traj.len(), recorded_rows(steps, k), "k = {k}");
        assert_eq!(traj.len(), rows.len(), "k = {k}");
        // PartialEq on f64 vectors: every time, state and torque bit for bit (no NaN here)
        assert_eq!(traj, expected(&full, &rows), "k = {k}");
        // exact times: row j at j as f64 * dt
        let times: Vec<f64> = rows.iter().map(|&j| j as f64 * DT).collect();
        assert_eq!(traj.t, times);
    }
    // steps = 0: the initial state alone, whatever k
    let (traj, ok) = run(&arm, 0, 4, &mut Sines { fail_at: None });
    ok.unwrap();
    assert_eq!(
        (traj.t.clone(), traj.x.clone(), traj.u.len()),
        (vec![0.0], full.x[..arm.layout().len()].to_vec(), 0)
    );
}

#[test]
fn a_failed_run_keeps_its_rows_and_ends_on_the_last_good_state() {
    let arm = small_arm();
    let (full, _) = run(&arm, 100, 1, &mut Sines { fail_at: None });
    for (fail_at, k, rows) in [
        (37, 10, vec![0, 10, 20, 30, 37]), // state 37 is not a kept row: appended
        (40, 10, vec![0, 10, 20, 30, 40]), // state 40 is a kept row: not repeated
        (0, 10, vec![0]),
        (5, 1, vec![0, 1, 2, 3, 4, 5]),
    ] {
        let (traj, result) = run(
            &arm,
            100,
            k,
            &mut Sines {
                fail_at: Some(fail_at),
            },
        );
        match result {
            Err(Error::Simulation {
                step,
                time,
                message,
            }) => {
                assert_eq!((step, time), (fail_at, fail_at as f64 * DT));
                assert!(message.contains("planned failure"), "{message}");
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(traj, expected(&full, &rows), "fail at {fail_at}, k = {k}");
        assert_eq!(traj.u.len(), (rows.len() - 1) * 3);
    }
}

/// A state that diverges is overwritten by the failing step: the record must end on the state
/// before it, as the full run's record does.
#[test]
fn a_diverged_run_ends_on_the_state_before_the_divergence() {
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
    let go = |k: usize| {
        let mut traj = Trajectory::reserved(arm.layout(), 1000, k).unwrap();
        let error = simulate_into(
            &arm,
            &Run::new(&x0, 1e-3, 1000).recording_every(k),
            &mut Drive::new(&mut pd.clone(), &mut Wrenches::default()),
            &mut Unobserved,
            &mut traj,
        )
        .unwrap_err();
        (traj, error)
    };
    let (full, full_error) = go(1);
    let Error::Simulation { step, .. } = full_error else {
        panic!("{full_error:?}")
    };
    assert_eq!(step, 195); // the known divergence (tests/simulation.rs)
    assert_eq!(full.len(), step + 1);
    let (traj, error) = go(50);
    assert_eq!(error.to_string(), full_error.to_string());
    assert_eq!(traj, expected(&full, &[0, 50, 100, 150, 195]));
}

/// Collects the chunks of a streamed run: `(concatenated record, chunk sizes, u rows per chunk)`.
fn stream(
    arm: &FlexibleArm,
    steps: usize,
    every: usize,
    capacity: usize,
    u: &mut dyn Controller,
) -> (Trajectory, Vec<usize>, Vec<usize>, orbitflex::Result<()>) {
    let mut all = Trajectory::empty(arm.layout());
    let mut sizes = Vec::new();
    let mut inputs = Vec::new();
    let result = {
        let mut sink = Chunks::new(arm.layout(), capacity, |chunk| {
            assert_eq!(chunk.first, all.len(), "chunks out of order");
            assert_eq!(chunk.x.len(), chunk.len() * arm.layout().len());
            assert_eq!(chunk.u.len(), chunk.inputs * arm.layout().n);
            all.t.extend_from_slice(chunk.t);
            all.x.extend_from_slice(chunk.x);
            all.u.extend_from_slice(chunk.u);
            sizes.push(chunk.len());
            inputs.push(chunk.inputs);
            Ok(())
        })
        .unwrap();
        let r = simulate_into(
            arm,
            &Run::new(&x0(arm), DT, steps).recording_every(every),
            &mut Drive::new(u, &mut Wrenches::default()),
            &mut Unobserved,
            &mut sink,
        );
        assert_eq!(sink.delivered(), sink.received());
        r
    };
    (all, sizes, inputs, result)
}

#[test]
fn streaming_delivers_every_kept_row_once_in_order() {
    let arm = small_arm();
    for (steps, k, capacity, sizes) in [
        (100, 7, 4, vec![4, 4, 4, 4]),     // 16 rows in full chunks
        (100, 10, 4, vec![4, 4, 3]),       // 11 rows, the last chunk partial
        (100, 1, 32, vec![32, 32, 32, 5]), // 101 rows
        (100, 1, 1, vec![1; 101]),         // a row per chunk
        (100, 3, 1000, vec![35]),          // all in one chunk (0, 3, …, 99, 100)
        (0, 3, 8, vec![1]),                // the initial state alone
    ] {
        let (memory, ok) = run(&arm, steps, k, &mut Sines { fail_at: None });
        ok.unwrap();
        let (streamed, got, inputs, ok) =
            stream(&arm, steps, k, capacity, &mut Sines { fail_at: None });
        ok.unwrap();
        assert_eq!(
            streamed, memory,
            "steps {steps}, k {k}, chunks of {capacity}"
        );
        assert_eq!(got, sizes, "steps {steps}, k {k}, chunks of {capacity}");
        // every chunk has an input per row but the one holding the final row
        let mut want: Vec<usize> = sizes.clone();
        *want.last_mut().unwrap() -= 1;
        assert_eq!(inputs, want);
    }
}

#[test]
fn a_failed_streamed_run_flushes_its_rows_and_the_last_good_state() {
    let arm = small_arm();
    let (memory, _) = run(&arm, 100, 10, &mut Sines { fail_at: Some(37) });
    let (streamed, sizes, inputs, result) =
        stream(&arm, 100, 10, 3, &mut Sines { fail_at: Some(37) });
    assert!(
        matches!(result, Err(Error::Simulation { step: 37, .. })),
        "{result:?}"
    );
    assert_eq!(streamed, memory); // rows 0, 10, 20, 30 and the state 37
    assert_eq!((sizes, inputs), (vec![3, 2], vec![3, 1]));
}

/// The observer stops the run like a failure: rows so far, and the state it stopped at.
#[test]
fn an_interrupted_run_ends_on_the_state_it_stopped_at() {
    struct StopAt(usize);
    impl Observer for StopAt {
        fn every(&self) -> usize {
            1
        }
        fn observe(&mut self, step: usize, _: usize) -> bool {
            step < self.0
        }
    }
    let arm = small_arm();
    let (full, _) = run(&arm, 100, 1, &mut Sines { fail_at: None });
    let mut traj = Trajectory::reserved(arm.layout(), 100, 8).unwrap();
    let error = simulate_into(
        &arm,
        &Run::new(&x0(&arm), DT, 100).recording_every(8),
        &mut Drive::new(&mut Sines { fail_at: None }, &mut Wrenches::default()),
        &mut StopAt(21),
        &mut traj,
    )
    .unwrap_err();
    assert!(
        matches!(error, Error::Simulation { step: 21, .. }),
        "{error:?}"
    );
    assert_eq!(traj, expected(&full, &[0, 8, 16, 21]));
}

/// A recorder that fails stops the run with an error naming the step.
#[test]
fn a_failing_recorder_stops_the_run() {
    struct Full(usize);
    impl Recorder for Full {
        fn state(&mut self, _: f64, _: &[f64]) -> orbitflex::Result<()> {
            if self.0 == 0 {
                return Err(Error::InvalidArgument {
                    what: "disk".into(),
                    message: "full".into(),
                });
            }
            self.0 -= 1;
            Ok(())
        }
        fn input(&mut self, _: &[f64]) -> orbitflex::Result<()> {
            Ok(())
        }
    }
    let arm = small_arm();
    let error = simulate_into(
        &arm,
        &Run::new(&x0(&arm), DT, 100).recording_every(5),
        &mut Drive::new(&mut Sines { fail_at: None }, &mut Wrenches::default()),
        &mut Unobserved,
        &mut Full(3), // rows 0, 5, 10 fit; row 15 (after step 14) does not
    )
    .unwrap_err();
    assert_eq!(
        error.to_string(),
        "simulation stopped at step 14 (t = 0.014 s): the recorder failed: disk: full"
    );
}

#[test]
fn zero_record_every_and_zero_chunk_rows_are_errors() {
    let arm = small_arm();
    let mut traj = Trajectory::empty(arm.layout());
    let error = simulate_into(
        &arm,
        &Run::new(&x0(&arm), DT, 10).recording_every(0),
        &mut Drive::new(&mut Sines { fail_at: None }, &mut Wrenches::default()),
        &mut Unobserved,
        &mut traj,
    )
    .unwrap_err();
    assert_eq!(
        error.to_string(),
        "record_every: expected an integer >= 1 (1 keeps every row), given 0"
    );
    assert!(traj.is_empty());
    let error = Trajectory::reserved(arm.layout(), 10, 0).unwrap_err();
    assert!(error.to_string().starts_with("record_every: "), "{error}");
    let error = Chunks::new(arm.layout(), 0, |_| Ok(())).err().unwrap();
    assert_eq!(
        error.to_string(),
        "chunk_rows: expected an integer >= 1, given 0"
    );
    let error = Chunks::new(arm.layout(), usize::MAX, |_| Ok(()))
        .err()
        .unwrap();
    assert!(
        error.to_string().starts_with("chunk_rows: a chunk of "),
        "{error}"
    );
}

/// Memory: the record of a decimated run is sized for its rows, not its steps.
#[test]
fn the_record_is_reserved_for_the_kept_rows() {
    let arm = small_arm();
    let traj = Trajectory::reserved(arm.layout(), 1_000_000, 1000).unwrap();
    assert_eq!(traj.t.capacity(), 1001);
    assert_eq!(traj.x.capacity(), 1001 * arm.layout().len());
    assert_eq!(traj.u.capacity(), 1000 * 3);
    let (traj, ok) = run(&arm, 10_000, 1000, &mut Sines { fail_at: None });
    ok.unwrap();
    assert_eq!((traj.t.capacity(), traj.len()), (11, 11));
}
