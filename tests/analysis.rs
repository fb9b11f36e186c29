//! Linear analysis (`orbitflex::analysis`): closed forms of one flexible joint, the held base's
//! linearisation against finite differences of the fixed-base dynamics, the eigen equation of
//! every mode, exact rigid-body counts, the frequency response against a dense solve, and the
//! physics of the modes (stiffer springs, clamped motors, PD gains).

use nalgebra::{Complex, DMatrix, DVector};
use orbitflex::algorithms::{self, Data};
use orbitflex::analysis::{
    frequency_response, modes, state_space, sweep, InputGroup, LinearSpec, Motors, OutputGroup,
};
use orbitflex::integrate::Feedback;
use orbitflex::planning::BaseMode;
use orbitflex::testing::{
    random_chain, random_joints, random_tree, random_tree_all_leaves, Rng, TREE_THREE_ARMS,
};
use orbitflex::{FlexibleArm, FlexibleJoints, RigidState, Robot, StateSpec, UrdfOptions};
use std::f64::consts::TAU;

/// One link turning about z at the base's origin: inertia about the joint
/// `I = I_zz + m c² = 0.3 + 2 · 0.5² = 0.8` kg·m².
const ONE_JOINT: &str = r#"<robot name="one_joint">
  <link name="base"><inertial><mass value="100"/>
    <inertia ixx="10" iyy="10" izz="10" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j" type="continuous"><parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/></joint>
  <link name="arm"><inertial><origin xyz="0.5 0 0"/><mass value="2"/>
    <inertia ixx="0.1" iyy="0.2" izz="0.3" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>"#;
const LINK_INERTIA: f64 = 0.8;

fn one_joint(k: f64, j: f64, d: f64, beta: f64) -> FlexibleArm {
    let robot = Robot::from_urdf_string(ONE_JOINT, &UrdfOptions::default()).unwrap();
    FlexibleArm::new(robot, FlexibleJoints::uniform(1, k, j, d, beta).unwrap()).unwrap()
}

fn spec(base: BaseMode, motors: Motors) -> LinearSpec<'static> {
    LinearSpec {
        base,
        motors,
        ..LinearSpec::default()
    }
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Held base: `f = √(k (1/I + 1/j)) / 2π` with free motors, `√(k/I) / 2π` clamped, and one
/// rigid-body mode (link and motor turning together) with free motors; with a joint damper the
/// damping ratio is `d / (2 √(k μ))`, `μ = I j / (I + j)`. Damped and undamped problems agree.
#[test]
fn one_flexible_joint_matches_its_closed_forms() {
    let (k, j) = (500.0, 0.3);
    let arm = one_joint(k, j, 0.0, 0.0);
    let x = arm.rest_state();
    let mut ws = arm.workspace();
    let free = ((k * (1.0 / LINK_INERTIA + 1.0 / j)).sqrt()) / TAU;
    let clamped = (k / LINK_INERTIA).sqrt() / TAU;
    for damped in [true, false] {
        let m = modes(
            &arm,
            &mut ws,
            &x,
            &spec(BaseMode::Held, Motors::Free),
            damped,
        )
        .unwrap();
        assert_eq!((m.rigid_body, m.frequency_hz.len()), (1, 1));
        assert!(
            rel(m.frequency_hz[0], free) < 1e-10,
            "{} vs {free}",
            m.frequency_hz[0]
        );
        assert!(m.damping_ratio[0].abs() < 1e-12);
        let m = modes(
            &arm,
            &mut ws,
            &x,
            &spec(BaseMode::Held, Motors::Clamped),
            damped,
        )
        .unwrap();
        assert_eq!((m.rigid_body, m.frequency_hz.len()), (0, 1));
        assert!(rel(m.frequency_hz[0], clamped) < 1e-10);
    }
    // a joint damper d and motor friction β = 0: the relative coordinate is a damped oscillator
    let d = 3.0;
    let arm = one_joint(k, j, d, 0.0);
    let mu = LINK_INERTIA * j / (LINK_INERTIA + j);
    let zeta = d / (2.0 * (k * mu).sqrt());
    let m = modes(
        &arm,
        &mut ws_for(&arm),
        &x,
        &spec(BaseMode::Held, Motors::Free),
        true,
    )
    .unwrap();
    assert!(
        rel(m.damping_ratio[0], zeta) < 1e-10,
        "{} vs {zeta}",
        m.damping_ratio[0]
    );
    assert!(rel(m.natural_frequency_hz[0], free) < 1e-10);
    assert!(rel(m.frequency_hz[0], free * (1.0 - zeta * zeta).sqrt()) < 1e-10);
    // clamped: I q̈ + d q̇ + k q = 0
    let zeta = d / (2.0 * (k * LINK_INERTIA).sqrt());
    let m = modes(
        &arm,
        &mut ws_for(&arm),
        &x,
        &spec(BaseMode::Held, Motors::Clamped),
        true,
    )
    .unwrap();
    assert!(rel(m.damping_ratio[0], zeta) < 1e-10);
    // past critical damping (ζ = 2) the mode decays without oscillating: no frequency, and its
    // two real eigenvalues ω_n (−ζ ± √(ζ² − 1)) listed as overdamped, slowest first
    let d = 4.0 * (k * LINK_INERTIA).sqrt();
    let arm = one_joint(k, j, d, 0.0);
    let clamped = spec(BaseMode::Held, Motors::Clamped);
    let m = modes(&arm, &mut ws_for(&arm), &x, &clamped, true).unwrap();
    assert!(m.frequency_hz.is_empty() && m.shapes.ncols() == 0);
    let (omega, zeta) = ((k / LINK_INERTIA).sqrt(), 2.0_f64);
    let root = (zeta * zeta - 1.0).sqrt();
    let want = [omega * (-zeta + root), omega * (-zeta - root)];
    assert_eq!(m.overdamped.len(), 2);
    for (got, want) in m.overdamped.iter().zip(want) {
        assert!(rel(*got, want) < 1e-10, "{got} vs {want}");
    }
}

