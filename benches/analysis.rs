//! Criterion benchmarks of the linear analysis (docs/modes.md, "Cost"), on the built-in 7-joint
//! space arm (free base and motors, 40 states) at one configuration; models, workspaces and
//! inputs are built outside `b.iter`. Groups:
//! - `eigen`: eigenvalues and eigenvectors of the 40 × 40 state matrix (`linalg::eigen`);
//! - `modes`: `analysis::modes`, damped (state matrix) and undamped (pencil), per base and motors;
//!   and with four reaction wheels in a pyramid (44 states), open loop and under an `AttitudePD`;
//! - `frequency_response`: 7 inputs × 7 outputs at 1000 frequencies (Laub's method);
//! - `sweep`: the modes at 100 configurations over the elbow angle, on one thread.
//!
//! `cargo bench --bench analysis`.

use criterion::{criterion_group, criterion_main, Criterion};
use orbitflex::analysis::{
    frequency_response, modes, state_space, sweep, InputGroup, LinearSpec, Motors, OutputGroup,
};
use orbitflex::control::{AttitudePD, AttitudeTarget};
use orbitflex::flex::{ReactionWheels, Wheel};
use orbitflex::planning::BaseMode;
use orbitflex::{FlexibleArm, FlexibleJoints, Robot, StateSpec};
use std::hint::black_box;
use std::time::Duration;

const Q: [f64; 7] = [0.3, -0.4, 0.2, 1.1, -0.3, 0.5, 0.1];

fn arm() -> FlexibleArm {
    FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap()
}

/// Four wheels in a pyramid (axes `(±1, ±1, 1)/√3`), as `orbitflex.models.pyramid_wheels()`.
fn pyramid() -> ReactionWheels {
    let wheels = (0..4)
        .map(|k| {
            let az = std::f64::consts::FRAC_PI_4 + std::f64::consts::FRAC_PI_2 * k as f64;
            let (s, c) = az.sin_cos();
            let tilt = (1.0f64 / 3.0).sqrt();
            let flat = (2.0f64 / 3.0).sqrt();
            Wheel {
                axis: [flat * c, flat * s, tilt],
                position: [0.45 * c, 0.45 * s, -0.45],
                mass: 12.0,
                spin_inertia: 0.25,
                transverse_inertia: 0.15,
                max_torque: 60.0,
                max_speed: 800.0,
                friction: 0.0,
            }
        })
        .collect();
    ReactionWheels::new(wheels).unwrap()
}

fn benches(c: &mut Criterion) {
    let arm = arm();
    let mut ws = arm.workspace();
    let x = arm
        .state(&StateSpec {
            q: Some(&Q),
            ..StateSpec::default()
        })
        .unwrap();
    let free = LinearSpec::default();
    let a = state_space(&arm, &mut ws, &x, &free).unwrap().a;
    c.bench_function("eigen/state_matrix_40", |b| {
        b.iter(|| orbitflex::linalg::eigen(black_box(&a)).unwrap())
    });
    let mut group = c.benchmark_group("modes");
    for (base, motors, name) in [
        (BaseMode::Free, Motors::Free, "free_free"),
        (BaseMode::Free, Motors::Clamped, "free_clamped"),
        (BaseMode::Held, Motors::Free, "held_free"),
    ] {
        let spec = LinearSpec {
            base,
            motors,
            ..LinearSpec::default()
        };
        for (damped, kind) in [(true, "damped"), (false, "undamped")] {
            group.bench_function(format!("{name}/{kind}"), |b| {
                b.iter(|| modes(&arm, &mut ws, black_box(&x), &spec, damped).unwrap())
            });
        }
    }
    // the same arm with four wheels in a pyramid, open loop and with the bus held by them
    let wheeled = arm.clone().with_wheels(pyramid()).unwrap();
    let mut wheeled_ws = wheeled.workspace();
    let xw = wheeled
        .state(&StateSpec {
            q: Some(&Q),
            ..StateSpec::default()
        })
        .unwrap();
    let allocation = wheeled.wheels().unwrap().allocation().unwrap();
    let pd = AttitudePD::new([2e5; 3], [2e4; 3], AttitudeTarget::Initial, allocation).unwrap();
    let held = LinearSpec {
        attitude: Some(&pd),
        ..LinearSpec::default()
    };
    for (spec, name) in [(free, "wheels_4/open"), (held, "wheels_4/attitude_pd")] {
        group.bench_function(format!("{name}/damped"), |b| {
            b.iter(|| modes(&wheeled, &mut wheeled_ws, black_box(&xw), &spec, true).unwrap())
        });
    }
    group.finish();
    let spec = LinearSpec {
        inputs: &[InputGroup::MotorTorque],
        outputs: &[OutputGroup::Q],
        ..LinearSpec::default()
    };
    let ss = state_space(&arm, &mut ws, &x, &spec).unwrap();
    let freqs: Vec<f64> = (0..1000)
        .map(|i| 0.1 * 1000f64.powf(i as f64 / 999.0))
        .collect();
    let mut group = c.benchmark_group("frequency_response");
    group.sample_size(20);
    group.bench_function("7x7_1000_frequencies", |b| {
        b.iter(|| frequency_response(black_box(&ss), &freqs).unwrap())
    });
    group.finish();
    let mut states = Vec::new();
    for i in 0..100 {
        let mut q = Q;
        q[3] = 2.5 * i as f64 / 99.0;
        states.extend(
            arm.state(&StateSpec {
                q: Some(&q),
                ..StateSpec::default()
            })
            .unwrap(),
        );
    }
    let mut group = c.benchmark_group("sweep");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    group.bench_function("100_configurations_1_thread", |b| {
        b.iter(|| sweep(&arm, black_box(&states), &free, true, Some(1)).unwrap())
    });
    group.finish();
}

criterion_group!(analysis_benches, benches);
criterion_main!(analysis_benches);
