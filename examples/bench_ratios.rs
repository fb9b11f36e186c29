//! The ratio targets in BENCHMARKS.md, measured interleaved so that a shared machine's changing load
//! cancels out (criterion runs its benchmarks one after another, so its ratios do not):
//! forward dynamics at n against n = 7, and one RK4 step against one forward dynamics.
//!
//! ```text
//! cargo run --release --example bench_ratios [-- ROUNDS]
//! ```
//! Random chains `orbitflex::testing::random_chain(n, 4)` as in `benches/dynamics.rs`. Each round
//! times, for every n in turn, a block of `aba` calls and a block of RK4 steps; the ratios are
//! formed within the round and their median over rounds is printed as a markdown table.

use orbitflex::algorithms::{self, Data};
use orbitflex::testing::{random_chain, random_state, Rng};
use orbitflex::{
    ArmWorkspace, FlexibleArm, FlexibleJoints, Inputs, Loads, RigidState, Schedule, StateSpec,
};
use std::hint::black_box;
use std::time::Instant;

const SIZES: [usize; 5] = [7, 14, 28, 56, 112];

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Mean ns per call of `iters` calls of `f`.
fn block(iters: usize, mut f: impl FnMut()) -> f64 {
    let start = Instant::now();
    for _ in 0..iters {
        f();
    }
    start.elapsed().as_secs_f64() * 1e9 / iters as f64
}

struct Case {
    n: usize,
    robot: orbitflex::Robot,
    arm: FlexibleArm,
    data: Data,
    ws: ArmWorkspace,
    q: Vec<f64>,
    v: Vec<f64>,
    qd: Vec<f64>,
    tau: Vec<f64>,
    fb: Vec<f64>,
    f: Vec<f64>,
    x0: Vec<f64>,
    x: Vec<f64>,
    dt: f64,
}

fn case(n: usize) -> Case {
    let robot = random_chain(n, 4);
    let (q, v, qd) = random_state(&robot, 4);
    let mut rng = Rng::new(5);
    let (tau, fb, f) = (
        rng.vector(n, -5.0, 5.0),
        rng.vector(6, -5.0, 5.0),
        rng.vector(6, -5.0, 5.0),
    );
    // benches/dynamics.rs's flexible arm and time step.
    let arm = FlexibleArm::new(
        robot.clone(),
        FlexibleJoints::uniform(n, 2e3, 0.5, 1.0, 0.5).unwrap(),
    )
    .unwrap();
    let theta: Vec<f64> = q.iter().map(|q| q + 0.01).collect();
    let x0 = arm
        .state(&StateSpec {
            q: Some(&q),
            theta: Some(&theta),
            qd: Some(&qd),
            base_twist: Some(&v),
            ..StateSpec::default()
        })
        .unwrap();
    let relaxed = arm
        .state(&StateSpec {
            q: Some(&q),
            ..StateSpec::default()
        })
        .unwrap();
    let dt = (0.25
        * arm
            .rk4_stability_limit(&relaxed, &Schedule::Zero)
            .unwrap()
            .dt)
        .min(1e-3);
    Case {
        n,
        data: Data::new(&robot),
        ws: ArmWorkspace::new(&arm),
        x: x0.clone(),
        robot,
        arm,
        q,
        v,
        qd,
        tau,
        fb,
        f,
        x0,
        dt,
    }
}

fn main() {
    let rounds: usize = std::env::args()
        .nth(1)
        .map_or(31, |s| s.parse().expect("ROUNDS"));
    let mut cases: Vec<Case> = SIZES.iter().map(|&n| case(n)).collect();
    let mut aba_ns = vec![Vec::new(); SIZES.len()];
    let mut step_ns = vec![Vec::new(); SIZES.len()];
    for round in 0..=rounds {
        for (k, c) in cases.iter_mut().enumerate() {
            // about 3 ms per block whatever n
            let iters = 20_000 / c.n + 1;
            let loads = Loads::from_slices(Some(&c.fb), Some(&c.f)).unwrap();
            let a = block(iters, || {
                let out = algorithms::aba(
                    &c.robot,
                    &mut c.data,
                    &RigidState::new(black_box(&c.q), &c.v, &c.qd),
                    &c.tau,
                    &loads,
                )
                .unwrap();
                black_box(out[0]);
            });
            let s = block(iters / 4 + 1, || {
                c.x.copy_from_slice(&c.x0);
                c.arm
                    .step(
                        &mut c.ws,
                        black_box(&mut c.x),
                        c.dt,
                        &Inputs {
                            u: &c.tau,
                            loads,
                            wheel_torque: &[],
                        },
                    )
                    .unwrap();
                black_box(c.x[0]);
            });
            if round > 0 {
                // round 0 is a warm-up
                aba_ns[k].push(a);
                step_ns[k].push(s);
            }
        }
    }
    println!(
        "Interleaved over {rounds} rounds (median µs; ratios formed within each round, then the median):\n"
    );
    println!("| n | ABA | ABA(n) / ABA(7) | RK4 step | RK4 step / ABA |");
    println!("|---:|---:|---:|---:|---:|");
    for (k, &n) in SIZES.iter().enumerate() {
        let growth = median(
            aba_ns[k]
                .iter()
                .zip(&aba_ns[0])
                .map(|(a, a7)| a / a7)
                .collect(),
        );
        let per_fd = median(
            step_ns[k]
                .iter()
                .zip(&aba_ns[k])
                .map(|(s, a)| s / a)
                .collect(),
        );
        println!(
            "| {n} | {:.2} | {growth:.1} | {:.2} | {per_fd:.2} |",
            median(aba_ns[k].clone()) / 1e3,
            median(step_ns[k].clone()) / 1e3
        );
    }
}
