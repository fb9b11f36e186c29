//! The linear model of an arm with reaction wheels: the Jacobians of `derivative` against
//! central differences (the reference), the wheel-torque inputs, the saturation's slope, and the
//! attitude loop's modes against closed forms and a simulation.

use nalgebra::DMatrix;
use orbitflex::flex::{ReactionWheels, Wheel};
use orbitflex::testing::{random_chain, random_joints, random_tree_all_leaves, Rng};
use orbitflex::{FlexibleArm, Inputs, Loads, Robot, StateSpec};

/// `k` random wheels ([`orbitflex::testing::random_wheels`]), torque limit 10.0 N·m.
fn random_wheels(k: usize, seed: u64) -> ReactionWheels {
    orbitflex::testing::random_wheels(k, seed, 10.0)
}

fn wheeled(robot: Robot, k: usize, seed: u64) -> FlexibleArm {
    let n = robot.dof();
    FlexibleArm::new(robot, random_joints(n, seed))
        .unwrap()
        .with_wheels(random_wheels(k, seed + 7))
        .unwrap()
}

/// A random state: angles ±1, small deflections, rates ±0.5, base twist ±0.3, wheel speeds
/// ±`speed`.
fn state(arm: &FlexibleArm, seed: u64, speed: f64) -> Vec<f64> {
    let n = arm.dof();
    let mut rng = Rng::new(seed + 3);
    let q = rng.vector(n, -1.0, 1.0);
    let theta: Vec<f64> = q.iter().map(|v| v + rng.range(-0.05, 0.05)).collect();
    let (qd, td, twist) = (
        rng.vector(n, -0.5, 0.5),
        rng.vector(n, -0.5, 0.5),
        rng.vector(6, -0.3, 0.3),
    );
    let pose = [0.4, -0.3, 0.2, 0.2, -0.4, 0.3, 0.8];
    let mut x = arm
        .state(&StateSpec {
            q: Some(&q),
            theta: Some(&theta),
            qd: Some(&qd),
            theta_dot: Some(&td),
            base_pose: Some(&pose),
            base_twist: Some(&twist),
        })
        .unwrap();
    let k = arm.layout().wheels;
    x[arm.layout().wheel_speed()].copy_from_slice(&rng.vector(k, -speed, speed));
    x
}

/// The dynamic part `ẋ[7..]` (every block after the pose: additive in the tangent, so its
/// derivative along `x ⊕ dx` is row `6 + i` of `F`).
fn rates(arm: &FlexibleArm, x: &[f64], inputs: &Inputs) -> Vec<f64> {
    let mut xdot = vec![0.0; x.len()];
    arm.derivative(&mut arm.workspace(), x, inputs, &mut xdot)
        .unwrap();
    xdot[7..].to_vec()
}

/// `F[6.., :]`, `G_u`, `G_W` of `derivative_jacobians` against central differences of
/// `derivative` with wheels, on chains and a tree, wheel axes off the base axes, friction, wheel
/// speeds up to 300 rad/s, the bus turning, and wheel torques applied.
///
/// Bound: central differences with step `h` err by `h²/6 |∂³ẋ|` (truncation) plus
/// `ε |ẋ| / h` (rounding). `ẋ` is at most quadratic in the rates (gyroscopic `ω × J_s Ω a`,
/// Coriolis), smooth in the angles with derivatives of the order of `|ẋ|` itself, so with
/// `h = 1e-5` (angles and rates of order 1; wheel speeds scaled by `h Ω_max`) the error is
/// `≲ 1e-10 |ẋ| + 2e-11 |ẋ|`; relative to the largest entry of the Jacobian (≥ 1 here, the
/// identity blocks), `1e-7` holds with three orders to spare for the spread of entries.
#[test]
fn wheel_jacobians_equal_central_differences() {
    let robots: Vec<(Robot, &str)> = vec![
        (random_chain(1, 4), "chain 1"),
        (random_chain(4, 5), "chain 4"),
        (
            random_tree_all_leaves(&[0, 0, 1, 2, 1, 4, 0, 6], 6),
            "tree 7",
        ),
    ];
    for (seed, (robot, label)) in robots.into_iter().enumerate() {
        let seed = seed as u64 + 1;
        let k = [1, 3, 4][seed as usize - 1];
        let arm = wheeled(robot, k, seed);
        let n = arm.dof();
        let x = state(&arm, seed, 300.0);
        let mut rng = Rng::new(seed + 40);
        let u = rng.vector(n, -2.0, 2.0);
        let (fb, wheel_torque) = (rng.vector(6, -2.0, 2.0), rng.vector(k, -0.5, 0.5));
        let inputs = Inputs {
            u: &u,
            loads: Loads::from_slices(Some(&fb), None).unwrap(),
            wheel_torque: &wheel_torque,
        };
        let j = arm
            .derivative_jacobians(&mut arm.workspace(), &x, &inputs)
            .unwrap();
        let t = arm.tangent_size();
        assert_eq!(t, 12 + 4 * n + k);
        assert_eq!(j.wheel_torque.shape(), (t, k));
        let h = 1e-5;
        let rows = t - 6;
        let mut fd = DMatrix::zeros(rows, t);
        for c in 0..t {
            let mut dx = vec![0.0; t];
            // wheel speeds are hundreds of rad/s: a relative step
            dx[c] = if c >= 12 + 4 * n { h * 300.0 } else { h };
            let plus = rates(&arm, &arm.integrate(&x, &dx).unwrap(), &inputs);
            let step = dx[c];
            dx[c] = -step;
            let minus = rates(&arm, &arm.integrate(&x, &dx).unwrap(), &inputs);
            for r in 0..rows {
                fd[(r, c)] = (plus[r] - minus[r]) / (2.0 * step);
            }
        }
        let got = j.x.rows(6, rows).into_owned();
        let err = (&got - &fd).amax() / fd.amax().max(1.0);
        assert!(err < 1e-7, "{label}: F {err:e}");
        // the wheel torque columns: exact in the torque (linear within the limits)
        let mut fd_w = DMatrix::zeros(rows, k);
        for c in 0..k {
            let mut w = wheel_torque.clone();
            w[c] += 1e-3;
            let plus = rates(
                &arm,
                &x,
                &Inputs {
                    wheel_torque: &w,
                    ..inputs
                },
            );
            w[c] -= 2e-3;
            let minus = rates(
                &arm,
                &x,
                &Inputs {
                    wheel_torque: &w,
                    ..inputs
                },
            );
            for r in 0..rows {
                fd_w[(r, c)] = (plus[r] - minus[r]) / 2e-3;
            }
        }
        let got_w = j.wheel_torque.rows(6, rows).into_owned();
        let err = (&got_w - &fd_w).amax() / fd_w.amax();
        assert!(err < 1e-9, "{label}: G_W {err:e}");
        // and of the motor torques (they reach the wheels only through nothing: θ̈ rows)
        assert_eq!(j.u.rows(12 + 4 * n, k).amax(), 0.0);
    }
}

