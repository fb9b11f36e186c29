//! Criterion benchmarks of the rigid and flexible dynamics (BENCHMARKS.md).
//!
//! Random floating-base chains (`orbitflex::testing::random_chain`) with n ∈ {7, 14, 28, 56, 112};
//! every model, workspace and input is seeded and built outside `b.iter`. Groups:
//! - `mass_matrix`, `bias_forces`, `forward_dynamics`: the paper's operator form (O(n³), dense)
//!   against the recursive algorithms (CRBA, RNEA, ABA) on the same inputs;
//! - `inverse_dynamics`: recursive Newton–Euler;
//! - `rk4_step`: one `FlexibleArm::step` (four derivatives) with an `ArmWorkspace`;
//! - `simulate_1e4`: `FlexibleArm::simulate` of 10⁴ steps under `MotorPD`, trajectory included;
//! - `space_arm`: the built-in model, the figures the Python comparison refers to;
//! - `plan_slew`: planning the built-in arm's 7-joint slew (held and free base) and its
//!   flexible-joint inverse dynamics at one instant.
//!
//! `cargo bench --bench dynamics` runs everything; `cargo bench --bench dynamics -- forward`
//! selects groups by name.

use criterion::{
    criterion_group, criterion_main, BenchmarkId, Criterion, SamplingMode, Throughput,
};
use orbitflex::algorithms::{self, Data};
use orbitflex::testing::{random_chain, random_state, Rng};
use orbitflex::{
    ArmWorkspace, FlexibleArm, FlexibleJoints, Inputs, Loads, MotorPD, Operators, RigidState,
    Robot, Schedule, StateSpec, Wrenches,
};
use std::hint::black_box;
use std::time::Duration;

const SIZES: [usize; 5] = [7, 14, 28, 56, 112];
const SEED: u64 = 4;

/// A model and one state with inputs `(q, V_B, q̇, τ, f_B, f)`.
struct Case {
    robot: Robot,
    q: Vec<f64>,
    v: Vec<f64>,
    qd: Vec<f64>,
    tau: Vec<f64>,
    fb: Vec<f64>,
    f: Vec<f64>,
}

fn case(n: usize) -> Case {
    let robot = random_chain(n, SEED);
    let (q, v, qd) = random_state(&robot, SEED);
    let mut rng = Rng::new(SEED + 1);
    Case {
        tau: rng.vector(n, -5.0, 5.0),
        fb: rng.vector(6, -5.0, 5.0),
        f: rng.vector(6, -5.0, 5.0),
        robot,
        q,
        v,
        qd,
    }
}

/// The operator form at n = 112 takes tens of milliseconds per call: fewer samples there.
fn operator_sample_size(n: usize) -> usize {
    if n >= 56 {
        10
    } else {
        30
    }
}

fn mass_matrix(c: &mut Criterion) {
    let mut group = c.benchmark_group("mass_matrix");
    for n in SIZES {
        let s = case(n);
        let zeros = vec![0.0; n];
        let mut data = Data::new(&s.robot);
        group.sample_size(100);
        group.bench_with_input(BenchmarkId::new("recursive", n), &n, |b, _| {
            b.iter(|| {
                algorithms::crba(&s.robot, &mut data, black_box(&s.q))
                    .unwrap()
                    .nrows()
            })
        });
        group.sample_size(operator_sample_size(n));
        group.bench_with_input(BenchmarkId::new("operator", n), &n, |b, _| {
            b.iter(|| {
                Operators::new(&s.robot, &RigidState::at_rest(black_box(&s.q), &zeros))
                    .unwrap()
                    .mass_matrix()
            })
        });
    }
    group.finish();
}

fn bias_forces(c: &mut Criterion) {
    let mut group = c.benchmark_group("bias_forces");
    for n in SIZES {
        let s = case(n);
        let mut data = Data::new(&s.robot);
        group.sample_size(100);
        group.bench_with_input(BenchmarkId::new("recursive", n), &n, |b, _| {
            b.iter(|| {
                algorithms::bias_forces(
                    &s.robot,
                    &mut data,
                    &RigidState::new(black_box(&s.q), &s.v, &s.qd),
                )
                .unwrap()[0]
            })
        });
        group.sample_size(operator_sample_size(n));
        group.bench_with_input(BenchmarkId::new("operator", n), &n, |b, _| {
            b.iter(|| {
                Operators::new(&s.robot, &RigidState::new(black_box(&s.q), &s.v, &s.qd))
                    .unwrap()
                    .bias_forces()
            })
        });
    }
    group.finish();
}

