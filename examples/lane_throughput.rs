//! Throughput of the lane kernel ([`orbitflex::lanes::LaneGroup`]) against the scalar step, on
//! one core: ns per run-step, rounds interleaved, median of the per-round ratios.
//!
//!     cargo run --release --example lane_throughput -- [N] [W] [RUNS] [STEPS] [ROUNDS] [ONLY]
//!
//! N = 7 (default) is the built-in space arm, any other N the seeded random chain of
//! `batch_scaling`. W = 4 or 8 (default: `orbitflex::lanes::width()`). Two comparisons, each
//! with the same work on both sides:
//! - **open loop**: `simulate_batch` on one thread (an input table, every row recorded, rows not
//!   kept) against lane groups fed the same table rows, each lane's state gathered every step
//!   as a record would;
//! - **MotorPD**: `FlexibleArm::simulate` run by run against lane groups with the PD law in
//!   lanes (states gathered as above).
//!
//! - **the batch**: `simulate_batch` on one thread on the scalar path (`Lanes::Off`) against
//!   the same batch in lanes of W (`Lanes::Width(W)`), bookkeeping and recording included.
//!
//! ONLY = `batch`, `batch_lanes`, `lanes`, `simulate` or `lanes_pd` times one side alone (for
//! callgrind); `batch_pd` and `batch_pd_lanes` run `simulate_batch` with a `MotorPD` per run
//! (scalar, lanes), after the stability check the Python binding makes; `limits` and `exceeded`
//! make those runs' stability checks alone (the full limit, and `dt` against it).
use orbitflex::integrate::batch::{
    simulate_batch_with_lanes, Batch, BatchControl, BatchInput, BatchSettings, BatchWatch, Lanes,
    PerRun,
};
use orbitflex::lanes::{LaneGroup, LaneInputs, Sv, L};
use orbitflex::{FlexibleArm, FlexibleJoints, MotorPD, Robot, Schedule, Wrenches};
use std::hint::black_box;
use std::time::Instant;

struct Setup {
    arm: FlexibleArm,
    dt: f64,
    x0: Vec<f64>,
    u: Vec<f64>,
    runs: usize,
    steps: usize,
}