/// A command beyond `max_torque`, or one that would speed up a wheel at `max_speed`, is cut:
/// its column of `G_W` is zero; a command that slows the wheel down passes (slope 1).
#[test]
fn saturated_wheels_have_no_torque_slope() {
    let arm = wheeled(random_chain(2, 9), 2, 9);
    let mut x = state(&arm, 9, 10.0);
    let speed = arm.layout().wheel_speed();
    x[speed.start] = 1e4; // wheel 0 at max_speed
    x[speed.start + 1] = 5.0;
    let u = vec![0.0; 2];
    for (command, zero) in [([0.1, 20.0], [true, true]), ([-0.1, 1.0], [false, false])] {
        let inputs = Inputs {
            wheel_torque: &command,
            ..Inputs::torques(&u)
        };
        let j = arm
            .derivative_jacobians(&mut arm.workspace(), &x, &inputs)
            .unwrap();
        for (w, zero) in zero.into_iter().enumerate() {
            assert_eq!(j.wheel_torque.column(w).amax() == 0.0, zero, "{command:?}");
        }
    }
}

use orbitflex::analysis::{modes, state_space, InputGroup, LinearSpec, Motors, OutputGroup};
use orbitflex::control::{AttitudePD, AttitudeTarget, Controller};
use orbitflex::integrate::Feedback;
use orbitflex::planning::BaseMode;
use orbitflex::FlexibleJoints;

/// Frictionless joints and wheels: every rigid-body and spin eigenvalue is exactly zero.
fn frictionless(robot: Robot, k: usize, seed: u64, stiffness: f64) -> FlexibleArm {
    let n = robot.dof();
    let wheels: Vec<Wheel> = random_wheels(k, seed)
        .wheels()
        .iter()
        .map(|w| Wheel {
            friction: 0.0,
            ..*w
        })
        .collect();
    FlexibleArm::new(
        robot,
        FlexibleJoints::uniform(n, stiffness, 0.4, 0.0, 0.0).unwrap(),
    )
    .unwrap()
    .with_wheels(ReactionWheels::new(wheels).unwrap())
    .unwrap()
}