fn forward_dynamics(c: &mut Criterion) {
    let mut group = c.benchmark_group("forward_dynamics");
    for n in SIZES {
        let s = case(n);
        let loads = Loads::from_slices(Some(&s.fb), Some(&s.f)).unwrap();
        let mut data = Data::new(&s.robot);
        group.sample_size(100);
        group.bench_with_input(BenchmarkId::new("recursive", n), &n, |b, _| {
            b.iter(|| {
                algorithms::aba(
                    &s.robot,
                    &mut data,
                    &RigidState::new(black_box(&s.q), &s.v, &s.qd),
                    &s.tau,
                    &loads,
                )
                .unwrap()[0]
            })
        });
        group.sample_size(operator_sample_size(n));
        group.bench_with_input(BenchmarkId::new("operator", n), &n, |b, _| {
            b.iter(|| {
                Operators::new(&s.robot, &RigidState::new(black_box(&s.q), &s.v, &s.qd))
                    .unwrap()
                    .forward_dynamics(&s.tau, &loads)
                    .unwrap()
            })
        });
    }
    group.finish();
}

fn inverse_dynamics(c: &mut Criterion) {
    let mut group = c.benchmark_group("inverse_dynamics");
    for n in SIZES {
        let s = case(n);
        let mut rng = Rng::new(SEED + 2);
        let (base_acc, qdd) = (rng.vector(6, -1.0, 1.0), rng.vector(n, -1.0, 1.0));
        let mut data = Data::new(&s.robot);
        group.bench_with_input(BenchmarkId::new("recursive", n), &n, |b, _| {
            b.iter(|| {
                algorithms::rnea(
                    &s.robot,
                    &mut data,
                    &RigidState::new(black_box(&s.q), &s.v, &s.qd),
                    &base_acc,
                    &qdd,
                    &s.f,
                )
                .unwrap()[0]
            })
        });
    }
    group.finish();
}

/// The analytical derivatives of the forward and inverse dynamics (O(n²)).
fn derivatives(c: &mut Criterion) {
    let mut group = c.benchmark_group("derivatives");
    for n in SIZES {
        let s = case(n);
        let loads = Loads::from_slices(Some(&s.fb), Some(&s.f)).unwrap();
        let mut data = Data::new(&s.robot);
        let state = RigidState::new(&s.q, &s.v, &s.qd);
        group.sample_size(if n >= 56 { 20 } else { 100 });
        group.bench_with_input(BenchmarkId::new("aba_derivatives", n), &n, |b, _| {
            b.iter(|| {
                algorithms::aba_derivatives(&s.robot, &mut data, black_box(&state), &s.tau, &loads)
                    .unwrap()
                    .fd_q[(0, 0)]
            })
        });
        group.bench_with_input(BenchmarkId::new("rnea_derivatives", n), &n, |b, _| {
            b.iter(|| {
                algorithms::rnea_derivatives(
                    &s.robot,
                    &mut data,
                    black_box(&state),
                    &s.fb,
                    &s.tau,
                    &s.f,
                )
                .unwrap()
                .id_q[(0, 0)]
            })
        });
    }
    group.finish();
}

/// The Jacobians of one flexible RK4 step, against one step.
fn step_jacobians(c: &mut Criterion) {
    let mut group = c.benchmark_group("step_jacobians");
    for n in SIZES {
        let s = case(n);
        let arm = flexible_arm(s.robot);
        let x0 = arm
            .state(&StateSpec {
                q: Some(&s.q),
                qd: Some(&s.qd),
                base_twist: Some(&s.v),
                ..StateSpec::default()
            })
            .unwrap();
        let dt = stable_dt(&arm, &s.q);
        let mut ws = ArmWorkspace::new(&arm);
        let u = vec![0.3; n];
        group.sample_size(if n >= 56 { 10 } else { 50 });
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                arm.step_jacobians(&mut ws, black_box(&x0), dt, &Inputs::torques(&u))
                    .unwrap()
                    .x[(0, 0)]
            })
        });
    }
    group.finish();
}