fn ws_for(arm: &FlexibleArm) -> orbitflex::ArmWorkspace {
    arm.workspace()
}

/// A random state at rest (`V_B = 0` and `θ̇ = 0`, so every model exists there), with moving
/// links and deflected springs: the held base's geometric terms are then non-zero.
fn state(arm: &FlexibleArm, seed: u64, at_rest: bool) -> Vec<f64> {
    let n = arm.dof();
    let mut rng = Rng::new(seed);
    let q = rng.vector(n, -1.0, 1.0);
    let theta: Vec<f64> = q
        .iter()
        .map(|v| v + if at_rest { 0.0 } else { rng.range(-0.05, 0.05) })
        .collect();
    let qd = if at_rest {
        vec![0.0; n]
    } else {
        rng.vector(n, -0.5, 0.5)
    };
    let pose = [0.4, -0.3, 0.2, 0.2, -0.4, 0.3, 0.8];
    arm.state(&StateSpec {
        q: Some(&q),
        theta: Some(&theta),
        qd: Some(&qd),
        base_pose: Some(&pose),
        ..StateSpec::default()
    })
    .unwrap()
}

/// `[q̈; θ̈]` of the held base by the rigid algorithms directly (`M_r` from CRBA, the bias from
/// RNEA at `α_B = 0`): the reference the analytical held linearisation is differenced against.
fn held_acceleration(arm: &FlexibleArm, data: &mut Data, y: &[f64], f: &[f64]) -> Vec<f64> {
    let n = arm.dof();
    let (q, theta, qd, td) = (&y[..n], &y[n..2 * n], &y[2 * n..3 * n], &y[3 * n..]);
    let p = arm.joints();
    let tau: Vec<f64> = (0..n)
        .map(|i| p.stiffness[i] * (theta[i] - q[i]) + p.damping[i] * (td[i] - qd[i]))
        .collect();
    let mass = algorithms::crba(arm.robot(), data, q).unwrap().clone();
    let m_r = mass.view((6, 6), (n, n)).into_owned();
    let state = RigidState::new(q, &[0.0; 6], qd);
    let bias = algorithms::rnea(arm.robot(), data, &state, &[0.0; 6], &vec![0.0; n], f)
        .unwrap()
        .clone();
    let rhs = DVector::from_fn(n, |i, _| tau[i] - bias[6 + i]);
    let qdd = m_r.cholesky().unwrap().solve(&rhs);
    let mut out = qdd.as_slice().to_vec();
    for i in 0..n {
        out.push((-tau[i] - p.motor_damping[i] * td[i]) / p.motor_inertia[i]);
    }
    out
}