/// The free linear model with wheels has `2 r + k` zero eigenvalues: two per rigid-body mode
/// (`r = 6 + n` free base and motors, 6 clamped, `n` held base with free motors, 0 held and
/// clamped) and one per wheel (its speed has no angle in the state: `δΩ = e_w` with the arm at
/// rest is an equilibrium); the other `2n` are the springs' `±iω`. `modes` separates exactly
/// those out.
///
/// "Zero" is decided against the smallest structural `|λ|`: the rigid-body zeros sit in 2×2
/// Jordan blocks, which round-off splits by `O(√(ε ‖A‖))` ≈ 1e-6 here, far below the springs'
/// `|λ| ≳ 10` rad/s; the threshold 1e-3 of the latter separates them with margins of 1e4 and
/// 1e3.
#[test]
fn free_model_with_wheels_has_rigid_body_and_wheel_spin_zeros() {
    for (robot, k, seed) in [(random_chain(3, 21), 3, 21), (random_chain(5, 22), 4, 22)] {
        let n = robot.dof();
        let arm = frictionless(robot, k, seed, 500.0);
        let x = arm.rest_state();
        for (base, motors, r) in [
            (BaseMode::Free, Motors::Free, 6 + n),
            (BaseMode::Free, Motors::Clamped, 6),
            (BaseMode::Held, Motors::Free, n),
            (BaseMode::Held, Motors::Clamped, 0),
        ] {
            let spec = LinearSpec {
                base,
                motors,
                ..LinearSpec::default()
            };
            for damped in [true, false] {
                let m = modes(&arm, &mut arm.workspace(), &x, &spec, damped).unwrap();
                assert_eq!(
                    (m.rigid_body, m.wheel_spin, m.frequency_hz.len()),
                    (r, k, n),
                    "{base:?} {motors:?} damped {damped}"
                );
                let smallest = m.natural_frequency_hz[0] * std::f64::consts::TAU;
                let zeros = m
                    .eigenvalues
                    .iter()
                    .filter(|l| l.norm() < 1e-3 * smallest)
                    .count();
                assert_eq!(zeros, 2 * r + k, "{base:?} {motors:?} damped {damped}");
                assert!(m.overdamped.is_empty());
            }
            let ss = state_space(&arm, &mut arm.workspace(), &x, &spec).unwrap();
            let kept = 4 * n + 12 + k
                - if base == BaseMode::Held { 12 } else { 0 }
                - if motors == Motors::Clamped { 2 * n } else { 0 };
            assert_eq!(ss.a.nrows(), kept);
            assert_eq!(
                ss.states.last().unwrap(),
                &format!("wheel_speed[{}]", k - 1)
            );
        }
    }
}

/// A rigid bus held by an `AttitudePD` through its wheels. With the arm locked (brakes on,
/// stiff springs) the whole craft turns as one body about its centre of mass (the PD's
/// torque is a pure moment, and the linear momentum stays zero), so about `x`
///
/// ```text
/// I_c φ̈ = T = −k_p φ − k_d φ̇,   I_c = M_ωω − M_ωv M_vv⁻¹ M_vω
/// ```
/// with `M` the 6×6 base block of the locked craft's mass matrix (the wheels' masses and
/// transverse inertias included, their spin inertias not: a wheel's spin is driven by its
/// motor, not by the bus's rotation, (W1)); `I_c` is the rotational inertia about the centre
/// of mass. With equal gains on the three axes, along each principal axis of `I_c` (inertia
/// `I_i`) the loop is `I_i s² + k_d s + k_p = 0`:
///
/// ```text
/// ω_n = √(k_p / I_i),   ζ = k_d / (2 √(k_p I_i)).
/// ```
///
/// Bound. The springs (stiffness `k`, lowest structural frequency `ω_s` of the model) make
/// the arm only nearly locked: by static condensation the attitude mode's `ω_n²` moves by a
/// fraction at most `(ω_n/ω_s)²` (the share of the craft's inertia behind the springs is below
/// 1), and `ζ` with it. Round-off in the eigenvalues of `A` is `≲ ε ‖A‖ ≈ ε ω_s²`, relative
/// `ε ω_s² / ω_n`, and we allow a conditioning factor 100 on it. Here `ω_n ≈ 0.3–1` rad/s and
/// `ω_s ≈ 2000` rad/s: the bound is about 1e-7.
#[test]
fn attitude_loop_on_a_locked_craft_matches_its_closed_form() {
    let robot = random_chain(3, 31);
    let n = robot.dof();
    let arm = frictionless(robot, 3, 31, 4e6);
    let mut q = vec![0.4, -0.7, 1.1];
    q.truncate(n);
    let x = arm
        .state(&StateSpec {
            q: Some(&q),
            ..StateSpec::default()
        })
        .unwrap();
    let (kp, kd) = (2.0, 0.8);
    let wheels = arm.wheels().unwrap();
    let pd = AttitudePD::new(
        [kp; 3],
        [kd; 3],
        AttitudeTarget::Initial,
        wheels.allocation().unwrap(),
    )
    .unwrap();
    let spec = LinearSpec {
        motors: Motors::Clamped,
        attitude: Some(&pd),
        ..LinearSpec::default()
    };
    let mut data = orbitflex::algorithms::Data::new(arm.rigid_model());
    let mass = orbitflex::algorithms::crba(arm.rigid_model(), &mut data, &q)
        .unwrap()
        .clone();
    let m_ww = mass.view((0, 0), (3, 3)).into_owned();
    let m_wv = mass.view((0, 3), (3, 3)).into_owned();
    let m_vv = mass.view((3, 3), (3, 3)).into_owned();
    let i_c = &m_ww - &m_wv * m_vv.try_inverse().unwrap() * m_wv.transpose();
    let mut principal: Vec<f64> = i_c.symmetric_eigenvalues().iter().copied().collect();
    principal.sort_by(|a, b| b.total_cmp(a)); // largest inertia: lowest frequency first
    let m = modes(&arm, &mut arm.workspace(), &x, &spec, true).unwrap();
    // 3 translations stay rigid; the rotations are held; the wheels spin free
    assert_eq!((m.rigid_body, m.wheel_spin), (3, 3));
    assert_eq!(m.frequency_hz.len(), 3 + n);
    let omega_s = m.natural_frequency_hz[3] * std::f64::consts::TAU;
    for (i, inertia) in principal.iter().enumerate() {
        let omega_n = (kp / inertia).sqrt();
        let zeta = kd / (2.0 * (kp * inertia).sqrt());
        let bound = (omega_n / omega_s).powi(2) + 100.0 * f64::EPSILON * omega_s.powi(2) / omega_n;
        assert!(bound < 1e-6, "the test's bound is {bound:e}");
        let got = m.natural_frequency_hz[i] * std::f64::consts::TAU;
        assert!(
            (got - omega_n).abs() / omega_n < bound,
            "axis {i}: ω_n {got} vs {omega_n} (bound {bound:e})"
        );
        assert!(
            (m.damping_ratio[i] - zeta).abs() / zeta < bound,
            "axis {i}: ζ {} vs {zeta}",
            m.damping_ratio[i]
        );
    }
    // the undamped pencil: the same ω_n from (K, M) with K = k_p on the rotations
    let undamped = modes(&arm, &mut arm.workspace(), &x, &spec, false).unwrap();
    for (i, inertia) in principal.iter().enumerate() {
        let omega_n = (kp / inertia).sqrt();
        let got = undamped.natural_frequency_hz[i] * std::f64::consts::TAU;
        assert!((got - omega_n).abs() / omega_n < 1e-6, "undamped axis {i}");
    }
}