fn batch(s: &Setup, lanes: Lanes) {
    let (n, len) = (s.arm.dof(), s.x0.len());
    let batch = Batch {
        runs: s.runs,
        arms: PerRun::All(&s.arm),
        x0: BatchInput::new("x0s", &s.x0, &[len], s.runs, None, len).unwrap(),
        u: BatchControl::Open(
            BatchInput::new("u", &s.u, &[s.runs, s.steps, n], s.runs, Some(s.steps), n).unwrap(),
        ),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let settings = BatchSettings {
        dt: s.dt,
        steps: s.steps,
        record_every: 1,
        keep_rows: false,
        threads: Some(1),
    };
    let record =
        simulate_batch_with_lanes(&batch, &settings, &BatchWatch::default(), lanes).unwrap();
    assert!(record.status.iter().all(|st| st.failed_step().is_none()));
    black_box(&record);
}

/// `simulate_batch` on one thread with a `MotorPD` per run (gains `kp + run`, `kd`, `θ_ref`),
/// rows not kept, after the stability check the Python binding makes before the steps
/// (`Batch::unstable_runs`).
fn batch_pd(s: &Setup, lanes: Lanes, (kp, kd, reference): (f64, f64, f64)) {
    let (n, len) = (s.arm.dof(), s.x0.len());
    let pds: Vec<MotorPD> = (0..s.runs)
        .map(|run| {
            MotorPD::new(
                vec![kp + run as f64; n],
                vec![kd; n],
                Schedule::Constant(vec![reference; n]),
                Schedule::Zero,
                Schedule::Zero,
            )
            .unwrap()
        })
        .collect();
    let refs: Vec<&MotorPD> = pds.iter().collect();
    let batch = Batch {
        runs: s.runs,
        arms: PerRun::All(&s.arm),
        x0: BatchInput::new("x0s", &s.x0, &[len], s.runs, None, len).unwrap(),
        u: BatchControl::Pd(PerRun::Each(&refs)),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let settings = BatchSettings {
        dt: s.dt,
        steps: s.steps,
        record_every: 1,
        keep_rows: false,
        threads: Some(1),
    };
    assert!(batch.unstable_runs(s.dt, Some(1)).unwrap().is_empty());
    let record =
        simulate_batch_with_lanes(&batch, &settings, &BatchWatch::default(), lanes).unwrap();
    assert!(record.status.iter().all(|st| st.failed_step().is_none()));
    black_box(&record);
}

/// Lane groups over the runs: `pd` = Some((kp, kd, θ_ref)) uses the PD law, None the u table.
fn lanes<const W: usize>(s: &Setup, pd: Option<(f64, f64, f64)>) {
    let (n, len) = (s.arm.dof(), s.x0.len());
    let mut row = vec![0.0; len];
    let zero = Sv::<W>::default();
    let mut u = vec![L::<W>::zero(); n];
    let splat = |v: f64| vec![L::<W>::splat(v); n];
    let (kp, kd, reference) = pd.map_or((0.0, 0.0, 0.0), |p| p);
    let (kp, kd, reference, rate, ff) = (
        splat(kp),
        splat(kd),
        splat(reference),
        splat(0.0),
        splat(0.0),
    );
    for first in (0..s.runs).step_by(W) {
        let lanes_here = W.min(s.runs - first);
        let mut g = LaneGroup::<W>::new(&s.arm);
        for k in 0..lanes_here {
            g.set_state(k, &s.x0);
        }
        for k in lanes_here..W {
            g.park(k, 0);
        }
        for step in 0..s.steps {
            if pd.is_some() {
                g.motor_pd([&kp, &kd], &reference, &rate, &ff, &mut u);
            } else {
                for k in 0..lanes_here {
                    let at = ((first + k) * s.steps + step) * n;
                    for (i, ui) in u.iter_mut().enumerate() {
                        ui.0[k] = s.u[at + i];
                    }
                }
            }
            let inputs = LaneInputs {
                u: &u,
                base_wrench: &zero,
                ee_wrench: &[],
                wheel_torque: &[],
            };
            let ok = g.step(&s.arm, s.dt, &inputs);
            assert!(ok.iter().all(|&o| o));
            for k in 0..lanes_here {
                g.state(k, &mut row);
                black_box(&row);
            }
        }
    }
}

fn simulate(s: &Setup, kp: f64, kd: f64, reference: f64) {
    let n = s.arm.dof();
    for _ in 0..s.runs {
        let mut pd = MotorPD::new(
            vec![kp; n],
            vec![kd; n],
            Schedule::Constant(vec![reference; n]),
            Schedule::Zero,
            Schedule::Zero,
        )
        .unwrap();
        let traj = s
            .arm
            .simulate(&s.x0, s.dt, s.steps, &mut pd, &Wrenches::ZERO)
            .unwrap();
        black_box(traj.len());
    }
}

fn time(f: impl FnOnce()) -> f64 {
    let start = Instant::now();
    f();
    start.elapsed().as_secs_f64()
}

fn main() -> orbitflex::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let num = |i: usize, default: usize| args.get(i).map_or(default, |a| a.parse().unwrap());
    let n = num(0, 7);
    let w = match num(1, 0) {
        0 => orbitflex::lanes::width().max(4),
        w => w,
    };
    let (runs, steps, rounds) = (num(2, 64), num(3, 1000), num(4, 7));
    let only = args.get(5).cloned();
    let arm = if n == 7 {
        FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?
    } else {
        let robot = orbitflex::testing::random_chain(n, 1);
        let joints = FlexibleJoints::defaults_for(&robot)?;
        FlexibleArm::new(robot, joints)?
    };
    let dt = 0.25
        * arm
            .rk4_stability_limit(&arm.rest_state(), &Schedule::Zero)?
            .dt;
    let x0 = arm.rest_state();
    let u: Vec<f64> = (0..runs * steps * n)
        .map(|k| 0.01 * ((k % 97) as f64 - 48.0))
        .collect();
    let s = Setup {
        arm,
        dt,
        x0,
        u,
        runs,
        steps,
    };
    // gains well inside the RK4 limit at this dt
    let (kp, kd, reference) = (50.0, 5.0, 0.2);
    let lanes_any = |pd: Option<(f64, f64, f64)>| match w {
        8 => lanes::<8>(&s, pd),
        _ => lanes::<4>(&s, pd),
    };
    if let Some(only) = only {
        match only.as_str() {
            "batch" => batch(&s, Lanes::Off),
            "batch_lanes" => batch(&s, Lanes::Width(w)),
            "lanes" => lanes_any(None),
            "simulate" => simulate(&s, kp, kd, reference),
            "lanes_pd" => lanes_any(Some((kp, kd, reference))),
            "batch_pd" => batch_pd(&s, Lanes::Off, (kp, kd, reference)),
            "batch_pd_lanes" => batch_pd(&s, Lanes::Width(w), (kp, kd, reference)),
            // the stability checks of those runs alone: the full limits, and `dt` against them
            "limits" => (0..s.runs).for_each(|run| {
                let pd = MotorPD::new(
                    vec![kp + run as f64; n],
                    vec![kd; n],
                    Schedule::Zero,
                    Schedule::Zero,
                    Schedule::Zero,
                )
                .unwrap();
                black_box(s.arm.rk4_stability_limit(&s.x0, &pd).unwrap());
            }),
            "exceeded" => (0..s.runs).for_each(|run| {
                let pd = MotorPD::new(
                    vec![kp + run as f64; n],
                    vec![kd; n],
                    Schedule::Zero,
                    Schedule::Zero,
                    Schedule::Zero,
                )
                .unwrap();
                black_box(s.arm.rk4_stability_exceeded(&s.x0, &pd, s.dt).unwrap());
            }),
            other => panic!("unknown side {other}"),
        }
        return Ok(());
    }
    let per = (runs * steps) as f64;
    let mut rows: Vec<[f64; 5]> = Vec::new();
    for round in 0..rounds {
        let mut t = [0.0; 5];
        let order: [usize; 5] = if round % 2 == 0 {
            [0, 1, 2, 3, 4]
        } else {
            [4, 3, 2, 1, 0]
        };
        for side in order {
            t[side] = time(|| match side {
                0 => batch(&s, Lanes::Off),
                1 => lanes_any(None),
                2 => simulate(&s, kp, kd, reference),
                3 => lanes_any(Some((kp, kd, reference))),
                _ => batch(&s, Lanes::Width(w)),
            }) / per
                * 1e9;
        }
        rows.push(t);
    }
    let median = |f: &dyn Fn(&[f64; 5]) -> f64| {
        let mut v: Vec<f64> = rows.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "n = {n}, W = {w} ({:?}), {runs} runs x {steps} steps, dt = {dt:.3e} s, {rounds} rounds (ns per run-step, medians)",
        orbitflex::lanes::level()
    );
    println!(
        "open loop: batch 1 thread {:.0}, lanes {:.0}, speed-up {:.2}",
        median(&|t| t[0]),
        median(&|t| t[1]),
        median(&|t| t[0] / t[1])
    );
    println!(
        "simulate_batch, 1 thread: scalar {:.0}, lanes {:.0}, speed-up {:.2}",
        median(&|t| t[0]),
        median(&|t| t[4]),
        median(&|t| t[0] / t[4])
    );
    println!(
        "MotorPD:   simulate {:.0}, lanes {:.0}, speed-up {:.2}",
        median(&|t| t[2]),
        median(&|t| t[3]),
        median(&|t| t[2] / t[3])
    );
    Ok(())
}