/// The held base's `A` and `B` (EE wrench) against central differences of the fixed-base
/// dynamics, at moving states with deflected springs, on a chain and a tree. The step 1e-6 gives
/// a truncation error of order h² ‖∂³f‖ ≈ 1e-12 and a rounding error of ε ‖f‖ / h ≈ 1e-10 of
/// the entries' scale, hence 1e-7 relative.
#[test]
fn held_base_linearisation_matches_finite_differences() {
    for (robot, seed) in [
        (random_chain(5, 11), 11),
        (random_tree_all_leaves(TREE_THREE_ARMS.0, 12), 12),
    ] {
        let n = robot.dof();
        let k = robot.end_effectors().len();
        let arm = FlexibleArm::new(robot, random_joints(n, seed)).unwrap();
        let x = state(&arm, seed, false);
        let spec = LinearSpec {
            base: BaseMode::Held,
            inputs: &[InputGroup::EeWrench, InputGroup::MotorTorque],
            ..LinearSpec::default()
        };
        let ss = state_space(&arm, &mut arm.workspace(), &x, &spec).unwrap();
        assert_eq!(ss.a.nrows(), 4 * n);
        let s = arm.layout().split(&x);
        let y0: Vec<f64> = [s.q, s.theta, s.qd, s.theta_dot].concat();
        let mut data = Data::new(arm.robot());
        let h = 1e-6;
        let mut fd = DMatrix::zeros(4 * n, 4 * n);
        for c in 0..4 * n {
            let (mut yp, mut ym) = (y0.clone(), y0.clone());
            yp[c] += h;
            ym[c] -= h;
            let (ap, am) = (
                held_acceleration(&arm, &mut data, &yp, &[]),
                held_acceleration(&arm, &mut data, &ym, &[]),
            );
            for r in 0..2 * n {
                fd[(2 * n + r, c)] = (ap[r] - am[r]) / (2.0 * h);
            }
            if c >= 2 * n {
                fd[(c - 2 * n, c)] = 1.0;
            }
        }
        let scale = fd.amax();
        assert!(
            (&ss.a - &fd).amax() < 1e-7 * scale,
            "{}",
            (&ss.a - &fd).amax() / scale
        );
        // the motor torque columns: θ̈_i = (u_i − …)/j_i
        for i in 0..n {
            for r in 0..4 * n {
                let want = if r == 3 * n + i {
                    1.0 / arm.joints().motor_inertia[i]
                } else {
                    0.0
                };
                assert_eq!(ss.b[(r, 6 * k + i)], want);
            }
        }
        // the EE wrench columns
        for c in 0..6 * k {
            let mut f = vec![0.0; 6 * k];
            f[c] = h;
            let ap = held_acceleration(&arm, &mut data, &y0, &f);
            f[c] = -h;
            let am = held_acceleration(&arm, &mut data, &y0, &f);
            for r in 0..n {
                let want = (ap[r] - am[r]) / (2.0 * h);
                assert!((ss.b[(2 * n + r, c)] - want).abs() < 1e-7 * scale.max(1.0));
            }
        }
    }
}

/// Every mode satisfies `A v = λ v` on the kept states, for the four base/motor combinations,
/// open and closed loop, on a chain and a tree; the rigid-body counts are exact and motor
/// friction does not change them.
#[test]
fn shapes_satisfy_the_eigen_equation_and_rigid_counts_are_exact() {
    for (robot, seed) in [
        (random_chain(6, 21), 21),
        (random_tree(TREE_THREE_ARMS, 22), 22),
    ] {
        let n = robot.dof();
        let joints = random_joints(n, seed); // damping and motor friction > 0
        assert!(joints.motor_damping.iter().all(|b| *b > 0.0));
        let arm = FlexibleArm::new(robot, joints).unwrap();
        let x = state(&arm, seed, true);
        let (kp, kd) = (vec![30.0; n], vec![2.0; n]);
        for (base, motors, want) in [
            (BaseMode::Free, Motors::Free, 6 + n),
            (BaseMode::Free, Motors::Clamped, 6),
            (BaseMode::Held, Motors::Free, n),
            (BaseMode::Held, Motors::Clamped, 0),
        ] {
            let loops: Vec<Feedback> = if motors == Motors::Free {
                vec![Feedback::None, Feedback::MotorPd { kp: &kp, kd: &kd }]
            } else {
                vec![Feedback::None]
            };
            for feedback in loops {
                let spec = LinearSpec {
                    base,
                    motors,
                    feedback,
                    ..LinearSpec::default()
                };
                let ss = state_space(&arm, &mut arm.workspace(), &x, &spec).unwrap();
                let m = modes(&arm, &mut arm.workspace(), &x, &spec, true).unwrap();
                let closed = feedback != Feedback::None;
                let rigid = if closed { want - n } else { want };
                assert_eq!(m.rigid_body, rigid, "{base:?} {motors:?} closed {closed}");
                let structural = if closed { 2 * n } else { n };
                assert_eq!(m.frequency_hz.len() + m.overdamped.len() / 2, structural);
                assert_eq!(m.eigenvalues.len(), ss.a.nrows());
                assert_eq!(m.shapes.nrows(), arm.tangent_size());
                assert_eq!(ss.states.len(), ss.a.nrows());
                let a = ss.a.map(|v| Complex::new(v, 0.0));
                for (j, f) in m.frequency_hz.iter().enumerate() {
                    let lambda = Complex::new(
                        -m.damping_ratio[j] * m.natural_frequency_hz[j] * TAU,
                        f * TAU,
                    );
                    let v =
                        DVector::from_fn(ss.a.nrows(), |r, _| m.shapes[(ss.tangent_index[r], j)]);
                    let residual = (&a * &v - &v * lambda).norm();
                    let scale = ss.a.norm() * v.norm();
                    assert!(residual < 1e-9 * scale, "mode {j}: {}", residual / scale);
                }
                // frequencies ascending
                assert!(m.frequency_hz.windows(2).all(|w| w[0] <= w[1]));
            }
        }
    }
}