/// The closed loop's `A` (a motor PD and an attitude PD, the latter holding a constant attitude
/// away from the state's, so that `δe = (w_e 𝟙 + [v_e]×) δφ` is exercised and the wheels carry
/// a torque at the operating point) against central differences of the closed-loop derivative
/// `ẋ(y) = f(y, u = PD(y), u_W = AttitudePD(y))` along `y = x ⊕ dx`, on a moving state with
/// spinning wheels. Bound as in `wheel_jacobians_equal_central_differences` (the controllers
/// are smooth and of order 1 in the state).
#[test]
fn closed_loop_matrix_equals_central_differences() {
    let arm = wheeled(random_chain(3, 41), 4, 41);
    let n = arm.dof();
    let x = state(&arm, 41, 200.0);
    let target = [0.25, -0.35, 0.3, 0.85];
    let wheels = arm.wheels().unwrap();
    let pd = AttitudePD::new(
        [3.0, 2.0, 4.0],
        [5.0, 6.0, 4.5],
        AttitudeTarget::Constant(target),
        wheels.allocation().unwrap(),
    )
    .unwrap();
    let (kp, kd) = (vec![40.0, 30.0, 20.0], vec![6.0, 5.0, 4.0]);
    let spec = LinearSpec {
        feedback: Feedback::MotorPd { kp: &kp, kd: &kd },
        attitude: Some(&pd),
        inputs: &[InputGroup::WheelTorque],
        outputs: &[OutputGroup::WheelSpeed, OutputGroup::BaseRate],
        ..LinearSpec::default()
    };
    let ss = state_space(&arm, &mut arm.workspace(), &x, &spec).unwrap();
    let t = arm.tangent_size();
    assert_eq!(ss.a.nrows(), t);
    let theta_ref = x[arm.layout().theta()].to_vec();
    let closed = |y: &[f64]| {
        let s = arm.layout().split(y);
        let u: Vec<f64> = (0..n)
            .map(|i| kp[i] * (theta_ref[i] - s.theta[i]) - kd[i] * s.theta_dot[i])
            .collect();
        let mut w = vec![0.0; 4];
        pd.clone().output(0, 0.0, y, &mut w).unwrap();
        assert!(w.iter().all(|v| v.abs() < 10.0), "within the torque limit");
        rates(
            &arm,
            y,
            &Inputs {
                wheel_torque: &w,
                ..Inputs::torques(&u)
            },
        )
    };
    let h = 1e-5;
    let mut fd = DMatrix::zeros(t - 6, t);
    for c in 0..t {
        let mut dx = vec![0.0; t];
        dx[c] = if c >= 12 + 4 * n { h * 200.0 } else { h };
        let step = dx[c];
        let plus = closed(&arm.integrate(&x, &dx).unwrap());
        dx[c] = -step;
        let minus = closed(&arm.integrate(&x, &dx).unwrap());
        for r in 0..t - 6 {
            fd[(r, c)] = (plus[r] - minus[r]) / (2.0 * step);
        }
    }
    let got = ss.a.rows(6, t - 6).into_owned();
    let err = (&got - &fd).amax() / fd.amax().max(1.0);
    assert!(err < 1e-7, "closed-loop A {err:e}");
    // B's wheel columns are the open derivative's G_W; C picks Ω and ω_B
    let j = arm
        .derivative_jacobians(&mut arm.workspace(), &x, &Inputs::torques(&[0.0; 3]))
        .unwrap();
    assert_eq!(
        ss.inputs,
        [
            "wheel_torque[0]",
            "wheel_torque[1]",
            "wheel_torque[2]",
            "wheel_torque[3]"
        ]
    );
    assert_eq!(ss.outputs[4], "base_rate_x");
    assert_eq!(ss.c[(0, 12 + 4 * n)], 1.0);
    assert_eq!(ss.c[(4, 6 + 2 * n)], 1.0);
    // the wheel rows of G_W depend on the configuration alone (through 𝓜⁻¹), not on the
    // operating torques, which differ between the two
    for w in 0..4 {
        let row = 12 + 4 * n + w;
        assert!(
            (ss.b[(row, w)] - j.wheel_torque[(row, w)]).abs()
                < 1e-12 * j.wheel_torque[(row, w)].abs().max(1.0)
        );
    }
}

