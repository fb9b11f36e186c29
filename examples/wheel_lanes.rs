//! Throughput of `simulate_batch` on arms with reaction wheels, SIMD lanes against the scalar
//! path, on one thread: ns per run-step, rounds alternated, medians of the per-round ratios.
//!
//!     cargo run --release --example wheel_lanes -- [W] [RUNS] [STEPS] [ROUNDS] [CONTROL] [SIDE]
//!
//! The built-in space arm with four wheels in a pyramid (the set-up of `wheel_step_cost`), every
//! run from its own moving start, rows not kept (summaries and final states only). W = 4 or 8
//! (default: `orbitflex::lanes::width()`); CONTROL = `tables` (motor and wheel torque tables per
//! run) or `pd` (a `MotorPD` on the motors and an `AttitudePD` holding the bus, one per run, the
//! default). SIDE = `scalar` or `lanes` times that side alone once (for callgrind: the
//! difference of two RUNS values over the extra run-steps is the cost of one run-step).
use orbitflex::control::{AttitudePD, AttitudeTarget};
use orbitflex::flex::{ReactionWheels, Wheel};
use orbitflex::integrate::batch::{
    simulate_batch_with_lanes, Batch, BatchControl, BatchInput, BatchSettings, BatchWatch, Lanes,
    PerRun,
};
use orbitflex::{FlexibleArm, FlexibleJoints, MotorPD, Robot, Schedule, StateSpec};
use std::hint::black_box;
use std::time::Instant;

fn pyramid() -> ReactionWheels {
    let (tilt, side) = ((1.0f64 / 3.0).sqrt(), (2.0f64 / 3.0).sqrt());
    let wheels = (0..4)
        .map(|w| {
            let phi = std::f64::consts::FRAC_PI_2 * w as f64;
            Wheel {
                axis: [side * phi.cos(), side * phi.sin(), tilt],
                position: [0.3 * phi.cos(), 0.3 * phi.sin(), -0.4],
                mass: 4.0,
                spin_inertia: 0.04,
                transverse_inertia: 0.025,
                max_torque: 0.2,
                max_speed: 600.0,
                friction: 1e-4,
            }
        })
        .collect();
    ReactionWheels::new(wheels).expect("valid wheels")
}

struct Setup {
    arm: FlexibleArm,
    dt: f64,
    steps: usize,
    runs: usize,
    x0: Vec<f64>,
    u: Vec<f64>,
    wheel: Vec<f64>,
    motors: Vec<MotorPD>,
    attitudes: Vec<AttitudePD>,
    pd: bool,
}

/// A `(runs, steps, width)` table.
fn table<'a>(what: &str, v: &'a [f64], runs: usize, steps: usize, w: usize) -> BatchControl<'a> {
    BatchControl::Open(BatchInput::new(what, v, &[runs, steps, w], runs, Some(steps), w).unwrap())
}

fn batch(s: &Setup, lanes: Lanes) {
    let (n, k, len, runs, steps) = (7, 4, s.arm.layout().len(), s.runs, s.steps);
    let motors: Vec<&MotorPD> = s.motors.iter().collect();
    let attitudes: Vec<&AttitudePD> = s.attitudes.iter().collect();
    let (u, wheel_torque) = if s.pd {
        (
            BatchControl::Pd(PerRun::Each(&motors)),
            BatchControl::Attitude(PerRun::Each(&attitudes)),
        )
    } else {
        (
            table("u", &s.u, runs, steps, n),
            table("wheel_torque", &s.wheel, runs, steps, k),
        )
    };
    let batch = Batch {
        runs,
        arms: PerRun::All(&s.arm),
        x0: BatchInput::new("x0s", &s.x0, &[runs, len], runs, None, len).unwrap(),
        u,
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque,
    };
    let settings = BatchSettings {
        dt: s.dt,
        steps,
        record_every: 1,
        keep_rows: false,
        threads: Some(1),
    };
    let record =
        simulate_batch_with_lanes(&batch, &settings, &BatchWatch::default(), lanes).unwrap();
    assert!(record.status.iter().all(|st| st.failed_step().is_none()));
    black_box(&record);
}