/// Without damping, at rest with relaxed springs, the state matrix's modes are the undamped
/// pencil's: `λ = ±iω` to round-off, for every base/motor combination, open loop and under a
/// motor PD without derivative gain (its `k_p` stiffens the motors).
#[test]
fn damped_and_undamped_modes_agree_without_damping() {
    let robot = random_chain(5, 31);
    let n = robot.dof();
    let p = random_joints(n, 31);
    let joints =
        FlexibleJoints::new(p.stiffness, p.motor_inertia, vec![0.0; n], vec![0.0; n]).unwrap();
    let arm = FlexibleArm::new(robot, joints).unwrap();
    let x = state(&arm, 31, true);
    let (kp, kd) = (vec![40.0; n], vec![0.0; n]);
    let pd = Feedback::MotorPd { kp: &kp, kd: &kd };
    for (base, motors, feedback) in [
        (BaseMode::Free, Motors::Free, Feedback::None),
        (BaseMode::Free, Motors::Clamped, Feedback::None),
        (BaseMode::Held, Motors::Free, Feedback::None),
        (BaseMode::Held, Motors::Clamped, Feedback::None),
        (BaseMode::Free, Motors::Free, pd),
        (BaseMode::Held, Motors::Free, pd),
    ] {
        let spec = LinearSpec {
            base,
            motors,
            feedback,
            ..LinearSpec::default()
        };
        let damped = modes(&arm, &mut arm.workspace(), &x, &spec, true).unwrap();
        let undamped = modes(&arm, &mut arm.workspace(), &x, &spec, false).unwrap();
        assert_eq!(damped.rigid_body, undamped.rigid_body);
        assert_eq!(damped.frequency_hz.len(), undamped.frequency_hz.len());
        for (a, b) in damped.frequency_hz.iter().zip(&undamped.frequency_hz) {
            assert!(rel(*a, *b) < 1e-9, "{base:?} {motors:?}: {a} vs {b}");
        }
        assert!(damped.damping_ratio.iter().all(|z| z.abs() < 1e-9));
        assert_eq!(undamped.natural_frequency_hz, undamped.frequency_hz);
        // every eigenvalue, sorted by modulus, in conjugate pairs: ±iω and 2r zeros
        for m in [&damped, &undamped] {
            let e = &m.eigenvalues;
            assert_eq!(e.len(), 2 * (m.rigid_body + m.frequency_hz.len()));
            assert!(e.windows(2).all(|w| w[0].norm() <= w[1].norm()));
            for lambda in e {
                let tolerance = 1e-9 * lambda.norm();
                let paired = e.iter().any(|o| (o - lambda.conj()).norm() <= tolerance);
                assert!(paired, "{lambda} has no conjugate");
            }
        }
        let structural = undamped.eigenvalues.iter().skip(2 * undamped.rigid_body);
        for (f, lambda) in undamped.frequency_hz.iter().zip(structural.step_by(2)) {
            assert!(rel(lambda.norm() / TAU, *f) < 1e-12);
        }
        // the same shapes, up to a phase each (both have unit modal mass)
        for j in 0..damped.frequency_hz.len() {
            let (u, v) = (damped.shapes.column(j), undamped.shapes.column(j));
            let overlap = u.dotc(&v).norm() / (u.norm() * v.norm());
            assert!((overlap - 1.0).abs() < 1e-6, "mode {j}: overlap {overlap}");
        }
    }
}