use orbitflex::analysis::{sampled_loop, SampledFeedback};
use orbitflex::UrdfOptions;

/// A 200 kg bus with one feather-light link (1e-9 kg, 1e-12 kg·m²) on a unit spring: the
/// craft is the bus and its wheels to within 1e-11 of its inertia.
const FEATHER: &str = r#"<robot name="feather">
  <link name="bus"><inertial><mass value="200"/>
    <inertia ixx="60" iyy="80" izz="100" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j" type="continuous"><parent link="bus"/><child link="feather"/>
    <origin xyz="0 0 0"/><axis xyz="0 0 1"/></joint>
  <link name="feather"><inertial><mass value="1e-9"/>
    <inertia ixx="1e-12" iyy="1e-12" izz="1e-12" ixy="0" ixz="0" iyz="0"/></inertial></link>
</robot>"#;

/// Three wheels along the bus axes, centred at its origin.
fn axis_wheels() -> ReactionWheels {
    let wheel = |axis| Wheel {
        axis,
        position: [0.0; 3],
        mass: 4.0,
        spin_inertia: 0.05,
        transverse_inertia: 0.03,
        max_torque: 100.0,
        max_speed: 1e4,
        friction: 0.0,
    };
    ReactionWheels::new(vec![
        wheel([1.0, 0.0, 0.0]),
        wheel([0.0, 1.0, 0.0]),
        wheel([0.0, 0.0, 1.0]),
    ])
    .unwrap()
}

/// An attitude PD sampled every `T` seconds on a rigid craft: per principal axis (inertia `I`)
/// the plant `I φ̈ = c` held over a period is `Φ = [[1, T], [0, 1]]`, `Γ = [T²/2I; T/I]`, and
/// `c = −k_p φ_j − k_d ω_j` closes it with the characteristic polynomial
///
/// ```text
/// z² − (2 − k_p T²/2I − k_d T/I) z + (1 − k_d T/I + k_p T²/2I) = 0
/// ```
/// whose roots lie inside the unit circle iff `k_p T/2 < k_d` and `k_d T < 2I` (Jury). The
/// other eigenvalues of the loop are the uncontrolled translations and wheel spins (1) and the
/// feather's spring (`e^{±iωT}`, modulus 1 without damping), so `ρ` is the larger of 1 and the
/// roots' moduli.
///
/// Bound: the feather moves the craft's inertia by 1e-11 relative; `exp` of the augmented
/// matrix (scaling and squaring, `‖A T‖ ≲ 1e6 T` for the feather's spring) is accurate to
/// `≲ 1e-16 · 2^s` with `s ≈ 20` squarings, ≈ 1e-10; the roots of a well-separated quadratic
/// move as much. 1e-8 leaves a margin of 100.
#[test]
fn sampled_attitude_loop_matches_the_discrete_closed_form() {
    let robot = Robot::from_urdf_string(FEATHER, &UrdfOptions::default()).unwrap();
    let arm = FlexibleArm::new(
        robot,
        FlexibleJoints::uniform(1, 1.0, 1.0, 0.0, 0.0).unwrap(),
    )
    .unwrap()
    .with_wheels(axis_wheels())
    .unwrap();
    let x = arm.rest_state();
    let (kp, kd) = (40.0, 20.0);
    let pd = AttitudePD::new(
        [kp; 3],
        [kd; 3],
        AttitudeTarget::Initial,
        arm.wheels().unwrap().allocation().unwrap(),
    )
    .unwrap();
    let plant = LinearSpec {
        motors: Motors::Clamped,
        ..LinearSpec::default()
    };
    // the craft's inertia about its centre (the bus's, plus the wheels' masses at the origin
    // and transverse inertias: 60 + 2·0.03, …)
    let inertia = [60.06, 80.06, 100.06];
    let critical = 2.0 * kd / kp; // k_p T/2 < k_d: T < 1 s
    for period in [0.05, 0.5, 0.99 * critical, 1.01 * critical, 1.5] {
        let l = sampled_loop(
            &arm,
            &mut arm.workspace(),
            &x,
            &plant,
            SampledFeedback::Attitude(&pd),
            1.0 / period,
            0,
        )
        .unwrap();
        let mut rho: f64 = 1.0;
        for i in inertia {
            let tr = 2.0 - kp * period * period / (2.0 * i) - kd * period / i;
            let det = 1.0 - kd * period / i + kp * period * period / (2.0 * i);
            let disc = Complex::new(tr * tr - 4.0 * det, 0.0).sqrt();
            for root in [(tr + disc) / 2.0, (tr - disc) / 2.0] {
                let nearest = l
                    .eigenvalues
                    .iter()
                    .map(|z| (z - root).norm())
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    nearest < 1e-8,
                    "T {period}: root {root} missing ({nearest:e})"
                );
                rho = rho.max(root.norm());
            }
        }
        assert!(
            (l.spectral_radius - rho).abs() < 1e-8,
            "T {period}: ρ {} vs {rho}",
            l.spectral_radius
        );
        assert_eq!(l.unstable(), period > critical, "T {period}");
    }
}
use nalgebra::Complex;

