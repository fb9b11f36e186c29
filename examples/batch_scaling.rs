//! Throughput of `simulate_batch` on 1 and 2 threads, in Rust (no Python): median wall time of
//! alternating rounds.
//!
//!     cargo run --release --example batch_scaling -- [RUNS] [STEPS] [ROUNDS] [N]
//!
//! N = 7 (default) is the built-in space arm; any other N a seeded random chain of N joints
//! (`orbitflex::testing::random_chain`) with `FlexibleJoints::defaults_for`.
use orbitflex::integrate::batch::{
    simulate_batch, Batch, BatchControl, BatchInput, BatchSettings, BatchWatch, PerRun,
};
use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
use std::time::Instant;

fn main() -> orbitflex::Result<()> {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let (runs, steps, rounds) = (
        *args.first().unwrap_or(&16),
        *args.get(1).unwrap_or(&4000),
        *args.get(2).unwrap_or(&5),
    );
    let n = *args.get(3).unwrap_or(&7);
    let arm = if n == 7 {
        FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?
    } else {
        let robot = orbitflex::testing::random_chain(n, 1);
        let joints = FlexibleJoints::defaults_for(&robot)?;
        FlexibleArm::new(robot, joints)?
    };
    let dt = 0.25
        * arm
            .rk4_stability_limit(&arm.rest_state(), &orbitflex::Schedule::Zero)?
            .dt;
    let x0 = arm.rest_state();
    let len = x0.len();
    let u: Vec<f64> = (0..runs)
        .flat_map(|b| vec![0.01 * (b + 1) as f64; n])
        .collect();
    let batch = Batch {
        runs,
        arms: PerRun::All(&arm),
        x0: BatchInput::new("x0s", &x0, &[len], runs, None, len)?,
        u: BatchControl::Open(BatchInput::new("u", &u, &[runs, n], runs, Some(steps), n)?),
        base_wrench: BatchInput::zero(6),
        ee_wrench: BatchInput::zero(6),
        wheel_torque: BatchControl::zero(0),
    };
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..rounds {
        for (k, threads) in [1, 2].into_iter().enumerate() {
            let settings = BatchSettings {
                dt,
                steps,
                record_every: 1,
                keep_rows: false,
                threads: Some(threads),
            };
            let start = Instant::now();
            let record = simulate_batch(&batch, &settings, &BatchWatch::default())?;
            times[k].push(start.elapsed().as_secs_f64());
            let failed = record
                .status
                .iter()
                .filter(|s| s.failed_step().is_some())
                .count();
            assert_eq!(
                failed, 0,
                "{failed} runs failed; this measures complete runs"
            );
        }
    }
    for t in &mut times {
        t.sort_by(f64::total_cmp);
    }
    let (one, two) = (times[0][rounds / 2], times[1][rounds / 2]);
    println!(
        "n = {n}, {runs} runs x {steps} steps of {dt:.3e} s: 1 thread {one:.3} s ({:.2} us/step), 2 threads {two:.3} s, ratio {:.3}",
        one / (runs * steps) as f64 * 1e6,
        one / two
    );
    Ok(())
}