/// `H(jω)` against `C (jωI − A)⁻¹ B + D` formed densely (a complex LU of the full matrix), free
/// and held, to 1e-9 of the response's scale.
#[test]
fn frequency_response_equals_the_dense_formula() {
    let robot = random_tree(TREE_THREE_ARMS, 41);
    let n = robot.dof();
    let arm = FlexibleArm::new(robot, random_joints(n, 41)).unwrap();
    let x = state(&arm, 41, true);
    for (base, inputs) in [
        (
            BaseMode::Free,
            vec![
                InputGroup::MotorTorque,
                InputGroup::BaseWrench,
                InputGroup::EeWrench,
            ],
        ),
        (
            BaseMode::Held,
            vec![InputGroup::MotorTorque, InputGroup::EeWrench],
        ),
    ] {
        let spec = LinearSpec {
            base,
            inputs: &inputs,
            outputs: &[
                OutputGroup::Q,
                OutputGroup::SpringTorque,
                OutputGroup::EePosition,
                OutputGroup::BaseAttitude,
            ],
            ..LinearSpec::default()
        };
        let ss = state_space(&arm, &mut arm.workspace(), &x, &spec).unwrap();
        let freqs = [0.01, 0.3, 1.7, 12.0, 95.0];
        let h = frequency_response(&ss, &freqs).unwrap();
        let size = ss.a.nrows();
        for (f, got) in freqs.iter().zip(&h) {
            let s = Complex::new(0.0, TAU * f);
            let m = DMatrix::from_fn(size, size, |r, c| {
                let diagonal = if r == c { s } else { Complex::new(0.0, 0.0) };
                diagonal - Complex::new(ss.a[(r, c)], 0.0)
            });
            let b = ss.b.map(|v| Complex::new(v, 0.0));
            let x = m.lu().solve(&b).unwrap();
            let want = ss.c.map(|v| Complex::new(v, 0.0)) * x + ss.d.map(|v| Complex::new(v, 0.0));
            let scale = want.iter().map(|v| v.norm()).fold(0.0, f64::max);
            let error = (got - &want).iter().map(|v| v.norm()).fold(0.0, f64::max);
            assert!(
                error < 1e-9 * scale,
                "{base:?} at {f} Hz: {}",
                error / scale
            );
        }
    }
    // a pole on the axis is an error naming the frequency: the free base at 0 Hz
    let spec = LinearSpec {
        inputs: &[InputGroup::MotorTorque],
        outputs: &[OutputGroup::Q],
        ..LinearSpec::default()
    };
    let ss = state_space(&arm, &mut arm.workspace(), &x, &spec).unwrap();
    let err = frequency_response(&ss, &[1.0, 0.0])
        .unwrap_err()
        .to_string();
    assert!(err.contains("element 1 (0 Hz) is a pole"), "{err}");
    assert!(frequency_response(&ss, &[-1.0]).is_err());
}

/// Stiffer springs raise every structural frequency; clamping the motors raises none above its
/// free value (Rayleigh: the clamped frequencies interlace below the free ones); a motor PD's
/// modes move as its gains do.
#[test]
fn modes_follow_the_physics() {
    let robot = Robot::space_arm();
    let n = robot.dof();
    let base = FlexibleJoints::space_arm();
    let stiffer = |factor: f64| {
        FlexibleJoints::new(
            base.stiffness.iter().map(|k| k * factor).collect(),
            base.motor_inertia.clone(),
            base.damping.clone(),
            base.motor_damping.clone(),
        )
        .unwrap()
    };
    let q = [0.3, -0.4, 0.2, 1.1, -0.3, 0.5, 0.1];
    let mut previous: Option<Vec<f64>> = None;
    for factor in [0.5, 1.0, 2.0, 4.0] {
        let arm = FlexibleArm::new(robot.clone(), stiffer(factor)).unwrap();
        let x = arm
            .state(&StateSpec {
                q: Some(&q),
                ..StateSpec::default()
            })
            .unwrap();
        let free = modes(
            &arm,
            &mut arm.workspace(),
            &x,
            &spec(BaseMode::Free, Motors::Free),
            false,
        )
        .unwrap();
        let clamped = modes(
            &arm,
            &mut arm.workspace(),
            &x,
            &spec(BaseMode::Free, Motors::Clamped),
            false,
        )
        .unwrap();
        for (c, f) in clamped.frequency_hz.iter().zip(&free.frequency_hz) {
            assert!(c <= &(f * (1.0 + 1e-12)), "clamped {c} above free {f}");
        }
        if let Some(prev) = &previous {
            for (now, before) in free.frequency_hz.iter().zip(prev) {
                assert!(now > before, "{now} not above {before}");
            }
        }
        previous = Some(free.frequency_hz.clone());
    }
    // closed loop: raising k_p raises the servo modes
    let arm = FlexibleArm::new(robot, base).unwrap();
    let x = arm.rest_state();
    let mut last = 0.0;
    for kp in [10.0, 40.0, 160.0] {
        let (kp, kd) = (vec![kp; n], vec![5.0; n]);
        let spec = LinearSpec {
            feedback: Feedback::MotorPd { kp: &kp, kd: &kd },
            ..LinearSpec::default()
        };
        let m = modes(&arm, &mut arm.workspace(), &x, &spec, true).unwrap();
        assert_eq!(m.rigid_body, 6);
        let lowest = m
            .natural_frequency_hz
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min);
        assert!(lowest > last, "{lowest} after {last}");
        last = lowest;
    }
}