/// The roots of `Σ c[i] zⁱ` (`c` from the constant term up, leading coefficient 1), as the
/// eigenvalues of its companion matrix.
fn roots(c: &[f64]) -> Vec<Complex<f64>> {
    let deg = c.len() - 1;
    let companion = DMatrix::from_fn(deg, deg, |r, col| {
        if r == 0 {
            -c[deg - 1 - col]
        } else if col + 1 == r {
            1.0
        } else {
            0.0
        }
    });
    orbitflex::linalg::eigenvalues(&companion).unwrap()
}

/// The distance from `z` to the nearest of `values`.
fn nearest(values: &[Complex<f64>], z: Complex<f64>) -> f64 {
    values
        .iter()
        .map(|v| (v - z).norm())
        .fold(f64::INFINITY, f64::min)
}

/// The attitude loop of `sampled_attitude_loop_matches_the_discrete_closed_form` with a delay of
/// `d` samples: the command held over period `j` is `c_{j−d}`, so per axis
/// `z^d (z𝟙 − Φ) dx = Γ K dx`, whose roots are those of
///
/// ```text
/// z^d (z − 1)² + α z + β,   α = k_p T²/2I + k_d T/I,   β = k_p T²/2I − k_d T/I
/// ```
/// (`d = 0` gives the quadratic of that test). The loop carries the `3d` wheel commands in
/// flight as states, so it has `3d` more eigenvalues than the undelayed one; the others stay
/// at 1 and `e^{±iωT}` as there. The same bound (1e-8) holds: the roots are simple and apart
/// by more than 1e-2.
#[test]
fn sampled_attitude_loop_with_a_delay_matches_the_closed_form() {
    let robot = Robot::from_urdf_string(FEATHER, &UrdfOptions::default()).unwrap();
    let arm = FlexibleArm::new(
        robot,
        FlexibleJoints::uniform(1, 1.0, 1.0, 0.0, 0.0).unwrap(),
    )
    .unwrap()
    .with_wheels(axis_wheels())
    .unwrap();
    let x = arm.rest_state();
    let (kp, kd) = (40.0, 20.0);
    let pd = AttitudePD::new(
        [kp; 3],
        [kd; 3],
        AttitudeTarget::Initial,
        arm.wheels().unwrap().allocation().unwrap(),
    )
    .unwrap();
    let plant = LinearSpec {
        motors: Motors::Clamped,
        ..LinearSpec::default()
    };
    let inertia = [60.06, 80.06, 100.06];
    let sampled = |rate: f64, delay: usize| {
        sampled_loop(
            &arm,
            &mut arm.workspace(),
            &x,
            &plant,
            SampledFeedback::Attitude(&pd),
            rate,
            delay,
        )
        .unwrap()
    };
    let states = sampled(10.0, 0).eigenvalues.len();
    let mut verdicts = Vec::new();
    for delay in 1..=3 {
        for period in [0.05, 0.2, 0.5] {
            let l = sampled(1.0 / period, delay);
            assert_eq!(l.eigenvalues.len(), states + 3 * delay);
            assert_eq!((l.delay, l.period), (delay, 1.0 / (1.0 / period)));
            let mut rho: f64 = 1.0;
            for i in inertia {
                let alpha = kp * period * period / (2.0 * i) + kd * period / i;
                let beta = kp * period * period / (2.0 * i) - kd * period / i;
                // z^d (z² − 2z + 1) + α z + β, from the constant term up
                let mut c = vec![0.0; delay + 3];
                c[delay] += 1.0;
                c[delay + 1] -= 2.0;
                c[delay + 2] += 1.0;
                c[1] += alpha;
                c[0] += beta;
                for root in roots(&c) {
                    let gap = nearest(&l.eigenvalues, root);
                    assert!(
                        gap < 1e-8,
                        "d {delay} T {period}: root {root} missing ({gap:e})"
                    );
                    rho = rho.max(root.norm());
                }
            }
            assert!(
                (l.spectral_radius - rho).abs() < 1e-8,
                "d {delay} T {period}: ρ {} vs {rho}",
                l.spectral_radius
            );
            // no root within 1e-4 of the unit circle: the verdict is not a matter of rounding
            assert!(
                rho == 1.0 || rho > 1.0 + 1e-4,
                "d {delay} T {period}: ρ {rho}"
            );
            assert_eq!(l.unstable(), rho > 1.0, "d {delay} T {period}: ρ {rho}");
            verdicts.push(l.unstable());
        }
    }
    // the delays make the slower loops unstable: both verdicts occur
    assert!(
        verdicts.contains(&true) && verdicts.contains(&false),
        "{verdicts:?}"
    );
}