fn main() -> orbitflex::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let num = |i: usize, default: usize| args.get(i).map_or(default, |a| a.parse().unwrap());
    let w = match num(0, 0) {
        0 => orbitflex::lanes::width().max(4),
        w => w,
    };
    let (runs, steps, rounds) = (num(1, 32), num(2, 1000), num(3, 7));
    let pd = args.get(4).map_or(true, |c| c == "pd");
    let side = args.get(5).cloned();
    let arm =
        FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?.with_wheels(pyramid())?;
    let n = 7;
    let layout = arm.layout();
    let x0: Vec<f64> = (0..runs)
        .flat_map(|r| {
            let f = r as f64 / runs as f64;
            let mut x = arm
                .state(&StateSpec {
                    qd: Some(&vec![0.05 * (f - 0.5); n]),
                    base_twist: Some(&[0.02 * f, -0.01, 0.01, 0.0, 0.0, 0.0]),
                    ..StateSpec::default()
                })
                .unwrap();
            x[layout.wheel_speed()].copy_from_slice(&[100.0 * f, -50.0, 20.0, 300.0 * f]);
            x
        })
        .collect();
    let dt = 1e-3;
    let wave = |count: usize, scale: f64| -> Vec<f64> {
        (0..count)
            .map(|k| scale * ((k % 97) as f64 - 48.0) / 48.0)
            .collect()
    };
    let allocation = arm.wheels().unwrap().allocation()?;
    let motors = (0..runs)
        .map(|r| {
            let reference = Schedule::Constant(vec![0.1 + 0.001 * r as f64; n]);
            MotorPD::new(
                vec![50.0; n],
                vec![5.0; n],
                reference,
                Schedule::Zero,
                Schedule::Zero,
            )
        })
        .collect::<orbitflex::Result<_>>()?;
    let attitudes = (0..runs)
        .map(|r| {
            let kp = [0.5 + 0.01 * r as f64, 0.6, 0.7];
            AttitudePD::new(kp, [1.5; 3], AttitudeTarget::Initial, allocation.clone())
        })
        .collect::<orbitflex::Result<_>>()?;
    let s = Setup {
        u: wave(runs * steps * n, 1.0),
        wheel: wave(runs * steps * 4, 0.1),
        arm,
        dt,
        steps,
        runs,
        x0,
        motors,
        attitudes,
        pd,
    };
    if let Some(side) = side {
        match side.as_str() {
            "scalar" => batch(&s, Lanes::Off),
            "lanes" => batch(&s, Lanes::Width(w)),
            other => panic!("unknown side {other}"),
        }
        return Ok(());
    }
    let per = (runs * steps) as f64;
    let time = |lanes| {
        let start = Instant::now();
        batch(&s, lanes);
        start.elapsed().as_secs_f64() / per * 1e9
    };
    let mut rows: Vec<[f64; 2]> = Vec::new();
    for round in 0..rounds {
        let (a, b) = if round % 2 == 0 {
            let a = time(Lanes::Off);
            (a, time(Lanes::Width(w)))
        } else {
            let b = time(Lanes::Width(w));
            (time(Lanes::Off), b)
        };
        rows.push([a, b]);
    }
    let median = |f: &dyn Fn(&[f64; 2]) -> f64| {
        let mut v: Vec<f64> = rows.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    println!(
        "space arm + 4 wheels, {}, W = {w} ({:?}), {runs} runs x {steps} steps, dt = {dt:e} s, \
         {rounds} rounds, 1 thread (ns per run-step, medians)",
        if pd {
            "MotorPD + AttitudePD per run"
        } else {
            "torque tables"
        },
        orbitflex::lanes::level()
    );
    println!(
        "simulate_batch: scalar {:.0}, lanes {:.0}, speed-up {:.2}",
        median(&|t| t[0]),
        median(&|t| t[1]),
        median(&|t| t[0] / t[1])
    );
    Ok(())
}
