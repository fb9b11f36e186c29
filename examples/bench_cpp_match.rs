//! orbitflex's side of the Rust-vs-C++ comparison with Pinocchio (BENCHMARKS.md): the same URDF,
//! the same inputs and the same timing loop as `benches/pinocchio_cpp/bench_aba.cpp`.
//!
//! ```text
//! cargo run --release --example bench_cpp_match -- <urdf> <ee_link or -> [locked joint ...]
//!     [--only NAME[,NAME...]] [--blocks N] [--iters N]
//! ```
//! Prints `<name> <median ns per call>` for `aba`, `rnea`, `crba`, `rk4_step` (one flexible-joint
//! RK4 step, four forward dynamics) and `simulate_1e4` (10⁴ steps under MotorPD, trajectory
//! included: the pure-Rust figure that `benches/compare_pinocchio.py` sets against `simulate`
//! from Python). Medians are over blocks of calls, after a warm-up. `--iters N` replaces every
//! measurement's number of calls per block (`benches/pinocchio_cpp/callgrind.sh` runs one
//! measurement with two values of `--blocks` and counts the instructions of the extra calls).

use orbitflex::algorithms::{self, Data};
use orbitflex::{
    ArmWorkspace, FlexibleArm, FlexibleJoints, Inputs, Loads, MotorPD, RigidState, Robot, Schedule,
    StateSpec, UrdfOptions, Wrenches,
};
use std::hint::black_box;
use std::time::Instant;

/// How many blocks to time, and the calls per block if `--iters` overrides each measurement's own.
#[derive(Clone, Copy)]
struct Reps {
    blocks: usize,
    iters: Option<usize>,
}