/// Two joints on a held bus, each carrying a rod whose centre of mass is on its axis (`I_i` =
/// 0.5 and 0.8 kg·m² about it), on two branches, so that the held bus decouples them; motor
/// inertia `j`, spring `k`, joint damping `d`, motor damping `β`. Over
/// `[q₁, q₂, θ₁, θ₂, q̇₁, q̇₂, θ̇₁, θ̇₂]` the plant is, per joint,
///
/// ```text
/// I_i q̈_i = k (θ_i − q_i) + d (θ̇_i − q̇_i),   j θ̈_i = u_i − k (θ_i − q_i) − d (θ̇_i − q̇_i) − β θ̇_i
/// ```
/// and a motor PD sampled every `T` feeds back `u_i = −k_p,i θ_i − k_d,i θ̇_i` (gains differing
/// per joint, so a gain on the wrong joint shows). The loop built here from these closed forms
/// (`Φ`, `Γ` from the exponential of `[[A, B], [0, 0]] T`, the delay line of `d` commands written
/// out) has the eigenvalues `sampled_loop` finds, and its threshold is `e^{1.1 T g}(1 + 10⁻⁶)`
/// with `g ≥ 0` the growth of the continuous loop `A + B K`. Bound: `‖A T‖ ≤ 3` and the
/// eigenvalues are simple, so both sides are accurate to ~1e-13; 1e-10 leaves a margin.
#[test]
fn sampled_motor_pd_loop_matches_the_two_joint_closed_form() {
    const RODS: &str = r#"<robot name="rods">
      <link name="bus"><inertial><mass value="100"/>
        <inertia ixx="10" iyy="10" izz="10" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <joint name="j1" type="continuous"><parent link="bus"/><child link="rod1"/>
        <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/></joint>
      <link name="rod1"><inertial><origin xyz="0 0 0.2"/><mass value="2"/>
        <inertia ixx="0.7" iyy="0.6" izz="0.5" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <joint name="j2" type="continuous"><parent link="bus"/><child link="rod2"/>
        <origin xyz="-0.3 0 0"/><axis xyz="0 0 1"/></joint>
      <link name="rod2"><inertial><origin xyz="0 0 -0.1"/><mass value="3"/>
        <inertia ixx="0.9" iyy="0.9" izz="0.8" ixy="0" ixz="0" iyz="0"/></inertial></link>
    </robot>"#;
    let (inertia, k, j, d, beta) = ([0.5, 0.8], 50.0, 0.1, 0.2, 0.05);
    let robot = Robot::from_urdf_string(RODS, &UrdfOptions::default()).unwrap();
    let arm = FlexibleArm::new(robot, FlexibleJoints::uniform(2, k, j, d, beta).unwrap()).unwrap();
    let x = arm.rest_state();
    let plant = LinearSpec {
        base: BaseMode::Held,
        ..LinearSpec::default()
    };
    let (mut a, mut b) = (DMatrix::zeros(8, 8), DMatrix::zeros(8, 2));
    for i in 0..2 {
        let (q, theta, qd, td) = (i, 2 + i, 4 + i, 6 + i);
        a[(q, qd)] = 1.0;
        a[(theta, td)] = 1.0;
        a[(qd, q)] = -k / inertia[i];
        a[(qd, theta)] = k / inertia[i];
        a[(qd, qd)] = -d / inertia[i];
        a[(qd, td)] = d / inertia[i];
        a[(td, q)] = k / j;
        a[(td, theta)] = -k / j;
        a[(td, qd)] = d / j;
        a[(td, td)] = -(d + beta) / j;
        b[(td, i)] = 1.0 / j;
    }
    // the last gains pump energy into the motors (k_d + β < 0): the continuous loop grows
    for (rate, delay, kd) in [
        (200.0, 0, [0.6, 0.4]),
        (50.0, 0, [0.6, 0.4]),
        (50.0, 1, [0.6, 0.4]),
        (20.0, 2, [0.6, 0.4]),
        (100.0, 0, [-0.3, 0.4]),
    ] {
        let kp = [8.0, 5.0];
        let feedback = SampledFeedback::MotorPd { kp: &kp, kd: &kd };
        assert_eq!(feedback.name(), "MotorPD");
        let mut gain = DMatrix::zeros(2, 8);
        for i in 0..2 {
            gain[(i, 2 + i)] = -kp[i];
            gain[(i, 6 + i)] = -kd[i];
        }
        let period = 1.0 / rate;
        let mut augmented = DMatrix::zeros(10, 10);
        augmented.view_mut((0, 0), (8, 8)).copy_from(&(&a * period));
        augmented.view_mut((0, 8), (8, 2)).copy_from(&(&b * period));
        let exp = augmented.exp();
        let (phi, gamma) = (exp.view((0, 0), (8, 8)), exp.view((0, 8), (8, 2)));
        let size = 8 + 2 * delay;
        let mut step = DMatrix::zeros(size, size);
        if delay == 0 {
            step.copy_from(&(phi + gamma * &gain));
        } else {
            // [dx; c_{j−1}; …; c_{j−d}]: dx' = Φ dx + Γ c_{j−d}, c_j = K dx, the line shifts
            step.view_mut((0, 0), (8, 8)).copy_from(&phi);
            step.view_mut((0, 8 + 2 * (delay - 1)), (8, 2))
                .copy_from(&gamma);
            step.view_mut((8, 0), (2, 8)).copy_from(&gain);
            for i in 1..delay {
                for r in 0..2 {
                    step[(8 + 2 * i + r, 8 + 2 * (i - 1) + r)] = 1.0;
                }
            }
        }
        let expected = orbitflex::linalg::eigenvalues(&step).unwrap();
        let l = sampled_loop(
            &arm,
            &mut arm.workspace(),
            &x,
            &plant,
            feedback,
            rate,
            delay,
        )
        .unwrap();
        assert_eq!(l.eigenvalues.len(), size, "rate {rate} delay {delay}");
        for z in &expected {
            let gap = nearest(&l.eigenvalues, *z);
            assert!(
                gap < 1e-10,
                "rate {rate} delay {delay}: {z} missing ({gap:e})"
            );
        }
        let rho = expected.iter().map(|z| z.norm()).fold(0.0, f64::max);
        assert!((l.spectral_radius - rho).abs() < 1e-10);
        // the threshold: e^{1.1 T g} (1 + 10⁻⁶), g the continuous loop's growth (≥ 0)
        let continuous = orbitflex::linalg::eigenvalues(&(&a + &b * &gain)).unwrap();
        let growth = continuous.iter().map(|z| z.re).fold(0.0, f64::max);
        assert_eq!(growth > 0.1, kd[0] < 0.0, "growth {growth}");
        let threshold = (1.1 * period * growth).exp() * (1.0 + 1e-6);
        assert!(
            (l.threshold - threshold).abs() < 1e-10 * threshold,
            "rate {rate} delay {delay}: threshold {} vs {threshold}",
            l.threshold
        );
    }
}