/// A flexible arm on `robot` whose stiffest joint mode is well inside the RK4 stability limit
/// at `dt`: stiffness 2·10³ N·m/rad, motor inertia 0.5 kg·m², light damping.
fn flexible_arm(robot: Robot) -> FlexibleArm {
    let n = robot.dof();
    FlexibleArm::new(
        robot,
        FlexibleJoints::uniform(n, 2e3, 0.5, 1.0, 0.5).unwrap(),
    )
    .unwrap()
}

/// A stable time step: a quarter of the arm's RK4 stability limit, at most 1 ms.
fn stable_dt(arm: &FlexibleArm, q: &[f64]) -> f64 {
    let x = arm
        .state(&StateSpec {
            q: Some(q),
            ..StateSpec::default()
        })
        .unwrap();
    (0.25 * arm.rk4_stability_limit(&x, &Schedule::Zero).unwrap().dt).min(1e-3)
}

fn rk4_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("rk4_step");
    for n in SIZES {
        let s = case(n);
        let arm = flexible_arm(s.robot);
        let theta: Vec<f64> = s.q.iter().map(|q| q + 0.01).collect();
        let x0 = arm
            .state(&StateSpec {
                q: Some(&s.q),
                theta: Some(&theta),
                qd: Some(&s.qd),
                base_twist: Some(&s.v),
                ..StateSpec::default()
            })
            .unwrap();
        let loads = Loads::from_slices(Some(&s.fb), Some(&s.f)).unwrap();
        let dt = stable_dt(&arm, &s.q);
        let mut ws = ArmWorkspace::new(&arm);
        let mut x = x0.clone();
        let u = vec![0.3; n];
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                x.copy_from_slice(&x0);
                arm.step(
                    &mut ws,
                    black_box(&mut x),
                    dt,
                    &Inputs {
                        u: &u,
                        loads,
                        wheel_torque: &[],
                    },
                )
                .unwrap();
                x[0]
            })
        });
    }
    group.finish();
}

fn motor_pd(n: usize, reference: f64) -> MotorPD {
    MotorPD::new(
        vec![200.0; n],
        vec![40.0; n],
        Schedule::Constant(vec![reference; n]),
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap()
}

const STEPS: usize = 10_000;

fn simulate(c: &mut Criterion) {
    let mut group = c.benchmark_group("simulate_1e4");
    group.sample_size(10);
    group.sampling_mode(SamplingMode::Flat);
    group.measurement_time(Duration::from_secs(10));
    group.throughput(Throughput::Elements(STEPS as u64));
    for n in SIZES {
        let s = case(n);
        let arm = flexible_arm(s.robot);
        let x0 = arm
            .state(&StateSpec {
                q: Some(&s.q),
                ..StateSpec::default()
            })
            .unwrap();
        let dt = stable_dt(&arm, &s.q);
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                let mut pd = motor_pd(n, 0.2);
                arm.simulate(black_box(&x0), dt, STEPS, &mut pd, &Wrenches::ZERO)
                    .unwrap()
                    .len()
            })
        });
    }
    group.finish();
}