/// Median over `reps.blocks` blocks of the mean time per call (ns) of `iters` calls of `f`
/// (or `reps.iters` calls when given).
fn median_ns(mut f: impl FnMut(), iters: usize, reps: Reps) -> f64 {
    let (blocks, iters) = (reps.blocks, reps.iters.unwrap_or(iters));
    for _ in 0..iters / 10 + 1 {
        f();
    }
    let mut times: Vec<f64> = (0..blocks)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..iters {
                f();
            }
            start.elapsed().as_secs_f64() * 1e9 / iters as f64
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

fn scientific(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:.15e}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut take_flag = |flag: &str| -> Option<String> {
        let i = args.iter().position(|a| a == flag)?;
        let value = args.get(i + 1).cloned();
        args.drain(i..(i + 2).min(args.len()));
        value
    };
    let only: Option<Vec<String>> =
        take_flag("--only").map(|s| s.split(',').map(str::to_string).collect());
    let blocks: usize = take_flag("--blocks").map_or(15, |s| s.parse().expect("--blocks N"));
    let iters: Option<usize> = take_flag("--iters").map(|s| s.parse().expect("--iters N"));
    let reps = Reps { blocks, iters };
    if args.len() < 2 {
        eprintln!("usage: bench_cpp_match <urdf> <ee_link or -> [locked joint ...] [--only NAMES] [--blocks N] [--iters N]");
        std::process::exit(2);
    }
    let options = UrdfOptions {
        ee_link: (args[1] != "-").then(|| args[1].clone()),
        locked_joints: args[2..].to_vec(),
        ..UrdfOptions::default()
    };
    let robot = Robot::from_urdf(&args[0], &options).expect("a valid URDF");
    let n = robot.dof();
    let wanted = |name: &str| only.as_ref().map_or(true, |o| o.iter().any(|w| w == name));

    // The inputs of bench_aba.cpp: q_i = 0.3 sin(i+1), q̇_i = 0.2 cos(i+1), τ_i = 1 + 0.1 i,
    // Pinocchio's base velocity [v; ω] = [0.01, -0.02, 0.03; 0.05, -0.04, 0.03] as [ω; v].
    let q: Vec<f64> = (0..n).map(|i| 0.3 * (i as f64 + 1.0).sin()).collect();
    let qd: Vec<f64> = (0..n).map(|i| 0.2 * (i as f64 + 1.0).cos()).collect();
    let tau: Vec<f64> = (0..n).map(|i| 1.0 + 0.1 * i as f64).collect();
    let twist = [0.05, -0.04, 0.03, 0.01, -0.02, 0.03];
    let (acc, qdd) = ([0.1; 6], vec![0.1; n]);
    // a zero wrench on every end-effector (as Pinocchio's rnea gets no external force)
    let zero_ee = vec![0.0; 6 * robot.end_effectors().len()];
    println!("model {} n {}", args[0], n);

    let mut data = Data::new(&robot);
    // The joint accelerations and one RK4 step's (q, θ) for run.sh's agreement check.
    let check = algorithms::aba(
        &robot,
        &mut data,
        &RigidState::new(&q, &twist, &qd),
        &tau,
        &Loads::ZERO,
    )
    .unwrap();
    println!("check_qdd {}", scientific(&check.as_slice()[6..]));
    if wanted("aba") {
        let t = median_ns(
            || {
                black_box(
                    algorithms::aba(
                        &robot,
                        &mut data,
                        &RigidState::new(black_box(&q), &twist, &qd),
                        &tau,
                        &Loads::ZERO,
                    )
                    .unwrap()[0],
                );
            },
            20_000,
            reps,
        );
        println!("aba {t:.1}");
    }
    if wanted("rnea") {
        let t = median_ns(
            || {
                black_box(
                    algorithms::rnea(
                        &robot,
                        &mut data,
                        &RigidState::new(black_box(&q), &twist, &qd),
                        &acc,
                        &qdd,
                        &zero_ee,
                    )
                    .unwrap()[0],
                );
            },
            20_000,
            reps,
        );
        println!("rnea {t:.1}");
    }
    if wanted("crba") {
        let t = median_ns(
            || {
                black_box(algorithms::crba(&robot, &mut data, black_box(&q)).unwrap()[(0, 0)]);
            },
            20_000,
            reps,
        );
        println!("crba {t:.1}");
    }
    if wanted("aba_derivatives") {
        let state = RigidState::new(&q, &twist, &qd);
        let t = median_ns(
            || {
                let d = algorithms::aba_derivatives(&robot, &mut data, &state, &tau, &Loads::ZERO)
                    .unwrap();
                black_box(d.fd_q[(0, 0)]);
            },
            4_000,
            reps,
        );
        println!("aba_derivatives {t:.1}");
    }
    if wanted("rnea_derivatives") {
        let state = RigidState::new(&q, &twist, &qd);
        let t = median_ns(
            || {
                let d =
                    algorithms::rnea_derivatives(&robot, &mut data, &state, &acc, &qdd, &zero_ee)
                        .unwrap();
                black_box(d.id_q[(0, 0)]);
            },
            4_000,
            reps,
        );
        println!("rnea_derivatives {t:.1}");
    }

    // bench_aba.cpp's FlexArm: k = 2·10⁴, d = 2, j = 160² · 4·10⁻⁵, β = 1; u = 1; dt = 1 ms.
    let joints = FlexibleJoints::from_gear(
        vec![2e4; n],
        &vec![160.0; n],
        &vec![4e-5; n],
        vec![2.0; n],
        vec![1.0; n],
    )
    .unwrap();
    let arm = FlexibleArm::new(robot, joints).unwrap();
    if wanted("rk4_step") {
        let x0 = arm
            .state(&StateSpec {
                q: Some(&q),
                qd: Some(&qd),
                base_twist: Some(&twist),
                ..StateSpec::default()
            })
            .unwrap();
        let mut ws = ArmWorkspace::new(&arm);
        let mut x = x0.clone();
        let u = vec![1.0; n];
        arm.step(&mut ws, &mut x, 1e-3, &Inputs::torques(&u))
            .unwrap();
        println!("check_step {}", scientific(&x[7..7 + 2 * n]));
        let t = median_ns(
            || {
                x.copy_from_slice(&x0);
                arm.step(&mut ws, black_box(&mut x), 1e-3, &Inputs::torques(&u))
                    .unwrap();
                black_box(x[0]);
            },
            5_000,
            reps,
        );
        println!("rk4_step {t:.1}");
    }
    if wanted("step_jacobians") {
        // The step's Jacobians analytically, and by central differences on the tangent space
        // (2 steps per column), the way a user would get them without derivatives.
        let x0 = arm
            .state(&StateSpec {
                q: Some(&q),
                qd: Some(&qd),
                base_twist: Some(&twist),
                ..StateSpec::default()
            })
            .unwrap();
        let mut ws = ArmWorkspace::new(&arm);
        let u = vec![1.0; n];
        let t = median_ns(
            || {
                let j = arm
                    .step_jacobians(&mut ws, black_box(&x0), 1e-3, &Inputs::torques(&u))
                    .unwrap();
                black_box(j.x[(0, 0)]);
            },
            500,
            reps,
        );
        println!("step_jacobians {t:.1}");
    }
    if wanted("step_jacobians_central_differences") {
        let x0 = arm
            .state(&StateSpec {
                q: Some(&q),
                qd: Some(&qd),
                base_twist: Some(&twist),
                ..StateSpec::default()
            })
            .unwrap();
        let mut ws = ArmWorkspace::new(&arm);
        let u = vec![1.0; n];
        let tangent = arm.tangent_size();
        let mut dx = vec![0.0; tangent];
        let (mut plus, mut minus) = (vec![0.0; x0.len()], vec![0.0; x0.len()]);
        let mut layout_out = vec![0.0; tangent];
        let t = median_ns(
            || {
                for k in 0..tangent {
                    dx[k] = 1e-6;
                    arm.layout().integrate(&x0, &dx, &mut plus);
                    dx[k] = -1e-6;
                    arm.layout().integrate(&x0, &dx, &mut minus);
                    dx[k] = 0.0;
                    arm.step(&mut ws, &mut plus, 1e-3, &Inputs::torques(&u))
                        .unwrap();
                    arm.step(&mut ws, &mut minus, 1e-3, &Inputs::torques(&u))
                        .unwrap();
                    arm.layout().difference(&minus, &plus, &mut layout_out);
                    black_box(layout_out[0]);
                }
            },
            100,
            reps,
        );
        println!("step_jacobians_central_differences {t:.1}");
    }
    if wanted("simulate_1e4") {
        // compare_pinocchio.py's run: at rest, MotorPD kp = 2000, kd = 800 to θ_ref = 0.2.
        let x0 = arm.rest_state();
        let t = median_ns(
            || {
                let mut pd = MotorPD::new(
                    vec![2000.0; n],
                    vec![800.0; n],
                    Schedule::Constant(vec![0.2; n]),
                    Schedule::Zero,
                    Schedule::Zero,
                )
                .unwrap();
                let traj = arm
                    .simulate(black_box(&x0), 1e-3, 10_000, &mut pd, &Wrenches::ZERO)
                    .unwrap();
                black_box(traj.len());
            },
            1,
            reps,
        );
        println!("simulate_1e4 {t:.1}");
    }
}