/// The sweep gives, row by row, the modes computed one by one, whatever the thread count; a bad
/// row gives its own error.
#[test]
fn sweep_equals_the_single_calls() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let mut states = Vec::new();
    for e in 0..6 {
        let q = [0.0, 0.2, 0.0, 0.3 * e as f64, 0.0, 0.0, 0.0];
        states.extend(
            arm.state(&StateSpec {
                q: Some(&q),
                ..StateSpec::default()
            })
            .unwrap(),
        );
    }
    let spec = LinearSpec::default();
    let one = sweep(&arm, &states, &spec, true, Some(1)).unwrap();
    let two = sweep(&arm, &states, &spec, true, Some(2)).unwrap();
    for (i, (a, b)) in one.iter().zip(&two).enumerate() {
        let single = modes(
            &arm,
            &mut arm.workspace(),
            &states[i * 41..(i + 1) * 41],
            &spec,
            true,
        )
        .unwrap();
        assert_eq!(a.as_ref().unwrap(), &single);
        assert_eq!(b.as_ref().unwrap(), &single);
    }
    assert!(sweep(&arm, &states[..40], &spec, true, None).is_err());
    let mut bad = states.clone();
    bad[41 + 3] = f64::NAN;
    let rows = sweep(&arm, &bad, &spec, true, None).unwrap();
    assert!(rows[0].is_ok() && rows[1].is_err() && rows[2].is_ok());
}

/// Arguments that describe no model are refused with what is wrong.
#[test]
fn impossible_models_are_refused() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let mut ws = arm.workspace();
    let moving = arm
        .state(&StateSpec {
            base_twist: Some(&[0.0, 0.0, 0.1, 0.0, 0.0, 0.0]),
            ..StateSpec::default()
        })
        .unwrap();
    let err = modes(
        &arm,
        &mut ws,
        &moving,
        &spec(BaseMode::Held, Motors::Free),
        true,
    )
    .unwrap_err();
    assert!(err.to_string().contains("base twist"), "{err}");
    let spinning = arm
        .state(&StateSpec {
            theta_dot: Some(&[0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0]),
            ..StateSpec::default()
        })
        .unwrap();
    let err = modes(
        &arm,
        &mut ws,
        &spinning,
        &spec(BaseMode::Free, Motors::Clamped),
        true,
    )
    .unwrap_err();
    assert!(err.to_string().contains("theta_dot[3]"), "{err}");
    let x = arm.rest_state();
    for (spec, words) in [
        (
            LinearSpec {
                motors: Motors::Clamped,
                inputs: &[InputGroup::MotorTorque],
                ..LinearSpec::default()
            },
            "\"motor_torque\" drives the motors",
        ),
        (
            LinearSpec {
                base: BaseMode::Held,
                inputs: &[InputGroup::BaseWrench],
                ..LinearSpec::default()
            },
            "\"base_wrench\" drives a free base",
        ),
        (
            LinearSpec {
                inputs: &[InputGroup::ThetaRef],
                ..LinearSpec::default()
            },
            "give u=MotorPD",
        ),
        (
            LinearSpec {
                feedback: Feedback::Unknown,
                ..LinearSpec::default()
            },
            "not known",
        ),
    ] {
        let err = state_space(&arm, &mut ws, &x, &spec)
            .unwrap_err()
            .to_string();
        assert!(err.contains(words), "{err}");
    }
    assert!(InputGroup::from_name("torque")
        .unwrap_err()
        .to_string()
        .contains("motor_torque, theta_ref"));
    assert!(OutputGroup::from_name("qq").is_err());
    assert!(Motors::from_name("braked").is_err());
}

