//! Times the linear analysis of the built-in 7-joint space arm (docs/modes.md, "Cost"):
//! `cargo run --release --example analysis_timing`. Medians of repeated runs, one thread unless
//! said.

use orbitflex::analysis::{
    frequency_response, modes, state_space, sweep, InputGroup, LinearSpec, OutputGroup,
};
use orbitflex::{FlexibleArm, FlexibleJoints, Robot, StateSpec};
use std::time::Instant;

fn median_seconds(runs: usize, mut f: impl FnMut()) -> f64 {
    f(); // warm up
    let mut times: Vec<f64> = (0..runs)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[runs / 2]
}

fn main() -> orbitflex::Result<()> {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
    let mut ws = arm.workspace();
    let q = [0.3, -0.4, 0.2, 1.1, -0.3, 0.5, 0.1];
    let x = arm.state(&StateSpec {
        q: Some(&q),
        ..StateSpec::default()
    })?;
    let free = LinearSpec::default();
    let a = state_space(&arm, &mut ws, &x, &free)?.a;
    let eigen = median_seconds(200, || {
        orbitflex::linalg::eigen(&a).unwrap();
    });
    println!(
        "eigenvalues and eigenvectors of A (40 × 40): {:.0} µs",
        eigen * 1e6
    );
    for (name, damped) in [
        ("modes (damped, state matrix)", true),
        ("modes (undamped pencil)", false),
    ] {
        let t = median_seconds(200, || {
            modes(&arm, &mut ws, &x, &free, damped).unwrap();
        });
        println!("{name}, free base and motors: {:.0} µs", t * 1e6);
    }
    let mut states = Vec::new();
    for i in 0..100 {
        let mut q = q;
        q[3] = 2.5 * i as f64 / 99.0;
        states.extend(arm.state(&StateSpec {
            q: Some(&q),
            ..StateSpec::default()
        })?);
    }
    let t = median_seconds(11, || {
        sweep(&arm, &states, &free, true, Some(1)).unwrap();
    });
    println!("sweep of 100 configurations, one thread: {:.1} ms", t * 1e3);
    let t = median_seconds(11, || {
        sweep(&arm, &states, &free, true, None).unwrap();
    });
    println!("sweep of 100 configurations, every core: {:.1} ms", t * 1e3);
    let spec = LinearSpec {
        inputs: &[InputGroup::MotorTorque],
        outputs: &[OutputGroup::Q],
        ..LinearSpec::default()
    };
    let ss = state_space(&arm, &mut ws, &x, &spec)?;
    let freqs: Vec<f64> = (0..1000)
        .map(|i| 0.1 * 1000f64.powf(i as f64 / 999.0))
        .collect();
    let t = median_seconds(11, || {
        frequency_response(&ss, &freqs).unwrap();
    });
    println!(
        "frequency response, 7 inputs × 7 outputs, 40 states, 1000 frequencies: {:.1} ms",
        t * 1e3
    );
    Ok(())
}