/// A rate that is not a finite positive number, gains of the wrong length and an attitude PD
/// on an arm without wheels are refused by name; the feedbacks name themselves as the Python
/// classes do.
#[test]
fn sampled_loop_refuses_bad_rates_and_gains() {
    let arm = FlexibleArm::new(
        random_chain(2, 4),
        FlexibleJoints::uniform(2, 50.0, 0.1, 0.2, 0.05).unwrap(),
    )
    .unwrap();
    let x = arm.rest_state();
    let plant = LinearSpec {
        base: BaseMode::Held,
        ..LinearSpec::default()
    };
    let (kp, kd) = ([8.0, 8.0], [0.6, 0.6]);
    let pd = SampledFeedback::MotorPd { kp: &kp, kd: &kd };
    let run = |feedback, rate| {
        sampled_loop(&arm, &mut arm.workspace(), &x, &plant, feedback, rate, 0)
            .map(|l| l.spectral_radius)
            .map_err(|e| e.to_string())
    };
    for rate in [0.0, -5.0, f64::NAN, f64::INFINITY] {
        assert_eq!(
            run(pd, rate).unwrap_err(),
            format!("rate_hz: expected a finite rate > 0 (Hz), given {rate}")
        );
    }
    let short = SampledFeedback::MotorPd {
        kp: &kp[..1],
        kd: &kd,
    };
    assert_eq!(
        run(short, 100.0).unwrap_err(),
        "kp: expected length 2, given length 1"
    );
    let short = SampledFeedback::MotorPd {
        kp: &kp,
        kd: &kd[..1],
    };
    assert_eq!(
        run(short, 100.0).unwrap_err(),
        "kd: expected length 2, given length 1"
    );
    assert!(run(pd, 100.0).is_ok());
    let wheels = axis_wheels();
    let attitude = AttitudePD::new(
        [1.0; 3],
        [1.0; 3],
        AttitudeTarget::Initial,
        wheels.allocation().unwrap(),
    )
    .unwrap();
    assert_eq!(SampledFeedback::Attitude(&attitude).name(), "AttitudePD");
    // the attitude PD is checked against the arm as the linear model checks it
    let e = run(SampledFeedback::Attitude(&attitude), 100.0).unwrap_err();
    assert!(
        e.starts_with("u: an AttitudePD drives reaction wheels, and the arm has none"),
        "{e}"
    );
}