/// The shapes are normalised as documented: the displacement part `z` (in velocity coordinates:
/// `[δφ_B; R_Bᵀ δr_B; δq; δθ]`) has unit modal mass `zᴴ M z = 1` with `M = diag(𝓜, j)`, its
/// heaviest component (largest `M_ii |z_i|²`) is real and positive, and the rates are `λ z`.
#[test]
fn shapes_have_unit_modal_mass() {
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let n = arm.dof();
    let q = [0.3, -0.4, 0.2, 1.1, -0.3, 0.5, 0.1];
    let pose = [0.1, 0.2, 0.3, 0.2, -0.4, 0.3, 0.8];
    let x = arm
        .state(&StateSpec {
            q: Some(&q),
            base_pose: Some(&pose),
            ..StateSpec::default()
        })
        .unwrap();
    let mut data = Data::new(arm.robot());
    let rigid = algorithms::crba(arm.robot(), &mut data, &q)
        .unwrap()
        .clone();
    let mut mass = DMatrix::zeros(6 + 2 * n, 6 + 2 * n);
    mass.view_mut((0, 0), (6 + n, 6 + n)).copy_from(&rigid);
    for i in 0..n {
        mass[(6 + n + i, 6 + n + i)] = arm.joints().motor_inertia[i];
    }
    let r = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
        pose[6], pose[3], pose[4], pose[5],
    ))
    .to_rotation_matrix()
    .into_inner();
    for damped in [true, false] {
        let m = modes(
            &arm,
            &mut arm.workspace(),
            &x,
            &LinearSpec::default(),
            damped,
        )
        .unwrap();
        for j in 0..m.frequency_hz.len() {
            let v = m.shapes.column(j);
            let lin = r.transpose().map(|a| Complex::new(a, 0.0)) * v.fixed_rows::<3>(0);
            let z = DVector::from_fn(6 + 2 * n, |i, _| match i {
                0..=2 => v[3 + i],
                3..=5 => lin[i - 3],
                _ => v[i],
            });
            let mz = mass.map(|a| Complex::new(a, 0.0)) * &z;
            let modal_mass = z.dotc(&mz);
            assert!((modal_mass.re - 1.0).abs() < 1e-12 && modal_mass.im.abs() < 1e-12);
            let heaviest = (0..z.len())
                .max_by(|&a, &b| {
                    (mass[(a, a)] * z[a].norm_sqr()).total_cmp(&(mass[(b, b)] * z[b].norm_sqr()))
                })
                .unwrap();
            assert!(z[heaviest].re > 0.0 && z[heaviest].im.abs() < 1e-14 * z[heaviest].re);
            let lambda = Complex::new(
                -m.damping_ratio[j] * m.natural_frequency_hz[j] * TAU,
                m.frequency_hz[j] * TAU,
            );
            // rates: δq̇ = λ δq, δθ̇ = λ δθ
            for i in 0..2 * n {
                let (disp, rate) = (v[6 + i], v[12 + 2 * n + i]);
                assert!(
                    (rate - lambda * disp).norm() < 1e-9 * (lambda.norm() * disp.norm()).max(1e-12)
                );
            }
        }
    }
}

/// Every group and setting parses back from its name, and the names are the documented ones.
#[test]
fn names_round_trip() {
    for g in InputGroup::ALL {
        assert_eq!(InputGroup::from_name(g.name()).unwrap(), g);
    }
    for g in OutputGroup::ALL {
        assert_eq!(OutputGroup::from_name(g.name()).unwrap(), g);
    }
    for m in [Motors::Free, Motors::Clamped] {
        assert_eq!(Motors::from_name(m.name()).unwrap(), m);
    }
    let names: Vec<&str> = OutputGroup::ALL.iter().map(|g| g.name()).collect();
    assert_eq!(
        names,
        [
            "q",
            "theta",
            "deflection",
            "spring_torque",
            "ee_position",
            "base_attitude",
            "base_position",
            "base_rate",
            "wheel_speed"
        ]
    );
    let names: Vec<&str> = InputGroup::ALL.iter().map(|g| g.name()).collect();
    assert_eq!(
        names,
        [
            "motor_torque",
            "theta_ref",
            "base_wrench",
            "ee_wrench",
            "wheel_torque"
        ]
    );
    assert_eq!(
        (Motors::Free.name(), Motors::Clamped.name()),
        ("free", "clamped")
    );
}