/// The built-in space arm with the parameters of `benches/compare_pinocchio.py`: the per-call
/// dynamics, one RK4 step and `simulate` of 10⁴ steps at dt = 1 ms under MotorPD.
fn space_arm(c: &mut Criterion) {
    let robot = Robot::space_arm();
    let n = robot.dof();
    let mut group = c.benchmark_group("space_arm");
    let mut rng = Rng::new(SEED);
    let q = rng.vector(n, -1.0, 1.0);
    let v = rng.vector(6, -0.1, 0.1);
    let qd = rng.vector(n, -0.2, 0.2);
    let tau = rng.vector(n, -10.0, 10.0);
    let zero6 = [0.0; 6];
    let mut data = Data::new(&robot);
    group.bench_function("aba", |b| {
        b.iter(|| {
            algorithms::aba(
                &robot,
                &mut data,
                &RigidState::new(black_box(&q), &v, &qd),
                &tau,
                &Loads::ZERO,
            )
            .unwrap()[0]
        })
    });
    group.bench_function("rnea", |b| {
        b.iter(|| {
            algorithms::rnea(
                &robot,
                &mut data,
                &RigidState::new(black_box(&q), &v, &qd),
                &zero6,
                &tau,
                &zero6,
            )
            .unwrap()[0]
        })
    });
    group.bench_function("crba", |b| {
        b.iter(|| algorithms::crba(&robot, &mut data, black_box(&q)).unwrap()[(0, 0)])
    });
    let arm = FlexibleArm::new(
        robot,
        FlexibleJoints::from_gear(
            vec![2e4; n],
            &vec![160.0; n],
            &vec![4e-5; n],
            vec![2.0; n],
            vec![1.0; n],
        )
        .unwrap(),
    )
    .unwrap();
    let x0 = arm.rest_state();
    let mut ws = ArmWorkspace::new(&arm);
    let mut x = x0.clone();
    let u = vec![1.0; n];
    group.bench_function("rk4_step", |b| {
        b.iter(|| {
            x.copy_from_slice(&x0);
            arm.step(&mut ws, black_box(&mut x), 1e-3, &Inputs::torques(&u))
                .unwrap();
            x[0]
        })
    });
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(10));
    group.throughput(Throughput::Elements(STEPS as u64));
    group.bench_function("simulate_1e4", |b| {
        b.iter(|| {
            let mut pd = MotorPD::new(
                vec![2000.0; n],
                vec![800.0; n],
                Schedule::Constant(vec![0.2; n]),
                Schedule::Zero,
                Schedule::Zero,
            )
            .unwrap();
            arm.simulate(black_box(&x0), 1e-3, STEPS, &mut pd, &Wrenches::ZERO)
                .unwrap()
                .len()
        })
    });
    group.finish();
}

/// Planning a 7-joint point-to-point slew (target: under 0.2 s on one core), and the jet inverse
/// dynamics it runs once per sample.
fn plan_slew(c: &mut Criterion) {
    use orbitflex::planning::{self, BaseMode, Limits, LinkMotion};
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let goal = [0.8, -0.6, 0.5, 1.0, -0.7, 0.6, 0.9];
    // the base limits bound the wrench that holds a held base; a free base takes none
    let limits = |base: BaseMode| {
        let held = base == BaseMode::Held;
        Limits::new(
            vec![60.0, 60.0, 60.0, 30.0, 15.0, 15.0, 15.0],
            vec![0.5],
            held.then_some(80.0),
            held.then_some(60.0),
        )
        .unwrap()
    };
    let mut group = c.benchmark_group("plan_slew");
    group.sample_size(10);
    for base in [BaseMode::Held, BaseMode::Free] {
        let limits = limits(base);
        group.bench_function(base.name(), |b| {
            b.iter(|| {
                planning::plan_slew(&arm, black_box(&goal), None, &limits, base, &[])
                    .unwrap()
                    .duration()
            })
        });
    }
    let m: [Vec<f64>; 5] = std::array::from_fn(|k| vec![0.3 / (1.0 + k as f64); 7]);
    let motion = LinkMotion {
        q: &m[0],
        qd: &m[1],
        qdd: &m[2],
        qddd: &m[3],
        qdddd: &m[4],
    };
    let deflection = [0.0; 7];
    group.sample_size(50);
    for base in [BaseMode::Held, BaseMode::Free] {
        group.bench_function(format!("inverse_dynamics_{}", base.name()), |b| {
            b.iter(|| {
                arm.inverse_dynamics(black_box(&motion), base, Some(&deflection))
                    .unwrap()
                    .u[0]
            })
        });
    }
    group.finish();
}

criterion_group!(
    benches,
    forward_dynamics,
    mass_matrix,
    bias_forces,
    inverse_dynamics,
    rk4_step,
    derivatives,
    step_jacobians,
    simulate,
    space_arm,
    plan_slew
);
criterion_main!(benches);