/// The motor PD closed into `A`: the `θ̈` rows equal central differences of the derivative with
/// `u = k_p (θ_ref − θ) − k_d θ̇` evaluated at each perturbed state (along the tangent, with
/// `x ⊕ dx`), at a moving state, free base.
#[test]
fn closed_loop_rows_match_finite_differences() {
    let robot = random_chain(4, 51);
    let n = robot.dof();
    let arm = FlexibleArm::new(robot, random_joints(n, 51)).unwrap();
    let x = state(&arm, 51, false);
    let (kp, kd) = (vec![30.0, 45.0, 60.0, 75.0], vec![3.0, 1.0, 4.0, 1.5]);
    let reference = [0.1, -0.2, 0.3, 0.0];
    let spec = LinearSpec {
        feedback: Feedback::MotorPd { kp: &kp, kd: &kd },
        ..LinearSpec::default()
    };
    let ss = state_space(&arm, &mut arm.workspace(), &x, &spec).unwrap();
    // the reference as an input: ∂θ̈_i/∂θ_ref,i = k_p,i / j_i
    let with_reference = LinearSpec {
        inputs: &[InputGroup::ThetaRef, InputGroup::MotorTorque],
        ..spec
    };
    let b = state_space(&arm, &mut arm.workspace(), &x, &with_reference)
        .unwrap()
        .b;
    for i in 0..n {
        let j = arm.joints().motor_inertia[i];
        for r in 0..ss.a.nrows() {
            let at = r == 12 + 3 * n + i;
            let (reference, torque) = if at { (kp[i] / j, 1.0 / j) } else { (0.0, 0.0) };
            assert!((b[(r, i)] - reference).abs() <= 1e-15 * reference.abs());
            assert_eq!(b[(r, n + i)], torque);
        }
    }
    let layout = arm.layout();
    let mut ws = arm.workspace();
    let mut theta_ddot = |dx: &[f64]| {
        let y = arm.integrate(&x, dx).unwrap();
        let s = layout.split(&y);
        let u: Vec<f64> = (0..n)
            .map(|i| kp[i] * (reference[i] - s.theta[i]) - kd[i] * s.theta_dot[i])
            .collect();
        let mut ydot = vec![0.0; y.len()];
        arm.derivative(&mut ws, &y, &orbitflex::Inputs::torques(&u), &mut ydot)
            .unwrap();
        ydot[layout.theta_dot()].to_vec()
    };
    let t = arm.tangent_size();
    let h = 1e-6;
    for c in 0..t {
        let mut dx = vec![0.0; t];
        dx[c] = h;
        let plus = theta_ddot(&dx);
        dx[c] = -h;
        let minus = theta_ddot(&dx);
        for i in 0..n {
            let want = (plus[i] - minus[i]) / (2.0 * h);
            let got = ss.a[(12 + 3 * n + i, c)];
            assert!(
                (got - want).abs() < 1e-6 * want.abs().max(1.0),
                "row {i}, column {c}: {got} vs {want}"
            );
        }
    }
}

/// Every output row of `C` against central differences of the output's own definition along the
/// tangent (`x ⊕ dx`): angles, deflections, spring torques (rates included), the end-effectors'
/// inertial positions (`FlexibleArm::ee_pose`), the base's small rotation (the tangent's `δφ_B`,
/// `x ⊖ y`), position and rate, at a turned, moving base, on a tree with several end-effectors
/// (every group but `wheel_speed`, which needs wheels: `tests/wheel_linear.rs`).
#[test]
fn output_rows_match_finite_differences() {
    let robot = random_tree_all_leaves(TREE_THREE_ARMS.0, 61);
    let n = robot.dof();
    let k = robot.end_effectors().len();
    assert!(k > 1);
    let arm = FlexibleArm::new(robot, random_joints(n, 61)).unwrap();
    let x = state(&arm, 61, false);
    let groups: Vec<OutputGroup> = OutputGroup::ALL
        .into_iter()
        .filter(|g| *g != OutputGroup::WheelSpeed)
        .collect();
    let spec = LinearSpec {
        outputs: &groups,
        ..LinearSpec::default()
    };
    let ss = state_space(&arm, &mut arm.workspace(), &x, &spec).unwrap();
    assert_eq!(ss.c.nrows(), 4 * n + 3 * k + 9);
    let layout = arm.layout();
    let p = arm.joints().clone();
    let outputs = |dx: &[f64]| {
        let y = arm.integrate(&x, dx).unwrap();
        let s = layout.split(&y);
        let mut out: Vec<f64> = s.q.to_vec();
        out.extend_from_slice(s.theta);
        out.extend((0..n).map(|i| s.theta[i] - s.q[i]));
        out.extend((0..n).map(|i| {
            p.stiffness[i] * (s.theta[i] - s.q[i]) + p.damping[i] * (s.theta_dot[i] - s.qd[i])
        }));
        for e in 0..k {
            out.extend_from_slice(&arm.ee_pose(&y, e)[..3]);
        }
        out.extend_from_slice(&arm.difference(&x, &y).unwrap()[3..6]);
        out.extend_from_slice(s.position);
        out.extend_from_slice(&s.base_twist[..3]);
        out
    };
    let t = arm.tangent_size();
    let h = 1e-6;
    for c in 0..t {
        let mut dx = vec![0.0; t];
        dx[c] = h;
        let plus = outputs(&dx);
        dx[c] = -h;
        let minus = outputs(&dx);
        for (r, (a, b)) in plus.iter().zip(&minus).enumerate() {
            let want = (a - b) / (2.0 * h);
            let got = ss.c[(r, c)];
            assert!(
                (got - want).abs() < 1e-7 * want.abs().max(1.0),
                "{} / {}: {got} vs {want}",
                ss.outputs[r],
                ss.states[c]
            );
        }
    }
}
